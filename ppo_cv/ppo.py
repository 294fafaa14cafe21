"""The pose-only (PPO) two-view geometry of Cai, Wu, Zhang and Zhang, in pure numpy.

Equation numbers refer to "Equivalent Constraints for Two-View Geometry: Pose Solution/Pure
Rotation Identification and 3D Reconstruction". Conventions:

* ``x1``, ``x2`` are normalized image points ``K^-1 [u, v, 1]^T``, shape (N, 2) with the
  homogeneous 1 implied (or (N, 3) homogeneous): the paper's X = (x, y, 1) and X'. A point
  seen in both views obeys ``z2 X' = z1 R X + t`` (eq. 2), i.e. ``X2 = R X1 + t`` in camera
  coordinates, the convention of OpenCV.
* ``e_t`` is the unit translation direction; the scale of ``t`` is unobservable.

Nothing here does I/O or calls OpenCV. Every function is vectorised over the points and works
on coordinate columns, so that its cost is a few passes over the data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import (
    as_camera_matrix,
    as_essential,
    as_finite_array,
    as_finite_rows,
    as_matrix3,
    as_points,
    as_vector3,
    shown,
)

__all__ = [
    "W1",
    "W2",
    "DEFAULT_PRI_THRESHOLD",
    "Candidates",
    "Selection",
    "decompose_essential",
    "candidates_from_svd",
    "same_side_scores",
    "intersection_scores",
    "frame_maps",
    "frame_scores",
    "select_pose",
    "pure_rotation_indicator",
    "m3_indicator",
    "analytic_depths",
    "analytic_points",
    "normalize",
    "rotation_from_rays",
]

W1 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
W2 = W1.T
_W1T = np.ascontiguousarray(W1.T)

DEFAULT_PRI_THRESHOLD = 0.015
"""The paper's delta_pri (Section 5.3), in normalized image coordinates."""

_BLOCK = 8192


@dataclass(frozen=True)
class Candidates:
    """The two rotations and the translation axis of an essential matrix (Table II, steps 2-3).

    The four poses are ``(R1 | +t)``, ``(R2 | +t)``, ``(R1 | -t)`` and ``(R2 | -t)``.

    Attributes
    ----------
    R1, R2 : ndarray, shape (3, 3)
        ``U W1^T V^T`` and ``U W2^T V^T`` with ``det(U V^T) = +1`` (eq. 57, Table I).
    t : ndarray, shape (3,)
        ``u_q3``, the unit left singular vector of the smallest singular value (eq. 62).
    singular_values : ndarray, shape (3,)
        Singular values of ``E / ||E||_F``; a valid essential matrix has ``(s, s, 0)``.
    U, Vt : ndarray, shape (3, 3)
        The SVD factors, signed so that ``det(U V^T) = +1``; ``t`` is the last column of ``U``.
    """

    R1: np.ndarray
    R2: np.ndarray
    t: np.ndarray
    singular_values: np.ndarray
    U: np.ndarray
    Vt: np.ndarray


@dataclass(frozen=True)
class Selection:
    """The pose picked by the PPO inequalities (Table II, step 4).

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation with the larger same-side support S1.
    t : ndarray, shape (3,)
        Unit translation with the larger intersection support S2.
    m1, m2 : ndarray, shape (N,)
        Same-side scores ``M1(R)`` (eq. 70) and intersection scores ``M2(t)`` (eq. 76) of the
        chosen pose for every point; a point satisfies the PPO inequalities when both are
        positive.
    support_R, support_R_rejected : int
        ``S1`` of the chosen and of the rejected rotation, over the used points.
    support_t, support_t_rejected : int
        ``S2`` of the chosen and of the rejected translation sign, over the used points.
    """

    R: np.ndarray
    t: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    support_R: int
    support_R_rejected: int
    support_t: int
    support_t_rejected: int


def normalize(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pixel points to normalized image points, ``K^-1 [u, v, 1]^T`` without the 1.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    K : ndarray, shape (3, 3)
        Intrinsics, last row (0, 0, 1).

    Returns
    -------
    ndarray, shape (N, 2)
    """
    return _normalize(as_points(points, "points"), as_camera_matrix(K, "K"))


def _normalize(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    """:func:`normalize` of checked points (N, 2) and camera matrix (3, 3)."""
    return (np.linalg.inv(K)[:2] @ _planar(points)).T


def _checked_rays(x: Any, name: str) -> np.ndarray:
    """Normalized points (N, 2), or homogeneous (N, 3), checked, as stacked rays (3, N)."""
    return _planar(as_finite_rows(x, name, 2 if np.shape(x)[-1:] == (2,) else 3))


def _checked_ray_pair(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Matched rays (3, N) of one length (:func:`_checked_rays`); ValueError otherwise."""
    X1, X2 = _checked_rays(x1, "x1"), _checked_rays(x2, "x2")
    if X1.shape != X2.shape:
        raise ValueError(
            f"x1 and x2 must have the same length, got {X1.shape[1]} and {X2.shape[1]}"
        )
    return X1, X2


def _checked_pose_rays(
    x1: Any, x2: Any, R: Any, t: Any = (0.0, 0.0, 1.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(X1, X2, R, e_t)``: matched rays (3, N) of one length, a finite 3x3 ``R`` and the unit
    direction of a finite nonzero ``t`` (3 numbers); ValueError or TypeError naming the
    argument otherwise."""
    X1, X2 = _checked_ray_pair(x1, x2)
    R = as_matrix3(R, "R")
    t = as_vector3(t, "t")
    if not t.any():
        raise ValueError("t is zero: it has no direction")
    return X1, X2, R, _unit(t)


def _planar(x: np.ndarray) -> np.ndarray:
    """Points (N, 2), or homogeneous (N, 3), as the paper's stacked rays ``(X_1 ... X_N)``."""
    if x.shape[1] == 3:
        return (x / x[:, 2:]).T
    rays = np.ones((3, x.shape[0]))
    rays[:2] = x.T
    return rays


def _dot(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Column-wise dot products of two (3, N) arrays: shape (N,)."""
    return np.einsum("ij,ij->j", A, B)


def _cross(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Column-wise cross products of two (3, N) arrays: shape (3, N)."""
    return np.stack(
        [A[1] * B[2] - A[2] * B[1], A[2] * B[0] - A[0] * B[2], A[0] * B[1] - A[1] * B[0]]
    )


def _det3(M: np.ndarray) -> float:
    (a, b, c), (d, e, f), (g, h, i) = M.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def _unit(t: np.ndarray) -> np.ndarray:
    return t / np.sqrt(t @ t)


def decompose_essential(E: np.ndarray) -> Candidates:
    """Split an essential matrix into its candidate poses (Section 3.2, Table I, Table II).

    ``E = U diag(s1, s2, s3) V^T``. The sign of ``V`` is fixed so that ``det(U V^T) = 1``,
    the row of Table I where ``W1`` and ``W2`` give proper rotations. Any scale or sign of
    ``E`` gives the same candidates; a noisy or rank-deficient ``E`` is handled the same way,
    ``t`` being the singular vector of its smallest singular value.

    Parameters
    ----------
    E : array_like, shape (3, 3)
        Essential matrix, any nonzero scale.

    Returns
    -------
    Candidates
    """
    as_essential(E, check_spread=False)  # a finite, nonzero 3x3 matrix, decomposed unscaled
    U, s, Vt = np.linalg.svd(np.asarray(E, dtype=np.float64))
    return _candidates_from_svd(U, s, Vt)


def candidates_from_svd(U: np.ndarray, s: np.ndarray, Vt: np.ndarray) -> Candidates:
    """:func:`decompose_essential` from a precomputed SVD ``E = U diag(s) Vt``.

    Any SVD routine will do (signs of singular vectors are arbitrary and fixed here). ``U``
    and ``Vt`` must be orthogonal 3x3 matrices, ``s`` three singular values >= 0 not all zero;
    ValueError or TypeError naming the argument otherwise.
    """
    _require_orthogonal(U, "U")
    _require_orthogonal(Vt, "Vt")
    values = as_finite_array(s, "s")
    if values.size != 3 or (values < 0).any() or not values.any():
        raise ValueError(f"s must be three singular values >= 0, not all zero, got {shown(s)}")
    return _candidates_from_svd(np.asarray(U, float), values, np.asarray(Vt, float))


def _require_orthogonal(matrix: Any, name: str) -> None:
    """ValueError or TypeError naming ``name`` unless ``matrix`` is an orthogonal 3x3 matrix,
    a factor of an SVD."""
    orthogonal = as_matrix3(matrix, name)
    if not np.allclose(orthogonal @ orthogonal.T, np.eye(3), atol=1e-6):
        raise ValueError(f"{name} must be an orthogonal 3x3 matrix (of an SVD)")


def _candidates_from_svd(U: np.ndarray, s: np.ndarray, Vt: np.ndarray) -> Candidates:
    Vt = _proper_svd(U, Vt)
    s = np.ravel(s)
    return Candidates(
        R1=U @ W1.T @ Vt,
        R2=U @ W2.T @ Vt,
        t=U[:, 2].copy(),
        singular_values=s / np.sqrt(s @ s),
        U=U,
        Vt=Vt,
    )


def _proper_svd(U: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """``Vt`` with its sign fixed so that ``det(U Vt) = +1`` (Table I), making ``U W Vt`` a
    rotation. Flipping ``U`` instead would only flip ``t``, which both signs cover anyway."""
    return -Vt if _det3(U) * _det3(Vt) < 0 else Vt


def same_side_scores(x1: np.ndarray, x2: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Same-side scores ``m1 = (e_t x R X) . (e_t x X')`` for all points (eq. 65-66, 70).

    The paper writes ``m1 = X'^T Q Q^T R X``; for an exact essential matrix
    ``Q Q^T = ||a||^2 [e_t]x^T [e_t]x`` (eq. 66), so this is the same inequality with the
    singular values of a noisy ``Q`` taken out. It is positive when both projection rays lie on
    the same side of the baseline, and ``m1(R1) = -m1(R2)`` (eq. 68).

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2)
        Normalized image points (homogeneous (N, 3) is accepted too).
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Translation direction (any length).

    Returns
    -------
    ndarray, shape (N,)
    """
    X1, X2, R, e = _checked_pose_rays(x1, x2, R, t)
    return _dot(X2, (R - e[:, None] * (e @ R)) @ X1)  # [e]x^T [e]x = I - e e^T


def intersection_scores(x1: np.ndarray, x2: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Intersection scores ``m2 = ||X|| X'.e_t - ||X'|| (R X).e_t`` for all points (eq. 73, 76).

    ``m2 = ||X|| ||X'|| (cos theta1 - cos theta2)``: positive when the second ray leans further
    towards the translation than the rotated first ray, as it must for the rays to intersect
    in front of both cameras (eq. 71-72). For the candidates of one essential matrix it does not
    depend on which rotation is used (eq. 74-75), and ``m2(-t) = -m2(t)``.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2)
        Normalized image points (homogeneous (N, 3) is accepted too).
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)

    Returns
    -------
    ndarray, shape (N,)
    """
    X1, X2, R, e = _checked_pose_rays(x1, x2, R, t)
    return np.sqrt(_dot(X1, X1)) * (e @ X2) - np.sqrt(_dot(X2, X2)) * ((e @ R) @ X1)


def _vote(scores: np.ndarray, used: np.ndarray | None) -> tuple[bool, np.ndarray, int, int]:
    """Table II step 4 for one score: whether ``+scores`` wins the count of positive entries
    over the used points, the mask of the points on the winning side, and the two counts.

    Ties (e.g. all scores zero) go to the larger sum, then to ``+``.
    """
    positive = scores > 0.0  # a float zero compares faster than 0
    if used is None:
        n_pos = int(np.count_nonzero(positive))
        n_neg = int(np.count_nonzero(scores)) - n_pos
    else:
        n_pos = int(np.count_nonzero(positive & used))
        n_neg = int(np.count_nonzero(scores[used])) - n_pos
    keep = n_pos > n_neg or (
        n_pos == n_neg and (scores if used is None else scores[used]).sum() >= 0
    )
    return keep, positive if keep else scores < 0.0, n_pos, n_neg


def select_pose(
    E: np.ndarray, x1: np.ndarray, x2: np.ndarray, used: np.ndarray | None = None
) -> Selection:
    """Pick the right pose among the four candidates of ``E`` (Table II).

    ``R`` maximises the count S1 of positive same-side scores (eq. 70) and ``t`` the count S2 of
    positive intersection scores (eq. 76). Because ``m1(R2) = -m1(R1)`` and
    ``m2(-t) = -m2(t)``, one evaluation of each score decides between two candidates, and no 3D
    point is reconstructed. The rotation is right even for a pure rotation (Proposition 7),
    where the translation is meaningless; see :func:`pure_rotation_indicator`.

    Parameters
    ----------
    E : ndarray, shape (3, 3)
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalized points.
    used : ndarray of bool, shape (N,), optional
        The points that vote (e.g. RANSAC inliers); scores are returned for all points.

    Returns
    -------
    Selection

    Examples
    --------
    >>> import numpy as np
    >>> from ppo_cv import ppo
    >>> rng = np.random.default_rng(1)
    >>> X = rng.uniform([-1, -1, 4], [1, 1, 6], (20, 3))  # points in camera 1
    >>> t = np.array([0.5, 0.0, 0.0])                       # camera 2 = camera 1 moved, R = I
    >>> x1, x2 = X[:, :2] / X[:, 2:], (X + t)[:, :2] / (X + t)[:, 2:]
    >>> E = np.array([[0, 0, 0], [0, 0, -0.5], [0, 0.5, 0]])  # [t]x R
    >>> sel = ppo.select_pose(E, x1, x2)
    >>> np.allclose(sel.R, np.eye(3)), sel.t.round(6).tolist(), sel.support_R, sel.support_t
    (True, [1.0, 0.0, 0.0], 20, 20)
    """
    X1, X2 = _checked_ray_pair(x1, x2)
    if used is not None:
        used = np.asarray(used)
        if used.dtype != bool or used.shape != (X1.shape[1],):
            raise TypeError(f"used must be a bool array of shape ({X1.shape[1]},), got "
                            f"{used.dtype} of shape {used.shape}")  # fmt: skip
    return _select(decompose_essential(E), X1, X2, used)


def frame_scores(F: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scores ``m1(R1)`` and ``m2(+t)`` for all points, from the rays in the frame of ``U``.

    With ``E = U diag(s) V^T``, ``det(U V^T) = 1``, ``t = u3`` and ``R1 = U W1^T V^T``, let
    ``A = U^T R1 X = W1^T V^T X`` and ``B = U^T X'``. In this frame ``t = (0, 0, 1)`` and
    ``U^T (I - t t^T) U = diag(1, 1, 0)``, so the same-side score (eq. 66, 70) and the
    intersection score (eq. 73, 76) reduce to

    ``m1 = a_x b_x + a_y b_y``  and  ``m2 = ||A|| b_z - ||B|| a_z``,

    the numbers :func:`same_side_scores` and :func:`intersection_scores` give for ``(R1, u3)``.
    ``m1(R2) = -m1`` (eq. 68) and ``m2(-t) = -m2``; ``a_z`` is the same for ``R1`` and ``R2``
    (eq. 74-75).

    Parameters
    ----------
    F : ndarray, shape (2, 3, 3)
        The maps of view 1 and view 2 into the frame: ``W1^T V^T`` and ``U^T`` for rays, or
        ``W1^T V^T K1^-1`` and ``U^T K2^-1`` for homogeneous pixels.
    points : ndarray, shape (2, 3, N)
        Rays or homogeneous pixels of view 1 and view 2, by coordinate rows.

    Returns
    -------
    m1, m2 : ndarray, shape (N,)
    """
    F, points = as_finite_array(F, "F"), as_finite_array(points, "points")
    if F.shape != (2, 3, 3):
        raise ValueError(f"F must have shape (2, 3, 3), got {F.shape}")
    if points.ndim != 3 or points.shape[:2] != (2, 3):
        raise ValueError(f"points must have shape (2, 3, N), got {points.shape}")
    return _blocked_frame_scores(F, points)


def _blocked_frame_scores(F: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = points.shape[2]
    if n <= _BLOCK:
        return _frame_scores(F @ points)
    m1, m2 = np.empty(n), np.empty(n)
    for start in range(0, n, _BLOCK):  # blocks that stay in cache: several times faster
        block = slice(start, start + _BLOCK)
        m1[block], m2[block] = _frame_scores(F @ points[:, :, block])
    return m1, m2


def frame_maps(U: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """The maps ``W1^T V^T`` and ``U^T`` of rays of view 1 and view 2 into the frame of ``U``.

    ``U``, ``Vt`` as in :attr:`Candidates.U`, :attr:`Candidates.Vt` (``det(U Vt) = +1``).
    ``U @ maps[0]`` is ``R1``. Returns shape (2, 3, 3), the ``F`` of :func:`frame_scores`.
    """
    _require_orthogonal(U, "U")
    _require_orthogonal(Vt, "Vt")
    return _frame_maps(np.asarray(U, float), np.asarray(Vt, float))


def _frame_maps(U: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    return np.array((_W1T @ Vt, U.T))


def _frame_scores(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    products = Y[0] * Y[1]
    norms = np.sqrt((Y * Y).sum(axis=1))
    return products[0] + products[1], norms[0] * Y[1, 2] - norms[1] * Y[0, 2]


def _select(cand: Candidates, X1: np.ndarray, X2: np.ndarray, used: np.ndarray | None) -> Selection:
    m1, m2 = _blocked_frame_scores(_frame_maps(cand.U, cand.Vt), np.array((X1, X2)))
    keep_R1, _, s1_R1, s1_R2 = _vote(m1, used)
    keep_t, _, s2_plus, s2_minus = _vote(m2, used)
    return Selection(
        R=cand.R1 if keep_R1 else cand.R2,
        t=cand.t if keep_t else -cand.t,
        m1=m1 if keep_R1 else -m1,
        m2=m2 if keep_t else -m2,
        support_R=s1_R1 if keep_R1 else s1_R2,
        support_R_rejected=s1_R2 if keep_R1 else s1_R1,
        support_t=s2_plus if keep_t else s2_minus,
        support_t_rejected=s2_minus if keep_t else s2_plus,
    )


def pure_rotation_indicator(m2: np.ndarray) -> float:
    """PRI = mean ``|M2(t)|`` (eq. 84); the motion is a pure rotation if PRI < delta (eq. 85).

    By Proposition 8, ``m2 = 0`` exactly when the two rays are parallel, which holds for every
    point under a pure rotation. ``|m2|`` does not depend on the sign of ``t``.

    Parameters
    ----------
    m2 : ndarray, shape (N,)
        Intersection scores of the points to average over (typically the used points).

    Returns
    -------
    float
        NaN for an empty input.
    """
    if np.ndim(m2) != 1:
        raise ValueError(f"m2 must be scores of shape (N,), got shape {np.shape(m2)}")
    m2 = as_finite_rows(np.reshape(m2, (-1, 1)), "m2", 1)
    return float(np.mean(np.abs(m2))) if m2.size else float("nan")


def m3_indicator(x1: np.ndarray, x2: np.ndarray, R: np.ndarray) -> float:
    """M3 = mean ``||X' x R X|| / (||X'|| ||X||)`` (eq. 78): mean sine of the parallax angle.

    The paper's alternative pure-rotation test, kept for comparison with PRI.
    """
    X1, X2, R, _ = _checked_pose_rays(x1, x2, R)
    if X1.shape[1] == 0:
        return float("nan")
    sin_parallax = np.sqrt(_dot(*(2 * [_cross(X2, R @ X1)])) / (_dot(X1, X1) * _dot(X2, X2)))
    return float(np.mean(sin_parallax))


def analytic_depths(
    x1: np.ndarray, x2: np.ndarray, R: np.ndarray, t: np.ndarray, rtol: float = 1e-12
) -> tuple[np.ndarray, np.ndarray]:
    """Depths of each point in both views from the pose alone (Proposition 3, eq. 36).

    ``z1 / ||t|| = ||e_t x X'|| / ||X' x R X||`` and ``z2 / ||t|| = ||e_t x R X|| / ||X' x R X||``:
    the law of sines in the triangle of the two centres and the point. Depths are returned in
    units of the baseline ``||t||``.

    Where the rays are parallel (``||X' x R X||`` at most ``rtol`` times ``||X|| ||X'||``: a
    point at infinity, on the baseline, or every point of a pure rotation, Propositions 4-5)
    the depth is ``+inf``.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
    rtol : float
        Relative size below which the parallax is taken as zero.

    Returns
    -------
    z1, z2 : ndarray, shape (N,)
        Depths (third coordinate) in camera 1 and camera 2.
    """
    X1, X2, R, e = _checked_pose_rays(x1, x2, R, t)
    z1, z2, _ = _depths(X1, X2, R, e, rtol)
    return z1, z2


def _depths(
    X1: np.ndarray, X2: np.ndarray, R: np.ndarray, e: np.ndarray, rtol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 36 on stacked rays; also returns the mask of finite depths."""
    RX1 = R @ X1
    parallax = np.sqrt(_dot(*(2 * [_cross(X2, RX1)])))
    n1sq, n2sq = _dot(X1, X1), _dot(X2, X2)
    e_cross_x2 = np.sqrt(np.maximum(n2sq - (e @ X2) ** 2, 0.0))
    e_cross_rx1 = np.sqrt(np.maximum(n1sq - (e @ RX1) ** 2, 0.0))
    finite = parallax > rtol * np.sqrt(n1sq * n2sq)
    inverse = np.divide(1.0, parallax, out=np.zeros_like(parallax), where=finite)
    z1 = np.where(finite, e_cross_x2 * inverse, np.inf)
    z2 = np.where(finite, e_cross_rx1 * inverse, np.inf)
    return z1, z2, finite


def analytic_points(
    x1: np.ndarray, x2: np.ndarray, R: np.ndarray, t: np.ndarray, rtol: float = 1e-12
) -> np.ndarray:
    """3D points in camera-1 coordinates from the pose alone, baseline ``||t|| = 1`` (eq. 36).

    Eq. 36 gives one point on each ray: ``P1 = z1 X`` and, from view 2,
    ``P2 = R^T (z2 X' - e_t)``. With noise they differ; the paper averages them. Here they are
    weighted by the inverse square of their depths,
    ``P = (z2^2 P1 + z1^2 P2) / (z1^2 + z2^2)``, which to first order minimises the sum of the
    squared angular reprojection errors in the two views (moving a point by ``d`` across a ray at
    depth ``z`` costs an angle ``d / z``). For equal depths this is the paper's average.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
    rtol : float
        As in :func:`analytic_depths`.

    Returns
    -------
    ndarray, shape (N, 3)
        NaN rows where the depth is infinite.
    """
    X1, X2, R, e = _checked_pose_rays(x1, x2, R, t)
    return _points(X1, X2, R, e, rtol).T


def _points(
    X1: np.ndarray, X2: np.ndarray, R: np.ndarray, e: np.ndarray, rtol: float
) -> np.ndarray:
    """Weighted eq. 36 points on stacked rays, shape (3, N)."""
    z1, z2, finite = _depths(X1, X2, R, e, rtol)
    z1, z2 = np.where(finite, z1, np.nan), np.where(finite, z2, np.nan)
    p1 = z1 * X1
    p2 = R.T @ (z2 * X2 - e[:, None])
    w1, w2 = z2 * z2, z1 * z1
    return (w1 * p1 + w2 * p2) / (w1 + w2)


def rotation_from_rays(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """The rotation that best aligns the rays of a pure rotation, ``X' ~ R X``.

    Not from the paper: once PRI has identified a pure rotation (eq. 85) every pair obeys
    ``X' = lambda R X`` (eq. 3 with ``t = 0``), so ``R`` is the least-squares fit of the unit
    rays, ``argmin sum ||b2 - R b1||^2`` (Wahba's problem), solved in closed form from the SVD of
    ``sum b2 b1^T`` with the determinant forced to +1. It uses every point, unlike the
    rotation of an essential matrix fitted to noise.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2)
        Normalized image points (homogeneous (N, 3) is accepted too), N >= 2.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    X1, X2, _, _ = _checked_pose_rays(x1, x2, np.eye(3))
    return _rotation_from_rays(X1, X2)


def _rotation_from_rays(X1: np.ndarray, X2: np.ndarray) -> np.ndarray:
    B1 = X1 / np.sqrt(_dot(X1, X1))
    B2 = X2 / np.sqrt(_dot(X2, X2))
    U, _, Vt = np.linalg.svd(B2 @ B1.T)
    D = np.diag([1.0, 1.0, np.sign(_det3(U) * _det3(Vt))])
    return U @ D @ Vt
