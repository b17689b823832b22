"""Helpers of the motion-guard tests: a simulated arm in its own process, ``robocal`` as a child process, signals,
and the count of what a bus in this process was asked to do (:func:`count_bus_calls`).

The oracle of these tests is the simulated arm's own state (:meth:`ArmHost.state`: every register of every servo,
read in the simulator's process after robocal has exited), never what robocal printed.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robocal.backends import REPLY_TIMEOUT_ENV

HOST = Path(__file__).with_name("arm_host.py")
HANG_GUARD_S = 120.0
"""Bound of every wait (a hang guard on a loaded machine, not a timing assumption)."""

KEPT = {
    "feetech": (
        "Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Operating_Mode", "Torque_Limit", "Lock",
        "Goal_Velocity", "Acceleration",
    ),
    "dynamixel": (
        "Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode", "Operating_Mode",
        "Goal_Current", "Goal_PWM", "Profile_Velocity", "Profile_Acceleration",
    ),
}  # fmt: skip
"""The registers a guarded run must leave as they were (EEPROM and RAM), per vendor."""


def count_bus_calls(bus: Any) -> list[tuple[str, int]]:
    """Record every operation of a LeRobot servo bus (what, retries allowed) from now on, in the returned list."""
    calls: list[tuple[str, int]] = []
    real: Callable[..., Any] = bus._call

    def counted(what: str, motor_id: int | None, register: str, fn: Callable[[], Any]) -> Any:
        calls.append((what, bus.retries))
        return real(what, motor_id, register, fn)

    bus._call = counted
    return calls


class ArmHost:
    """``tests/autocal/arm_host.py ROBOT SEED`` running: a simulated arm with physics on a pseudo-terminal."""

    def __init__(self, robot: str, seed: int = 1) -> None:
        self.robot = robot
        self.proc = subprocess.Popen(
            [sys.executable, str(HOST), robot, str(seed)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        line = self._line()
        assert line.startswith("port: "), line
        self.port = line.removeprefix("port: ").strip()

    def _line(self) -> str:
        assert self.proc.stdout is not None
        box: queue.Queue[str] = queue.Queue()
        threading.Thread(target=lambda: box.put(self.proc.stdout.readline()), daemon=True).start()  # type: ignore[union-attr]
        try:
            line = box.get(timeout=HANG_GUARD_S)
        except queue.Empty:
            self.proc.kill()
            raise AssertionError("the simulated arm did not answer within the hang guard") from None
        if not line:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise AssertionError(f"the simulated arm exited ({self.proc.wait()}): {err}")
        return line

    def _ask(self, cmd: str) -> str:
        assert self.proc.stdin is not None
        self.proc.stdin.write(cmd + "\n")
        self.proc.stdin.flush()
        return self._line()

    def state(self) -> dict[str, dict[str, int]]:
        """Motor name → register → value, as the simulated servos hold them now."""
        return dict(json.loads(self._ask("state")))

    def vanish(self) -> None:
        """The device disappears (the pseudo-terminal closes, as when the USB cable is pulled)."""
        assert self._ask("vanish").strip() == "ok"

    def close(self) -> None:
        if self.proc.poll() is None:
            with contextlib.suppress(AssertionError, OSError):
                self._ask("quit")
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def kept_registers(state: dict[str, dict[str, int]], vendor: str) -> dict[str, dict[str, int]]:
    """The registers of :data:`KEPT` (those a motor has) of every motor."""
    return {m: {r: v for r, v in regs.items() if r in KEPT[vendor]} for m, regs in state.items()}


def torque_on(state: dict[str, dict[str, int]]) -> list[str]:
    """The motors whose Torque_Enable is not 0."""
    return [m for m, regs in state.items() if regs.get("Torque_Enable", 0) != 0]


class Robocal:
    """``python -m robocal ARGS`` in a child process; standard error is read line by line as it comes."""

    def __init__(self, args: list[str], cwd: Path, env: dict[str, str] | None = None) -> None:
        full_env = dict(os.environ, **{REPLY_TIMEOUT_ENV: "2000", "COLUMNS": "200"}, **(env or {}))
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "robocal", *args],
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=full_env,
            start_new_session=True,  # a signal reaches robocal only, as `kill PID` would
        )
        self.err_lines: list[str] = []
        self.out = ""
        self._new: queue.Queue[str] = queue.Queue()
        assert self.proc.stderr is not None and self.proc.stdout is not None
        stderr, stdout = self.proc.stderr, self.proc.stdout

        def pump_err() -> None:
            for line in iter(stderr.readline, ""):
                self.err_lines.append(line.rstrip("\n"))
                self._new.put(line)
            self._new.put("")

        def pump_out() -> None:
            self.out = stdout.read()

        threading.Thread(target=pump_err, daemon=True).start()
        self._out_thread = threading.Thread(target=pump_out, daemon=True)
        self._out_thread.start()

    def wait_for(self, text: str, nth: int = 1) -> None:
        """Block until the ``nth`` standard-error line containing ``text`` appeared (bounded by the hang guard)."""
        deadline = time.monotonic() + HANG_GUARD_S
        while sum(text in line for line in self.err_lines) < nth:
            try:
                line = self._new.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.proc.kill()
                raise AssertionError(f"no {text!r} within the hang guard: {self.err_lines}") from None
            if not line:
                raise AssertionError(f"robocal exited ({self.proc.wait()}) before {text!r}: {self.err_lines}")

    def signal(self, signum: int) -> None:
        self.proc.send_signal(signum)

    def finish(self) -> int:
        """Wait for the exit (hang guard); returns the exit code (negative: killed by that signal)."""
        try:
            code = self.proc.wait(timeout=HANG_GUARD_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise AssertionError(f"robocal did not end within the hang guard: {self.err_lines}") from None
        self._out_thread.join(timeout=HANG_GUARD_S)
        deadline = time.monotonic() + HANG_GUARD_S
        while time.monotonic() < deadline:  # the stderr pump has seen the end
            try:
                if self._new.get(timeout=1.0) == "":
                    break
            except queue.Empty:
                continue
        return code

    @property
    def stderr(self) -> str:
        return "\n".join(self.err_lines)


def auto_args(port: str, tmp: Path, *, robot: str = "so101_follower", joints: str | None = None) -> list[str]:
    """``lerobot calibrate --auto --yes`` on ``port``, the calibration folder under ``tmp``."""
    args = ["lerobot", "calibrate", "--auto", "--yes", "--robot", robot, "--port", port, "--id", "g",
            "--calibration-dir", str(tmp / "cal")]  # fmt: skip
    if joints is not None:
        args += ["--joints", joints]
    return args


SIGNAL_EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129, signal.SIGQUIT: 131}
