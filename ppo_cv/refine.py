"""Non-linear refinement of a relative pose over its inliers, and the rotation-only fit.

- ``refine_pose``: Levenberg-Marquardt on the tangent Sampson error of ``E = [t]_x R`` over the
  inliers (``pycolmap.refine_relative_pose``), ``t`` kept on the unit sphere.
- ``refine_pose_radial``: the same cost with the points first undistorted by a one-parameter
  division model shared by both views (Fitzgibbon, 2001), the coefficient under a Gaussian prior
  and kept only when significant: lens distortion nobody gave, which an essential matrix
  otherwise absorbs into a wrong rotation and a spurious translation.
- ``refine_pose_huber``: the pose alone on that cost's Huber-weighted Sampson errors, the
  general pose where no radial term is kept.
- ``fit_rotation``: for a pure rotation ``b2 ~ R b1`` on unit bearing vectors; the least-squares
  rotation ``argmin_R sum_i ||b2_i - R b1_i||^2`` (:func:`ppo_cv.ppo.rotation_from_rays`),
  re-fitted on the matches whose angular residual ``angle(b2_i, R b1_i)`` stays below the
  threshold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import (
    MAX_FOCAL,
    MAX_RADIAL,
    MAX_RAY_SLOPE,
    MAX_WHOLE_NUMBER,
    as_deviation,
    as_deviation_pair,
    as_finite_array,
    as_nonnegative,
    as_number,
    as_positive,
    as_positive_at_most,
    as_whole_number,
    require_pose_matches,
)
from .lsq import (
    _cross_matrices,
    _cross_matrix,
    _gauss_newton_covariance,
    _huber_weights,
    _levenberg_marquardt,
    _levenberg_marquardt_batched,
    _levenberg_marquardt_stacked,
    _pose_increment,
    _pose_increments,
    _rotation_increments,
    stack_by_chunks,
    tangent_basis,
)
from .model_selection import robust_sigma
from .plane import K1_SIGNIFICANCE, _rms_rotation_angle_deg, _undistort_division
from .ppo import rotation_from_rays
from .robust import _sampson_signed as _essential_sampson_signed
from .robust import _sampson_signed_rows, virtual_camera
from .rotation import FOCAL_PRIOR, K1_PRIOR
from .significance import MIN_CHECKED_INLIERS

__all__ = [
    "HUBER_NOISE_FACTOR",
    "K1_BIAS_REPLICATES",
    "K1_MIN",
    "LEVERAGE_MAX",
    "checked_inliers",
    "checked_matches",
    "huber_bound_px",
    "PoseSigmas",
    "RadialPose",
    "T_SIGMA_CAP_DEG",
    "refine_pose",
    "refine_pose_huber",
    "refine_pose_radial",
    "released_lens_shift_deg",
    "fit_rotation",
    "k1_noise_bias",
    "noise_replicates",
    "rotation_residuals",
    "PoseInformation",
    "pose_information",
    "pose_sigmas_deg",
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

    t = require_pose_matches(R, t, x1, x2, inliers, max_slope=MAX_RAY_SLOPE)
    focal = as_positive_at_most(focal, "focal", MAX_FOCAL, " pixels")
    if np.count_nonzero(inliers) < 5:
        return R, t / np.linalg.norm(t)
    x1, x2 = (np.asarray(x, dtype=np.float64) for x in (x1, x2))
    x1, x2 = x1[:, :2] / x1[:, 2:], x2[:, :2] / x2[:, 2:]
    camera = virtual_camera(focal)
    start = pycolmap.Rigid3d(pycolmap.Rotation3d(np.asarray(R, dtype=np.float64)), t)
    refined = pycolmap.refine_relative_pose(
        start,
        camera,
        np.ascontiguousarray(focal * x1),
        camera,
        np.ascontiguousarray(focal * x2),
        np.asarray(inliers, dtype=bool),
    )
    if refined is None:
        return R, t / np.linalg.norm(t)
    pose = refined["cam2_from_cam1"] if isinstance(refined, dict) else refined
    t_new = np.asarray(pose.translation, dtype=np.float64).reshape(3)
    return pose.rotation.matrix(), t_new / np.linalg.norm(t_new)


HUBER_NOISE_FACTOR = 5.0
"""Huber bound of :func:`refine_pose_radial` in deviations of the image noise, when that is
below the RANSAC threshold: the inliers of a 1 px threshold on features located to a few
hundredths of a pixel carry a tail (occlusion edges, JPEG blocks) that a bound at the threshold
weighs as noise, and in a narrow field ``k1`` and the direction of ``t`` trade along a shallow
valley that this tail tilts. On ``ppo_cv.data_gen`` ``tiny-baseline`` pairs at baseline /
depth 0.02 (``REAL_PHOTO``, indices 0-13) the true pose leaves a median Sampson error of 0.031
px where the pose refined with the bound at 1 px leaves 0.037 (index 3, ``t`` 8 degrees off);
bounded at five deviations the median error of ``t`` over the set falls from 4.1 to 2.3
degrees (1.13 to 1.03 at 0.05, 0.70 to 0.69 on ``general``; three deviations reach 2.1 at
0.02 but lose 0.1 of freiburg's AUC@5), the freiburg AUC unchanged
(``benchmarks/translation_sigma.py``)."""


def huber_bound_px(threshold_px: float, noise_px: float) -> float:
    """Huber bound of :func:`refine_pose_radial` (pixels): :data:`HUBER_NOISE_FACTOR`
    deviations of the measured image noise ``noise_px``, at most the RANSAC threshold
    ``threshold_px``, which is kept when the noise was not measured (NaN or 0)."""
    threshold_px = as_positive(threshold_px, "threshold_px")
    bound = HUBER_NOISE_FACTOR * as_number(noise_px, "noise_px")
    return min(threshold_px, bound) if bound > 0 else threshold_px


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
    k1_fitted : float
        The coefficient the fit reached, kept or not (0 when it was not fitted): less
        ``k1_noise_bias``, with ``k1_sigma`` what the matches say of a coefficient held at 0
        (:func:`ppo_cv.plane.held_k1_deviation`).
    k1_noise_bias : float
        What the fit reaches on the same matches without distortion under their own noise
        (:func:`k1_noise_bias`); 0 when the coefficient was not significant without it.
    k1_noise_bias_sigma : float
        Deviation of that mean; NaN when it was not measured.
    """

    R: np.ndarray
    t: np.ndarray
    k1: float
    k1_sigma: float
    k1_fitted: float = 0.0
    k1_noise_bias: float = 0.0
    k1_noise_bias_sigma: float = float("nan")

    @property
    def noise_bias_measured(self) -> bool:
        """Whether :func:`k1_noise_bias` ran: the coefficient passed the test without it."""
        return bool(np.isfinite(self.k1_noise_bias_sigma))


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
    focal_prior: float | None = FOCAL_PRIOR,
    principal_prior: np.ndarray | None = None,
) -> RadialPose:
    """Refine ``(R, t)`` with a radial distortion coefficient on the Sampson error.

    Minimises ``sum_i rho(r_i) + (scale k1 / k1_prior)^2`` over the inliers, ``r_i`` the signed
    Sampson error of ``E = [t]x R`` between ``q1_i`` and ``q2_i``, the points undistorted by
    the division model ``q = x / (1 + k1 |x|^2)`` (:func:`ppo_cv.plane.undistort_division`,
    one coefficient for both views), ``rho`` Huber's loss with bound ``scale``, by
    Levenberg-Marquardt on 6 parameters: ``R = exp([w]x) R0`` (3), ``t`` on the unit sphere
    (2 tangent coordinates), ``k1``. The coefficient is kept when the cost fell,
    ``K1_MIN <= |k1| <= max_k1`` and ``|k1|`` exceeds :data:`ppo_cv.plane.K1_SIGNIFICANCE`
    standard deviations, and so does its distance from what the fit reaches on the same
    matches without distortion under their own noise (:func:`k1_noise_bias`, the deviation of
    that estimate added); otherwise the start is returned with ``k1 = 0`` (the pipeline then
    refines it on the same cost without the coefficient, :func:`refine_pose_huber`). That bias
    is what makes a lens term buy a rotation on a handheld swing: where the pose's bas-relief
    valley mimics all but a few tenths of a percent of the coefficient's signature, the noise
    of the points alone pulls ``k1`` by one to four of its deviations, and the valley carries
    the rotation with it (about 14 degrees per unit of ``k1`` on a 6 degree pan about a pivot
    0.4 m behind the camera, 50 degree field).

    That deviation holds the given intrinsics right to within their priors: besides the
    Gauss-Newton covariance it counts the focal length's error (deviation ``focal_prior``,
    ``x -> (1 + e) x`` in both views) as a considered parameter (Schmidt), which moves ``k1``
    by ``S = (J^T J)^-1 J^T J_e`` per unit. In a narrow field a focal scale and ``k1`` trade
    along one valley with the pose, and two views cannot tell them apart: the coefficient is
    kept only where the matches demand it beyond what a focal length off by a few percent
    explains, so that it does not buy a rotation. A principal point only guessed at the image
    centre (``principal_prior``) is counted the same way (``x -> x - p``).

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
        Huber bound, normalized units: the RANSAC threshold over the focal length, or
        :data:`HUBER_NOISE_FACTOR` deviations of the image noise when that is smaller.
    k1_prior, max_k1 : float
        Standard deviation of the prior on ``k1``; bound on ``|k1|``.
    iterations : int
        Largest number of Levenberg-Marquardt steps.
    focal_prior : float or None
        Deviation of the relative error of the given focal length
        (:data:`ppo_cv.rotation.FOCAL_PRIOR`) in the deviation of ``k1``; None holds the
        focal length exact.
    principal_prior : array_like of 2 floats, optional
        Deviations ``(x, y)`` (normalised units) of the error of a guessed principal point in
        the deviation of ``k1``; None holds it exact.

    Returns
    -------
    RadialPose
    """
    t0 = require_pose_matches(R, t, x1, x2, inliers)
    scale, k1_prior, iterations = _radial_settings(scale, k1_prior, iterations)
    max_k1, focal_prior, principal_prior = _lens_bounds(max_k1, focal_prior, principal_prior)
    R0 = np.asarray(R, dtype=np.float64)
    t0 = t0 / np.linalg.norm(t0)
    start = RadialPose(R0, t0, 0.0, float("inf"))
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    if len(a) < 12:
        return start
    fit = _radial_fit(R0, t0, a, b, scale, k1_prior, iterations)
    r_start = fit.residuals(np.zeros(6))
    r = fit.residuals(fit.p)
    cov = _gauss_newton_covariance(fit.J, float(r @ r) / max(len(r) - 6, 1))
    if cov is None:
        return start
    k1_variance = max(cov[5, 5], 0.0) + _considered_k1_variance(
        lambda *moved: fit.residuals(fit.p, *moved), fit.J, r, focal_prior, principal_prior
    )
    k1, k1_sigma = float(fit.p[5]), float(np.sqrt(k1_variance))
    kept = K1_MIN <= abs(k1) <= max_k1 and abs(k1) > K1_SIGNIFICANCE * k1_sigma
    bias, bias_sigma = 0.0, float("nan")
    if kept:
        bias, bias_sigma = _k1_noise_bias(
            R0, t0, a, b, fit.p, scale, k1_prior, iterations, K1_BIAS_REPLICATES
        )
        kept = abs(k1 - bias) > K1_SIGNIFICANCE * np.hypot(k1_sigma, bias_sigma)
    if not (kept and r @ r < r_start @ r_start):
        return RadialPose(R0, t0, 0.0, k1_sigma, k1, bias, bias_sigma)
    Rp, tp = fit.pose(fit.p)
    return RadialPose(Rp, tp, k1, k1_sigma, k1, bias, bias_sigma)


def refine_pose_huber(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    *,
    scale: float,
    iterations: int = 30,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine ``(R, t)`` on Huber's loss of the signed Sampson errors over the inliers: the
    cost of :func:`refine_pose_radial` with ``k1`` held at 0.

    :func:`refine_pose` minimises the squared errors of every inlier of a threshold of about
    1 px, which on features located to a few hundredths of a pixel lets a tail of a few
    percent of them (mismatches on repeated texture, occlusion edges) weigh as much as the
    rest. With a small baseline the direction of ``t`` and the rotation slide together along
    a nearly flat valley, and that tail tilts it: on ``ppo_cv.data_gen`` ``small-parallax``
    seed 1 index 4 (baseline / depth 0.04, 2114 inliers, 66 of them beyond
    :data:`HUBER_NOISE_FACTOR` deviations of the noise, 0.23 px) the least-squares pose has
    ``t`` 0.45 degrees off with a median error of 0.031 px, and on Huber's loss bounded there
    0.02 off with 0.027 px (the true pose: 0.034 px, its sum of squares 9 % above the
    least-squares one).

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Start, e.g. :func:`refine_pose`'s result.
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches of the cost; fewer than 12 return the start.
    scale : float
        Huber bound, normalized units (:func:`huber_bound_px` over the focal length): a finite
        number > 0.
    iterations : int
        Largest number of Levenberg-Marquardt steps, at least 1.

    Returns
    -------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Unit norm.

    Raises
    ------
    ValueError
        For matches :func:`ppo_cv.checks.require_pose_matches` refuses (a zero ``t`` among
        them), a ``scale`` that is not a finite number > 0 or ``iterations`` below 1.
    """
    t0 = require_pose_matches(R, t, x1, x2, inliers)
    scale = as_positive(scale, "scale")
    iterations = as_whole_number(iterations, "iterations", 1, MAX_WHOLE_NUMBER)
    R0 = np.asarray(R, dtype=np.float64)
    t0 = t0 / np.linalg.norm(t0)
    inliers = np.asarray(inliers, dtype=bool)
    if np.count_nonzero(inliers) < 12:
        return R0, t0
    X1, X2 = (np.ascontiguousarray(np.asarray(x, float)[inliers].T) for x in (x1, x2))
    basis = tangent_basis(t0)

    def residuals(P: np.ndarray) -> np.ndarray:
        r = _sampson_by_coordinate(*_pose_increments(R0, t0, P, basis), X1, X2)
        return _huber_weights(np.abs(r), scale) * r

    p, _ = _levenberg_marquardt_stacked(residuals, np.zeros(5), iterations)
    return _pose_increment(R0, t0, p, basis)


def _radial_settings(scale: float, k1_prior: float, iterations: int) -> tuple[float, float, int]:
    """The Huber bound and the prior deviation (both > 0) and the step count (a whole number
    >= 0) of :func:`refine_pose_radial`'s cost, checked; ValueError or TypeError naming each."""
    return (
        as_positive(scale, "scale"),
        as_positive(k1_prior, "k1_prior"),
        as_whole_number(iterations, "iterations", 0, MAX_WHOLE_NUMBER),
    )


def _lens_bounds(max_k1: float, focal_prior: float | None, principal_prior) -> tuple:
    """:func:`refine_pose_radial`'s bound on ``|k1|`` (>= 0) and the deviations of its
    considered intrinsics (None or >= 0), checked."""
    return (
        as_nonnegative(max_k1, "max_k1"),
        as_deviation(focal_prior, "focal_prior"),
        as_deviation_pair(principal_prior, "principal_prior"),
    )


@dataclass(frozen=True)
class _RadialFit:
    """Levenberg-Marquardt minimum ``p`` (6,) of :func:`refine_pose_radial`'s cost, its Jacobian
    ``J`` there, the stacked residuals as a function of the parameters (and of the considered
    focal error and principal offset) and the pose of a parameter vector."""

    p: np.ndarray
    J: np.ndarray
    residuals: object
    pose: object


def _radial_fit(
    R0, t0, a, b, scale, k1_prior, iterations, k1_start=0.0, prior_weight=None
) -> _RadialFit:
    """The cost of :func:`refine_pose_radial` minimised from ``(R0, t0)`` (``t0`` a unit
    vector) and the coefficient ``k1_start`` (``p[5]`` its change), the prior row weighted by
    ``prior_weight`` (the Huber bound ``scale`` when None) against the Huber-weighted signed
    Sampson errors of the matches ``a, b``."""
    weight = scale if prior_weight is None else prior_weight
    basis = tangent_basis(t0)
    given = [_RadialPoints(x) for x in (a, b)]

    def pose(p):
        return _pose_increment(R0, t0, p, basis)

    residuals = _radial_residuals(R0, t0, basis, scale, k1_prior, k1_start)

    def many(P, focal_error=0.0, offset=(0.0, 0.0)):
        moved = given
        if not (focal_error == 0.0 and offset == (0.0, 0.0)):
            moved = [_RadialPoints(_adjusted(x, focal_error, offset)) for x in (a, b)]
        return residuals(P, moved, weight)

    def stacked(p, focal_error=0.0, offset=(0.0, 0.0)):
        return many(p[None], focal_error, offset)[0]

    p, J = _levenberg_marquardt(stacked, np.zeros(6), iterations, many=many)
    return _RadialFit(p, J, stacked, pose)


def _radial_fits(
    R0, t0, A, B, scale, k1_prior, iterations, k1_start=0.0, prior_weights=None
) -> np.ndarray:
    """The parameters (S, 6) of :func:`_radial_fit` on S match sets of one size, ``A`` and
    ``B`` (S, N, 3), fitted together (:func:`ppo_cv.lsq.levenberg_marquardt_batched`); the
    prior row of set ``s`` weighted by ``prior_weights[s]`` (the Huber bound when None)."""
    weights = np.full(len(A), scale) if prior_weights is None else np.asarray(prior_weights)
    residuals = _radial_residuals(R0, t0, tangent_basis(t0), scale, k1_prior, k1_start)
    given = [_RadialPoints(x) for x in (A, B)]

    def many(P, rows):
        return residuals(P, given, weights[rows], rows)

    return _levenberg_marquardt_batched(many, np.zeros((len(A), 6)), iterations)


def _radial_residuals(R0, t0, basis, scale, k1_prior, k1_start):
    """The residuals (K, N + 1) of :func:`_radial_fit`'s cost at the parameter rows ``P`` (K,
    6) about ``(R0, t0)`` (``basis`` the tangent basis of ``t0``), on the ``points`` of the
    two views (:class:`_RadialPoints`, of their sets ``rows`` when given), the prior row
    weighted by ``weight`` (a float or (K,)); the rows evaluated by chunks
    (:func:`ppo_cv.lsq.stack_by_chunks`), each row's figures those of the row alone."""

    def chunk(P, points, weight, rows):
        Rp, tp = _pose_increments(R0, t0, P, basis)
        k1 = k1_start + P[:, 5]
        r = _sampson_by_coordinate(Rp, tp, *(view.undistorted(k1, rows) for view in points))
        return np.column_stack([_huber_weights(np.abs(r), scale) * r, weight * k1 / k1_prior])

    def residuals(P, points, weight, rows=None):
        weight = np.broadcast_to(weight, (len(P),))
        evaluate = lambda s: chunk(P[s], points, weight[s], None if rows is None else rows[s])  # noqa: E731
        return stack_by_chunks(evaluate, len(P), points[0].r2.shape[-1])

    return residuals


def _stacked_sets(sets) -> tuple[np.ndarray, np.ndarray]:
    """Match sets ``(x1, x2)`` of one size (:func:`noise_replicates`) as two arrays (S, N, 3)."""
    sets = list(sets)
    return np.stack([a for a, _ in sets]), np.stack([b for _, b in sets])


class _RadialPoints:
    """Normalised points (N, 2 or 3), or S sets of them (S, N, 2 or 3), as
    :func:`ppo_cv.plane.undistort_division` reads them, their coordinates held as contiguous
    arrays (N,) or (S, N) and their squared radii taken once for the several coefficients of
    a fit."""

    def __init__(self, x: np.ndarray) -> None:
        xy = np.asarray(x, dtype=np.float64)[..., :2]
        self.r2 = np.sum(xy**2, axis=-1)
        self.x, self.y = np.ascontiguousarray(xy[..., 0]), np.ascontiguousarray(xy[..., 1])

    def undistorted(self, k1: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """:func:`~ppo_cv.plane.undistort_division` by each coefficient of ``k1`` (K,), of the
        one set or of the sets ``rows`` (K,), laid out by coordinate, shape (K, 3, N): the
        same figures, each coordinate a contiguous row (a broadcast over pairs of coordinates
        is several times slower)."""
        x, y, r2 = (self.x, self.y, self.r2) if rows is None else (
            self.x[rows], self.y[rows], self.r2[rows])  # fmt: skip
        scale = 1.0 + k1[:, None] * r2
        out = np.empty((len(scale), 3, scale.shape[1]))
        np.divide(x, scale, out=out[:, 0])
        np.divide(y, scale, out=out[:, 1])
        out[:, 2] = 1.0
        return out


def _sampson_by_coordinate(R: np.ndarray, t: np.ndarray, X1: np.ndarray, X2: np.ndarray):
    """:func:`_sampson_signed` (K, N) of ``E = [t]_x R``, ``R`` (K, 3, 3) and ``t`` (K, 3), on
    points laid out by coordinate (K or 1, 3, N) (:func:`ppo_cv.robust.sampson_signed_rows`):
    the same figures."""
    return _sampson_signed_rows(_cross_matrices(t) @ R, X1, X2)


K1_BIAS_REPLICATES = 16
"""Simulated match sets of :func:`k1_noise_bias`. The standard deviation of their mean, a
quarter of the coefficient's spread, enters the test of :func:`refine_pose_radial`. Where that
test ran, the rotation choice refits as many for the noise's own part of
:func:`released_lens_shift_deg`."""


def k1_noise_bias(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    scale: float,
    k1_prior: float = 0.1,
    iterations: int = 20,
    replicates: int = K1_BIAS_REPLICATES,
) -> tuple[float, float]:
    """Coefficient (and the deviation of that mean) that :func:`refine_pose_radial` fits on
    matches of the pose ``(R, t)`` without any lens distortion, perturbed by the noise the
    matches show (their residuals with the coefficient fitted): a parametric bootstrap of the
    estimator's bias.

    The noise of the points enters the Sampson cost nonlinearly (errors in the variables): the
    fitted coefficient is biased, by a fraction of its deviation where ``k1`` has its own
    signature, by several where the pose's bas-relief valley mimics all but a few tenths of a
    percent of it (a handheld swing, a narrow field with a tiny baseline), and a linearised
    deviation does not see the bias. Each replicate (:func:`noise_replicates` of the matches
    ``x1, x2``, inliers, normalised (N, 3), and the essential matrix of ``(R, t)``) is refitted
    from ``(R, t)``.

    Returns
    -------
    bias : float
        Mean fitted coefficient over the replicates.
    sigma : float
        Standard deviation of that mean.
    """
    t = require_pose_matches(R, t, x1, x2)
    scale, k1_prior, iterations = _radial_settings(scale, k1_prior, iterations)
    replicates = as_whole_number(replicates, "replicates", 2, MAX_WHOLE_NUMBER)
    R = np.asarray(R, dtype=np.float64)
    t = t / np.linalg.norm(t)
    p = _radial_fit(R, t, x1, x2, scale, k1_prior, iterations).p
    return _k1_noise_bias(R, t, x1, x2, p, scale, k1_prior, iterations, replicates)


def _k1_noise_bias(R, t, x1, x2, p, scale, k1_prior, iterations, replicates) -> tuple:
    """:func:`k1_noise_bias` given the parameters ``p`` (6,) the fit reached on the matches
    themselves (``t`` a unit vector), whose residuals size the simulated noise."""
    E = _cross_matrix(t) @ R
    sizes = np.abs(
        _sampson_signed(
            *_pose_increment(R, t, p), *(_undistort_division(x, p[5]) for x in (x1, x2))
        )
    )
    A, B = _stacked_sets(noise_replicates(E, x1, x2, sizes, replicates))
    fitted = _radial_fits(R, t, A, B, scale, k1_prior, iterations)[:, 5]
    return float(np.mean(fitted)), float(np.std(fitted, ddof=1) / np.sqrt(replicates))


def noise_replicates(
    E: np.ndarray, x1: np.ndarray, x2: np.ndarray, sizes: np.ndarray, count: int, k1: float = 0.0
):
    """Simulated match sets of the epipolar model ``E`` under the noise the matches show.

    The matches ``x1, x2`` (normalised (N, 3)), undistorted by the division coefficient ``k1``
    (:func:`ppo_cv.plane.undistort_division`), are moved onto ``x2^T E x1 = 0`` (first order,
    along the Sampson gradient), each coordinate of a replicate gets a Gaussian of one of
    the ``sizes`` (N,), drawn without replacement, and the points are distorted again by
    ``k1``. The sizes are the matches' Sampson residuals to the model that explains them best
    (with its lens term, so that they are noise and not a lens's misfit), whose spread and
    tail the simulated noise then has. Deterministic (fixed seed).

    Yields
    ------
    x1, x2 : ndarray, shape (N, 3)
        ``count`` times.
    """
    a, b = (_undistort_division(np.asarray(x, float) / np.asarray(x, float)[:, 2:], k1)
            for x in (x1, x2))  # fmt: skip
    a, b = _sampson_corrected(E, a, b)
    rng = np.random.default_rng(0)
    for _ in range(count):
        noise = rng.permutation(sizes)[:, None, None] * rng.standard_normal((len(a), 2, 2))
        moved = (x[:, :2] + noise[:, i] for i, x in enumerate((a, b)))
        yield tuple(_distorted(np.column_stack([xy, np.ones(len(xy))]), k1) for xy in moved)


def _distorted(q: np.ndarray, k1: float) -> np.ndarray:
    """The points ``x`` (N, 3) that :func:`ppo_cv.plane.undistort_division` takes to the
    undistorted ``q`` (N, 3), last coordinate 1: ``|x| = |q| (1 + k1 |x|^2)`` solved for the
    root that tends to ``|q|`` as ``k1 -> 0``, ``x = 2 q / (1 + sqrt(1 - 4 k1 |q|^2))``."""
    if k1 == 0.0:
        return q
    r2 = np.sum(q[:, :2] ** 2, axis=1)
    factor = 2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * k1 * r2, 0.0)))
    return np.column_stack([q[:, :2] * factor[:, None], q[:, 2:]])


def released_lens_shift_deg(
    R: np.ndarray,
    t: np.ndarray,
    k1: float,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    scale: float,
    iterations: int = 30,
    replicates: int = 0,
) -> tuple[float, float]:
    """How far (degrees) a general pose's rotation moves when its lens term is fitted anew, less
    the move the matches' noise alone makes, and the deviation of that figure: the essential
    matrix's bias in :func:`ppo_cv.rotation_choice.choose_rotation`.

    The pose ``(R, t)`` with division coefficient ``k1`` is refitted on the cost of
    :func:`refine_pose_radial` (Huber bound ``scale``, normalised units, over the signed
    Sampson errors of the ``inliers``, normalised points (N, 3), lens not corrected), started
    at ``k1`` and with the prior :data:`ppo_cv.rotation.K1_PRIOR` weighed against the matches'
    robust noise rather than against the Huber bound. Where the field is wide and the baseline
    long, ``t`` and ``k1`` hardly trade with the rotation, which moves by what the lens term as
    it was held really cost it (hundredths of a degree). In a narrow field with a tiny
    baseline it slides with ``t`` and ``k1`` along the bas-relief valley, and the matches'
    error is dominated by the lens's misfit, not their noise: the valley's floor is where that
    misfit puts it, which the prior's weight or the choice to hold ``k1`` moves by degrees. A
    linearisation at the estimate does not see this, nor does a rise of the cost in units of
    the noise: at the rotation-only fit's rotation the cost of the real tripod pairs of
    ``pano_dev`` rises by 30-7000 such units whether that rotation is 0.1 or 13 degrees from
    the essential matrix's, and is the right one.

    The noise of the points pulls the released coefficient as it pulls that of
    :func:`refine_pose_radial` (:func:`k1_noise_bias`), and the rotation with it: on handheld
    swings rendered without distortion (50 degree field, 6 degree pans about a pivot 0.4 m
    behind the camera) a third to a half of the move. With ``replicates`` (at least 2) the same
    refit runs on :func:`noise_replicates` of the pose, lens and noise sizes of the released
    fit's residuals; the shift is then ``|w - mean(w_i)|`` of the rotation increments ``w`` of
    the matches and ``w_i`` of the replicates, and its deviation the root-mean-square spread of
    one ``w_i`` (that of ``w``) with that of their mean. Without, the whole move is returned
    with deviation 0.

    Returns
    -------
    shift_deg, sigma_deg : float
        ``(0, 0)`` with fewer than 12 inliers or no noise.
    """
    t = require_pose_matches(R, t, x1, x2, inliers)
    k1 = _as_coefficient(k1)
    scale, _, iterations = _radial_settings(scale, 1.0, iterations)
    replicates = as_whole_number(replicates, "replicates", 0, MAX_WHOLE_NUMBER)
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    if len(a) < 12:
        return 0.0, 0.0
    R = np.asarray(R, dtype=np.float64)
    t = t / np.linalg.norm(t)
    released = _released_move(R, t, k1, a, b, scale, iterations)
    if released is None:
        return 0.0, 0.0
    move, sizes = released
    if replicates < 2:
        return float(np.degrees(np.linalg.norm(move))), 0.0
    A, B = _stacked_sets(noise_replicates(_cross_matrix(t) @ R, a, b, sizes, replicates, k1))
    moves = _released_moves(R, t, k1, A, B, scale, iterations)
    if len(moves) < 2:
        return float(np.degrees(np.linalg.norm(move))), 0.0
    spread = np.sqrt(np.sum(np.var(moves, axis=0, ddof=1)) * (1.0 + 1.0 / len(moves)))
    return float(np.degrees(np.linalg.norm(move - moves.mean(axis=0)))), float(np.degrees(spread))


def _as_coefficient(k1: float) -> float:
    """A division coefficient: a finite number of magnitude at most :data:`MAX_RADIAL`."""
    number = as_number(k1, "k1")
    if not abs(number) <= MAX_RADIAL:
        raise ValueError(f"k1 must be a finite number in [-{MAX_RADIAL:g}, {MAX_RADIAL:g}], "
                         f"got {number}")  # fmt: skip
    return number


def _released_move(R, t, k1, a, b, scale, iterations) -> tuple | None:
    """Rotation increment (3,) of :func:`released_lens_shift_deg`'s refit of the matches ``a,
    b`` and the sizes (N,) of their Sampson residuals there (``k1`` fitted); None without
    noise."""
    noise = robust_sigma(_sampson_signed(R, t, *(_undistort_division(x, k1) for x in (a, b))), 1)
    if not noise > 0:
        return None
    fit = _radial_fit(R, t, a, b, scale, K1_PRIOR, iterations, k1_start=k1, prior_weight=noise)
    fitted = (_undistort_division(x, k1 + fit.p[5]) for x in (a, b))
    return fit.p[:3], np.abs(_sampson_signed(*fit.pose(fit.p), *fitted))


def _released_moves(R, t, k1, A, B, scale, iterations) -> np.ndarray:
    """The rotation increments (S', 3) of :func:`_released_move` on the match sets ``A``,
    ``B`` (S, N, 3), fitted together, of the S' sets that have noise."""
    noise = np.array([
        robust_sigma(_sampson_signed(R, t, *(_undistort_division(x, k1) for x in (a, b))), 1)
        for a, b in zip(A, B, strict=True)
    ])  # fmt: skip
    has = noise > 0
    if not has.any():
        return np.empty((0, 3))
    p = _radial_fits(R, t, A[has], B[has], scale, K1_PRIOR, iterations, k1, noise[has])
    return p[:, :3]


def _sampson_corrected(E: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> tuple:
    """The matches (normalised (N, 3), last coordinate 1) moved onto ``x2^T E x1 = 0`` to first
    order: along the gradient of the algebraic error in ``(x1, y1, x2, y2)``."""
    Ex1, Etx2 = x1 @ E.T, x2 @ E
    gradient = np.column_stack([Etx2[:, :2], Ex1[:, :2]])
    algebraic = np.sum(x2 * Ex1, axis=1)
    step = -(algebraic / np.maximum(np.sum(gradient**2, axis=1), 1e-300))[:, None] * gradient
    return (np.column_stack([x[:, :2] + step[:, 2 * i : 2 * i + 2], x[:, 2]])
            for i, x in enumerate((x1, x2)))  # fmt: skip


def _considered_k1_variance(moved_residuals, J, r, focal_prior, principal_prior) -> float:
    """Variance that the given focal length's and principal point's errors (Schmidt's
    considered parameters, deviations ``focal_prior`` and ``principal_prior``) add to ``k1``,
    the last parameter: ``S = (J^T J)^-1 J^T dr/de`` per unit of each error."""
    considered = []  # (residuals with one given intrinsic moved by h, its deviation)
    h = 1e-6
    if focal_prior is not None:
        considered.append((moved_residuals(h), focal_prior))
    if principal_prior is not None:
        px, py = np.broadcast_to(np.asarray(principal_prior, float), (2,))
        considered += [(moved_residuals(0.0, (h, 0.0)), px), (moved_residuals(0.0, (0.0, h)), py)]
    variance = 0.0
    for moved, deviation in considered:
        S = np.linalg.lstsq(J, (moved - r) / h, rcond=None)[0]
        variance += (deviation * S[-1]) ** 2
    return variance


def _adjusted(x: np.ndarray, focal_error: float, offset=(0.0, 0.0)) -> np.ndarray:
    """Homogeneous normalised points (N, 3) of a camera whose focal length is ``1 +
    focal_error`` times the given one and whose principal point is moved by ``offset``
    (normalised units): ``x -> (1 + e) (x - p)``."""
    if focal_error == 0.0 and offset == (0.0, 0.0):
        return x
    xy = (x[:, :2] - np.asarray(offset, float)) * (1.0 + focal_error)
    return np.column_stack([xy, x[:, 2:]])


def _bearings(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def rotation_residuals(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Angle (radians) between ``b2_i`` and ``R b1_i`` for each match, shape (N,), of
    homogeneous points or bearings ``x1``, ``x2`` (N, 3)."""
    require_pose_matches(R, np.zeros(3), x1, x2, moving=False, bearings=True)
    R, x1, x2 = (np.asarray(v, dtype=np.float64) for v in (R, x1, x2))
    _require_directions(x1, x2)
    return _rotation_residuals(R, x1, x2)


def _require_directions(x1: np.ndarray, x2: np.ndarray) -> None:
    """ValueError naming the argument holding a zero row, which has no direction."""
    for name, rows in (("x1", x1), ("x2", x2)):
        if len(rows) and not np.abs(rows).max(axis=1).all():
            raise ValueError(f"{name} has a zero row, which has no direction")


def _rotation_residuals(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
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
    require_pose_matches(
        np.eye(3) if R is None else R, np.zeros(3), x1, x2, inliers, moving=False, bearings=True
    )
    threshold = as_positive(threshold, "threshold")
    iterations = as_whole_number(iterations, "iterations", 0, MAX_WHOLE_NUMBER)
    _require_directions(*(np.asarray(x, float) for x in (x1, x2)))
    b1, b2 = _bearings(np.asarray(x1, float)), _bearings(np.asarray(x2, float))
    allowed = np.asarray(inliers, dtype=bool)
    if np.count_nonzero(allowed) < 2:
        raise ValueError(
            f"inliers selects {np.count_nonzero(allowed)} matches: a rotation needs at least 2"
        )
    used = allowed.copy()
    if R is not None:
        used &= _rotation_residuals(np.asarray(R, float), b1, b2) < threshold
    if np.count_nonzero(used) < 2:
        used = allowed.copy()
    R = rotation_from_rays(b1[used], b2[used])
    for _ in range(iterations):
        keep = allowed & (_rotation_residuals(R, b1, b2) < threshold)
        if np.count_nonzero(keep) < 2 or np.array_equal(keep, used):
            break
        used = keep
        R = rotation_from_rays(b1[used], b2[used])
    return R, used


def _sampson_signed(R: np.ndarray, t: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Signed Sampson residuals of ``E = [t]_x R``: ``R`` (..., 3, 3), ``t`` (..., 3) and the
    points (..., N, 3) broadcast to (..., N)."""
    t = np.asarray(t, dtype=np.float64)
    E = _cross_matrices(t.reshape(-1, 3)).reshape(t.shape[:-1] + (3, 3)) @ R
    return _essential_sampson_signed(E, x1, x2)


T_SIGMA_CAP_DEG = 90.0
"""Largest ``t_sigma_deg``. The direction of ``t`` is a point of the unit sphere and cheirality
fixes its sign, so it lies in the hemisphere around any estimate: a one-sigma cone of 90 degrees
already covers all of it, and a larger linearised value says no more than "undetermined"."""


@dataclass(frozen=True)
class PoseSigmas:
    """Standard deviations of a refined pose (:func:`pose_sigmas_deg`).

    Attributes
    ----------
    rotation_deg : float
        Root-mean-square angle of the rotation's error, degrees (inf when undetermined).
    translation_deg : float
        Of the direction of ``t`` in its worst direction, degrees, at most
        :data:`T_SIGMA_CAP_DEG`.
    """

    rotation_deg: float
    translation_deg: float


_UNDETERMINED = PoseSigmas(float("inf"), T_SIGMA_CAP_DEG)


def translation_sigma_deg(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    noise: float | None = None,
    step: float = 1e-6,
    *,
    focal_prior: float | None = FOCAL_PRIOR,
    k1_prior: float | None = None,
) -> float:
    """One standard deviation of the direction of ``t`` (degrees): the translation of
    :func:`pose_sigmas_deg`, whose parameters these are."""
    return pose_sigmas_deg(
        R, t, x1, x2, inliers, noise, step, focal_prior=focal_prior, k1_prior=k1_prior
    ).translation_deg


def pose_sigmas_deg(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    noise: float | None = None,
    step: float = 1e-6,
    *,
    focal_prior: float | None = FOCAL_PRIOR,
    k1_prior: float | None = None,
    principal_prior: np.ndarray | None = None,
    held_k1_prior: float | None = None,
) -> PoseSigmas:
    """Standard deviations of the rotation and of the direction of ``t`` (degrees) from the
    Sampson cost.

    The estimated parameters are the pose, ``R(w) = exp([w]_x) R`` and
    ``t(v) = (t + v1 u1 + v2 u2) / |.|`` with ``(u1, u2)`` an orthonormal basis of the tangent
    plane of the sphere at ``t``, and with ``k1_prior`` the radial term the refinement fitted,
    ``x -> x (1 - k1 |x|^2)`` (the first order of the division model of
    :func:`refine_pose_radial`) under a Gaussian prior. ``r`` are the signed Sampson residuals
    of the inliers and ``J`` their Jacobian (central differences).

    ``J^T J`` alone would claim for a pure rotation a direction known to ``1 / sqrt(n)``
    radians: ``r_i = t . m_i / d_i`` with ``m_i = R x1_i x x2_i``, and there every ``m_i`` is
    noise. That part is taken away (errors in variables): with ``G_i`` the derivative of row
    ``i`` of ``J`` with respect to the four image coordinates of match ``i``, image noise of
    variance ``s^2`` per coordinate puts ``s^2 sum_i G_i G_i^T`` into ``J^T J`` whatever the
    motion. With ``I = J^T J - s^2 sum_i G_i G_i^T`` (plus ``s^2 / k1_prior^2`` on ``k1``) the
    covariance is ``s^2 I^-1``, the cap :data:`T_SIGMA_CAP_DEG` when ``I`` is not positive
    definite (the translation created no information beyond the noise).

    The focal length is held at its given value, which is off by a few percent on real
    photos; in a narrow field that moves ``t`` like a forward translation (0.8 degrees per
    percent on a 28 degree field). Its error, of deviation ``focal_prior`` (``x -> (1 + e) x``
    in both views), enters as a considered parameter (Schmidt): with ``c`` its cross
    information with the estimated ones, ``focal_prior^2 (I^-1 c)(I^-1 c)^T`` is added to the
    covariance. ``s^2`` is the noise variance of one residual, ``|r|^2 / (n - 5)`` of the fit or
    ``noise^2``. The rotation's deviation is the root-mean-square angle of its (3, 3) block
    (:func:`ppo_cv.plane.rms_rotation_angle_deg`, as the rotation-only fit reports its own); the
    translation's the square root of the largest eigenvalue of its (2, 2) block (the worst
    direction), at most the cap; both in degrees. Only matches the others can check enter
    (:func:`checked_matches`): not a false match on which the epipole was placed.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Refined pose, ``X2 = R X1 + t``, at the minimum of the Sampson cost.
    x1, x2 : ndarray, shape (N, 3)
        Normalised homogeneous coordinates of the matches (undistorted by any fitted lens term).
    inliers : ndarray of bool, shape (N,)
        Matches of the cost; fewer than 6 gives the cap.
    noise : float, optional
        Deviation of one Sampson residual (normalised) when the fit's own understate it.
    step : float
        Finite-difference step (normalised units and radians).
    focal_prior : float or None
        Deviation of the relative error of the given focal length
        (:data:`ppo_cv.rotation.FOCAL_PRIOR`); None holds the focal length exact.
    k1_prior : float or None
        Deviation of the prior on the radial term the refinement fitted
        (:data:`ppo_cv.rotation.K1_PRIOR`); None: no radial term was fitted.
    principal_prior : array_like of 2 floats, optional
        Deviations ``(x, y)`` (normalised units) of the error of a principal point that was
        only guessed (at the image centre; ``PairOptions.principal_point``), a considered
        parameter like the focal length (``x -> x - p`` in both views): in a narrow field an
        offset of 1 % of the image is nearly a rotation, and the essential matrix trades it
        against ``t`` along the bas-relief valley. None holds it exact.
    held_k1_prior : float or None
        Deviation of a ``k1`` held at 0 (:func:`ppo_cv.plane.held_k1_deviation`; ``k1_prior``
        None), a considered parameter like the focal length. None holds it exact.

    Returns
    -------
    PoseSigmas
        ``inf`` for the rotation and the cap for the translation with fewer than 6 inliers or
        an information that is not positive definite.
    """
    return pose_information(R, t, x1, x2, inliers, noise, step).sigmas_deg(
        focal_prior=focal_prior, k1_prior=k1_prior, principal_prior=principal_prior,
        held_k1_prior=held_k1_prior,
    )  # fmt: skip


@dataclass(frozen=True)
class PoseInformation:
    """The information of a refined pose in the parameters of :func:`pose_sigmas_deg`, the
    image noise taken out, before any prior: what its deviations under several priors share
    (:func:`pose_information`).

    Attributes
    ----------
    info : ndarray, shape (9, 9), or None
        ``J^T J - s^2 sum_i G_i G_i^T`` over the checked inliers, in the pose increment (5),
        the focal scale, ``k1`` and the principal-point offset (2); None with fewer than 6
        of them (the pose undetermined).
    variance : float
        ``s^2``, the noise variance of one Sampson residual.
    checked : ndarray of bool, shape (N,)
        The inliers behind it: :func:`checked_inliers` at the same pose.
    """

    info: np.ndarray | None
    variance: float
    checked: np.ndarray

    def sigmas_deg(
        self,
        *,
        focal_prior: float | None = FOCAL_PRIOR,
        k1_prior: float | None = None,
        principal_prior: np.ndarray | None = None,
        held_k1_prior: float | None = None,
    ) -> PoseSigmas:
        """:func:`pose_sigmas_deg` of this information under the given priors (its keywords)."""
        focal_prior = as_deviation(focal_prior, "focal_prior")
        k1_prior = as_deviation(k1_prior, "k1_prior", positive=True)
        principal_prior = as_deviation_pair(principal_prior, "principal_prior")
        held_k1_prior = as_deviation(held_k1_prior, "held_k1_prior")
        if self.info is None:
            return _UNDETERMINED
        info = self.info.copy()
        estimated = [*range(_NPOSE), *([_K1] if k1_prior is not None else [])]
        if k1_prior is not None:
            info[_K1, _K1] += self.variance / k1_prior**2
        considered, deviations = _considered_parameters(
            focal_prior, principal_prior, None if k1_prior is not None else held_k1_prior
        )
        fixed = info[np.ix_(estimated, considered)]
        return _pose_sigmas_deg(
            info[np.ix_(estimated, estimated)], self.variance, fixed, np.asarray(deviations, float)
        )


def pose_information(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    noise: float | None = None,
    step: float = 1e-6,
) -> PoseInformation:
    """The :class:`PoseInformation` of the pose ``(R, t)`` on the ``inliers`` that
    :func:`pose_sigmas_deg` takes (its parameters of the same names), whose
    :meth:`PoseInformation.sigmas_deg` gives the deviations under each set of priors without
    the Jacobians again."""
    t = require_pose_matches(R, t, x1, x2, inliers)
    noise = as_deviation(noise, "noise")
    step = as_positive_at_most(step, "step", 1e-2)
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    a, b = a / a[:, 2:], b / b[:, 2:]
    t = t / np.linalg.norm(t)
    residuals = _calibrated_residuals(R, t)
    kept, a, b, J, noise_info = _checked_jacobian_and_noise(residuals, a, b, step)
    checked = np.asarray(inliers, dtype=bool).copy()
    checked[np.flatnonzero(checked)[~kept]] = False
    if len(a) < MIN_CHECKED_INLIERS:
        return PoseInformation(None, float("nan"), checked)
    r0 = residuals(np.zeros((1, _NPARAMS)), a[None], b[None])[0]
    variance = float(r0 @ r0) / (len(a) - _NPOSE) if noise is None else float(noise) ** 2
    return PoseInformation(J.T @ J - variance * noise_info, variance, checked)


LEVERAGE_MAX = 0.5
"""Largest leverage of one match in the information of :func:`pose_sigmas_deg`. The leverage
``h_i = J_i (J^T J)^-1 J_i^T`` of match ``i`` is the share of its own residual that the pose
moves to fit it: above one half, the match sets a direction of the pose more than all the
others together, so its residual is no test of it (Huber's bound for a point that a least
squares fit cannot check). In a narrow field with a tiny baseline the Sampson error of a
match next to the epipole varies quickly with ``t``: a refined pose whose epipole lies on
one or two false matches (a few pixels off the true pose, a few hundredths of a pixel off
this one) holds them at leverage 0.97-0.999, and their information makes the bas-relief
valley that the other matches leave nearly flat look like a sharp minimum (``t`` 37-83
degrees off its truth with ``t_sigma_deg`` 0.2-2, the rotation 0.6-3 degrees off with a
deviation of 0.14-0.24 on ``tests/imperfect.py`` renders at baseline / depth 0.02-0.05)."""


def checked_matches(J: np.ndarray, leverage_max: float = LEVERAGE_MAX) -> np.ndarray:
    """Matches whose residual the others can check: a mask (N,) of the rows of the Jacobian
    ``J`` (N, P) whose leverage ``J_i (J^T J)^-1 J_i^T`` is at most ``leverage_max``.

    One pass: with a row left out the leverages of the others rise, and where the pose has a
    nearly flat direction (the bas-relief valley of a narrow field, or a few dozen matches) the
    matches nearest the epipole take turns above the bound, so leaving out in rounds would empty
    the set. The rows above it at the pose itself are those it rests on.

    Parameters
    ----------
    J : ndarray, shape (N, P)
        Jacobian of the residuals with respect to the estimated parameters.
    leverage_max : float
        Largest leverage kept, in (0, 1].

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    J = as_finite_array(J, "J")
    if J.ndim != 2:
        raise ValueError(f"J must have shape (N, P), got {J.shape}")
    leverage_max = as_positive_at_most(leverage_max, "leverage_max", 1.0)
    leverage = np.einsum("ij,jk,ik->i", J, np.linalg.pinv(J.T @ J), J)
    return leverage <= leverage_max


def checked_inliers(
    R: np.ndarray, t: np.ndarray, x1: np.ndarray, x2: np.ndarray, inliers: np.ndarray
) -> np.ndarray:
    """The inliers whose Sampson residual the other inliers check at the pose ``(R, t)``
    (:func:`checked_matches` of the Jacobian of the pose, leverage at most
    :data:`LEVERAGE_MAX`): ``inliers`` less the matches that set a direction of the pose by
    themselves, such as false matches on which the epipole was placed.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Pose, ``X2 = R X1 + t``.
    x1, x2 : ndarray, shape (N, 3)
        Normalised homogeneous coordinates of the matches.
    inliers : ndarray of bool, shape (N,)

    Returns
    -------
    ndarray of bool, shape (N,)
        A subset of ``inliers``; ``inliers`` itself with fewer than 6 of them.
    """
    t = require_pose_matches(R, t, x1, x2, inliers)
    inliers = np.asarray(inliers, dtype=bool)
    a, b = np.asarray(x1, float)[inliers], np.asarray(x2, float)[inliers]
    if len(a) < 6:
        return inliers
    t = t / np.linalg.norm(t)
    J = _jacobian(_calibrated_residuals(R, t), a / a[:, 2:], b / b[:, 2:], 1e-6)
    checked = inliers.copy()
    checked[np.flatnonzero(inliers)[~checked_matches(J[:, :_NPOSE])]] = False
    return checked


def _considered_parameters(focal_prior, principal_prior, held_k1_prior) -> tuple[list, list]:
    """Indices of the parameters of :func:`_calibrated_residuals` held at their given values
    and the deviations of their errors (those not None)."""
    considered, deviations = [], []
    if focal_prior is not None:
        considered.append(_FOCAL)
        deviations.append(focal_prior)
    if principal_prior is not None:
        considered += list(_PRINCIPAL)
        deviations += list(np.broadcast_to(np.asarray(principal_prior, float), (2,)))
    if held_k1_prior is not None:
        considered.append(_K1)
        deviations.append(held_k1_prior)
    return considered, deviations


_NPOSE = 5
_NPARAMS = 9  # pose increment (5), focal scale, k1, principal-point offset (2)
_FOCAL, _K1, _PRINCIPAL = 5, 6, (7, 8)
_ROTATION = slice(0, 3)
_TRANSLATION = slice(3, 5)


def _calibrated_residuals(R: np.ndarray, t: np.ndarray):
    """Signed Sampson residuals (P, N) for parameter rows (P, 9) and points (P or 1, N, 3).

    A row is (rotation increment ``w`` (3), tangent step ``v`` (2), focal scale ``s - 1``,
    ``k1``, principal-point offset ``p`` (2)); row ``p`` is evaluated on the points of row
    ``p`` (or on shared points). The rows are evaluated by chunks
    (:func:`ppo_cv.lsq.stack_by_chunks`), each row's figures those of the row alone.
    """
    U = tangent_basis(t)

    def lens(x: np.ndarray, p: np.ndarray) -> np.ndarray:
        x0, x1 = x[..., 0] - p[:, 7:8], x[..., 1] - p[:, 8:9]
        r2 = x0**2 + x1**2
        s = 1.0 + p[:, 5:6]
        factor = s * (1.0 - p[:, 6:7] * s * s * r2)
        out = np.empty((len(factor), 3, factor.shape[1]))
        np.multiply(x0, factor, out=out[:, 0])
        np.multiply(x1, factor, out=out[:, 1])
        out[:, 2] = 1.0
        return out

    def chunk(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        tp = t + p[:, 3:4] * U[0] + p[:, 4:5] * U[1]
        tp /= np.linalg.norm(tp, axis=1, keepdims=True)
        Rp = _rotation_increments(p[:, :3]) @ R
        return _sampson_by_coordinate(Rp, tp, lens(a, p), lens(b, p))

    def residuals(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        evaluate = lambda s: chunk(p[s], a if len(a) == 1 else a[s], b if len(b) == 1 else b[s])  # noqa: E731
        return stack_by_chunks(evaluate, len(p), a.shape[1])

    return residuals


def _jacobian_and_noise(residuals, a: np.ndarray, b: np.ndarray, step: float):
    """Jacobian ``J`` (N, 9) at 0 and ``sum_i G_i G_i^T`` (9, 9), by central differences.

    ``G_i`` (9, 4), the derivative of row ``i`` of ``J`` with respect to the image coordinates
    ``(x1, y1, x2, y2)`` of match ``i`` (each moved by ``+-sqrt(step)``), is what unit image
    noise adds to ``J^T J``. Being an expectation, the sum is estimated on at most
    :data:`_NOISE_SAMPLE` evenly spaced matches and scaled to all of them.
    """
    dp = _steps(step)
    J = _jacobian(residuals, a, b, step)
    sample = np.unique(np.linspace(0, len(a) - 1, min(len(a), _NOISE_SAMPLE)).astype(int))
    h = np.sqrt(step)
    shifts = np.zeros((8, 2, 1, 3))
    for k, (view, axis, sign) in enumerate(np.ndindex(2, 2, 2)):
        shifts[k, view, 0, axis] = -h if sign else h
    points = np.repeat(np.stack([a[sample], b[sample]])[None] + shifts, len(dp), axis=0)
    r = residuals(np.tile(dp, (8, 1)), points[:, 0], points[:, 1]).reshape(8, 2, _NPARAMS, -1)
    jac = (r[:, 0] - r[:, 1]) / (2.0 * step)  # (8, 9, n): coordinate k, moved + (even) or -
    G = (jac[0::2] - jac[1::2]) / (2.0 * h)  # (4, 9, n)
    return J, np.einsum("cpn,cqn->pq", G, G) * (len(a) / len(sample))


_NOISE_SAMPLE = 256


def _checked_jacobian_and_noise(residuals, a: np.ndarray, b: np.ndarray, step: float) -> tuple:
    """The mask (N,) of the matches :func:`checked_matches` keeps (all with fewer than 6),
    their points ``a``, ``b`` and their :func:`_jacobian_and_noise` (None with fewer than 6
    matches)."""
    checked = np.ones(len(a), dtype=bool)
    if len(a) < 6:
        return checked, a, b, None, None
    J, noise_info = _jacobian_and_noise(residuals, a, b, step)
    checked = checked_matches(J[:, :_NPOSE])
    if checked.all():
        return checked, a, b, J, noise_info
    a, b = a[checked], b[checked]
    return checked, a, b, *_jacobian_and_noise(residuals, a, b, step)


def _steps(step: float) -> np.ndarray:
    return np.concatenate([np.eye(_NPARAMS), -np.eye(_NPARAMS)]) * step


def _jacobian(residuals, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """Jacobian (N, 9) of :func:`_calibrated_residuals` at 0, by central differences."""
    r = residuals(_steps(step), a[None], b[None])
    return ((r[:_NPARAMS] - r[_NPARAMS:]) / (2.0 * step)).T


def _pose_sigmas_deg(
    info: np.ndarray, variance: float, fixed: np.ndarray, fixed_sigma: np.ndarray
) -> PoseSigmas:
    """Deviations (degrees) of the rotation and translation of ``variance * info^-1``, with
    held parameters.

    ``fixed`` (P, F) is the cross information of the estimated parameters with F held at their
    given values, whose errors have deviations ``fixed_sigma`` (F,): they move the estimate by
    ``S = -info^-1 fixed`` per unit, adding ``S diag(fixed_sigma^2) S^T`` to the covariance
    (considered parameters, Schmidt). Undetermined when ``info`` is not positive definite.
    """
    w, V = np.linalg.eigh(info)
    if w[0] <= 1e-12 * max(abs(w[-1]), 1e-300):
        return _UNDETERMINED
    inverse = (V / w) @ V.T
    cov = variance * inverse
    S = inverse @ fixed
    cov = cov + (S * fixed_sigma**2) @ S.T

    worst = np.linalg.eigvalsh(cov[_TRANSLATION, _TRANSLATION])[-1]
    return PoseSigmas(
        rotation_deg=_rms_rotation_angle_deg(cov[_ROTATION, _ROTATION]),
        translation_deg=min(float(np.degrees(np.sqrt(max(worst, 0.0)))), T_SIGMA_CAP_DEG),
    )
