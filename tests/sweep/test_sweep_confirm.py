"""A half-finished sweep never silently replaces good offsets: the terminal prompt, --yes and the non-TTY path.

The prompt is driven through a real pseudo-terminal, as a person at a terminal would answer it.
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path
from typing import Any

import pytest

from robocal.cli.main import main
from robocal.formats import read_calibration
from robocal.workflows.sweep.job import SweepRequest, run_sweep
from robocal.workflows.sweep.output import changes_to_confirm, keep_prior

ELBOW = "left_elbow_pitch"
WRIST = "right_wrist_roll"
GOOD = "sim:lite?seed=7"
SHORT = (
    "sim:lite?seed=7&short=left_elbow_pitch:0.5&short=right_wrist_roll:0.4"  # stopped short: span_mismatch
)
CODE = "import sys; from robocal.cli.main import main; sys.exit(main(sys.argv[1:]))"


class Terminal:
    """``robocal`` in a child process whose stdin, stdout and stderr are a pseudo-terminal (200 columns)."""

    def __init__(self, *args: str) -> None:
        self.master, slave = os.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 200, 0, 0))
        env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES", "NO_COLOR")}
        env["TERM"] = "xterm-256color"

        def controlling_tty() -> None:
            os.setsid()
            fcntl.ioctl(0, termios.TIOCSCTTY, 0)

        self.proc = subprocess.Popen(
            [sys.executable, "-c", CODE, *args],
            stdin=slave,
            stdout=slave,
            stderr=slave,
            env=env,
            preexec_fn=controlling_tty,
        )
        os.close(slave)
        self.out = b""

    def expect(self, text: str, timeout: float = 60.0) -> str:
        """Read until ``text`` appears; return everything read so far."""
        end = time.monotonic() + timeout
        while text.encode() not in self.out:
            if time.monotonic() > end:
                raise AssertionError(f"{text!r} did not appear; got:\n{self.text}")
            ready, _, _ = select.select([self.master], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(self.master, 65536)
                except OSError:
                    chunk = b""
                if not chunk and self.proc.poll() is not None:
                    raise AssertionError(f"{text!r} did not appear before exit; got:\n{self.text}")
                self.out += chunk
        return self.text

    def send(self, keys: str) -> None:
        os.write(self.master, keys.encode())

    def wait(self, timeout: float = 60.0) -> int:
        end = time.monotonic() + timeout
        while self.proc.poll() is None and time.monotonic() < end:
            ready, _, _ = select.select([self.master], [], [], 0.2)
            if ready:
                try:
                    self.out += os.read(self.master, 65536)
                except OSError:
                    break
        rc = self.proc.wait(timeout=5)
        os.close(self.master)
        return rc

    @property
    def text(self) -> str:
        return self.out.decode("utf-8", "replace").replace("\r\n", "\n")

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait()


@pytest.fixture
def good(urdf: Path, tmp_path: Path) -> dict[str, float]:
    """A good calibration in tmp_path/cal.yaml (a complete sweep); its offsets by joint."""
    out = tmp_path / "cal.yaml"
    assert main(["sweep", "--urdf", str(urdf), "--source", GOOD, "--out", str(out)]) == 1  # wrap_in_travel
    cal = read_calibration(out).calibration
    return dict(zip(cal.joint_names, map(float, cal.homing_offset), strict=True))


def _offsets(path: Path) -> dict[str, float]:
    cal = read_calibration(path).calibration
    return dict(zip(cal.joint_names, map(float, cal.homing_offset), strict=True))


def _sweep_args(urdf: Path, tmp_path: Path, *extra: str) -> list[str]:
    out, rep = tmp_path / "cal.yaml", tmp_path / "rep.json"
    return ["sweep", "--urdf", str(urdf), "--source", SHORT, "--out", str(out), "--report", str(rep), *extra]


@pytest.mark.slow
def test_terminal_asks_per_joint_and_keeps_the_declined_offset(
    urdf: Path, tmp_path: Path, good: dict[str, float]
) -> None:
    term = Terminal(*_sweep_args(urdf, tmp_path))
    try:
        screen = term.expect(f"{ELBOW}: replace {good[ELBOW]:+.4f} with ")
        # the old-vs-new table and the reason came first
        assert "replace their previous offset?" in screen and "span_mismatch" in screen
        assert f"warning: {ELBOW}: span_mismatch: swept " in screen
        term.send("n\r")
        term.expect(f"{WRIST}: replace {good[WRIST]:+.4f} with ")
        term.send("y\r")
        rc = term.wait()
    finally:
        term.kill()
    assert rc == 1, term.text
    assert f"keeping the previous offset of {ELBOW}" in term.text
    written = _offsets(tmp_path / "cal.yaml")
    report = json.loads((tmp_path / "rep.json").read_text())["joints"]
    assert written[ELBOW] == good[ELBOW]  # declined: the good offset stays, exactly
    assert report[ELBOW]["kept_prior"] is True and report[ELBOW]["homing_offset"] == good[ELBOW]
    assert report[ELBOW]["warnings"][0] == "span_mismatch"
    assert written[WRIST] == report[WRIST]["homing_offset"] != good[WRIST]  # accepted: the new one
    assert abs(written[WRIST] - good[WRIST]) > 0.1
    others = [n for n in written if n not in (ELBOW, WRIST)]
    assert all(written[n] == report[n]["homing_offset"] for n in others)  # no warning: no question


@pytest.mark.slow
@pytest.mark.parametrize(("answer", "elbow_new", "wrist_new"), [("all", True, True), ("none", False, False)])
def test_all_and_none_answer_for_the_rest(
    urdf: Path, tmp_path: Path, good: dict[str, float], answer: str, elbow_new: bool, wrist_new: bool
) -> None:
    term = Terminal(*_sweep_args(urdf, tmp_path))
    try:
        term.expect(f"{ELBOW}: replace ")
        term.send("maybe\r")  # not an answer: asked again
        term.expect("please answer y, n, all or none")
        term.send(f"{answer}\r")
        rc = term.wait()
    finally:
        term.kill()
    assert rc == 1
    assert term.text.count(": replace ") == 2  # the elbow twice, the wrist never
    written = _offsets(tmp_path / "cal.yaml")
    assert (written[ELBOW] != good[ELBOW]) is elbow_new
    assert (written[WRIST] != good[WRIST]) is wrist_new


@pytest.mark.slow
def test_end_of_input_keeps_every_prior_offset(urdf: Path, tmp_path: Path, good: dict[str, float]) -> None:
    term = Terminal(*_sweep_args(urdf, tmp_path))
    try:
        term.expect(f"{ELBOW}: replace ")
        term.send("\x04")  # Ctrl-D
        rc = term.wait()
    finally:
        term.kill()
    assert rc == 1
    written = _offsets(tmp_path / "cal.yaml")
    assert written[ELBOW] == good[ELBOW] and written[WRIST] == good[WRIST]


def test_ctrl_c_at_the_prompt_writes_nothing(urdf: Path, tmp_path: Path, good: dict[str, float]) -> None:
    before = (tmp_path / "cal.yaml").read_bytes()
    term = Terminal(*_sweep_args(urdf, tmp_path))
    try:
        term.expect(f"{ELBOW}: replace ")
        term.send("\x03")  # Ctrl-C while finishing: abort, nothing written
        rc = term.wait()
    finally:
        term.kill()
    assert rc == 130, term.text
    assert "nothing was written" in term.text
    assert (tmp_path / "cal.yaml").read_bytes() == before and not (tmp_path / "rep.json").exists()


@pytest.mark.slow
def test_yes_writes_every_new_offset_without_asking(
    urdf: Path, tmp_path: Path, good: dict[str, float]
) -> None:
    term = Terminal(*_sweep_args(urdf, tmp_path, "--yes"))
    try:
        rc = term.wait()
    finally:
        term.kill()
    assert rc == 1 and ": replace " not in term.text
    written = _offsets(tmp_path / "cal.yaml")
    assert written[ELBOW] != good[ELBOW] and written[WRIST] != good[WRIST]


@pytest.mark.slow
def test_without_a_terminal_nothing_is_asked(urdf: Path, tmp_path: Path, good: dict[str, float]) -> None:
    # a replay in CI: standard input and output are pipes; behaves as before (the new offsets are written)
    p = subprocess.run(
        [sys.executable, "-c", CODE, *_sweep_args(urdf, tmp_path)],
        input="n\nn\n",
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 1 and ": replace " not in p.stdout + p.stderr
    written = _offsets(tmp_path / "cal.yaml")
    assert written[ELBOW] != good[ELBOW] and written[WRIST] != good[WRIST]


@pytest.mark.slow
def test_workflow_confirm_sees_only_changed_offsets_with_a_doubtful_warning(
    urdf: Path, tmp_path: Path, good: dict[str, float], h: Any
) -> None:
    asked: list[tuple[str, ...]] = []

    def confirm(result: Any, names: Any) -> set[str]:
        asked.append(tuple(names))
        assert changes_to_confirm(result) == list(names)
        return set()

    outcome = run_sweep(SweepRequest(urdf, SHORT, tmp_path / "cal.yaml"), confirm=confirm)
    assert asked == [(ELBOW, WRIST)]  # wrap_in_travel of left_shoulder_pitch is no reason to ask
    assert outcome.result[ELBOW].homing_offset == good[ELBOW] and outcome.result[ELBOW].kept_prior
    # a joint without a prior offset has nothing to protect: nothing is asked
    fresh = tmp_path / "fresh.yaml"
    asked.clear()
    run_sweep(SweepRequest(urdf, SHORT, fresh), confirm=confirm)
    assert asked == []
    assert keep_prior(outcome.result, []) == outcome.result


@pytest.mark.slow
def test_enter_finishes_a_sweep_that_is_still_running(urdf: Path, tmp_path: Path) -> None:
    # a recording that is still being written (a FIFO fed row by row) never ends by itself: only Enter ends it
    import threading

    import numpy as np

    from robocal.backends.sim.lite import LITE_JOINTS

    fifo = tmp_path / "live.csv"
    os.mkfifo(fifo)
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])
    stop = threading.Event()

    def feed() -> None:
        with open(fifo, "w") as fh:
            fh.write("t," + ",".join(j.name for j in LITE_JOINTS) + "\n")
            k = 0
            try:
                while not stop.is_set() and k < 1_000_000:
                    rows = []
                    for _ in range(200):
                        x = 0.5 - 0.5 * np.cos(2 * np.pi * k / 20000)  # a full sweep every 20000 rows
                        rows.append(",".join(f"{v:.6f}" for v in (k / 1000, *(lo + (up - lo) * x))))
                        k += 1
                    fh.write("\n".join(rows) + "\n")
                    fh.flush()
                    time.sleep(0.02)
            except BrokenPipeError:
                pass

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    out = tmp_path / "cal.yaml"
    term = Terminal("sweep", "--urdf", str(urdf), "--source", f"replay:{fifo}", "--out", str(out), "--yes")
    try:
        term.expect("Enter or Ctrl-C to finish")
        time.sleep(1.0)
        term.send("\r")  # Enter
        rc = term.wait(timeout=60)
    finally:
        stop.set()
        term.kill()
    assert rc in (0, 1), term.text
    assert "sweep result" in term.text and out.exists()
    writer.join(timeout=10)
