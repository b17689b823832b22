"""LeRobot v3 dataset layout: ``meta/info.json``, data files and vector features.

A LeRobot v3 dataset root holds::

    meta/info.json                                  features (dtype, shape, joint names), paths, fps
    meta/stats.json                                 whole-dataset statistics per feature
    meta/episodes/chunk-XXX/file-YYY.parquet        one row per episode, with ``stats/...`` columns
    meta/tasks.parquet                              task strings
    data/chunk-XXX/file-YYY.parquet                 frames, one Parquet row group per episode
    videos/...                                      camera streams (never touched here)

Vector features such as ``observation.state`` and ``action`` are Arrow ``fixed_size_list<float32>[D]``; the
joint order is the feature's ``names`` list in ``info.json`` (``"shoulder_pan.pos"`` etc.).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import FileFormatError, UsageError
from ..fileio import MAX_DOCUMENT_BYTES, read_text
from ..formats._json import load_json

__all__ = [
    "DEFAULT_FEATURES",
    "DatasetLayout",
    "VectorFeature",
    "is_position_entry",
    "joint_name",
    "read_layout",
]

DEFAULT_FEATURES: tuple[str, ...] = ("observation.state", "action")
"""Features re-calibrated when none are named: the joint positions read and commanded."""

_POSITION_SUFFIX = ".pos"


def joint_name(feature_name: str) -> str:
    """Joint name of one entry of a feature's ``names`` (LeRobot writes ``"<motor>.pos"``)."""
    return feature_name[: -len(_POSITION_SUFFIX)] if feature_name.endswith(_POSITION_SUFFIX) else feature_name


def is_position_entry(feature_name: str) -> bool:
    """Whether a feature entry is a joint position: ``"<motor>.pos"`` or a bare motor name (no ``.``).

    Other entries (``"x.vel"``, ``"theta.vel"``, ``"<motor>.effort"``, ...) are not joint positions; they are
    passed through unchanged by a re-calibration.
    """
    return feature_name.endswith(_POSITION_SUFFIX) or "." not in feature_name


@dataclass(frozen=True)
class VectorFeature:
    """One vector feature of a dataset.

    Attributes:
        key: Column name, e.g. ``"observation.state"``.
        dtype: Element dtype from ``info.json`` (``"float32"``).
        names: Entry names in column order, e.g. ``("shoulder_pan.pos", ...)``; length ``D``.
    """

    key: str
    dtype: str
    names: tuple[str, ...]

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in column order (``.pos`` suffix removed)."""
        return tuple(joint_name(n) for n in self.names)

    @property
    def position_joint_names(self) -> tuple[str, ...]:
        """Joint names of the joint-position entries only (see :func:`is_position_entry`), column order."""
        return tuple(joint_name(n) for n in self.names if is_position_entry(n))

    @property
    def size(self) -> int:
        """Vector length ``D``."""
        return len(self.names)


@dataclass(frozen=True)
class DatasetLayout:
    """What robocal needs to know about a LeRobot v3 dataset root.

    Attributes:
        root: Dataset root folder.
        info: Parsed ``meta/info.json``.
        data_files: Frame files relative to ``root``, sorted (``data/chunk-000/file-000.parquet``, ...).
        episode_files: Episode metadata files relative to ``root``, sorted (may be empty).
    """

    root: Path
    info: dict[str, Any]
    data_files: tuple[str, ...]
    episode_files: tuple[str, ...]

    @property
    def features(self) -> dict[str, Any]:
        """The ``features`` mapping of ``info.json``."""
        feats: dict[str, Any] = self.info["features"]
        return feats

    @property
    def robot_type(self) -> str | None:
        """``robot_type`` of ``info.json`` (e.g. ``"so101_follower"``), if any."""
        rt = self.info.get("robot_type")
        return rt if isinstance(rt, str) else None

    def vector_feature(self, key: str) -> VectorFeature:
        """Return a float vector feature with per-entry names.

        Raises:
            UsageError: The feature does not exist (the message lists the vector features) or has no names.
        """
        if key not in self.features:
            valid = ", ".join(self.vector_feature_keys()) or "none"
            raise UsageError(
                f"{self.root / 'meta/info.json'}: unknown feature {key!r}; float vector features: {valid}"
            )
        spec = self.features[key]
        names = _names_of(spec)
        dtype = spec.get("dtype") if isinstance(spec, dict) else None
        if dtype not in ("float32", "float64") or names is None:
            raise UsageError(
                f"{self.root / 'meta/info.json'}: feature {key!r} is not a float vector with joint names "
                f"(dtype {dtype!r}); float vector features: {', '.join(self.vector_feature_keys()) or 'none'}"
            )
        shape = spec.get("shape")
        if not (isinstance(shape, list) and len(shape) == 1 and shape[0] == len(names)):
            raise FileFormatError(
                f"{self.root / 'meta/info.json'}: feature {key!r} has shape {shape!r} but {len(names)} names"
            )
        return VectorFeature(key=key, dtype=str(dtype), names=names)

    def vector_feature_keys(self) -> list[str]:
        """Keys of every float vector feature that has names (candidates for re-calibration)."""
        out = []
        for key, spec in self.features.items():
            if (
                isinstance(spec, dict)
                and spec.get("dtype") in ("float32", "float64")
                and _names_of(spec) is not None
            ):
                out.append(key)
        return out

    def select(self, keys: Sequence[str] | None) -> list[VectorFeature]:
        """Resolve the features to re-calibrate (default: those of :data:`DEFAULT_FEATURES` present)."""
        if keys is None:
            keys = [k for k in DEFAULT_FEATURES if k in self.features]
            if not keys:
                raise UsageError(
                    f"{self.root / 'meta/info.json'}: none of the default features "
                    f"{', '.join(DEFAULT_FEATURES)} exist; name them with --features "
                    f"(float vector features: {', '.join(self.vector_feature_keys()) or 'none'})"
                )
        if len(set(keys)) != len(keys):
            raise UsageError(f"features {', '.join(keys)}: a feature is named twice")
        return [self.vector_feature(k) for k in keys]


def _names_of(spec: Any) -> tuple[str, ...] | None:
    if not isinstance(spec, dict):
        return None
    names = spec.get("names")
    if isinstance(names, dict):  # some datasets nest names as {"motors": [...]}
        values = list(names.values())
        names = values[0] if len(values) == 1 else None
    if isinstance(names, list) and names and all(isinstance(n, str) for n in names):
        return tuple(names)
    return None


def read_layout(root: str | Path) -> DatasetLayout:
    """Read and check the layout of a LeRobot v3 dataset.

    Args:
        root: Dataset root folder.

    Returns:
        The layout.

    Raises:
        UsageError: ``root`` is not a folder.
        FileFormatError: ``meta/info.json`` is missing or malformed, or there are no data files although
            ``total_frames`` is not 0.
    """
    r = Path(root)
    if not r.is_dir():
        raise UsageError(f"dataset {r}: {'not a folder' if r.exists() else 'no such folder'}")
    info_path = r / "meta" / "info.json"
    if not info_path.is_file():
        what = "meta/info.json is not a file" if info_path.exists() else "missing meta/info.json"
        raise FileFormatError(f"dataset {r}: {what} (is this a LeRobot v3 dataset?)")
    info = load_json(read_text(info_path, "dataset info", limit=MAX_DOCUMENT_BYTES), str(info_path))
    if not isinstance(info, dict) or not isinstance(info.get("features"), dict):
        raise FileFormatError(f"{info_path}: expected an object with a 'features' object")
    version = info.get("codebase_version")
    if isinstance(version, str) and not version.startswith("v3"):
        raise FileFormatError(
            f"{info_path}: codebase_version {version!r}; only LeRobot v3 datasets are supported"
        )
    data_files = tuple(sorted(p.relative_to(r).as_posix() for p in r.glob("data/chunk-*/file-*.parquet")))
    if not data_files and info.get("total_frames") != 0:  # an empty dataset (no episode yet) has none
        raise FileFormatError(
            f"dataset {r}: no data/chunk-*/file-*.parquet files "
            f"(meta/info.json total_frames {info.get('total_frames')!r}, expected 0 for an empty dataset)"
        )
    episode_files = tuple(
        sorted(p.relative_to(r).as_posix() for p in r.glob("meta/episodes/chunk-*/file-*.parquet"))
    )
    odd = next((rel for rel in (*data_files, *episode_files) if not (r / rel).is_file()), None)
    if odd is not None:  # a FIFO would block the reader for ever; a folder is no Parquet file
        raise FileFormatError(f"dataset {r}: {odd} is not a regular file")
    return DatasetLayout(root=r, info=info, data_files=data_files, episode_files=episode_files)
