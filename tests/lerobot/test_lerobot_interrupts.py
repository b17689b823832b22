"""``lerobot calibrate`` under a second Ctrl-C, an unwritable calibration folder and a failing final write.

Everything runs through the real SDKs against the simulated SO-101 / Koch arms on a pseudo-terminal; the second
Ctrl-C is a real SIGINT sent to this process while the rollback is writing the EEPROM back.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

import robocal.workflows.lerobot as wf
import robocal.workflows.lerobot.arms as wf_arms
from robocal.backends.sim import lerobot_arms
from robocal.backends.sim.lerobot_arms import SimArm, SimArmOperator
from robocal.cli import _common
from robocal.cli.main import main
from robocal.errors import UsageError
from robocal.lerobot import MotorCalibration
from robocal.workflows.lerobot import CalibrateRequest, calibrate, open_bus, robot_spec

from .conftest import PREVIOUS, calibrate_args

pytestmark = pytest.mark.timeout(60)



class CtrlCDuringRollback:
    """A real SDK bus that, once ``armed``, sends this process a SIGINT (a real Ctrl-C) before chosen writes.

    ``direct=True`` raises KeyboardInterrupt from inside the write instead (what a Ctrl-C looks like where no
    handler can be installed).
    """

    def __init__(self, bus: Any, at: set[int], *, direct: bool = False) -> None:
        self._bus, self._at, self._direct = bus, at, direct
        self.armed = False
        self.count = 0
        self.sent = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self._bus, name)

    def write(self, register: str, motor_id: int, value: int) -> None:
        if self.armed:
            self.count += 1
            if self.count in self._at:
                self.sent += 1
                if self._direct:
                    raise KeyboardInterrupt
                os.kill(os.getpid(), signal.SIGINT)
        self._bus.write(register, motor_id, value)


class FirstCtrlC(SimArmOperator):
    """The operator presses Ctrl-C at a sweep step and arms the bus for the second Ctrl-C."""

    def __init__(self, arm: SimArm, bus: CtrlCDuringRollback, at_step: int) -> None:
        super().__init__(arm)
        self._bus, self._at_step = bus, at_step

    def sweep_step(self) -> bool:
        if self.step >= self._at_step:
            self._bus.armed = True
            raise KeyboardInterrupt
        return super().sweep_step()


@pytest.mark.parametrize("robot", ["so101_follower", "koch_leader"])
@pytest.mark.parametrize(("at", "direct"), [({1}, False), ({2, 5, 9}, False), ({3, 4}, True)])
def test_second_ctrl_c_during_rollback_restores_every_register(
    tmp_path: Path, robot: str, at: set[int], direct: bool
) -> None:
    with SimArm(robot_spec(robot), eeprom=PREVIOUS[robot]) as arm:
        before = arm.eeprom()
        bus = CtrlCDuringRollback(open_bus(arm.spec, arm.port), at, direct=direct)
        try:
            with pytest.raises(KeyboardInterrupt) as info:
                calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "c.json"), FirstCtrlC(arm, bus, 6))  # type: ignore[arg-type]
        finally:
            bus.close()
        assert bus.sent == len(at)  # the second (and third...) Ctrl-C really came during the rollback
        assert info.value.args == ()  # nothing left unrestored
        assert arm.eeprom() == before  # Homing_Offset, limits (and Drive_Mode) equal the originals
        assert not (tmp_path / "c.json").exists()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is put back


def test_rollback_reports_that_it_is_restoring_and_each_deferred_ctrl_c(tmp_path: Path) -> None:
    with SimArm(robot_spec("so101_follower"), eeprom=PREVIOUS["so101_follower"]) as arm:
        before = arm.eeprom()
        bus = CtrlCDuringRollback(open_bus(arm.spec, arm.port), {2, 7})
        status: list[str] = []
        try:
            with pytest.raises(KeyboardInterrupt):
                calibrate(
                    bus,
                    CalibrateRequest(
                        arm.spec,
                        path=tmp_path / "c.json",
                    ),
                    FirstCtrlC(arm, bus, 3),
                    on_status=status.append,
                )  # type: ignore[arg-type]
        finally:
            bus.close()
        assert status == [
            "restoring the previous EEPROM of every motor…",
            "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
            "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
        ]
        assert arm.eeprom() == before


def test_rollback_names_exactly_the_motors_and_registers_not_restored(tmp_path: Path) -> None:
    with SimArm(robot_spec("so101_follower"), eeprom=PREVIOUS["so101_follower"]) as arm:
        before = arm.eeprom()
        sim = arm.bus

        class DiesDuringRollback(CtrlCDuringRollback):
            def write(self, register: str, motor_id: int, value: int) -> None:
                if self.armed:
                    self.count += 1
                    if self.count == 2:  # shoulder_pan's Min_Position_Limit: the motor drops off the bus
                        sim.silent_ids.add(1)
                self._bus.write(register, motor_id, value)

        bus = DiesDuringRollback(open_bus(arm.spec, arm.port), set())
        try:
            with pytest.raises(KeyboardInterrupt) as info:
                calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "c.json"), FirstCtrlC(arm, bus, 6))  # type: ignore[arg-type]
        finally:
            bus.close()
        assert str(info.value) == (
            "could not write the previous EEPROM back to motor 'shoulder_pan' (id 1): Min_Position_Limit, "
            "Max_Position_Limit, Operating_Mode, Phase, Lock (restored: shoulder_lift, elbow_flex, wrist_flex, wrist_roll, gripper)"
        )
        sim.silent_ids.clear()
        after = arm.eeprom()
        assert after["shoulder_pan"]["Homing_Offset"] == before["shoulder_pan"]["Homing_Offset"]
        assert after["shoulder_pan"]["Min_Position_Limit"] != before["shoulder_pan"]["Min_Position_Limit"]
        assert {n: v for n, v in after.items() if n != "shoulder_pan"} == {
            n: v for n, v in before.items() if n != "shoulder_pan"
        }


# ------------------------------------------------------------------------------------------- CLI
def _args(tmp: Path, robot: str = "so101_follower") -> list[str]:
    return calibrate_args(tmp, robot=robot, robot_id="a")


def _interrupting_operator(monkeypatch: pytest.MonkeyPatch, step: int) -> None:
    original = lerobot_arms.SimArmOperator.__init__

    def init(self: SimArmOperator, arm: SimArm, **kw: object) -> None:
        original(self, arm, interrupt_at_step=step)

    monkeypatch.setattr(lerobot_arms.SimArmOperator, "__init__", init)


def test_cli_second_ctrl_c_shows_restoring_and_restores(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _interrupting_operator(monkeypatch, 6)
    real = wf.open_bus
    made: list[CtrlCDuringRollback] = []

    def make(spec: Any, port: str, **kw: Any) -> CtrlCDuringRollback:
        b = CtrlCDuringRollback(real(spec, port, **kw), {1, 3}, direct=False)
        made.append(b)
        return b

    monkeypatch.setattr(wf_arms, "open_bus", make)
    arms: list[SimArm] = []
    orig_enter = SimArm.__enter__

    def enter(self: SimArm) -> SimArm:
        arms.append(self)
        return orig_enter(self)

    monkeypatch.setattr(SimArm, "__enter__", enter)
    original_sweep = SimArmOperator.sweep_step

    def sweep_step(self: SimArmOperator) -> bool:
        if self.step >= 6:
            made[0].armed = True
        return original_sweep(self)

    monkeypatch.setattr(SimArmOperator, "sweep_step", sweep_step)
    assert main(_args(tmp_path)) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert made[0].sent == 2
    assert err[-4:] == [
        "restoring the previous EEPROM of every motor…",
        "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
        "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
        "error: interrupted: every motor's EEPROM was restored and no file was written",
    ]


def test_cli_no_stale_summary_after_the_error_line_on_a_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    # a terminal: the live table is used (rich writes to the same stderr the error line goes to)
    monkeypatch.setattr(_common, "err_console", Console(file=sys.stderr, force_terminal=True, width=100))
    _interrupting_operator(monkeypatch, 14)
    assert main(_args(tmp_path)) == 130
    err = capsys.readouterr().err
    assert err.rstrip().endswith(
        "error: interrupted: every motor's EEPROM was restored and no file was written"
    )
    assert "reading 14" not in err.split("error: interrupted")[1]


# ----------------------------------------------------------------------------- unwritable output
@pytest.fixture
def readonly_dir(tmp_path: Path) -> Iterator[Path]:
    """A read-only file system (a tmpfs mounted ro): refused even for root, unlike chmod."""
    mnt = tmp_path / "ro"
    mnt.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(mnt)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip("cannot mount a read-only tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=False)


def test_calibrate_into_read_only_folder_fails_before_any_motor_write(readonly_dir: Path) -> None:
    with SimArm(robot_spec("so101_follower"), eeprom=PREVIOUS["so101_follower"]) as arm:
        before = arm.eeprom()
        bus = CtrlCDuringRollback(open_bus(arm.spec, arm.port), set())
        bus.armed = True
        op = SimArmOperator(arm)
        try:
            with pytest.raises(UsageError, match="cannot create folders in"):
                calibrate(
                    bus,
                    CalibrateRequest(
                        arm.spec,
                        path=readonly_dir / "robots" / "so_follower" / "a.json",
                    ),
                    op,
                )  # type: ignore[arg-type]
        finally:
            bus.close()
        assert bus.count == 0 and op.prompts == []  # no motor touched, no prompt shown
        assert arm.eeprom() == before


def test_cli_calibrate_read_only_folder_one_error_line_exit_2(
    readonly_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(_args(readonly_dir)) == 2
    cap = capsys.readouterr()
    assert cap.err.strip().splitlines() == [
        f"error: cannot write {readonly_dir}/robots/so_follower/a.json: cannot create folders in {readonly_dir} "
        "(permission denied)"
    ]
    assert "reading" not in cap.err


def test_calibrate_final_write_failure_prints_the_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The folder passes the preflight, then the disk fills up: the JSON is printed and the EEPROM restored."""

    real_replace = os.replace

    def full(src: Any, dst: Any) -> None:
        if str(dst).endswith("a.json"):
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", full)
    assert main(_args(tmp_path)) == 2
    cap = capsys.readouterr()
    path = tmp_path / "robots" / "so_follower" / "a.json"
    err = cap.err.strip().splitlines()
    assert err[-1] == (
        f"error: cannot write {path}: No space left on device; the file and its backups are unchanged; "
        "previous EEPROM values written back; "
        "the calibration is printed above as LeRobot JSON: save it and write it to the motors with "
        "`robocal lerobot calibrate --use-file`"
    )
    cals = {n: MotorCalibration(**v) for n, v in json.loads(cap.out).items()}
    assert cals["shoulder_pan"] == MotorCalibration(1, 0, 53, 847, 3247)  # what a good run writes
    assert not path.exists()


def test_ctrl_c_while_the_restoring_line_is_shown_is_deferred(tmp_path: Path) -> None:
    with SimArm(robot_spec("so101_follower"), eeprom=PREVIOUS["so101_follower"]) as arm:
        before = arm.eeprom()
        bus = CtrlCDuringRollback(open_bus(arm.spec, arm.port), set())
        status: list[str] = []

        def show(line: str) -> None:
            status.append(line)
            if len(status) == 1:  # the person presses Ctrl-C again just as "restoring…" appears
                os.kill(os.getpid(), signal.SIGINT)

        try:
            with pytest.raises(KeyboardInterrupt) as info:
                calibrate(
                    bus,
                    CalibrateRequest(
                        arm.spec,
                        path=tmp_path / "c.json",
                    ),
                    FirstCtrlC(arm, bus, 3),
                    on_status=show,
                )  # type: ignore[arg-type]
        finally:
            bus.close()
        assert info.value.args == ()
        assert status == [
            "restoring the previous EEPROM of every motor…",
            "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
        ]
        assert arm.eeprom() == before


def test_cli_read_only_folder_is_refused_before_the_port_is_opened(
    readonly_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [
        "lerobot",
        "calibrate",
        "--robot",
        "koch_follower",
        "--port",
        "/dev/robocal-no-such-port",
        "--id",
        "a",
    ]
    assert main([*args, "--calibration-dir", str(readonly_dir)]) == 2  # not 3 (the port was never tried)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"error: cannot write {readonly_dir}/robots/koch_follower/a.json"
    )
