"""Fault injection on the Damiao path (issue 31, with issue 26's oracle): ``sweep --auto`` on a simulated OpenArm.

One trial: start ``robocal sim openarm --side right`` (its own process: eight simulated Damiao motors in real
time behind a loopback socketcand server and a control socket), put a TCP relay between it and robocal (so the
bus itself can vanish), record every motor's RAM and flash registers and its stored zero through the control
socket, run ``robocal sweep --auto --robot openarm_follower_right --source can:socketcand:can0?...`` on one joint,
inject the fault at a random instant of the chosen phase (``harness._wait_for_phase``), then judge by the
simulated motors' own state:

* no motor enabled (state 0x1) once robocal is gone. Where robocal could not act (SIGKILL, the motors silenced,
  the bus cut, the simulator frozen) only the motors' TIMEOUT watchdog can: an enabled motor must have tripped it
  (state 0xD, limp) within the armed time (0.5 s) of the last frame it heard;
* every RAM register as before, except the TIMEOUT robocal armed when it could not put it back (host lost);
* every flash register, the zero in flash and the flash write count as before: ``sweep --auto`` writes nothing
  to a motor's flash, even when it finishes. ``--write-zero`` stores one zero per motor when it finishes; where
  the host was lost (SIGKILL, lost device or bus, frozen device) after a zero reached flash, one write per motor
  is accepted only when the next run says so (``next_run.damiao_next_run_reports_zeros``: it runs again);
* the calibration file absent, or (exit 0) whole; no ``.rc-*`` temporary left unless robocal was killed;
* the exit code the fault calls for (130 / 143 / 129; 3 for a lost device or bus; 3 after a CPU stall that
  tripped the watchdog), or a finished run (0, or 1: the file written with a joint's warning), never 70 nor a
  traceback.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .harness import (
    EXPECTED_EXIT,
    FAULTS,
    HANG_GUARD_S,
    SRC,
    TrialResult,
    _before_robocal,
    _default_signals,
    _inject,
    _report_tail,
    _Run,
    _Sim,
    _suppress,
    _wait_for_phase,
)
from .proc_state import RunQueueSampler

OPENARM_ROBOT = "openarm"
OPENARM_FAULTS = (*FAULTS, "lost-bus")
"""Every fault of the other robots, and the socketcand connection cut (the daemon or the network gone)."""
OPENARM_JOINT = "openarm_right_gripper_motor"  # the shortest search (60°): a trial takes 20-40 s
ZERO_JOINTS = (
    "openarm_right_gripper_motor,openarm_right_joint6"  # --write-zero: two zeros, one after the other
)
ZERO_PHASE = "zero-write"
"""``--write-zero`` trials (robot ``openarm-zero``): right after the first of the zeros is stored in flash."""
HOST_LOST = ("sigkill", "lost-device", "lost-bus", "frozen-device")
ZERO_NEXT_RUNS: list[list[str]] = []
"""Per trial whose zeros the host left in flash: the motors the next run had to name (its judgement: ``_judge``)."""
HELD_PHASE = "held"
"""Two joints searched: the second's search, while the first holds its park angle (an idle enabled motor)."""
HELD_JOINTS = "openarm_right_gripper_motor,openarm_right_joint7"
"""The joints of a ``held`` trial: the gripper parks and holds while J7 is searched (two motors to make limp)."""
STARVE_S = 0.15
"""``starve``: robocal is stopped this long, then runs this long, until it exits."""
WATCHDOG_S = 0.5  # the TIMEOUT robocal arms (backends/damiao/joint_driver.py WATCHDOG_S)
TIMEOUT_UNIT_S = 50e-6
LIMP_WAIT_S = 30.0  # hang guard for the watchdogs to act once the host is gone (0.5 s of real time)
LIMP_BOUND_S = 0.1
"""Issue 26: a signal robocal can act on leaves no motor able to push for longer than this."""
LIMP_LATENCIES: list[dict[str, tuple[float, float | None]]] = []
"""Per judged trial with a timed signal: motor → seconds from the signal to the simulator's torque off, and to its
disable frame on the wire (None: not seen, or no relay) (the soak's figures, :func:`limp_summary`)."""
LIMP_LOAD_LATE: list[tuple[float, float]] = []
"""Disable frames later than the bound on the wire only by robocal's run-queue wait: (on the wire, waited), s."""
DISABLE = bytes([0xFF] * 7 + [0xFD])
"""The data of a Damiao disable frame (0xFD): the frame that takes a motor's torque away."""
LIMP_TIMED = ("sigint", "double-sigint", "sigterm", "sighup")
"""The faults robocal can act on, whose limp is timed (a killed, frozen or cut-off host leaves it to the TIMEOUT)."""


class _Relay:
    """A TCP relay robocal's socketcand client goes through; :meth:`cut` closes every connection and closes each new
    one at once (the bus gone) until :meth:`resume` (the next run on the same address); :meth:`close` ends it.

    It also notes every CAN frame robocal sends (:attr:`sent`: the host's ``time.monotonic()`` at which the frame
    reached the relay's socket, from the kernel's stamp (:func:`_arrived`), arbitration id, data): the wire's view,
    independent of robocal's own account and of when the relay or the simulator got round to the frame.
    """

    def __init__(self, host: str, port: int) -> None:
        self.upstream = (host, port)
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.lock = threading.Lock()
        self.sent: list[tuple[float, int, bytes]] = []
        self.refusing = False
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.sock.accept()
            except OSError:
                return
            if self.refusing:
                with _suppress():
                    client.close()
                continue
            upstream = socket.create_connection(self.upstream)
            with self.lock:
                self.conns += [client, upstream]
            threading.Thread(target=self._pump, args=(client, upstream, self._note), daemon=True).start()
            threading.Thread(target=self._pump, args=(upstream, client), daemon=True).start()

    @staticmethod
    def _pump(src: socket.socket, dst: socket.socket, note: Any = None) -> None:
        text = ""
        try:
            if note is not None:  # the kernel's arrival stamp, not when this thread got round to reading it
                src.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            while True:
                data, ancillary, _flags, _addr = src.recvmsg(65536, socket.CMSG_SPACE(16))
                if not data:
                    break
                if note is not None:
                    text = note(_arrived(ancillary), text + data.decode("ascii", "replace"))
                dst.sendall(data)
        except OSError:
            pass
        with _suppress():
            dst.shutdown(socket.SHUT_WR)

    def _note(self, at: float, text: str) -> str:
        """Note the complete ``< send ID LEN B0 B1 ... >`` commands in ``text`` (socketcand's raw mode, as
        python-can writes them); returns the incomplete rest."""
        while (end := text.find(">")) >= 0:
            words = text[:end].split()
            text = text[end + 1 :]
            if len(words) >= 3 and words[:2] == ["<", "send"]:
                with contextlib.suppress(ValueError):  # not a frame python-can wrote
                    self.sent.append((at, int(words[2], 16), bytes(int(b, 16) for b in words[4:])))
        return text

    def cut(self) -> None:
        self.refusing = True
        with self.lock:
            conns, self.conns = self.conns, []
        for c in conns:
            with _suppress():
                c.shutdown(socket.SHUT_RDWR)
            with _suppress():
                c.close()

    def resume(self) -> None:
        """Relay new connections again (the port kept: the same bus address for the next run)."""
        self.refusing = False

    def close(self) -> None:
        self.cut()
        with _suppress():
            self.sock.close()


_SO_TIMESTAMPNS = 35
"""Linux's ``SO_TIMESTAMPNS`` (= ``SCM_TIMESTAMPNS``; Python's socket module has no name for it)."""


def _arrived(ancillary: list[tuple[int, int, bytes]]) -> float:
    """When the bytes of one ``recvmsg`` reached the relay's socket, on the host's ``time.monotonic()`` clock.

    The kernel stamps each arriving segment (``SO_TIMESTAMPNS``, wall clock); for TCP ``recvmsg`` reports the stamp
    of the last segment it read, so several sends read at once carry the latest one (never earlier than the
    truth). A relay thread the harness's other threads or a loaded machine kept from reading is then not counted as
    robocal's lateness. Without a stamp (the kernel turns its stamps on a moment after the first socket asks, so a
    connection's first segments may have none): now, the relay's own reading time, as before.
    """
    mono, wall = time.monotonic(), time.time()
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(data) >= 16:
            sec, nsec = struct.unpack("qq", data[:16])
            return mono - max(0.0, wall - (sec + nsec * 1e-9))
    return mono


def _motors(state: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {j["name"]: j for j in state}


def _control(sim: _Sim, cmd: str, **fields: Any) -> dict[str, Any]:
    from robocal.backends.sim.control import SimControl

    with SimControl(sim.info["control"], timeout_s=60) as ctl:
        return ctl.request(cmd, **fields)


def run_openarm_trial(
    fault: str,
    phase: str,
    rng: random.Random,
    joints: str | None = None,
    *,
    write_zero: bool = False,
    reply_ms: int | None = None,
) -> TrialResult:
    """Run one trial in a fresh folder with a fresh simulated OpenArm (seeded from ``rng``).

    ``write_zero``: ``sweep --auto --write-zero`` (each joint's zero stored in its motor's flash once the stops
    are found); the phase ``zero-write`` is then the instant right after the first flash write. ``reply_ms``:
    robocal runs with ``ROBOCAL_REPLY_TIMEOUT_MS`` set to it (its watchdog then ``watchdog_for`` that wait).
    """
    with tempfile.TemporaryDirectory(prefix="robocal-fault-oa-") as tmp:
        folder = Path(tmp)
        seed = rng.randrange(1000)
        sim = _Sim(OPENARM_ROBOT, folder, argv=("--side", "right", "--port", "0", "--seed", str(seed)))
        relay = None
        try:
            relay = _Relay("127.0.0.1", int(sim.info["socketcand"].rsplit(":", 1)[1]))
            default = ZERO_JOINTS if write_zero else HELD_JOINTS if phase == HELD_PHASE else OPENARM_JOINT
            return _trial(sim, relay, folder, fault, phase, rng, joints or default, write_zero, reply_ms)
        finally:
            if relay is not None:
                relay.close()
            sim.stop()


def _trial(
    sim: _Sim,
    relay: _Relay,
    folder: Path,
    fault: str,
    phase: str,
    rng: random.Random,
    joints: str,
    write_zero: bool,
    reply_ms: int | None = None,
) -> TrialResult:
    import importlib.resources

    from robocal.backends.mit_keepalive import watchdog_for

    before = _motors(sim.state())
    urdf = Path(str(importlib.resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
    (folder / "cal").mkdir()
    source = f"can:socketcand:can0?host=127.0.0.1&port={relay.port}"
    args = ["sweep", "--auto", "--urdf", str(urdf), "--robot", "openarm_follower_right", "--source", source,
            "--out", str(folder / "cal" / "calibration.json"), "--joints", joints, "--yes"]  # fmt: skip
    if write_zero:
        args.append("--write-zero")
    # robocal as shipped (reply timeout 0.1 s): a longer floor lets one reply wait starve the other enabled motors'
    # 0.5 s TIMEOUT (measured with ROBOCAL_REPLY_TIMEOUT_MS=500: their watchdogs tripped)
    env = dict(os.environ, PYTHONPATH=str(SRC), COLUMNS="200", XDG_STATE_HOME=str(folder / "state"))
    if reply_ms is not None:
        env["ROBOCAL_REPLY_TIMEOUT_MS"] = str(reply_ms)
    watchdog_s = watchdog_for(max(0.1, (reply_ms or 0) / 1000.0))
    run = _Run(subprocess.Popen(
        [sys.executable, "-m", "robocal", *args], cwd=folder, env=env, stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals,
    ))  # fmt: skip
    run.start_reader()
    run_queue = RunQueueSampler(run.proc).start()
    robot = "openarm-zero" if write_zero else OPENARM_ROBOT
    try:
        if phase == ZERO_PHASE:
            injected = _wait_for_flash_write(run, sim, before, rng)
        elif phase == HELD_PHASE:
            injected = _wait_for_held(run, rng)
        else:
            injected = _wait_for_phase(run, sim, phase, len(joints.split(",")), rng, folder)
        signalled_at = None
        if injected:
            if fault in LIMP_TIMED:
                signalled_at = time.monotonic()  # the host's monotonic clock: the simulator stamps with the same
            if fault == "lost-device":
                _control(sim, "attach", joints=[])
            elif fault == "lost-bus":
                relay.cut()
            elif fault == "starve":
                threading.Thread(target=_starve, args=(run.proc,), daemon=True).start()
            else:
                _inject(run.proc, sim, fault, rng)
        try:
            code = run.proc.wait(timeout=HANG_GUARD_S)
        except subprocess.TimeoutExpired:
            return TrialResult(
                OPENARM_ROBOT, fault, phase, injected, -1, ("hung: robocal did not exit in 600 s",)
            )
    finally:
        if run.proc.poll() is None:
            with _suppress():
                os.kill(run.proc.pid, signal.SIGCONT)
            run.proc.kill()
            run.proc.wait()
    run.drained()  # robocal's last lines are read before they are judged
    if fault == "frozen-device":
        os.kill(sim.proc.pid, signal.SIGCONT)
    def next_run(zeroed: list[str]) -> list[str]:
        from .next_run import damiao_next_run_reports_zeros

        ZERO_NEXT_RUNS.append(zeroed)
        relay.cut()
        relay.resume()  # the same bus: the same address (the record is kept per bus)
        try:
            return damiao_next_run_reports_zeros(sim, folder, args, env, zeroed)
        finally:
            relay.cut()

    failures = tuple(
        _judge(sim, folder, fault, code, before, run, write_zero, signalled_at=signalled_at, watchdog_s=watchdog_s,
               sent=relay.sent, next_run=next_run, waited_s=run_queue.waited_s)
    )
    if failures and _before_robocal(fault, code, run) and all("exit" in f for f in failures):
        # as for the other robots: the signal met Python's own start-up, before robocal's first line
        return TrialResult(robot, fault, phase, False, code, (), "before robocal's first line")
    tail = _report_tail(run, failures)
    return TrialResult(robot, fault, phase, injected, code, failures, tail)


def _wait_for_held(run: _Run, rng: random.Random) -> bool:
    """Wait until the second joint's search began (the first holds its park angle), then 0-1 s."""
    deadline = time.monotonic() + HANG_GUARD_S
    while run.proc.poll() is None and time.monotonic() < deadline and run.count("searching its stops") < 2:
        time.sleep(0.02)
    time.sleep(rng.uniform(0.0, 1.0))
    return run.proc.poll() is None


def _starve(proc: subprocess.Popen[str]) -> None:
    """Hold robocal up half of the time (stopped 0.15 s, running 0.15 s) until it exits: a starved host."""
    while proc.poll() is None:
        with _suppress():
            os.kill(proc.pid, signal.SIGSTOP)
        time.sleep(STARVE_S)
        with _suppress():
            os.kill(proc.pid, signal.SIGCONT)
        time.sleep(STARVE_S)


def _wait_for_flash_write(
    run: _Run, sim: _Sim, before: dict[str, dict[str, Any]], rng: random.Random
) -> bool:
    """Wait until a motor's flash write count rose (the first zero stored), then 0-20 ms; False if robocal ended."""
    deadline = time.monotonic() + HANG_GUARD_S
    while run.proc.poll() is None and time.monotonic() < deadline:
        with _suppress():
            now = _motors(sim.state())
            if any(now[n]["flash_writes"] > before[n]["flash_writes"] for n in now):
                time.sleep(rng.uniform(0.0, 0.02))
                return run.proc.poll() is None
        time.sleep(0.005)
    return False


def _settled(sim: _Sim, host_lost: bool) -> dict[str, dict[str, Any]]:
    """The motors once nothing is enabled (host lost: the watchdogs act within 0.5 s), or after the hang guard."""
    deadline = time.monotonic() + (LIMP_WAIT_S if host_lost else 0.0)
    while True:
        state = _motors(sim.state())
        if not any(m["enabled"] for m in state.values()) or time.monotonic() > deadline:
            return state
        time.sleep(0.05)


def limp_latency(before: dict[str, dict[str, Any]], after: dict[str, dict[str, Any]], signalled_at: float
                 ) -> dict[str, float]:
    """Per motor that was made limp after the signal: how long after it (s, the host's monotonic clock) the first
    frame or event took its torque away (the simulator's ``torque_off_at``)."""
    out: dict[str, float] = {}
    for name, m in after.items():
        new = m["torque_off_at"][len(before[name]["torque_off_at"]):]
        later = [wall for _sim, wall in new if wall >= signalled_at]
        if later:
            out[name] = min(later) - signalled_at
    return out


def wire_latency(
    sent: list[tuple[float, int, bytes]], motors: dict[str, dict[str, Any]], signalled_at: float
) -> dict[str, float]:
    """Per motor: how long after the signal (s) its first disable frame (0xFD to its ESC_ID) was on the wire (the
    relay read it); ``sent`` is the relay's :attr:`_Relay.sent`."""
    esc = {int(m["ram"]["ESC_ID"]): name for name, m in motors.items()}
    out: dict[str, float] = {}
    for at, arb, data in sent:
        name = esc.get(arb)
        if name is not None and at >= signalled_at and data == DISABLE and name not in out:
            out[name] = at - signalled_at
    return out


def limp_latency_failures(
    before: dict[str, dict[str, Any]],
    after: dict[str, dict[str, Any]],
    signalled_at: float,
    sent: list[tuple[float, int, bytes]] | None = None,
    waited_s: Callable[[float, float], float] | None = None,
) -> list[str]:
    """A motor whose torque went off later than :data:`LIMP_BOUND_S` after the signal, as the simulator stamped it.

    With the frames robocal sent (``sent``, the relay's): a motor whose disable frame was on the wire within the
    bound had robocal's part done; the simulator's later stamp is then the test rig's lateness (the simulator or
    the relay descheduled on a loaded machine), kept in :data:`LIMP_LATENCIES` and the soak's figures, not a
    failure. ``waited_s(t0, t1)``: how long robocal was runnable but not running between two instants
    (:class:`tests.faults.proc_state.RunQueueSampler`); a frame later than the bound only by that wait is the
    machine's lateness (counted in :data:`LIMP_LOAD_LATE`), not robocal's.
    """
    on_wire = wire_latency(sent, after, signalled_at) if sent is not None else {}
    out = []
    for name, dt in limp_latency(before, after, signalled_at).items():
        wire = on_wire.get(name)
        if dt > LIMP_BOUND_S and (wire is None or wire > LIMP_BOUND_S):
            waited = waited_s(signalled_at, signalled_at + wire) if waited_s is not None and wire is not None else 0.0
            if wire is not None and wire - waited <= LIMP_BOUND_S:
                LIMP_LOAD_LATE.append((wire, waited))
                continue
            seen = "" if sent is None else "; its disable frame " + (
                "not seen" if wire is None else f"on the wire after {wire * 1000:.0f} ms")
            if waited > 0:
                seen += f", robocal waiting for a CPU {waited * 1000:.0f} ms of it"
            out.append(f"{name}: limp {dt * 1000:.0f} ms after the signal (bound {LIMP_BOUND_S * 1000:.0f} ms{seen})")
    return out


def limp_summary(latencies: list[dict[str, tuple[float, float | None]]] | None = None) -> str:
    """The soak's limp times: per motor made limp after a timed signal, from the signal to its disable frame on the
    wire and to the simulator's torque off (max / median, ms), and how many were over the bound."""
    trials = LIMP_LATENCIES if latencies is None else latencies
    rows = [v for trial in trials for v in trial.values()]
    if not rows:
        return "limp times: no timed signal reached an enabled motor"

    def fig(xs: list[float]) -> str:
        return f"max {max(xs) * 1000:.1f} ms, median {statistics.median(xs) * 1000:.1f} ms" if xs else "none"

    bound = f"{LIMP_BOUND_S * 1000:.0f} ms"
    wires = [w for _s, w in rows if w is not None]
    late_wire = sum(w is None or w > LIMP_BOUND_S for _s, w in rows)
    late_sim = sum(s > LIMP_BOUND_S for s, _w in rows)
    return (
        f"limp times ({len(rows)} motors after {len(trials)} timed signals): disable frame on the wire {fig(wires)} "
        f"({late_wire} over {bound} or not seen); the simulator's torque off {fig([s for s, _w in rows])} "
        f"({late_sim} over {bound}); over {bound} on the wire only while robocal waited for a CPU: "
        f"{len(LIMP_LOAD_LATE)}"
        + (f" (on the wire max {max(w for w, _ in LIMP_LOAD_LATE) * 1000:.0f} ms, of which waiting "
           f"{max(q for _, q in LIMP_LOAD_LATE) * 1000:.0f} ms)" if LIMP_LOAD_LATE else "")
    )


def _judge(
    sim: _Sim,
    folder: Path,
    fault: str,
    code: int,
    before: dict[str, dict[str, Any]],
    run: _Run,
    write_zero: bool = False,
    *,
    signalled_at: float | None = None,
    watchdog_s: float = WATCHDOG_S,
    sent: list[tuple[float, int, bytes]] | None = None,
    next_run: Any = None,
    waited_s: Callable[[float, float], float] | None = None,
) -> list[str]:
    """What the trial got wrong, by the simulator's state (the module's docstring lists the oracle).

    ``next_run(motors)``: runs the command again after a ``--write-zero`` run the host lost with those motors'
    zeros in flash; what it got wrong (None: such zeros are failures).
    """
    failures: list[str] = []
    zeroed: list[str] = []
    err = "".join(run.lines)
    if code == 70 or "Traceback" in err or "internal error" in err:
        failures.append(f"exit {code} / traceback or internal error: {err.strip().splitlines()[-1:]}")
    out = folder / "cal" / "calibration.json"
    # finished: exit 0, or 1 with the file written and a warning (a joint's status, e.g. wrap_in_travel)
    finished = code == 0 or (code == 1 and out.exists())
    # a signal after the file was written whole: robocal says so (issue 26 item 6), and exits with the signal's code
    written_then_signalled = code in (130, 143, 129) and out.exists() and f" after writing {out}" in err
    if written_then_signalled and "nothing was written" in err:
        failures.append("says 'nothing was written' although it wrote the calibration")
    finished = finished or written_then_signalled
    expected = {**EXPECTED_EXIT, "lost-bus": 3}
    if fault in expected and code != expected[fault] and not finished:
        failures.append(f"exit {code}, expected {expected[fault]}")
    if fault == "cpu-stall" and code != 3 and not finished:
        failures.append(f"exit {code} after a CPU stall, expected 0 or 3")
    if fault == "starve" and code != 3 and not finished:
        failures.append(f"exit {code} while starved, expected 0, 1 or 3")
    if fault == "lost-device":
        _control(sim, "attach", joints="all")
    host_lost = fault in HOST_LOST
    after = _settled(sim, host_lost)
    on = [n for n, m in after.items() if m["enabled"]]
    if on:
        failures.append(f"enabled after the run: {', '.join(on)}")
    if signalled_at is not None:
        on_wire = wire_latency(sent, after, signalled_at) if sent is not None else {}
        LIMP_LATENCIES.append({n: (dt, on_wire.get(n)) for n, dt in limp_latency(before, after, signalled_at).items()})
        failures += limp_latency_failures(before, after, signalled_at, sent, waited_s)
    # robocal went silent for longer than a TIMEOUT (a host-lost fault, or a CPU stall that tripped a watchdog): a zero
    # already in flash stays; the next run must say so
    went_silent = host_lost or any(len(m["lost_comm_at_s"]) > len(before[n]["lost_comm_at_s"]) for n, m in after.items())
    for name, m in after.items():
        b = before[name]
        tripped = len(m["lost_comm_at_s"]) > len(b["lost_comm_at_s"])
        if tripped and m["ram"]["TIMEOUT"] * TIMEOUT_UNIT_S > watchdog_s + 1e-9:
            failures.append(
                f"{name}: TIMEOUT tripped after {m['ram']['TIMEOUT'] * TIMEOUT_UNIT_S:g} s, over {watchdog_s:g} s"
            )
        if tripped and fault == "starve":
            failures.append(f"{name}: TIMEOUT tripped although robocal was only starved, never silent")
        ram = sorted(r for r in m["ram"] if m["ram"][r] != b["ram"][r] and not (host_lost and r == "TIMEOUT"))
        if ram:
            failures.append(f"{name}: RAM register(s) changed: {', '.join(ram)}")
        flash = sorted(r for r in m["flash"] if m["flash"][r] != b["flash"][r])
        if write_zero and finished and m["flash_writes"] == b["flash_writes"] + 1 and not flash:
            continue  # --write-zero finished: this joint's new zero (one write); its accuracy is test_openarm_files'
        one_zero = m["flash_writes"] == b["flash_writes"] + 1 and not flash and m["zero_abs_rad"] != b["zero_abs_rad"]
        if write_zero and one_zero and fault == "sigkill" and _whole_json(out):
            continue  # killed after its file was written whole: the new zero is in a file (nothing to say next run)
        if write_zero and went_silent and next_run is not None and one_zero:
            zeroed.append(name)  # no write takes a zero back: the next run must say it is there (judged below)
            continue
        if flash or m["zero_abs_rad"] != b["zero_abs_rad"] or m["flash_writes"] != b["flash_writes"]:
            failures.append(
                f"{name}: flash changed: {', '.join(flash) or 'zero'} ({m['flash_writes']} writes)"
            )
    if out.exists():
        try:
            json.loads(out.read_text())
        except ValueError:
            failures.append("calibration file not whole JSON")
    leftovers = [p.name for p in (folder / "cal").rglob(".rc-*")]
    if code == 0 and not out.exists():
        failures.append("exit 0 without a calibration file")
    if not finished and out.exists() and fault != "sigkill":
        failures.append(f"exit {code} but a calibration file was written")
    if leftovers and fault != "sigkill":
        failures.append(f"temporary files left: {leftovers}")
    if zeroed and not failures:
        failures += next_run(zeroed)
    elif zeroed:
        failures.append(f"flash zero changed on {', '.join(zeroed)} (not judged further: the trial failed already)")
    return failures


def _whole_json(out: Path) -> bool:
    """The calibration file ``out`` exists and is whole JSON (this trial's folder is new: this run wrote it)."""
    try:
        json.loads(out.read_text())
    except (OSError, ValueError):
        return False
    return True
