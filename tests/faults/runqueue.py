"""How long a process was runnable but not running (Linux ``/proc/PID/schedstat``), for the limp-time oracle.

Issue 26 asks for every motor limp within 100 ms of a signal robocal can act on, and for timing that is correct
when the process is descheduled for hundreds of milliseconds. On a loaded machine the kernel may keep robocal
waiting on a run queue for longer than the bound: no code can send a frame while it is not scheduled. The harness
therefore samples the run-queue wait of robocal's main thread (the second field of ``/proc/PID/schedstat``,
nanoseconds spent runnable but waiting for a CPU) every few milliseconds; a disable frame late on the wire whose
lateness is covered by that wait is the machine's, counted in the soak's figures, not robocal's failure. The window
used is the samples strictly inside the interval, so the wait is never overstated.
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
