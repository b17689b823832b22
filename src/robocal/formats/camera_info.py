"""Camera intrinsics as ROS ``camera_info`` YAML (what ``camera_calibration`` writes and camera drivers load).

::

    image_width: 1280
    image_height: 960
    camera_name: camera
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    projection_matrix: {rows: 3, cols: 4, data: [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]}

``plumb_bob`` (5 coefficients) and ``rational_polynomial`` (8) are OpenCV's distortion model; both are read.
robocal adds ``rms_px`` (the calibration's RMS reprojection error), which other readers ignore.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..backends.vision import CameraIntrinsics
from ..errors import FileFormatError
from ..fileio import MAX_DOCUMENT_BYTES, atomic_write_text, read_text
from ._yaml import load_yaml, yaml_float

__all__ = ["camera_info_text", "read_camera_info", "write_camera_info"]

_MODELS = {"plumb_bob": 5, "rational_polynomial": 8}


def _flow(values: Any) -> str:
    return "[" + ", ".join(yaml_float(float(v)) for v in values) + "]"


def camera_info_text(camera: CameraIntrinsics, name: str = "camera") -> str:
    """The ``camera_info`` YAML text of ``camera``."""
    K = camera.K
    dist = list(camera.distortion) + [0.0] * max(0, 5 - len(camera.distortion))
    model = "plumb_bob" if len(dist) <= 5 else "rational_polynomial"
    dist = dist[: _MODELS[model]] + [0.0] * (_MODELS[model] - len(dist))
    P = [K[0, 0], 0.0, K[0, 2], 0.0, 0.0, K[1, 1], K[1, 2], 0.0, 0.0, 0.0, 1.0, 0.0]
    lines = [
        "# camera intrinsics (ROS camera_info), written by robocal kinematics camera-calibrate",
        f"image_width: {camera.width}",
        f"image_height: {camera.height}",
        f"camera_name: {name}",
        f"camera_matrix: {{rows: 3, cols: 3, data: {_flow(K.reshape(-1))}}}",
        f"distortion_model: {model}",
        f"distortion_coefficients: {{rows: 1, cols: {len(dist)}, data: {_flow(dist)}}}",
        "rectification_matrix: {rows: 3, cols: 3, data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]}",
        f"projection_matrix: {{rows: 3, cols: 4, data: {_flow(P)}}}",
    ]
    if camera.rms_px is not None:
        lines.append(f"rms_px: {yaml_float(camera.rms_px)}")
    return "\n".join(lines) + "\n"


def write_camera_info(path: str | os.PathLike[str], camera: CameraIntrinsics, name: str = "camera") -> Path:
    """Write the intrinsics atomically (the previous file kept as ``.bak``)."""
    return atomic_write_text(path, camera_info_text(camera, name))


def _matrix(doc: dict[str, Any], key: str, rows: int, cols: int | None, source: str) -> np.ndarray:
    m = doc.get(key)
    if not isinstance(m, dict) or "data" not in m:
        raise FileFormatError(f"{source}: {key} needs rows, cols and data")
    data = m["data"]
    if not isinstance(data, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in data
    ):
        raise FileFormatError(f"{source}: {key}.data must be a list of numbers")
    n_cols = cols if cols is not None else len(data)
    if len(data) != rows * n_cols or m.get("rows", rows) != rows or m.get("cols", n_cols) != n_cols:
        raise FileFormatError(
            f"{source}: {key} must be {rows}x{n_cols} ({rows * n_cols} numbers), got {len(data)}"
        )
    arr = np.asarray(data, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise FileFormatError(f"{source}: {key} has a NaN or infinite number")
    return arr.reshape(rows, n_cols)


def read_camera_info(path: str | os.PathLike[str]) -> CameraIntrinsics:
    """Read ``camera_info`` YAML.

    Raises:
        FileFormatError: A missing or malformed field (named), an unknown distortion model, a camera matrix
            that is not ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` with positive focal lengths.
    """
    source = str(path)
    doc = load_yaml(read_text(path, "camera file", limit=MAX_DOCUMENT_BYTES), source)
    if not isinstance(doc, dict):
        raise FileFormatError(f"{source}: expected a camera_info mapping (image_width, camera_matrix, ...)")
    size = []
    for key in ("image_width", "image_height"):
        v = doc.get(key)
        if not isinstance(v, int) or isinstance(v, bool) or v <= 0:
            raise FileFormatError(f"{source}: {key} must be a positive integer, got {v!r}")
        size.append(v)
    K = _matrix(doc, "camera_matrix", 3, 3, source)
    if not (K[0, 0] > 0 and K[1, 1] > 0 and K[2, 2] == 1.0 and K[1, 0] == K[2, 0] == K[2, 1] == 0.0):
        raise FileFormatError(
            f"{source}: camera_matrix must be [fx, s, cx, 0, fy, cy, 0, 0, 1] with fx, fy > 0"
        )
    model = doc.get("distortion_model", "plumb_bob")
    if model not in _MODELS:
        raise FileFormatError(f"{source}: distortion_model {model!r}; robocal reads {', '.join(_MODELS)}")
    dist = _matrix(doc, "distortion_coefficients", 1, None, source).reshape(-1)
    if dist.size not in (0, 4, 5, 8, 12, 14):
        raise FileFormatError(
            f"{source}: {dist.size} distortion coefficients; OpenCV takes 4, 5, 8, 12 or 14"
        )
    rms = doc.get("rms_px")
    rms_px = (
        float(rms)
        if isinstance(rms, int | float) and not isinstance(rms, bool) and math.isfinite(rms)
        else None
    )
    return CameraIntrinsics(size[0], size[1], K, dist, rms_px)
