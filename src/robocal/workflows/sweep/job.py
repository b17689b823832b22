"""Hard-stop sweep calibration of Robstride joints: source → range tracker → bisection → file + report.

The source is read in the identity frame (``s = direction·raw``, what the robot publishes with an empty
calibration file). When the sweep ends (source exhausted, Enter, or a first Ctrl-C) the offsets are computed,
validated and written atomically; a second Ctrl-C while finishing aborts and writes nothing more (a first one
that arrives after the sweep ended by itself asks for what is already happening, and is not a second).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from ...backends import load_backend
from ...backends.sources import DEFAULT_TOPIC, JointSpec, Source, SourceSpec, open_source
from ...core.jointmap import RobotCalibration
from ...core.profile import METHODS, RobotProfile
from ...core.sweep import DEFAULT_ONE_SIDED_THRESHOLD_RAD
from ...core.sweep_result import DEFAULT_SPAN_TOLERANCE_RAD, DEFAULT_THRESHOLD_RAD, SweepResult
from ...core.vendors import hand_sweep_source, speaks_live_can_sweep
from ...errors import CalibError, FileFormatError, JointMismatchError, SignalInterrupt, UsageError
from ...fileio import atomic_write_text
from ...formats import CalibrationFile, read_calibration, write_calibration
from ...formats.calibration import read_existing_output
from ...formats.profiles import resolve_profile
from ...formats.urdf import UrdfModel, read_urdf
from .interrupts import FinishingCtrlC
from .joint_specs import joints_from_urdf
from .output import (
    OUTPUT_FORMATS,
    ConfirmFn,
    SweepNotSavedError,
    calibration_text,
    changes_to_confirm,
    check_outputs,
    keep_prior,
    output_format,
)
from .session import (
    DEFAULT_DIRECTION_STEP_S,
    HardStopSweepView,
    SweepSession,
    check_source_options,
    run_direction_check,
)

__all__ = [
    "DEFAULT_TOPIC",
    "OUTPUT_FORMATS",
    "SweepAbortedError",
    "SweepOutcome",
    "SweepRequest",
    "existing_output",
    "offsets_by_joint",
    "run_sweep",
    "write_sweep_files",
]

class SweepAbortedError(CalibError):
    """A second Ctrl-C (or one at the prompt, SIGTERM, SIGHUP) aborted the finishing sweep (exit 130, 143, 129).

    The message says which files were written before it (each whole) and which not.
    """

    exit_code = 130


@dataclass(frozen=True)
class SweepOutcome:
    """What :func:`run_sweep` produced.

    Attributes:
        result: Offsets and diagnostics.
        out: The calibration file written.
        fmt: Its format.
        report: The report written, or None.
        exit_code: 0 every joint ok, 1 warnings.
        samples: Samples read.
        interrupted: True when the sweep was ended by Ctrl-C or Enter.
        missing_samples: Joint → samples without a position for it (NaN), skipped; joints with none left out.
    """

    result: SweepResult
    out: Path
    fmt: str
    report: Path | None
    exit_code: int
    samples: int
    interrupted: bool
    missing_samples: Mapping[str, int] = field(default_factory=dict)
    method: str = "two-sided"
    robot: str | None = None


def offsets_by_joint(cf: CalibrationFile) -> dict[str, float]:
    """Homing offset (rad) of every joint in ``cf``, by joint name."""
    cal = cf.calibration
    return {n: float(h) for n, h in zip(cal.joint_names, cal.homing_offset, strict=True)}


def _check_number(value: float, flag: str) -> float:
    if not (math.isfinite(value) and value >= 0):
        raise UsageError(f"{flag} {value}: expected a finite number of rad >= 0")
    return float(value)


_VERIFY_ADVICE = (
    "--verify reads the calibration to check from --out: name the file the calibration was written to (and its "
    "--format)"
)
"""What a refusal of ``--out`` says under ``--verify`` (where it is read, never written)."""


def existing_output(
    out: Path, fmt: str, urdf: UrdfModel, profile: RobotProfile | None = None, *, verify: bool = False
) -> CalibrationFile | None:
    """The calibration already in ``--out`` (updated in place), or None for a missing or empty file.

    A file holding only comments counts as empty.

    Args:
        out: ``--out``.
        fmt: The format written (or, with ``verify``, read).
        urdf: The URDF (directions, ids).
        profile: The robot profile in effect.
        verify: ``--verify``: ``out`` is only read; a refusal says what to give instead of where else to write.

    Raises:
        FileFormatError: ``--out`` holds something else than a ``fmt`` calibration (it would be replaced;
            nothing is written).
    """
    advice = _VERIFY_ADVICE if verify else None
    return read_existing_output(out, fmt, "--out", urdf=urdf, robot=profile, advice=advice)  # convert's rule too


def _check_foreign_ids(out: Path, existing: CalibrationFile, joints: Sequence[JointSpec]) -> None:
    """Refuse an ``--out`` whose other joints use a CAN id of a calibrated joint (it would be inconsistent)."""
    ours = {j.can_id: j.name for j in joints}
    names = set(ours.values())
    for name, can_id in existing.ids.items():
        if name not in names and can_id in ours:
            raise FileFormatError(
                f"--out {out}: joint {name!r} (not in the URDF) has CAN id {can_id}, "
                f"the id of URDF joint {ours[can_id]!r}"
            )


@dataclass(frozen=True)
class SweepRequest:
    """One hard-stop sweep calibration: what to read, what to write and how to judge it.

    The numbers and choices are checked once, when the request is built (``UsageError`` naming the flag);
    files, the source and the robot are checked by :func:`run_sweep` before anything is opened or written.
    The CLI builds it from ``robocal sweep``'s options; Python callers build it directly.

    Attributes:
        urdf_path: The robot's URDF: joint names and limits; direction, can_id and model from its
            ``<ros2_control>`` params when present, else from the calibration file or the robot profile.
        source: ``--source`` string.
        out: Calibration file to write (updated in place when it exists).
        prior: Calibration whose offsets are kept for joints not swept (default: ``out`` if it exists).
        threshold_rad: Sweeps below this count as not swept (default 0.5 rad two-sided, 0.05 rad one-sided).
        span_tolerance_rad: Allowed ``|sweep − (upper − lower)|``.
        report: JSON report to write.
        fmt: ``lite-yaml`` or ``lite-json`` (default: from ``out``'s name, ``lite-yaml`` otherwise).
        direction_check: Run the guided direction check before the sweep.
        direction_step_s: Time the direction check waits per joint for the motion, s (source clock).
        topic: JointState topic of a rosbag2 replay.
        frame: Frame of a replay (``identity`` or ``motor``).
        max_samples: Stop after this many samples (None: until the source ends or the user stops).
        robot: Robot profile (name, path or profile); default: the built-in robot the URDF's joint names match.
            Gives directions and CAN ids the URDF lacks, the default output format and the joint order of
            ``berkeley-offsets``.
        method: ``one-sided`` (each joint pushed into the profile's stop: ``position_offset = limit_reading −
            stop_angle``, as Berkeley-Humanoid-Lite-Lowlevel) or ``two-sided`` (bisection); default: the
            profile's procedure, else ``two-sided``.

    Raises:
        UsageError: ``threshold_rad`` or ``span_tolerance_rad`` not a finite number ≥ 0, an unknown ``method``,
            ``direction_step_s`` not a finite number > 0.
    """

    urdf_path: str | Path
    source: str
    out: str | Path
    prior: str | Path | None = None
    threshold_rad: float | None = None
    span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD
    report: str | Path | None = None
    fmt: str | None = None
    direction_check: bool = False
    direction_step_s: float = DEFAULT_DIRECTION_STEP_S
    topic: str = DEFAULT_TOPIC
    frame: str | None = None
    max_samples: int | None = None
    robot: str | os.PathLike[str] | RobotProfile | None = None
    method: str | None = None

    def __post_init__(self) -> None:
        if self.threshold_rad is not None:
            object.__setattr__(self, "threshold_rad", _check_number(self.threshold_rad, "--threshold"))
        if self.method is not None and self.method not in METHODS:
            raise UsageError(f"--method {self.method!r}: expected one of {', '.join(METHODS)}")
        object.__setattr__(self, "span_tolerance_rad", _check_number(self.span_tolerance_rad, "--span-tolerance"))
        if not (math.isfinite(self.direction_step_s) and self.direction_step_s > 0):
            raise UsageError(f"--direction-time {self.direction_step_s}: expected a finite number of seconds > 0")


def run_sweep(
    request: SweepRequest,
    *,
    view: HardStopSweepView | None = None,
    stop: threading.Event | None = None,
    open_source_fn: Callable[..., Source] | None = None,
    confirm: ConfirmFn | None = None,
) -> SweepOutcome:
    """Run a whole sweep calibration and write the calibration file (and report).

    Args:
        request: What to sweep, write and judge (:class:`SweepRequest`, checked when it was built).
        view: Live view.
        stop: Set to end the sweep (Enter).
        open_source_fn: Opens the source (default :func:`robocal.backends.sources.open_source`).
        confirm: Asked, before anything is written, about the joints of :func:`changes_to_confirm` (a prior
            offset would be replaced while the joint has a span_mismatch, no_overlap, offset_large or wrong_side warning);
            returns the joints whose new offset to write, the others keep their prior offset. None (no
            terminal, ``--yes``): every new offset is written.

    Returns:
        The :class:`SweepOutcome`.

    Raises:
        UsageError, FileFormatError, InvalidCalibrationError: bad input; nothing written.
        DeviceError: a bus failed; nothing written.
        SweepAbortedError: a second Ctrl-C; the message says which files were already written (the
            report is written before the calibration, so a calibration is never newer than its report).
    """
    r = request
    source, topic, frame, fmt, method, max_samples = r.source, r.topic, r.frame, r.fmt, r.method, r.max_samples
    threshold_rad, span_tolerance_rad = r.threshold_rad, r.span_tolerance_rad
    # ---- validate everything before touching a device or a file (the request checked its numbers)
    out_path, report_path = check_outputs(
        r.out, r.report, fmt, urdf=r.urdf_path, source=source, robot=r.robot, prior=r.prior
    )
    spec = check_source_options(source, frame)
    if r.direction_check and spec.kind == "replay":
        raise UsageError("--direction-check needs a live or simulated source, not a replay")
    urdf = read_urdf(r.urdf_path)
    profile = resolve_profile(r.robot, urdf)
    if fmt is None:
        fmt = output_format(out_path, profile)
    if fmt == "berkeley-offsets" and profile is None:
        raise UsageError(
            "--format berkeley-offsets is positional in the order of the robot's low-level code; "
            "pass --robot NAME or a profile file"
        )
    if spec.kind == "can" and profile is not None and not speaks_live_can_sweep(profile.actuator):
        raise UsageError(
            f"--source {source}: robot {profile.name} has {profile.actuator} actuators; a live sweep speaks "
            "the Robstride protocol only. Record the joint positions (CSV or rosbag2) and use replay:FILE"
        )
    existing = existing_output(out_path, fmt, urdf, profile)
    joints = joints_from_urdf(urdf, profile, existing)
    if method is None:
        method = profile.method if profile is not None else "two-sided"
    stops: list[tuple[str, float] | None] = []
    for j in joints:
        pj = profile.get(j.name) if profile is not None else None
        stops.append(None if pj is None or pj.stop is None or pj.stop_rad is None else (pj.stop, pj.stop_rad))
    if method == "one-sided":
        lacking = [j.name for j, st in zip(joints, stops, strict=True) if st is None]
        if lacking:
            who = "no robot profile" if profile is None else f"profile {profile.name} has none for them"
            raise UsageError(
                f"--method one-sided needs the stop each joint is pushed into and its angle; {who}: "
                f"{', '.join(lacking)}. Pass --robot NAME (or a profile file with stop/stop_deg), "
                "or --method two-sided"
            )
    if threshold_rad is None:
        threshold_rad = DEFAULT_ONE_SIDED_THRESHOLD_RAD if method == "one-sided" else DEFAULT_THRESHOLD_RAD
    wraps = profile.position_wraps if profile is not None else True
    no_id = [j.name for j in joints if j.can_id <= 0]
    if no_id and fmt != "berkeley-offsets":
        raise FileFormatError(
            f"URDF {urdf.source}: no <param name='can_id'> for {', '.join(no_id)}; "
            f"{fmt} needs an id per joint (pass --robot NAME for a robot robocal knows)"
        )
    if existing is not None:
        _check_foreign_ids(out_path, existing, joints)
    prior_offsets: dict[str, float] = {}
    if r.prior is not None:
        prior_offsets = offsets_by_joint(read_calibration(Path(r.prior), urdf=urdf, robot=profile))
    elif existing is not None:
        prior_offsets = offsets_by_joint(existing)

    # ---- sample
    vendor_source = hand_sweep_source(profile.actuator) if spec.kind == "can" and profile is not None else None
    if vendor_source is not None and open_source_fn is None:  # not Robstride's protocol: the vendor's own source
        assert profile is not None
        if vendor_source == "damiao.source":  # the zeros a killed `sweep --auto --write-zero` left in flash: a note
            from ..motion.damiao_watchdog import note_left_zeros_on

            note_left_zeros_on(spec)
        src: Source = load_backend(vendor_source).open(spec, joints, profile)
    else:
        src = _open_with_upstream_names(open_source_fn or open_source, spec, joints, profile, topic, frame)
    session = SweepSession(src, joints, method=method, stops=stops, wraps=wraps)
    interrupted = ctrl_c_sampling = False
    checks: dict[str, int] | None = None
    zero_sta: dict[str, int] = {}
    try:
        try:
            if r.direction_check:
                checks = run_direction_check(
                    src,
                    joints,
                    on_prompt=view.prompt if view else None,
                    on_result=view.direction_result if view else None,
                    step_s=r.direction_step_s,
                )
            zero_sta = src.zero_sta()
            src.begin_sweep()
            while not (stop is not None and stop.is_set()):
                if max_samples is not None and session.samples >= max_samples:
                    break
                if not session.step():
                    break
                if view is not None:
                    view.update(session)
                if session.exhausted:
                    break
        except KeyboardInterrupt as exc:
            if isinstance(exc, SignalInterrupt):
                raise  # SIGTERM / SIGHUP: stop, write nothing (the CLI says which signal)
            interrupted = ctrl_c_sampling = True  # first Ctrl-C: finish and write
        if stop is not None and stop.is_set():
            interrupted = True
        # ---- finish: a second Ctrl-C from here on aborts; the files not yet written stay as they were
        before = {p: _file_id(p) for p in (out_path, report_path) if p is not None}
        ctrl_c = FinishingCtrlC(seen=1 if ctrl_c_sampling else 0)  # Enter is no Ctrl-C
        try:
            with ctrl_c:
                src.close()
                result = session.result(
                    prior=prior_offsets,
                    threshold_rad=threshold_rad,
                    span_tolerance_rad=span_tolerance_rad,
                    zero_sta=zero_sta,
                    direction_check=checks,
                )
                if view is not None:
                    view.finish(result)
                risky = changes_to_confirm(result) if confirm is not None else []
                if confirm is not None and risky:
                    with ctrl_c.at_prompt():
                        accepted = set(confirm(result, tuple(risky)))
                    result = keep_prior(result, {n for n in risky if n not in accepted})
                write_sweep_files(result, urdf, joints, out_path, fmt, report_path, existing, profile)
        except KeyboardInterrupt as exc:
            cause = ctrl_c.cause(exc)
            err = SweepAbortedError(_aborted_message(before, out_path, report_path, cause))
            if isinstance(exc, SignalInterrupt):
                err.exit_code = exc.exit_code
            raise err from None
    finally:
        with contextlib.suppress(Exception, KeyboardInterrupt):
            src.close()
    code = 0 if result.ok else 1
    return SweepOutcome(
        result,
        out_path,
        fmt,
        report_path,
        code,
        session.samples,
        interrupted,
        session.missing,
        method,
        profile.name if profile is not None else None,
    )


def _open_with_upstream_names(
    opener: Callable[..., Source],
    spec: SourceSpec,
    joints: Sequence[JointSpec],
    profile: RobotProfile | None,
    topic: str,
    frame: str | None,
) -> Source:
    """Open the source; a recording whose columns use the robot code's joint names is accepted too."""
    try:
        return opener(spec, joints, topic=topic, frame=frame)
    except JointMismatchError:
        if spec.kind != "replay" or profile is None or profile.upstream_names == profile.joint_names:
            raise
        alias = [
            replace(j, name=profile.joint(j.name).upstream_name) if j.name in profile else j for j in joints
        ]
        return opener(spec, alias, topic=topic, frame=frame)


def _file_id(path: Path) -> tuple[int, int, int] | None:
    """Identity of the file at ``path`` (inode, size, mtime); an atomic write always changes it."""
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns)


def _aborted_message(
    before: Mapping[Path, tuple[int, int, int] | None], out: Path, report: Path | None, cause: str
) -> str:
    """What an interruption while finishing left behind, by comparing the files with their state before."""
    written = [p for p, ident in before.items() if _file_id(p) != ident]
    if not written:
        return f"sweep aborted by {cause}; nothing was written"
    kept = [str(p) for p in before if p not in written]
    msg = f"sweep aborted by {cause} after writing {' and '.join(str(p) for p in written)} (complete)"
    if kept:
        msg += f"; {' and '.join(kept)} not written (unchanged)"
    return msg


def write_sweep_files(
    result: SweepResult,
    urdf: UrdfModel,
    joints: Sequence[JointSpec],
    out: Path,
    fmt: str,
    report: Path | None,
    existing: CalibrationFile | None = None,
    profile: RobotProfile | None = None,
) -> None:
    """Write the calibration (and the report): refuses when a joint has neither a sweep nor a prior offset."""
    missing = [j for j in result.joints if not j.has_offset]
    if missing:
        detail = ", ".join(f"{j.name} (swept {j.sweep:.3f} rad)" for j in missing)
        raise SweepNotSavedError(
            f"not swept and no prior offset: {detail}; threshold {result.threshold_rad:g} rad. "
            "Sweep them or pass --prior FILE; nothing was written (the offsets of the other joints are "
            "printed above: save them and pass them as --prior to the next sweep)",
            result,
            calibration_text(result, joints, fmt),
            fmt,
        )
    # the URDF joints (id and direction copied from the URDF), in the existing file's order, which keeps its
    # other joints unchanged; new joints go last
    rows = {j.name: (j.direction, result[j.name].homing_offset, j.can_id) for j in joints}
    if existing is not None:
        old = existing.calibration
        kept = {
            n: (int(d), float(h), existing.ids.get(n, 0))
            for n, d, h in zip(old.joint_names, old.direction, old.homing_offset, strict=True)
            if n not in rows
        }
        rows = {n: rows.get(n) or kept[n] for n in (*old.joint_names, *rows)}
    cal = RobotCalibration(list(rows), [r[0] for r in rows.values()], [r[1] for r in rows.values()])
    ids = {n: r[2] for n, r in rows.items() if r[2] > 0}
    text = json.dumps(result.to_report(), indent=2) + "\n" if report is not None else ""
    written: list[Path] = []
    try:  # the report first, the calibration last: an interrupted write never leaves a calibration behind
        if report is not None:  # without the report that describes it
            atomic_write_text(report, text)
            written.append(report)
        ranges = {
            j.name: (j.sampled_min - j.direction * j.homing_offset, j.sampled_max - j.direction * j.homing_offset)
            for j in result.joints
            if math.isfinite(j.sampled_min) and math.isfinite(j.sampled_max) and math.isfinite(j.homing_offset)
        }
        write_calibration(out, CalibrationFile(cal, ids, fmt, ranges_rad=ranges), fmt, urdf=urdf, robot=profile)
    except (CalibError, OSError) as exc:
        if isinstance(exc, OSError):
            reason = f"cannot write {exc.filename or out}: {exc.strerror or exc}"
        else:
            reason = str(exc)
        done = f"{written[0]} was written; " if written else ""
        raise SweepNotSavedError(
            f"{reason}; {done}{out} was NOT written (unchanged). The computed calibration is printed above: "
            f"save it as a {fmt} file so the sweep is not lost",
            result,
            calibration_text(result, joints, fmt),
            fmt,
            written,
        ) from None

