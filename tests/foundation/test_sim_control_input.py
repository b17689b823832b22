"""The simulator control socket: hostile request lines and garbage answers are errors, not crashes."""

from __future__ import annotations

import socket
import threading
from pathlib import Path
from types import SimpleNamespace

import pytest

from robocal.backends.sim.control import ControlServer, SimControl
from robocal.errors import ProtocolError


def test_deeply_nested_request_is_an_error_answer() -> None:
    server = SimpleNamespace(commands={})
    answer = ControlServer.handle_line(server, "[" * 100_000 + "]" * 100_000)  # type: ignore[arg-type]
    assert answer == {"ok": False, "error": "not a JSON object: nested too deeply"}


@pytest.mark.parametrize("reply", [b"not json\n", b"[" * 50_000 + b"\n", b"[1, 2]\n"])
def test_garbage_answer_is_a_protocol_error(tmp_path: Path, reply: bytes) -> None:
    path = str(tmp_path / "c.sock")
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen(1)

    def serve() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.makefile("rb").readline()
            conn.sendall(reply)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        client = SimControl(path, timeout_s=10)
        with pytest.raises(
            ProtocolError, match=r"c\.sock: the simulator's answer is not (JSON|a JSON object)"
        ):
            client.request("state")
    finally:
        t.join(5)
        listener.close()
