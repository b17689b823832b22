"""``robocal lerobot`` commands through robocal.cli.main.main, against the simulator."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from tests.robots import SO101_JOINTS

from robocal.backends.sim import lerobot_arms
from robocal.backends.sim.lerobot_arms import SimArm
from robocal.cli.main import main
from robocal.formats import read_calibration as read_joint_map
from robocal.lerobot import MotorCalibration, normalize, read_calibration
from robocal.workflows.lerobot import open_bus, restore, robot_spec

from .conftest import LEGACY, calibrate_args

pytestmark = pytest.mark.timeout(60)


def _calibrate(tmp_path: Path, robot: str = "so101_follower", *extra: str) -> int:
    return main(calibrate_args(tmp_path, *extra, robot=robot))


@pytest.mark.slow
def test_calibrate_sim_writes_lerobot_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate(tmp_path) == 0
    out = capsys.readouterr()
    path = tmp_path / "robots" / "so_follower" / "arm1.json"
    assert f"calibration saved to {path}" in out.out
    assert "reading 20: shoulder_pan 847..3247" in out.err  # plain progress lines without a terminal
    cals = read_calibration(path)
    assert cals["shoulder_pan"] == MotorCalibration(1, 0, 53, 847, 3247)
    assert path.read_text().startswith('{\n    "shoulder_pan": {\n        "id": 1,\n        "drive_mode": 0,')
    assert _calibrate(tmp_path, "koch_leader", "--home-after-sweep", "--sweep-full-turn") == 0
    k = read_calibration(tmp_path / "teleoperators" / "koch_leader" / "arm1.json")
    assert k["elbow_flex"].drive_mode == 1 and k["shoulder_pan"].range_min != 0


def test_calibrate_ctrl_c_exit_130_no_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    original = lerobot_arms.SimArmOperator.__init__

    def interrupting(self: lerobot_arms.SimArmOperator, arm: SimArm, **kw: object) -> None:
        original(self, arm, interrupt_at_step=4)

    monkeypatch.setattr(lerobot_arms.SimArmOperator, "__init__", interrupting)
    assert _calibrate(tmp_path) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "error: interrupted: every motor's EEPROM was restored and no file was written"
    )
    assert not (tmp_path / "robots").exists() or not list((tmp_path / "robots").rglob("*.json"))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["calibrate", "--robot", "so102", "--port", "sim", "--id", "x"], "error: unknown robot 'so102'"),
        (
            ["calibrate", "--robot", "so101_follower", "--port", "sim", "--id", "../x"],
            "error: calibration id '../x'",
        ),
        (["migrate", "LEGACY", "--vendor", "robstride"], "error: vendor 'robstride'"),
        (["migrate", "LEGACY", "--vendor", "feetech", "--ids", "1,x"], "error: --ids '1,x'"),
        (["check", "--robot", "so101_follower", "--port", "sim"], "error: give --id"),
        (
            ["show", "--robot", "so101_follower", "--port", "sim", "--file", "BAD", "--compat", "fast"],
            "error: --compat 'fast'",
        ),
        (
            ["export-urdf", "--robot", "so101_follower", "--file", "BAD", "--out", "OUT"],
            "error: BAD: motor 'wrist_roll': missing",
        ),
        (
            [
                "export-urdf",
                "--robot",
                "so101_follower",
                "--file",
                "GOOD",
                "--out",
                "OUT",
                "--sign",
                "gripper=2",
            ],
            "error: --sign gripper=2: expected -1 or 1",
        ),
        (
            ["export-urdf", "--robot", "so101_follower", "--file", "GOOD", "--out", "OUT", "--sign", "elbow"],
            "error: --sign 'elbow'",
        ),
        (
            ["migrate", "GOOD", "--vendor", "feetech", "--out", "OUT"],
            "error: GOOD: this is a current LeRobot",
        ),
        (
            ["export-urdf", "--robot", "so101_follower", "--file", "LEGACY", "--out", "OUT"],
            "error: LEGACY: this is a legacy LeRobot calibration",
        ),
        (
            ["check", "--robot", "koch_leader", "--port", "/nonexistent/tty", "--file", "GOOD"],
            "error: /nonexistent/tty: cannot open the serial port",
        ),
    ],
)
def test_malformed_cli_matrix(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    good = tmp_path / "good.json"
    good.write_text(
        json.dumps(
            {
                n: {"id": i + 1, "drive_mode": 0, "homing_offset": 0, "range_min": 0, "range_max": 4095}
                for i, n in enumerate(
                    ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
                )
            },
            indent=4,
        )
    )
    bad = tmp_path / "bad.json"
    data = json.loads(good.read_text())
    del data["wrist_roll"]["range_max"]
    bad.write_text(json.dumps(data))
    legacy = tmp_path / "legacy.json"
    legacy.write_text(LEGACY)
    repl = {"BAD": str(bad), "GOOD": str(good), "LEGACY": str(legacy), "OUT": str(tmp_path / "out.yaml")}
    args = [repl.get(a, a) for a in args]
    for key in ("BAD", "GOOD", "LEGACY"):
        message = message.replace(key, repl[key])
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["lerobot", *args])
    err = capsys.readouterr().err.strip().splitlines()
    expected_code = 3 if "cannot open" in message else 2
    assert code == expected_code
    assert len([e for e in err if e.startswith("error:")]) == 1 and err[-1].startswith(message)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert good.read_text().startswith('{\n    "shoulder_pan"')


@pytest.mark.slow
def test_check_names_motor_and_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate(tmp_path, "koch_leader") == 0
    path = tmp_path / "teleoperators" / "koch_leader" / "arm1.json"
    cals = read_calibration(path)
    with SimArm(robot_spec("koch_leader")) as arm:
        capsys.readouterr()
        assert (
            main(["lerobot", "check", "--robot", "koch_leader", "--port", arm.port, "--file", str(path)]) == 1
        )
        out = capsys.readouterr().out
        assert "differs: motor 'elbow_flex' (id 3): drive_mode is 0 on the motor, 1 in the file" in out
        assert (
            f"differs: motor 'gripper' (id 6): homing_offset is 0 on the motor, {cals['gripper'].homing_offset}"
            in out
        )
        bus = open_bus(arm.spec, arm.port)
        try:
            restore(bus, arm.spec, cals)
        finally:
            bus.close()
        assert (
            main(["lerobot", "check", "--robot", "koch_leader", "--port", arm.port, "--file", str(path)]) == 0
        )
        assert f"EEPROM matches {path}" in capsys.readouterr().out
    # --use-file writes the file onto a fresh simulated arm (Drive_Mode included) and exits 0
    assert _calibrate(tmp_path, "koch_leader", "--use-file") == 0


def test_migrate_keeps_legacy_zero(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    legacy = tmp_path / "main_follower.json"
    legacy.write_text(LEGACY)
    out = tmp_path / "current.json"
    assert main(["lerobot", "migrate", str(legacy), "--vendor", "dynamixel", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    # issue #15: a Dynamixel (Koch) migration no longer prints the SO-100/SO-101 transform
    assert "shoulder_lift_new" not in text and "LeRobot documents no value transform for Koch arms" in text
    cals = read_calibration(out)
    assert cals["shoulder_pan"] == MotorCalibration(1, 1, 2048 + 2047, 0, 4094)
    assert cals["gripper"] == MotorCalibration(6, 0, 0, 2499, 3144)
    # Dynamixel: Present = −raw + H in reverse mode; legacy 0° (raw 2048) now reads 2047 = mid -> 0°
    present = -2048 + cals["shoulder_pan"].homing_offset
    assert float(normalize(present, cals["shoulder_pan"], "degrees", apply_drive_mode=False)) == 0.0
    assert main(["lerobot", "migrate", str(legacy), "--vendor", "feetech"]) == 1
    captured = capsys.readouterr()
    assert "shoulder_lift_new = -(old - 90); elbow_flex_new = old - 90" in captured.out
    assert (
        "warning: shoulder_pan: inverted (drive_mode 1) but LeRobot's DEGREES ignores drive_mode"
        in captured.err
    )
    printed = json.loads(captured.out[: captured.out.index("}\n}") + 3])
    assert printed["wrist_flex"] == {
        "id": 4,
        "drive_mode": 0,
        "homing_offset": (1024 - 2047 + 2048) % 4096 - 2048,
        "range_min": 0,
        "range_max": 4094,
    }


@pytest.mark.slow
def test_export_urdf_joint_map_is_exact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate(tmp_path) == 0
    path = tmp_path / "robots" / "so_follower" / "arm1.json"
    out = tmp_path / "so101.yaml"
    code = main(
        [
            "lerobot",
            "export-urdf",
            "--robot",
            "so101_follower",
            "--file",
            str(path),
            "--out",
            str(out),
            "--sign",
            "elbow_flex=-1",
            "--offset-deg",
            "shoulder_lift=90",
        ]
    )
    assert code == 1  # gripper (RANGE_0_100) is not exported: warning
    assert "warning: not exported (range modes, no angle): gripper" in capsys.readouterr().err
    jm = read_joint_map(out).calibration
    cals = read_calibration(path)
    names = list(jm.joint_names)
    assert names == ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
    present = np.array([[900, 1200, 2500, 3000, 17], [2047, 2047, 2047, 2047, 2047]])
    q_lerobot = np.deg2rad(normalize(present, [cals[n] for n in names], "degrees"))
    sign = np.array([1, 1, -1, 1, 1])
    offset = np.array([0, math.pi / 2, 0, 0, 0])
    np.testing.assert_allclose(jm.to_joint(present), sign * q_lerobot + offset, atol=1e-12)


@pytest.mark.slow
def test_show_prints_normalised_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate(tmp_path) == 0
    capsys.readouterr()
    assert (
        main(
            [
                "lerobot",
                "show",
                "--robot",
                "so101_follower",
                "--port",
                "sim",
                "--id",
                "arm1",
                "--calibration-dir",
                str(tmp_path),
                "--samples",
                "2",
            ]
        )
        == 0
    )
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].split() == ["reading", *SO101_JOINTS]
    # the simulated arm rests at its mid pose: shoulder_pan reads 2047 = the middle of 847..3247 -> 0°
    assert lines[1].split()[:2] == ["0", "0.000"] and len(lines) == 3


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["so101", "koch"])
def test_run_demo(tmp_path: Path, capsys: pytest.CaptureFixture[str], robot: str) -> None:
    assert main(["demo", "--robot", robot, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.count("6 motors in LeRobot's format") == 2 and "shoulder_pan" in out
    files = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*.json"))
    expected = {
        "so101": ["robots/so_follower/demo.json", "teleoperators/so_leader/demo.json"],
        "koch": ["robots/koch_follower/demo.json", "teleoperators/koch_leader/demo.json"],
    }
    assert files == expected[robot]
    assert main(["demo", "--robot", robot]) == 0


def test_old_so101_folder_is_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate(tmp_path) == 0
    new = tmp_path / "robots" / "so_follower" / "arm1.json"
    old = tmp_path / "robots" / "so101_follower" / "arm1.json"
    old.parent.mkdir(parents=True)
    new.rename(old)
    capsys.readouterr()
    args = ["lerobot", "show", "--robot", "so101_follower", "--port", "sim", "--id", "arm1"]
    assert main([*args, "--calibration-dir", str(tmp_path)]) == 0
    assert f"warning: using {old} (LeRobot < 0.4.3 folder)" in capsys.readouterr().err


def test_live_table_on_a_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from robocal.cli import _common

    monkeypatch.setattr(_common.err_console, "_force_terminal", True)
    assert _common.err_console.is_terminal
    assert _calibrate(tmp_path) == 0
    err = capsys.readouterr().err
    assert "range of motion (reading" in err and "shoulder_pan" in err and "reading 20:" not in err


@pytest.mark.parametrize(("port", "transport"), [("sim", "pty"), ("sim", "inproc")])
def test_a_simulated_arm_s_bus_errors_name_the_port_as_given_not_its_pty(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, port: str, transport: str
) -> None:
    """Before: "motor 'elbow_flex': Min_Position_Limit: /dev/pts/3: motor 3: value -3 does not fit ...", the
    simulator's pseudo-terminal (or its inproc:// name), a path the user never gave and that is gone at exit."""
    if transport == "inproc":  # the same arm behind the in-process port
        original = SimArm.__init__

        def inproc(self: SimArm, robot: object, **kw: object) -> None:
            original(self, robot, **{**kw, "transport": "inproc"})  # type: ignore[arg-type]

        monkeypatch.setattr(SimArm, "__init__", inproc)
    cals = {n: {"id": k + 1, "drive_mode": 0, "homing_offset": 0, "range_min": 1000, "range_max": 3000}
            for k, n in enumerate(SO101_JOINTS)}  # fmt: skip
    cals["elbow_flex"]["range_min"] = -3  # a value no register holds (read, and refused by the bus)
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(cals))
    rc = main(["lerobot", "show", "--robot", "so101_follower", "--port", port, "--file", str(path)])
    out, err = capsys.readouterr()
    assert (rc, out) == (2, "")
    assert err.splitlines()[-1] == (
        "error: motor 'elbow_flex': Min_Position_Limit: sim: motor 3: value -3 does not fit register "
        "'Min_Position_Limit'"
    )
    assert err.count("error:") == 1 and "/dev/" not in err and "inproc://" not in err
