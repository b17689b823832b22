"""Running a simulated robot as a standalone device (``robocal sim``): the stable link and the control socket.

A :class:`Session` owns what a running simulator exposes besides its wire: an optional symlink to the
pseudo-terminal (``--link``), the operator's :class:`~robocal.backends.sim.operator.HandOperator` and its
:class:`~robocal.backends.sim.control.ControlServer`. Everything it creates is removed on :meth:`close`.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import shutil
import tempfile
from collections.abc import Callable, Mapping
from typing import Any

from ...core.lifecycle import ClosesOnExit
from ...errors import UsageError
from .control import ControlServer, Handler
from .operator import HandDevice, HandOperator

__all__ = ["Session", "in_dev", "make_link", "remove_link"]


def in_dev(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` would be in ``/dev`` (its folder, resolved, is ``/dev``)."""
    return pathlib.Path(os.path.abspath(os.fspath(path))).parent.resolve() == pathlib.Path("/dev").resolve()


def make_link(link: str | os.PathLike[str], target: str) -> pathlib.Path:
    """Point the symlink ``link`` at ``target`` (replacing a stale symlink atomically, never a file).

    Raises:
        UsageError: ``link`` exists and is not a symlink, or its folder does not exist.
    """
    path = pathlib.Path(link)
    if path.exists() and not path.is_symlink():
        raise UsageError(f"--link {path}: exists and is not a symlink; choose another path")
    if not path.parent.is_dir():
        raise UsageError(f"--link {path}: folder {path.parent} does not exist")
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    os.symlink(target, tmp)
    os.replace(tmp, path)
    return path


def remove_link(link: pathlib.Path, target: str) -> None:
    """Remove ``link`` if it still points at ``target`` (another simulator may have taken it over)."""
    with contextlib.suppress(OSError):
        if link.is_symlink() and os.readlink(link) == target:
            link.unlink()


class Session(ClosesOnExit):
    """The link and control socket of one running simulator.

    Args:
        device: The hand-movable simulated robot.
        name: Device name (shown by ``state``).
        wire: What clients open: the pty path (or a CAN channel / address, shown only).
        link: Symlink to create to ``wire`` (pty only).
        control: Control socket path; default ``<link>.control`` with a link outside ``/dev``, else in a new
            temporary folder (a socket beside ``/dev/ttyX`` would be listed as a serial port by ``/dev/tty*``
            scanners such as ``lerobot-find-port``).
        extra: Extra control commands.
        on_usb: With a link: the ``usb`` control command (``{"cmd": "usb", "plugged": false}``) unplugs the
            simulated USB cable (the link vanishes, then this is called with False) and plugs it back in (the
            link returns, then True).
    """

    def __init__(
        self,
        device: HandDevice,
        name: str,
        wire: str,
        *,
        link: str | os.PathLike[str] | None = None,
        control: str | os.PathLike[str] | None = None,
        extra: Mapping[str, Handler] | None = None,
        on_usb: Callable[[bool], None] | None = None,
    ) -> None:
        self.wire = wire
        self._tmpdir: str | None = None
        self.plugged = True
        self._on_usb = on_usb
        if link is not None and on_usb is not None:
            extra = {**dict(extra or {}), "usb": self._usb}
        if control is None:
            if link is not None and not in_dev(link):
                control = f"{os.fspath(link)}.control"
            else:
                self._tmpdir = tempfile.mkdtemp(prefix="robocal-sim-")
                control = os.path.join(self._tmpdir, "control.sock")
        self.control_path = os.path.abspath(os.fspath(control))
        self.link: pathlib.Path | None = None
        self.operator = HandOperator(device)
        try:
            self.server = ControlServer(self.control_path, self.operator, name, extra).start()
        except BaseException:
            self._cleanup_partial()
            raise
        try:
            self.link = make_link(link, wire) if link is not None else None
        except BaseException:
            self.server.close()
            self._cleanup_partial()
            raise

    def _usb(self, req: dict[str, Any]) -> dict[str, Any]:
        plugged = req.get("plugged")
        if not isinstance(plugged, bool):
            raise UsageError("usb: 'plugged' must be true or false")
        self.set_plugged(plugged)
        return {"plugged": self.plugged, "link": str(self.link)}

    def set_plugged(self, plugged: bool) -> None:
        """Unplug (the link vanishes, then ``on_usb(False)``) or plug the simulated USB cable back in."""
        if self.link is None or plugged == self.plugged:
            return
        if plugged:
            make_link(self.link, self.wire)
        else:
            remove_link(self.link, self.wire)
        self.plugged = plugged
        if self._on_usb is not None:
            self._on_usb(plugged)

    def _cleanup_partial(self) -> None:
        self.operator.close()
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)

    def info(self) -> dict[str, Any]:
        """Port (or channel), link and control socket paths."""
        return {
            "wire": self.wire,
            "link": str(self.link) if self.link else None,
            "plugged": self.plugged,
            "control": self.control_path,
        }

    def close(self) -> None:
        """Stop the operator, remove the control socket and the link."""
        self.operator.release()
        self.server.close()
        if self.link is not None:
            remove_link(self.link, self.wire)
        self._cleanup_partial()
