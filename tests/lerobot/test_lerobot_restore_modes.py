"""``--use-file`` rollback, ``--use-degrees`` / ``--modes`` and ``configure``, through the real SDKs on a pty."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import robocal.workflows.lerobot as wf
import robocal.workflows.lerobot.arms as wf_arms
from robocal.backends.sim.lerobot_arms import SimArm
from robocal.cli.main import main
from robocal.errors import CalibError, CalibTimeoutError
from robocal.formats import read_calibration as read_joint_map
from robocal.lerobot import MotorCalibration, normalize, read_calibration, unnormalize, write_calibration
from robocal.workflows.lerobot import CalibrateRequest, calibrate, configure, open_bus, restore, robot_spec

from .conftest import PREVIOUS

pytestmark = pytest.mark.timeout(60)

# restore's writes: torque (and Feetech Lock) off on every motor, then per motor its registers in bus order
TORQUE_WRITES = {"so101_follower": 12, "koch_leader": 6}
REGS_PER_MOTOR = {"so101_follower": 3, "koch_leader": 4}


def _new_cals(arm: SimArm) -> dict[str, MotorCalibration]:
    """A calibration that differs from PREVIOUS in every register (Koch leader elbow_flex inverted)."""
    return {
        m.name: MotorCalibration(m.motor_id, int(m.name in arm.spec.inverted), 7 + m.motor_id, 200, 3800)
        for m in arm.spec.motors
    }


class FaultyBus:
    """Delegates to a real SDK bus; runs ``fault`` just before the ``at``-th register write (1-based)."""

    def __init__(
        self, bus: Any, at: int, fault: Callable[[], None], *, heal: Callable[[], None] | None = None
    ):
        self._bus, self._at, self._fault, self._heal = bus, at, fault, heal
        self.writes: list[tuple[str, int, int]] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._bus, name)

    def write(self, register: str, motor_id: int, value: int) -> None:
        self.writes.append((register, motor_id, value))
        if len(self.writes) == self._at:
            self._fault()
        try:
            self._bus.write(register, motor_id, value)
        except CalibError:
            if self._heal is not None:  # the motor answers again (a transient drop-out)
                self._heal()
                self._heal = None
            raise


def _ctrl_c() -> None:
    raise KeyboardInterrupt


@pytest.fixture(params=["so101_follower", "koch_leader"])
def arm(request: pytest.FixtureRequest) -> Iterator[SimArm]:
    with SimArm(robot_spec(request.param), eeprom=PREVIOUS[request.param]) as a:
        yield a


def _midway(robot: str, motor_index: int) -> int:
    """Write number of the first register of the motor at ``motor_index`` (0-based) in restore's plan."""
    return TORQUE_WRITES[robot] + REGS_PER_MOTOR[robot] * motor_index + 1


# ----------------------------------------------------------------------------------- --use-file rollback
def test_restore_ctrl_c_midway_writes_the_snapshot_back(arm: SimArm) -> None:
    before = arm.eeprom()
    robot = arm.spec.name
    bus = FaultyBus(open_bus(arm.spec, arm.port), _midway(robot, 3) + 1, _ctrl_c)
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            restore(bus, arm.spec, _new_cals(arm))  # type: ignore[arg-type]
    finally:
        bus.close()
    assert info.value.args == ()  # every motor restored
    # motors 1..3 had been written with the new calibration before the Ctrl-C ...
    new = _new_cals(arm)
    assert ("Min_Position_Limit", 3, new["elbow_flex"].range_min) in bus.writes
    # ... and everything was written back
    assert arm.eeprom() == before


def test_restore_transient_silent_motor_is_rolled_back_exit_3(arm: SimArm) -> None:
    before = arm.eeprom()
    robot = arm.spec.name
    sim = arm.bus
    bus = FaultyBus(
        open_bus(arm.spec, arm.port),
        _midway(robot, 1),  # motor 2 is being written; motor 4 drops out and comes back after the error
        lambda: sim.silent_ids.add(4),
        heal=sim.silent_ids.clear,
    )
    try:
        with pytest.raises(CalibTimeoutError) as info:
            restore(bus, arm.spec, _new_cals(arm))  # type: ignore[arg-type]
    finally:
        bus.close()
    msg = str(info.value)
    assert "motor 4" in msg and msg.endswith("; previous EEPROM values written back")
    assert info.value.exit_code == 3
    assert arm.eeprom() == before


def test_restore_ctrl_c_with_a_dead_motor_names_it(arm: SimArm) -> None:
    before = arm.eeprom()
    robot = arm.spec.name
    sim = arm.bus

    def die_then_interrupt() -> None:
        sim.silent_ids.add(5)
        raise KeyboardInterrupt

    bus = FaultyBus(open_bus(arm.spec, arm.port), _midway(robot, 2), die_then_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            restore(bus, arm.spec, _new_cals(arm))  # type: ignore[arg-type]
    finally:
        bus.close()
    regs = "Homing_Offset, Min_Position_Limit, Max_Position_Limit" + (
        ", Drive_Mode" if robot == "koch_leader" else ""
    )
    assert str(info.value) == (  # exactly which motor and registers were not restored, and which motors were
        f"could not write the previous EEPROM back to motor 'wrist_roll' (id 5): {regs} "
        "(restored: shoulder_pan, shoulder_lift, elbow_flex, wrist_flex, gripper); "
        "wrist_roll (id 5) may still hold torque: switch the arm's power off before touching it"
    )  # the silent motor's torque-off could not be read back (issue 26)
    after = arm.eeprom()
    assert {n: v for n, v in after.items() if n != "wrist_roll"} == {
        n: v for n, v in before.items() if n != "wrist_roll"
    }


def _use_file(tmp_path: Path, arm: SimArm) -> list[str]:
    spec = arm.spec
    path = tmp_path / spec.kind / spec.device_name / "a.json"
    write_calibration(path, _new_cals(arm))
    return [
        "lerobot", "calibrate", "--robot", spec.name, "--port", arm.port, "--id", "a",
        "--calibration-dir", str(tmp_path), "--use-file",
    ]  # fmt: skip


def _patch_bus(monkeypatch: pytest.MonkeyPatch, make: Callable[[Any], FaultyBus]) -> None:
    real = wf.open_bus
    monkeypatch.setattr(wf_arms, "open_bus", lambda spec, port, **kw: make(real(spec, port, **kw)))


def test_use_file_ctrl_c_exit_130_eeprom_restored(
    tmp_path: Path, arm: SimArm, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    before = arm.eeprom()
    args = _use_file(tmp_path, arm)
    _patch_bus(monkeypatch, lambda b: FaultyBus(b, _midway(arm.spec.name, 4), _ctrl_c))
    assert main(args) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "restoring the previous EEPROM of every motor…",
        "error: interrupted: the motors' previous EEPROM was written back",
    ]
    assert arm.eeprom() == before


@pytest.mark.slow
def test_use_file_silent_motor_exit_3_one_error_line(
    tmp_path: Path, arm: SimArm, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    before = arm.eeprom()
    args = _use_file(tmp_path, arm)
    sim = arm.bus
    _patch_bus(
        monkeypatch,
        lambda b: FaultyBus(
            b, _midway(arm.spec.name, 2), lambda: sim.silent_ids.add(6), heal=sim.silent_ids.clear
        ),
    )
    assert main(args) == 3
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert (
        len(err) == 2
        and err[0] == "restoring the previous EEPROM of every motor…"
        and err[1].startswith(f"error: {arm.port}: motor 6: write ")
    )
    assert err[1].endswith("; previous EEPROM values written back")
    assert "wrote" not in cap.out
    assert arm.eeprom() == before
    # without a fault the same command writes the file and prints it
    monkeypatch.undo()
    assert main(args) == 0
    assert "wrote " in capsys.readouterr().out
    bus = open_bus(arm.spec, arm.port)
    try:
        assert wf.check(bus, arm.spec, _new_cals(arm)) == []
    finally:
        bus.close()


def test_calibrate_rollback_skips_a_dead_motor_and_restores_the_others(tmp_path: Path) -> None:
    from robocal.backends.sim.lerobot_arms import SimArmOperator

    with SimArm(robot_spec("so101_follower"), eeprom=PREVIOUS["so101_follower"]) as arm:
        before = arm.eeprom()
        sim = arm.bus
        # torque/Lock 12, Operating_Mode 6, reset 18 writes; then motor 2 dies at the first half-turn homing write
        bus = FaultyBus(open_bus(arm.spec, arm.port), 12 + 6 + 18 + 1, lambda: sim.silent_ids.add(2))
        try:
            with pytest.raises(CalibTimeoutError) as info:
                calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "c.json"), SimArmOperator(arm))  # type: ignore[arg-type]
        finally:
            bus.close()
        assert ("Homing_Offset", 1, 2100 - 2047) in bus.writes
        assert str(info.value).endswith(
            "; could not write the previous EEPROM back to motor 'shoulder_lift' (id 2): Homing_Offset, "
            "Min_Position_Limit, Max_Position_Limit, Operating_Mode, Phase, Lock (restored: shoulder_pan, elbow_flex, wrist_flex, wrist_roll, "
            "gripper); shoulder_lift (id 2) may still hold torque: switch the arm's power off before touching it"
        )
        after = arm.eeprom()
        assert {n: v for n, v in after.items() if n != "shoulder_lift"} == {
            n: v for n, v in before.items() if n != "shoulder_lift"
        }
        assert not (tmp_path / "c.json").exists()


def test_use_file_ctrl_c_with_a_dead_motor_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    with SimArm(robot_spec("koch_leader"), eeprom=PREVIOUS["koch_leader"]) as arm:
        args = _use_file(tmp_path, arm)
        sim = arm.bus

        def die_then_interrupt() -> None:
            sim.silent_ids.add(2)
            raise KeyboardInterrupt

        _patch_bus(monkeypatch, lambda b: FaultyBus(b, _midway("koch_leader", 3), die_then_interrupt))
        monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
        assert main(args) == 130
        kept = next((tmp_path / "state" / "robocal" / "left-changed").iterdir())
        assert capsys.readouterr().err.strip().splitlines() == [
            "restoring the previous EEPROM of every motor…",
            "error: interrupted: could not write the previous EEPROM back to motor 'shoulder_lift' (id 2): "
            "Homing_Offset, Min_Position_Limit, Max_Position_Limit, Drive_Mode (restored: shoulder_pan, "
            "elbow_flex, wrist_flex, wrist_roll, gripper); shoulder_lift (id 2) may still hold torque: switch the "
            f"arm's power off before touching it; the previous values are kept in {kept}; the next robocal "
            f"command on {arm.port} offers to write them back",
        ]


# ----------------------------------------------------------------------------- --use-degrees / --modes
def _calibrate(tmp_path: Path, robot: str) -> Path:
    args = ["lerobot", "calibrate", "--robot", robot, "--port", "sim", "--id", "a"]
    assert main([*args, "--calibration-dir", str(tmp_path)]) == 0
    spec = wf.robot_spec(robot)
    return tmp_path / spec.kind / spec.device_name / "a.json"


@pytest.mark.slow
def test_export_urdf_koch_use_degrees(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _calibrate(tmp_path, "koch_follower")
    out = tmp_path / "koch.yaml"
    base = ["lerobot", "export-urdf", "--robot", "koch_follower", "--file", str(path), "--out", str(out)]
    capsys.readouterr()
    # default unchanged: LeRobot's Koch uses RANGE_M100_100, so there is no angle to export
    assert main(base) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "error: koch_follower: no DEGREES motors to export"
    ]
    assert not out.exists()
    assert main([*base, "--use-degrees", "--sign", "elbow_flex=-1"]) == 1
    assert "warning: not exported (range modes, no angle): gripper" in capsys.readouterr().err
    jm = read_joint_map(out).calibration
    names = list(jm.joint_names)
    assert names == ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
    cals = read_calibration(path)
    present = np.array([[100, 1200, 2500, 3000, 4000], [2047] * 5])
    q = np.deg2rad(normalize(present, [cals[n] for n in names], "degrees", apply_drive_mode=False))
    np.testing.assert_allclose(jm.to_joint(present), np.array([1, 1, -1, 1, 1]) * q, atol=1e-12)


@pytest.mark.slow
def test_export_urdf_so_modes_and_no_use_degrees(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _calibrate(tmp_path, "so101_follower")
    out = tmp_path / "so.yaml"
    base = ["lerobot", "export-urdf", "--robot", "so101_follower", "--file", str(path), "--out", str(out)]
    capsys.readouterr()
    assert main([*base, "--no-use-degrees"]) == 2
    assert capsys.readouterr().err.strip() == "error: so101_follower: no DEGREES motors to export"
    # --modes wins over --no-use-degrees and the gripper default
    assert main([*base, "--no-use-degrees", "--modes", "gripper=degrees,wrist_roll=DEGREES"]) == 1
    assert capsys.readouterr().err.strip() == (
        "warning: not exported (range modes, no angle): shoulder_pan, shoulder_lift, elbow_flex, wrist_flex"
    )
    assert list(read_joint_map(out).calibration.joint_names) == ["wrist_roll", "gripper"]


@pytest.mark.parametrize(
    ("modes", "message"),
    [
        ("elbow=degrees", "error: --modes: unknown motor(s) elbow on a so101_follower"),
        ("gripper=deg", "error: --modes gripper=deg: expected one of degrees, range_0_100, range_m100_100"),
        ("gripper", "error: --modes 'gripper'"),
    ],
)
def test_bad_modes_are_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], modes: str, message: str
) -> None:
    for cmd in (["show", "--port", "sim"], ["export-urdf", "--out", str(tmp_path / "o.yaml")]):
        args = ["lerobot", *cmd, "--robot", "so101_follower", "--file", str(tmp_path / "missing.json")]
        assert main([*args, "--modes", modes]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(message)  # refused before the (missing) file is read
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_show_koch_use_degrees(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _calibrate(tmp_path, "koch_follower")
    cals = read_calibration(path)
    args = ["lerobot", "show", "--robot", "koch_follower", "--port", "sim", "--file", str(path)]
    for flag, modes in (
        ([], ["range_m100_100"] * 5 + ["range_0_100"]),
        (["--use-degrees"], ["degrees"] * 5 + ["range_0_100"]),
        (
            ["--modes", "wrist_flex=range_0_100"],
            ["range_m100_100"] * 3 + ["range_0_100", "range_m100_100", "range_0_100"],
        ),
    ):
        capsys.readouterr()
        assert main([*args, *flag]) == 0
        row = capsys.readouterr().out.strip().splitlines()[1].split()[1:]
        # the simulated arm rests at its mid pose, which the half-turn homing put at Present 2047
        expected = normalize([2047] * 6, list(cals.values()), modes, apply_drive_mode=False)
        assert row == [f"{v:.3f}" for v in expected], flag


# ------------------------------------------------------------------------------------------- configure
@pytest.mark.slow
def test_configure_cli_so_follower_and_leader(capsys: pytest.CaptureFixture[str]) -> None:
    for robot in ("so101_follower", "so101_leader"):
        with SimArm(robot_spec(robot)) as arm:
            arm.servo("shoulder_lift").set_reg("Phase", 0xFF)
            capsys.readouterr()
            assert main(["lerobot", "configure", "--robot", robot, "--port", arm.port]) == 0
            out = capsys.readouterr().out
            assert "Phase=239" in out and "Return_Delay_Time=0" in out
            g = arm.servo("gripper")
            assert arm.servo("shoulder_lift").get_reg("Phase") == 0b11101111
            assert g.get_reg("Acceleration") == 254 and g.get_reg("Operating_Mode") == 0
            follower = robot == "so101_follower"
            # LeRobot's SO leader configure() sets no PID and no gripper limits: the factory values stay
            assert (g.get_reg("P_Coefficient"), g.get_reg("D_Coefficient")) == (
                (16, 32) if follower else (32, 32)
            )
            assert g.get_reg("Max_Torque_Limit") == (500 if follower else 1000)
            assert ("P_Coefficient=16" in out) is follower
            assert all(arm.servo(m.name).get_reg("Torque_Enable") == 0 for m in arm.spec.motors)


def test_configure_koch_follower_pid() -> None:
    with SimArm(robot_spec("koch_follower")) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            written = configure(bus, arm.spec)
        finally:
            bus.close()
        e = arm.servo("elbow_flex")
        assert (e.get_reg("Position_P_Gain"), e.get_reg("Position_I_Gain"), e.get_reg("Position_D_Gain")) == (
            1500,
            0,
            600,
        )
        assert ("elbow_flex", "Position_D_Gain", 600) in written
        assert [arm.servo(n).get_reg("Operating_Mode") for n in ("wrist_flex", "gripper")] == [4, 5]
        assert arm.servo("gripper").get_reg("Torque_Enable") == 0


@pytest.mark.slow
def test_koch_leader_gripper_trigger(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robocal.backends.sim.lerobot_arms import SimArmOperator

    with SimArm(robot_spec("koch_leader")) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            cals = calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "lead.json"), SimArmOperator(arm)).calibration
        finally:
            bus.close()
        base = ["lerobot", "configure", "--robot", "koch_leader", "--port", arm.port]
        capsys.readouterr()
        # without a calibration the trigger is skipped with a warning; the gripper stays limp
        assert main(base) == 1
        assert "warning: gripper trigger not set: give --id or --file" in capsys.readouterr().err
        assert arm.servo("gripper").get_reg("Torque_Enable") == 0
        assert main([*base, "--file", str(tmp_path / "lead.json"), "--gripper-open-pos", "40"]) == 0
        assert "gripper trigger: torque on, held at 40 % open" in capsys.readouterr().out
        g = arm.servo("gripper")
        goal = int(unnormalize(40.0, cals["gripper"], "range_0_100", apply_drive_mode=False))
        assert goal == int(
            0.4 * (cals["gripper"].range_max - cals["gripper"].range_min) + cals["gripper"].range_min
        )
        assert (g.get_reg("Operating_Mode"), g.get_reg("Torque_Enable"), g.get_reg("Goal_Position")) == (
            5,
            1,
            goal,
        )
        # the gripper moved to the open position (Dynamixel: Present = Actual + Homing_Offset)
        assert g.actual_ticks == goal - cals["gripper"].homing_offset
        assert [arm.servo(n).get_reg("Torque_Enable") for n in arm.spec.motor_names[:-1]] == [0] * 5
        assert main([*base, "--file", str(tmp_path / "lead.json"), "--gripper-open-pos", "150"]) == 2
