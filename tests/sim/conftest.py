"""Running ``robocal sim`` as a separate process, as a person would in a second terminal."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robocal.backends import REPLY_TIMEOUT_ENV

CLIENT_ENV = {REPLY_TIMEOUT_ENV: "2000", "COLUMNS": "200"}


def open_sdk(sdk: Any, port: str, baud: int, protocol: float) -> tuple[Any, Any]:
    """A vendor SDK's (scservo_sdk / dynamixel_sdk) port and packet handler on a simulator's pseudo-terminal.

    Every packet timeout is at least 500 ms: the simulator shares the cores with the test suite.
    """
    ph = sdk.PortHandler(port)
    assert ph.openPort() and ph.setBaudRate(baud)
    original = ph.setPacketTimeout

    def at_least_500_ms(packet_length: int) -> None:
        original(packet_length)
        ph.packet_timeout = max(ph.packet_timeout, 500.0)

    ph.setPacketTimeout = at_least_500_ms
    return ph, sdk.PacketHandler(protocol)


"""Environment of robocal's commands that talk to a ``robocal sim`` process: the simulator is a process the
machine's load can hold up for a moment, so a reply is waited for up to 2 s (a servo's 100 ms is meant for a
motor that answers in 1 ms); a simulator that never answers still times out."""


class SimProcess:
    """A ``robocal sim ...`` child process and the lines it printed at start."""

    def __init__(self, args: list[str], cwd: Path, until: str = "control") -> None:
        view = [] if args[:1] == ["ur"] else ["--no-view"]
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "robocal", "sim", *args, *view],
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.info: dict[str, str] = {}
        assert self.proc.stdout is not None
        lines: queue.Queue[str] = queue.Queue()
        stdout = self.proc.stdout

        def read_lines() -> None:
            for line in iter(stdout.readline, ""):
                lines.put(line)
                if line.startswith(f"{until}: "):
                    return  # the rest stays in the pipe, unread, as before
            lines.put("")

        threading.Thread(target=read_lines, daemon=True).start()
        deadline = time.monotonic() + 120  # a hang guard only: starting can take long on a loaded machine
        while until not in self.info:
            try:
                line = lines.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                self.proc.kill()
                raise AssertionError(f"robocal sim: no {until!r} line within 120 s: {self.info}") from None
            if not line:
                err = self.proc.stderr.read() if self.proc.stderr else ""
                raise AssertionError(f"robocal sim exited early ({self.proc.wait()}): {err}")
            key, sep, value = line.rstrip("\n").partition(": ")
            if sep:
                self.info[key] = value

    def stop(self) -> tuple[int, str]:
        """Ctrl-C; returns exit code and standard error."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            _, err = self.proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        return self.proc.returncode, err


@pytest.fixture
def sim_process(tmp_path: Path) -> Iterator[type[SimProcess]]:
    started: list[SimProcess] = []

    class Tracked(SimProcess):
        def __init__(self, args: list[str], cwd: Path = tmp_path, until: str = "control") -> None:
            super().__init__(args, cwd, until)
            started.append(self)

    yield Tracked
    for p in started:
        p.stop()


def robocal(
    *args: str, cwd: Path, stdin: str | None = None, timeout: float = 120
) -> subprocess.CompletedProcess[str]:
    """Run the robocal CLI in a child process."""
    env = dict(os.environ, **CLIENT_ENV)
    return subprocess.run(
        [sys.executable, "-m", "robocal", *args],
        cwd=cwd,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


class Interactive:
    """A child process whose prompts are answered as a person would: wait for the text, then type."""

    def __init__(self, argv: list[str], cwd: Path, env: dict[str, str] | None = None) -> None:
        import threading

        self.proc = subprocess.Popen(
            argv,
            cwd=cwd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            env=dict(env or os.environ, **CLIENT_ENV),
        )
        self.output = b""
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        while True:
            chunk = self.proc.stdout.read1(4096)
            if not chunk:
                return
            with self._lock:
                self.output += chunk

    def text(self) -> str:
        with self._lock:
            return self.output.decode(errors="replace")

    def expect(self, needle: str, timeout: float = 60.0, after: int = 0) -> int:
        """Wait until ``needle`` appears in the output (at or after ``after``); returns the end of the match."""
        deadline = time.monotonic() + timeout
        while True:
            text = self.text()
            k = text.find(needle, after)
            if k >= 0:
                return k + len(needle)
            if self.proc.poll() is not None and not self._reader.is_alive():
                raise AssertionError(f"exited {self.proc.returncode} before {needle!r}:\n{text[-3000:]}")
            if time.monotonic() > deadline:
                raise AssertionError(f"no {needle!r} within {timeout} s:\n{text[-3000:]}")
            time.sleep(0.02)

    def send(self, line: str = "") -> None:
        """Type ``line`` and ENTER. A child that already exited fails the test with its own output (its error
        message), not with the BrokenPipeError of writing to a closed pipe."""
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(line.encode() + b"\n")
            self.proc.stdin.flush()
        except BrokenPipeError:
            code, out = self.finish(timeout=60.0)
            raise AssertionError(f"exited {code} before reading {line!r}:\n{out[-3000:]}") from None

    def finish(self, timeout: float = 120.0) -> tuple[int, str]:
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(timeout=5)
        return self.proc.returncode, self.text()

    def calibrate_as_operator(self, control: str, mid_prompt: str, sweep_prompt: str) -> tuple[int, str]:
        """Answer a range calibration's two prompts through the simulator's control socket ``control``: hold
        every joint at the middle, ENTER; sweep every joint, ENTER. The exit code and the output."""
        from robocal.backends.sim.control import SimControl

        with SimControl(control) as ctl:
            k = self.expect(mid_prompt)
            ctl.mid()
            self.send()
            self.expect(sweep_prompt, after=k)
            # paced: the hand moves on only once the command read where it is (both stops seen, however loaded)
            ctl.sweep(seconds=1.2, dwell_s=0.2, paced=True)
            self.send()
        return self.finish()
