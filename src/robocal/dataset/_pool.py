"""Worker processes for the data files of a dataset: no hang when a worker dies, no worker outlives the run.

:func:`run_pool` hands one job at a time to each worker over its own pipe and waits on the pipes and the
process sentinels together, so a worker that dies (killed, out of memory) ends the run within moments with
:class:`WorkerDiedError`; the others are stopped before it is raised. Each worker asks Linux to kill it when
the main process dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``) and also checks its parent once a second (other
systems, and a parent that died before the request took effect), so killing the main process (``kill -9``)
leaves no worker behind. Workers ignore Ctrl-C: the main process handles it and stops them.

``concurrent.futures.ProcessPoolExecutor`` was used before; it could hang when a worker died early in the
run, and its workers outlived a killed main process.
"""

from __future__ import annotations

import ctypes
import os
import pickle
import signal
import sys
import threading
from collections import deque
from collections.abc import Callable, Sequence
from multiprocessing import get_context, get_start_method
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import Any, Generic, TypeVar

from ..errors import CalibError

__all__ = ["WorkerDiedError", "die_with_parent", "run_pool"]

J = TypeVar("J")
R = TypeVar("R")

_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_STOP_TIMEOUT_S = 5.0
"""How long a stopped worker may take to exit before it is killed."""


class WorkerDiedError(CalibError, RuntimeError):
    """A worker process died before finishing its job. Exit code 3."""

    exit_code = 3


class _RemoteError(RuntimeError):
    """A worker's exception that cannot be sent back as itself (it does not pickle); its text is kept."""


def die_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """Make this process exit when ``parent_pid`` (its parent) dies.

    On Linux the kernel sends ``SIGKILL`` the moment the parent dies (``PR_SET_PDEATHSIG``); everywhere a daemon
    thread also compares ``os.getppid()`` with ``parent_pid`` every ``poll_s`` seconds (re-parenting to init or a
    subreaper means the parent is gone). A parent that already died before this call ends the process at once.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no libc symbol: the watchdog thread below still works
            pass
    if os.getppid() != parent_pid:
        os._exit(1)

    def watch() -> None:
        while True:
            threading.Event().wait(poll_s)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="robocal-parent-watch", daemon=True).start()


def _sendable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling (the parent re-raises it as is), else a :class:`_RemoteError` with its text."""
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:
        return _RemoteError(f"{type(exc).__name__}: {exc}")
    return exc


def _worker_main(fn: Callable[[Any], Any], conn: Connection, parent_pid: int) -> None:
    """Run jobs ``(index, job)`` from ``conn`` until ``None`` or EOF; send back ``(ok, index, result or error)``."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        index, job = msg
        try:
            reply: tuple[bool, int, Any] = (True, index, fn(job))
        except BaseException as exc:
            reply = (False, index, _sendable(exc))
        conn.send(reply)


class _Worker(Generic[J]):
    """One worker process, the parent's end of its pipe and the job it is working on."""

    def __init__(self, proc: BaseProcess, conn: Connection) -> None:
        self.proc = proc
        self.conn = conn
        self.job: int | None = None

    def give(self, index: int, job: J) -> None:
        self.job = index
        self.conn.send((index, job))


def _stop_all(workers: Sequence[_Worker[Any]], *, graceful: bool) -> None:
    """Stop every worker: ask (``graceful``) or terminate, wait a bounded time, then kill what is left."""
    for w in workers:
        try:
            if graceful:
                w.conn.send(None)
            elif w.proc.is_alive():
                w.proc.terminate()
        except (OSError, ValueError):
            pass
    for w in workers:
        w.proc.join(_STOP_TIMEOUT_S)
        if w.proc.is_alive():
            w.proc.kill()
            w.proc.join(_STOP_TIMEOUT_S)
        w.conn.close()


def run_pool(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    workers: int,
    on_result: Callable[[R], None] | None = None,
    *,
    describe: Callable[[J], str] = str,
) -> list[R]:
    """Run ``fn`` on every job in ``workers`` processes; results in job order.

    ``fn`` is looked up by the worker as the parent had it (fork start method) or by reference (spawn).

    Args:
        fn: The work; exceptions it raises are re-raised here (the first one), the other workers stopped.
        jobs: Picklable jobs.
        workers: Number of processes (at most ``len(jobs)`` are started).
        on_result: Called in this process with each result as it arrives.
        describe: Names a job in the error when its worker dies.

    Raises:
        WorkerDiedError: A worker died (killed, out of memory) before finishing; the message names its job.
        BaseException: The first exception ``fn`` raised in a worker, or Ctrl-C here.
    """
    # a worker must be this process's own child (its parent-death signal and check need that): not forkserver's
    ctx = get_context("spawn" if get_start_method() == "forkserver" else None)
    parent = os.getpid()
    pool: list[_Worker[J]] = []
    results: dict[int, R] = {}
    pending = deque(enumerate(jobs))
    ok = False
    try:
        for _ in range(min(workers, len(jobs))):
            mine, theirs = ctx.Pipe(duplex=True)
            proc = ctx.Process(
                target=_worker_main, args=(fn, theirs, parent), name="robocal-dataset-worker", daemon=True
            )
            proc.start()
            theirs.close()
            pool.append(_Worker(proc, mine))
        busy: list[_Worker[J]] = []
        for w in pool:
            if pending:
                _give(w, pending, jobs, describe)
                busy.append(w)
        while busy:
            ready = wait([w.conn for w in busy] + [w.proc.sentinel for w in busy])
            for w in [w for w in busy if w.conn in ready or w.proc.sentinel in ready]:
                if not w.conn.poll():  # the sentinel fired and nothing is left to read
                    raise _died(w, jobs, describe)
                try:
                    good, index, value = w.conn.recv()
                except (EOFError, OSError, pickle.UnpicklingError):
                    raise _died(w, jobs, describe) from None
                if not good:
                    raise value
                results[index] = value
                w.job = None
                if on_result is not None:
                    on_result(value)
                if pending:
                    _give(w, pending, jobs, describe)
                else:
                    busy.remove(w)
        ok = True
    finally:
        _stop_all(pool, graceful=ok)
    return [results[i] for i in range(len(jobs))]


def _give(
    w: _Worker[J], pending: deque[tuple[int, J]], jobs: Sequence[J], describe: Callable[[J], str]
) -> None:
    index, job = pending.popleft()
    try:
        w.give(index, job)
    except OSError:  # the worker is already gone (broken pipe)
        raise _died(w, jobs, describe) from None


def _died(w: _Worker[Any], jobs: Sequence[Any], describe: Callable[[Any], str]) -> WorkerDiedError:
    w.proc.join(_STOP_TIMEOUT_S)
    code = w.proc.exitcode
    how = f"exit status {code}"
    if code is not None and code < 0:
        try:
            how = f"killed by {signal.Signals(-code).name}"
        except ValueError:
            how = f"killed by signal {-code}"
    what = f" while converting {describe(jobs[w.job])}" if w.job is not None else ""
    return WorkerDiedError(f"a worker process died{what} ({how})")
