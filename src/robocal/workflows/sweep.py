"""Hard-stop sweep calibration of Robstride joints: source → range tracker → bisection → file + report.

The source is read in the identity frame (``s = direction·raw``, what the robot publishes with an empty
calibration file). When the sweep ends (source exhausted, Enter, or a first Ctrl-C) the offsets are computed,
validated and written atomically; a second Ctrl-C while finishing aborts and writes nothing.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import threading
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Protocol

import numpy as np
import numpy.typing as npt

from ..backends.sources import (
    FRAMES,
    JointSpec,
    Source,
    SourceSpec,
    open_source,
    parse_source,
)
from ..core.jointmap import RobotCalibration
from ..core.profile import METHODS, RobotProfile
from ..core.sweep import (
    DEFAULT_ONE_SIDED_THRESHOLD_RAD,
    DEFAULT_SPAN_TOLERANCE_RAD,
    DEFAULT_THRESHOLD_RAD,
    RangeTracker,
    SweepResult,
    analyse_sweep,
    direction_from_motion,
)
from ..errors import (
    CalibError,
    FileFormatError,
    JointMismatchError,
    UsageError,
)
from ..fileio import atomic_write_text, check_output_path
from ..formats import CalibrationFile, read_calibration, write_calibration
from ..formats.calibration import read_existing_output
from ..formats.profiles import resolve_profile
from ..formats.urdf import UrdfModel, read_urdf

__all__ = [
    "CONFIRM_CODES",
    "DEFAULT_DIRECTION_STEP_S",
    "OUTPUT_FORMATS",
    "BranchCheck",
    "SweepAbortedError",
    "SweepNotSavedError",
    "SweepOutcome",
    "SweepSession",
    "SweepView",
    "changes_to_confirm",
    "check_source",
    "check_source_options",
    "joints_from_urdf",
    "keep_prior",
    "run_direction_check",
    "run_sweep",
]

FloatArray = npt.NDArray[np.float64]
OUTPUT_FORMATS = ("lite-yaml", "lite-json", "berkeley-offsets")


class SweepAbortedError(CalibError):
    """A second Ctrl-C aborted the sweep; nothing was written (exit 130)."""

    exit_code = 130


CONFIRM_CODES = ("span_mismatch", "no_overlap", "offset_large", "wrong_side")
"""Warnings that make a changed offset need the person's yes before it replaces the prior one."""

ConfirmFn = Callable[[SweepResult, Sequence[str]], Collection[str]]
"""``confirm(result, joints) -> accepted``: asks about ``joints`` and returns those whose new offset to write."""


def changes_to_confirm(result: SweepResult) -> list[str]:
    """Joints whose finished sweep would replace a prior offset while they carry a :data:`CONFIRM_CODES` warning.

    A half-finished sweep (one Enter or Ctrl-C too early) gives ``span_mismatch`` offsets; written silently
    they would replace a good calibration.
    """
    return [
        j.name
        for j in result.joints
        if j.previous_homing_offset is not None
        and not j.kept_prior
        and any(c in CONFIRM_CODES for c in j.warnings)
        and abs(j.homing_offset - j.previous_homing_offset) > 1e-12
    ]


def keep_prior(result: SweepResult, names: Collection[str]) -> SweepResult:
    """``result`` with the prior offset kept (``kept_prior`` True) for the joints ``names`` (declined changes)."""
    joints = tuple(
        replace(j, homing_offset=float(j.previous_homing_offset), kept_prior=True)
        if j.name in names and j.previous_homing_offset is not None
        else j
        for j in result.joints
    )
    return replace(result, joints=joints)


class SweepNotSavedError(CalibError):
    """The sweep finished but its calibration was not saved; the computed offsets travel with the error.

    Raised when a file cannot be written at the end (disk full, folder made read-only during the sweep...)
    or when a joint has no offset at all. The CLI prints :attr:`calibration_text` so that nothing the person
    did is lost: save it as the calibration (or pass it as ``--prior`` to the next sweep).

    Attributes:
        result: The sweep's offsets and diagnostics.
        calibration_text: The joints that have an offset, in the output format (the file that would have
            been written, without the existing file's other joints and comments).
        fmt: That format.
        written: Files that were written before the failure (the report, when the calibration failed).
    """

    exit_code = 2

    def __init__(
        self,
        message: str,
        result: SweepResult,
        calibration_text: str,
        fmt: str,
        written: Sequence[Path] = (),
    ) -> None:
        super().__init__(message)
        self.result = result
        self.calibration_text = calibration_text
        self.fmt = fmt
        self.written = tuple(written)


def calibration_text(result: SweepResult, joints: Sequence[JointSpec], fmt: str) -> str:
    """The joints of ``result`` that have an offset as a ``lite-yaml`` or ``lite-json`` document.

    Offsets are written with ``repr`` (every digit), so the text read back gives the same numbers.
    """
    entries = {
        j.name: {"id": j.can_id, "direction": j.direction, "homing_offset": result[j.name].homing_offset}
        for j in joints
        if result[j.name].has_offset
    }
    if fmt == "lite-json":
        return json.dumps(entries, indent=4) + "\n"
    lines = []
    for name, e in entries.items():
        key = name if name.replace("_", "").isalnum() else json.dumps(name)
        lines += [f"{key}:", f"  id: {e['id']}", f"  direction: {e['direction']}"]
        lines.append(f"  homing_offset: {float(e['homing_offset'])!r}")
    return "\n".join(lines) + "\n"


def joints_from_urdf(
    urdf: UrdfModel,
    profile: RobotProfile | None = None,
    calibration: CalibrationFile | None = None,
) -> list[JointSpec]:
    """The calibrated joints with direction, limits, CAN id and model.

    The joints are the URDF's ``<ros2_control>`` joints when it has any, else the profile's (in the profile's
    order), else the URDF's movable joints. A direction comes from the URDF's ``direction`` param, else the
    calibration file (formats that store one), else the profile; CAN id and model from the URDF's params, else
    the profile. Limits always come from the URDF.

    Raises:
        FileFormatError: A joint has no direction in any source, or no limits.
    """
    if urdf.ros2_control_joint_names or profile is None:
        names = list(urdf.calibration_joint_names())
    else:
        names = list(profile.joint_names)
    file_dirs: dict[str, int] = {}
    if calibration is not None and calibration.fmt != "berkeley-offsets":
        cal = calibration.calibration
        file_dirs = {n: int(d) for n, d in zip(cal.joint_names, cal.direction, strict=True)}
    out = []
    lacking = []
    for name in names:
        d = urdf.direction(name)
        if d is None:
            d = file_dirs.get(name)
        if d is None and profile is not None:
            d = profile.direction(name)
        if d is None:
            lacking.append(name)
            continue
        lo, up = urdf.limits(name)
        can_id = urdf.motor_id(name)
        if can_id is None and profile is not None:
            can_id = profile.motor_id(name)
        model = urdf.param(name, "model") or (
            profile.joint(name).model if profile and name in profile else None
        )
        out.append(JointSpec(name, can_id or 0, model or "rs-00", d, lo, up))
    if lacking:
        where = "no robot profile" if profile is None else f"profile {profile.name} has none"
        raise FileFormatError(
            f"URDF {urdf.source}: no direction for {', '.join(lacking)}: no <param name='direction'>, "
            f"none in a calibration file, {where}; pass --robot NAME or a profile file (docs/profiles.md)"
        )
    if not out:
        raise FileFormatError(f"URDF {urdf.source}: no joints to calibrate")
    owner: dict[int, str] = {}
    for j in out:
        if j.can_id > 0 and owner.setdefault(j.can_id, j.name) != j.name:
            raise FileFormatError(
                f"URDF {urdf.source}: joints {owner[j.can_id]!r} and {j.name!r} share CAN id {j.can_id}"
            )
    return out


def _identity(frame: str, direction: FloatArray, positions: FloatArray) -> FloatArray:
    """Positions in ``frame`` → identity frame ``direction·raw`` (the map is its own inverse), ``(..., N)``."""
    if frame == "motor":
        out: FloatArray = positions * direction
        return out
    return positions


class SweepView(Protocol):
    """What the sweep loop reports to (the CLI's live table; tests use a recorder)."""

    def update(self, session: SweepSession) -> None:
        """Called after every sample (rate-limit the drawing yourself)."""
        ...

    def prompt(self, joint: str) -> None:
        """The direction check asks the operator to move ``joint`` toward its + limit."""
        ...

    def direction_result(self, joint: str, verdict: int) -> None:
        """The direction check's verdict for ``joint``: +1 right, −1 flipped, 0 not verified (no motion)."""
        ...

    def finish(self, result: SweepResult) -> None:
        """Called once with the final result, before anything is written."""
        ...


class SweepSession:
    """The state of a running sweep: a wrap-aware range tracker over the identity frame.

    Besides the wrap-aware range, the session keeps the extremes exactly as read (the one-sided rule of a
    robot whose reading does not wrap uses them, as upstream does) and each joint's first reading.

    Args:
        source: Where samples come from.
        joints: Joints in URDF order (the source's order).
        method: ``two-sided`` or ``one-sided`` (shown by the live view).
        stops: Per joint, the stop of the one-sided procedure as ``(side, angle_rad)``, or None.
        wraps: Whether the position reading wraps each motor turn.
    """

    def __init__(
        self,
        source: Source,
        joints: Sequence[JointSpec],
        *,
        method: str = "two-sided",
        stops: Sequence[tuple[str, float] | None] | None = None,
        wraps: bool = True,
    ) -> None:
        self.source = source
        self.joints = tuple(joints)
        self.names = tuple(j.name for j in self.joints)
        self.direction = np.array([j.direction for j in self.joints], dtype=np.float64)
        self.lower = np.array([j.lower for j in self.joints], dtype=np.float64)
        self.upper = np.array([j.upper for j in self.joints], dtype=np.float64)
        self.tracker = RangeTracker(len(self.joints))
        self.samples = 0
        self.t_s = 0.0
        self.method = method
        self.stops: tuple[tuple[str, float] | None, ...] = (
            tuple(stops) if stops is not None else (None,) * len(self.joints)
        )
        self.wraps = wraps
        n = len(self.joints)
        self._exact_min = np.full(n, np.inf)
        self._exact_max = np.full(n, -np.inf)
        self._first = np.full(n, np.nan)

    def _observe(self, s: FloatArray) -> None:
        """Exact extremes and first readings of a block ``(T, N)`` of identity-frame samples (NaN skipped)."""
        if s.shape[0] == 0:
            return
        np.fmin(self._exact_min, np.fmin.reduce(s, axis=0), out=self._exact_min)
        np.fmax(self._exact_max, np.fmax.reduce(s, axis=0), out=self._exact_max)
        todo = np.isnan(self._first)
        if todo.any():
            finite = np.isfinite(s)
            row = np.argmax(finite, axis=0)
            val = s[row, np.arange(s.shape[1])]
            take = todo & finite.any(axis=0)
            self._first[take] = val[take]

    @property
    def first(self) -> FloatArray:
        """First finite identity-frame reading per joint, shape ``(N,)``, rad (NaN before one)."""
        out: FloatArray = self._first.copy()
        return out

    @property
    def exact_minimum(self) -> FloatArray:
        """Minimum of the readings exactly as read (no unwrapping), shape ``(N,)``, rad (NaN before one)."""
        return np.where(np.isfinite(self._exact_min), self._exact_min, np.nan)

    @property
    def exact_maximum(self) -> FloatArray:
        """Maximum of the readings exactly as read (no unwrapping), shape ``(N,)``, rad (NaN before one)."""
        return np.where(np.isfinite(self._exact_max), self._exact_max, np.nan)

    def to_identity(self, positions: FloatArray) -> FloatArray:
        """Source frame → identity frame ``direction·raw``, shape ``(..., N)``."""
        return _identity(self.source.frame, self.direction, positions)

    @property
    def exhausted(self) -> bool:
        """True when the source has nothing more."""
        return self.source.exhausted

    @property
    def missing(self) -> dict[str, int]:
        """Joint → samples that had no position for it (NaN, e.g. in a JointState), skipped; only joints with some."""
        gaps = self.samples - self.tracker.count
        return {n: int(g) for n, g in zip(self.names, gaps, strict=True) if g > 0}

    def step(self) -> bool:
        """Read one sample (a replay: a block) into the tracker; False when the source is exhausted."""
        read_block = getattr(self.source, "read_block", None)
        if read_block is not None:  # a replay: blocks of rows, memory bounded by the block
            t, pos = read_block(2000)
            if len(t) == 0:
                return False
            block = self.to_identity(pos)
            self.tracker.update_many(block)
            self._observe(block)
            self.samples += len(t)
            self.t_s = float(t[-1])
            return True
        sample = self.source.read()
        if sample is None:
            return False
        s = self.to_identity(sample.position_rad)
        self.tracker.update(s)
        self._observe(s[None, :])
        self.samples += 1
        self.t_s = sample.t_s
        return True

    def result(
        self,
        *,
        prior: Mapping[str, float] | None = None,
        threshold_rad: float = DEFAULT_THRESHOLD_RAD,
        span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
        zero_sta: Mapping[str, int] | None = None,
        direction_check: Mapping[str, int] | None = None,
    ) -> SweepResult:
        """Bisection and diagnostics for what was sampled so far."""
        zs = np.array([(zero_sta or {}).get(n, 0) for n in self.names])
        exact = not self.wraps  # a reading that does not wrap: the extremes exactly as read (as upstream)
        return analyse_sweep(
            self.names,
            self.direction,
            self.lower,
            self.upper,
            self.exact_minimum if exact else self.tracker.minimum,
            self.exact_maximum if exact else self.tracker.maximum,
            prior=prior,
            threshold_rad=threshold_rad,
            span_tolerance_rad=span_tolerance_rad,
            zero_sta=zs,
            direction_check=direction_check,
            method=self.method,
            stops=[None if x is None else x[0] for x in self.stops],
            stop_rad=[math.nan if x is None else x[1] for x in self.stops],
            first=self.first,
            wraps=self.wraps,
        )


DEFAULT_DIRECTION_STEP_S = 5.0
"""Time the guided direction check waits per joint for the motion, s (source clock)."""


def run_direction_check(
    source: Source,
    joints: Sequence[JointSpec],
    *,
    on_prompt: Callable[[str], None] | None = None,
    on_result: Callable[[str, int], None] | None = None,
    min_motion_rad: float = 0.1,
    step_s: float = DEFAULT_DIRECTION_STEP_S,
    timeout_s: float = 60.0,
) -> dict[str, int]:
    """Guided direction check: per joint, ask for a move toward the + limit and watch the sign of motion.

    The wait per joint is measured on the source's clock (sample time stamps: wall-clock time on a live bus,
    simulated time on ``sim:``), so a live bus gets ``step_s`` seconds per joint whatever its poll rate;
    ``timeout_s`` of wall-clock time is a guard for a source whose clock stops.

    Args:
        source: A live or simulated source.
        joints: Joints in the source's order.
        on_prompt: Shows the instruction (called before the source is told).
        on_result: Called with each joint's verdict as soon as it is known (+1, −1 or 0: not verified).
        min_motion_rad: Motion that counts, rad.
        step_s: Time to wait at most per joint, s, on the source's clock.
        timeout_s: Wall-clock time to wait at most per joint, s.

    Returns:
        Joint → +1 (URDF direction right), −1 (flipped) or 0 (the joint did not move enough within
        ``step_s``: its direction is not verified).
    """
    if not (math.isfinite(step_s) and step_s > 0):
        raise UsageError(f"direction check time {step_s}: expected a finite number of seconds > 0")
    d = np.array([j.direction for j in joints], dtype=np.float64)
    out: dict[str, int] = {}
    for i, j in enumerate(joints):
        if on_prompt is not None:
            on_prompt(j.name)
        first = source.read()
        source.prompt_positive(j.name)
        verdict = 0
        if first is not None:
            start = float(_identity(source.frame, d, first.position_rad)[i])
            tracker = RangeTracker(1)
            tracker.update([start])
            t_end = first.t_s + step_s
            deadline = time.monotonic() + timeout_s
            while True:
                s = source.read()
                if s is None or s.t_s > t_end or time.monotonic() > deadline:
                    break
                tracker.update([float(_identity(source.frame, d, s.position_rad)[i])])
                start = start if math.isfinite(start) else float(tracker.current[0])
                verdict = direction_from_motion(float(tracker.current[0]) - start, min_motion_rad)
                if verdict:
                    break
        out[j.name] = verdict
        if on_result is not None:
            on_result(j.name, verdict)
    return out


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


def _offsets(cf: CalibrationFile) -> dict[str, float]:
    cal = cf.calibration
    return {n: float(h) for n, h in zip(cal.joint_names, cal.homing_offset, strict=True)}


def _check_number(value: float, flag: str) -> float:
    if not (math.isfinite(value) and value >= 0):
        raise UsageError(f"{flag} {value}: expected a finite number of rad >= 0")
    return float(value)


def _check_writable(path: Path, flag: str) -> None:
    """Refuse, before the sweep starts, an output the end of the sweep could not write (a real probe)."""
    check_output_path(path, flag)


def _existing_output(
    out: Path, fmt: str, urdf: UrdfModel, profile: RobotProfile | None = None
) -> CalibrationFile | None:
    """The calibration already in ``--out`` (updated in place), or None for a missing or empty file.

    A file holding only comments counts as empty.

    Raises:
        FileFormatError: ``--out`` holds something else than a ``fmt`` calibration (it would be replaced;
            nothing is written).
    """
    return read_existing_output(out, fmt, "--out", urdf=urdf, robot=profile)  # the rule convert applies too


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


def run_sweep(
    urdf_path: str | Path,
    source: str,
    out: str | Path,
    *,
    prior: str | Path | None = None,
    threshold_rad: float | None = None,
    span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
    report: str | Path | None = None,
    fmt: str | None = None,
    direction_check: bool = False,
    direction_step_s: float = DEFAULT_DIRECTION_STEP_S,
    topic: str = "/lite/joint_states",
    frame: str | None = None,
    view: SweepView | None = None,
    stop: threading.Event | None = None,
    max_samples: int | None = None,
    open_source_fn: Callable[..., Source] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
    confirm: ConfirmFn | None = None,
    method: str | None = None,
) -> SweepOutcome:
    """Run a whole sweep calibration and write the calibration file (and report).

    Args:
        urdf_path: URDF with ``<ros2_control>`` joint params (direction, limits, can_id, model).
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
        view: Live view.
        stop: Set to end the sweep (Enter).
        max_samples: Stop after this many samples (None: until the source ends or the user stops).
        open_source_fn: Opens the source (default :func:`robocal.backends.sources.open_source`).
        robot: Robot profile (name, path or profile); default: the built-in robot the URDF's joint names match.
            Gives directions and CAN ids the URDF lacks, the default output format and the joint order of
            ``berkeley-offsets``.
        confirm: Asked, before anything is written, about the joints of :func:`changes_to_confirm` (a prior
            offset would be replaced while the joint has a span_mismatch, no_overlap, offset_large or wrong_side warning);
            returns the joints whose new offset to write, the others keep their prior offset. None (no
            terminal, ``--yes``): every new offset is written.
        method: ``one-sided`` (each joint pushed into the profile's stop: ``position_offset = limit_reading −
            stop_angle``, as Berkeley-Humanoid-Lite-Lowlevel) or ``two-sided`` (bisection); default: the
            profile's procedure, else ``two-sided``.

    Returns:
        The :class:`SweepOutcome`.

    Raises:
        UsageError, FileFormatError, InvalidCalibrationError: bad input; nothing written.
        DeviceError: a bus failed; nothing written.
        SweepAbortedError: a second Ctrl-C; the message says which files were already written (the
            report is written before the calibration, so a calibration is never newer than its report).
    """
    # ---- validate everything before touching a device or a file
    if threshold_rad is not None:
        threshold_rad = _check_number(threshold_rad, "--threshold")
    if method is not None and method not in METHODS:
        raise UsageError(f"--method {method!r}: expected one of {', '.join(METHODS)}")
    span_tolerance_rad = _check_number(span_tolerance_rad, "--span-tolerance")
    if not (math.isfinite(direction_step_s) and direction_step_s > 0):
        raise UsageError(f"--direction-time {direction_step_s}: expected a finite number of seconds > 0")
    out_path = Path(out)
    if fmt is not None and fmt not in OUTPUT_FORMATS:
        raise UsageError(f"--format {fmt!r}: expected one of {', '.join(OUTPUT_FORMATS)}")
    _check_writable(out_path, "--out")
    report_path = Path(report) if report is not None else None
    if report_path is not None:
        _check_writable(report_path, "--report")
        if report_path.resolve() == out_path.resolve():
            raise UsageError(f"--report {report_path}: is the same file as --out")
    spec = check_source_options(source, frame)
    if direction_check and spec.kind == "replay":
        raise UsageError("--direction-check needs a live or simulated source, not a replay")
    urdf = read_urdf(urdf_path)
    profile = resolve_profile(robot, urdf)
    if fmt is None:
        if out_path.suffix.lower() == ".json":
            fmt = "lite-json"
        elif profile is not None and profile.file_format in OUTPUT_FORMATS:
            fmt = profile.file_format
        else:
            fmt = "lite-yaml"
    if fmt == "berkeley-offsets" and profile is None:
        raise UsageError(
            "--format berkeley-offsets is positional in the order of the robot's low-level code; "
            "pass --robot NAME or a profile file"
        )
    if spec.kind == "can" and profile is not None and profile.actuator not in (None, "robstride"):
        raise UsageError(
            f"--source {source}: robot {profile.name} has {profile.actuator} actuators; a live sweep speaks "
            "the Robstride protocol only. Record the joint positions (CSV or rosbag2) and use replay:FILE"
        )
    existing = _existing_output(out_path, fmt, urdf, profile)
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
    if prior is not None:
        prior_offsets = _offsets(read_calibration(Path(prior), urdf=urdf, robot=profile))
    elif existing is not None:
        prior_offsets = _offsets(existing)

    # ---- sample
    src = _open_with_upstream_names(open_source_fn or open_source, spec, joints, profile, topic, frame)
    session = SweepSession(src, joints, method=method, stops=stops, wraps=wraps)
    interrupted = False
    checks: dict[str, int] | None = None
    zero_sta: dict[str, int] = {}
    try:
        try:
            if direction_check:
                checks = run_direction_check(
                    src,
                    joints,
                    on_prompt=view.prompt if view else None,
                    on_result=view.direction_result if view else None,
                    step_s=direction_step_s,
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
        except KeyboardInterrupt:
            interrupted = True  # first Ctrl-C: finish and write
        if stop is not None and stop.is_set():
            interrupted = True
        # ---- finish: a second Ctrl-C from here on aborts; the files not yet written stay as they were
        before = {p: _file_id(p) for p in (out_path, report_path) if p is not None}
        try:
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
                accepted = set(confirm(result, tuple(risky)))
                result = keep_prior(result, {n for n in risky if n not in accepted})
            _write(result, urdf, joints, out_path, fmt, report_path, existing, profile)
        except KeyboardInterrupt:
            raise SweepAbortedError(_aborted_message(before, out_path, report_path)) from None
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
    before: Mapping[Path, tuple[int, int, int] | None], out: Path, report: Path | None
) -> str:
    """What a second Ctrl-C left behind, by comparing the files with their state before writing."""
    written = [p for p, ident in before.items() if _file_id(p) != ident]
    if not written:
        return "sweep aborted by a second Ctrl-C; nothing was written"
    kept = [str(p) for p in before if p not in written]
    msg = f"sweep aborted by a second Ctrl-C after writing {' and '.join(str(p) for p in written)} (complete)"
    if kept:
        msg += f"; {' and '.join(kept)} not written (unchanged)"
    return msg


def _write(
    result: SweepResult,
    urdf: UrdfModel,
    joints: Sequence[JointSpec],
    out: Path,
    fmt: str,
    report: Path | None,
    existing: CalibrationFile | None = None,
    profile: RobotProfile | None = None,
) -> None:
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
        write_calibration(out, CalibrationFile(cal, ids, fmt), fmt, urdf=urdf, robot=profile)
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


# ------------------------------------------------------------------------------------------ power-on check
@dataclass(frozen=True)
class BranchCheck:
    """First reading after power-on of one joint, with the 2π branch selection applied.

    Attributes:
        name: Joint name.
        raw_rad: Raw motor position as read, rad.
        raw_selected_rad: Raw position on the branch that puts the joint inside its limits, rad.
        turns: Whole turns added (``(raw_selected − raw)/2π``).
        q_rad: Joint position on the selected branch, rad.
        lower: Lower limit, rad.
        upper: Upper limit, rad.
        in_limits: Whether ``q_rad`` is inside the limits (± margin).
    """

    name: str
    raw_rad: float
    raw_selected_rad: float
    turns: int
    q_rad: float
    lower: float
    upper: float
    in_limits: bool

    @property
    def problem(self) -> str | None:
        """A one-line problem description, or None."""
        if not self.in_limits:
            return (
                f"{self.name}: q = {self.q_rad:.3f} rad is outside [{self.lower:.3f}, {self.upper:.3f}] "
                "on every 2π branch; recalibrate or check the URDF"
            )
        return None


def check_source_options(source: str, frame: str | None = None) -> SourceSpec:
    """Validate ``--source`` and ``--frame`` (before anything is read or printed).

    Raises:
        UsageError: Malformed source string or unknown frame.
    """
    if frame is not None and frame not in FRAMES:
        raise UsageError(f"--frame {frame!r}: expected one of {', '.join(FRAMES)}")
    return parse_source(source)


def check_source(
    urdf_path: str | Path,
    calibration_path: str | Path,
    source: str,
    *,
    topic: str = "/lite/joint_states",
    frame: str | None = None,
    margin_rad: float = 0.05,
    open_source_fn: Callable[..., Source] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> list[BranchCheck]:
    """Read the first sample after power-on and apply the 2π branch selection per joint.

    Args:
        urdf_path: The URDF.
        calibration_path: The calibration file (any format robocal reads).
        source: ``--source``.
        topic: rosbag2 topic.
        frame: Replay frame.
        margin_rad: Tolerance on the limits, rad.
        open_source_fn: Opens the source.
        robot: Robot profile (default: the built-in robot the URDF's joint names match).

    Returns:
        One :class:`BranchCheck` per URDF joint the calibration has, in URDF order (``robocal check`` reports
        the joints it lacks).
    """
    spec = check_source_options(source, frame)
    urdf = read_urdf(urdf_path)
    profile = resolve_profile(robot, urdf)
    cf = read_calibration(calibration_path, urdf=urdf, robot=profile)
    all_joints = joints_from_urdf(urdf, profile, cf)
    keep = [i for i, j in enumerate(all_joints) if j.name in cf.calibration]
    if not keep:
        raise JointMismatchError(f"calibration {calibration_path}: no offset for any joint of the URDF")
    joints = [all_joints[i] for i in keep]
    names = [j.name for j in joints]
    cal = cf.calibration.select(names).with_directions({j.name: j.direction for j in joints})
    src = (open_source_fn or open_source)(spec, all_joints, topic=topic, frame=frame)
    try:
        sample = src.read()
        if sample is None:
            raise FileFormatError(f"source {source}: no samples")
        d = np.array([j.direction for j in joints], dtype=np.float64)
        pos = sample.position_rad[keep]
        raw = pos if src.frame == "motor" else d * pos  # identity → raw is d·s as well (d² = 1)
    finally:
        src.close()
    if not np.all(np.isfinite(raw)):
        bad = [n for n, r in zip(names, raw, strict=True) if not math.isfinite(r)]
        raise FileFormatError(f"source {source}: first sample has no position for {', '.join(bad)}")
    lo = np.array([j.lower for j in joints])
    up = np.array([j.upper for j in joints])
    sel = cal.unwrap_to_limits(raw, lo, up)
    q = cal.to_joint(sel)
    inside = (q >= lo - margin_rad) & (q <= up + margin_rad)
    return [
        BranchCheck(
            n,
            float(raw[i]),
            float(sel[i]),
            round((sel[i] - raw[i]) / (2 * math.pi)),
            float(q[i]),
            float(lo[i]),
            float(up[i]),
            bool(inside[i]),
        )
        for i, n in enumerate(names)
    ]
