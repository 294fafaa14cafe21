"""Non-linear refinement of a relative pose over its inliers, and the rotation-only fit.

- ``refine_pose``: Levenberg-Marquardt on the tangent Sampson error of ``E = [t]_x R`` over the
  inliers (``pycolmap.refine_relative_pose``), ``t`` kept on the unit sphere.
- ``refine_pose_radial``: the same cost with the points first undistorted by a one-parameter
  division model shared by both views (Fitzgibbon, 2001), the coefficient under a Gaussian prior
  and kept only when significant: lens distortion nobody gave, which an essential matrix
  otherwise absorbs into a wrong rotation and a spurious translation.
- ``fit_rotation``: for a pure rotation ``b2 ~ R b1`` on unit bearing vectors; the least-squares
  rotation ``argmin_R sum_i ||b2_i - R b1_i||^2`` (:func:`ppo_cv.ppo.rotation_from_rays`),
  re-fitted on the matches whose angular residual ``angle(b2_i, R b1_i)`` stays below the
  threshold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lsq import (
    gauss_newton_covariance,
    huber_weights,
    levenberg_marquardt,
    rotation_increment,
    tangent_basis,
)
from .plane import K1_SIGNIFICANCE, undistort_division
from .ppo import rotation_from_rays
from .robust import virtual_camera

__all__ = [
    "K1_MIN",
    "RadialPose",
    "T_SIGMA_CAP_DEG",
    "refine_pose",
    "refine_pose_radial",
    "fit_rotation",
    "rotation_residuals",
    "translation_sigma_deg",
]


def refine_pose(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    focal: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine ``(R, t)`` by minimising the Sampson error over the inliers.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
        Initial rotation, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Initial translation direction.
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches that enter the cost.
    focal : float
        Focal length (pixels) of the virtual camera in which the error is measured; it scales the
        cost, not the minimiser.

    Returns
    -------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Unit norm. The input pose is returned when the solver fails.
    """
    import pycolmap

    t = np.asarray(t, dtype=np.float64).reshape(3)
    if np.count_nonzero(inliers) < 5:
        return R, t / np.linalg.norm(t)
    camera = virtual_camera(focal)
    start = pycolmap.Rigid3d(pycolmap.Rotation3d(np.asarray(R, dtype=np.float64)), t)
    refined = pycolmap.refine_relative_pose(
        start,
        camera,
        np.ascontiguousarray(focal * x1[:, :2]),
        camera,
        np.ascontiguousarray(focal * x2[:, :2]),
        np.asarray(inliers, dtype=bool),
    )
    if refined is None:
        return R, t / np.linalg.norm(t)
    pose = refined["cam2_from_cam1"] if isinstance(refined, dict) else refined
    t_new = np.asarray(pose.translation, dtype=np.float64).reshape(3)
    return pose.rotation.matrix(), t_new / np.linalg.norm(t_new)


K1_MIN = 0.02
"""Smallest division coefficient :func:`refine_pose_radial` keeps. Below it the coefficient
trades with the pose: on distortion-free renders at small baselines the fit finds ``|k1|`` up
to 0.016 at 3-8 standard deviations, and keeping it moved ``t`` by up to 3 degrees; the
unmodelled distortion of ``data_gen.REAL_PHOTO`` starts at 0.02."""


@dataclass(frozen=True)
class RadialPose:
    """Outcome of :func:`refine_pose_radial`.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Unit norm, ``X2 = R X1 + t`` between the undistorted points.
    k1 : float
        Division-model coefficient on normalized points (0 when not kept).
    k1_sigma : float
        Its standard deviation (Gauss-Newton); ``inf`` when it was not fitted.
    """

    R: np.ndarray
    t: np.ndarray
    k1: float
    k1_sigma: float


def refine_pose_radial(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    *,
    scale: float,
    k1_prior: float = 0.1,
    max_k1: float = 0.3,
    iterations: int = 20,
) -> RadialPose:
    """Refine ``(R, t)`` with a radial distortion coefficient on the Sampson error.

    Minimises ``sum_i rho(r_i) + (scale k1 / k1_prior)^2`` over the inliers, ``r_i`` the signed
    Sampson error of ``E = [t]x R`` between ``q1_i`` and ``q2_i``, the points undistorted by
    the division model ``q = x / (1 + k1 |x|^2)`` (:func:`ppo_cv.plane.undistort_division`,
    one coefficient for both views), ``rho`` Huber's loss with bound ``scale``, by
    Levenberg-Marquardt on 6 parameters: ``R = exp([w]x) R0`` (3), ``t`` on the unit sphere
    (2 tangent coordinates), ``k1``. The coefficient is kept when the cost fell,
    ``K1_MIN <= |k1| <= max_k1`` and ``|k1|`` exceeds :data:`ppo_cv.plane.K1_SIGNIFICANCE`
    standard deviations; otherwise the start is returned with ``k1 = 0``.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Start, e.g. :func:`refine_pose`'s result.
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates of the matches, distortion unmodelled.
    inliers : ndarray of bool, shape (N,)
        Matches of the cost; fewer than 12 return the start.
    scale : float
        Huber bound, normalized units (the RANSAC threshold over the focal length).
    k1_prior, max_k1 : float
        Standard deviation of the prior on ``k1``; bound on ``|k1|``.
    iterations : int
        Largest number of Levenberg-Marquardt steps.

    Returns
    -------
    RadialPose
    """
    R0 = np.asarray(R, dtype=np.float64)
    t0 = np.asarray(t, dtype=np.float64).reshape(3)
    t0 = t0 / np.linalg.norm(t0)
    start = RadialPose(R0, t0, 0.0, float("inf"))
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    if len(a) < 12:
        return start
    U = tangent_basis(t0)

    def pose(p):
        tp = t0 + p[3:5] @ U
        return rotation_increment(p[:3]) @ R0, tp / np.linalg.norm(tp)

    def stacked(p):
        Rp, tp = pose(p)
        r = _sampson_signed(Rp, tp, undistort_division(a, p[5]), undistort_division(b, p[5]))
        return np.append(huber_weights(np.abs(r), scale) * r, scale * p[5] / k1_prior)

    r_start = stacked(np.zeros(6))
    p, J = levenberg_marquardt(stacked, np.zeros(6), iterations)
    r = stacked(p)
    cov = gauss_newton_covariance(J, float(r @ r) / max(len(r) - 6, 1))
    if cov is None:
        return start
    k1, k1_sigma = float(p[5]), float(np.sqrt(max(cov[5, 5], 0.0)))
    kept = K1_MIN <= abs(k1) <= max_k1 and abs(k1) > K1_SIGNIFICANCE * k1_sigma
    if not (kept and r @ r < r_start @ r_start):
        return RadialPose(R0, t0, 0.0, k1_sigma)
    Rp, tp = pose(p)
    return RadialPose(Rp, tp, k1, k1_sigma)


def _bearings(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def rotation_residuals(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Angle (radians) between ``b2_i`` and ``R b1_i`` for each match, shape (N,)."""
    b1, b2 = _bearings(x1), _bearings(x2)
    cross = np.linalg.norm(np.cross(b1 @ R.T, b2), axis=1)
    dot = np.einsum("ij,ij->i", b1 @ R.T, b2)
    return np.arctan2(cross, dot)


def fit_rotation(
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    threshold: float,
    R: np.ndarray | None = None,
    iterations: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation between bearing vectors, re-fitted on its own inliers.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates (or bearings) of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches allowed in the fit.
    threshold : float
        Largest angular residual (radians) of a match kept in the re-fit.
    R : ndarray, shape (3, 3), optional
        Initial rotation (e.g. from the essential matrix) that selects the first matches;
        without it the first fit uses all allowed matches, which suits outlier-free input only.
    iterations : int
        Number of re-fits.

    Returns
    -------
    R : ndarray, shape (3, 3)
    used : ndarray of bool, shape (N,)
        The matches of the last fit.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> b1 = rng.normal(size=(20, 3)); b1[:, 2] = np.abs(b1[:, 2]) + 2
    >>> c, s = np.cos(0.1), np.sin(0.1)
    >>> R_true = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> R, used = fit_rotation(b1, b1 @ R_true.T, np.ones(20, bool), 1e-3)
    >>> bool(np.allclose(R, R_true)), int(used.sum())
    (True, 20)
    """
    b1, b2 = _bearings(np.asarray(x1, float)), _bearings(np.asarray(x2, float))
    allowed = np.asarray(inliers, dtype=bool)
    used = allowed.copy()
    if R is not None:
        used &= rotation_residuals(R, b1, b2) < threshold
    if np.count_nonzero(used) < 2:
        used = allowed.copy()
    R = rotation_from_rays(b1[used], b2[used])
    for _ in range(iterations):
        keep = allowed & (rotation_residuals(R, b1, b2) < threshold)
        if np.count_nonzero(keep) < 2 or np.array_equal(keep, used):
            break
        used = keep
        R = rotation_from_rays(b1[used], b2[used])
    return R, used


def _sampson_signed(R: np.ndarray, t: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    E = tx @ R
    Ex1, Etx2 = x1 @ E.T, x2 @ E
    denominator = np.sqrt(np.sum(Ex1[:, :2] ** 2, axis=1) + np.sum(Etx2[:, :2] ** 2, axis=1))
    return np.einsum("ij,ij->i", x2, Ex1) / np.maximum(denominator, 1e-300)


T_SIGMA_CAP_DEG = 90.0
"""Largest ``t_sigma_deg``. The direction of ``t`` is a point of the unit sphere and cheirality
fixes its sign, so it lies in the hemisphere around any estimate: a one-sigma cone of 90 degrees
already covers all of it, and a larger linearised value says no more than "undetermined"."""


def translation_sigma_deg(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    noise: float | None = None,
    step: float = 1e-4,
) -> float:
    """One standard deviation of the direction of ``t`` (degrees) from the Sampson cost.

    The pose is perturbed as ``R(w) = exp([w]_x) R`` and ``t(v) = (t + v1 u1 + v2 u2) / |.|``
    with ``(u1, u2)`` an orthonormal basis of the tangent plane of the sphere at ``t`` (5 dof).
    The cost is ``f = 1/2 sum_i r_i^2`` over the signed Sampson residuals ``r`` of the inliers;
    its Hessian ``H`` (5, 5) is taken by central differences of ``f`` itself, not as the
    Gauss-Newton ``J^T J``: ``r_i = t . m_i / d_i`` with ``m_i = R x1_i x x2_i``, so on the
    sphere ``H`` is ``J^T J`` minus the curvature term ``sum r_i^2`` (in the ``v`` block). For a
    pure rotation every ``m_i`` is noise, ``J^T J`` grows like ``n`` times the noise and would
    claim a direction known to ``1 / sqrt(n)`` radians; the exact ``H`` is then a fluctuation
    around 0. What is left of it is taken away too: noise in the matches puts
    ``E[m_i m_i^T]`` into the ``v`` block whatever the motion (an errors-in-variables term,
    computed per match from the noise variance), and only the rest is information a translation
    created. For a pure rotation the corrected block is not positive and the value is the cap;
    for a clear baseline the correction is negligible. With ``s^2`` the noise variance of one
    residual (``|r|^2 / (I - 5)`` of the fit, or ``noise^2``) the covariance is ``s^2 H^-1``;
    its ``v`` block (2, 2) is that of the direction of ``t`` in radians, and the value returned
    is the square root of its largest eigenvalue, capped at :data:`T_SIGMA_CAP_DEG` (also when
    ``H`` is not positive definite: the cost does not curve up in every direction).

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Refined pose, ``X2 = R X1 + t``, at the minimum of the Sampson cost.
    x1, x2 : ndarray, shape (N, 3)
        Normalised homogeneous coordinates of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches of the cost; fewer than 6 gives the cap.
    noise : float, optional
        Standard deviation of one Sampson residual (normalised units) when the fit's own residuals
        understate it, e.g. the rotation model's noise for a pair judged a pure rotation (the
        essential matrix's spurious translation absorbs part of the noise).
    step : float
        Finite-difference step (radians).

    Returns
    -------
    float
    """
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    if len(a) < 6:
        return T_SIGMA_CAP_DEG
    t = np.asarray(t, float).reshape(3) / np.linalg.norm(t)
    u1, u2 = tangent_basis(t)

    def cost(p: np.ndarray) -> float:
        tp = t + p[3] * u1 + p[4] * u2
        r = _sampson_signed(rotation_increment(p[:3]) @ R, tp / np.linalg.norm(tp), a, b)
        return 0.5 * float(r @ r)

    r0 = _sampson_signed(R, t, a, b)
    variance = float(r0 @ r0) / (len(a) - _NPOSE) if noise is None else float(noise) ** 2
    H = _hessian(cost, _NPOSE, step)
    H[3:, 3:] -= _noise_information(R, t, np.column_stack([u1, u2]), a, b, variance)
    eigenvalues, vectors = np.linalg.eigh(H)
    if eigenvalues[0] <= 1e-12 * max(eigenvalues[-1], 1e-300):
        return T_SIGMA_CAP_DEG
    cov = variance * (vectors / eigenvalues) @ vectors.T
    largest = float(np.linalg.eigvalsh(cov[3:, 3:])[-1])
    return float(min(np.degrees(np.sqrt(max(largest, 0.0))), T_SIGMA_CAP_DEG))


_NPOSE = 5


def _noise_information(R, t, U, a, b, variance: float) -> np.ndarray:
    """Expected part (2, 2) of the ``v`` block of ``H`` that the noise itself contributes.

    ``r_i = t . m_i / d_i`` with ``m_i = R a_i x b_i``, so the ``v`` block holds
    ``sum (U^T m_i)(U^T m_i)^T / d_i^2``. Image noise of variance ``sigma^2`` per coordinate puts
    ``E[m m^T] = sigma^2 ([Ra]_x P [Ra]_x^T + [b]_x R P R^T [b]_x^T)`` (``P = diag(1, 1, 0)``)
    into ``m`` whatever the motion: information about ``t`` that a translation did not create.
    For a pure rotation it is all there is; for a clear baseline it is negligible.
    """
    P = np.diag([1.0, 1.0, 0.0])
    Ra = a @ R.T
    A, B = _skew_rows(Ra), _skew_rows(b)
    C = A @ P @ np.swapaxes(A, 1, 2) + B @ (R @ P @ R.T) @ np.swapaxes(B, 1, 2)
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    E = tx @ R
    Ea, Etb = a @ E.T, b @ E
    d2 = np.sum(Ea[:, :2] ** 2, axis=1) + np.sum(Etb[:, :2] ** 2, axis=1)
    weighted = np.einsum("nij,n->ij", C, 1.0 / np.maximum(d2, 1e-300))
    return variance * U.T @ weighted @ U


def _skew_rows(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (N, 3, 3) of the rows of ``v``."""
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    return S - np.swapaxes(S, 1, 2)


def _hessian(f, size: int, step: float) -> np.ndarray:
    """Hessian (size, size) of a scalar function at 0 by central differences."""
    basis = np.eye(size) * step
    H = np.empty((size, size))
    for j in range(size):
        for k in range(j, size):
            value = (
                f(basis[j] + basis[k])
                - f(basis[j] - basis[k])
                - f(-basis[j] + basis[k])
                + f(-basis[j] - basis[k])
            ) / (4.0 * step * step)
            H[j, k] = H[k, j] = value
    return H
