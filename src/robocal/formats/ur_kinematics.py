"""UR kinematics files: ur_description's kinematics YAML (out and in) and the DH inputs.

Output (what ``ur_description`` reads through ``kinematics_params_file``)::

    kinematics:
      shoulder:
        x: 0.0
        y: 0.0
        z: 0.1625
        roll: 0.0
        pitch: 0.0
        yaw: 0.0
      upper_arm: ...
      forearm: ...
      wrist_1: ...
      wrist_2: ...
      wrist_3: ...
      hash: calib_12788084448423163542

Floats are written shortest-round-trip (Python ``repr``), never ``-0``; ``hash`` is the last key under
``kinematics`` and is never quoted (a quoted hash makes the driver's check fail).

DH inputs:

* a DH YAML with ``dh_theta``, ``dh_a``, ``dh_d``, ``dh_alpha`` (six numbers each, radians and metres): flow
  lists with commas, block lists, or flow lists separated by spaces (``[a b c d e f ]``) as the driver's log and
  the ur_calibration docs print them; a pasted ROS log (line prefixes, ``checksum`` and ``calibration_status``
  lines) reads as well;
* a deltas file with ``delta_theta``, ``delta_a``, ``delta_d``, ``delta_alpha``, either YAML or the
  controller's ``calibration.conf`` (``delta_theta = [ ... ]`` under ``[mounting]``, a list possibly spanning
  several lines), to be added to a model's nominal DH.

Unknown keys in a YAML input (e.g. a misspelt ``dh_alhpa``) are reported as warnings; a
``calibration.conf``'s other entries (``joint_checksum``, ``calibration_status``, ...) are ignored.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..core.dh import DHParameters
from ..core.ur import JOINT_NAMES, LINK_NAMES, LinkOrigin, UrKinematics
from ..errors import FileFormatError, JointMismatchError
from ..fileio import MAX_DOCUMENT_BYTES, atomic_write_bytes, atomic_write_text, read_text
from ._yaml import load_yaml, yaml_float
from .urdf import UrdfDocument, UrdfModel

__all__ = [
    "DELTA_KEYS",
    "DH_KEYS",
    "kinematics_to_text",
    "read_deltas",
    "read_dh",
    "read_kinematics",
    "require_ur_joints",
    "update_urdf_origins",
    "urdf_with_origins",
    "write_kinematics",
]

DH_KEYS: tuple[str, ...] = ("dh_theta", "dh_a", "dh_d", "dh_alpha")
"""Keys of a DH YAML file (θ rad, a m, d m, α rad)."""

DELTA_KEYS: tuple[str, ...] = ("delta_theta", "delta_a", "delta_d", "delta_alpha")
"""Keys of a calibration deltas file (added to the nominal DH)."""

_FIELDS = ("x", "y", "z", "roll", "pitch", "yaw")
_HASH_RE = re.compile(r"calib_[0-9]{1,20}")
_UINT64_MAX = (1 << 64) - 1


def kinematics_to_text(kin: UrKinematics) -> str:
    """Serialise kinematics to ur_description YAML text (block style, fixed key order).

    Args:
        kin: The six link origins and the hash.

    Returns:
        The file text, ending with a newline.
    """
    lines = [
        f"# UR kinematics for ur_description (kinematics_params_file), written by robocal; "
        f"rpy convention: {kin.rpy_convention}",
        "kinematics:",
    ]
    for link in kin.links:
        lines.append(f"  {link.name}:")
        for key, value in zip(_FIELDS, (*link.xyz_m, *link.rpy_rad), strict=True):
            if not math.isfinite(value):
                raise FileFormatError(
                    f"kinematics {link.name}.{key} is {value}; refusing to write a non-finite value"
                )
            lines.append(f"    {key}: {yaml_float(value)}")
    lines.append(f"  hash: {kin.hash}")
    return "\n".join(lines) + "\n"


def write_kinematics(path: str | os.PathLike[str], kin: UrKinematics) -> Path:
    """Validate, then write the kinematics YAML atomically (previous file kept as ``NAME.bak``).

    Args:
        path: Destination; its folder must exist.
        kin: Content.

    Returns:
        The written path.
    """
    text = kinematics_to_text(kin)  # raises before anything is written
    return atomic_write_text(path, text)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FileFormatError(f"{where} is {value!r}; expected a number")
    v = float(value)
    if not math.isfinite(v):
        raise FileFormatError(f"{where} is {v}; expected a finite number")
    return v


def read_kinematics(path: str | os.PathLike[str]) -> UrKinematics:
    """Read a ur_description kinematics YAML (robocal's or upstream's).

    The rpy convention is taken from robocal's header comment when present (``rpy convention: upstream``),
    else ``"urdf"`` — which is how ur_description interprets the numbers in any case.

    Args:
        path: The YAML file.

    Returns:
        The six link origins and the hash.

    Raises:
        FileFormatError: Missing links or fields, non-numbers, NaN, or a malformed hash (names file and key).
    """
    text = read_text(path, "kinematics YAML", limit=MAX_DOCUMENT_BYTES)
    data = load_yaml(text, str(path))
    where = f"kinematics YAML {path}"
    if not isinstance(data, Mapping):
        raise FileFormatError(
            f"{where}: the document is {_shown(data)}; expected a top-level 'kinematics' mapping"
        )
    if "kinematics" not in data:
        found = ", ".join(str(k) for k in data) or "none"
        hint = ""
        if all(k in data for k in DH_KEYS):
            hint = "; this is a DH file (pass it with --dh)"
        elif all(k in data for k in DELTA_KEYS):
            hint = "; this is a deltas file (pass it with --model MODEL --deltas FILE)"
        raise FileFormatError(
            f"{where}: expected a top-level 'kinematics' mapping; found keys: {found}{hint}"
        )
    kin = data["kinematics"]
    if not isinstance(kin, Mapping):
        raise FileFormatError(f"{where}: kinematics is {_shown(kin)}; expected a mapping of the six links")
    links: list[LinkOrigin] = []
    for name in LINK_NAMES:
        if name not in kin:
            found = ", ".join(str(k) for k in kin) or "none"
            raise FileFormatError(f"{where}: kinematics.{name} is missing (found: {found})")
        entry = kin[name]
        if not isinstance(entry, Mapping):
            raise FileFormatError(
                f"{where}: kinematics.{name} is {_shown(entry)}; expected a mapping with {', '.join(_FIELDS)}"
            )
        vals = []
        for key in _FIELDS:
            if key not in entry:
                raise FileFormatError(f"kinematics YAML {path}: kinematics.{name}.{key} is missing")
            vals.append(_number(entry[key], f"kinematics YAML {path}: kinematics.{name}.{key}"))
        links.append(LinkOrigin(name, (vals[0], vals[1], vals[2]), (vals[3], vals[4], vals[5])))
    h = kin.get("hash")
    if not isinstance(h, str) or not _HASH_RE.fullmatch(h) or int(h[6:]) > _UINT64_MAX:
        raise FileFormatError(f"kinematics YAML {path}: kinematics.hash is {h!r}; expected calib_<uint64>")
    convention = "upstream" if "rpy convention: upstream" in text.split("\n", 1)[0] else "urdf"
    return UrKinematics(links=tuple(links), hash=h, rpy_convention=convention)


_SIX_FORMS = "[a, b, c, d, e, f], [a b c d e f] or a block list"


def _shown(value: Any) -> str:
    text = repr(value if not isinstance(value, (list, tuple)) else list(value))
    return text if len(text) <= 120 else text[:117] + "..."


def _six(value: Any, where: str) -> tuple[float, ...]:
    """Six finite numbers from a YAML list in any form UR and the ROS drivers write.

    ``[a, b, c, d, e, f]`` and block lists are YAML lists of numbers. UR's driver log and the ur_calibration
    docs print ``[a b c d e f ]`` (numbers separated by spaces), which YAML reads as a list holding one string;
    that string is split at whitespace.
    """
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise FileFormatError(f"{where} is {_shown(value)}; expected a list of 6 numbers ({_SIX_FORMS})")
    items: list[Any] = list(value)
    if len(items) == 1 and isinstance(items[0], str) and len(items[0].split()) > 1:
        tokens = items[0].split()
        items = []
        for i, token in enumerate(tokens):
            try:
                items.append(float(token))
            except ValueError:
                raise FileFormatError(
                    f"{where}[{i}] is {token!r}; expected a number (the list is {_shown(value[0])})"
                ) from None
    else:
        for i, v in enumerate(items):
            if isinstance(v, str):
                hint = "; separate the 6 numbers all by commas or all by spaces" if len(v.split()) > 1 else ""
                raise FileFormatError(
                    f"{where}[{i}] is {v!r}; expected a number (the list is {_shown(value)}){hint}"
                )
    if len(items) != 6:
        raise FileFormatError(
            f"{where} has {len(items)} values ({_shown(items)}); expected 6 numbers ({_SIX_FORMS})"
        )
    return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(items))


_CONF_SECTION = re.compile(r"^\[\s*[A-Za-z_][\w .-]*\]$")
_CONF_ASSIGN = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*)$")
_CONF_TOKEN = re.compile(r",|[^,\s]+")


def _conf_code(line: str) -> str:
    """A ``calibration.conf`` line without its comment (``# ...`` anywhere, ``;`` at the start) or spaces."""
    code = line.split("#", 1)[0].strip()
    return "" if code.startswith(";") else code


def _conf_items(key: str, start_line: int, body: str, source: str) -> list[tuple[int, str]]:
    """Split the inside of ``[ ... ]`` (possibly several lines joined by newlines) into ``(line, entry)``.

    Entries are separated by commas (the controller's syntax) or whitespace; an empty entry (``1,,2``, a
    leading or trailing comma) is refused.
    """
    items: list[tuple[int, str]] = []
    after_comma = True  # a comma before the first entry is an empty entry too
    commas = 0
    for m in _CONF_TOKEN.finditer(body):
        lineno = start_line + body.count("\n", 0, m.start())
        if m.group() == ",":
            if after_comma:
                raise FileFormatError(f"{source} line {lineno}: {key} has an empty entry (stray comma)")
            after_comma = True
            commas += 1
        else:
            items.append((lineno, m.group()))
            after_comma = False
    if commas and after_comma:
        last = start_line + body.count("\n")
        raise FileFormatError(f"{source} line {last}: {key} ends with a comma (empty entry)")
    return items


def _parse_conf(text: str, source: str, keys: tuple[str, ...]) -> dict[str, Any]:
    """Parse a controller ``calibration.conf`` (INI-like, as the controller writes it).

    Understood: ``[section]`` headers (ignored), ``key = value`` lines, ``key = [v, v, ...]`` lists that may
    span several lines until the closing ``]``, ``# comments`` (also after a value) and blank lines. Only the
    ``keys`` asked for are converted to numbers, so other entries such as ``joint_checksum = [ 0xb3241580, ...]``
    or ``calibration_status = 2 # ...`` do not matter.

    Raises:
        FileFormatError: A line that is none of the above, a list with no closing ``]``, text after ``]``,
            an empty entry, a requested key given twice, or a non-number in a requested list (names the line).
    """
    raw: dict[str, Any] = {}
    first_line: dict[str, int] = {}
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        lineno = i + 1
        code = _conf_code(lines[i])
        i += 1
        if not code or _CONF_SECTION.fullmatch(code):
            continue
        m = _CONF_ASSIGN.fullmatch(code)
        if m is None:
            raise FileFormatError(
                f"{source} line {lineno}: expected 'key = value', 'key = [ ... ]' or a [section]; got {code!r}"
            )
        key, value = m.group(1), m.group(2)
        if key in keys and key in first_line:
            raise FileFormatError(
                f"{source} line {lineno}: {key} appears twice (first on line {first_line[key]})"
            )
        first_line.setdefault(key, lineno)
        if not value.startswith("["):
            raw[key] = value  # a scalar (e.g. calibration_status = 2); a requested key is refused by _six
            continue
        parts = [value[1:]]
        while "]" not in parts[-1]:
            if "[" in parts[-1]:
                raise FileFormatError(f"{source} line {i}: {key} has a '[' inside its list")
            if i >= len(lines):
                raise FileFormatError(
                    f"{source} line {lineno}: the list of {key} is not closed with ']' before the end of the file"
                )
            nxt = _conf_code(lines[i])
            if _CONF_ASSIGN.fullmatch(nxt) or _CONF_SECTION.fullmatch(nxt):
                raise FileFormatError(
                    f"{source} line {lineno}: the list of {key} is not closed with ']' before line {i + 1}"
                )
            parts.append(nxt)
            i += 1
        body, _, rest = "\n".join(parts).partition("]")
        if "[" in body:
            raise FileFormatError(f"{source} line {lineno}: {key} has a '[' inside its list")
        if rest.strip():
            raise FileFormatError(f"{source} line {i}: unexpected {rest.strip()!r} after the list of {key}")
        if key not in keys:
            raw[key] = body
            continue
        values: list[Any] = []
        for item_line, item in _conf_items(key, lineno, body, source):
            try:
                values.append(float(item))
            except ValueError:
                raise FileFormatError(
                    f"{source} line {item_line}: {key} entry {item!r} is not a number"
                ) from None
        raw[key] = values
    return raw


_LOG_PREFIX = re.compile(
    r"^(?:\[[\w./-]+\]\s+)?\[\s*(?:DEBUG|INFO|WARN|WARNING|ERROR|FATAL)\s*\](?:\s*\[[^\]]*\])*\s*:\s?"
)
"""A ROS log line's prefix: ``[ INFO] [1560953586.35]: `` (ROS 1), ``[INFO] [1700000000.1] [node]: `` (ROS 2),
optionally after a launch prefix ``[calibration_correction-1] ``."""

_LOG_KEYS = ("checksum", "calibration_status")
"""Other lines of the KinematicsInfo as UR's client library prints it (next to dh_*); not warned about."""


def _strip_log_prefixes(text: str) -> str:
    """Remove ROS log prefixes so a pasted driver log reads as the YAML it prints."""
    if "[" not in text:
        return text
    return "\n".join(_LOG_PREFIX.sub("", line, count=1) for line in text.split("\n"))


def _close_key(name: str, candidates: list[str]) -> str | None:
    match = difflib.get_close_matches(name, candidates, n=1, cutoff=0.75)
    return match[0] if match else None


def _load_mapping(
    path: str | os.PathLike[str], what: str, keys: tuple[str, ...], warnings: list[str] | None
) -> dict[str, Any]:
    text = _strip_log_prefixes(read_text(path, what, limit=MAX_DOCUMENT_BYTES))
    source = f"{what} {path}"
    stripped = text.lstrip()
    is_conf = stripped.startswith("[") or re.search(r"^\s*\w+\s*=\s*\[", text, re.MULTILINE) is not None
    data: Any = _parse_conf(text, source, keys) if is_conf else load_yaml(text, source)
    if not isinstance(data, Mapping):
        raise FileFormatError(f"{source}: expected a mapping with keys {', '.join(keys)}")
    present = [str(k) for k in data]
    unknown = [k for k in present if k not in keys and not (keys == DH_KEYS and k in _LOG_KEYS)]
    missing = [k for k in keys if k not in data]
    if missing:
        hint = ""
        typo = _close_key(missing[0], unknown)
        if "kinematics" in data:
            hint = "; this is a kinematics YAML (robocal ur correct output), not DH parameters"
        elif keys == DH_KEYS and all(k in data for k in DELTA_KEYS):
            hint = "; this is a deltas file: use --model MODEL --deltas FILE"
        elif keys == DELTA_KEYS and all(k in data for k in DH_KEYS):
            hint = "; this is a DH file: use --dh FILE"
        elif typo is not None:
            hint = f"; found {typo!r} instead (a typo?)"
        raise FileFormatError(f"{source}: missing key {missing[0]} (expected {', '.join(keys)}){hint}")
    if not is_conf and warnings is not None:  # a calibration.conf has many other entries; a YAML should not
        for k in unknown:
            near = _close_key(k, list(keys))
            hint = f" (did you mean {near}?)" if near is not None else ""
            warnings.append(f"{source}: unknown key {k!r} ignored{hint}; expected only {', '.join(keys)}")
    return dict(data)


def _read_four(
    path: str | os.PathLike[str], what: str, keys: tuple[str, ...], warnings: list[str] | None
) -> DHParameters:
    """Read four six-number lists (θ, a, d, α in ``keys`` order) from a YAML or ``.conf`` file."""
    data = _load_mapping(path, what, keys, warnings)
    status = data.get("calibration_status") if keys == DH_KEYS else None
    if status is not None and warnings is not None and str(status).strip() != "2":
        warnings.append(
            f"{what} {path}: calibration_status is {status}, not 2 (linearised); the DH may be nominal "
            "rather than the robot's calibration"
        )
    th, a, d, al = (_six(data[k], f"{what} {path}: {k}") for k in keys)
    return DHParameters(theta_rad=th, a_m=a, d_m=d, alpha_rad=al)


def read_dh(path: str | os.PathLike[str], *, warnings: list[str] | None = None) -> DHParameters:
    """Read a DH YAML (``dh_theta``, ``dh_a``, ``dh_d``, ``dh_alpha``; six numbers each).

    Args:
        path: The file.
        warnings: When given, a warning naming each unknown key (e.g. a misspelt ``dh_alhpa``) is appended.

    Raises:
        FileFormatError: Missing key, wrong length, NaN/inf or a non-number; names the file and key.
    """
    return _read_four(path, "DH file", DH_KEYS, warnings)


def read_deltas(path: str | os.PathLike[str], *, warnings: list[str] | None = None) -> DHParameters:
    """Read calibration deltas (``delta_theta``, ``delta_a``, ``delta_d``, ``delta_alpha``), YAML or .conf.

    Args:
        path: A YAML file or the controller's ``calibration.conf``.
        warnings: When given, a warning naming each unknown key of a YAML file is appended (a
            ``calibration.conf`` has many other entries, which are ignored silently).

    Raises:
        FileFormatError: Missing key, wrong length, NaN/inf, a non-number or a malformed ``.conf`` line;
            names the file, line and key.
    """
    return _read_four(path, "deltas file", DELTA_KEYS, warnings)


def require_ur_joints(model: UrdfModel, source: str | os.PathLike[str]) -> None:
    """Refuse a URDF that lacks one of the six UR joints (``shoulder_pan_joint`` … ``wrist_3_joint``).

    Raises:
        JointMismatchError: Lists the missing joints and names the file.
    """
    names = set(model.joint_names)
    missing = [j for j in JOINT_NAMES if j not in names]
    if missing:
        raise JointMismatchError(f"URDF {source}: missing UR joint(s) {', '.join(missing)}")


def update_urdf_origins(
    urdf_in: str | os.PathLike[str], urdf_out: str | os.PathLike[str], kin: UrKinematics
) -> Path:
    """Set the six UR joint origins of an expanded URDF in place and write it atomically.

    Comments, element order and ``<ros2_control>`` are kept (lxml in-place edit). All six joints
    (``shoulder_pan_joint`` … ``wrist_3_joint``) must exist; nothing is written otherwise.

    Args:
        urdf_in: Existing expanded URDF (run xacro first).
        urdf_out: Destination (may equal ``urdf_in``).
        kin: Kinematics to write; should use the ``urdf`` rpy convention.

    Returns:
        The written path.
    """
    data = urdf_with_origins(urdf_in, kin)
    return atomic_write_bytes(urdf_out, data)


def urdf_with_origins(urdf_in: str | os.PathLike[str], kin: UrKinematics) -> bytes:
    """The bytes of ``urdf_in`` with its six UR joint origins set from ``kin`` (nothing is written).

    Raises:
        FileFormatError: The URDF cannot be read or parsed.
        JointMismatchError: One of the six UR joints is missing.
    """
    doc = UrdfDocument.load(urdf_in)
    require_ur_joints(doc.model(), urdf_in)
    for joint, link in zip(JOINT_NAMES, kin.links, strict=True):
        doc.set_origin(joint, link.xyz_m, link.rpy_rad)
    return doc.to_bytes()
