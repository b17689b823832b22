"""LeRobot calibration files: the current per-motor JSON and the legacy parallel-array JSON.

Current (huggingface/lerobot#777 → v0.6.x): ``draccus.dump(dict[str, MotorCalibration], indent=4)`` — a JSON
object keyed by motor name in bus order, each value ``{"id", "drive_mode", "homing_offset", "range_min",
"range_max"}`` (ints, that key order), 4-space indent, no trailing newline. Reading is strict like draccus:
every field required, no extra field, ints only.

Legacy (2024 → 2025-06): ``json.dump(calibration, f)`` without indent — a flat object of six parallel arrays
``homing_offset, drive_mode, start_pos, end_pos, calib_mode, motor_names``.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..core.lerobot import LegacyCalibration, MotorCalibration, ranges_beyond_one_turn
from ..errors import CalibError, FileFormatError, InvalidCalibrationError, UsageError
from ..fileio import MAX_DOCUMENT_BYTES, atomic_write_text, check_output_path, read_text
from ._json import load_json

__all__ = [
    "CURRENT_FIELDS",
    "KINDS",
    "LEGACY_KEYS",
    "LeRobotRangeWarning",
    "calibration_path",
    "default_calibration_root",
    "dumps_current",
    "dumps_legacy",
    "parse_current",
    "parse_legacy",
    "read_current",
    "read_legacy",
    "write_current",
    "write_legacy",
]

CURRENT_FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
"""Field order of one motor in the current JSON (``MotorCalibration`` field order)."""
LEGACY_KEYS = ("homing_offset", "drive_mode", "start_pos", "end_pos", "calib_mode", "motor_names")
"""Key order of the legacy JSON."""


class LeRobotRangeWarning(UserWarning):
    """A calibration written or read has a motor range beyond one servo turn (LeRobot accepts it unchecked)."""


def dumps_current(cals: Mapping[str, MotorCalibration]) -> str:
    """Serialise like ``draccus.dump(..., indent=4)``: 4-space indent, bus order, ints, no final newline.

    Raises:
        InvalidCalibrationError: ``cals`` is not a mapping of motor name → ``MotorCalibration``.
    """
    if not isinstance(cals, Mapping):
        raise InvalidCalibrationError(
            f"calibration is a {type(cals).__name__}; expected a mapping of motor name → MotorCalibration"
        )
    for name, c in cals.items():
        if not isinstance(name, str) or not isinstance(c, MotorCalibration):
            raise InvalidCalibrationError(
                f"motor {name!r}: expected a MotorCalibration keyed by its name, got {type(c).__name__}"
            )
    data = {name: {f: int(getattr(c, f)) for f in CURRENT_FIELDS} for name, c in cals.items()}
    return json.dumps(data, indent=4)


INT32_MAX = 2**31 - 1
"""Largest magnitude accepted for an integer field: every servo register robocal knows fits in 32 bits."""


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _int_problem(value: Any) -> str | None:
    """Why ``value`` is not a usable integer field (None when it is one)."""
    if not _is_int(value):
        return f"is {value!r}; expected an integer"
    if abs(value) > INT32_MAX:
        digits = len(str(abs(value)))
        shown = str(value) if digits <= 24 else f"an integer of {digits} digits"
        return f"is {shown}; expected an integer within ±{INT32_MAX} (a 32-bit register)"
    return None


def parse_current(text: str, source: str = "<string>") -> dict[str, MotorCalibration]:
    """Parse and strictly validate a current LeRobot calibration JSON.

    Args:
        text: File contents.
        source: File name used in error messages.

    Returns:
        Motor name → calibration, in file order.

    Raises:
        FileFormatError: Not JSON, not an object of objects, a missing/extra/non-int field, duplicate ids,
            ``range_min >= range_max``, or a legacy array file. The message names the file, motor and field.
    """
    data = load_json(text, source, item="motor")
    if not isinstance(data, dict):
        raise FileFormatError(f"{source}: expected a JSON object of motors, got {type(data).__name__}")
    if data and all(isinstance(v, list) for v in data.values()):
        raise FileFormatError(
            f"{source}: this is a legacy LeRobot calibration (parallel arrays); convert it with "
            "`robocal lerobot migrate`"
        )
    if not data:
        raise FileFormatError(f"{source}: no motors")
    out: dict[str, MotorCalibration] = {}
    ids: dict[int, str] = {}
    for motor, entry in data.items():
        if not isinstance(entry, dict):
            raise FileFormatError(
                f"{source}: motor {motor!r}: expected an object, got {type(entry).__name__}"
            )
        missing = [f for f in CURRENT_FIELDS if f not in entry]
        if missing:
            raise FileFormatError(
                f"{source}: motor {motor!r}: missing required field(s) {', '.join(missing)}"
            )
        extra = [f for f in entry if f not in CURRENT_FIELDS]
        if extra:
            raise FileFormatError(f"{source}: motor {motor!r}: unknown field(s) {', '.join(extra)}")
        for f in CURRENT_FIELDS:
            problem = _int_problem(entry[f])
            if problem is not None:
                raise FileFormatError(f"{source}: motor {motor!r}: field {f} {problem}")
        if entry["drive_mode"] not in (0, 1):
            raise FileFormatError(
                f"{source}: motor {motor!r}: field drive_mode is {entry['drive_mode']}; expected 0 or 1"
            )
        if not 0 <= entry["id"] <= 253:
            raise FileFormatError(f"{source}: motor {motor!r}: field id is {entry['id']}; expected 0..253")
        if entry["range_min"] >= entry["range_max"]:
            raise FileFormatError(
                f"{source}: motor {motor!r}: field range_min {entry['range_min']} must be less than "
                f"range_max {entry['range_max']}"
            )
        if entry["id"] in ids:
            raise FileFormatError(
                f"{source}: motor {motor!r}: field id {entry['id']} is also used by {ids[entry['id']]!r}"
            )
        ids[entry["id"]] = motor
        out[motor] = MotorCalibration(**{f: entry[f] for f in CURRENT_FIELDS})
    return out


def read_current(path: str | os.PathLike[str]) -> dict[str, MotorCalibration]:
    """Read a current LeRobot calibration JSON file (see :func:`parse_current`)."""
    return parse_current(read_text(path, "LeRobot calibration", limit=MAX_DOCUMENT_BYTES), str(path))


def write_current(
    path: str | os.PathLike[str], cals: Mapping[str, MotorCalibration], *, make_dirs: bool = True
) -> Path:
    """Write a current LeRobot calibration JSON atomically (keeps ``NAME.bak``); validates first.

    A motor whose range lies beyond one turn (``0..4095``) is written as given, like LeRobot, but with a
    :class:`LeRobotRangeWarning` naming it (see :func:`robocal.core.lerobot.ranges_beyond_one_turn`).

    Raises:
        FileFormatError: The calibration would not read back (duplicate ids, ``range_min >= range_max``, ...).
        UsageError: The file cannot be created there (:func:`robocal.fileio.check_output_path`, missing
            folders allowed).
    """
    text = dumps_current(cals)
    parse_current(text, str(path))
    p = check_output_path(path, "cannot write", create_dirs=True)
    for message in ranges_beyond_one_turn(cals):
        warnings.warn(f"{p}: {message}", LeRobotRangeWarning, stacklevel=2)
    if make_dirs:
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"cannot write {p}: cannot create folder {p.parent} ({exc.strerror})") from None
    return atomic_write_text(p, text)


def dumps_legacy(cal: LegacyCalibration) -> str:
    """Serialise like LeRobot's legacy ``json.dump(calibration, f)`` (no indent, default separators)."""
    if not isinstance(cal, LegacyCalibration):
        raise InvalidCalibrationError(
            f"calibration is a {type(cal).__name__}; expected a LegacyCalibration (see read_legacy)"
        )
    data = {
        "homing_offset": [int(v) for v in cal.homing_offset],
        "drive_mode": [int(v) for v in cal.drive_mode],
        "start_pos": [int(v) for v in cal.start_pos],
        "end_pos": [int(v) for v in cal.end_pos],
        "calib_mode": list(cal.calib_mode),
        "motor_names": list(cal.motor_names),
    }
    return json.dumps(data)


def _motor_name(data: Mapping[str, Any], i: int) -> str:
    names = data.get("motor_names")
    if isinstance(names, list) and i < len(names) and isinstance(names[i], str):
        return f" (motor {names[i]!r})"
    return ""


def parse_legacy(text: str, source: str = "<string>") -> LegacyCalibration:
    """Parse and validate a legacy LeRobot calibration JSON (six parallel arrays).

    Raises:
        FileFormatError: Not JSON, a missing/extra key, a wrong element type, arrays of different lengths,
            or a current-format file; the message names the file and key.
    """
    data = load_json(text, source)
    if not isinstance(data, dict):
        raise FileFormatError(f"{source}: expected a JSON object of arrays, got {type(data).__name__}")
    if data and all(isinstance(v, dict) for v in data.values()):
        raise FileFormatError(
            f"{source}: this is a current LeRobot calibration (per-motor objects), not legacy"
        )
    missing = [k for k in LEGACY_KEYS if k not in data]
    if missing:
        raise FileFormatError(f"{source}: missing key(s) {', '.join(missing)}")
    extra = [k for k in data if k not in LEGACY_KEYS]
    if extra:
        raise FileFormatError(f"{source}: unknown key(s) {', '.join(extra)}")
    n = None
    for key in LEGACY_KEYS:
        arr = data[key]
        if not isinstance(arr, list):
            raise FileFormatError(f"{source}: key {key} is {type(arr).__name__}; expected a list")
        want_str = key in ("calib_mode", "motor_names")
        for i, v in enumerate(arr):
            if want_str and not isinstance(v, str):
                raise FileFormatError(f"{source}: key {key}[{i}] is {v!r}; expected a string")
            problem = None if want_str else _int_problem(v)
            if problem is not None:
                motor = _motor_name(data, i)
                raise FileFormatError(f"{source}: key {key}[{i}] {problem}{motor}")
        if n is None:
            n = len(arr)
        elif len(arr) != n:
            raise FileFormatError(
                f"{source}: key {key} has {len(arr)} entries; expected {n} like homing_offset"
            )
    if not n:
        raise FileFormatError(f"{source}: no motors (the arrays are empty)")
    for i, m in enumerate(data["calib_mode"]):
        if m not in ("DEGREE", "LINEAR"):
            raise FileFormatError(f"{source}: key calib_mode[{i}] is {m!r}; expected 'DEGREE' or 'LINEAR'")
    for i, d in enumerate(data["drive_mode"]):
        if d not in (0, 1):
            raise FileFormatError(f"{source}: key drive_mode[{i}] is {d}; expected 0 or 1")
    try:
        return LegacyCalibration(
            data["motor_names"],
            data["homing_offset"],
            data["drive_mode"],
            data["start_pos"],
            data["end_pos"],
            data["calib_mode"],
        )
    except CalibError as exc:
        raise FileFormatError(f"{source}: {exc}") from None


def read_legacy(path: str | os.PathLike[str]) -> LegacyCalibration:
    """Read a legacy LeRobot calibration JSON file (see :func:`parse_legacy`)."""
    return parse_legacy(read_text(path, "LeRobot legacy calibration", limit=MAX_DOCUMENT_BYTES), str(path))


def write_legacy(path: str | os.PathLike[str], cal: LegacyCalibration) -> Path:
    """Write a legacy LeRobot calibration JSON atomically, byte-identical to LeRobot's writer."""
    text = dumps_legacy(cal)
    parse_legacy(text, str(path))  # refuses what would not read back (e.g. a lone surrogate in a name)
    return atomic_write_text(path, text)


# ------------------------------------------------------------------------------ calibration paths
KINDS = {
    "robots": "robots",
    "robot": "robots",
    "teleoperators": "teleoperators",
    "teleoperator": "teleoperators",
}


def default_calibration_root() -> Path:
    """LeRobot's calibration root folder.

    ``$HF_LEROBOT_CALIBRATION``, else ``$HF_LEROBOT_HOME/calibration``, else ``$HF_HOME/lerobot/calibration``
    where ``HF_HOME`` defaults like ``huggingface_hub`` to ``$XDG_CACHE_HOME/huggingface``, else
    ``~/.cache/huggingface`` (so ``~/.cache/huggingface/lerobot/calibration``). Empty variables count as unset.
    """
    env = os.environ
    if env.get("HF_LEROBOT_CALIBRATION"):
        return Path(env["HF_LEROBOT_CALIBRATION"]).expanduser()
    if env.get("HF_LEROBOT_HOME"):
        return Path(env["HF_LEROBOT_HOME"]).expanduser() / "calibration"
    if env.get("HF_HOME"):
        hf_home = Path(os.path.expandvars(os.path.expanduser(env["HF_HOME"])))
    else:
        cache = Path(env["XDG_CACHE_HOME"]) if env.get("XDG_CACHE_HOME") else Path.home() / ".cache"
        hf_home = Path(os.path.expandvars(os.path.expanduser(cache / "huggingface")))
    return hf_home / "lerobot" / "calibration"


def calibration_path(
    kind: str, name: str, id: str | None, root: str | os.PathLike[str] | None = None
) -> Path:
    """LeRobot's calibration file path ``ROOT/{robots|teleoperators}/<name>/<id>.json``.

    Args:
        kind: ``"robots"`` or ``"teleoperators"`` (singular accepted).
        name: Device class name, e.g. ``"so_follower"`` (v0.4.3+), ``"so101_follower"`` (older),
            ``"koch_leader"``.
        id: The robot id; ``None`` gives LeRobot's literal ``None.json``.
        root: Calibration root; default :func:`default_calibration_root`.
    """
    if kind not in KINDS:
        raise UsageError(f"calibration kind {kind!r}: expected 'robots' or 'teleoperators'")
    for what, value in (("name", name), ("id", str(id))):
        if not value or "/" in value or "\\" in value or value in (".", ".."):
            raise UsageError(f"calibration {what} {value!r}: expected a plain file name")
    base = Path(root).expanduser() if root is not None else default_calibration_root()
    return base / KINDS[kind] / name / f"{id}.json"
