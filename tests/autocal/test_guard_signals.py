"""Issue 26: ``lerobot calibrate --auto`` killed by a signal mid-motion ends limp and restored.

robocal runs as a child process against a simulated SO-101 with physics in another process (on a pseudo-terminal,
on the wall clock); the signal is sent when robocal says a joint started its search (the arm is moving). The
oracle is the simulated arm: after robocal exited, every servo's Torque_Enable is 0 and every register robocal
may change (EEPROM and RAM) holds its value from before the run. On main before the guard, SIGTERM and SIGHUP
killed robocal on the spot (exit -15 / -1, torque on, Homing_Offset changed).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .guardlib import HANG_GUARD_S, SIGNAL_EXIT, ArmHost, Robocal, auto_args, kept_registers, torque_on

pytestmark = [pytest.mark.timeout(600)]


@pytest.fixture
def state_home(tmp_path: Path) -> Path:
    return tmp_path / "state"


def _run(arm: ArmHost, tmp_path: Path, state_home: Path, joints: str | None = None) -> Robocal:
    return Robocal(
        auto_args(arm.port, tmp_path, joints=joints), tmp_path, env={"XDG_STATE_HOME": str(state_home)}
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "nth"),
    [
        (signal.SIGTERM, 1),  # the first joint's search (shoulder_lift)
        (signal.SIGHUP, 2),  # a closed terminal during the second joint's search
        (signal.SIGINT, 1),
        (signal.SIGQUIT, 2),
    ],
)
def test_signal_mid_motion_leaves_every_motor_limp_and_every_register_as_before(
    arm: ArmHost, tmp_path: Path, state_home: Path, signum: int, nth: int
) -> None:
    before = arm.state()
    run = _run(arm, tmp_path, state_home, joints="shoulder_lift,gripper")
    run.wait_for("searching its stops", nth)
    run.signal(signum)
    code = run.finish()
    after = arm.state()
    assert torque_on(after) == []
    assert kept_registers(after, "feetech") == kept_registers(before, "feetech")
    assert code == SIGNAL_EXIT[signum], run.stderr
    errors = [line for line in run.err_lines if line.startswith("error:")]
    said = "interrupted" if signum == signal.SIGINT else f"interrupted by {signal.Signals(signum).name}"
    assert errors == [
        f"error: {said}: every motor is limp, every register the search changed was written back; "
        "no file was written"
    ], run.stderr
    assert "Traceback" not in run.stderr
    assert not (tmp_path / "cal" / "robots" / "so_follower" / "g.json").exists()
    assert not (state_home / "robocal" / "left-changed").exists() or not any(
        (state_home / "robocal" / "left-changed").iterdir()
    )  # everything was restored: no snapshot is kept


@pytest.mark.slow
def test_a_second_signal_during_the_restore_does_not_cut_it_short(
    arm: ArmHost, tmp_path: Path, state_home: Path
) -> None:
    before = arm.state()
    run = _run(arm, tmp_path, state_home, joints="shoulder_lift")
    run.wait_for("searching its stops")
    run.signal(signal.SIGTERM)
    run.wait_for("restoring the previous EEPROM")
    run.signal(signal.SIGINT)
    run.signal(signal.SIGHUP)
    code = run.finish()
    after = arm.state()
    assert torque_on(after) == []
    assert kept_registers(after, "feetech") == kept_registers(before, "feetech")
    assert code == 143, run.stderr  # the first signal's code
    assert "Traceback" not in run.stderr


@pytest.mark.slow
def test_a_vanished_device_exits_3_naming_the_motors_that_may_hold_torque(
    arm: ArmHost, tmp_path: Path, state_home: Path
) -> None:
    """The USB cable pulled mid-search (the pseudo-terminal closes): exit 3, never 70, one line that says which
    motors may still hold torque and what to do; the snapshot of the registers stays in the state folder."""
    before = arm.state()
    run = _run(arm, tmp_path, state_home, joints="shoulder_lift")
    run.wait_for("searching its stops")
    deadline = time.monotonic() + HANG_GUARD_S
    while "shoulder_lift" not in torque_on(arm.state()):  # pushing: the cable goes now
        assert time.monotonic() < deadline and run.proc.poll() is None, run.stderr
    arm.vanish()
    code = run.finish()
    after = arm.state()  # the simulated servos as the cable left them
    assert code == 3, run.stderr
    assert "Traceback" not in run.stderr and "internal error" not in run.stderr
    errors = [line for line in run.err_lines if line.startswith("error:")]
    assert len(errors) == 1, run.stderr
    line = errors[0]
    on = torque_on(after)
    assert on  # the search was pushing when the cable went: nothing could turn it off
    for name in on:  # every motor that still holds torque is named as one that may
        assert f"{name} (id " in line.split("may still hold torque")[0]
    assert "switch the arm's power off" in line
    kept = list((state_home / "robocal" / "left-changed").iterdir())
    assert len(kept) == 1 and str(kept[0]) in line
    doc = json.loads(kept[0].read_text())
    assert doc["port"] == arm.port and doc["command"] == "lerobot calibrate --auto"
    for motor, regs in doc["registers"].items():  # the values from before the run, as the servos held them
        assert regs == {r: before[motor][r] for r in regs}
    assert "Homing_Offset" in doc["registers"]["shoulder_lift"]


class _Restored:
    def __init__(self, snapshot: dict[str, dict[str, int]]) -> None:
        self.restored = tuple(snapshot)
        self.not_restored: dict[str, tuple[str, ...]] = {}

    def summary(self) -> str:
        return f"restored {', '.join(self.restored)}"


def test_the_guard_in_process_makes_limp_before_it_restores_and_exits_with_the_signal() -> None:
    """The quick representative: SIGTERM inside the guard → limp, then the snapshot back, exit code 143."""
    import os

    from robocal.errors import SignalInterrupt
    from robocal.workflows.motion.guard import MotionGuard

    calls: list[str] = []
    seen: list[dict[str, dict[str, int]]] = []

    def limp() -> tuple[str, ...]:
        calls.append("limp")
        return ()

    def restore(snapshot: dict[str, dict[str, int]]) -> _Restored:
        calls.append("restore")
        seen.append({m: dict(r) for m, r in snapshot.items()})
        return _Restored({m: dict(r) for m, r in snapshot.items()})

    before = signal.getsignal(signal.SIGTERM)
    with MotionGuard(limp=limp, restore=restore):  # a clean run: nothing made limp, nothing restored
        pass
    assert calls == []
    with pytest.raises(SignalInterrupt) as caught, MotionGuard(limp=limp, restore=restore) as guard:
        guard.snapshot({"shoulder_lift": {"Homing_Offset": 17}})
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # never reached: the handler raises at once in the main thread
    assert caught.value.exit_code == 143
    assert calls == ["limp", "restore"]
    assert seen == [{"shoulder_lift": {"Homing_Offset": 17}}]
    assert signal.getsignal(signal.SIGTERM) is before


@pytest.mark.slow
def test_two_calibrations_side_by_side_under_load_each_ctrl_c_ends_limp_and_restored(tmp_path: Path) -> None:
    """Two arms, two ``calibrate --auto`` at once, a busy sibling process on the same cores, one Ctrl-C each
    while its arm moves: both arms end limp with every register as before (issue 26's "side by side" case)."""
    hosts = [ArmHost("so101_follower", seed) for seed in (1, 2)]
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        befores = [h.state() for h in hosts]
        runs = [
            Robocal(
                auto_args(h.port, tmp_path / f"run{i}", joints="shoulder_lift,elbow_flex"),
                tmp_path,
                env={"XDG_STATE_HOME": str(tmp_path / f"state{i}")},
            )
            for i, h in enumerate(hosts)
        ]
        for run in runs:
            run.wait_for("searching its stops")
        for run in runs:
            run.signal(signal.SIGINT)
        codes = [run.finish() for run in runs]
        for host, before, run, code in zip(hosts, befores, runs, codes, strict=True):
            after = host.state()
            assert torque_on(after) == [], run.stderr
            assert kept_registers(after, "feetech") == kept_registers(before, "feetech")
            assert code == 130, run.stderr
            assert "Traceback" not in run.stderr
    finally:
        busy.kill()
        busy.wait()
        for h in hosts:
            h.close()


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_koch_signal_mid_motion_leaves_every_motor_limp_and_every_register_as_before(
    tmp_path: Path, signum: int
) -> None:
    """The same on a Koch follower (Dynamixel protocol 2: current-based position mode, Goal_Current, gains)."""
    host = ArmHost("koch_follower")
    try:
        before = host.state()
        run = Robocal(
            auto_args(host.port, tmp_path, robot="koch_follower", joints="gripper"),
            tmp_path,
            env={"XDG_STATE_HOME": str(tmp_path / "state")},
        )
        run.wait_for("searching its stops")
        run.signal(signum)
        code = run.finish()
        after = host.state()
        assert torque_on(after) == []
        assert kept_registers(after, "dynamixel") == kept_registers(before, "dynamixel")
        assert code == SIGNAL_EXIT[signum], run.stderr
        assert "Traceback" not in run.stderr
    finally:
        host.close()
