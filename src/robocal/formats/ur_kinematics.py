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

* a DH YAML with ``dh_theta``, ``dh_a``, ``dh_d``, ``dh_alpha`` (six numbers each, radians and metres), the
  layout ur_calibration logs;
* a deltas file with ``delta_theta``, ``delta_a``, ``delta_d``, ``delta_alpha``, either YAML or the
  controller's ``calibration.conf`` (``delta_theta = [ ... ]`` lines under ``[mounting]``), to be added to a
  model's nominal DH.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..core.dh import DHParameters
from ..core.ur import JOINT_NAMES, LINK_NAMES, LinkOrigin, UrKinematics
from ..errors import FileFormatError, JointMismatchError
from ..fileio import atomic_write_text, read_text
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
    text = read_text(path, "kinematics YAML")
    data = load_yaml(text, str(path))
    if not isinstance(data, Mapping) or not isinstance(data.get("kinematics"), Mapping):
        raise FileFormatError(f"kinematics YAML {path}: expected a top-level 'kinematics' mapping")
    kin = data["kinematics"]
    links: list[LinkOrigin] = []
    for name in LINK_NAMES:
        entry = kin.get(name)
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"kinematics YAML {path}: kinematics.{name} is missing or not a mapping")
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


def _six(value: Any, where: str) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise FileFormatError(f"{where} is {value!r}; expected a list of 6 numbers")
    if len(value) != 6:
        raise FileFormatError(f"{where} has {len(value)} values; expected 6")
    return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))


_CONF_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*\[(.*)\]\s*$")


def _parse_conf(text: str, source: str) -> dict[str, Any]:
    """Parse ``key = [v, v, ...]`` lines of a controller ``calibration.conf`` (other lines ignored)."""
    out: dict[str, Any] = {}
    first_line: dict[str, int] = {}
    for lineno, line in enumerate(text.splitlines(), 1):
        m = _CONF_LINE.match(line)
        if not m:
            continue
        if m.group(1) in first_line:
            raise FileFormatError(
                f"{source} line {lineno}: {m.group(1)} appears twice (first on line {first_line[m.group(1)]})"
            )
        first_line[m.group(1)] = lineno
        items = [s for s in re.split(r"[,\s]+", m.group(2).strip()) if s]
        values: list[Any] = []
        for s in items:
            try:
                values.append(float(s))
            except ValueError:
                raise FileFormatError(
                    f"{source} line {lineno}: {m.group(1)} entry {s!r} is not a number"
                ) from None
        out[m.group(1)] = values
    return out


def _load_mapping(path: str | os.PathLike[str], what: str, keys: tuple[str, ...]) -> dict[str, Any]:
    text = read_text(path, what)
    source = f"{what} {path}"
    stripped = text.lstrip()
    if stripped.startswith("[") or re.search(r"^\s*\w+\s*=\s*\[", text, re.MULTILINE):
        data: Any = _parse_conf(text, source)
    else:
        data = load_yaml(text, source)
    if not isinstance(data, Mapping):
        raise FileFormatError(f"{source}: expected a mapping with keys {', '.join(keys)}")
    missing = [k for k in keys if k not in data]
    if missing:
        hint = ""
        if "kinematics" in data:
            hint = "; this is a kinematics YAML (robocal ur correct output), not DH parameters"
        elif keys == DH_KEYS and all(k in data for k in DELTA_KEYS):
            hint = "; this is a deltas file: use --model MODEL --deltas FILE"
        elif keys == DELTA_KEYS and all(k in data for k in DH_KEYS):
            hint = "; this is a DH file: use --dh FILE"
        raise FileFormatError(f"{source}: missing key {missing[0]} (expected {', '.join(keys)}){hint}")
    return dict(data)


def _read_four(path: str | os.PathLike[str], what: str, keys: tuple[str, ...]) -> DHParameters:
    """Read four six-number lists (θ, a, d, α in ``keys`` order) from a YAML or ``.conf`` file."""
    data = _load_mapping(path, what, keys)
    th, a, d, al = (_six(data[k], f"{what} {path}: {k}") for k in keys)
    return DHParameters(theta_rad=th, a_m=a, d_m=d, alpha_rad=al)


def read_dh(path: str | os.PathLike[str]) -> DHParameters:
    """Read a DH YAML (``dh_theta``, ``dh_a``, ``dh_d``, ``dh_alpha``; six numbers each).

    Raises:
        FileFormatError: Missing key, wrong length, NaN/inf or a non-number; names the file and key.
    """
    return _read_four(path, "DH file", DH_KEYS)


def read_deltas(path: str | os.PathLike[str]) -> DHParameters:
    """Read calibration deltas (``delta_theta``, ``delta_a``, ``delta_d``, ``delta_alpha``), YAML or .conf.

    Raises:
        FileFormatError: Missing key, wrong length, NaN/inf or a non-number; names the file and key.
    """
    return _read_four(path, "deltas file", DELTA_KEYS)


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
    doc = UrdfDocument.load(urdf_in)
    require_ur_joints(doc.model(), urdf_in)
    for joint, link in zip(JOINT_NAMES, kin.links, strict=True):
        doc.set_origin(joint, link.xyz_m, link.rpy_rad)
    return doc.write(urdf_out)
