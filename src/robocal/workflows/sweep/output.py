"""The guards around what a finished sweep writes.

The output checks made before anything moves (``--out``, ``--report``, ``--format`` and its default; shared by
``sweep`` and ``sweep --auto``), confirming changes that would replace a good offset, and the calibration text
that travels with :class:`SweepNotSavedError` when the file could not be written.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Sequence
from dataclasses import replace
from pathlib import Path

from ...backends.sources import JointSpec, recording_path
from ...core.profile import RobotProfile
from ...core.sweep_result import SweepResult
from ...errors import CalibError, UsageError
from ...fileio import check_output_path
from ...formats.profiles import profile_file

__all__ = [
    "CONFIRM_CODES",
    "OUTPUT_FORMATS",
    "ConfirmFn",
    "SweepNotSavedError",
    "calibration_text",
    "changes_to_confirm",
    "check_outputs",
    "keep_prior",
    "output_format",
]

OUTPUT_FORMATS = ("lite-yaml", "lite-json", "berkeley-offsets", "openarm-lerobot", "openarm-ros2")
"""Formats a sweep writes (``--format``)."""


def check_outputs(
    out: str | Path,
    report: str | Path | None,
    fmt: str | None,
    *,
    urdf: str | Path | None = None,
    source: str | None = None,
    robot: object = None,
    prior: str | Path | None = None,
) -> tuple[Path, Path | None]:
    """Refuse, before the sweep starts, outputs the end of the sweep could not write (a real probe of each).

    Neither output may be one of the sweep's inputs (the URDF, a ``replay:`` recording, a profile file; the report
    not ``--prior`` either): ``--out`` is the one file a sweep updates in place.

    Returns:
        ``(out_path, report_path)``.

    Raises:
        UsageError: ``fmt`` not in :data:`OUTPUT_FORMATS`, an output not writable or an input, or ``--report`` is
            ``--out``.
    """
    out_path = Path(out)
    if fmt is not None and fmt not in OUTPUT_FORMATS:
        raise UsageError(f"--format {fmt!r}: expected one of {', '.join(OUTPUT_FORMATS)}")
    inputs = {"--urdf": urdf, "--source": recording_path(source), "--robot": profile_file(robot)}
    check_output_path(out_path, "--out", inputs=inputs)
    report_path = Path(report) if report is not None else None
    if report_path is not None:
        check_output_path(report_path, "--report", inputs={**inputs, "--prior": prior})
        if report_path.resolve() == out_path.resolve():
            raise UsageError(f"--report {report_path}: is the same file as --out")
    return out_path, report_path


def output_format(out_path: Path, profile: RobotProfile | None) -> str:
    """The format written without ``--format``.

    ``lite-json`` for a ``.json`` file, else the profile's format when a sweep writes it, else ``lite-yaml``.
    """
    if out_path.suffix.lower() == ".json":
        return "lite-json"
    if profile is not None and profile.file_format in OUTPUT_FORMATS:
        return profile.file_format
    return "lite-yaml"


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
