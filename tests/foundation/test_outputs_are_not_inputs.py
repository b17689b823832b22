"""No output may replace one of the command's inputs or land inside an input folder (a hostile user's typo).

Before, ``robocal dataset health ROOT --report ROOT/meta/info.json`` wrote the report over the dataset's own
``info.json`` (exit 0: the dataset was then unreadable), and ``robocal sweep --report URDF`` wrote the JSON report
over the URDF it read. Each command now refuses such a path before any work: exit 2, one ``error:`` line naming
the output and the input, every input byte-identical and no backup made.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import FileWriteError
from robocal.fileio import check_not_an_input, check_output_path

ROOT = Path(__file__).resolve().parents[2]
LITE_URDF = ROOT / "examples" / "lite" / "lite_bimanual.urdf"
LITE_CAL = ROOT / "examples" / "lite" / "calibration.yaml"


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(argv: list[str], folder: Path, capsys: pytest.CaptureFixture[str], match: str) -> None:
    before = _snapshot(folder)
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert match in lines[0], lines[0]
    assert _snapshot(folder) == before  # nothing written, no .bak


def test_the_check_follows_links_and_names_the_input(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    (tmp_path / "cal.json").write_text("{}")
    (tmp_path / "link").symlink_to(data)
    with pytest.raises(FileWriteError, match=r"^--report .*link/x\.json: inside the dataset \(.*data\)"):
        check_output_path(tmp_path / "link" / "x.json", "--report", inputs={"the dataset": data})
    with pytest.raises(FileWriteError, match=r"^--out .*cal\.json: is --file \(.*cal\.json\); give the output"):
        check_not_an_input(tmp_path / "cal.json", "--out", {"--file": tmp_path / "cal.json", "--urdf": None})
    # beside an input folder, or an input that does not exist yet: fine
    assert check_output_path(tmp_path / "data.json", "--report", inputs={"the dataset": data}) == tmp_path / "data.json"
    check_not_an_input(tmp_path / "x.json", "--out", {"--file": tmp_path / "x.json.missing"})


def test_dataset_health_report_inside_the_dataset_or_over_a_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.dataset.teleop_sim import TeleopFaults, generate_teleop_datasets

    (root,) = generate_teleop_datasets(
        tmp_path, "so101", [3], [TeleopFaults()], episodes=1, episode_s=2.0, calibration_files=True
    )
    leader, follower = tmp_path / "so101-3.leader.json", tmp_path / "so101-3.follower.json"
    base = ["dataset", "health", str(root), "--robot", "so101_follower"]
    _refused([*base, "--report", str(root / "meta" / "info.json")], tmp_path, capsys,
             f"--report {root / 'meta' / 'info.json'}: inside the dataset ({root})")  # fmt: skip
    _refused([*base, "--report", str(root / "health.json")], tmp_path, capsys, "inside the dataset")
    files = ["--leader-calibration", str(leader), "--follower-calibration", str(follower)]
    _refused([*base, *files, "--report", str(follower)], tmp_path, capsys,
             f"--report {follower}: is --follower-calibration ({follower})")  # fmt: skip
    # the picture goes beside the report as .png: it may not replace an input either
    urdf = tmp_path / "arm.png"
    shutil.copy(ROOT / "src" / "robocal" / "data" / "so101_new_calib.urdf", urdf)
    _refused([*base, "--urdf", str(urdf), "--report", str(tmp_path / "arm.json")], tmp_path, capsys,
             f"the report's picture {tmp_path / 'arm.png'}: is --urdf")  # fmt: skip
    assert main([*base, "--report", str(tmp_path / "ok.json")]) in (0, 1)
    assert (tmp_path / "ok.json").is_file() and (tmp_path / "ok.png").is_file()


def test_sweep_report_over_its_urdf_prior_or_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf, prior = tmp_path / "lite.urdf", tmp_path / "prior.yaml"
    shutil.copy(LITE_URDF, urdf)
    shutil.copy(LITE_CAL, prior)
    (tmp_path / "rec.csv").write_text("t\n")
    base = ["sweep", "--urdf", str(urdf), "--out", str(tmp_path / "cal.yaml")]
    _refused([*base, "--source", "sim:lite", "--report", str(urdf)], tmp_path, capsys,
             f"--report {urdf}: is --urdf ({urdf})")  # fmt: skip
    _refused([*base, "--source", "sim:lite", "--prior", str(prior), "--report", str(prior)], tmp_path, capsys,
             "is --prior")  # fmt: skip
    _refused([*base, "--source", f"replay:{tmp_path / 'rec.csv'}", "--report", str(tmp_path / "rec.csv")],
             tmp_path, capsys, "is --source")  # fmt: skip
    _refused(["sweep", "--auto", "--yes", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(tmp_path / "c.yaml"),
              "--report", str(urdf)], tmp_path, capsys, "is --urdf")  # fmt: skip


def test_kinematics_outputs_over_their_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf, data = tmp_path / "arm.urdf", tmp_path / "session.csv"
    shutil.copy(ROOT / "src" / "robocal" / "data" / "so101_new_calib.urdf", urdf)
    data.write_text("pose,x,y,z\n")
    identify = ["kinematics", "identify", "--urdf", str(urdf), "--data", str(data)]
    _refused([*identify, "--out", str(tmp_path / "new.urdf"), "--report", str(data)], tmp_path, capsys,
             f"--report {data}: is --data ({data})")  # fmt: skip
    _refused([*identify, "--out", str(urdf)], tmp_path, capsys, "is --urdf")
    _refused(["kinematics", "plan", "--urdf", str(urdf), "--out", str(urdf)], tmp_path, capsys, "is --urdf")
    _refused(["kinematics", "record", "--source", "sim:lite", "--urdf", str(urdf), "--out", str(urdf)],
             tmp_path, capsys, "--out " + str(urdf) + ": is --urdf")  # fmt: skip
    image = tmp_path / "board.png"
    image.write_bytes(b"\x89PNG\r\n\x1a\n")
    _refused(["kinematics", "camera-calibrate", str(image), "--board", "charuco:5x7:0.04:0.03:DICT_5X5_100",
              "--out", str(image)], tmp_path, capsys, "is image 1")  # fmt: skip


def test_ur_and_lerobot_outputs_over_their_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dh = tmp_path / "dh.yaml"
    dh.write_text("dh_theta: [0, 0, 0, 0, 0, 0]\n")
    _refused(["ur", "correct", "--dh", str(dh), "--out", str(dh)], tmp_path, capsys, f"--out {dh}: is --dh")
    _refused(["ur", "plot", "--dh", str(dh), "--out", str(dh)], tmp_path, capsys, "is --dh")
    urdf = tmp_path / "ur.urdf"
    urdf.write_text("<robot name='ur'/>")
    _refused(["ur", "correct", "--model", "ur5e", "--out", str(urdf), "--urdf-in", str(urdf), "--urdf-out",
              str(tmp_path / "new.urdf")], tmp_path, capsys, f"--out {urdf}: is --urdf-in")  # fmt: skip
    cal = tmp_path / "so101.json"
    cal.write_text("{}")
    _refused(["lerobot", "export-urdf", "--robot", "so101_follower", "--file", str(cal), "--out", str(cal)],
             tmp_path, capsys, f"--out {cal}: is --file")  # fmt: skip
