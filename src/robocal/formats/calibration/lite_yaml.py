"""``lite-yaml``: Humanoid-Control ``calibration.yaml``, the Lite schema; an existing file is updated in place.

Comments, key order and untouched values stay as they were; only changed values change.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ruamel.yaml.comments import CommentedMap

from ...core.profile import RobotProfile
from ...errors import FileFormatError
from ...fileio import MAX_DOCUMENT_BYTES, atomic_write_text, read_text
from .._yaml import dump_yaml, load_yaml
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, Traits, first_value, yaml_data
from ._lite import LITE_KEYS, lite_entries, parse_lite


def read(path: Path, parsed_yaml: Any = None, **_: Any) -> CalibrationFile:
    """Read a ``lite-yaml`` file."""
    return parse_lite(yaml_data(path, parsed_yaml), str(path), "lite-yaml")


def write(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    """Write a ``lite-yaml`` file, updating an existing one in place."""
    entries = lite_entries(cf, urdf, "lite-yaml", profile)
    doc: Any = None
    if path.exists():
        try:
            doc = load_yaml(read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES), str(path), item="joint", round_trip=True)
            parse_lite(doc, str(path), "lite-yaml")
        except FileFormatError:
            doc = None  # not a lite-yaml file we can update: replace it (the old one is kept as .bak)
    if doc is None:
        doc = CommentedMap()
    # the file holds exactly the calibration written, so reading it back gives the same joints
    for name in [k for k in doc if k not in entries]:
        del doc[name]
    for name, entry in entries.items():
        if name in doc:
            node = doc[name]
            for key in LITE_KEYS:
                old = node.get(key)
                new = entry[key]
                if old is None or isinstance(old, bool) or float(old) != float(new):
                    node[key] = new
        else:
            node = CommentedMap()
            for key in LITE_KEYS:
                node[key] = entry[key]
            doc[name] = node
    atomic_write_text(path, dump_yaml(doc))


def sniff(content: Content) -> bool:
    """A YAML mapping of joint mappings."""
    return content.kind == "yaml" and isinstance(first_value(content.data), Mapping)


_TRAITS = Traits.DIRECTIONS | Traits.IDS | Traits.SELF_CONTAINED
SPEC = FormatSpec("lite-yaml", read, write, sniff, sniff_rank=2, suffixes=(".yaml", ".yml"), traits=_TRAITS)
