"""Relative pose from an essential matrix and pixel correspondences: the rich API."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import ppo
from .checks import (
    as_camera_matrix,
    as_distance_threshold,
    as_essential,
    as_mask,
    as_point_pair,
    as_points,
    as_pri_threshold,
)
from .result import compact_repr

__all__ = ["PoseResult", "recover_pose", "pixel_rays", "inverse_camera"]


@dataclass(frozen=True, repr=False)
class PoseResult:
    """The pose chosen by the PPO inequalities, with its evidence.

    Its ``repr`` is one line, the per-point arrays by their shape
    (:func:`ppo_cv.result.compact_repr`).

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation from camera 1 to camera 2: ``X2 = R X1 + t``. For a pure rotation, the
        least-squares rotation of the inlier rays (:func:`ppo_cv.ppo.rotation_from_rays`).
    t : ndarray, shape (3,)
        Unit translation direction. Undetermined when ``pure_rotation`` is True: it is then the
        direction fitted to noise by the essential matrix (Proposition 7).
    inliers : ndarray of bool, shape (N,)
        Points that were used (input mask) and satisfy both PPO inequalities, ``m1 > 0`` and
        ``m2 > 0`` (and lie closer than ``distance_thresh``, when one is given). For a pure
        rotation only the same-side inequality applies, ``m1 > 0``.
    pure_rotation : bool
        ``pri < pri_threshold`` (eq. 85).
    pri : float
        Pure-rotation indicator, mean ``|m2|`` over the used points (eq. 84).
    m3 : float
        The paper's alternative indicator (eq. 78), mean sine of the parallax angle.
    points3d : ndarray, shape (N, 3)
        Analytic points in camera-1 coordinates, baseline = 1 (Proposition 3), one row per input
        point: NaN outside ``inliers``, where the rays are parallel, and everywhere for a pure
        rotation, which has no structure (``PairResult.points3d`` follows the same rule).
    depths : ndarray, shape (N, 2)
        Depth of each point in camera 1 and camera 2, baseline = 1 (eq. 36), outliers included
        (negative behind a camera); inf where the rays are parallel, and everywhere for a pure
        rotation.
    support_R, support_R_rejected : int
        Number of used points with positive same-side score for the chosen and the rejected
        rotation (S1 of Table II).
    support_t, support_t_rejected : int
        The same for the intersection score and the two translation signs (S2).
    pri_threshold : float
        The threshold the decision used.
    """

    R: np.ndarray
    t: np.ndarray
    inliers: np.ndarray
    pure_rotation: bool
    pri: float
    m3: float
    points3d: np.ndarray
    depths: np.ndarray
    support_R: int
    support_R_rejected: int
    support_t: int
    support_t_rejected: int
    pri_threshold: float

    @property
    def num_inliers(self) -> int:
        """Number of points that satisfy both PPO inequalities."""
        return int(np.count_nonzero(self.inliers))

    def __repr__(self) -> str:
        return compact_repr(self)


def inverse_camera(K: Any) -> np.ndarray:
    """``K^-1`` of a pinhole camera matrix.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Upper triangular with last row (0, 0, 1) and positive focal lengths (skew allowed).

    Returns
    -------
    ndarray, shape (3, 3)
        Its inverse, float64.
    """
    return _inverse(as_camera_matrix(K, "K"))


def pixel_rays(points: Any, K: Any) -> np.ndarray:
    """Pixel points to stacked normalized rays ``K^-1 [u, v, 1]^T``.

    Parameters
    ----------
    points : array_like, shape (N, 2), (N, 1, 2), (1, N, 2) or (N, 2, 1)
        Finite pixel coordinates.
    K : array_like, shape (3, 3)
        Camera matrix, as for :func:`inverse_camera`.

    Returns
    -------
    ndarray, shape (3, N)
        One ray per column, third coordinate 1.
    """
    return _rays(as_points(points, "points"), as_camera_matrix(K, "K"))


def _inverse(K: np.ndarray) -> np.ndarray:
    """``K^-1`` of a checked camera matrix (3, 3)."""
    (fx, skew, cx), (_, fy, cy), _ = K.tolist()
    fxy = fx * fy
    inverse = [1.0 / fx, -skew / fxy, (skew * cy - cx * fy) / fxy, 0.0, 1.0 / fy, -cy / fy]
    return np.array([*inverse, 0.0, 0.0, 1.0]).reshape(3, 3)


def _rays(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    """:func:`pixel_rays` of checked points (N, 2) and camera matrix (3, 3)."""
    if points.shape[0] <= 4096:  # one small matrix product is cheapest here, row passes beyond
        K_inv = _inverse(K)
        return K_inv[:, :2] @ points.T + K_inv[:, 2:]
    (fx, skew, cx), (_, fy, cy), _ = K.tolist()
    rays = np.empty((3, points.shape[0]))
    rays[1] = (points[:, 1] - cy) * (1.0 / fy)
    rays[0] = (points[:, 0] - cx - skew * rays[1]) * (1.0 / fx)
    rays[2] = 1.0
    return rays


def recover_pose(
    E: Any,
    points1: Any,
    points2: Any,
    K1: Any,
    K2: Any = None,
    *,
    mask: Any = None,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
    distance_thresh: float | None = None,
) -> PoseResult:
    """Recover ``(R, t)`` from an essential matrix by the PPO inequalities (Table II).

    Unlike cheirality (``cv2.recoverPose``) no point is triangulated to choose the pose, and the
    rotation is right even for a pure rotation (Proposition 7), which ``pure_rotation`` reports.

    Parameters
    ----------
    E : array_like, shape (3, 3)
        Essential matrix in normalized coordinates, ``x2^T E x1 = 0``, any scale.
    points1, points2 : array_like, shape (N, 2), (N, 1, 2), (1, N, 2) or (N, 2, 1)
        Matching pixel coordinates in image 1 and image 2, N >= 5.
    K1 : array_like, shape (3, 3)
        Intrinsics of camera 1; positive focal lengths (a negative one would mirror the image
        and flip ``t``: it is an error).
    K2 : array_like, shape (3, 3), optional
        Intrinsics of camera 2; defaults to ``K1``.
    mask : array_like, shape (N,) or (N, 1), optional
        Nonzero entries select the points to use (e.g. RANSAC inliers): bool or whole numbers
        0..255; it must select at least 5 points.
    pri_threshold : float
        Motion is a pure rotation when PRI is below it (paper: 0.015).
    distance_thresh : float, optional
        Points farther than this (in baselines) from either camera are not inliers; infinity
        (as None) drops none.

    Returns
    -------
    PoseResult

    Examples
    --------
    >>> import numpy as np, ppo_cv
    >>> rng = np.random.default_rng(0)
    >>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    >>> X = rng.uniform([-2, -2, 4], [2, 2, 8], (50, 3))
    >>> R, t = np.eye(3), np.array([1.0, 0, 0])
    >>> p1 = (X @ K.T)[:, :2] / X[:, 2:]
    >>> X2 = X @ R.T + t
    >>> p2 = (X2 @ K.T)[:, :2] / X2[:, 2:]
    >>> E = np.array([[0, 0, 0], [0, 0, -1.0], [0, 1, 0]]) @ R
    >>> result = ppo_cv.recover_pose(E, p1, p2, K)
    >>> np.allclose(result.t, t), result.num_inliers, result.pure_rotation
    (True, 50, False)
    """
    E = as_essential(E)
    pri_threshold = as_pri_threshold(pri_threshold)
    p1, p2 = as_point_pair(points1, points2)
    K1 = as_camera_matrix(K1, "K1")
    K2 = K1 if K2 is None else as_camera_matrix(K2, "K2")
    used = as_mask(mask, p1.shape[0])
    used = np.ones(p1.shape[0], dtype=bool) if used is None else used
    if distance_thresh is not None:
        distance_thresh = as_distance_threshold(distance_thresh, "distance_thresh")
        distance_thresh = None if distance_thresh == np.inf else distance_thresh
    X1, X2 = _rays(p1, K1), _rays(p2, K2)
    return _recover_rays(E, X1, X2, used, pri_threshold, distance_thresh)


def _recover_normalized(
    E: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    used: np.ndarray,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
    distance_thresh: float | None = None,
) -> PoseResult:
    """:func:`recover_pose` on normalized points (N, 2), unchecked."""
    return _recover_rays(E, ppo._planar(x1), ppo._planar(x2), used, pri_threshold, distance_thresh)


def _recover_rays(
    E: np.ndarray,
    X1: np.ndarray,
    X2: np.ndarray,
    used: np.ndarray,
    pri_threshold: float,
    distance_thresh: float | None,
) -> PoseResult:
    sel = ppo._select(ppo.decompose_essential(E), X1, X2, used)
    pri = ppo.pure_rotation_indicator(sel.m2[used])
    pure_rotation = bool(pri < pri_threshold)
    if pure_rotation:
        inliers = used & (sel.m1 > 0)
        R = ppo._rotation_from_rays(X1[:, inliers], X2[:, inliers])
        n = X1.shape[1]
        points3d, depths = np.full((n, 3), np.nan), np.full((n, 2), np.inf)
    else:
        R = sel.R
        z1, z2, _ = ppo._depths(X1, X2, R, sel.t, 1e-12)
        inliers = used & (sel.m1 > 0) & (sel.m2 > 0)
        if distance_thresh is not None:
            inliers &= (z1 < distance_thresh) & (z2 < distance_thresh)
        points3d = np.where(inliers[:, None], ppo._points(X1, X2, R, sel.t, 1e-12).T, np.nan)
        depths = np.stack([z1, z2], axis=1)
    return PoseResult(
        R=R,
        t=sel.t,
        inliers=inliers,
        pure_rotation=pure_rotation,
        pri=pri,
        m3=ppo.m3_indicator(X1[:, used].T, X2[:, used].T, R),
        points3d=points3d,
        depths=depths,
        support_R=sel.support_R,
        support_R_rejected=sel.support_R_rejected,
        support_t=sel.support_t,
        support_t_rejected=sel.support_t_rejected,
        pri_threshold=pri_threshold,
    )
