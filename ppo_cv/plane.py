"""Pose of a plane from its calibrated homography, chosen by the PPO inequalities (pure numpy).

A plane ``n^T X1 = d`` (unit normal ``n`` in camera 1, distance ``d > 0``) seen by two cameras
with ``X2 = R X1 + t`` maps the normalized points of view 1 to those of view 2 by

``X2 = (R + t n^T / d) X1``,  i.e.  ``x2 ~ Hn x1``  with  ``Hn = K2^-1 H K1 = R + T n^T``,

``T = t / d``. Scaled so that its middle singular value is 1 and signed so that
``x2^T Hn x1 > 0`` (points in front of both cameras), ``Hn`` is exactly ``R + T n^T``
(:func:`normalize_homography`). Its decomposition (:func:`decompose_homography`) has four
candidates ``(Ra, Ta, na)``, ``(Ra, -Ta, -na)``, ``(Rb, Tb, nb)``, ``(Rb, -Tb, -nb)``.

The right one is chosen as the paper chooses among the four candidates of an essential matrix:
each candidate is a pose, so the same-side score ``M1`` (eq. 66-70) and the intersection score
``M2`` (eq. 73-76) of :mod:`ppo_cv.ppo` apply to it unchanged, and by the paper's equivalence
``M1 > 0`` and ``M2 > 0`` hold exactly for the points that lie in front of both cameras.
A candidate with the flipped pair ``(-T, -n)`` flips every ``M2`` (``m2(-t) = -m2(t)``): the
plane behind camera 1. The other rotation generally puts part of the points behind a camera or
on the wrong side of the baseline. :func:`select_plane_pose` keeps the candidate with the most
points satisfying both inequalities. When the second rotation also keeps every point in front of
both cameras, the images of a plane cannot tell the two poses apart (the two-fold ambiguity of a
homography); the tie is then broken by the matches off the plane when there are any (the
candidate whose ``E = [t]x R`` explains more of them), else by the prior that the plane faces the
cameras (:func:`frontality`): the false interpretation exchanges the directions of ``t`` and
``n`` and so sees the plane obliquely.

This extends the paper, whose inequalities are derived for the candidates of an essential
matrix, to homographies; see ``docs/homography.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import ppo
from .checks import (
    as_finite_array,
    as_finite_rows,
    as_matrix3,
    as_number,
    as_real_array,
    as_rotation,
    as_vector3,
    require_instance,
)
from .lsq import (
    _forward_jacobian,
    _gauss_newton_covariance,
    _huber_weights,
    _levenberg_marquardt,
    _rotation_increment,
    tangent_basis,
)
from .rotation import FOCAL_PRIOR

__all__ = [
    "K1_SIGNIFICANCE",
    "SUPPORT_SIGNIFICANCE",
    "held_k1_deviation",
    "rms_rotation_angle_deg",
    "MIN_OFF_PLANE",
    "HomographyCandidates",
    "PlanarPose",
    "normalize_homography",
    "homography_from_pose",
    "decompose_homography",
    "candidate_supports",
    "frontality",
    "select_plane_pose",
    "support_ties",
    "planar_pose",
    "RefinedPlanarPose",
    "refine_planar_pose",
    "undistort_division",
]

_DEGENERATE = 1e-12

MIN_OFF_PLANE = 8
"""Fewest off-plane matches that may break the two-fold ambiguity (:func:`select_plane_pose`)."""

SUPPORT_SIGNIFICANCE = 3.0
"""A candidate's support leads another's only beyond this many deviations of a sign test on the
matches one keeps in front of both cameras and the other does not (:func:`support_ties`)."""

K1_SIGNIFICANCE = 3.0
"""A fitted division coefficient is kept only beyond this many standard deviations
(:func:`refine_planar_pose`); below, ``k1`` and the pose trade off within the noise."""


@dataclass(frozen=True)
class HomographyCandidates:
    """The four candidate poses ``Hn = R_i + T_i n_i^T`` of a calibrated homography.

    Candidates 0 and 1 share a rotation, as do 2 and 3; ``(T, n)`` of 1 and 3 are those of 0
    and 2 negated.

    Attributes
    ----------
    R : ndarray, shape (4, 3, 3)
        Rotations, ``X2 = R X1 + t``.
    T : ndarray, shape (4, 3)
        Translations divided by the plane distance, ``t / d``; zero for a pure rotation.
    n : ndarray, shape (4, 3)
        Unit plane normals in camera 1, the plane being ``n^T X1 = d``.
    H : ndarray, shape (3, 3)
        The normalized homography (:func:`normalize_homography`) they decompose.
    """

    R: np.ndarray
    T: np.ndarray
    n: np.ndarray
    H: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Unit translation directions, shape (4, 3) (zero rows for a pure rotation)."""
        norms = np.linalg.norm(self.T, axis=1, keepdims=True)
        return np.divide(self.T, norms, out=np.zeros_like(self.T), where=norms > 0)


@dataclass(frozen=True)
class PlanarPose:
    """Pose of a plane chosen among the candidates of its homography by the PPO inequalities.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Unit translation direction; zero when ``H`` is a rotation (then ``n`` is arbitrary
        and every support 0: a pure rotation, for the rotation-only model to report).
    n : ndarray, shape (3,)
        Unit normal of the plane in camera 1, ``n^T X1 = d`` with ``d > 0``.
    distance : float
        ``d`` in units of the baseline ``||t||`` (``1 / ||T||``); ``inf`` for a pure rotation.
    candidate : int
        Index of the chosen candidate in ``candidates``.
    supports : ndarray of int, shape (4,)
        Points (among the used ones) satisfying ``M1 > 0`` and ``M2 > 0`` for each candidate.
    ambiguous : bool
        Another candidate's support is not significantly below the chosen one's
        (:func:`support_ties`): both poses keep the points in front of both cameras alike (the
        two-fold ambiguity), and the tie-break decided.
    inliers : ndarray of bool, shape (N,)
        The used points satisfying both inequalities for the chosen pose.
    m1, m2 : ndarray, shape (N,)
        Same-side (eq. 70) and intersection (eq. 76) scores of the chosen pose, all points.
    candidates : HomographyCandidates
        The decomposition the choice was made from.
    """

    R: np.ndarray
    t: np.ndarray
    n: np.ndarray
    distance: float
    candidate: int
    supports: np.ndarray
    ambiguous: bool
    inliers: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    candidates: HomographyCandidates

    @property
    def support(self) -> int:
        """Points satisfying both inequalities for the chosen pose."""
        return int(self.supports[self.candidate])


def _homogeneous(x: np.ndarray) -> np.ndarray:
    """(N, 2) or (N, 3) normalized points as homogeneous rows (N, 3) of float64."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (N, 2) or (N, 3), got {x.shape}")
    return np.column_stack([x, np.ones(len(x))]) if x.shape[1] == 2 else x


def normalize_homography(
    H: np.ndarray, x1: np.ndarray | None = None, x2: np.ndarray | None = None
) -> np.ndarray:
    """Scale a calibrated homography to ``R + T n^T``: middle singular value 1, positive depths.

    For ``Hn = R + T n^T`` the middle singular value of ``Hn`` is 1 (Faugeras and Lustman), so
    dividing any multiple of it by its middle singular value leaves ``+-Hn``. The sign is the
    one for which ``x2^T Hn x1 > 0`` for most matches: ``z2 x2 = z1 Hn x1`` with positive depths
    ``z1``, ``z2`` for a point in front of both cameras.

    Parameters
    ----------
    H : array_like, shape (3, 3)
        Homography between normalized points, ``x2 ~ H x1`` (``K2^-1 H_pixels K1``).
    x1, x2 : ndarray, shape (N, 2) or (N, 3), optional
        Matches that fix the sign (e.g. the inliers); without them ``det(Hn) > 0`` is used, which
        is right unless the plane passes between the two centres.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    H = as_matrix3(H, "H")
    s = np.linalg.svd(H, compute_uv=False)
    if not s[1] > 0:
        raise ValueError("H has rank below 2: not a homography between two views")
    H = H / s[1]
    if x1 is None or x2 is None or len(x1) == 0:
        return H if np.linalg.det(H) > 0 else -H
    products = np.einsum("ij,ij->i", _homogeneous(x2), _homogeneous(x1) @ H.T)
    return H if np.count_nonzero(products > 0) >= np.count_nonzero(products < 0) else -H


def homography_from_pose(R: np.ndarray, t: np.ndarray, n: np.ndarray, d: float) -> np.ndarray:
    """``Hn = R + t n^T / d``, the homography of the plane ``n^T X1 = d`` (``x2 ~ Hn x1``): a
    rotation ``R``, three finite numbers ``t``, a normal ``n`` not zero and a finite distance
    ``d`` not zero; ValueError or TypeError naming the argument otherwise."""
    R, t, n = as_rotation(R, "R"), as_vector3(t, "t"), as_vector3(n, "n")
    distance = as_number(d, "d")
    if not n.any():
        raise ValueError("n is zero: a plane needs a normal")
    if not (math.isfinite(distance) and distance != 0.0):
        raise ValueError(f"d must be a finite distance other than 0, got {distance}")
    return R + np.outer(t, n) / distance


def decompose_homography(H: np.ndarray) -> HomographyCandidates:
    """The four candidate poses of a normalized calibrated homography, in closed form.

    The method of Faugeras and Lustman in the form of Ma, Soatto, Kosecka and Sastry (An
    Invitation to 3-D Vision, Section 5.3): with ``Hn^T Hn = V diag(s1^2, 1, s3^2) V^T``,
    ``det V = 1``, the vectors ``v2`` and
    ``u+- = (sqrt(1 - s3^2) v1 +- sqrt(s1^2 - 1) v3) / sqrt(s1^2 - s3^2)`` keep their length
    under ``Hn``; with ``U = [v2, u, v2 x u]`` and ``W = [Hn v2, Hn u, Hn v2 x Hn u]``,
    ``R = W U^T``, ``n = v2 x u`` and ``T = (Hn - R) n``. Both bases are orthonormal by
    construction, so ``R`` is a rotation even for a noisy ``Hn``. Normals are signed to face
    camera 1 (``n_z > 0``) in candidates 0 and 2; 1 and 3 negate ``(T, n)``.

    For ``s1 = s3`` (a rotation, ``T = 0``) every candidate is ``(Hn, 0, n)``.

    Parameters
    ----------
    H : array_like, shape (3, 3)
        Normalized homography (:func:`normalize_homography`).

    Returns
    -------
    HomographyCandidates
    """
    H = as_matrix3(H, "H")
    _, s, Vt = np.linalg.svd(H)  # Hn^T Hn = V diag(s^2) V^T
    if not s[1] > 0:
        raise ValueError("H has rank below 2: not a homography between two views")
    V = Vt.T * np.sign(np.linalg.det(Vt))
    s1, s3 = s[0] ** 2 / s[1] ** 2, s[2] ** 2 / s[1] ** 2  # squared, middle value taken as 1
    v1, v2, v3 = V.T
    spread = s1 - s3
    if spread > _DEGENERATE:
        a, b = np.sqrt(max(1.0 - s3, 0.0) / spread), np.sqrt(max(s1 - 1.0, 0.0) / spread)
    else:
        a, b = 1.0, 0.0
    Hn = H / s[1]
    u = np.array([a * v1 + b * v3, a * v1 - b * v3])  # (2, 3)
    U = np.stack([np.broadcast_to(v2, (2, 3)), u, np.cross(v2, u)], axis=2)  # columns
    Hv2, Hu = Hn @ v2, u @ Hn.T
    W = np.stack([np.broadcast_to(Hv2, (2, 3)), Hu, np.cross(Hv2, Hu)], axis=2)
    R = W @ np.swapaxes(U, 1, 2)
    n = U[:, :, 2]
    n = n * np.where(n[:, 2:] < 0, -1.0, 1.0)
    T = np.einsum("kij,kj->ki", Hn - R, n) if spread > _DEGENERATE else np.zeros((2, 3))
    order = [0, 0, 1, 1]
    sign = np.array([1.0, -1.0, 1.0, -1.0])[:, None]
    return HomographyCandidates(R=R[order], T=sign * T[order], n=sign * n[order], H=Hn)


def candidate_supports(
    candidates: HomographyCandidates,
    x1: np.ndarray,
    x2: np.ndarray,
    used: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scores ``M1`` (eq. 70) and ``M2`` (eq. 76) of every candidate and their supports.

    Parameters
    ----------
    candidates : HomographyCandidates
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalized points.
    used : ndarray of bool, shape (N,), optional
        Points that count; all by default.

    Returns
    -------
    m1, m2 : ndarray, shape (4, N)
        Scores of each candidate for all points.
    supports : ndarray of int, shape (4,)
        Used points with ``M1 > 0`` and ``M2 > 0``. A pure-rotation candidate (``T = 0``) has
        no translation to score and support 0.
    """
    X1, X2 = _homogeneous(x1), _homogeneous(x2)
    m1 = np.zeros((4, len(X1)))
    m2 = np.zeros((4, len(X1)))
    for k, (R, t) in enumerate(zip(candidates.R, candidates.t, strict=True)):  # 4, not N
        if t @ t > 0:
            m1[k] = ppo.same_side_scores(X1, X2, R, t)
            m2[k] = ppo.intersection_scores(X1, X2, R, t)
    both = (m1 > 0) & (m2 > 0)
    if used is not None:
        both &= np.asarray(used, dtype=bool)[None, :]
    return m1, m2, np.count_nonzero(both, axis=1)


def _epipolar_support(
    candidates: HomographyCandidates, X1: np.ndarray, X2: np.ndarray, threshold: float
) -> np.ndarray:
    """Matches within ``threshold`` (Sampson, normalized units) of each ``E = [t]x R``."""
    from .robust import _essential_from_pose, _sampson_errors

    counts = [
        np.count_nonzero(_sampson_errors(_essential_from_pose(R, t), X1, X2) < threshold)
        if t @ t > 0
        else 0
        for R, t in zip(candidates.R, candidates.t, strict=True)
    ]
    return np.asarray(counts)


def _significant(counts: np.ndarray, tied: np.ndarray) -> np.ndarray:
    """``counts`` if the best of the tied candidates beats the next clearly, else zeros.

    Clearly: at least ``MIN_OFF_PLANE`` matches and a lead above three standard deviations of
    a count, ``3 sqrt(a + b)``. Mismatches fall near a wrong epipolar line by chance; matches
    off a real plane favour the true pose by far more.
    """
    top = np.sort(counts[tied])[::-1]
    second = top[1] if len(top) > 1 else 0
    if top[0] >= MIN_OFF_PLANE and top[0] - second > 3.0 * np.sqrt(top[0] + second):
        return counts
    return np.zeros_like(counts)


def support_ties(in_front: np.ndarray) -> np.ndarray:
    """Candidates whose support the largest one does not exceed significantly, shape (K,) bool.

    ``in_front`` (K, N) marks the matches each candidate keeps in front of both cameras. Two
    candidates differ only on the matches one keeps and the other does not; were neither the
    true pose, each such match would favour either alike, so the best candidate's lead
    ``a - b`` counts only beyond :data:`SUPPORT_SIGNIFICANCE` deviations ``sqrt(a + b)`` of
    that sign test (``a``, ``b`` the matches only the best, only the other keeps).

    >>> in_front = np.array([[1, 1, 1, 1, 1, 1, 1, 1, 1, 1], [1, 1, 1, 1, 1, 1, 1, 1, 1, 0],
    ...                      [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]], dtype=bool)
    >>> support_ties(in_front).tolist()
    [True, True, False]
    """
    flags = np.asarray(in_front)
    if flags.dtype != bool or flags.ndim != 2:
        raise TypeError(
            f"in_front must be a (K, N) array of bool, got {flags.dtype} of shape {flags.shape}"
        )
    return _support_ties(flags)


def _support_ties(in_front: np.ndarray) -> np.ndarray:
    in_front = np.asarray(in_front, dtype=bool)
    best = int(np.argmax(np.count_nonzero(in_front, axis=1)))
    only_best = np.count_nonzero(in_front[best] & ~in_front, axis=1)
    only_other = np.count_nonzero(in_front & ~in_front[best], axis=1)
    return only_best - only_other <= SUPPORT_SIGNIFICANCE * np.sqrt(only_best + only_other)


def frontality(candidates: HomographyCandidates) -> np.ndarray:
    """``n_z + (R n)_z`` of each candidate, shape (4,): how squarely the plane faces both cameras.

    The sum of the cosines of the angles between the plane normal and the optical axes of
    camera 1 (``n``) and camera 2 (``R n``): 2 for a plane seen head-on in both views. Not from
    the paper: the prior that breaks the two-fold ambiguity of a plane, whose two physical
    interpretations exchange the directions of ``t`` and ``n`` (to first order) and so tilt the
    plane of the false one towards the baseline, i.e. obliquely to both views.
    """
    require_instance(candidates, HomographyCandidates, "candidates")
    return candidates.n[:, 2] + np.einsum("kj,kij->ki", candidates.n, candidates.R)[:, 2]


def select_plane_pose(
    candidates: HomographyCandidates,
    x1: np.ndarray,
    x2: np.ndarray,
    used: np.ndarray | None = None,
    *,
    off_plane: np.ndarray | None = None,
    threshold: float | None = None,
) -> PlanarPose:
    """Choose the candidate with the most points satisfying ``M1 > 0`` and ``M2 > 0``.

    Rule, in order: (1) the largest support, the number of used points for which both the
    same-side score (eq. 70) and the intersection score (eq. 76) are positive, i.e. points in
    front of both cameras, where a lead counts only when significant (:func:`support_ties`);
    (2) among candidates tied on support (the two-fold ambiguity of a plane), the one whose
    essential matrix ``[t]x R`` has clearly the most ``off_plane`` matches within
    ``threshold`` (matches off the plane see the true epipolar geometry only; clearly: at
    least :data:`MIN_OFF_PLANE` and a lead of three standard deviations); (3) the plane facing
    both cameras more squarely (:func:`frontality`), a prior: the images of a plane cannot
    tell the two apart; (4) the larger support; (5) the lower index. A lead of a few matches
    in the support is the noise of the points near the cameras' horizons: on renders at a
    baseline of 0.005 of the depth, 784 against 782 of 811 matches (29 kept by one candidate
    only, 27 by the other) chose an interpretation 0.37 degree off over one 0.21 off.

    Parameters
    ----------
    candidates : HomographyCandidates
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalized points.
    used : ndarray of bool, shape (N,), optional
        Points that vote (the homography inliers); all by default.
    off_plane : ndarray of bool, shape (N,), optional
        Matches that may lie off the plane (e.g. the homography outliers), for the tie-break.
    threshold : float, optional
        Sampson error bound (normalized units) of the tie-break; required with ``off_plane``.

    Returns
    -------
    PlanarPose
    """
    X1, X2 = _homogeneous(x1), _homogeneous(x2)
    if X1.shape != X2.shape:
        raise ValueError(f"x1 and x2 must have the same shape, got {X1.shape} and {X2.shape}")
    used_mask = np.ones(len(X1), bool) if used is None else np.asarray(used, bool).reshape(-1)
    if used_mask.shape != (len(X1),):
        raise ValueError(f"used must have shape ({len(X1)},), got {used_mask.shape}")
    m1, m2, supports = candidate_supports(candidates, X1, X2, used_mask)
    tied = _support_ties((m1 > 0) & (m2 > 0) & used_mask[None, :])
    epipolar = np.zeros(4, int)
    if off_plane is not None and threshold is not None:
        off = np.asarray(off_plane, bool).reshape(-1)
        if off.shape != (len(X1),):
            raise ValueError(f"off_plane must have shape ({len(X1)},), got {off.shape}")
        if off.any():
            counts = _epipolar_support(candidates, X1[off], X2[off], float(threshold))
            epipolar = _significant(counts, tied)
    keys = list(zip(tied, epipolar, frontality(candidates), supports, -np.arange(4), strict=True))
    best = max(range(4), key=lambda k: keys[k])
    T = candidates.T[best]
    norm = float(np.linalg.norm(T))
    return PlanarPose(
        R=candidates.R[best],
        t=candidates.t[best],
        n=candidates.n[best],
        distance=1.0 / norm if norm > 0 else float("inf"),
        candidate=int(best),
        supports=supports,
        ambiguous=bool(np.count_nonzero(tied) > 1 and supports[best] > 0),
        inliers=used_mask & (m1[best] > 0) & (m2[best] > 0),
        m1=m1[best],
        m2=m2[best],
        candidates=candidates,
    )


def planar_pose(
    H: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray | None = None,
    threshold: float | None = None,
) -> PlanarPose:
    """Relative pose from a homography between normalized points, chosen by PPO.

    Normalizes ``H`` on the inliers (:func:`normalize_homography`), decomposes it
    (:func:`decompose_homography`) and chooses among the candidates with the PPO inequalities
    (:func:`select_plane_pose`), the homography outliers breaking a tie when ``threshold`` is
    given.

    Parameters
    ----------
    H : array_like, shape (3, 3)
        ``x2 ~ H x1`` on normalized points (``K2^-1 H_pixels K1``), any scale.
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalized points of all matches.
    inliers : ndarray of bool, shape (N,), optional
        Homography inliers; all matches by default.
    threshold : float, optional
        Epipolar (Sampson) bound in normalized units for the tie-break on the outliers, e.g.
        the RANSAC threshold in pixels divided by the focal length.

    Returns
    -------
    PlanarPose

    Examples
    --------
    >>> import numpy as np
    >>> from ppo_cv.plane import homography_from_pose, planar_pose
    >>> rng = np.random.default_rng(0)
    >>> X = np.column_stack([rng.uniform(-1, 1, (30, 2)), np.full(30, 4.0)])  # plane Z = 4
    >>> t = np.array([0.3, 0.0, 0.0])
    >>> x1, x2 = X / X[:, 2:], (X + t) / (X + t)[:, 2:]
    >>> pose = planar_pose(homography_from_pose(np.eye(3), t, [0, 0, 1], 4.0), x1, x2)
    >>> np.allclose(pose.R, np.eye(3)), np.allclose(pose.t, [1, 0, 0]), pose.n.round(6) + 0.0
    (True, True, array([0., 0., 1.]))
    """
    as_matrix3(H, "H")
    _require_matches(x1, x2)
    X1, X2 = _homogeneous(x1), _homogeneous(x2)
    used = None if inliers is None else np.asarray(inliers, bool).reshape(-1)
    if used is not None and used.shape != (len(X1),):
        raise ValueError(f"inliers must have shape ({len(X1)},), got {used.shape}")
    sign_from = slice(None) if used is None else used
    Hn = normalize_homography(H, X1[sign_from], X2[sign_from])
    off_plane = None if used is None else ~used
    return select_plane_pose(
        decompose_homography(Hn), X1, X2, used, off_plane=off_plane, threshold=threshold
    )


def _require_matches(x1: Any, x2: Any) -> None:
    """ValueError or TypeError naming ``x1`` or ``x2`` unless both are finite normalized points
    (N, 2) or (N, 3) of one length: a NaN match gave a pose of the identity without a word."""
    a, b = as_finite_rows(x1, "x1", (2, 3)), as_finite_rows(x2, "x2", (2, 3))
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"x1 and x2 must have the same length, got {a.shape[0]} and {b.shape[0]}")


def _require_plane_pose(R: Any, T: Any, n: Any, x1: Any, x2: Any) -> None:
    """ValueError or TypeError naming the argument unless ``R`` is a rotation, ``T`` three
    finite numbers, ``n`` a nonzero normal and the matches as :func:`_require_matches` wants."""
    as_rotation(R, "R")
    as_vector3(T, "T")
    if not np.any(as_vector3(n, "n")):
        raise ValueError("n must be a plane's normal, got (0, 0, 0)")
    _require_matches(x1, x2)


@dataclass(frozen=True)
class RefinedPlanarPose:
    """Pose of a plane refined on its homography (:func:`refine_planar_pose`).

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Unit translation direction.
    n : ndarray, shape (3,)
        Unit plane normal in camera 1, ``n^T X1 = d``.
    distance : float
        ``d`` in baselines, ``1 / ||T||``.
    k1 : float
        Division-model coefficient of both views (:func:`undistort_division`); 0 unless fitted
        and significant.
    k1_sigma : float
        Its standard deviation from the Gauss-Newton covariance (``inf`` when not fitted).
    residuals : ndarray, shape (N,)
        Symmetric transfer error of every match (normalized units) under the refined model.
    cost_start, cost : float
        Robust cost over the used matches before and after.
    rotation_sigma_deg : float
        Root-mean-square angle error (degrees) of ``R`` from the Gauss-Newton covariance
        of this refinement, ``k1`` estimated under its prior (or, when held at 0, a considered
        parameter of deviation :func:`held_k1_deviation` of ``k1_sigma``) and the given focal
        length's error counted at :data:`ppo_cv.rotation.FOCAL_PRIOR` (inf when not
        determined).
    rotation_fit_sigma_deg : float
        The same from the matches alone: ``k1`` estimated under its prior, the focal length
        held exact (what :mod:`ppo_cv.rotation_choice` weighs against the rotation-only fit).
    """

    R: np.ndarray
    t: np.ndarray
    n: np.ndarray
    distance: float
    k1: float
    k1_sigma: float
    residuals: np.ndarray
    cost_start: float
    cost: float
    rotation_sigma_deg: float = float("inf")
    rotation_fit_sigma_deg: float = float("inf")


def undistort_division(x: np.ndarray, k1: float) -> np.ndarray:
    """One-parameter division model (Fitzgibbon, 2001): ``q = x / (1 + k1 |x|^2)``, (N, 3).

    ``x`` are normalized points ``K^-1 (u, v, 1)`` with the distortion unmodelled; to first
    order ``k1`` equals OpenCV's radial ``k1`` of the lens. Returns homogeneous rows. Finite
    points and a finite ``k1`` under which ``1 + k1 |x|^2 > 0`` at every point (else the model
    folds the image over itself); ValueError or TypeError naming the argument otherwise.
    """
    X = _homogeneous(as_finite_array(x, "x"))
    coefficient = as_number(k1, "k1")
    if not math.isfinite(coefficient):
        raise ValueError(f"k1 must be a finite number, got {coefficient}")
    folded = 1.0 + coefficient * np.sum(X[:, :2] ** 2, axis=1) <= 0
    if folded.any():
        raise ValueError(
            f"k1 = {coefficient:g} folds {int(folded.sum())} of the points over "
            "(1 + k1 |x|^2 <= 0): no lens's division model"
        )
    return _undistort_division(X, coefficient)


def _undistort_division(x: np.ndarray, k1: float) -> np.ndarray:
    X = _homogeneous(as_real_array(x, "x"))
    scale = 1.0 + as_number(k1, "k1") * np.sum(X[:, :2] ** 2, axis=1)
    return np.column_stack([X[:, :2] / scale[:, None], np.ones(len(X))])


def _transfer(H: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Forward and backward transfer residuals, shape (N, 4): ``H q1 - q2``, ``H^-1 q2 - q1``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        f = q1 @ H.T
        b = q2 @ np.linalg.inv(H).T
        r = np.column_stack([f[:, :2] / f[:, 2:] - q2[:, :2], b[:, :2] / b[:, 2:] - q1[:, :2]])
    return np.where(np.isfinite(r), r, 1e3)


class _PlaneModel:
    """Residuals of the plane-induced homography at ``(R0, T0, n0)`` moved by ``p``."""

    def __init__(self, R0, T0, n0, x1, x2):
        self.R0, self.T0, self.n0 = R0, T0, n0
        self.basis = tangent_basis(n0)
        self.x1, self.x2 = x1, x2

    def pose(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = self.n0 + p[6:8] @ self.basis
        return _rotation_increment(p[:3]) @ self.R0, self.T0 + p[3:6], n / np.linalg.norm(n)

    def residuals(self, p: np.ndarray) -> np.ndarray:
        R, T, n = self.pose(p)
        k1 = p[8] if len(p) > 8 else 0.0
        q1, q2 = _undistort_division(self.x1, k1), _undistort_division(self.x2, k1)
        return _transfer(R + np.outer(T, n), q1, q2)


def _huber(r: np.ndarray, scale: float) -> float:
    norm = np.linalg.norm(r, axis=1)
    return float(np.sum(np.where(norm <= scale, norm**2, 2 * scale * norm - scale**2)))


def refine_planar_pose(
    R: np.ndarray,
    T: np.ndarray,
    n: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    used: np.ndarray | None = None,
    *,
    fit_k1: bool = False,
    scale: float = 1e-3,
    k1_prior: float = 0.1,
    max_k1: float = 0.3,
    iterations: int = 30,
) -> RefinedPlanarPose:
    """Refine ``(R, T = t / d, n)`` on the symmetric transfer error of ``Hn = R + T n^T``.

    Minimises ``sum_i rho(||(pi(Hn q1_i) - q2_i, pi(Hn^-1 q2_i) - q1_i)||)`` over the used
    matches, ``pi`` the perspective division, ``rho`` Huber's loss with bound ``scale``, by
    Levenberg-Marquardt on 8 parameters: a rotation increment ``R = exp([w]x) R0`` (3),
    ``T`` (3), ``n`` on the unit sphere (2 tangent coordinates). With ``fit_k1`` the points
    are first undistorted by the division model (:func:`undistort_division`) with one
    coefficient shared by both views, a ninth parameter with the Gaussian prior
    ``k1 ~ N(0, k1_prior^2)`` (in units of ``scale``); a radial distortion is observable from
    one plane, unlike the focal length (any ``Hn`` scaled to a middle singular value 1
    decomposes as ``R + T n^T``). Start from the PPO-chosen candidate
    (:func:`select_plane_pose`): the refinement stays in its basin, so it keeps the
    interpretation PPO chose.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    T : ndarray, shape (3,)
        Translation over plane distance, ``t / d`` (not a unit vector).
    n : ndarray, shape (3,)
        Plane normal in camera 1.
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalized points.
    used : ndarray of bool, shape (N,), optional
        Matches in the cost (the homography inliers); all by default. At least 8 (10 with
        ``fit_k1``), else the start is returned.
    fit_k1 : bool
        Also fit the division-model coefficient.
    scale : float
        Huber bound of a match's residual norm, normalized units (e.g. the RANSAC threshold in
        pixels over the focal length).
    k1_prior, max_k1 : float
        Standard deviation of the prior on ``k1``; bound on ``|k1|`` (beyond it ``k1 = 0``).
    iterations : int
        Largest number of Levenberg-Marquardt steps.

    Returns
    -------
    RefinedPlanarPose
        The start is kept when the refined cost is not lower.
    """
    _require_plane_pose(R, T, n, x1, x2)
    X1, X2 = _homogeneous(x1), _homogeneous(x2)
    used = np.ones(len(X1), bool) if used is None else np.asarray(used, bool).reshape(-1)
    if used.shape != (len(X1),):
        raise ValueError(f"used must have shape ({len(X1)},), got {used.shape}")
    R0, T0 = np.asarray(R, float), np.asarray(T, float).reshape(3)
    n0 = np.asarray(n, float).reshape(3) / np.linalg.norm(n)
    model = _PlaneModel(R0, T0, n0, X1[used], X2[used])
    count = int(np.count_nonzero(used))
    p = np.zeros(8)
    cost_start = _huber(model.residuals(p), scale)
    if count >= 9:
        p = _fit_stacked(model, p, scale, k1_prior, iterations)
    k1_sigma, k1_fitted = float("inf"), 0.0
    if fit_k1 and count >= 10:
        lens = _fit_stacked(model, np.append(p, 0.0), scale, k1_prior, iterations)
        k1_sigma, k1_fitted = _k1_sigma(model, lens, scale, k1_prior), float(lens[8])
        if abs(lens[8]) <= max_k1 and abs(lens[8]) > K1_SIGNIFICANCE * k1_sigma:
            p = lens
    cost = _huber(model.residuals(p), scale)
    if not cost < cost_start:
        p, cost = np.zeros(8), cost_start
    Rr, Tr, nr = model.pose(p)
    k1 = float(p[8]) if len(p) > 8 else 0.0
    norm = float(np.linalg.norm(Tr))
    q1, q2 = _undistort_division(X1, k1), _undistort_division(X2, k1)
    full = _transfer(Rr + np.outer(Tr, nr), q1, q2)
    rotation_sigma, fit_sigma = _rotation_sigmas_deg(
        model, np.append(p[:8], k1), scale, k1_prior, count,
        held_k1_sigma=None if len(p) > 8 else held_k1_deviation(k1_fitted, k1_sigma),
    )  # fmt: skip
    return RefinedPlanarPose(
        R=Rr,
        t=Tr / norm if norm > 0 else np.zeros(3),
        n=nr,
        distance=1.0 / norm if norm > 0 else float("inf"),
        k1=k1,
        k1_sigma=k1_sigma,
        residuals=np.linalg.norm(full, axis=1),
        cost_start=cost_start,
        cost=cost,
        rotation_sigma_deg=rotation_sigma,
        rotation_fit_sigma_deg=fit_sigma,
    )


def _stacked(model, p, scale, k1_prior):
    """Huber-weighted residuals of the used matches and the prior on ``k1``, flat."""
    r = model.residuals(p)
    extra = [scale / k1_prior * p[8:9]] if len(p) > 8 else []
    weights = _huber_weights(np.linalg.norm(r, axis=1), scale)
    return np.concatenate([(weights[:, None] * r).ravel(), *extra])


def _k1_sigma(model, p, scale, k1_prior) -> float:
    """Standard deviation of ``k1`` from the Gauss-Newton covariance ``2 s^2 (J^T J)^-1``.

    The factor 2: the forward and backward transfer residuals of a match carry the same noise,
    so ``J^T J`` counts every measurement twice."""
    r = _stacked(model, p, scale, k1_prior)
    J = _forward_jacobian(lambda q: _stacked(model, q, scale, k1_prior), p, r)
    dof = max(len(r) - len(p), 1)
    cov = _gauss_newton_covariance(J, 2.0 * float(r @ r) / dof)
    return float("inf") if cov is None else float(np.sqrt(max(cov[8, 8], 0.0)))


def held_k1_deviation(k1_fitted: float, k1_sigma: float) -> float:
    """Root-mean-square error of a division coefficient held at 0 although its fit reached
    ``k1_fitted`` with deviation ``k1_sigma`` (not significant, or too small to keep): given the
    matches the true coefficient lies about ``N(k1_fitted, k1_sigma^2)``, so the held value is
    off by ``sqrt(k1_fitted^2 + k1_sigma^2)`` on average.

    >>> round(held_k1_deviation(0.03, 0.04), 4)
    0.05
    """
    return float(np.hypot(as_number(k1_fitted, "k1_fitted"), as_number(k1_sigma, "k1_sigma")))


def rms_rotation_angle_deg(covariance: np.ndarray) -> float:
    """Root-mean-square angle (degrees) of a rotation increment ``w`` of covariance
    ``covariance`` (3, 3), radians: ``sqrt(E |w|^2) = sqrt(trace)``, the angle of
    ``exp([w]_x)`` being ``|w|``. The largest eigenvalue alone (the worst direction) falls
    short of it by up to ``sqrt(3)`` when the three directions are alike.

    >>> round(rms_rotation_angle_deg(np.diag([3e-6, 1e-6, 0.0])), 4)
    0.1146
    """
    covariance = as_matrix3(covariance, "covariance")
    return _rms_rotation_angle_deg(covariance)


def _rms_rotation_angle_deg(covariance: np.ndarray) -> float:
    return float(np.degrees(np.sqrt(max(float(np.trace(covariance)), 0.0))))


def _rotation_sigmas_deg(
    model, p, scale, k1_prior, count: int, held_k1_sigma: float | None
) -> tuple[float, float]:
    """Root-mean-square angle errors (degrees) of the rotation increment ``p[:3]``
    (:func:`rms_rotation_angle_deg`): with the given
    intrinsics' errors as considered parameters (Schmidt), and from the matches alone (the
    covariance of :func:`_k1_sigma`, ``k1`` under its prior).

    The given focal length's error (deviation :data:`ppo_cv.rotation.FOCAL_PRIOR`,
    ``x -> (1 + e) x`` in both views) moves the parameters by ``S = (J^T J)^-1 J^T J_e`` per
    unit, ``J_e`` the derivative of the residuals in ``e``, adding ``FOCAL_PRIOR^2 S S^T``: a
    homography does not tell a focal scale from the rotation's angle (any ``Hn`` scaled to a
    middle singular value 1 decomposes as ``R + T n^T``), so the angle inherits the focal
    length's relative error. ``k1`` is estimated under its prior unless it was held at 0
    (``held_k1_sigma`` given): then it is a considered parameter too, of deviation
    ``held_k1_sigma`` (:func:`held_k1_deviation`). inf with fewer than 10 matches."""
    if count < 10:
        return float("inf"), float("inf")
    fit = _rotation_deg(_plane_covariance(model, p, scale, k1_prior)[0])
    held = held_k1_sigma is not None and np.isfinite(held_k1_sigma)
    estimated = p[:8] if held else p
    cov, J, r = _plane_covariance(model, estimated, scale, k1_prior)
    if cov is None:
        return float("inf"), fit
    step = 1e-7
    moved = [(_stacked(_scaled_model(model, step), estimated, scale, k1_prior), FOCAL_PRIOR)]
    if held:
        with_k1 = _stacked(model, np.append(estimated, step), scale, k1_prior)[:-1]
        moved.append((with_k1, held_k1_sigma))
    for residuals, deviation in moved:
        S = np.linalg.lstsq(J, (residuals - r) / step, rcond=None)[0]
        cov = cov + deviation**2 * np.outer(S, S)
    return _rotation_deg(cov), fit


def _plane_covariance(model, p, scale, k1_prior):
    """Covariance ``2 s^2 (J^T J)^-1`` of :func:`_k1_sigma` at ``p`` (None when singular), its
    Jacobian and residuals."""
    r = _stacked(model, p, scale, k1_prior)
    J = _forward_jacobian(lambda q: _stacked(model, q, scale, k1_prior), p, r)
    return _gauss_newton_covariance(J, 2.0 * float(r @ r) / max(len(r) - len(p), 1)), J, r


def _rotation_deg(cov: np.ndarray | None) -> float:
    """:func:`rms_rotation_angle_deg` of the rotation block; inf for None."""
    return float("inf") if cov is None else _rms_rotation_angle_deg(cov[:3, :3])


def _scaled_model(model: _PlaneModel, focal_error: float) -> _PlaneModel:
    """``model`` with both views' normalised points multiplied by ``1 + focal_error``: a
    camera whose focal length is that many times the given one."""
    factor = np.array([1.0 + focal_error, 1.0 + focal_error, 1.0])
    return _PlaneModel(model.R0, model.T0, model.n0, model.x1 * factor, model.x2 * factor)


def _fit_stacked(model, p, scale, k1_prior, iterations):
    """:func:`ppo_cv.lsq.levenberg_marquardt` on :func:`_stacked`."""
    return _levenberg_marquardt(lambda q: _stacked(model, q, scale, k1_prior), p, iterations)[0]
