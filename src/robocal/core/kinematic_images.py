"""Kinematic identification from camera images of a planar target (pure numpy).

Two set-ups, both estimated jointly with the kinematic parameters from the image positions of the target's
corners (detected and undistorted with the camera's intrinsics from a separate calibration):

* **camera fixed, target on the tool** (``camera_on_tool=False``): a camera fixed in the world looks at a target
  (an AprilTag or a ChArUco board) carried by the tool. The error model's measurement frame is the camera's:
  ``T_world_base`` is the camera → base pose (``base.*``, the hand-eye of the fixed camera) and ``T_tip_tool``
  the target's pose on the tip link (``tool.*``, the target mounting). A corner ``c`` is seen at
  ``T_world_tool · c``.
* **camera on the tool, target fixed** (``camera_on_tool=True``, eye-in-hand): the measurement frame is the
  target's: ``T_world_base`` is the target → base pose (``base.*``, where the target stands) and ``T_tip_tool``
  the camera's pose on the tip link (``tool.*``, the camera mounting). A corner ``c`` (fixed in the target
  frame) is seen at ``T_world_tool⁻¹ · c``; its derivative comes from the body twist of the tool frame, which
  three tool-point Jacobians of the error model give exactly.

Residuals are reprojection errors in pixels: ``f·(π(p_cam) − m)`` per corner, where ``π(p) = (x/z, y/z)``,
``m`` is the detected corner in normalised (undistorted) coordinates and ``f`` the mean focal length.

Start values come from :func:`hand_eye`: with ``C_i = T_cam_target`` from PnP per image and ``F_i`` the nominal
``T_base_tip``, ``C_i = X·F_i·Y`` is solved for the camera pose ``X`` and the target mounting ``Y`` in closed
form (relative motions ``A = C_i C_j⁻¹``, ``B = F_i F_j⁻¹``, ``A X = X B``: rotation from the rotation axes,
translation by least squares). With the camera on the tool the same equation holds for ``C_i⁻¹ = T_target_cam``:
``X`` is then the target → base pose and ``Y`` the camera mounting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, ShapeMismatchError, UsageError
from .arrays import FloatArray, IntArray
from .identifiability import Identifiability, analyse_columns, common_reason, still_joints
from .kinematic_errors import ErrorModel
from .kinematic_problem import _priority
from .se3 import homogeneous, matrix_from_rotvec, rotvec_from_matrix

__all__ = ["INTRINSICS", "ImageObservations", "ImageProblem", "hand_eye", "project"]



INTRINSICS: tuple[str, ...] = ("camera.fx", "camera.fy", "camera.cx", "camera.cy")
"""The refined intrinsics (pixels), in ``θ`` after the model parameters."""


def project(p_cam: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Pinhole projection ``(x/z, y/z)`` of ``(M, 3)`` points and its derivative ``(M, 2, 3)``."""
    p = np.asarray(p_cam, dtype=np.float64)
    z = p[:, 2]
    uv = p[:, :2] / z[:, None]
    D = np.zeros((p.shape[0], 2, 3))
    D[:, 0, 0] = 1.0 / z
    D[:, 1, 1] = 1.0 / z
    D[:, :, 2] = -uv / z[:, None]
    return uv, D


@dataclass(frozen=True, eq=False)
class ImageObservations:
    """Target corners seen in images taken at known joint readings.

    Attributes:
        q_rad: ``(N, n_q)`` joint readings, one row per image.
        pose: ``(M,)`` image (row of ``q_rad``) of each corner.
        corner_m: ``(M, 3)`` corner position in the target's frame, metres.
        uv: ``(M, 2)`` detected corner in normalised image coordinates (undistorted, ``x/z, y/z``).
        focal_px: Mean focal length, pixels (scales residuals to pixels).
        T_cam_target: ``(N, 4, 4)`` per-image target pose from PnP (start values and validation), or None.
        K: ``(3, 3)`` camera matrix the corners were normalised with (needed to refine the intrinsics), or None.
    """

    q_rad: FloatArray
    pose: IntArray
    corner_m: FloatArray
    uv: FloatArray
    focal_px: float
    T_cam_target: FloatArray | None = None
    K: FloatArray | None = None

    def __post_init__(self) -> None:
        q = np.asarray(self.q_rad, dtype=np.float64)
        if q.ndim != 2:
            raise ShapeMismatchError(f"joint readings must be (N, n_q), got {q.shape}")
        pose = np.asarray(self.pose, dtype=np.int64)
        c = np.asarray(self.corner_m, dtype=np.float64)
        uv = np.asarray(self.uv, dtype=np.float64)
        m = pose.shape[0]
        if pose.ndim != 1 or c.shape != (m, 3) or uv.shape != (m, 2):
            raise ShapeMismatchError(f"corners: pose {pose.shape}, corner_m {c.shape}, uv {uv.shape}")
        if m and (pose.min() < 0 or pose.max() >= q.shape[0]):
            raise ShapeMismatchError("a corner refers to an image that has no joint reading")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(uv))):
            raise InvalidCalibrationError("a detected corner is NaN or infinite")
        if not (math.isfinite(self.focal_px) and self.focal_px > 0):
            raise InvalidCalibrationError(f"focal length must be positive, got {self.focal_px}")
        object.__setattr__(self, "q_rad", q)
        object.__setattr__(self, "pose", pose)
        object.__setattr__(self, "corner_m", c)
        object.__setattr__(self, "uv", uv)
        if self.K is not None:
            K = np.asarray(self.K, dtype=np.float64)
            if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
                raise InvalidCalibrationError("the camera matrix must be a finite (3, 3) with positive fx, fy")
            object.__setattr__(self, "K", K)

    @property
    def n_poses(self) -> int:
        """Number of images."""
        return int(self.q_rad.shape[0])

    def subset(self, rows: ArrayLike) -> ImageObservations:
        """The observations of images ``rows`` (renumbered)."""
        r = np.asarray(rows, dtype=np.int64)
        new_index = np.full(self.n_poses, -1)
        new_index[r] = np.arange(r.size)
        keep = np.isin(self.pose, r)
        return ImageObservations(
            self.q_rad[r],
            new_index[self.pose[keep]],
            self.corner_m[keep],
            self.uv[keep],
            self.focal_px,
            None if self.T_cam_target is None else self.T_cam_target[r],
            self.K,
        )


def _axis_angle(R: FloatArray) -> FloatArray:
    return np.asarray(rotvec_from_matrix(R), dtype=np.float64)


def hand_eye(T_cam_target: ArrayLike, T_base_tip: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Solve ``T_cam_target_i = X · T_base_tip_i · Y`` for ``X = T_cam_base`` and ``Y = T_tip_target``.

    Args:
        T_cam_target: ``(N, 4, 4)`` target poses seen by the camera (PnP).
        T_base_tip: ``(N, 4, 4)`` tip poses from the (nominal) kinematics.

    Returns:
        ``(X, Y)``, each ``(4, 4)``.

    Raises:
        UsageError: Fewer than three images, or motions that do not turn about two different axes.
    """
    C = np.asarray(T_cam_target, dtype=np.float64)
    F = np.asarray(T_base_tip, dtype=np.float64)
    n = C.shape[0]
    if n < 3 or F.shape != C.shape:
        raise UsageError(f"hand-eye needs at least 3 images with joint readings, got {n}")
    alphas, betas, As, Bs = [], [], [], []
    for i in range(n):
        for j in range(i + 1, n):
            A = C[i] @ np.linalg.inv(C[j])
            B = F[i] @ np.linalg.inv(F[j])
            a, b = _axis_angle(A[:3, :3]), _axis_angle(B[:3, :3])
            if np.linalg.norm(a) > 0.05 and np.linalg.norm(b) > 0.05:
                alphas.append(a)
                betas.append(b)
                As.append(A)
                Bs.append(B)
    if len(alphas) < 2:
        raise UsageError("hand-eye: the images need the target turned about at least two different axes")
    Al, Be = np.asarray(alphas), np.asarray(betas)
    H = Be.T @ Al
    U, s, Vt = np.linalg.svd(H)
    if s[1] < 1e-6 * s[0]:
        raise UsageError("hand-eye: the images need the target turned about at least two different axes")
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    M = np.concatenate([A[:3, :3] - np.eye(3) for A in As])
    v = np.concatenate([R @ B[:3, 3] - A[:3, 3] for A, B in zip(As, Bs, strict=True)])
    t = np.linalg.lstsq(M, v, rcond=None)[0]
    X = homogeneous(R, t)
    Ys = [np.linalg.inv(F[i]) @ np.linalg.inv(X) @ C[i] for i in range(n)]
    t_y = np.mean([Y[:3, 3] for Y in Ys], axis=0)
    U2, _, Vt2 = np.linalg.svd(np.sum([Y[:3, :3] for Y in Ys], axis=0))
    R_y = U2 @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U2 @ Vt2))]) @ Vt2
    return X, homogeneous(R_y, t_y)


@dataclass(frozen=True, eq=False)
class ImageProblem:
    """Reprojection residuals of image observations over the free model parameters.

    Attributes:
        model: Error model. Camera fixed: ``T_world_base`` is the camera → base start value and ``T_tip_tool``
            the target mounting's. Camera on the tool: ``T_world_base`` is the target → base start value and
            ``T_tip_tool`` the camera mounting's.
        data: The observations.
        free: Estimated model parameter indices.
        x_fixed: ``(P,)`` values of all model parameters.
        group_ids: No contact groups (the interface of :class:`~robocal.core.kinematic_problem.Problem`).
        camera_on_tool: The set-up: False for a fixed camera and the target on the tool, True for a camera on
            the tool and a fixed target.
        refine_intrinsics: Estimate ``fx, fy, cx, cy`` too (four more unknowns after the model parameters, in
            pixels, changes to ``data.K``); residuals are then ``K'·π(p) − K·m``, the pinhole pixels of the
            undistorted corners (the lens distortion stays as calibrated).
    """

    model: ErrorModel
    data: ImageObservations
    free: tuple[int, ...]
    x_fixed: FloatArray

    group_ids: tuple[int, ...] = ()
    camera_on_tool: bool = False
    refine_intrinsics: bool = False

    def __post_init__(self) -> None:
        if self.refine_intrinsics and self.data.K is None:
            raise UsageError("refining the intrinsics needs the camera matrix the corners were normalised with")

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the unknowns: model parameters, then ``camera.fx/fy/cx/cy`` when the intrinsics are refined."""
        extra = INTRINSICS if self.refine_intrinsics else ()
        return tuple(self.model.names[i] for i in self.free) + extra

    @property
    def n_theta(self) -> int:
        """Number of unknowns."""
        return len(self.free) + (len(INTRINSICS) if self.refine_intrinsics else 0)

    def x_of(self, theta: ArrayLike) -> FloatArray:
        """The full parameter vector for unknowns ``θ``."""
        x = np.array(self.x_fixed, dtype=np.float64)
        x[list(self.free)] = np.asarray(theta, dtype=np.float64)[: len(self.free)]
        return x

    def camera_matrix(self, theta: ArrayLike) -> FloatArray:
        """The camera matrix under ``θ`` (``data.K`` plus the refined changes), ``(3, 3)``."""
        assert self.data.K is not None
        K = np.array(self.data.K, dtype=np.float64)
        if self.refine_intrinsics:
            d = np.asarray(theta, dtype=np.float64)[len(self.free) :]
            K[0, 0] += d[0]
            K[1, 1] += d[1]
            K[0, 2] += d[2]
            K[1, 2] += d[3]
        return K

    def points_of(self, theta: ArrayLike) -> FloatArray:
        """No contact points: ``(0, 3)``."""
        return np.zeros((0, 3))

    def initial_theta(self) -> FloatArray:
        """The free parameters of ``x_fixed`` (and no change to the intrinsics)."""
        t = np.asarray(self.x_fixed, dtype=np.float64)[list(self.free)]
        return np.concatenate([t, np.zeros(self.n_theta - len(self.free))])

    def _points(self, theta: ArrayLike, jacobian: bool) -> tuple[FloatArray, FloatArray | None]:
        """Corners in the camera frame ``(M, 3)`` and, when asked, their Jacobian ``(M, 3, n_theta)``."""
        if self.camera_on_tool:
            return self._points_seen_from_tool(theta, jacobian)
        q = self.data.q_rad[self.data.pose]
        if jacobian:
            p, J = self.model.point_jacobian(q, self.x_of(theta), self.data.corner_m)
            return p, J[:, :, list(self.free)]
        T = self.model.tool_poses(q, self.x_of(theta))
        return T[:, :3, 3] + np.einsum("nij,nj->ni", T[:, :3, :3], self.data.corner_m), None

    def _points_seen_from_tool(self, theta: ArrayLike, jacobian: bool) -> tuple[FloatArray, FloatArray | None]:
        """Camera on the tool: ``p = T_target_cam⁻¹ · c`` per corner, and ``∂p/∂θ = −(v + ω × p)``.

        ``v`` and ``ω`` are the tool frame's body twist per unit parameter: a tool point ``a`` moves by
        ``R (v + ω × a)``, so the error model's Jacobians of the points ``0``, ``e_x`` and ``e_y`` give both.
        """
        x = self.x_of(theta)
        q = self.data.q_rad
        T = self.model.tool_poses(q, x)  # (N, 4, 4): T_target_cam per image
        R = T[self.data.pose, :3, :3]
        p = np.einsum("mji,mj->mi", R, self.data.corner_m - T[self.data.pose, :3, 3])
        if not jacobian:
            return np.asarray(p, dtype=np.float64), None
        cols = list(self.free)
        Rt = np.transpose(T[:, :3, :3], (0, 2, 1))
        J0 = self.model.point_jacobian(q, x)[1][:, :, cols]
        dx = Rt @ (self.model.point_jacobian(q, x, (1.0, 0.0, 0.0))[1][:, :, cols] - J0)  # ω × e_x
        dy = Rt @ (self.model.point_jacobian(q, x, (0.0, 1.0, 0.0))[1][:, :, cols] - J0)  # ω × e_y
        v = (Rt @ J0)[self.data.pose]
        w = np.stack([dy[:, 2, :], -dx[:, 2, :], dx[:, 1, :]], axis=1)[self.data.pose]
        Jp = -(v + np.cross(w, p[:, :, None], axisa=1, axisb=1, axisc=1))
        return np.asarray(p, dtype=np.float64), np.asarray(Jp, dtype=np.float64)

    def residuals(self, theta: ArrayLike) -> FloatArray:
        """Reprojection errors, pixels, ``(2M,)``."""
        p, _ = self._points(theta, False)
        uv, _ = project(p)
        if self.refine_intrinsics:
            K, K0 = self.camera_matrix(theta), self.camera_matrix(np.zeros(self.n_theta))
            r = uv * K[[0, 1], [0, 1]] + K[:2, 2] - (self.data.uv * K0[[0, 1], [0, 1]] + K0[:2, 2])
            return np.asarray(r.reshape(-1), dtype=np.float64)
        return np.asarray((self.data.focal_px * (uv - self.data.uv)).reshape(-1), dtype=np.float64)

    def residuals_and_jacobian(self, theta: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Reprojection errors (px) and their Jacobian ``(2M, n_theta)``."""
        p, Jp = self._points(theta, True)
        assert Jp is not None
        uv, D = project(p)
        if not self.refine_intrinsics:
            f = self.data.focal_px
            r = (f * (uv - self.data.uv)).reshape(-1)
            J = f * np.einsum("mij,mjk->mik", D, Jp)
            return np.asarray(r, dtype=np.float64), np.asarray(J.reshape(-1, J.shape[2]), dtype=np.float64)
        fxy = self.camera_matrix(theta)[[0, 1], [0, 1]]
        r = self.residuals(theta)
        Jg = fxy[None, :, None] * np.einsum("mij,mjk->mik", D, Jp)
        Jk = np.zeros((p.shape[0], 2, len(INTRINSICS)))
        Jk[:, 0, 0] = uv[:, 0]
        Jk[:, 1, 1] = uv[:, 1]
        Jk[:, 0, 2] = 1.0
        Jk[:, 1, 3] = 1.0
        J = np.concatenate([Jg, Jk], axis=2)
        return r, np.asarray(J.reshape(-1, J.shape[2]), dtype=np.float64)

    def pose_errors(self, theta: ArrayLike) -> FloatArray:
        """RMS reprojection error per image, pixels ``(N,)`` (NaN for an image without corners)."""
        r = self.residuals(theta).reshape(-1, 2)
        sq = np.bincount(self.data.pose, np.sum(r * r, axis=1), minlength=self.data.n_poses)
        count = np.bincount(self.data.pose, minlength=self.data.n_poses)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.asarray(np.sqrt(sq / count), dtype=np.float64)

    def priority(self) -> FloatArray:
        """Base-set preference: camera pose or target place, then offsets, origin translations, tilts, mounting."""
        pri = _priority(self.model)[list(self.free)]
        return np.concatenate([pri, np.full(self.n_theta - len(self.free), 7.0)])  # intrinsics last

    def analyse(self, theta: ArrayLike | None = None, *, tolerance: float = 1e-8) -> Identifiability:
        """Identifiability of the unknowns at ``θ`` (default: the start values)."""
        t = self.initial_theta() if theta is None else np.asarray(theta, dtype=np.float64)
        _, J = self.residuals_and_jacobian(t)
        still = still_joints(self.model.chain.movable, self.data.q_rad)
        names = self.names

        def explain(col: int, same: tuple[tuple[str, float], ...], is_zero: bool) -> str:
            group, _, kind = names[col].partition(".")
            if group in still:
                return f"{group} did not move in the images (always {still[group]:.4g}); move it through its range"
            common = common_reason(group, kind, same, is_zero, "images")
            if common is not None:
                return common
            if len(same) == 1:
                other, c = same[0]
                if other.partition(".")[0] == "base":
                    frame = "target's place" if self.camera_on_tool else "camera pose"
                    return (
                        f"moves the image exactly like the {frame} {other} (×{c:.3g}); the {frame} is "
                        "identified instead"
                    )
                return f"moves the target exactly like {other} (×{c:.3g}); {other} is identified instead"
            return "cannot be told apart from a combination of " + ", ".join(n for n, _ in same[:4])

        return analyse_columns(J, names, priority=self.priority(), tolerance=tolerance, explain=explain)


def frame_from_rotvec(rotvec: ArrayLike, t: ArrayLike) -> FloatArray:
    """``(4, 4)`` transform from a rotation vector and a translation (OpenCV's rvec/tvec)."""
    return homogeneous(
        matrix_from_rotvec(np.asarray(rotvec, dtype=np.float64)), np.asarray(t, dtype=np.float64)
    )
