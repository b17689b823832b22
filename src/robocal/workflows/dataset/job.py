"""Dataset job: resolve calibration files, modes and motor family, then re-calibrate or inspect.

This is the layer the CLI calls; it turns flags into :class:`~robocal.dataset.ValueConvention` values and
leaves the numbers to :mod:`robocal.dataset`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ...core.lerobot import parse_compat, parse_convention
from ...core.vendors import expected_homing_vendors, homing_vendor
from ...errors import JointMismatchError, UsageError

if TYPE_CHECKING:
    from ...dataset import DatasetReport, InspectReport, ValueConvention
    from ...dataset._driver import ProgressCallback

__all__ = ["DatasetOptions", "RecalibrateRequest", "data_file_count", "inspect", "recalibrate", "resolve_modes"]

_VALID_MODES = ("degrees", "range_m100_100", "range_0_100")


@dataclass(frozen=True)
class DatasetOptions:
    """How to read the calibrations of a dataset.

    Attributes:
        robot: LeRobot robot type (``so101_follower``, ``koch_follower``, ...); default: ``info.json``'s.
        motor_family: ``feetech`` or ``dynamixel``; default from ``robot``.
        use_degrees: Whether arm joints were recorded in degrees; ``None``: the robot's default.
        modes: Joint → mode for the new calibration (overrides the preset).
        old_modes: Joint → mode for the old calibration (default: the new modes).
        compat: ``lerobot`` (bit-identical, truncating) or ``exact`` (rounding, lossless); rounding only.
        convention: DEGREES values as LeRobot records them (``lerobot``: 4095 ticks per 360°, drive_mode
            ignored) or ``physical`` (4096 ticks per 360°, drive_mode honoured).
    """

    robot: str | None = None
    motor_family: str | None = None
    use_degrees: bool | None = None
    modes: Mapping[str, str] | None = None
    old_modes: Mapping[str, str] | None = None
    compat: str = "lerobot"
    convention: str = "lerobot"

    def __post_init__(self) -> None:
        if self.robot is not None and not self.robot.strip():  # not "use info.json's", said so
            raise UsageError(
                f"--robot {self.robot!r} is empty: name the LeRobot robot type (so101_follower, koch_follower, "
                "...), or leave --robot out to use meta/info.json's robot_type"
            )


def _check_modes(modes: Mapping[str, str], joints: Sequence[str], flag: str) -> None:
    unknown = [j for j in modes if j not in joints]
    if unknown:
        raise JointMismatchError(
            f"{flag}: joint(s) {', '.join(unknown)} not in the dataset; joints: {', '.join(joints)}"
        )
    bad = {j: m for j, m in modes.items() if m not in _VALID_MODES}
    if bad:
        j, m = next(iter(bad.items()))
        raise UsageError(f"{flag}: mode {m!r} for {j!r} is not one of {', '.join(_VALID_MODES)}")


def resolve_modes(
    joints: Sequence[str], opts: DatasetOptions, robot: str | None
) -> tuple[dict[str, str] | None, dict[str, str] | None]:
    """Modes for (old, new): the robot preset, overridden by ``--modes`` and ``--old-modes``.

    Returns:
        ``(old_modes, new_modes)``, ``None`` where nothing determines a mode.
    """
    from ...dataset.lerobot import preset_modes

    new: dict[str, str] | None = dict(preset_modes(robot, joints, opts.use_degrees)) if robot else None
    if opts.modes:
        _check_modes(opts.modes, joints, "--modes")
        new = {**(new or {}), **opts.modes}
    old = dict(new) if new is not None else None
    if opts.old_modes:
        _check_modes(opts.old_modes, joints, "--old-modes")
        old = {**(old or {}), **opts.old_modes}
    return old, new


def _family(opts: DatasetOptions, robot: str | None) -> str | None:
    from ...dataset.lerobot import motor_family_for_robot

    if opts.motor_family is not None:
        if homing_vendor(opts.motor_family) is None:
            raise UsageError(f"--motor-family {opts.motor_family!r}: expected {expected_homing_vendors(quoted=False)}")
        return opts.motor_family
    return motor_family_for_robot(robot) if robot else None


def _conventions(
    root: Path, old: Path | None, new: Path | None, features: Sequence[str] | None, opts: DatasetOptions
) -> tuple[list[str], ValueConvention | None, ValueConvention | None]:
    from ...dataset import read_layout
    from ...dataset.lerobot import load_convention

    layout = read_layout(root)
    feats = layout.select(features)
    joints: list[str] = []
    for f in feats:  # joint-position entries only; "x.vel" and the like are passed through
        joints += [j for j in f.position_joint_names if j not in joints]
    robot = opts.robot or layout.robot_type
    compat = parse_compat(opts.compat)
    convention = parse_convention(opts.convention, "--convention")
    if opts.robot is None and robot is not None and opts.motor_family is None:
        # info.json's robot_type only helps when it names a known robot
        try:
            family = _family(opts, robot)
        except UsageError:
            robot, family = None, None
    else:
        family = _family(opts, robot)
    old_modes, new_modes = resolve_modes(joints, opts, robot)

    def load(path: Path | None, modes: dict[str, str] | None, what: str) -> ValueConvention | None:
        if path is None:
            return None
        return load_convention(
            path,
            joint_names=joints,
            modes=modes,
            family=family,
            compat=compat,
            what=what,
            convention=convention,
        )

    return [f.key for f in feats], load(old, old_modes, "--old"), load(new, new_modes, "--new")


@dataclass(frozen=True)
class RecalibrateRequest:
    """One dataset re-calibration: ``src`` recorded with calibration ``old`` → ``dst`` for ``new``.

    The CLI builds it from ``robocal dataset recalibrate``'s arguments; Python callers build it directly.

    Attributes:
        src: Dataset root (LeRobot v3).
        dst: New dataset root to write.
        old: The calibration the dataset was recorded with.
        new: The calibration to convert to.
        features: Joint features to convert (default: every position feature).
        workers: Processes converting files in parallel.
        overwrite: Replace ``dst`` once the new root is complete.
        options: How to read the calibrations (robot, motor family, modes, compat, convention).
    """

    src: str | Path
    dst: str | Path
    old: str | Path
    new: str | Path
    features: Sequence[str] | None = None
    workers: int = 1
    overwrite: bool = False
    options: DatasetOptions | None = None


def recalibrate(request: RecalibrateRequest, *, on_file_done: ProgressCallback | None = None) -> DatasetReport:
    """Re-calibrate a dataset as ``request`` says (see :func:`robocal.dataset.recalibrate_dataset`).

    Args:
        request: What to convert and how.
        on_file_done: Called with each data file's path and frame count when it is written.

    Returns:
        The :class:`~robocal.dataset.DatasetReport`.
    """
    from ...dataset import recalibrate_dataset

    r = request
    opts = r.options or DatasetOptions()
    keys, c_old, c_new = _conventions(Path(r.src), Path(r.old), Path(r.new), r.features, opts)
    assert c_old is not None and c_new is not None
    return recalibrate_dataset(
        r.src,
        r.dst,
        c_old,
        c_new,
        features=keys,
        workers=r.workers,
        overwrite=r.overwrite,
        on_file_done=on_file_done,
    )


def data_file_count(root: str | Path) -> int:
    """How many data files the dataset at ``root`` holds (the total of a progress bar).

    Raises:
        UsageError: ``root`` is not a folder.
        FileFormatError: Its layout is not a LeRobot v3 dataset's (see :func:`robocal.dataset.read_layout`).
    """
    from ...dataset import read_layout

    return len(read_layout(root).data_files)


def inspect(
    root: str | Path,
    *,
    calibration: str | Path | None = None,
    features: Sequence[str] | None = None,
    options: DatasetOptions | None = None,
) -> InspectReport:
    """Summarise a dataset per joint (see :func:`robocal.dataset.inspect_dataset`).

    Returns:
        The :class:`~robocal.dataset.InspectReport`.
    """
    from ...dataset import inspect_dataset, read_layout

    opts = options or DatasetOptions()
    cal_path = Path(calibration) if calibration is not None else None
    keys, _, conv = _conventions(Path(root), None, cal_path, features, opts)
    modes = None
    if conv is None:
        layout = read_layout(root)
        joints: list[str] = []
        for f in layout.select(keys):
            joints += [j for j in f.position_joint_names if j not in joints]
        robot = opts.robot or layout.robot_type
        try:
            _, modes = resolve_modes(joints, opts, robot)
        except UsageError:
            if opts.robot is not None:
                raise
            _, modes = resolve_modes(joints, opts, None)
    return inspect_dataset(root, features=keys, calibration=conv, modes=modes)
