from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.formats import read_calibration

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "lite"
URDF = EXAMPLES / "lite_bimanual.urdf"
CAL = EXAMPLES / "calibration.yaml"


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("robocal 0.")


def test_check_consistent_file_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--calibration", str(CAL), "--urdf", str(URDF)]) == 0
    out = capsys.readouterr().out
    assert "14/14 joints matched (lite-yaml)" in out
    assert "left_elbow_pitch" in out and "-1.026153" in out


def test_check_reports_mismatches_and_exits_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = CAL.read_text()
    text = text.replace(
        "left_elbow_pitch:\n  id: 14\n  direction: -1", "left_elbow_pitch:\n  id: 99\n  direction: 1"
    )
    text = text.replace("right_wrist_pitch:", "right_wrist_pich:")
    cal = tmp_path / "calibration.yaml"
    cal.write_text(text)
    assert main(["check", "--calibration", str(cal), "--urdf", str(URDF)]) == 1
    captured = capsys.readouterr()
    assert "13/14 joints matched" in captured.out
    err = captured.err
    assert "warning: joints missing from the calibration file: right_wrist_pitch" in err
    assert "warning: joints in the calibration file but not in the URDF: right_wrist_pich" in err
    assert "warning: left_elbow_pitch: direction +1 in the file disagrees with -1 in the URDF" in err
    assert "warning: left_elbow_pitch: id 99 in the file disagrees with can_id 14 in the URDF" in err


def test_check_zero_matched_key_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "c.yaml"
    cal.write_text("joint_a: {id: 1, direction: 1, homing_offset: 0.0}\n")
    assert main(["check", "--calibration", str(cal), "--urdf", str(URDF)]) == 1
    assert "0/14 joints matched" in capsys.readouterr().out


def test_convert_chain_is_exact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    steps = [
        ("a.json", []),
        ("b.yaml", ["--to", "berkeley-offsets", "--urdf", str(URDF)]),
        ("c.urdf", ["--to", "ros2-transmission", "--urdf", str(URDF)]),
        ("d.yaml", ["--to", "robocal"]),
        ("e.yaml", ["--to", "lite-yaml", "--urdf", str(URDF)]),
    ]
    src = CAL
    for name, extra in steps:
        dst = tmp_path / name
        code = main(
            ["convert", str(src), str(dst), *extra, *(["--urdf", str(URDF)] if src.name == "b.yaml" else [])]
        )
        assert code == 0, capsys.readouterr().err
        src = dst
    original = read_calibration(CAL)
    final = read_calibration(tmp_path / "e.yaml")
    assert final.calibration.is_close(original.calibration, 0.0)
    assert dict(final.ids) == dict(original.ids)
    assert (tmp_path / "c.urdf").read_text().count("SimpleTransmission") == 14
    data = json.loads((tmp_path / "a.json").read_text())
    assert data["left_shoulder_pitch"] == {"id": 11, "direction": -1, "homing_offset": -0.422801}


def test_convert_joint_order_for_positional_output(tmp_path: Path) -> None:
    dst = tmp_path / "b.yaml"
    order = "left_wrist_pitch,left_elbow_pitch"
    assert main(["convert", str(CAL), str(dst), "--to", "berkeley-offsets", "--joints", order]) == 0
    # left_wrist_pitch: direction -1, h = -1.060803 -> off = 1.060803; left_elbow_pitch: -1 * -1.026153
    assert "position_offsets: [1.060803, 1.026153]" in dst.read_text()


def test_convert_keeps_backup(tmp_path: Path) -> None:
    dst = tmp_path / "calibration.yaml"
    shutil.copy(CAL, dst)
    shutil.copy(CAL, tmp_path / "src.yaml")
    src_text = (tmp_path / "src.yaml").read_text().replace("homing_offset: -0.422801", "homing_offset: 0.5")
    (tmp_path / "src.yaml").write_text(src_text)
    assert main(["convert", str(tmp_path / "src.yaml"), str(dst)]) == 0
    assert (tmp_path / "calibration.yaml.bak").read_text() == CAL.read_text()
    assert dst.read_text() == src_text


def test_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--urdf", str(URDF)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "--calibration" in err
    assert main(["frobnicate"]) == 2
    assert capsys.readouterr().err.startswith("error: No such command")


def test_convert_lerobot_legacy_degree_exact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import math

    import numpy as np

    src = tmp_path / "legacy.json"
    src.write_text(
        json.dumps(
            {
                "homing_offset": [2048, -1024, 0],
                "drive_mode": [1, 0, 0],
                "start_pos": [0, 0, 0],
                "end_pos": [0, 0, 0],
                "calib_mode": ["DEGREE"] * 3,
                "motor_names": ["a", "b", "c"],
            }
        )
    )
    dst = tmp_path / "map.yaml"
    assert main(["convert", str(src), str(dst), "--to", "robocal"]) == 0
    cal = read_calibration(dst).calibration
    # LeRobot legacy golden vector: raw [3072, 3072, -2048] -> [-90, 180, -180] degrees
    np.testing.assert_allclose(
        np.degrees(cal.to_joint([3072, 3072, -2048])), [-90.0, 180.0, -180.0], atol=1e-12
    )
    assert cal.scale[0] == math.pi / 2048
    # a motor-rad format cannot hold tick offsets: clear error, nothing written
    assert main(["convert", str(src), str(tmp_path / "x.json")]) == 2
    assert "use --to robocal" in capsys.readouterr().err
    linear = json.loads(src.read_text())
    linear["calib_mode"][2] = "LINEAR"
    src.write_text(json.dumps(linear))
    # issue #15: the DEGREE motors are converted, the LINEAR one is named and left out (exit 1, warnings)
    assert main(["convert", str(src), str(tmp_path / "y.yaml"), "--to", "robocal"]) == 1
    assert "LINEAR motor(s) c left out" in capsys.readouterr().err
    assert read_calibration(tmp_path / "y.yaml").calibration.joint_names == ("a", "b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["legacy.json", "map.yaml", "y.yaml"]


def test_stray_ctrl_c_is_one_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    import typer

    from robocal.cli import main as cli_main

    sub = typer.Typer()

    @sub.command("boom")
    def boom() -> None:
        raise KeyboardInterrupt

    @sub.command("other")
    def other() -> None:
        pass

    cli_main._wrap_commands(sub)
    command = typer.main.get_command(sub)
    with pytest.raises(cli_main.UserInterruptError, match="interrupted"):
        command.main(args=["boom"], standalone_mode=False)


def test_demo_robot_names(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--robot", "atlas"]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith("error: unknown demo robot 'atlas'; valid: lite, so101, koch, ur3")
        and err.count("\n") == 1
    )


def test_demo_out_must_be_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["demo", "--out", str(f)]) == 2
    assert capsys.readouterr().err.startswith("error: --out ")
    assert f.read_text() == "x"
