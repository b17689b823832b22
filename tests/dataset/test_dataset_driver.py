"""dataset/_driver.py, _root.py, _metadata.py: whole-root re-calibration (symbolic links, interrupts, workers, destinations, statistics)."""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from dataset_testutil import (
    FEATURES,
    HI,
    HOMING_A,
    HOMING_B,
    LO,
    RANGE_A,
    RANGE_B,
    A,
    B,
    all_values,
    tree,
)

from robocal.cli.main import main
from robocal.dataset import (
    SO_ARM_JOINTS,
    _driver,
    generate_dataset,
    inspect_dataset,
    recalibrate_dataset,
)
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.errors import FileFormatError, UsageError
from robocal.formats import write_calibration
from robocal.lerobot import MotorCalibration

VIDEO = "videos/observation.images.front/chunk-000/file-000.mp4"


@pytest.fixture()
def src(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    generate_dataset(root, n_episodes=4, frames_per_episode=[30, 40, 25, 12], convention=A)
    return root


def _split_episode_across_files(root: Path) -> None:
    """Move the second half of episode 2 (file-001) into a new file of a second chunk, in two row groups."""
    path = root / "data/chunk-000/file-001.parquet"
    table = pq.read_table(path)
    pq.write_table(table.slice(0, 10), path, row_group_size=10)
    (root / "data/chunk-001").mkdir()
    with pq.ParquetWriter(root / "data/chunk-001/file-000.parquet", table.schema) as writer:
        writer.write_table(table.slice(10, 7), row_group_size=7)
        writer.write_table(table.slice(17), row_group_size=100)


def _slow_work(args: tuple[str, str, str, list[object]]) -> object:

    with open(os.environ["ROBOCAL_TEST_LOG"], "a") as log:
        log.write(args[2] + "\n")
    time.sleep(0.05)
    return _driver.recalibrate_file(*args[:2], args[3], args[2])  # type: ignore[arg-type]


def _dying_work(args: object) -> object:
    os._exit(1)  # a worker killed mid-file (e.g. by the OOM killer)


def test_episode_spanning_files_has_exact_quantiles(src: Path, tmp_path: Path) -> None:
    _split_episode_across_files(src)
    rep = recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert (rep.files, rep.frames) == (3, 107)
    values = all_values(tmp_path / "dst", "action")
    episodes = np.concatenate(
        [
            np.asarray(pq.read_table(p).column("episode_index"))
            for p in sorted((tmp_path / "dst").glob("data/chunk-*/file-*.parquet"))
        ]
    )
    rows = pq.read_table(tmp_path / "dst/meta/episodes/chunk-000/file-000.parquet").to_pylist()
    for row in rows:
        seg = values[episodes == row["episode_index"]]
        assert row["stats/action/count"] == [len(seg)]
        for name, f in (("q01", 0.01), ("q10", 0.1), ("q50", 0.5), ("q90", 0.9), ("q99", 0.99)):
            np.testing.assert_allclose(row[f"stats/action/{name}"], np.quantile(seg, f, axis=0), rtol=1e-12)
        np.testing.assert_allclose(row["stats/action/std"], seg.std(axis=0), rtol=1e-9)


def test_dangling_symlink_destination(src: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_calibration(tmp_path / "a.yaml", A.calibration, "robocal")
    (tmp_path / "dst").symlink_to(tmp_path / "nowhere")
    args = [
        str(src),
        str(tmp_path / "dst"),
        "--old",
        str(tmp_path / "a.yaml"),
        "--new",
        str(tmp_path / "a.yaml"),
    ]
    code = main(["dataset", "recalibrate", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "is a broken symbolic link" in err
    with pytest.raises(UsageError, match="broken symbolic link"):
        recalibrate_dataset(src, tmp_path / "dst", A, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "dst", "src"]


def test_symlinked_videos_and_folders(src: Path, tmp_path: Path) -> None:
    # a Hugging Face cache snapshot: files are relative links into a blob store; here also a linked folder
    store = tmp_path / "blobs"
    store.mkdir()
    (src / VIDEO).rename(store / "video")
    (src / VIDEO).symlink_to(os.path.relpath(store / "video", (src / VIDEO).parent))
    shutil.move(str(src / "meta/tasks.parquet"), store / "tasks")
    (src / "meta/tasks.parquet").symlink_to(store / "tasks")
    (tmp_path / "extra").mkdir()
    (tmp_path / "extra/notes.txt").write_text("kept")
    (src / "docs").symlink_to(tmp_path / "extra")
    nested = tmp_path / "deeper" / "out"
    nested.parent.mkdir()
    recalibrate_dataset(src, nested, A, B)
    assert tree(nested) == sorted([*tree(src), "docs/notes.txt"])
    out_video = nested / VIDEO
    assert not out_video.is_symlink()
    assert out_video.read_bytes() == (store / "video").read_bytes()
    assert out_video.stat().st_ino == (store / "video").stat().st_ino  # hard link to the real file
    assert not (nested / "meta/tasks.parquet").is_symlink()
    assert (nested / "docs/notes.txt").read_text() == "kept"


def test_broken_symlink_in_source_is_an_error(src: Path, tmp_path: Path) -> None:
    (src / "videos/broken.mp4").symlink_to(tmp_path / "missing.mp4")
    with pytest.raises(FileFormatError, match=r"videos/broken\.mp4 is a broken symbolic link"):
        recalibrate_dataset(src, tmp_path / "dst", A, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="patches the worker function")
def test_interrupt_cancels_queued_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=20, frames_per_episode=5, episodes_per_file=1, convention=A)
    log = tmp_path.parent / f"{tmp_path.name}.log"
    monkeypatch.setenv("ROBOCAL_TEST_LOG", str(log))
    monkeypatch.setattr(_driver, "_work", _slow_work)

    def interrupt(path: str, frames: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2, on_file_done=interrupt)
    started = log.read_text().splitlines()
    log.unlink()
    assert len(started) < 20  # the queued files were dropped, not converted into a folder being deleted
    assert multiprocessing.active_children() == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_empty_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=1, frames_per_episode=5, convention=A)
    info = json.loads((src / "meta/info.json").read_text())
    info.update(total_frames=0, total_episodes=0)
    (src / "meta/info.json").write_text(json.dumps(info))
    shutil.rmtree(src / "data")
    (src / "meta/episodes/chunk-000/file-000.parquet").unlink()
    rep = recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert (rep.frames, rep.files, rep.row_groups) == (0, 0, 0)
    files = [rel for rel in tree(src) if (src / rel).is_file()]
    assert [rel for rel in tree(tmp_path / "dst") if (tmp_path / "dst" / rel).is_file()] == files
    assert "meta/stats.json" in files
    summary = inspect_dataset(src, calibration=A)
    assert summary.frames == 0 and summary.flagged == ()
    assert np.isnan(summary.joints[0].min) and np.isnan(summary.joints[0].mean)


def test_dataset_per_feature_mapping_without_the_feature(src: Path, tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="feature 'action': no old calibration for it"):
        recalibrate_dataset(src, tmp_path / "dst", {"observation.state": A}, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_overwrite_keeps_old_destination_when_the_final_rename_fails(
    src: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dst = tmp_path / "dst"
    dst.mkdir()
    (dst / "keep.txt").write_text("old")
    real_replace = os.replace

    def failing_replace(a: object, b: object) -> None:
        if Path(str(a)).name.startswith(".dst.robocal-"):
            raise OSError(28, "No space left on device")
        real_replace(a, b)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(FileFormatError, match=r"cannot move the new dataset into place \(No space left"):
        recalibrate_dataset(src, dst, A, B, overwrite=True)
    assert (dst / "keep.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dst", "src"]


def test_relative_paths_and_dot_destination(
    src: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    write_calibration(tmp_path / "a.yaml", A.calibration, "robocal")
    write_calibration(tmp_path / "b.yaml", B.calibration, "robocal")
    recalibrate_dataset(src, tmp_path / "ref", A, B)
    monkeypatch.chdir(tmp_path)
    code = main(["dataset", "recalibrate", "src", "out", "--old", "a.yaml", "--new", "b.yaml"])
    assert (code, capsys.readouterr().err) == (0, "")
    np.testing.assert_array_equal(
        all_values(tmp_path / "out", "action"), all_values(tmp_path / "ref", "action")
    )
    shutil.rmtree(tmp_path / "ref")
    # DST "." (the current folder) with --overwrite: replaced as a whole
    monkeypatch.chdir(tmp_path / "out")
    code = main(
        ["dataset", "recalibrate", "../src", ".", "--old", "../a.yaml", "--new", "../a.yaml", "--overwrite"]
    )
    assert (code, capsys.readouterr().err) == (0, "")
    monkeypatch.chdir(tmp_path)
    np.testing.assert_array_equal(all_values(tmp_path / "out", "action"), all_values(src, "action"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "b.yaml", "out", "src"]


def _dying_second_work(args: tuple[str, str, str, list[object]]) -> object:
    if args[2].endswith("file-000.parquet"):
        return _driver.recalibrate_file(*args[:2], args[3], args[2])  # type: ignore[arg-type]
    os._exit(1)


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="patches the worker function")
@pytest.mark.parametrize("work", [_dying_work, _dying_second_work], ids=["first-file", "after-a-file"])
def test_dead_worker_is_one_error_not_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, work: Any
) -> None:
    """A worker that dies is one ``DatasetWorkerError`` (exit 3) naming the file, no worker left, nothing written."""
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=4, frames_per_episode=5, episodes_per_file=1, convention=A)
    monkeypatch.setattr(_driver, "_work", work)
    with pytest.raises(_driver.DatasetWorkerError, match=r"worker process died while converting .*file-00") as info:
        recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert info.value.exit_code == 3
    assert "(exit status 1)" in str(info.value)
    assert multiprocessing.active_children() == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def _so_conv(homing: list[int]) -> LeRobotConvention:
    ranges = RANGE_A if homing is HOMING_A else RANGE_B
    return LeRobotConvention.from_calibrations(
        {n: MotorCalibration(i + 1, 0, homing[i], *ranges[i]) for i, n in enumerate(SO_ARM_JOINTS)},
        preset_modes("so101_follower", SO_ARM_JOINTS),
        "feetech",
    )


def test_data_without_episode_index_recomputes_dataset_stats(tmp_path: Path) -> None:
    src = tmp_path / "src"
    generate_dataset(
        src,
        n_episodes=4,
        frames_per_episode=[30, 40, 25, 12],
        convention=_so_conv(HOMING_A),
        actual_lo=LO,
        actual_hi=HI,
    )
    path = src / "data/chunk-000/file-001.parquet"  # episodes 2 and 3
    pf = pq.ParquetFile(path)
    parts = [pf.read_row_group(g).drop(["episode_index"]) for g in range(pf.metadata.num_row_groups)]
    with pq.ParquetWriter(path, parts[0].schema) as writer:
        for t in parts:
            writer.write_table(t, row_group_size=t.num_rows)
    old_episodes = pq.read_table(src / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    rep = recalibrate_dataset(src, tmp_path / "dst", _so_conv(HOMING_A), _so_conv(HOMING_B))
    assert rep.frames == 107
    assert rep.warnings[0] == (
        "data file data/chunk-000/file-001.parquet has no 'episode_index' column: meta/stats.json is "
        "recomputed from its 37 frames, but per-episode statistics cannot be updated for them"
    )
    assert rep.warnings[1].startswith(
        "meta/episodes/chunk-000/file-000.parquet: per-episode statistics of observation.state, action "
        "for 2 episode(s) (2, 3) could not be updated"
    )
    assert len(rep.warnings) == 2
    stats = json.loads((tmp_path / "dst/meta/stats.json").read_text())
    for key in FEATURES:
        values = all_values(tmp_path / "dst", key)
        assert stats[key]["count"] == [107]
        np.testing.assert_array_equal(stats[key]["min"], values.min(axis=0))
        np.testing.assert_array_equal(stats[key]["max"], values.max(axis=0))
        np.testing.assert_allclose(stats[key]["mean"], values.mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(stats[key]["std"], values.std(axis=0), rtol=1e-9)
    episodes = pq.read_table(tmp_path / "dst/meta/episodes/chunk-000/file-000.parquet").to_pylist()
    values = all_values(tmp_path / "dst", "action")
    # episodes 0 and 1 (first file) updated; 2 and 3 kept as they were
    np.testing.assert_array_equal(episodes[0]["stats/action/min"], values[:30].min(axis=0))
    for e in (2, 3):
        assert episodes[e]["stats/action/min"] == old_episodes[e]["stats/action/min"]
