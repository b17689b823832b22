"""Camera targets through OpenCV (``cv2.aruco``): AprilTag / ChArUco detection, camera calibration, PnP, rendering.

OpenCV comes with the ``vision`` extra (``pip install 'robocal[vision]'``, opencv-python-headless ≥ 4.7, whose
``cv2.aruco`` has the AprilTag dictionaries, ``ArucoDetector``, ``CharucoBoard`` and ``CharucoDetector``).

Targets (``--target`` / ``--board``):

* ``apriltag:<family>:<id>:<size_mm>``, e.g. ``apriltag:36h11:0:60`` — one tag; ``size`` is the black square's
  side. Families: 16h5, 25h9, 36h10, 36h11.
* ``charuco:<cols>x<rows>:<square_mm>:<marker_mm>[:<dictionary>]``, e.g. ``charuco:7x5:30:22:4x4_50`` — a
  ChArUco board of ``cols × rows`` squares (OpenCV's layout); the dictionary defaults to ``4x4_50``
  (``aruco_4x4_50``, ``5x5_100``, ``apriltag_36h11``, … any ``cv2.aruco.DICT_*`` name).

Target frames are OpenCV's: AprilTag x right, y up, z out of the tag towards the viewer, origin at the tag's
centre; ChArUco x right, y down, z into the board, origin at the board's top-left outer corner (as
``CharucoBoard.getChessboardCorners``). :meth:`Target.front_normal` is the printed face's outward normal. A simple renderer
(:func:`render`) draws a target seen by an ideal pinhole camera, antialiased by 2×2 supersampling, with pixel
noise; the simulated sessions and the tests use it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.arrays import FloatArray, IntArray
from ..errors import BackendNotAvailableError, FileFormatError, UsageError
from . import require

__all__ = [
    "CameraIntrinsics",
    "Detection",
    "Target",
    "calibrate_camera",
    "detect",
    "normalised",
    "parse_target",
    "read_image",
    "render",
    "solve_pnp",
    "write_image",
]


APRILTAG_FAMILIES = ("16h5", "25h9", "36h10", "36h11")


def _cv2() -> Any:
    cv2 = require(
        "cv2",
        "camera targets",
        message="camera targets need OpenCV: pip install 'robocal[vision]' (opencv-python-headless)",
    )
    if not hasattr(cv2, "aruco") or not hasattr(cv2.aruco, "CharucoDetector"):  # pragma: no cover
        raise BackendNotAvailableError(
            f"OpenCV {cv2.__version__} has no cv2.aruco.CharucoDetector; need >= 4.7"
        )
    return cv2


@dataclass(frozen=True)
class CameraIntrinsics:
    """A calibrated pinhole camera with OpenCV distortion.

    Attributes:
        width: Image width, pixels.
        height: Image height, pixels.
        K: ``(3, 3)`` camera matrix.
        distortion: OpenCV distortion coefficients (``k1 k2 p1 p2 [k3 …]``; may be empty).
        rms_px: RMS reprojection error of the calibration (None when unknown).
    """

    width: int
    height: int
    K: FloatArray
    distortion: FloatArray
    rms_px: float | None = None

    @property
    def focal_px(self) -> float:
        """Mean focal length, pixels."""
        return float(0.5 * (self.K[0, 0] + self.K[1, 1]))


@dataclass(frozen=True)
class Target:
    """A parsed target.

    Attributes:
        kind: ``apriltag`` or ``charuco``.
        dictionary: ``cv2.aruco`` dictionary name, e.g. ``DICT_APRILTAG_36h11``.
        tag_id: The tag's id (AprilTag).
        size_m: Tag side (AprilTag) or square side (ChArUco), metres.
        marker_m: ChArUco marker side, metres.
        cols: ChArUco squares along x.
        rows: ChArUco squares along y.
        text: The string it was parsed from.
    """

    kind: str
    dictionary: str
    tag_id: int = 0
    size_m: float = 0.0
    marker_m: float = 0.0
    cols: int = 0
    rows: int = 0
    text: str = ""

    def front_normal(self) -> FloatArray:
        """Outward normal of the printed face in the target frame (the camera must be on this side)."""
        return np.array([0.0, 0.0, 1.0 if self.kind == "apriltag" else -1.0])

    def object_points(self) -> FloatArray:
        """``(K, 3)`` corner positions in the target frame, in the order of the ids the detector reports."""
        if self.kind == "apriltag":
            h = self.size_m / 2
            return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        return np.asarray(_board(self).getChessboardCorners(), dtype=np.float64).reshape(-1, 3)


def _dictionary_name(text: str, where: str) -> str:
    cv2 = _cv2()
    t = text.strip().upper()
    name = t if t.startswith("DICT_") else f"DICT_{t}"
    if name.startswith("DICT_APRILTAG_"):
        name = "DICT_APRILTAG_" + name.removeprefix("DICT_APRILTAG_").lower()
    if not hasattr(cv2.aruco, name):
        raise UsageError(f"{where}: unknown dictionary {text!r} (e.g. 4x4_50, 5x5_100, apriltag_36h11)")
    return name


def _positive_mm(text: str, what: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise UsageError(f"{where}: {what} must be a positive number of millimetres, got {text!r}")
    return v * 1e-3


def parse_target(text: str, option: str = "--target") -> Target:
    """Parse ``apriltag:<family>:<id>:<size_mm>`` or ``charuco:<cols>x<rows>:<square_mm>:<marker_mm>[:<dict>]``.

    Raises:
        UsageError: A malformed string (the message shows the accepted forms).
    """
    where = f"{option} {text!r}"
    forms = (
        "expected apriltag:<family>:<id>:<size_mm> or charuco:<cols>x<rows>:<square_mm>:<marker_mm>[:<dict>]"
    )
    parts = [p.strip() for p in text.split(":")]
    kind = parts[0].lower()
    if kind == "apriltag" and len(parts) == 4:
        family = parts[1].lower()
        if family not in APRILTAG_FAMILIES:
            raise UsageError(f"{where}: family {parts[1]!r}; valid: {', '.join(APRILTAG_FAMILIES)}")
        if not (parts[2].isascii() and parts[2].isdigit()):
            raise UsageError(f"{where}: tag id {parts[2]!r} must be a non-negative integer")
        name = _dictionary_name(f"apriltag_{family}", where)
        tag_id = int(parts[2])
        size = int(_cv2().aruco.getPredefinedDictionary(getattr(_cv2().aruco, name)).bytesList.shape[0])
        if tag_id >= size:
            raise UsageError(f"{where}: tag id {tag_id} is beyond the {size} tags of family {family}")
        return Target(
            "apriltag", name, tag_id=tag_id, size_m=_positive_mm(parts[3], "the tag size", where), text=text
        )
    if kind == "charuco" and len(parts) in (4, 5):
        cols_s, sep, rows_s = parts[1].lower().partition("x")
        if not (sep and cols_s.isdigit() and rows_s.isdigit() and int(cols_s) >= 2 and int(rows_s) >= 2):
            raise UsageError(f"{where}: board size {parts[1]!r} must be <cols>x<rows>, each at least 2")
        square = _positive_mm(parts[2], "the square size", where)
        marker = _positive_mm(parts[3], "the marker size", where)
        if marker >= square:
            raise UsageError(
                f"{where}: the marker ({parts[3]} mm) must be smaller than the square ({parts[2]} mm)"
            )
        name = _dictionary_name(parts[4] if len(parts) == 5 else "4x4_50", where)
        target = Target(
            "charuco", name, size_m=square, marker_m=marker, cols=int(cols_s), rows=int(rows_s), text=text
        )
        n_markers = target.cols * target.rows // 2
        size = int(_cv2().aruco.getPredefinedDictionary(getattr(_cv2().aruco, name)).bytesList.shape[0])
        if n_markers > size:
            raise UsageError(
                f"{where}: the board needs {n_markers} markers; {parts[4] if len(parts) == 5 else '4x4_50'} has {size}"
            )
        return target
    raise UsageError(f"{where}: {forms}")


def _board(target: Target) -> Any:
    cv2 = _cv2()
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, target.dictionary))
    return cv2.aruco.CharucoBoard((target.cols, target.rows), target.size_m, target.marker_m, d)


@dataclass(frozen=True, eq=False)
class Detection:
    """Target corners found in one image.

    Attributes:
        corner_ids: ``(K,)`` index of each corner in :meth:`Target.object_points`.
        pixels: ``(K, 2)`` sub-pixel corner positions.
    """

    corner_ids: IntArray
    pixels: FloatArray


def read_image(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """A greyscale image from a file; :class:`FileFormatError` if it cannot be read.

    An empty file, and a PNG or JPEG cut short (no ``IEND`` chunk, no end-of-image marker: a copy or upload that
    stopped) are refused before decoding: OpenCV would decode a cut JPEG's first rows and grey the rest.
    """
    cv2 = _cv2()
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"image {p}: no such file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"image {p}: cannot be read ({exc.strerror or exc})") from None
    if not data:
        raise FileFormatError(f"image {p}: empty file")
    if data.startswith(b"\x89PNG\r\n\x1a\n") and b"IEND" not in data[-32:]:
        raise FileFormatError(f"image {p}: truncated PNG (no IEND chunk at its end)")
    if data.startswith(b"\xff\xd8") and not data.rstrip(b"\x00\r\n\t ").endswith(b"\xff\xd9"):
        raise FileFormatError(f"image {p}: truncated JPEG (no end-of-image marker)")
    img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise FileFormatError(f"image {p}: not an image OpenCV can read")
    return np.asarray(img, dtype=np.uint8)


def write_image(path: str | os.PathLike[str], image: ArrayLike) -> Path:
    """Write a PNG atomically (via :mod:`robocal.fileio`)."""
    from ..fileio import atomic_write_bytes

    cv2 = _cv2()
    ok, buf = cv2.imencode(".png", np.asarray(image, dtype=np.uint8))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 greyscale image
        raise UsageError(f"cannot encode {path} as PNG")
    return atomic_write_bytes(path, buf.tobytes())


def detect(image: ArrayLike, target: Target) -> Detection | None:
    """Find the target's corners in a greyscale image (None when it is not there).

    AprilTag: the tag with the target's id; its 4 corners refined to sub-pixel. ChArUco: the board's inner
    corners interpolated from its markers (at least 4).
    """
    cv2 = _cv2()
    img = np.asarray(image, dtype=np.uint8)
    if target.kind == "apriltag":
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, target.dictionary))
        params = cv2.aruco.DetectorParameters()
        # the AprilTag refinement is the most precise (measured: σ 0.06 px against 0.19 px for SUBPIX on
        # rendered tags) but reports corners half a pixel off OpenCV's pixel-centre convention (+0.43 px measured)
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
        corners, ids, _ = cv2.aruco.ArucoDetector(d, params).detectMarkers(img)
        if ids is None:
            return None
        hits = [i for i, v in enumerate(ids.reshape(-1)) if int(v) == target.tag_id]
        if len(hits) != 1:
            return None
        px = np.asarray(corners[hits[0]], dtype=np.float64).reshape(4, 2) - 0.5
        return Detection(np.arange(4, dtype=np.int64), px)
    ch_corners, ch_ids, _, _ = cv2.aruco.CharucoDetector(_board(target)).detectBoard(img)
    if ch_ids is None or len(ch_ids) < 4:
        return None
    return Detection(
        np.asarray(ch_ids, dtype=np.int64).reshape(-1),
        np.asarray(ch_corners, dtype=np.float64).reshape(-1, 2),
    )


def normalised(pixels: ArrayLike, camera: CameraIntrinsics) -> FloatArray:
    """Undistorted normalised coordinates ``(x/z, y/z)`` of ``(K, 2)`` pixel positions."""
    cv2 = _cv2()
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
    out = cv2.undistortPoints(px, camera.K, camera.distortion)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def solve_pnp(object_m: ArrayLike, pixels: ArrayLike, camera: CameraIntrinsics) -> FloatArray:
    """``T_cam_target`` ``(4, 4)`` from corners (iterative PnP; planar targets)."""
    cv2 = _cv2()
    from ..core.kinematic_images import frame_from_rotvec

    obj = np.asarray(object_m, dtype=np.float64).reshape(-1, 3)
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    flag = cv2.SOLVEPNP_IPPE_SQUARE if obj.shape[0] == 4 else cv2.SOLVEPNP_IPPE
    ok, rvec, tvec = cv2.solvePnP(obj, px, camera.K, camera.distortion, flags=flag)
    if not ok:
        raise UsageError("PnP found no target pose")
    ok, rvec, tvec = cv2.solvePnP(
        obj, px, camera.K, camera.distortion, rvec, tvec, useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE
    )
    return frame_from_rotvec(np.asarray(rvec).reshape(3), np.asarray(tvec).reshape(3))


def calibrate_camera(
    images: Sequence[tuple[str, ArrayLike]], board: Target, *, min_corners: int = 6
) -> tuple[CameraIntrinsics, list[str]]:
    """Intrinsics from ChArUco images (``cv2.calibrateCamera``: k1, k2, p1, p2; k3 held at zero).

    Args:
        images: ``(name, greyscale image)`` pairs, all of one size.
        board: A ``charuco`` target.
        min_corners: Images with fewer detected corners are skipped (named in the warnings).

    Returns:
        The intrinsics (with the RMS reprojection error) and warnings for skipped images.

    Raises:
        UsageError: Not a ChArUco board, images of different sizes, or fewer than 4 usable images.
    """
    cv2 = _cv2()
    if board.kind != "charuco":
        raise UsageError("--board must be a ChArUco board (charuco:<cols>x<rows>:<square_mm>:<marker_mm>)")
    obj_all = board.object_points()
    objs, pts, warnings = [], [], []
    size: tuple[int, int] | None = None
    for name, image in images:
        img = np.asarray(image, dtype=np.uint8)
        h, w = img.shape[:2]
        if size is None:
            size = (w, h)
        elif size != (w, h):
            raise UsageError(f"image {name} is {w}x{h}; the others are {size[0]}x{size[1]}")
        det = detect(img, board)
        if det is None or det.corner_ids.size < min_corners:
            warnings.append(f"{name}: board not found (fewer than {min_corners} corners); skipped")
            continue
        objs.append(obj_all[det.corner_ids].astype(np.float32))
        pts.append(det.pixels.astype(np.float32).reshape(-1, 1, 2))
    if len(objs) < 4 or size is None:
        raise UsageError(f"camera calibration needs at least 4 images showing the board; {len(objs)} did")
    # k3 held at zero: with a dozen images it is poorly determined and its error grows towards the corners
    rms, K, dist, _, _ = cv2.calibrateCamera(objs, pts, size, None, None, flags=cv2.CALIB_FIX_K3)
    return (
        CameraIntrinsics(
            size[0],
            size[1],
            np.asarray(K, dtype=np.float64),
            np.asarray(dist, dtype=np.float64).reshape(-1),
            float(rms),
        ),
        warnings,
    )


def _texture(target: Target, px_per_m: float) -> tuple[NDArray[np.uint8], float]:
    """The printed target (white margin included) and its metres per texture pixel."""
    cv2 = _cv2()
    if target.kind == "apriltag":
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, target.dictionary))
        bits = int(d.markerSize) + 2
        per_bit = max(4, round(target.size_m * px_per_m / bits))
        side = bits * per_bit
        tag = cv2.aruco.generateImageMarker(d, target.tag_id, side)
        margin = 2 * per_bit
        tex = np.full((side + 2 * margin, side + 2 * margin), 255, np.uint8)
        tex[margin : margin + side, margin : margin + side] = tag
        return tex, target.size_m / side
    per_square = max(8, round(target.size_m * px_per_m))
    w = target.cols * per_square
    h = target.rows * per_square
    margin = per_square // 2
    img = _board(target).generateImage((w + 2 * margin, h + 2 * margin), marginSize=margin)
    return np.asarray(img, dtype=np.uint8), target.size_m / per_square


def _texture_to_target(target: Target, tex_shape: tuple[int, ...], m_per_px: float) -> FloatArray:
    """``(3, 3)`` map from texture pixel ``(u, v, 1)`` (pixel centres at integers) to target ``(x, y, 1)``."""
    h, w = tex_shape[:2]
    if target.kind == "apriltag":  # centre of the tag, y up
        x0, y0 = w / 2, h / 2
        return np.array(
            [[m_per_px, 0.0, (0.5 - x0) * m_per_px], [0.0, -m_per_px, (y0 - 0.5) * m_per_px], [0.0, 0.0, 1.0]]
        )
    margin = (w - target.cols * round(target.size_m / m_per_px)) / 2  # board's outer corner, y down
    return np.array(
        [
            [m_per_px, 0.0, (0.5 - margin) * m_per_px],
            [0.0, m_per_px, (0.5 - margin) * m_per_px],
            [0.0, 0.0, 1.0],
        ]
    )


def render(
    target: Target,
    K: ArrayLike,
    size: tuple[int, int],
    T_cam_target: ArrayLike,
    *,
    noise_grey: float = 2.0,
    rng: np.random.Generator | None = None,
    background: int = 110,
) -> NDArray[np.uint8]:
    """An ideal pinhole camera's greyscale image of the target (2×2 supersampled, Gaussian pixel noise).

    Args:
        target: The target.
        K: ``(3, 3)`` camera matrix.
        size: ``(width, height)``.
        T_cam_target: ``(4, 4)`` target pose in the camera frame.
        noise_grey: Standard deviation of the pixel noise, grey levels.
        rng: Random generator for the noise.
        background: Grey level around the target.
    """
    cv2 = _cv2()
    Km = np.asarray(K, dtype=np.float64)
    T = np.asarray(T_cam_target, dtype=np.float64)
    w, h = size
    tex, mpp = _texture(target, px_per_m=8000.0)
    A = _texture_to_target(target, tex.shape, mpp)
    K2 = np.array(
        [[2 * Km[0, 0], 2 * Km[0, 1], 2 * Km[0, 2] + 0.5], [0.0, 2 * Km[1, 1], 2 * Km[1, 2] + 0.5], [0, 0, 1]]
    )
    H = K2 @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
    big = cv2.warpPerspective(
        tex, H, (2 * w, 2 * h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background
    )
    img = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float64)
    if noise_grey > 0:
        img += (rng or np.random.default_rng()).normal(0.0, noise_grey, img.shape)
    return np.asarray(np.clip(np.round(img), 0, 255), dtype=np.uint8)
