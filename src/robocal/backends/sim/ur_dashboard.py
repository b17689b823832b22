"""Simulated UR dashboard server (TCP 29999): one ASCII line in, one line out.

On connect it sends ``Connected: Universal Robots Dashboard Server``; every command line (ending in a newline)
gets one reply line with the text URCL's dashboard client matches (its ``g_command_list``), and commands that
change the arm (``power on/off``, ``brake release``, ``play`` …) change the shared :class:`UrArmState` that the
primary/secondary streams report. ``quit`` answers ``Disconnected`` and closes. Sources and assumptions:
docs/sim.md (UR section).
"""

from __future__ import annotations

import socket
from collections.abc import Callable

from ...core.lifecycle import StartsOnEnter
from ._sockets import LoopbackServer
from .ur_arm_state import UrArmState

__all__ = ["DASHBOARD_GREETING", "SimUrDashboard", "dashboard_reply"]

DASHBOARD_GREETING = "Connected: Universal Robots Dashboard Server"
"""The line the server sends on connect."""

_MAX_LINE_BYTES = 4096


def dashboard_reply(arm: UrArmState, line: str, *, version: str = "5.8.0.0") -> str:
    """The reply to one dashboard command (without the newline), applying its effect to ``arm``.

    Args:
        arm: The arm the command acts on.
        line: The command as received (surrounding whitespace is ignored).
        version: Software version ``version`` / ``PolyscopeVersion`` report (matches the primary interface's
            version message).
    """
    cmd = line.strip()
    low = cmd.lower()
    simple: dict[str, Callable[[], str]] = {
        "robotmode": lambda: f"Robotmode: {arm.robot_mode_name}",
        "safetymode": lambda: f"Safetymode: {arm.safety_mode}",
        "safetystatus": lambda: f"Safetystatus: {arm.safety_mode}",
        "programstate": lambda: f"{arm.program_state} {arm.program or '<unnamed>'}",
        "running": lambda: f"Program running: {str(arm.program_state == 'PLAYING').lower()}",
        "get serial number": lambda: arm.serial_number,
        "get robot model": lambda: arm.model,
        "polyscopeversion": lambda: f"URSoftware {version} (Jan 01 2026)",
        "version": lambda: version,
        "is in remote control": lambda: "true",
        "get loaded program": lambda: arm.program or "No program loaded",
        "quit": lambda: "Disconnected",
        "unlock protective stop": lambda: "Protective stop releasing",
        "close safety popup": lambda: "closing safety popup",
        "close popup": lambda: "closing popup",
    }
    if low in simple:
        return simple[low]()
    if low == "power on":
        arm.power_on()
        return "Powering on"
    if low == "power off":
        arm.power_off()
        return "Powering off"
    if low == "brake release":
        arm.brake_release()
        return "Brake releasing"
    if low == "restart safety":
        arm.power_off()
        return "Restarting safety"
    if low == "play":
        return "Starting program" if arm.play() else f"Failed to execute: {cmd}"
    if low == "pause":
        return "Pausing program" if arm.pause() else f"Failed to execute: {cmd}"
    if low == "stop":
        arm.stop_program()
        return "Stopped"
    if low.startswith("load ") and cmd[5:].strip():
        program = cmd[5:].strip()
        arm.load(program)
        return f"Loading program: {program}"
    return f"Could not understand: '{cmd}'"


class SimUrDashboard(LoopbackServer, StartsOnEnter):
    """Loopback dashboard server on a real TCP socket (context manager).

    Args:
        arm: The arm state commands act on (shared with the primary stream).
        host: Bind address.
        port: Bind port (0 = a free port; see :attr:`address`).
        version: Software version reported.

    Raises:
        OSError: The address cannot be bound.
    """

    def __init__(
        self, arm: UrArmState, *, host: str = "127.0.0.1", port: int = 0, version: str = "5.8.0.0"
    ) -> None:
        super().__init__(host=host, port=port, name="sim-ur-dashboard")
        self.arm = arm
        self.version = version

    def _serve(self, conn: socket.socket) -> None:
        conn.settimeout(None)
        conn.sendall((DASHBOARD_GREETING + "\n").encode())
        buf = b""
        while not self.stopping:
            data = conn.recv(4096)
            if not data:
                return
            buf += data
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                line = raw.decode("ascii", "replace")
                conn.sendall((dashboard_reply(self.arm, line, version=self.version) + "\n").encode())
                if line.strip().lower() == "quit":
                    return
            if len(buf) > _MAX_LINE_BYTES:  # no newline in sight: answer and drop it
                conn.sendall((dashboard_reply(self.arm, buf.decode("ascii", "replace")) + "\n").encode())
                buf = b""
