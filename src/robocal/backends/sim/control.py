"""The operator control interface of ``robocal sim``: line-delimited JSON on a local Unix socket.

One request per line, one answer per line, on a connection that can carry any number of requests::

    → {"cmd": "state"}
    ← {"ok": true, "device": "so101_follower", "unit": "ticks", "joints": [{"name": "shoulder_pan", ...}]}
    → {"cmd": "push", "joint": "gripper", "stop": "max"}
    ← {"ok": true, "positions": {"gripper": 3400.0}}
    → {"cmd": "bogus"}
    ← {"ok": false, "error": "unknown command 'bogus'; commands: attach, mid, move, push, release, ..."}

Commands (``joint``/``joints``: a name, a list of names, or ``"all"``; positions in the device unit):

=========== ========================================================= ==========================================
command     fields                                                    answer
=========== ========================================================= ==========================================
state                                                                 ``device``, ``unit``, ``busy``, ``joints``
move        ``joint``, ``to`` or ``by``                               ``position``
push        ``joints`` (default all), ``stop``: ``min``/``max``       ``positions``
mid         ``joints`` (default all)                                  ``positions``
sweep       ``joints`` (default all), ``seconds`` (3), ``dwell_s``     ``seconds`` (until done), ``done``
            (0.3), ``wait`` (false), ``paced`` (false: see
            :meth:`HandOperator.sweep <.operator.HandOperator.sweep>`)
release                                                               (stops every running motion)
wait        ``timeout_s`` (60)                                        ``idle``
attach      ``joints`` (servo arms: the motors plugged into the bus)  ``attached``
=========== ========================================================= ==========================================

:class:`SimControl` is the Python client (used by the tests and usable from scripts).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ...core.lifecycle import ClosesOnExit
from ...errors import CalibTimeoutError, DeviceError, ProtocolError, UsageError
from ._sockets import accept_loop
from .operator import HandOperator

__all__ = ["ControlServer", "SimControl"]

Handler = Callable[[dict[str, Any]], dict[str, Any]]


def _joints(req: Mapping[str, Any], key: str = "joints") -> str | list[str] | None:
    value = req.get(key, req.get("joint"))
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return value
    raise UsageError(f'{key!r} must be a joint name, a list of names or "all"')


def _number(req: Mapping[str, Any], key: str, default: float | None = None) -> float | None:
    value = req.get(key, default)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or value != value:
        raise UsageError(f"{key!r} must be a number, not {value!r}")
    return float(value)


class ControlServer:
    """Serves the control interface for one simulated device on a Unix socket.

    Args:
        path: Socket path (created; refused when something other than a stale socket is there).
        operator: The hands that carry out the motions.
        device: Device name reported by ``state``.
        extra: Extra commands (name → handler taking the request, returning answer fields).
    """

    def __init__(
        self, path: str, operator: HandOperator, device: str, extra: Mapping[str, Handler] | None = None
    ) -> None:
        self.path = path
        self.operator = operator
        self.device = device
        self.commands: dict[str, Handler] = {
            "state": self._state,
            "move": self._move,
            "push": self._push,
            "mid": self._mid,
            "sweep": self._sweep,
            "release": self._release,
            "wait": self._wait,
            **dict(extra or {}),
        }
        if os.path.lexists(path):
            import stat

            if not stat.S_ISSOCK(os.lstat(path).st_mode):
                raise UsageError(f"{path}: exists and is not a socket; choose another --control path")
            probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                probe.connect(path)
            except OSError:
                os.unlink(path)  # a stale socket of a simulator that is gone
            else:
                raise UsageError(f"{path}: another simulator is listening there")
            finally:
                probe.close()
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._sock.bind(path)
        except OSError as exc:
            self._sock.close()
            raise DeviceError(f"{path}: cannot create the control socket ({exc.strerror or exc})") from None
        self._sock.listen(8)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._accept, name="sim-control", daemon=True)

    def start(self) -> ControlServer:
        """Start accepting connections."""
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop accepting and remove the socket file."""
        self._stop.set()
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)
        self._sock.close()
        self._thread.join(timeout=2.0)
        with contextlib.suppress(OSError):
            os.unlink(self.path)

    def __enter__(self) -> ControlServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------------------------------------- serving
    def _accept(self) -> None:
        accept_loop(self._sock, self._stop, self._accepted)

    def _accepted(self, conn: socket.socket) -> None:
        threading.Thread(target=self._serve, args=(conn,), name="sim-control-conn", daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        with conn, conn.makefile("rwb") as f:
            for line in f:
                if not line.strip():
                    continue
                answer = self.handle_line(line)
                try:
                    f.write(json.dumps(answer).encode() + b"\n")
                    f.flush()
                except OSError:
                    return

    def handle_line(self, line: bytes | str) -> dict[str, Any]:
        """Answer one request line (never raises: errors become ``{"ok": false, "error": ...}``)."""
        try:
            req = json.loads(line)
        except (ValueError, UnicodeDecodeError) as exc:
            return {"ok": False, "error": f"not a JSON object: {exc}"}
        except RecursionError:
            return {"ok": False, "error": "not a JSON object: nested too deeply"}
        if not isinstance(req, dict):
            return {"ok": False, "error": "a request is a JSON object with a 'cmd' field"}
        cmd = req.get("cmd")
        handler = self.commands.get(cmd) if isinstance(cmd, str) else None
        if handler is None:
            return {
                "ok": False,
                "error": f"unknown command {cmd!r}; commands: {', '.join(sorted(self.commands))}",
            }
        try:
            return {"ok": True, **handler(req)}
        except UsageError as exc:
            return {"ok": False, "error": str(exc)}

    # ---------------------------------------------------------------------------------------- commands
    def _state(self, req: dict[str, Any]) -> dict[str, Any]:
        return {
            "device": self.device,
            "unit": self.operator.device.unit,
            "busy": self.operator.busy,
            "joints": [v.as_dict() for v in self.operator.state()],
        }

    def _move(self, req: dict[str, Any]) -> dict[str, Any]:
        joint = req.get("joint")
        if not isinstance(joint, str):
            raise UsageError("move: 'joint' must be one joint name")
        return {"position": self.operator.move(joint, to=_number(req, "to"), by=_number(req, "by"))}

    def _push(self, req: dict[str, Any]) -> dict[str, Any]:
        return {"positions": self.operator.push(_joints(req), str(req.get("stop")))}

    def _mid(self, req: dict[str, Any]) -> dict[str, Any]:
        return {"positions": self.operator.mid(_joints(req))}

    def _sweep(self, req: dict[str, Any]) -> dict[str, Any]:
        paced = req.get("paced", False)
        if not isinstance(paced, bool):
            raise UsageError(f"'paced' must be true or false, not {paced!r}")
        seconds = self.operator.sweep(
            _joints(req),
            seconds=_number(req, "seconds", 3.0) or 0.0,
            dwell_s=_number(req, "dwell_s", 0.3) or 0.0,
            paced=paced,
        )
        done = True
        if req.get("wait"):  # a paced sweep lasts as long as the client takes to read it: wait longer
            done = self.operator.wait(seconds + (60.0 if paced else 30.0))
        return {"seconds": seconds, "done": done}

    def _release(self, req: dict[str, Any]) -> dict[str, Any]:
        self.operator.release()
        return {}

    def _wait(self, req: dict[str, Any]) -> dict[str, Any]:
        return {"idle": self.operator.wait(_number(req, "timeout_s", 60.0) or 0.0)}


class SimControl(ClosesOnExit):
    """Client of a ``robocal sim`` control socket.

    Args:
        path: The socket path ``robocal sim`` printed (``control: PATH``).
        timeout_s: Per-request timeout.

    Raises:
        DeviceError: Nothing listens at ``path``.
    """

    def __init__(self, path: str | os.PathLike[str], timeout_s: float = 90.0) -> None:
        self.path = os.fspath(path)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.settimeout(timeout_s)
        try:
            self._sock.connect(self.path)
        except OSError as exc:
            self._sock.close()
            raise DeviceError(f"{self.path}: no simulator control socket ({exc.strerror or exc})") from None
        self._file = self._sock.makefile("rwb")

    def request(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Send one command; return the answer's fields.

        Raises:
            UsageError: The simulator refused the command (its message).
            CalibTimeoutError: No answer in time.
        """
        try:
            self._file.write(json.dumps({"cmd": cmd, **fields}).encode() + b"\n")
            self._file.flush()
            line = self._file.readline()
        except TimeoutError:
            raise CalibTimeoutError(f"{self.path}: no answer to {cmd!r}") from None
        if not line:
            raise DeviceError(f"{self.path}: the simulator closed the connection")
        try:
            answer: dict[str, Any] = json.loads(line)
        except (ValueError, RecursionError):
            raise ProtocolError(f"{self.path}: the simulator's answer is not JSON: {line[:80]!r}") from None
        if not isinstance(answer, dict):
            raise ProtocolError(f"{self.path}: the simulator's answer is not a JSON object: {line[:80]!r}")
        if not answer.pop("ok", False):
            raise UsageError(str(answer.get("error")))
        return answer

    def state(self) -> dict[str, dict[str, Any]]:
        """Joint name → state (position, low, high, mid, torque, reading, last_write, ...)."""
        return {j["name"]: j for j in self.request("state")["joints"]}

    def move(self, joint: str, *, to: float | None = None, by: float | None = None) -> float:
        """Move a joint to / by (device unit); returns where it ended."""
        fields: dict[str, Any] = {"joint": joint}
        if to is not None:
            fields["to"] = to
        if by is not None:
            fields["by"] = by
        return float(self.request("move", **fields)["position"])

    def push(self, joints: str | Sequence[str] = "all", stop: str = "max") -> dict[str, float]:
        """Push joints into their ``min``/``max`` stop."""
        return dict(self.request("push", joints=joints, stop=stop)["positions"])

    def mid(self, joints: str | Sequence[str] = "all") -> dict[str, float]:
        """Hold joints at the middle of their range."""
        return dict(self.request("mid", joints=joints)["positions"])

    def sweep(
        self,
        joints: str | Sequence[str] = "all",
        *,
        seconds: float = 3.0,
        dwell_s: float = 0.3,
        wait: bool = True,
        paced: bool = False,
    ) -> float:
        """Sweep joints stop to stop (waits for the end unless ``wait=False``); returns its duration.

        ``paced``: each joint the client reads moves on only once the client read it (both stops are seen, however
        loaded the machine is); see :meth:`HandOperator.sweep <robocal.backends.sim.operator.HandOperator.sweep>`.

        Raises:
            CalibTimeoutError: With ``wait``, the sweep did not end in time.
        """
        fields: dict[str, Any] = {"joints": joints, "seconds": seconds, "dwell_s": dwell_s, "wait": wait}
        if paced:
            fields["paced"] = True
        answer = self.request("sweep", **fields)
        if wait and not answer.get("done", True):
            raise CalibTimeoutError(f"{self.path}: the sweep did not end in time")
        return float(answer["seconds"])

    def release(self) -> None:
        """Stop every running motion."""
        self.request("release")

    def attach(self, joints: str | Sequence[str] = "all") -> list[str]:
        """Servo arms: plug exactly these motors into the bus."""
        return list(self.request("attach", joints=joints)["attached"])

    def usb(self, plugged: bool) -> bool:
        """Unplug (False) or plug back (True) the simulated USB cable of a device served with a link."""
        return bool(self.request("usb", plugged=plugged)["plugged"])

    def close(self) -> None:
        """Close the connection."""
        with contextlib.suppress(OSError):
            self._file.close()
        self._sock.close()
