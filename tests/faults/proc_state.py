"""What ``/proc`` says of a robocal process under test: its run-queue wait and its signal state.

**Run-queue wait** (the limp-time oracle): issue 26 asks for every motor limp within 100 ms of a signal robocal can
act on, and for timing that is correct when the process is descheduled for hundreds of milliseconds. On a loaded
machine the kernel may keep robocal waiting on a run queue for longer than the bound: no code can send a frame
while it is not scheduled. The harness therefore samples the run-queue wait of robocal's main thread (the second
field of ``/proc/PID/schedstat``, nanoseconds spent runnable but waiting for a CPU) every few milliseconds; a
disable frame late on the wire whose lateness is covered by that wait is the machine's, counted in the soak's
figures, not robocal's failure. The window used is the samples strictly inside the interval, so the wait is never
overstated.

**Signal state** (a failed trial's report): which signals the process ignores, catches and has pending, and each
thread's blocked mask (``/proc/PID/status``, ``/proc/PID/task/TID/status``), so a signal robocal did not act on
says whether it was blocked, ignored or never delivered.
"""

from __future__ import annotations

import subprocess
import threading
import time
from bisect import bisect_left, bisect_right
from dataclasses import dataclass, field

__all__ = ["RunQueueSampler"]

PERIOD_S = 0.005


@dataclass
class RunQueueSampler:
    """Samples ``(time.monotonic(), run-queue wait ns)`` of ``proc``'s main thread until it exits.

    Where ``/proc`` has no ``schedstat`` (not Linux, or schedstats off) there are no samples and :meth:`waited_s`
    is 0: the oracle is then the plain wall-clock bound.
    """

    proc: subprocess.Popen[str]
    times: list[float] = field(default_factory=list)
    waits_ns: list[int] = field(default_factory=list)

    def start(self) -> RunQueueSampler:
        threading.Thread(target=self._run, name="runqueue-sampler", daemon=True).start()
        return self

    def _run(self) -> None:
        path = f"/proc/{self.proc.pid}/schedstat"
        while self.proc.returncode is None:
            try:
                with open(path) as f:
                    fields = f.read().split()
            except OSError:  # the process is gone (or no schedstat here)
                return
            self.times.append(time.monotonic())
            self.waits_ns.append(int(fields[1]))
            time.sleep(PERIOD_S)

    def waited_s(self, t0: float, t1: float) -> float:
        """Run-queue wait (s) between the first sample at or after ``t0`` and the last at or before ``t1``."""
        return waited_between(self.times, self.waits_ns, t0, t1)


def waited_between(times: list[float], waits_ns: list[int], t0: float, t1: float) -> float:
    """The wait accumulated between the samples strictly inside ``[t0, t1]`` (0 with fewer than two)."""
    i, j = bisect_left(times, t0), bisect_right(times, t1) - 1
    if j <= i:
        return 0.0
    return max(0, waits_ns[j] - waits_ns[i]) / 1e9


SIGNAL_STATES: dict[int, str] = {}
"""robocal's pid → its signal state (:func:`signal_state`) right after the harness sent it a signal, and 50 ms
later: for the report of a trial whose signal was not acted on (which thread blocked it, was it ignored)."""


def signal_state(pid: int) -> str:
    """``/proc`` view of ``pid``'s signals: ignored/caught (process-wide), pending, and each thread's blocked mask.

    Hex masks as the kernel prints them (bit ``n-1`` is signal ``n``: SIGINT 0x2, SIGHUP 0x1, SIGTERM 0x4000).
    Empty where ``/proc`` has no such process.
    """
    import os

    def fields(path: str, names: tuple[str, ...]) -> str:
        try:
            with open(path) as f:
                rows = dict(line.split(":", 1) for line in f if ":" in line)
        except OSError:
            return ""
        return " ".join(f"{n}={rows[n].strip().lstrip('0') or '0'}" for n in names if n in rows)

    head = fields(f"/proc/{pid}/status", ("State", "ShdPnd", "SigIgn", "SigCgt"))
    try:
        tids = sorted(os.listdir(f"/proc/{pid}/task"), key=int)
    except OSError:
        return head
    threads = [f"{tid}:{fields(f'/proc/{pid}/task/{tid}/status', ('SigPnd', 'SigBlk'))}" for tid in tids]
    return f"{head} threads {' '.join(threads)}"


def note_signal_state(pid: int) -> None:
    """Keep :func:`signal_state` of ``pid`` now and 50 ms later in :data:`SIGNAL_STATES` (for a failed trial)."""
    first = signal_state(pid)
    time.sleep(0.05)
    SIGNAL_STATES[pid] = f"signal state at +0 ms: {first}; at +50 ms: {signal_state(pid)}"
