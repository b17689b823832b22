"""Fault injection against the standalone simulators (issue 26 item 5).

One trial: start ``robocal sim ROBOT`` (a separate process: a pseudo-terminal and a control socket), record every
motor's registers through the control socket, run ``robocal lerobot calibrate --auto`` against the port, wait for
the chosen phase (seen in the simulator's state or robocal's output), inject the fault at a random instant of it,
then judge by the simulator's own state, never by robocal's output alone:

* every motor limp (torque off) once robocal is gone, unless the fault left no host to act (SIGKILL, the device
  gone) on a family without a host-loss watchdog (Feetech has none: that is reported as ``energised``);
* the registers (``Homing_Offset``, ``Min_Position_Limit``, ``Max_Position_Limit``) byte-equal to before, unless
  the run finished (exit 0: the new calibration is in the motors and in the file);
* the calibration file old (absent here) or new and whole JSON;
* the exit code the fault calls for (SIGINT 130, SIGTERM 143, SIGHUP 129, a lost or frozen device 3; a stall of
  robocal's CPU 0 or 3) and never 70 or a traceback.

``python benchmarks/run.py faults --trials N`` runs the soak (``soak.py``, ``benchmarks/bench_faults.py``);
``tests/faults/test_fault_injection.py`` runs a seeded few.
"""

from __future__ import annotations

import json
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if __package__:
    from .proc_state import SIGNAL_STATES, note_signal_state
else:  # run as a script: the Lite's trial in its own network namespace (_lite_in_netns)
    from proc_state import SIGNAL_STATES, note_signal_state  # type: ignore[no-redef]

SRC = Path(__file__).resolve().parents[2] / "src"

FAULTS = (
    "sigint",
    "double-sigint",
    "sigterm",
    "sighup",
    "sigkill",
    "cpu-stall",
    "frozen-device",
    "lost-device",
)
PHASES = ("start-up", "search", "contact", "restore", "file-write")
ROBOTS = ("so101_follower", "koch_follower", "lite", "openarm", "openarm-zero")  # openarm*: damiao_harness.py
LITE_JOINT = "left_wrist_roll"  # the Lite's trials search this joint (the arms': the gripper)
NETNS_SETUP = "ip link set lo up && ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo"
EXPECTED_EXIT = {"sigint": 130, "double-sigint": 130, "sigterm": 143, "sighup": 129, "frozen-device": 3,
                 "lost-device": 3}  # fmt: skip
REGISTERS = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit")
# Feetech STS3215 has no host-loss watchdog; Dynamixel has its Bus Watchdog, Robstride its CAN timeout
NO_WATCHDOG = {"so101_follower"}
# the Lite's simulator has no "unplug" (a frozen device is the nearest: the process stopped)
LITE_FAULTS = tuple(f for f in FAULTS if f != "lost-device")
HOST_LOST = ("sigkill", "lost-device", "frozen-device")  # the host cannot act: only a watchdog can
HANG_GUARD_S = 600.0


def _default_signals() -> None:
    """In each child: SIGINT, SIGTERM, SIGHUP as a fresh terminal has them.

    A harness started in the background (``cmd &`` in a script) inherits SIGINT ignored, and so would robocal:
    it keeps a signal its parent ignores (``nohup``), so every SIGINT trial would test nothing. The signal mask is
    emptied too: a child inherits the mask of the thread that forked it, and a harness thread started with signals
    blocked (as robocal's own helper threads are) would hand robocal a SIGINT that stays pending for good.
    """
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_SETMASK, set())


SIGNAL_FAULTS = ("sigint", "double-sigint", "sigterm", "sighup")


@dataclass(frozen=True)
class TrialResult:
    """One trial's fault, phase and verdict.

    Attributes:
        robot: The simulated robot.
        fault: What was injected.
        phase: The phase it was aimed at.
        injected: False when the run ended before the phase came (nothing injected: not judged).
        exit_code: robocal's exit code (negative: killed by that signal).
        failures: What the oracle found wrong (empty: passed).
        stderr_tail: robocal's last lines on standard error (for the report; not judged).
    """

    robot: str
    fault: str
    phase: str
    injected: bool
    exit_code: int
    failures: tuple[str, ...] = ()
    stderr_tail: str = ""

    @property
    def finished_despite(self) -> bool:
        """A signal was sent while robocal ran, and it finished anyway (exit 0)."""
        return self.injected and self.fault in SIGNAL_FAULTS and self.exit_code == 0

    @property
    def verdict(self) -> str:
        """``pass``, ``fail`` or ``not-reached``."""
        if not self.injected:
            return "not-reached"
        return "fail" if self.failures else "pass"


class _Sim:
    """``robocal sim ROBOT`` in its own process; ``state()`` asks its control socket."""

    def __init__(self, robot: str, folder: Path, argv: tuple[str, ...] = ("--no-view",)) -> None:
        env = dict(os.environ, PYTHONPATH=str(SRC))
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "robocal", "sim", robot, *argv],
            cwd=folder, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, preexec_fn=_default_signals,
        )  # fmt: skip
        assert self.proc.stdout is not None
        self.info: dict[str, str] = {}
        deadline = time.monotonic() + 120  # hang guard: start-up on a loaded machine
        while "control" not in self.info:
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError(
                    f"robocal sim {robot} exited early: {self.proc.stderr.read() if self.proc.stderr else ''}"
                )
            key, sep, value = line.rstrip("\n").partition(": ")
            if sep:
                self.info[key] = value
            if time.monotonic() > deadline:
                raise RuntimeError(f"robocal sim {robot}: no control line in 120 s")

    def state(self) -> list[dict[str, Any]]:
        from robocal.backends.sim.control import SimControl

        with SimControl(self.info["control"], timeout_s=60) as ctl:
            return list(ctl.request("state")["joints"])

    def detach_all(self) -> None:
        """Every motor stops answering (the cable pulled); the simulated motors keep their state."""
        from robocal.backends.sim.control import SimControl

        with SimControl(self.info["control"], timeout_s=60) as ctl:
            ctl.request("attach", joints=[])

    def stop(self) -> None:
        if self.proc.poll() is None:
            with _suppress():
                os.kill(self.proc.pid, signal.SIGCONT)
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.communicate()


class _suppress:  # noqa: N801 - a tiny contextlib.suppress(OSError) without the import cost in a signal path
    def __enter__(self) -> None:
        return None

    def __exit__(self, et: object, ev: object, tb: object) -> bool:
        return et is not None and isinstance(ev, OSError)


def _registers(state: list[dict[str, Any]]) -> dict[str, tuple[int, ...]]:
    """The registers robocal may change, per motor (the Lite's simulator shows none: an empty tuple)."""
    return {j["name"]: tuple(int(j[r]) for r in REGISTERS if r in j) for j in state}


def _torque_on(state: list[dict[str, Any]]) -> list[str]:
    return [j["name"] for j in state if j.get("torque") or j.get("enabled")]


WATCHDOG_S = 0.5  # the time robocal arms the Dynamixel Bus_Watchdog and the Robstride canTimeout with
WATCHDOG_SLACK_S = 0.05  # the simulators' trip lands on the due time (simulated or checked every 20 ms)


def _stopped_by_watchdog(joint: dict[str, Any]) -> bool:
    """A Dynamixel's Bus_Watchdog tripped within its time after the last packet it heard (it holds, torque on)."""
    trips = joint.get("watchdog_trips") or []
    return bool(trips) and all(at - rx <= WATCHDOG_S + WATCHDOG_SLACK_S for rx, at in trips)


def _at_a_stop(state: list[dict[str, Any]], margin: float = 60.0) -> bool:
    return any(
        (j.get("torque") or j.get("enabled"))
        and min(abs(j["position"] - j["low"]), abs(j["position"] - j["high"]))
        < (margin if "Homing_Offset" in j else 0.05)  # ticks; rad for the Lite
        for j in state
    )


@dataclass
class _Run:
    proc: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)
    out: list[str] = field(default_factory=list)
    readers: list[threading.Thread] = field(default_factory=list)

    def start_reader(self) -> None:
        def read(stream: Any, into: list[str]) -> None:
            for line in iter(stream.readline, ""):
                into.append(line)

        self.readers[:] = [threading.Thread(target=read, args=(self.proc.stderr, self.lines), daemon=True),
                        threading.Thread(target=read, args=(self.proc.stdout, self.out), daemon=True)]  # fmt: skip
        for t in self.readers:
            t.start()

    def drained(self, timeout_s: float = 30.0) -> None:
        """Wait until robocal's output has been read to its end (the process has exited; bounded)."""
        for t in self.readers:
            t.join(timeout_s)

    def count(self, text: str) -> int:
        return sum(text in ln for ln in list(self.lines))


def run_trial(
    robot: str, fault: str, phase: str, rng: random.Random, joints: str | None = None
) -> TrialResult:
    """Run one trial in a fresh folder with a fresh simulator; see the module docstring for the oracle.

    The Lite's CAN is python-can's ``udp_multicast`` shared by the simulator and robocal: the trial runs in a
    private network namespace (``unshare --net``, as ``tests/sim/test_sim_lite_cli.py``), in a child process.
    """
    if robot in ("openarm", "openarm-zero"):  # sweep --auto [--write-zero] over socketcand (damiao_harness.py)
        from .damiao_harness import run_openarm_trial

        return run_openarm_trial(fault, phase, rng, joints, write_zero=robot == "openarm-zero")
    if robot == "lite" and os.environ.get("ROBOCAL_FAULT_NETNS") != "1":
        return _lite_in_netns(fault, phase, rng.randrange(2**32), joints)
    with tempfile.TemporaryDirectory(prefix="robocal-fault-") as tmp:
        folder = Path(tmp)
        sim = _Sim(robot, folder)
        try:
            return _trial(sim, folder, robot, fault, phase, rng, joints)
        finally:
            sim.stop()


def _trial(
    sim: _Sim, folder: Path, robot: str, fault: str, phase: str, rng: random.Random, joints: str | None
) -> TrialResult:
    before = _registers(sim.state())
    if robot == "lite":
        from robocal.backends.sim.lite import lite_urdf_text

        (folder / "cal").mkdir()
        (folder / "lite.urdf").write_text(lite_urdf_text())
        joints = joints or LITE_JOINT
        args = ["sweep", "--auto", "--urdf", "lite.urdf", "--robot", "bhl_arms", "--source", sim.info["source"],
                "--out", str(folder / "cal" / "calibration.json"), "--yes"]  # fmt: skip
    else:
        args = ["lerobot", "calibrate", "--robot", robot, "--port", sim.info["port"], "--id", "t",
                "--calibration-dir", str(folder / "cal"), "--auto", "--yes"]  # fmt: skip
    if joints:
        args += ["--joints", joints]
    n_joints = len(joints.split(",")) if joints else len(before) - (1 if robot == "so101_follower" else 0)
    env = dict(os.environ, PYTHONPATH=str(SRC), ROBOCAL_REPLY_TIMEOUT_MS="2000", COLUMNS="200",
               XDG_STATE_HOME=str(folder / "state"))  # fmt: skip  # this trial's snapshots only
    run = _Run(subprocess.Popen(
        [sys.executable, "-m", "robocal", *args], cwd=folder, env=env, stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals,
    ))  # fmt: skip
    run.start_reader()
    try:
        injected = _wait_for_phase(run, sim, phase, n_joints, rng, folder)
        if injected:
            _inject(run.proc, sim, fault, rng)
        try:
            code = run.proc.wait(timeout=HANG_GUARD_S)
        except subprocess.TimeoutExpired:
            return TrialResult(robot, fault, phase, injected, -1, ("hung: robocal did not exit in 600 s",))
    finally:
        if run.proc.poll() is None:  # the harness itself is stopping, or robocal hung
            with _suppress():
                os.kill(run.proc.pid, signal.SIGCONT)
            run.proc.kill()
            run.proc.wait()
    time.sleep(0.2)  # the stderr reader drains the last lines (their content is not judged by timing)
    if fault == "frozen-device":
        os.kill(sim.proc.pid, signal.SIGCONT)
    failures = tuple(_judge(sim, folder, robot, fault, code, before, run))
    if robot != "lite" and fault in HOST_LOST and code != 0 and injected and not _files(folder):
        from .next_run import next_run_restores  # the next run reports what was left changed and restores it

        failures += tuple(next_run_restores(sim, folder, robot, before, env))
    if failures and _before_robocal(fault, code, run) and all("exit" in f for f in failures):
        # the signal came while the interpreter itself was starting, before robocal's first line (its handlers):
        # Python's default ended it and nothing was touched (the other checks passed): robocal was not reached
        return TrialResult(robot, fault, phase, False, code, (), "before robocal's first line")
    tail = _report_tail(run, failures)
    return TrialResult(robot, fault, phase, injected, code, failures, tail)


def _report_tail(run: _Run, failures: Sequence[str]) -> str:
    """robocal's standard error for the trial's report: the last 3 lines, all of it (and its signal state) if failed.

    The signal state (:func:`proc_state.note_signal_state`) says which thread blocked a signal, whether it was ignored
    or caught: for a signal that was not acted on.
    """
    tail = " | ".join(ln.strip() for ln in (run.lines[-40:] if failures else run.lines[-3:]))
    state = SIGNAL_STATES.pop(run.proc.pid, "")
    return f"{tail} || {state}" if failures and state else tail


def _before_robocal(fault: str, code: int, run: _Run) -> bool:
    """The signal met Python's own start-up, before robocal's first line (its handlers were not in yet).

    SIGTERM/SIGHUP: killed by the default action without a line. SIGINT: the same before Python installs its own
    handler, afterwards Python's ``KeyboardInterrupt`` (a traceback through ``runpy``/``site``/``<frozen …>``, never
    through robocal's files). Measured with ``benchmarks/run.py faults --early N``.
    """
    signums = {"sigterm": signal.SIGTERM, "sighup": signal.SIGHUP, "sigint": signal.SIGINT,
               "double-sigint": signal.SIGINT}  # fmt: skip
    err = "".join(run.lines)
    if fault not in signums or str(SRC) in err:
        return False
    if code == -signums[fault] and not err.strip():
        return True
    return signums[fault] == signal.SIGINT and code in (-2, 1) and err.rstrip().endswith("KeyboardInterrupt")


def _wait_for_phase(
    run: _Run, sim: _Sim, phase: str, n_joints: int, rng: random.Random, folder: Path | None = None
) -> bool:
    """Wait until ``phase`` (then a random part of it); False when robocal ended first.

    ``file-write`` with ``folder``: the instant is taken from the run itself, the first calibration file or
    ``.rc-*`` temporary under ``folder/cal`` (polled every 2 ms), then up to 30 ms more; a fixed delay after the
    last joint line missed it in about one trial in eight (the run had ended 0.3 s after that line).
    """
    deadline = time.monotonic() + HANG_GUARD_S

    def alive() -> bool:
        return run.proc.poll() is None and time.monotonic() < deadline

    if phase == "start-up":
        time.sleep(rng.uniform(0.0, 2.0))
        return alive()
    if phase in ("search", "contact"):
        while alive() and run.count("searching its stops") == 0:
            time.sleep(0.02)
        if phase == "search":
            time.sleep(rng.uniform(0.0, 2.0))
            return alive()
        while alive():
            with _suppress():
                if _at_a_stop(sim.state()):
                    time.sleep(rng.uniform(0.0, 0.3))
                    return alive()
        return False
    while alive() and run.count(": ok") + run.count(": FAILED") < n_joints:
        time.sleep(0.02)
    if run.count(": FAILED"):
        return (
            False  # the search failed: robocal ends on its own (exit 3), there is no new calibration to write
        )
    if phase == "file-write" and folder is not None:
        cal = folder / "cal"
        while alive() and not (any(cal.rglob("*.json")) or any(cal.rglob(".rc-*"))):
            time.sleep(0.002)
        time.sleep(rng.uniform(0.0, 0.03))
        return alive()
    time.sleep(rng.uniform(0.0, 0.4) if phase == "restore" else rng.uniform(0.3, 1.5))
    return alive()


_ONE_SIGNAL = {"sigint": signal.SIGINT, "sigterm": signal.SIGTERM, "sighup": signal.SIGHUP}
"""The faults that are one signal robocal can act on (its signal state is noted for the report)."""


def _inject(proc: subprocess.Popen[str], sim: _Sim, fault: str, rng: random.Random) -> None:
    pid = proc.pid
    with _suppress():
        if fault in _ONE_SIGNAL:
            os.kill(pid, _ONE_SIGNAL[fault])
            note_signal_state(pid)
        elif fault == "double-sigint":
            os.kill(pid, signal.SIGINT)
            time.sleep(rng.uniform(0.02, 0.3))
            os.kill(pid, signal.SIGINT)
        elif fault == "sigkill":
            os.kill(pid, signal.SIGKILL)
        elif fault == "cpu-stall":
            os.kill(pid, signal.SIGSTOP)
            time.sleep(rng.uniform(0.3, 1.5))
            os.kill(pid, signal.SIGCONT)
        elif fault == "frozen-device":
            os.kill(sim.proc.pid, signal.SIGSTOP)  # continued once robocal has exited
        elif fault == "lost-device":
            sim.detach_all()


def _judge(
    sim: _Sim, folder: Path, robot: str, fault: str, code: int, before: dict[str, tuple[int, ...]], run: _Run
) -> list[str]:
    failures: list[str] = []
    err = "".join(run.lines)
    if code == 70 or "Traceback" in err or "internal error" in err:
        failures.append(f"exit {code} / traceback or internal error: {err.strip().splitlines()[-1:]}")
    if fault in EXPECTED_EXIT and code not in (EXPECTED_EXIT[fault], 0) and not (robot == "lite" and code == 1):
        failures.append(f"exit {code}, expected {EXPECTED_EXIT[fault]}")
    # exit 0 after a signal: robocal finished (its last writes hold Ctrl-C off, or the signal came as it exited);
    # judged like a finished run below (file whole, the new calibration in place); counted by finished_despite()
    # sweep --auto (the Lite) exits 1 when it wrote the calibration with a warning: a finished run too
    finished = code == 0 or (robot == "lite" and code == 1)
    if fault == "cpu-stall" and not finished and code != 3:
        failures.append(f"exit {code} after a CPU stall, expected 0 or 3")
    if fault == "lost-device":
        with _suppress():
            from robocal.backends.sim.control import SimControl

            with SimControl(sim.info["control"], timeout_s=60) as ctl:
                ctl.request("attach", joints="all")
    host_lost = fault in HOST_LOST

    def left_on(state: list[dict[str, Any]]) -> list[str]:
        on = _torque_on(state)
        if host_lost:  # only a watchdog can act: a motor whose watchdog stopped it within its time is not a failure
            on = [n for n in on if not _stopped_by_watchdog(next(j for j in state if j["name"] == n))]
        return on

    state = sim.state()
    on = left_on(state)
    if on and host_lost and robot not in NO_WATCHDOG:
        # a simulator resumed after a freeze first works through what it missed (the bytes robocal sent meanwhile,
        # the watchdog's due time on its own clock): judged once it has caught up (bounded poll)
        deadline = time.monotonic() + 10.0
        while on and time.monotonic() < deadline:
            time.sleep(0.1)
            state = sim.state()
            on = left_on(state)
    if on and not (host_lost and robot in NO_WATCHDOG):
        failures.append(f"torque on after the run: {', '.join(on)}")
    after = _registers(state)
    files = _files(folder)
    for f in files:
        try:
            json.loads(f.read_text())
        except ValueError:
            failures.append(f"calibration file {f.name} not whole JSON")
    leftovers = [p.name for p in (folder / "cal").rglob(".rc-*")] if (folder / "cal").exists() else []
    if code == 0 or (robot == "lite" and code == 1):
        if not files:
            failures.append(f"exit {code} without a calibration file")
    elif files and code in (130, 143, 129, 131) and re.search(
        rf"interrupted(?: by SIG[A-Z]+)? after writing {re.escape(str(files[-1]))} \(complete\)", err
    ):
        # the signal came after the file was written whole: robocal says so (item 6); nothing else may be left
        if leftovers:
            failures.append(f"temporary files left: {leftovers}")
        if "nothing was written" in err:
            failures.append("says 'nothing was written' although it wrote the calibration")
    else:
        changed = sorted(n for n in before if after.get(n) != before[n])
        if changed and not host_lost:
            failures.append(f"registers changed: {', '.join(changed)}")
        if files and fault not in ("sigkill",):
            failures.append(f"exit {code} but a calibration file was written")
        if leftovers and fault != "sigkill":
            failures.append(f"temporary files left: {leftovers}")
    return failures


def _files(folder: Path) -> list[Path]:
    return sorted((folder / "cal").rglob("*.json")) if (folder / "cal").exists() else []


def _lite_in_netns(fault: str, phase: str, seed: int, joints: str | None) -> TrialResult:
    import shutil

    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return TrialResult("lite", fault, phase, False, 0, ("cannot run: unshare or ip is not installed",))
    cmd = ["unshare", "--net", "sh", "-c", f'{NETNS_SETUP} && exec "$0" "$@"', sys.executable, __file__,
           "lite", fault, phase, str(seed), joints or ""]  # fmt: skip
    env = dict(os.environ, ROBOCAL_FAULT_NETNS="1", PYTHONPATH=str(SRC))
    r = subprocess.run(
        cmd, capture_output=True, text=True, timeout=HANG_GUARD_S + 120, env=env, preexec_fn=_default_signals
    )
    lines = r.stdout.strip().splitlines()
    if r.returncode != 0 or not lines:
        return TrialResult(
            "lite", fault, phase, False, r.returncode, (f"netns trial failed: {r.stderr[-500:]}",)
        )
    d = json.loads(lines[-1])
    return TrialResult(
        d["robot"], d["fault"], d["phase"], d["injected"], d["exit_code"], tuple(d["failures"]), d["tail"]
    )


if __name__ == "__main__":  # one trial, in the Lite's network namespace: prints its result as JSON
    sys.path.insert(0, str(SRC))
    _robot, _fault, _phase, _seed, _joints = sys.argv[1:6]
    _r = run_trial(_robot, _fault, _phase, random.Random(int(_seed)), _joints or None)
    print(json.dumps({"robot": _r.robot, "fault": _r.fault, "phase": _r.phase, "injected": _r.injected,
                      "exit_code": _r.exit_code, "failures": list(_r.failures), "tail": _r.stderr_tail}))  # fmt: skip
