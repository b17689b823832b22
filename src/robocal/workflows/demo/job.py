"""``robocal demo``: one job end to end on a simulated robot, checked against the simulator's hidden truth.

Every demo runs the same code path as a real robot (the simulators speak the real wire protocols) in a folder
of its own, by default a temporary one, and returns a :class:`DemoResult` the CLI renders: truth tables
(simulated truth vs what robocal recovered), lines and warnings, the exit code, and the job's own result for
the job's own printer.

The jobs:

* ``sweep`` (``lite``): hard-stop sweep of the simulated Lite's 14 Robstride joints on ``virtual`` CAN.
* ``lerobot`` (``so101``, ``koch``): LeRobot calibration of the simulated follower and leader arms through the
  vendor SDKs on a pseudo-terminal.
* ``ur`` (``ur3`` … ``ur30``): extract + verify against a simulated controller on loopback TCP.
* ``identify`` (``so101``, ``koch`` with ``--identify``): kinematic identification of an arm with hidden errors
  (:mod:`robocal.workflows.demo.identify`; :attr:`DemoResult.detail` is its
  :class:`~robocal.workflows.demo.identify.IdentifyDemo`).
* ``auto`` (``lite``, ``so101``, ``koch`` with ``--auto``): zero-touch calibration, each simulated joint finds its
  own hard stops (physics on a simulated clock behind the Robstride wire protocol; the LeRobot followers behind
  the vendor SDK on a pseudo-terminal, :mod:`robocal.workflows.demo.auto_arm`); :attr:`DemoResult.detail` is the
  :class:`~robocal.workflows.autocal.sweep.AutoSweepOutcome`.

A new mode adds a function ``(robot, folder, say, temporary, **options) -> DemoResult`` to :data:`JOBS`, the
robots it works with to :data:`MODE_ROBOTS` (and, optionally, its own refusal to :data:`MODE_REFUSALS`), and a
flag to ``robocal demo`` (see :func:`run_demo`).
"""

from __future__ import annotations

import contextlib
import json
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import UsageError

__all__ = [
    "AUTO_ROBOTS",
    "DEMO_ROBOTS",
    "IDENTIFY_ROBOTS",
    "JOBS",
    "LITE_DEMO_SOURCE",
    "MODE_REFUSALS",
    "MODE_ROBOTS",
    "DemoResult",
    "DemoSection",
    "Say",
    "TruthTable",
    "demo_folder",
    "demo_urdf",
    "prepare_demo",
    "run_demo",
    "temporary_note",
]

DEMO_ROBOTS: dict[str, str] = {
    "lite": "sweep",
    "so101": "lerobot",
    "koch": "lerobot",
    "ur3": "ur",
    "ur5": "ur",
    "ur10": "ur",
    "ur3e": "ur",
    "ur5e": "ur",
    "ur10e": "ur",
    "ur16e": "ur",
    "ur20": "ur",
    "ur30": "ur",
    "openarm": "auto",
}
"""Demo robot → the job ``robocal demo --robot ROBOT`` runs."""

IDENTIFY_ROBOTS: tuple[str, ...] = ("so101", "koch")
"""Robots ``demo --identify`` simulates."""

AUTO_ROBOTS: tuple[str, ...] = ("lite", "so101", "koch", "openarm")
"""Robots ``demo --auto`` simulates."""

MODE_ROBOTS: dict[str, tuple[str, ...]] = {"identify": IDENTIFY_ROBOTS, "auto": AUTO_ROBOTS}
"""Demo mode (a flag of ``robocal demo``) → the robots it works with; the mode is also the job it runs."""

MODE_REFUSALS: dict[str, str] = {
    "auto": "demo --auto simulates the lite (14 Robstride joints), so101 or koch (LeRobot followers) or openarm "
    "(8 Damiao motors); "
    "{robot!r} is not available",
}
"""Demo mode → its own message for a robot it does not work with (``{robot!r}``); default
``--MODE works with …, not 'ROBOT'``."""


LITE_DEMO_SOURCE = "sim:lite?seed=8"
"""The Lite demo's simulated robot (a seed whose sweep raises no warning, so the demo exits 0 like a clean
sweep)."""

SWEEP_TOLERANCE_RAD = 2e-3
"""Largest recovered-offset error the Lite demo accepts, rad."""

STOP_TOLERANCE_TICKS = 2
"""Largest recovered hard-stop error the LeRobot demo accepts, ticks."""

Say = Callable[[str], None]
"""Prints one progress line while the demo runs (rich markup allowed)."""


@dataclass(frozen=True)
class TruthTable:
    """The simulator's truth beside what robocal recovered, as text cells.

    Attributes:
        title: Table title.
        columns: Column headers.
        rows: One tuple of cells per joint or motor.
    """

    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class DemoSection:
    """One table and the lines printed after it (the LeRobot demo has one per arm)."""

    table: TruthTable
    lines: tuple[str, ...] = ()


@dataclass(frozen=True)
class DemoResult:
    """What a demo produced.

    Attributes:
        robot: Demo robot name.
        job: ``sweep``, ``lerobot``, ``ur``, ``identify``, ``auto`` (or a mode added later).
        folder: Where the files were written.
        temporary: True when ``folder`` was a temporary folder (removed when the demo returned).
        exit_code: 0 ok, 1 warnings or a recovered value outside the demo's tolerance.
        detail: The job's own result for its printer (``ur``: the verification reports; ``identify``: the
            :class:`~robocal.workflows.demo.identify.IdentifyDemo`; ``sweep``: the
            :class:`~robocal.workflows.sweep.job.SweepOutcome`; ``auto``: the
            :class:`~robocal.workflows.autocal.sweep.AutoSweepOutcome`), or None.
        sections: Truth tables, each with its lines.
        lines: Lines printed after the sections and the job's own output.
        warnings: Warning sentences (printed as ``warning: …``).
    """

    robot: str
    job: str
    folder: Path
    temporary: bool
    exit_code: int
    detail: object = None
    sections: tuple[DemoSection, ...] = ()
    lines: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


def prepare_demo(robot: str, out: Path | None, mode: str | None = None) -> str:
    """Validate ``robocal demo``'s options and create ``--out``; return the normalised robot name.

    Raises:
        UsageError: Unknown robot, a mode the robot does not have, or ``--out`` a file / not creatable.
    """
    robot = robot.strip().lower()
    if robot not in DEMO_ROBOTS:
        raise UsageError(f"unknown demo robot {robot!r}; valid: {', '.join(DEMO_ROBOTS)}")
    if out is not None:
        if out.exists() and not out.is_dir():
            raise UsageError(f"--out {out} is a file; give a folder for the demo's files")
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"cannot create --out folder {out}: {exc.strerror or exc}") from None
    if mode is not None:
        robots = MODE_ROBOTS.get(mode)
        if robots is None:
            raise UsageError(f"unknown demo mode {mode!r}; valid: {', '.join(MODE_ROBOTS)}")
        if robot not in robots:
            refusal = MODE_REFUSALS.get(mode)
            if refusal is not None:
                raise UsageError(refusal.format(robot=robot))
            raise UsageError(f"--{mode} works with {', '.join(robots)}, not {robot!r}")
    return robot


@contextlib.contextmanager
def demo_folder(out_dir: Path | None, job: str) -> Iterator[tuple[Path, bool]]:
    """The demo's folder: ``out_dir``, or a temporary folder removed on exit. Yields ``(folder, temporary)``."""
    if out_dir is not None:
        yield out_dir, False
        return
    with tempfile.TemporaryDirectory(prefix=f"robocal-demo-{job}-") as tmp:
        yield Path(tmp), True


def temporary_note(temporary: bool) -> str:
    """The note after a written file's name when the demo's folder is temporary (else empty)."""
    return " (temporary folder, removed on exit; keep the files with --out DIR)" if temporary else ""


def demo_urdf(robot: str) -> Path | None:
    """The URDF ``demo --auto --view`` draws for ``robot`` (the OpenArm's right arm), None for the simulated Lite's."""
    if robot == "openarm":
        from importlib import resources

        return Path(str(resources.files("robocal") / "data" / "openarm_v10_right.urdf"))
    return None


def run_demo(
    robot: str,
    out_dir: Path | None = None,
    *,
    mode: str | None = None,
    say: Say | None = None,
    **options: Any,
) -> DemoResult:
    """Run the demo of ``robot`` (``mode``: ``identify``, …, instead of its calibration job).

    Args:
        robot: A :data:`DEMO_ROBOTS` name.
        out_dir: Folder for the files (must exist; :func:`prepare_demo` creates it); a temporary folder when
            None.
        mode: A :data:`MODE_ROBOTS` mode, or None for the robot's calibration job.
        say: Prints progress lines while the demo runs.
        **options: Passed to the job (``source=`` for the Lite sweep's simulated robot, ``view=`` for the
            live view of ``auto``).

    Returns:
        The :class:`DemoResult`.

    Raises:
        UsageError: Unknown robot or mode.
    """
    robot = prepare_demo(robot, None, mode)
    job = mode if mode is not None else DEMO_ROBOTS[robot]
    with demo_folder(out_dir, job) as (folder, temporary):
        return JOBS[job](robot, folder, say or (lambda _line: None), temporary, **options)


# ------------------------------------------------------------------------------------------------ the jobs
def _sweep_demo(
    robot: str, folder: Path, say: Say, temporary: bool, *, source: str = LITE_DEMO_SOURCE
) -> DemoResult:
    """Sweep-calibrate the simulated Lite (14 Robstride joints) and compare with the simulator's offsets."""
    from ...backends.sim.lite import lite_urdf_text
    from ...backends.sources import open_source
    from ...fileio import atomic_write_text
    from ..sweep.job import SweepRequest, run_sweep

    urdf = folder / "lite_bimanual.urdf"
    atomic_write_text(urdf, lite_urdf_text(), backup=False)
    opened: list[Any] = []

    def capture(*args: Any, **kwargs: Any) -> Any:
        src = open_source(*args, **kwargs)
        opened.append(src)
        return src

    say("robocal demo: simulated Lite bimanual robot, 14 Robstride joints on two virtual CAN buses")
    say("a simulated operator pushes every joint into both hard stops (encoder noise 3e-4 rad)")
    outcome = run_sweep(
        SweepRequest(
            urdf,
            source,
            folder / "calibration.yaml",
            report=folder / "sweep_report.json",
        ),
        open_source_fn=capture,
    )
    truth: Mapping[str, float] = opened[0].sim.true_offsets()
    rows = []
    worst = 0.0
    for j in outcome.result.joints:
        err = j.homing_offset - truth[j.name]
        worst = max(worst, abs(err))
        rows.append(
            (
                j.name,
                f"{truth[j.name]:+.4f}",
                f"{j.homing_offset:+.4f}",
                f"{err:+.1e}",
                ", ".join(j.warnings) or "ok",
            )
        )
    table = TruthTable(
        f"true vs recovered homing_offset (rad), {outcome.samples} samples",
        ("joint", "true", "recovered", "error", "status"),
        tuple(rows),
    )
    warnings = [
        f"{j.name}: {c}: {outcome.result.explain(j.name, c)}"
        for j in outcome.result.joints
        for c in j.warnings
    ]
    code = outcome.exit_code
    if worst > SWEEP_TOLERANCE_RAD:
        warnings.append(
            f"largest error {worst:.1e} rad is above the demo's {SWEEP_TOLERANCE_RAD:g} rad tolerance"
        )
        code = max(code, 1)
    line = (
        f"largest error {worst:.1e} rad; wrote {outcome.out} and {outcome.report}{temporary_note(temporary)}"
    )
    return DemoResult(
        robot,
        "sweep",
        folder,
        temporary,
        code,
        outcome,
        sections=(DemoSection(table),),
        lines=(line,),
        warnings=tuple(warnings),
    )


def _lerobot_demo(robot: str, folder: Path, say: Say, temporary: bool) -> DemoResult:
    """Calibrate the simulated follower and leader through the real SDK on a pty; recovered vs true stops."""
    from ...backends.sim.lerobot_arms import SimArm, SimArmOperator
    from ...formats.lerobot import calibration_path
    from ..lerobot import CalibrateRequest, calibrate, open_sim_bus, robot_spec

    ok = True
    sections = []
    for name in (f"{robot}_follower", f"{robot}_leader"):
        spec = robot_spec(name)
        with SimArm(spec, noise_ticks=1, seed=1) as arm:
            bus = open_sim_bus(spec, arm)
            try:
                path = calibration_path(spec.kind, spec.device_name, "demo", root=folder)
                result = calibrate(bus, CalibrateRequest(spec, path=path, sweep_full_turn=True), SimArmOperator(arm))
            finally:
                bus.close()
            stops = arm.recovered_stops(result.calibration)
            rows = []
            for n, c in result.calibration.items():
                tr = arm.truth[n]
                lo, hi = stops[n]
                shift = spec.homing.turn_shift(tr.stop_low_ticks, lo, arm.servo(n).resolution)
                lo, hi = lo + shift, hi + shift
                good = abs(lo - tr.stop_low_ticks) <= STOP_TOLERANCE_TICKS and (
                    abs(hi - tr.stop_high_ticks) <= STOP_TOLERANCE_TICKS
                )
                ok = ok and good
                rows.append(
                    (
                        n,
                        f"{tr.stop_low_ticks:g}..{tr.stop_high_ticks:g}",
                        f"{lo}..{hi}" + ("" if good else " !"),
                        str(c.homing_offset),
                        f"{c.range_min}..{c.range_max}",
                    )
                )
            table = TruthTable(
                f"{name}: simulated {spec.vendor} servos on {arm.port}",
                ("motor", "true stops (ticks)", "recovered stops", "homing_offset", "range"),
                tuple(rows),
            )
        motors = len(json.loads(Path(str(result.path)).read_text()))
        lines = (f"wrote {result.path}{temporary_note(temporary)}", f"{motors} motors in LeRobot's format")
        sections.append(DemoSection(table, lines))
    return DemoResult(robot, "lerobot", folder, temporary, 0 if ok else 1, sections=tuple(sections))


def _ur_demo(robot: str, folder: Path, say: Say, temporary: bool) -> DemoResult:
    """Extract → kinematics YAML → verify against a simulated controller with a real UR10e's deltas.

    The simulated controller reports ``robot``'s nominal DH plus the calibration deltas of a real UR10e
    (ur_calibration's test set 3: d2 ≈ 439 m, d3 ≈ −446 m). :attr:`DemoResult.detail` holds the verification
    reports (the CLI prints them and adds their warnings to the exit code).
    """
    from ...backends.sim.ur_controller import SimUrController
    from ...core.ur import TEST_SET_3_DELTAS, nominal_dh
    from ..ur import job as wf
    from ..ur import verify as ur_verify

    out = folder / f"{robot}_calibration.yaml"
    with SimUrController(nominal_dh(robot) + TEST_SET_3_DELTAS) as sim:
        host, port = sim.address
        say(f"[bold]UR demo[/]: simulated {robot} controller on {host}:{port}")
        result = wf.extract(host, out, port=port, timeout_s=5.0)
    reports = ur_verify.verify(out, result.dh, samples=1000, seed=0)
    forearm, wrist_1 = result.kinematics.links[2], result.kinematics.links[3]
    say(
        f"controller DH: d2 = {result.dh.d_m[1]:.3f} m, d3 = {result.dh.d_m[2]:.3f} m (the split DH of a real "
        "UR10e's calibration, upstream ur_calibration's test set 3: joints 2 and 3 are nearly parallel, so their "
        f"common normal lies far away; docs/ur.md) → corrected (d2 = d3 = 0) forearm x = {forearm.xyz_m[0]:.6f} m, wrist_1 x = "
        f"{wrist_1.xyz_m[0]:.6f} m"
    )
    gone = " (temporary folder, removed on exit)" if temporary else ""
    lines = (f"hash: {result.kinematics.hash}", f"wrote {out}{gone}")
    return DemoResult(
        robot, "ur", folder, temporary, 1 if result.warnings else 0, lines=lines, detail=reports
    )


def _auto_demo(robot: str, folder: Path, say: Say, temporary: bool, **options: Any) -> DemoResult:
    """``demo --auto``: :func:`robocal.workflows.demo.auto.auto_demo`."""
    from .auto import auto_demo

    return auto_demo(robot, folder, say, temporary, **options)


def _identify_demo(robot: str, folder: Path, say: Say, temporary: bool) -> DemoResult:
    """``demo --identify``: simulated kinematic identification checked against the hidden truth."""
    from .identify import IDENTIFY_INTRO, identify_demo

    say(IDENTIFY_INTRO.format(robot=robot))
    found = identify_demo(robot, folder, say)
    lines = ("(temporary folder, removed on exit)",) if temporary else ()
    return DemoResult(robot, "identify", folder, temporary, 1 if found.has_warnings else 0, found, lines=lines)


JOBS: dict[str, Callable[..., DemoResult]] = {
    "sweep": _sweep_demo,
    "lerobot": _lerobot_demo,
    "ur": _ur_demo,
    "auto": _auto_demo,
    "identify": _identify_demo,
}
"""Job name → ``job(robot, folder, say, temporary, **options) -> DemoResult``, run in the demo's folder."""
