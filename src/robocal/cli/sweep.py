"""``robocal sweep`` (hard-stop sweep calibration of Robstride joints) and the ``lite`` demo."""

from __future__ import annotations

import contextlib
import math
import queue
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table

from ..core.sweep import (
    DEFAULT_ONE_SIDED_THRESHOLD_RAD,
    DEFAULT_SPAN_TOLERANCE_RAD,
    DEFAULT_THRESHOLD_RAD,
    SweepResult,
)
from ..errors import UsageError
from ..workflows.sweep import (
    CONFIRM_CODES,
    DEFAULT_DIRECTION_STEP_S,
    SweepNotSavedError,
    SweepSession,
    run_sweep,
)
from . import _common

STATUS_STYLE = {"ok": "green", "not_swept": "yellow", "sweeping": "cyan", "moved": "green"}
LIVE_WARNINGS = ("no_overlap", "offset_large")
"""Warnings the live view explains as soon as a joint shows them: a flipped direction or a wrong URDF shows
early. The others need the finished sweep (wrap_in_travel depends on the final offset and on ``zero_sta``)."""
DEMO_SOURCE = "sim:lite?seed=8"
"""The demo's simulated robot (a seed whose sweep raises no warning, so the demo exits 0 like a clean sweep)."""


def print_warnings(result: SweepResult) -> None:
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


class StdinLines:
    """The one reader of standard input on a terminal: a thread puts each line in a queue.

    During the sweep the first line (Enter) sets ``stop``; afterwards the confirmation prompt takes the lines
    from the same queue, so no thread left blocked in ``readline`` swallows the person's answer.
    """

    def __init__(self, stop: threading.Event) -> None:
        self.stop = stop
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.prompting = False
        threading.Thread(target=self._run, name="robocal-stdin", daemon=True).start()

    def _run(self) -> None:
        while True:
            try:
                line = sys.stdin.readline()
            except Exception:
                line = ""
            if not line:
                self.lines.put(None)  # end of input
                return
            if self.prompting:
                self.lines.put(line)
            else:
                self.stop.set()  # Enter during the sweep: finish

    def ask(self, question: str) -> str | None:
        """Print ``question`` and wait for a line (None at end of input); Ctrl-C stays possible while waiting."""
        self.prompting = True
        _common.console.print(question, end="", markup=False)
        sys.stdout.flush()
        while True:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                continue
            return None if line is None else line.strip()


def _stdin_is_terminal() -> bool:
    try:
        return sys.stdin.isatty()
    except (AttributeError, ValueError):
        return False


def _terminal() -> bool:
    """Whether a person is at a terminal (standard input and output both TTYs)."""
    try:
        return sys.stdin.isatty() and sys.stdout.isatty()
    except (AttributeError, ValueError):
        return False


def confirm_table(result: SweepResult, names: Sequence[str]) -> Table:
    """Old vs new offset of the joints whose change needs a yes, with the warning that makes it doubtful."""
    t = Table(title="these joints have a warning; replace their previous offset? (rad, motor frame)")
    for col in ("joint", "previous", "new", "change", "warning"):
        t.add_column(col, justify="left" if col in ("joint", "warning") else "right")
    for name in names:
        j = result[name]
        prev = float(j.previous_homing_offset) if j.previous_homing_offset is not None else math.nan
        t.add_row(
            name,
            f"{prev:+.4f}",
            f"{j.homing_offset:+.4f}",
            f"{j.homing_offset - prev:+.4f}",
            ", ".join(c for c in j.warnings if c in CONFIRM_CODES),
        )
    return t


ANSWERS = {
    "y": "yes",
    "yes": "yes",
    "n": "no",
    "no": "no",
    "": "no",
    "a": "all",
    "all": "all",
    "none": "none",
}


def make_confirm(lines: StdinLines) -> Callable[[SweepResult, Sequence[str]], set[str]]:
    """The terminal prompt: show old vs new, then ask per joint (y / n, or all / none for the rest)."""

    def confirm(result: SweepResult, names: Sequence[str]) -> set[str]:
        con = _common.console
        con.print(confirm_table(result, names))
        for name in names:
            for code in result[name].warnings:
                if code in CONFIRM_CODES:
                    _common.print_warning(f"{name}: {code}: {result.explain(name, code)}")
        accepted: set[str] = set()
        for k, name in enumerate(names):
            j = result[name]
            question = (
                f"{name}: replace {j.previous_homing_offset:+.4f} with {j.homing_offset:+.4f} rad? "
                "[y]es / [n]o, keep it (default) / [a]ll / none: "
            )
            while True:
                line = lines.ask(question)
                answer = "none" if line is None else ANSWERS.get(line.lower())
                if answer is not None:
                    break
                con.print("please answer y, n, all or none", markup=False)
            if answer == "yes":
                accepted.add(name)
            elif answer in ("all", "none"):
                if answer == "all":
                    accepted.update(names[k:])
                break
        kept = [n for n in names if n not in accepted]
        if kept:
            con.print(f"keeping the previous offset of {', '.join(kept)}", markup=False)
        return accepted

    return confirm


@contextlib.contextmanager
def _web_view(
    enabled: bool, urdf: Path, port: int, inner: Any, threshold: float | None, span_tolerance: float
) -> Iterator[Any]:
    """``--view``: the sweep drawn on the robot in the browser (robocal.viewer.sweep_page), else ``inner``."""
    if not enabled:
        yield inner
        return
    from ..viewer.sweep_page import open_sweep_page

    web = open_sweep_page(urdf, inner=inner, port=port, threshold_rad=threshold, span_tolerance_rad=span_tolerance)
    _common.err_console.print(f"sweep view: {web.app.url}", markup=False)
    try:
        yield web
    finally:
        web.app.stop()


@contextlib.contextmanager
def _not_lost() -> Iterator[None]:
    """When the sweep's calibration could not be saved, show it (table, warnings, the file's text) first."""
    try:
        yield
    except SweepNotSavedError as exc:
        _common.console.print(result_table(exc.result))
        print_warnings(exc.result)
        if exc.calibration_text.strip() not in ("", "{}"):
            _common.err_console.print(
                f"the sweep's calibration was NOT saved; here it is ({exc.fmt}, on standard output):",
                markup=False,
            )
            sys.stdout.write(exc.calibration_text)
            sys.stdout.flush()
        raise


def sweep(
    urdf: Annotated[Path, typer.Option("--urdf", help="URDF with <ros2_control> joint params.")],
    source: Annotated[
        str,
        typer.Option(
            "--source", help="sim:lite[?seed=N], can:<interface>:<channel>[,<channel>...] or replay:<file>."
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", help="Calibration file to write (updated in place if it exists).")
    ],
    prior: Annotated[Path | None, typer.Option("--prior", help="Offsets kept for joints not swept.")] = None,
    threshold: Annotated[
        float | None,
        typer.Option("--threshold", help="Not-swept threshold, rad (default 0.5 two-sided, 0.05 one-sided)."),
    ] = None,
    span_tolerance: Annotated[
        float, typer.Option("--span-tolerance", help="Allowed |sweep - URDF span|, rad.")
    ] = DEFAULT_SPAN_TOLERANCE_RAD,
    report: Annotated[Path | None, typer.Option("--report", help="Write the JSON report here.")] = None,
    fmt: Annotated[
        str | None,
        typer.Option(
            "--format", help="lite-yaml or lite-json (default: from --out's extension, .json is lite-json)."
        ),
    ] = None,
    direction_check: Annotated[
        bool, typer.Option("--direction-check", help="Guided 'move toward +' check first.")
    ] = False,
    direction_time: Annotated[
        float,
        typer.Option("--direction-time", help="Seconds the direction check waits per joint for the motion."),
    ] = DEFAULT_DIRECTION_STEP_S,
    topic: Annotated[str, typer.Option("--topic", help="JointState topic of a rosbag2 replay.")] = (
        "/lite/joint_states"
    ),
    frame: Annotated[
        str | None, typer.Option("--frame", help="Replay positions: identity (default) or motor.")
    ] = None,
    robot: Annotated[
        str | None,
        typer.Option(
            "--robot",
            help="Robot profile: built-in name or profile YAML (docs/profiles.md). Default: the URDF's robot.",
        ),
    ] = None,
    yes: Annotated[
        bool,
        typer.Option(
            "--yes",
            "-y",
            help="Write every new offset without asking (on a terminal, a changed offset of a joint with a "
            "span_mismatch, no_overlap, offset_large or wrong_side warning is otherwise asked about).",
        ),
    ] = False,
    method: Annotated[
        str | None,
        typer.Option(
            "--method",
            help="one-sided (each joint into the profile's stop, as the robot's own procedure) or two-sided "
            "(both stops, bisection). Default: the profile's procedure, else two-sided.",
        ),
    ] = None,
    auto: Annotated[
        bool,
        typer.Option(
            "--auto",
            help="The joints find their own hard stops (Robstride; the profile's auto_calibration section): "
            "asks to clear the workspace first (--yes skips), Ctrl-C makes every motor limp (docs/auto_calibration.md).",
        ),
    ] = False,
    joints: Annotated[
        str | None, typer.Option("--joints", help="--auto: calibrate only these joints (comma-separated).")
    ] = None,
    partial: Annotated[
        bool, typer.Option("--partial", help="--auto: write the joints that passed even if others failed.")
    ] = False,
    web_view: Annotated[
        bool, typer.Option("--view", help="Also draw the sweep on the robot in the browser (robocal[view]).")
    ] = False,
    view_port: Annotated[int, typer.Option("--view-port", help="TCP port of the --view page (0: any).")] = 8080,
) -> None:
    """Hard-stop sweep calibration: sweep every joint between its stops, then write the homing offsets."""
    if auto:
        from ._autocal import sweep_auto

        if web_view:
            raise UsageError("--view does not work with --auto yet: the automatic stop search is not drawn")

        if prior is not None or threshold is not None or method is not None or direction_check or frame:
            raise UsageError(
                "--auto finds the stops itself: --prior, --threshold, --method, --direction-check "
                "and --frame do not apply"
            )
        sweep_auto(
            urdf, source, out, robot=robot, joints=joints, report=report, fmt=fmt, partial=partial, yes=yes
        )
        return
    if joints is not None or partial:
        raise UsageError("--joints and --partial go with --auto")
    stop = threading.Event()
    lines = StdinLines(stop) if _stdin_is_terminal() else None  # Enter finishes the sweep
    confirm = make_confirm(lines) if lines is not None and _terminal() and not yes else None
    with (
        _not_lost(),
        LiveView(threshold_rad=threshold, span_tolerance_rad=span_tolerance) as live_view,
        _web_view(web_view, urdf, view_port, live_view, threshold, span_tolerance) as view,
    ):
        outcome = run_sweep(
            urdf,
            source,
            out,
            prior=prior,
            threshold_rad=threshold,
            span_tolerance_rad=span_tolerance,
            report=report,
            fmt=fmt,
            direction_check=direction_check,
            direction_step_s=direction_time,
            topic=topic,
            frame=frame,
            view=view,
            stop=stop,
            robot=robot,
            confirm=confirm,
            method=method,
        )
    _common.console.print(result_table(outcome.result))
    print_warnings(outcome.result)
    for name, count in outcome.missing_samples.items():  # informational: NaN is legal in a JointState
        _common.err_console.print(
            f"note: {name}: {count} of {outcome.samples} samples had no position (NaN) and were skipped",
            markup=False,
        )
    robot_text = f", robot {outcome.robot}" if outcome.robot else ""
    _common.console.print(f"method: {outcome.method}{robot_text}", markup=False)
    _common.console.print(f"wrote {outcome.out} ({outcome.fmt})", markup=False)
    if outcome.report is not None:
        _common.console.print(f"wrote {outcome.report}", markup=False)
    raise typer.Exit(outcome.exit_code)


def run_demo(robot: str, out_dir: Path | None, *, source: str = DEMO_SOURCE) -> int:
    """Sweep-calibrate the simulated Lite (14 Robstride joints) and print true vs recovered offsets.

    Args:
        robot: ``"lite"``.
        out_dir: Folder for ``lite_bimanual.urdf``, ``calibration.yaml`` and ``sweep_report.json``
            (a temporary folder when None).
        source: The simulated robot (``sim:lite?...``).

    Returns:
        The exit code ``robocal sweep`` gives for the same sweep (0 clean, 1 warnings), and 1 as well when a
        recovered offset is more than 2e-3 rad from the simulator's truth.
    """
    from ..backends.sim.lite import lite_urdf_text
    from ..backends.sources import open_source
    from ..errors import UsageError
    from ..fileio import atomic_write_text

    if robot != "lite":
        raise UsageError(f"run_demo: robot {robot!r} is not a sweep demo; expected 'lite'")
    tmp = None
    if out_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="robocal-demo-")
        out_dir = Path(tmp.name)
    try:
        urdf = out_dir / "lite_bimanual.urdf"
        atomic_write_text(urdf, lite_urdf_text(), backup=False)
        opened: list[Any] = []

        def capture(*args: Any, **kwargs: Any) -> Any:
            src = open_source(*args, **kwargs)
            opened.append(src)
            return src

        con = _common.console
        con.print("robocal demo: simulated Lite bimanual robot, 14 Robstride joints on two virtual CAN buses")
        con.print("a simulated operator pushes every joint into both hard stops (encoder noise 3e-4 rad)")
        outcome = run_sweep(
            urdf,
            source,
            out_dir / "calibration.yaml",
            report=out_dir / "sweep_report.json",
            open_source_fn=capture,
        )
        truth = opened[0].sim.true_offsets()
        t = Table(title=f"true vs recovered homing_offset (rad), {outcome.samples} samples")
        for col in ("joint", "true", "recovered", "error", "status"):
            t.add_column(col, justify="left" if col in ("joint", "status") else "right")
        worst = 0.0
        for j in outcome.result.joints:
            err = j.homing_offset - truth[j.name]
            worst = max(worst, abs(err))
            t.add_row(
                j.name,
                f"{truth[j.name]:+.4f}",
                f"{j.homing_offset:+.4f}",
                f"{err:+.1e}",
                ", ".join(j.warnings) or "ok",
            )
        con.print(t)
        print_warnings(outcome.result)
        where = (
            " (temporary folder, removed on exit; keep the files with --out DIR)" if tmp is not None else ""
        )
        con.print(
            f"largest error {worst:.1e} rad; wrote {outcome.out} and {outcome.report}{where}", markup=False
        )
        if worst > 2e-3:
            _common.print_warning(f"largest error {worst:.1e} rad is above the demo's 2e-3 rad tolerance")
            return 1
        return outcome.exit_code
    finally:
        if tmp is not None:
            tmp.cleanup()


def register(app: typer.Typer) -> None:
    """Add ``sweep`` to the root app."""
    app.command("sweep")(sweep)
