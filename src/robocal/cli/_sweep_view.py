"""The live view and the result table of ``robocal sweep`` (rich on a terminal, plain lines otherwise)."""

from __future__ import annotations

import math
import time

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table

from ..core.sweep import DEFAULT_ONE_SIDED_THRESHOLD_RAD
from ..core.sweep_result import DEFAULT_SPAN_TOLERANCE_RAD, DEFAULT_THRESHOLD_RAD, SweepResult
from ..workflows.sweep.session import SweepSession
from . import _common

__all__ = ["LIVE_WARNINGS", "STATUS_STYLE", "LiveView", "print_sweep_warnings", "result_table"]

STATUS_STYLE = {"ok": "green", "not_swept": "yellow", "sweeping": "cyan", "moved": "green"}
LIVE_WARNINGS = ("no_overlap", "offset_large")
"""Warnings the live view explains as soon as a joint shows them: a flipped direction or a wrong URDF shows
early. The others need the finished sweep (wrap_in_travel depends on the final offset and on ``zero_sta``)."""


def print_sweep_warnings(result: SweepResult) -> None:
    """One ``warning: JOINT: code: sentence`` line per warning (sentence with the numbers and the next step)."""
    for j in result.joints:
        for code in j.warnings:
            _common.print_warning(f"{j.name}: {code}: {result.explain(j.name, code)}")


def _stop_text(stop: tuple[str, float] | None) -> str:
    """``lower stop (-10.00°)`` for a one-sided stop, ``-`` for none."""
    if stop is None:
        return "-"
    return f"{stop[0]} stop ({math.degrees(stop[1]):+.2f}°)"


def _bar(fraction: float, width: int = 12) -> str:
    if not math.isfinite(fraction):
        fraction = 0.0
    filled = max(0, min(width, round(fraction * width)))
    return "█" * filled + "·" * (width - filled) + f" {100 * fraction:4.0f}%"


class LiveView:
    """The sweep's live view: a rich table at ``rate_hz`` on a terminal, else plain lines every ``period_s``.

    Args:
        console: Where to draw (standard error by default).
        rate_hz: Table refresh rate on a terminal (5–10 Hz).
        period_s: Interval of plain progress lines without a terminal.
        threshold_rad: Sweep below which a joint shows as not swept yet (None: the method's default).
        span_tolerance_rad: A joint within this of its URDF span shows as ok.
    """

    def __init__(
        self,
        console: Console | None = None,
        *,
        rate_hz: float = 8.0,
        period_s: float = 1.0,
        threshold_rad: float | None = None,
        span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
    ) -> None:
        self.console = console or _common.err_console
        self.span_tolerance_rad = span_tolerance_rad
        self.rate_hz = rate_hz
        self.period_s = period_s
        self.threshold_rad = threshold_rad
        self.live: Live | None = None
        self._last = -math.inf
        self._t0 = -math.inf
        self._session: SweepSession | None = None
        self.direction: dict[str, int] = {}
        self._told = False

    def __enter__(self) -> LiveView:
        if self.console.is_terminal:
            self.live = Live(console=self.console, refresh_per_second=self.rate_hz, transient=False)
            self.live.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live is not None:
            self.live.__exit__(None, None, None)
            self.live = None

    def _threshold(self, session: SweepSession) -> float:
        if self.threshold_rad is not None:
            return self.threshold_rad
        return DEFAULT_ONE_SIDED_THRESHOLD_RAD if session.method == "one-sided" else DEFAULT_THRESHOLD_RAD

    def table(self, session: SweepSession) -> Table:
        """The per-joint table: position, min, max, sweep vs URDF span, status (one-sided: the stop to push into)."""
        one_sided = session.method == "one-sided"
        what = "push each joint into the stop shown" if one_sided else "sweep each joint into both stops"
        t = Table(
            title=f"sweep ({session.method}: {what}): {session.samples} samples, t = {session.t_s:.1f} s "
            "(Enter or Ctrl-C to finish)"
        )
        cols = [
            "joint",
            *(["push into"] if one_sided else []),
            "position",
            "min",
            "max",
            "sweep / span",
            "status",
        ]
        for col in cols:
            t.add_column(
                col, justify="left" if col in ("joint", "status", "sweep / span", "push into") else "right"
            )
        tr = session.tracker
        cur, lo, hi, sw = tr.current, tr.minimum, tr.maximum, tr.sweep
        first = session.first
        threshold = self._threshold(session)
        for i, name in enumerate(session.names):
            span = session.upper[i] - session.lower[i]
            stop = session.stops[i]
            if one_sided and stop is not None:
                side = stop[0]
                toward = first[i] - lo[i] if side == "lower" else hi[i] - first[i]
                away = hi[i] - first[i] if side == "lower" else first[i] - lo[i]
                if away >= threshold and toward < 0.1 * threshold:
                    status = "wrong_side"
                else:
                    status = "moved" if sw[i] >= threshold else "not_swept"
            else:
                status = (
                    "ok"
                    if sw[i] >= span - self.span_tolerance_rad
                    else ("sweeping" if sw[i] >= threshold else "not_swept")
                )
            style = STATUS_STYLE.get(status, "yellow")
            verdict = self.direction.get(name)
            if verdict is not None and verdict <= 0:
                status += ", direction_unknown" if verdict == 0 else ", direction_flipped"
                style = "yellow"
            push = [_stop_text(stop)] if one_sided else []
            t.add_row(
                name,
                *push,
                f"{cur[i]:+.3f}",
                f"{lo[i]:+.3f}",
                f"{hi[i]:+.3f}",
                _bar(sw[i] / span if span > 0 else 0.0),
                f"[{style}]{status}[/]",
            )
        notes = self.live_notes(session)
        if notes:
            t.caption = "\n".join(notes)
            t.caption_justify = "left"
        return t

    def live_notes(self, session: SweepSession) -> list[str]:
        """``JOINT: code: sentence`` for warnings a swept joint shows already (no_overlap, offset_large)."""
        swept = session.tracker.sweep >= self._threshold(session)
        if not swept.any():
            return []
        result = session.result(
            threshold_rad=self._threshold(session), span_tolerance_rad=self.span_tolerance_rad
        )
        return [
            f"{j.name}: {code}: {result.explain(j.name, code)}"
            for j, ok in zip(result.joints, swept, strict=True)
            if ok
            for code in j.warnings
            if code in LIVE_WARNINGS
        ]

    def _instructions(self, session: SweepSession) -> None:
        """Once, before the first progress line: which stop to push each joint into (one-sided)."""
        self._told = True
        if session.method != "one-sided":
            return
        self.console.print(
            "one-sided sweep: push each joint into this stop (and hold it there a moment):", markup=False
        )
        for name, stop in zip(session.names, session.stops, strict=True):
            self.console.print(f"  {name}: {_stop_text(stop)}", markup=False)

    def progress(self, session: SweepSession) -> tuple[float, str] | None:
        """A replay's progress: (fraction read, ``"80.0 of 177.0 MB"``), or None for a live source."""
        got = getattr(session.source, "progress", None)
        if got is None:
            return None
        done, total, unit, _rows = got
        if total <= 0:
            return None
        frac = min(1.0, done / total)
        if unit == "bytes":
            return frac, f"{done / 1e6:.1f} of {total / 1e6:.1f} MB"
        return frac, f"{done} of {total} {unit}"

    def renderable(self, session: SweepSession) -> RenderableType:
        """The table, under a progress bar for a replay."""
        table = self.table(session)
        prog = self.progress(session)
        if prog is None:
            return table
        frac, what = prog
        elapsed = time.monotonic() - self._t0 if math.isfinite(self._t0) else 0.0
        eta = f", {elapsed * (1 - frac) / frac:.0f} s left" if frac > 0.01 else ""
        line = Table.grid(padding=(0, 1))
        line.add_row(
            "replay",
            ProgressBar(total=1.0, completed=frac, width=40),
            f"{100 * frac:3.0f}%  {what}, {session.samples} rows, {elapsed:.0f} s{eta}",
        )
        return Group(line, table)

    def update(self, session: SweepSession) -> None:
        """Redraw at most ``rate_hz`` times a second (plain lines: every ``period_s``)."""
        now = time.monotonic()
        if not self._told and self.live is None:
            self._instructions(session)
        if self._t0 == -math.inf:
            self._t0 = now
        if self.live is not None:
            if now - self._last >= 1.0 / self.rate_hz:
                self._last = now
                self.live.update(self.renderable(session))
            return
        self._session = session
        if now - self._last >= self.period_s:
            self._last = now
            self.plain_line(session)

    def plain_line(self, session: SweepSession) -> None:
        """One plain progress line (no terminal); a replay's says how much of the file was read."""
        sw = session.tracker.sweep
        prog = self.progress(session)
        where = f"replay {100 * prog[0]:.0f}% ({prog[1]}), " if prog is not None else ""
        if session.method == "one-sided":
            moved = int((sw >= self._threshold(session)).sum())
            self.console.print(
                f"sweep: {where}{session.samples} samples, {moved}/{len(session.names)} joints moved",
                markup=False,
            )
            return
        span = session.upper - session.lower
        done = int((sw >= span - self.span_tolerance_rad).sum())
        self.console.print(
            f"sweep: {where}{session.samples} samples, {done}/{len(session.names)} joints at full span",
            markup=False,
        )

    def prompt(self, joint: str) -> None:
        """Direction check instruction."""
        self.console.print(f"direction check: move {joint} toward its + limit", markup=False)

    def direction_result(self, joint: str, verdict: int) -> None:
        """Direction check verdict: a joint that did not move is said to be not verified, at once."""
        self.direction[joint] = verdict
        if verdict == 0:
            self.console.print(
                f"direction check: {joint}: direction_unknown: did not move 0.1 rad within the direction "
                "check's time, so its direction was NOT verified; rerun with --direction-check (and a longer "
                "--direction-time) and move it toward its + limit",
                markup=False,
            )
        elif verdict < 0:
            self.console.print(
                f"direction check: {joint}: direction_flipped: moved toward − when asked to move toward its + "
                "limit; flip its URDF direction and sweep again",
                markup=False,
            )

    def finish(self, result: SweepResult) -> None:
        """Stop the live table (a confirmation prompt may follow; the command prints the summary).

        Without a terminal, a replay's last progress line (100 %) is printed.
        """
        if self.live is None and self._session is not None and self.progress(self._session) is not None:
            self.plain_line(self._session)
        self.__exit__(None, None, None)


def result_table(result: SweepResult) -> Table:
    """Final per-joint table: sampled range, sweep, offset (previous), warnings.

    A one-sided sweep adds upstream's ``position_offset`` (joint frame); when some joint reached both stops,
    a column gives the difference of the two rules (joint angle by the one-sided rule minus by bisection, rad).
    """
    one_sided = any(j.method == "one-sided" for j in result.joints)
    both = any(math.isfinite(j.rule_difference) for j in result.joints)
    t = Table(title="sweep result (rad, identity frame; homing_offset in the motor frame)")
    cols = ["joint", "min", "max", "sweep", "span", "homing_offset", "previous"]
    cols += ["position_offset"] if one_sided else []
    cols += ["one- vs two-sided"] if both else []
    for col in (*cols, "status"):
        t.add_column(col, justify="left" if col in ("joint", "status") else "right")

    def f(x: float | None) -> str:
        return "-" if x is None or not math.isfinite(x) else f"{x:+.4f}"

    for j in result.joints:
        status = ", ".join(j.warnings) if j.warnings else "ok"
        if j.kept_prior:
            status += " (prior kept)"
        style = "green" if not j.warnings else "yellow"
        extra = [f(j.position_offset)] if one_sided else []
        extra += [f(j.rule_difference)] if both else []
        t.add_row(
            j.name,
            f(j.sampled_min),
            f(j.sampled_max),
            f(j.sweep),
            f(j.span),
            f(j.homing_offset),
            f(j.previous_homing_offset),
            *extra,
            f"[{style}]{status}[/]",
        )
    return t
