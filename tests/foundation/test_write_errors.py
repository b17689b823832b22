"""Writes that fail for the file system (read-only, full) are one ``error:`` line, exit 2, nothing changed."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from fs_sandbox import FILL_DISK, SRC, needs_unshare, run_on_tmpfs

from robocal.dataset import SO_ARM_JOINTS, generate_dataset
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.lerobot import MotorCalibration, write_calibration

RANGES = [(900, 2950), (1000, 3000), (950, 3100), (1000, 3000), (0, 4095), (1000, 3000)]


def _cals(homing: list[int]) -> dict[str, MotorCalibration]:
    return {n: MotorCalibration(i + 1, 0, homing[i], *RANGES[i]) for i, n in enumerate(SO_ARM_JOINTS)}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("ds")
    write_calibration(d / "a.json", _cals([100, -40, 60, 0, -120, 0]))
    write_calibration(d / "b.json", _cals([-150, 30, -90, 200, 50, 500]))
    conv = LeRobotConvention.from_calibrations(
        _cals([100, -40, 60, 0, -120, 0]), preset_modes("so101_follower", SO_ARM_JOINTS), "feetech"
    )
    generate_dataset(
        d / "src",
        n_episodes=2,
        frames_per_episode=[20, 30],
        convention=conv,
        actual_lo=[1100] * 4 + [200, 1100],
        actual_hi=[2800] * 4 + [3900, 2400],
    )
    return d


def _cli(*args: str) -> str:
    """Python source running the CLI in a subprocess and printing its exit code and stderr as JSON."""
    return f"""
    import subprocess
    r = subprocess.run([sys.executable, "-m", "robocal", *{list(args)!r}], capture_output=True, text=True)
    print(json.dumps({{"rc": r.returncode, "err": r.stderr, "files": sorted(os.listdir(mnt))}}))
    """


def _recalibrate_args(dataset: Path, dst: Path) -> list[str]:
    """``dataset recalibrate`` of the generated SO-101 dataset from calibration a to b into ``dst``."""
    return ["dataset", "recalibrate", str(dataset / "src"), str(dst), "--old", str(dataset / "a.json"),
            "--new", str(dataset / "b.json"), "--robot", "so101_follower"]  # fmt: skip


@pytest.mark.slow
@needs_unshare
def test_dataset_recalibrate_into_read_only_folder(tmp_path: Path, dataset: Path) -> None:
    out = run_on_tmpfs(
        tmp_path,
        "",
        _cli(*_recalibrate_args(dataset, tmp_path / "mnt" / "out")),
        read_only=True,
    )
    assert out["rc"] == 2
    assert out["err"] == (
        f"error: cannot write {tmp_path / 'mnt' / 'out'}: cannot create a folder in {tmp_path / 'mnt'} "
        "(Read-only file system); nothing written\n"
    )
    assert out["files"] == []


@needs_unshare
@pytest.mark.parametrize("read_only", [True, False])
def test_convert_onto_read_only_or_full_disk(tmp_path: Path, read_only: bool) -> None:
    src = tmp_path / "src.json"
    src.write_text('{"j1": {"id": 1, "direction": 1, "homing_offset": 0.5}}\n')
    fill = "" if read_only else FILL_DISK
    out = run_on_tmpfs(
        tmp_path,
        '(mnt / \'cal.json\').write_text(\'{"j1": {"id": 1, "direction": 1, "homing_offset": 0.1}}\')\n'
        + textwrap.dedent(fill),
        _cli("convert", str(src), str(tmp_path / "mnt" / "cal.json"), "--to", "lite-json"),
        read_only=read_only,
    )
    assert out["rc"] == 2
    why = "Read-only file system" if read_only else "disk full"
    assert out["err"].startswith(f"error: cannot write {tmp_path / 'mnt' / 'cal.json'}") and why in out["err"]
    assert len(out["err"].splitlines()) == 1
    assert out["files"] == (["cal.json"] if read_only else ["cal.json", "fill"])


@pytest.mark.slow
def test_dataset_long_destination_name_uses_a_short_temporary_name(tmp_path: Path, dataset: Path) -> None:
    dst = tmp_path / ("d" * 250)
    env = {**os.environ, "PYTHONPATH": SRC}
    r = subprocess.run(
        [sys.executable, "-m", "robocal", *_recalibrate_args(dataset, dst)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert r.returncode in (0, 1), r.stderr  # 1: the generated data has values outside the new range
    assert (dst / "meta" / "info.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [dst.name]
