"""dataset/_pool.py, _root.py: workers killed at random instants, the main process killed, the next run tidies up.

Each run is ``robocal dataset recalibrate --workers 2`` in its own process (``dataset_slowrun.py`` slows every
data file down so the kills land midway); the kill instants are drawn from a seeded generator. Processes are
found and judged through ``/proc`` (a zombie counts as dead: it runs nothing).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from dataset_testutil import A, B

from robocal.dataset import _pool, generate_dataset
from robocal.formats import write_calibration

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc")

SLOWRUN = Path(__file__).with_name("dataset_slowrun.py")
HANG_GUARD_S = 90.0
FILES = 12
SECONDS_PER_FILE = 0.2


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of a process, or None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text.rsplit(")", 1)[1].split()
    return fields[0], int(fields[1])


def _children(pid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit() and (st := _stat(int(entry))) is not None and st[1] == pid and st[0] != "Z":
            out.append(int(entry))
    return sorted(out)


def _running(pid: int) -> bool:
    st = _stat(pid)
    return st is not None and st[0] != "Z"


def _wait_for(cond: object, what: str) -> None:
    deadline = time.monotonic() + HANG_GUARD_S
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < deadline, f"hang guard: {what}"
        time.sleep(0.01)


@pytest.fixture()
def job(tmp_path: Path) -> tuple[Path, list[str]]:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=FILES, frames_per_episode=5, episodes_per_file=1, convention=A)
    write_calibration(tmp_path / "a.yaml", A.calibration, "robocal")
    write_calibration(tmp_path / "b.yaml", B.calibration, "robocal")
    args = [str(src), str(tmp_path / "dst"), "--old", str(tmp_path / "a.yaml"), "--new", str(tmp_path / "b.yaml")]
    return tmp_path, args


def _start(args: list[str]) -> tuple[subprocess.Popen[str], list[int]]:
    """Start a slowed run with two workers; return it and its workers once both are running."""
    proc = subprocess.Popen(
        [sys.executable, str(SLOWRUN), str(SECONDS_PER_FILE), *args, "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_for(lambda: len(_children(proc.pid)) == 2 or proc.poll() is not None, "workers start")
    return proc, _children(proc.pid)


def _leftovers(tmp_path: Path) -> list[str]:
    return sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".dst."))


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_worker_killed_at_a_random_instant_ends_the_run_cleanly(job: tuple[Path, list[str]], seed: int) -> None:
    """A worker killed at any instant: the run ends (no hang) with exit 3 and one error line, nothing written.

    (If the kill lands after the worker's last file, the run may finish: then exit 0 and a complete DST.)
    """
    tmp_path, args = job
    proc, workers = _start(args)
    assert len(workers) == 2
    rng = random.Random(seed)
    time.sleep(rng.uniform(0.0, FILES * SECONDS_PER_FILE / 2))  # the random instant itself, not a wait
    os.kill(workers[rng.randrange(2)], signal.SIGKILL)
    _out, err = proc.communicate(timeout=HANG_GUARD_S)
    assert [p for p in workers if _running(p)] == []
    assert _leftovers(tmp_path) == []
    if proc.returncode == 0:
        assert (tmp_path / "dst/meta/info.json").is_file()
        assert err == ""
        return
    assert proc.returncode == 3, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: a worker process died while converting "), err
    assert "(killed by SIGKILL" in lines[0] and "nothing was written" in lines[0]
    assert "Traceback" not in err and not (tmp_path / "dst").exists()


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "sig"), [(0, signal.SIGKILL), (1, signal.SIGKILL), (2, signal.SIGTERM)])
def test_killing_the_main_process_kills_the_workers_and_the_next_run_tidies_up(
    job: tuple[Path, list[str]], seed: int, sig: signal.Signals
) -> None:
    """The main process killed at a random instant: no worker survives it; the next run removes its folder."""
    tmp_path, args = job
    proc, workers = _start(args)
    assert len(workers) == 2
    rng = random.Random(seed)
    time.sleep(rng.uniform(0.0, FILES * SECONDS_PER_FILE / 2))
    left = _leftovers(tmp_path)  # the temporary root exists before the workers start
    os.kill(proc.pid, sig)
    proc.communicate(timeout=HANG_GUARD_S)
    assert proc.returncode == -sig
    _wait_for(lambda: not any(_running(p) for p in workers), "the workers die with the main process")
    if (tmp_path / "dst").exists():  # the kill came after the rename: a finished run
        return
    assert left == [f".dst.robocal-{proc.pid}-{left[0].rsplit('-', 1)[1]}"]
    assert _leftovers(tmp_path) == left
    # the next run (not slowed) removes the dead run's folder and says so
    done = subprocess.run(
        [sys.executable, "-m", "robocal", "dataset", "recalibrate", *args],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert (done.returncode, done.stderr) == (0, "")
    assert f"removed {tmp_path / left[0]}, left by a run that was killed (process {proc.pid})" in done.stdout
    assert _leftovers(tmp_path) == []
    assert (tmp_path / "dst/meta/info.json").is_file()


def test_folders_of_running_or_unknown_runs_are_named_not_removed(tmp_path: Path) -> None:
    """A folder of a live process, or without a process id, is kept and named; a dead run's previous DST is kept."""
    from robocal.dataset._root import sweep_leftovers

    dst = tmp_path / "dst"
    live = tmp_path / f".dst.robocal-{os.getppid()}-abcdefgh"
    unknown = tmp_path / ".dst.robocal-0a1b2c3d"
    dead_pid = _dead_pid()
    old = tmp_path / f".dst.old-{dead_pid}-zzzzzzzz"
    dead = tmp_path / f".dst.robocal-{dead_pid}-yyyyyyyy"
    other = tmp_path / ".dst2.robocal-12345678"  # another destination's
    for folder in (live, unknown, old / "root", dead, other):
        folder.mkdir(parents=True)
    notes, warnings = sweep_leftovers(dst)
    assert notes == [f"removed {dead}, left by a run that was killed (process {dead_pid})"]
    assert warnings == [
        f"{unknown} was left by an unknown run; remove it if no robocal run is writing {dst}",
        f"{live} was left by process {os.getppid()}, which is still running; remove it if no robocal run is "
        f"writing {dst}",
        f"{old / 'root'} holds {dst} as it was before a run (process {dead_pid}) was killed while replacing it; "
        f"move it back to {dst} or remove it",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (live, unknown, old, other))
    dst.mkdir()  # with DST in place, the previous one is garbage
    assert sweep_leftovers(dst)[0] == [f"removed {old}, left by a run that was killed (process {dead_pid})"]


def _dead_pid() -> int:
    """The id of a process that has exited (and been reaped)."""
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(proc.stdout)


def test_worker_exits_when_its_parent_is_already_gone() -> None:
    """die_with_parent: a parent id that is not the real parent (it died before the call) ends the process."""
    code = (
        "import os, sys; sys.path[:0] = " + repr(sys.path) + "\n"
        "from robocal.dataset._pool import die_with_parent\n"
        "die_with_parent(os.getppid() + 1)\n"
        "print('still here')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_GUARD_S)
    assert (done.returncode, done.stdout) == (1, "")
    assert _pool.WorkerDiedError.exit_code == 3


@pytest.mark.slow
@pytest.mark.parametrize("method", ["forkserver", "spawn"])
def test_workers_under_other_start_methods(tmp_path: Path, method: str) -> None:
    """Workers must be this process's children (forkserver's would see the server as their parent and quit at
    once): under forkserver the pool spawns them; spawn works as it is."""
    code = (
        "import multiprocessing, sys\n"
        f"sys.path[:0] = {sys.path!r}\n"
        "from pathlib import Path\n"
        "from dataset_testutil import A, B\n"
        "from robocal.dataset import generate_dataset, recalibrate_dataset\n"
        "if __name__ == '__main__':\n"
        f"    multiprocessing.set_start_method({method!r})\n"
        f"    root = Path({str(tmp_path)!r})\n"
        "    generate_dataset(root / 'src', n_episodes=4, frames_per_episode=5, episodes_per_file=1, convention=A)\n"
        "    rep = recalibrate_dataset(root / 'src', root / 'dst', A, B, workers=2)\n"
        "    print(rep.files, rep.frames)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_GUARD_S, cwd=Path(__file__).parent
    )
    assert (done.returncode, done.stdout) == (0, "4 20\n"), done.stderr
