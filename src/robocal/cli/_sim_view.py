"""The live terminal view of ``robocal sim``: one row per joint, keys to move the joints by hand."""

from __future__ import annotations

import contextlib
import os
import select
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from ..errors import CalibError

if TYPE_CHECKING:
    from ..backends.sim.operator import HandOperator, JointView

__all__ = ["KEYS", "run_view"]

KEYS = (
    "↑/↓ select  ←/→ move (−/+ step)  +/- step ×2/÷2  [ ] push to min/max stop  m middle  M all middle  "
    "s sweep all  S sweep selected  r release  c plug in only selected  a plug in all  u USB cable out/in  q quit"
)
"""The key help line shown under the table."""


def _fmt(value: float, unit: str) -> str:
    return f"{value:.0f}" if unit == "ticks" else f"{value:+.3f}"


def _table(title: str, views: list[JointView], selected: int, unit: str, busy: bool) -> Table:
    t = Table(title=Text(title + ("  (moving)" if busy else "")), title_justify="left")
    cols = [
        "",
        "joint",
        f"position ({unit})",
        "low stop",
        "high stop",
        "reading",
        "torque",
        "last client write",
    ]
    for c in cols:
        t.add_column(
            c, justify="right" if c in ("low stop", "high stop", "reading") or c.startswith("pos") else "left"
        )
    for k, v in enumerate(views):
        extra = v.extra
        name = v.name
        if "id" in extra:
            name += f" (id {extra['id']}" + ("" if extra.get("attached", True) else ", unplugged") + ")"
        age = "" if v.last_write_age_s is None else f" ({v.last_write_age_s:.1f} s ago)"
        t.add_row(
            "▶" if k == selected else "",
            name,
            _fmt(v.position, unit),
            _fmt(v.low, unit),
            _fmt(v.high, unit),
            _fmt(v.reading, unit),
            "on" if v.torque else "off",
            (v.last_write or "—") + age,
            style="bold" if k == selected else None,
        )
    return t


@contextlib.contextmanager
def _cbreak(fd: int) -> Iterator[None]:
    old = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


def _keys(fd: int, timeout_s: float) -> list[str]:
    ready, _, _ = select.select([fd], [], [], timeout_s)
    if not ready:
        return []
    data = os.read(fd, 64).decode(errors="replace")
    out: list[str] = []
    i = 0
    arrows = {"A": "up", "B": "down", "C": "right", "D": "left"}
    while i < len(data):
        if data.startswith("\x1b[", i) and i + 2 < len(data) and data[i + 2] in arrows:
            out.append(arrows[data[i + 2]])
            i += 3
        else:
            out.append(data[i])
            i += 1
    return out


def run_view(
    operator: HandOperator,
    title: str,
    header: str,
    stop: threading.Event,
    attach: Callable[[list[str] | None], object] | None = None,
    usb: Callable[[], bool] | None = None,
) -> None:
    """Show the joints live on the terminal and act on keys until ``q``, Ctrl-C or ``stop``.

    Args:
        operator: The hands that move the joints.
        title: Table title.
        header: Lines shown above the table (port, link, control socket).
        stop: Set by a signal handler to end the view.
        attach: Plug in motors (servo arms): None = all, else these joints only.
        usb: Unplug / plug back the USB cable (``u``; with a link); returns whether it is plugged in now.
    """
    console = Console(highlight=False)
    names = list(operator.device.joint_names())
    unit = operator.device.unit
    selected = 0
    step = operator.device.step
    message = ""
    fd = sys.stdin.fileno()

    def render() -> Group:
        views = operator.state()
        return Group(
            Text(header),
            _table(title, views, selected, unit, operator.busy),
            Text(f"step {_fmt(step, unit) if unit == 'ticks' else f'{step:.3f}'} {unit}   {message}"),
            Text(KEYS, style="dim"),
        )

    with _cbreak(fd), Live(render(), console=console, refresh_per_second=10, screen=False) as live:
        while not stop.is_set():
            for key in _keys(fd, 0.1):
                name = names[selected]
                try:
                    message = ""
                    if key == "q":
                        return
                    if key in ("up", "k"):
                        selected = (selected - 1) % len(names)
                    elif key in ("down", "j"):
                        selected = (selected + 1) % len(names)
                    elif key in ("left", "right", "h", "l"):
                        operator.move(name, by=step if key in ("right", "l") else -step)
                    elif key == "+":
                        step *= 2
                    elif key == "-":
                        step /= 2
                    elif key in ("[", "]"):
                        operator.push(name, "min" if key == "[" else "max")
                    elif key == "m":
                        operator.mid(name)
                    elif key == "M":
                        operator.mid()
                    elif key == "s":
                        operator.sweep()
                    elif key == "S":
                        operator.sweep(name)
                    elif key == "r":
                        operator.release()
                    elif key in ("c", "a") and attach is not None:
                        attach([name] if key == "c" else None)
                        message = f"plugged in: {name} only" if key == "c" else "plugged in: all motors"
                    elif key == "u" and usb is not None:
                        message = "USB cable plugged in" if usb() else "USB cable unplugged (the link is gone)"
                except CalibError as exc:
                    message = f"refused: {exc}"
            live.update(render())
            time.sleep(0.0)
