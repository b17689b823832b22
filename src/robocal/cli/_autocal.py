"""CLI side of the automatic hard-stop calibration (``sweep --auto``, ``lerobot calibrate --auto``, ``demo --auto``).

The clear-workspace prompt, the live view and the result table; the logic lives in
:mod:`robocal.workflows.autocal.job` and :mod:`robocal.workflows.autocal.sweep` (``demo --auto``: a job of
:mod:`robocal.workflows.demo.job`).
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.table import Table

from ..core.stop_search import StopSample
from ..errors import UsageError
from ..workflows.autocal.model import AutoCalResult, JointOutcome
from ..workflows.written import files_written
from . import _common

if TYPE_CHECKING:
    from ..workflows.autocal.sweep import SweepAutoRequest

__all__ = [
    "AutoLiveView",
    "auto_demo_view",
    "auto_table",
    "auto_web_view",
    "cap_text",
    "interrupted_limp_text",
    "make_confirm_start",
    "sweep_auto",
]


def cap_text(name: str, caps: Mapping[str, float]) -> str:
    """``cap 0.40 N·m = 25 % of the RS05's 1.6 N·m rating`` (the model part when ``caps`` knows it)."""
    text = f"cap {caps[name]:.2f} N·m"
    model = getattr(caps, "models", {}).get(name)
    if model is not None and model[1] > 0:
        text += f" = {100.0 * caps[name] / model[1]:.0f} % of the {model[0]}'s {model[1]:g} N·m rating"
    return text


def make_confirm_start(yes: bool, what: str = "robot") -> Any:
    """The clear-workspace prompt (None with ``--yes``).

    Raises:
        UsageError: Not on a terminal and no ``--yes`` (a script must say so explicitly).
    """
    if yes:
        return None
    if not sys.stdin.isatty():
        raise UsageError(
            "--auto moves the robot on its own: on a terminal it asks to confirm the workspace is clear; "
            "pass --yes to skip the question in a script"
        )

    def confirm(names: Sequence[str], caps: Mapping[str, float]) -> bool:
        con = _common.console
        cap = max(caps.values()) if caps else 0.0
        con.print(
            f"CLEAR THE WORKSPACE: these {len(names)} joints of the {what} will move on their own into their hard "
            f"stops, in this order (a joint the profile puts alongside another moves with it), pushing with at "
            f"most {cap:.2f} N·m:",
            markup=False,
        )
        for n in names:
            con.print(f"  {n}  ({cap_text(n, caps)})", markup=False)
        if getattr(caps, "host_loss", ""):
            con.print(caps.host_loss, markup=False)  # type: ignore[attr-defined]
        con.print("Ctrl-C at any time makes every motor limp at once.", markup=False)
        return bool(typer.confirm("Start?", default=False))

    return confirm


class AutoLiveView:
    """A line per joint and a status line at most every 0.2 s (wall clock) while a joint is searched."""

    def __init__(self, min_interval_s: float = 0.2) -> None:
        self.min_interval_s = min_interval_s
        self._last = 0.0

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        _common.err_console.print(
            f"{name}: searching its stops at {math.degrees(speed_rad_s):.0f}°/s, cap {cap_nm:.2f} N·m",
            markup=False,
        )

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        now = time.monotonic()
        if now - self._last < self.min_interval_s or not sys.stderr.isatty():
            return
        self._last = now
        q = f"{math.degrees(sample.q_rad):+8.2f}°" if sample.ok else "  (no reply)"
        tau = f"{sample.torque_nm:+.2f} N·m" if math.isfinite(sample.torque_nm) else ""
        sys.stderr.write(f"\r  {name} {side:5s} {phase:8s} q {q} {tau}   ")
        sys.stderr.flush()

    def joint_done(self, outcome: JointOutcome) -> None:
        if sys.stderr.isatty():
            sys.stderr.write("\r" + " " * 70 + "\r")
        st = outcome.stops
        if outcome.ok:
            span = f", span {math.degrees(st.span_rad):.2f}°" if math.isfinite(st.span_rad) else ""
            _common.err_console.print(f"{outcome.name}: ok{span} in {outcome.time_s:.1f} s", markup=False)
        else:
            _common.err_console.print(f"{outcome.name}: FAILED {st.code}: {st.reason}", markup=False)


def interrupted_limp_text(files_before: int) -> str:
    """The line of an interrupted auto run: "nothing was written" only when no file was (the CLI names those)."""
    if files_written()[files_before:]:
        return "interrupted: every motor is limp"  # main's line says what was written (complete)
    return "interrupted: every motor is limp; nothing was written"


@contextlib.contextmanager
def auto_web_view(
    port: int | None,
    urdf: Path | None,
    inner: Any,
    title: str,
    *,
    page: Callable[[Any, int], Any] | None = None,
) -> Iterator[Any]:
    """``--view``: the stop search drawn on the robot in the browser (robocal.viewer.autocal_page), else ``inner``.

    The page opens before anything moves (a port in use or a URDF that does not load ends the command first);
    the run's end, failure or interruption is shown on it; it closes when the command ends. ``page(inner,
    port)`` opens another page than ``urdf``'s (a LeRobot arm's: its URDF, motor names and servo frame).
    """
    if port is None:
        yield inner
        return
    from ..viewer.autocal_page import open_auto_sweep_page
    from ..workflows.autocal.model import AutoCalAbortedError, AutoCalFailedError

    if page is not None:
        web = page(inner, port)
    else:
        assert urdf is not None
        web = open_auto_sweep_page(urdf, inner=inner, port=port, title=title)
    _common.err_console.print(f"auto-calibration view: {web.app.url}", markup=False)
    before = len(files_written())
    try:
        yield web
    except AutoCalFailedError as exc:
        web.finish(exc.result)
        raise
    except AutoCalAbortedError as exc:
        web.failed(str(exc))
        raise
    except KeyboardInterrupt:
        web.failed(interrupted_limp_text(before))
        raise
    finally:
        web.app.stop()


def _deg(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{math.degrees(x):+.2f}"


def auto_table(result: AutoCalResult, title: str = "automatic hard-stop calibration") -> Table:
    """Per joint: q_stop−/q_stop+, span, stiffness, detection torque, time, which test fired, verdict."""
    t = Table(title=f"{title} ({result.total_time_s:.1f} s)")
    for col in (
        "joint",
        "q_stop− °",
        "q_stop+ °",
        "span °",
        "k N·m/rad",
        "τ detect N·m",
        "time s",
        "test",
        "status",
    ):
        t.add_column(col, justify="left" if col in ("joint", "test", "status") else "right")
    for o in result.joints:
        st = o.stops
        lo, hi = st.lower, st.upper
        ks = [
            r.stiffness_nm_per_rad
            for r in (lo, hi)
            if r is not None and math.isfinite(r.stiffness_nm_per_rad)
        ]
        taus = [f"{r.torque_nm:+.2f}" for r in (lo, hi) if r is not None and math.isfinite(r.torque_nm)]
        tests = [r.test for r in (lo, hi) if r is not None and r.test]
        t.add_row(
            o.name,
            _deg(lo.q_stop_rad if lo is not None else None),
            _deg(hi.q_stop_rad if hi is not None else None),
            _deg(st.span_rad),
            f"{sum(ks) / len(ks):.0f}" if ks else "-",
            "/".join(taus) or "-",
            f"{o.time_s:.1f}",
            "/".join(tests) or "-",
            "ok" if o.ok else f"{st.code}: {st.reason}",
        )
    return t


def drift_table(drifts: Sequence[Any], title: str) -> Table:
    """``--verify``: per joint the drift, its uncertainty, each stop's shift and the verdict."""
    table = Table(title=title)
    for col in ("joint", "drift °", "± °", "lower stop °", "upper stop °", ""):
        table.add_column(col, justify="left" if col in ("joint", "") else "right")
    for j in drifts:
        table.add_row(
            j.name,
            f"{j.drift_deg:+.2f}",
            f"{j.uncertainty_deg:.2f}",
            "—" if math.isnan(j.lower_deg) else f"{j.lower_deg:+.2f}",
            "—" if math.isnan(j.upper_deg) else f"{j.upper_deg:+.2f}",
            "DRIFTED" if j.flagged else "ok",
        )
    return table


def print_drifts(
    drifts: Sequence[Any], title: str, stored: object, tolerance_deg: float, footer: str
) -> None:
    """The drift table, a warning naming the joints past the tolerance, the footer (what was written: nothing)."""
    _common.console.print(drift_table(drifts, title))
    flagged = [j.name for j in drifts if j.flagged]
    if flagged:
        _common.print_warning(
            f"{', '.join(flagged)} drifted more than {tolerance_deg:g}° from {stored}: recalibrate (--auto)"
        )
    _common.console.print(footer, markup=False)


def searched_footer(search_s: float) -> str:
    """The last line of an ``--auto --verify``."""
    return f"searched in {search_s:.1f} s; nothing was written (every register the search changed is back, no file)"


def sweep_auto(request: SweepAutoRequest, *, confirm_start: Any, view_port: int | None = None) -> None:
    """``robocal sweep --auto``: run ``request``, print the tables, exit 0/1 (3 on failure, 130 on Ctrl-C).

    Args:
        request: The run, built (and checked) by the command from its options.
        confirm_start: The clear-workspace prompt (:func:`make_confirm_start`; None with ``--yes``).
        view_port: ``--view``: the search is drawn on the robot in the browser as well.
    """
    from ..workflows.autocal.sweep import run_sweep_auto
    from ._sweep_view import print_sweep_warnings, result_table

    before = len(files_written())
    with auto_web_view(view_port, Path(request.urdf_path), AutoLiveView(), "sweep --auto") as live:
        try:
            outcome = run_sweep_auto(request, confirm_start=confirm_start, view=live)
        except KeyboardInterrupt:
            _common.err_console.print(interrupted_limp_text(before), markup=False)
            raise
        if view_port is not None:
            live.finish(outcome.auto, outcome.result)
    _common.console.print(auto_table(outcome.auto))
    if request.verify:
        out, tolerance_deg = request.out, request.tolerance_deg
        title = f"drift of {out} (tolerance {tolerance_deg:g}°)"
        print_drifts(outcome.drifts, title, out, tolerance_deg, searched_footer(outcome.auto.total_time_s))
        raise typer.Exit(outcome.exit_code)
    _common.console.print(result_table(outcome.result))
    print_sweep_warnings(outcome.result)
    if outcome.auto.failed:
        _common.print_warning(f"written with --partial although {outcome.auto.failure_summary()}")
    if outcome.out is not None:
        _common.console.print(f"wrote {outcome.out} ({outcome.fmt})", markup=False)
    if outcome.report is not None:
        _common.console.print(f"wrote {outcome.report}", markup=False)
    raise typer.Exit(outcome.exit_code)


def auto_demo_view(
    run: Callable[[Any], Any], render: Callable[[Any], int], port: int, urdf: Path | None = None
) -> int:
    """``robocal demo --auto --view``: the simulated robot's stop searches drawn in the browser as they run.

    ``run(view)`` runs the demo with the given live view and returns its result, ``render(result)`` prints it
    and returns the exit code. The page draws ``urdf`` (default: the simulated Lite's), opens before anything
    moves and keeps serving the result after the run until Ctrl-C; the exit code is the demo's.
    """
    import tempfile

    from ..workflows.autocal.sim import write_sim_lite_urdf

    with tempfile.TemporaryDirectory(prefix="robocal-demo-auto-view-") as folder:
        if urdf is None:
            urdf = write_sim_lite_urdf(Path(folder) / "lite_bimanual.urdf")
        with auto_web_view(port, urdf, AutoLiveView(), "demo --auto") as live:
            result = run(live)
            outcome = result.detail
            if outcome is not None:
                live.finish(outcome.auto, outcome.result)
            code = render(result)
            try:  # Ctrl-C may come as soon as the line is out
                _common.console.print(f"serving the result at {live.app.url} (Ctrl-C to stop)", markup=False)
                while not live.app.wait(0.2):
                    pass
            except KeyboardInterrupt:
                pass
    return code
