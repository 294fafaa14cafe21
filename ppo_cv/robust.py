"""Robust estimation of the essential matrix from putative matches.

Two backends, both fed normalized (undistorted) image coordinates ``x = K^-1 [u, v, 1]``:

- ``"pycolmap"``: COLMAP's LO-RANSAC on the 5-point solver with the tangent Sampson error
  (``pycolmap.estimate_relative_pose``); the default, the more accurate on real pairs.
- ``"opencv"``: OpenCV's USAC with MAGSAC++ scoring (``cv2.findEssentialMat(..., USAC_MAGSAC)``).

The threshold is given in pixels and converted to normalized units with one focal length ``f``:
the points are handed to the backends as those of a virtual pinhole camera ``(f, f, 0, 0)``, so
two cameras with different intrinsics share one error scale.

:func:`estimate_essential_ordered` samples by match quality around either backend (the idea
of PROSAC, Chum and Matas 2005: the best-ranked matches are far more often inliers): a robust
fit on the best-ranked matches, where the inlier ratio is higher and the adaptive stop comes
after far fewer trials, a second fit on the consensus of that model over all matches, and the
full fit (capped) only when the result is not significant (:mod:`ppo_cv.significance`).

The full fit of a weak result stops by the evidence it can still gain: after ``t`` hypotheses,
an untested consensus of ``k`` of ``n`` matches has given no all-inlier sample with probability
``(1 - q_k)^t``, ``q_k = prod_{i<5} (k - i) / (n - i)``. Only a consensus at least as large as
the best so far (``k_best``) and as the smallest that could pass the significance bar
(``k_sig``, :func:`ppo_cv.significance.smallest_significant_consensus`) can change the answer,
so the fit stops once ``(1 - q_k)^t`` falls below ``eta``
(:data:`ppo_cv.significance.MISSED_CONSENSUS_PROBABILITY`) for ``k = max(k_best, k_sig)``:
the backend's adaptive stop at confidence ``1 - eta`` (``k_best``) and a cap of
:func:`trials_for_consensus` of ``k_sig`` hypotheses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .checks import (
    MAX_COORDINATE,
    MAX_FOCAL,
    MAX_WHOLE_NUMBER,
    as_camera_matrix,
    as_finite_array,
    as_flag,
    as_image_rows,
    as_image_size,
    as_number,
    as_positive,
    as_positive_at_most,
    as_ransac_settings,
    as_real_array,
    as_rotation,
    as_vector3,
    as_whole_number,
)
from .lsq import _cross_matrix
from .significance import (
    ESSENTIAL_SAMPLE_SIZE,
    MISSED_CONSENSUS_PROBABILITY,
    epipolar_significance,
    smallest_significant_consensus,
)

__all__ = [
    "ROBUST_BACKENDS",
    "RobustEstimate",
    "estimate_essential",
    "estimate_essential_ordered",
    "ORDERED_FRACTION",
    "ORDERED_MIN_MATCHES",
    "ORDERED_MAX_TRIALS",
    "CONSENSUS_FACTOR",
    "FALLBACK_MAX_LOG10_NFA",
    "FALLBACK_MAX_TRIALS",
    "ORDERED_TRUSTED_LOG10_NFA",
    "essential_from_pose",
    "sampson_errors",
    "sampson_signed",
    "sampson_signed_rows",
    "trials_for_consensus",
]

ROBUST_BACKENDS = ("pycolmap", "opencv")

POSE_AGREEMENT = 0.5
"""Share of pycolmap's inliers the pose it returns must explain within the threshold; below it
the essential matrix of its RANSAC is used instead of that pose."""
ORDERED_FRACTION = 0.5
"""Share of the matches, best-ranked first, that the first fit of ordered sampling sees."""
ORDERED_MIN_MATCHES = 30
"""The first fit sees at least this many matches (all of them when there are fewer)."""
ORDERED_MAX_TRIALS = 10_000
"""Cap on the hypotheses of each of the two fits of ordered sampling."""
CONSENSUS_FACTOR = 3.0
"""The second fit runs on the matches within this many thresholds of the first fit's model."""
FALLBACK_MAX_LOG10_NFA = -5.0
"""Ordered sampling falls back to the full fit when ``log10 NFA`` of its model is above this:
a margin below the textbook a-contrario bar 0 (one consensus this good expected by chance),
because a wrong model found on the ranked subset can gather a consensus near that bar (on the
freiburg pairs the bar -5 kept the mean AUC closer to the full fit's than 0)."""
FALLBACK_MAX_TRIALS = 30_000
"""Least budget of the fallback fit over all matches (at most ``max_trials``); it has more when a
rival consensus as large as the ordered one needs more to give an all-inlier sample with
probability ``1 - eta`` (:func:`trials_for_consensus`), and the full ``max_trials`` when the
ordered result would be weak (``log10 NFA`` above ``ORDERED_TRUSTED_LOG10_NFA`` or
``max_log10_nfa``)."""
ORDERED_TRUSTED_LOG10_NFA = 0.0
"""Above this ``log10 NFA`` an ordered result is always replaced by the full fit over all matches.
The significance test of :mod:`ppo_cv.significance` (its bar and the distinctiveness test of a
weak consensus) is calibrated on uniform sampling, under which chance consensus scored +2.95 and
above; sampling the distinctive matches first let a chance consensus of two unrelated renders
score +2.79, and biases the distinctiveness test. At the textbook bar 0 (one consensus this good
expected by chance) and above, the decision is therefore made on the uniform fit."""


@dataclass(frozen=True)
class RobustEstimate:
    """Essential matrix and inliers of a robust fit.

    Attributes
    ----------
    E : ndarray, shape (3, 3)
        Essential matrix, ``x2^T E x1 = 0``, unit Frobenius norm.
    inliers : ndarray of bool, shape (N,)
        Matches within the threshold of ``E``.
    backend : str
        The backend that produced it.
    sampling : str
        ``"uniform"``: one fit over all matches; ``"ordered"``: the ordered-sampling fits of
        :func:`estimate_essential_ordered`; ``"fallback"``: ordered sampling was not
        significant and the full fit over all matches found more inliers.
    """

    E: np.ndarray
    inliers: np.ndarray
    backend: str
    sampling: str = "uniform"

    @property
    def num_inliers(self) -> int:
        """Number of inliers."""
        return int(np.count_nonzero(self.inliers))


def essential_from_pose(R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """``E = [t]_x R`` (3, 3) normalised to unit Frobenius norm, of a rotation ``R`` (3, 3) and
    a translation ``t`` (3,) of any nonzero finite length; ValueError or TypeError naming the
    argument otherwise (a zero ``t``, a pure rotation, has no essential matrix).

    ``t`` is first rescaled by a power of two, exactly: the same ``E`` for any length
    (1e-310 or 1e300), whose norm would otherwise underflow or overflow.
    """
    R, t = as_rotation(R, "R"), as_vector3(t, "t")
    largest = float(np.abs(t).max())
    if largest == 0:
        raise ValueError("t is zero: a pure rotation has no essential matrix")
    return _essential_from_pose(R, np.ldexp(t, -math.frexp(largest)[1]))


def _essential_from_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """:func:`essential_from_pose`, unchecked (a zero ``t`` gives a zero ``E``)."""
    E = _cross_matrix(t) @ R
    return E / max(np.linalg.norm(E), 1e-300)


def _checked_sampson(E: Any, x1: Any, x2: Any, by_coordinate: bool) -> tuple:
    """``E`` (..., 3, 3) rescaled by powers of two to a largest entry in [0.5, 1), each matrix
    of a stack on its own (exactly: the residuals do not depend on the scale of ``E``), and
    the points (..., N, 3), or (..., 3, N) ``by_coordinate``, finite, of magnitude at most
    :data:`ppo_cv.checks.MAX_COORDINATE` and as many in each image, the leading axes of all
    three broadcasting; ValueError or TypeError naming the argument otherwise."""
    E = as_finite_array(E, "E")
    if E.ndim < 2 or E.shape[-2:] != (3, 3):
        raise ValueError(f"E must be a 3x3 matrix or a stack (..., 3, 3), got shape {E.shape}")
    largest = np.abs(E).max(axis=(-2, -1), keepdims=True)
    if not largest.all():
        raise ValueError("E is all zeros: it defines no epipolar geometry")
    axis, (name1, name2) = (-2, "X1 X2".split()) if by_coordinate else (-1, "x1 x2".split())
    x1, x2 = _checked_sampson_points(x1, name1, axis), _checked_sampson_points(x2, name2, axis)
    n1, n2 = x1.shape[-1 if by_coordinate else -2], x2.shape[-1 if by_coordinate else -2]
    if n1 != n2:
        raise ValueError(f"{name1} and {name2} must hold as many matches, got {n1} and {n2}")
    try:
        np.broadcast_shapes(E.shape[:-2], x1.shape[:-2], x2.shape[:-2])
    except ValueError:
        raise ValueError(
            f"the leading axes of E {E.shape}, {name1} {x1.shape} and {name2} {x2.shape} do "
            "not broadcast"
        ) from None
    return np.ldexp(E, -np.frexp(largest)[1]), x1, x2


def _checked_sampson_points(value: Any, name: str, axis: int) -> np.ndarray:
    """Homogeneous image points, coordinates along ``axis``, each divided by its ``w`` (the
    residuals are those of the image points ``(x / w, y / w)``; ``x`` and ``y`` were read as
    they stood, a wrong residual for a bearing vector)."""
    points = as_finite_array(value, name)
    if points.ndim < 2 or points.shape[axis] != 3:
        wanted = "(..., 3, N)" if axis == -2 else "(N, 3) or (..., N, 3)"
        raise ValueError(f"{name} must have shape {wanted}, got {points.shape}")
    w = points[..., 2, :] if axis == -2 else points[..., 2]
    if not (w == 1.0).all():
        if not w.all():
            raise ValueError(
                f"{name} has {int(np.count_nonzero(w == 0))} point(s) with w = 0 (at infinity): "
                "not image points"
            )
        points = points / np.expand_dims(w, axis)
    if points.size and not -MAX_COORDINATE <= points.min() <= points.max() <= MAX_COORDINATE:
        raise ValueError(
            f"{name} has coordinates up to {float(np.abs(points).max()):.3g}, beyond "
            f"{MAX_COORDINATE:.0e}: not normalized points"
        )
    return points


def sampson_signed(E: ArrayLike, x1: ArrayLike, x2: ArrayLike) -> np.ndarray:
    """Signed Sampson residual (normalized units) of each match to ``E``.

    ``x2^T E x1 / sqrt((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)``, the first-order
    geometric distance of the match to the epipolar constraint with the sign of ``x2^T E x1``.
    ``E`` (..., 3, 3) and the points (..., N, 3) broadcast to (..., N); ValueError or TypeError
    naming the argument for anything else, a non-finite entry or an all-zero ``E``.
    """
    return _sampson_signed(*_checked_sampson(E, x1, x2, by_coordinate=False))


def _sampson_signed(E: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """:func:`sampson_signed`, unchecked. The sums run over the coordinate columns one by one,
    in the order a sum along the last axis takes them (the same figures, a third of the time
    of ``np.sum`` over a length-3 axis: 500 matches 83 -> 27 us; the refinements call it for
    every step and Jacobian column)."""
    Ex1, Etx2 = x1 @ np.swapaxes(E, -1, -2), x2 @ E
    line1, line2 = Ex1[..., 0], Ex1[..., 1]
    back1, back2 = Etx2[..., 0], Etx2[..., 1]
    denominator = np.sqrt((line1 * line1 + line2 * line2) + (back1 * back1 + back2 * back2))
    residual = (x2[..., 0] * line1 + x2[..., 1] * line2) + x2[..., 2] * Ex1[..., 2]
    return residual / np.maximum(denominator, 1e-300)


def sampson_signed_rows(E: ArrayLike, X1: ArrayLike, X2: ArrayLike) -> np.ndarray:
    """:func:`sampson_signed` of points laid out by coordinate: ``E`` (..., 3, 3) and the
    points (..., 3, N), ``X[..., i, :]`` coordinate ``i`` of every match, broadcast to
    (..., N); checked as :func:`sampson_signed` checks its arguments.
    """
    return _sampson_signed_rows(*_checked_sampson(E, X1, X2, by_coordinate=True))


def _sampson_signed_rows(E: np.ndarray, X1: np.ndarray, X2: np.ndarray) -> np.ndarray:
    """:func:`sampson_signed_rows`, unchecked. The same figures as :func:`_sampson_signed`
    (each product of ``E`` and a point is the same three-term sum, the rest the same
    operations in the same order), faster where many ``E`` meet many points: the products and
    every pass after them run along contiguous rows."""
    Ex1, Etx2 = E @ X1, np.swapaxes(E, -1, -2) @ X2
    line1, line2 = Ex1[..., 0, :], Ex1[..., 1, :]
    back1, back2 = Etx2[..., 0, :], Etx2[..., 1, :]
    denominator = np.sqrt((line1 * line1 + line2 * line2) + (back1 * back1 + back2 * back2))
    residual = (X2[..., 0, :] * line1 + X2[..., 1, :] * line2) + X2[..., 2, :] * Ex1[..., 2, :]
    return residual / np.maximum(denominator, 1e-300)


def sampson_errors(E: ArrayLike, x1: ArrayLike, x2: ArrayLike) -> np.ndarray:
    """Sampson distance (normalized units) of each match to ``E``, shape (N,) (or (..., N)
    for a stack): the absolute value of :func:`sampson_signed`, checked as it is; multiply by
    the focal length for pixels."""
    return np.abs(sampson_signed(E, x1, x2))


def _sampson_errors(E: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """:func:`sampson_errors`, unchecked."""
    return np.abs(_sampson_signed(E, x1, x2))


def virtual_camera(focal: float, width: int = 0, height: int = 0):
    """A pycolmap pinhole camera ``(f, f, 0, 0)`` in which ``f * x[:, :2]`` are pixel points."""
    import pycolmap

    return pycolmap.Camera(
        model="PINHOLE",
        width=max(int(width), 1),
        height=max(int(height), 1),
        params=[focal, focal, 0.0, 0.0],
    )


def checked_rays(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Two arrays of matched homogeneous image points as contiguous float64 (N, 3), all finite,
    of ``w = 1`` (:func:`ppo_cv.checks.as_image_rows` divides a row of another ``w`` by it); a
    ValueError or TypeError naming ``x1`` or ``x2`` otherwise, or when their lengths differ."""
    x1, x2 = as_image_rows(x1, x2)
    return np.ascontiguousarray(x1), np.ascontiguousarray(x2)


def checked_fit_settings(
    focal: Any, threshold: Any, confidence: Any, min_trials: Any, max_trials: Any, seed: Any
) -> tuple[float, float, float, int, int, int]:
    """``(focal, threshold, confidence, min_trials, max_trials, seed)`` of a robust fit checked:
    a positive focal length, the rest as :func:`ppo_cv.checks.as_ransac_settings` checks them;
    ValueError or TypeError naming the argument."""
    focal = as_positive(focal, "focal")
    return (focal, *as_ransac_settings(threshold, confidence, min_trials, max_trials, seed))


def ransac_options(threshold, confidence, min_trials, max_trials, seed, multiplier=3.0):
    """``pycolmap.RANSACOptions`` for a pixel ``threshold``, trial bounds, a seed and the factor
    on the hypotheses of the adaptive stop (COLMAP's ``dyn_num_trials_multiplier``)."""
    import pycolmap

    options = pycolmap.RANSACOptions()
    options.max_error = threshold
    options.confidence = confidence
    options.dyn_num_trials_multiplier = float(multiplier)
    options.max_num_trials = int(max_trials)
    options.min_num_trials = min(int(min_trials), int(max_trials))
    options.random_seed = int(seed)
    return options


def _pycolmap(x1, x2, focal, threshold, confidence, min_trials, max_trials, seed, multiplier):
    import pycolmap

    options = ransac_options(threshold, confidence, min_trials, max_trials, seed, multiplier)
    camera = virtual_camera(focal)
    points1, points2 = focal * x1[:, :2], focal * x2[:, :2]
    found = pycolmap.estimate_relative_pose(camera, points1, camera, points2, options)
    if found is None:
        return None
    pose = found["cam2_from_cam1"]
    E = _essential_from_pose(pose.rotation.matrix(), np.asarray(pose.translation).ravel())
    mask = np.asarray(found["inlier_mask"]).reshape(-1).astype(bool)
    agree = np.count_nonzero(_sampson_errors(E, x1[mask], x2[mask]) < threshold / focal)
    if agree < POSE_AGREEMENT * np.count_nonzero(mask):
        # the pose pycolmap decomposed its E into can disagree with it (seen with a principal
        # point 10 px off: none of the model's inliers fit the pose); then E itself
        found = pycolmap.estimate_essential_matrix(points1, points2, camera, camera, options)
        if found is None:
            return None
        E = np.asarray(found["E"], dtype=np.float64)
        E, mask = E / np.linalg.norm(E), np.asarray(found["inlier_mask"]).reshape(-1) != 0
    return E, mask


def _opencv(x1, x2, focal, threshold, confidence, min_trials, max_trials, seed, multiplier):
    import cv2

    cv2.setRNGSeed(int(seed))
    E, mask = cv2.findEssentialMat(
        x1[:, :2],
        x2[:, :2],
        np.eye(3),
        cv2.USAC_MAGSAC,
        confidence,
        threshold / focal,
        int(max_trials),
    )
    if E is None or mask is None or E.shape[0] < 3:
        return None
    E = E[:3]
    return E / np.linalg.norm(E), mask.reshape(-1) != 0


def estimate_essential(
    x1: np.ndarray,
    x2: np.ndarray,
    focal: float,
    *,
    backend: str = "pycolmap",
    threshold: float = 1.0,
    confidence: float = 0.9999,
    min_trials: int = 100,
    max_trials: int = 100_000,
    seed: int = 0,
    trials_multiplier: float = 3.0,
) -> RobustEstimate | None:
    """Robustly fit an essential matrix to normalized correspondences.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous image coordinates (last entry 1) of the matches, N >= 5.
    focal : float
        Focal length (pixels) that converts ``threshold`` to normalized units.
    backend : {"pycolmap", "opencv"}
        Robust estimator.
    threshold : float
        Inlier threshold on the epipolar (Sampson) error, pixels.
    confidence : float
        Stop when a better model is this unlikely to be missed.
    min_trials, max_trials : int
        Bounds on the number of hypotheses (``min_trials`` is ignored by OpenCV).
    seed : int
        Seed of the sampler, for repeatable results.
    trials_multiplier : float
        pycolmap draws this many times the hypotheses its adaptive stop computes from
        ``confidence`` and the best consensus (ignored by OpenCV).

    Returns
    -------
    RobustEstimate or None
        None when the backend finds no model.
    """
    if backend not in ROBUST_BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(ROBUST_BACKENDS)}")
    x1, x2 = checked_rays(x1, x2)
    settings = checked_fit_settings(focal, threshold, confidence, min_trials, max_trials, seed)
    multiplier = as_positive(trials_multiplier, "trials_multiplier")
    fit = _pycolmap if backend == "pycolmap" else _opencv
    found = fit(x1, x2, *settings, multiplier)
    if found is None or not found[1].any():
        return None
    return RobustEstimate(E=found[0], inliers=found[1], backend=backend)


def estimate_essential_ordered(
    x1: np.ndarray,
    x2: np.ndarray,
    focal: float,
    scores: np.ndarray,
    image_size: tuple[int, int],
    *,
    backend: str = "pycolmap",
    threshold: float = 1.0,
    confidence: float = 0.9999,
    min_trials: int = 100,
    max_trials: int = 100_000,
    seed: int = 0,
    max_log10_nfa: float = 5.0,
    K2: np.ndarray | None = None,
    uniform_when_weak: bool = True,
) -> RobustEstimate | None:
    """Robust essential matrix sampling the best-ranked matches first.

    1. Fit (:func:`estimate_essential`, at most ``ORDERED_MAX_TRIALS`` hypotheses) on the
       ``max(ORDERED_FRACTION * N, ORDERED_MIN_MATCHES)`` matches of lowest ``scores``.
    2. Fit again on the consensus of that model over all N matches: those within
       ``CONSENSUS_FACTOR * threshold`` (Sampson error), nearly all inliers, so the adaptive
       stop comes after ``min_trials``; its local optimisation then sees every inlier.
       The inliers are the matches within ``threshold`` of the result.
    3. When the result's ``log10 NFA`` (:func:`ppo_cv.significance.epipolar_significance`) is
       above ``FALLBACK_MAX_LOG10_NFA``, fit all N matches (as many hypotheses as a rival
       consensus of as many inliers needs, :data:`FALLBACK_MAX_TRIALS` to ``max_trials``),
       refit that model on its consensus as in step 2, and keep whichever has more
       inliers. A weak result (``log10 NFA`` above ``max_log10_nfa`` or
       ``ORDERED_TRUSTED_LOG10_NFA``) is replaced by the full fit as it is (no refit), the
       consensus that the significance test was calibrated on (uniform sampling alone), of
       at most ``max_trials`` hypotheses and stopped by the evidence it can still gain
       (module docstring); with ``uniform_when_weak`` False that fit is left to the caller:
       ordered sampling has not settled the matches, and None says so.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates of the matches.
    focal : float
        Focal length (pixels) that converts ``threshold`` to normalized units.
    scores : ndarray, shape (N,)
        Quality of each match, lower is better (the ratio-test distance ratio of
        :func:`ppo_cv.features.match_features_scored`).
    image_size : tuple of int
        ``(width, height)`` of image 2, for the significance test.
    backend, threshold, confidence, min_trials, max_trials, seed
        As :func:`estimate_essential`; ``max_trials`` also caps each stage.
    max_log10_nfa : float
        The significance bar the caller refuses a pose above
        (:attr:`ppo_cv.pipeline.PairOptions.max_log10_nfa`).
    K2 : ndarray, shape (3, 3), optional
        Intrinsics of camera 2 for the significance test; by default ``focal`` with the
        principal point at the centre of ``image_size``.
    uniform_when_weak : bool
        Run the full fit of a weak result (step 3); False returns None instead, for a caller
        with other matches of the same images to try first.

    Returns
    -------
    RobustEstimate or None
        ``sampling`` says which fit it is; None when no fit finds a model, or when ordered
        sampling is weak and ``uniform_when_weak`` is False.
    """
    x1, x2, scores = _scored_matches(x1, x2, scores)
    image_size, K2 = _ordered_fit_settings(image_size, K2, focal, uniform_when_weak, max_log10_nfa)
    settings = {
        "backend": backend,
        "threshold": threshold,
        "confidence": confidence,
        "min_trials": min_trials,
        "seed": seed,
    }
    n = x1.shape[0]
    size = min(n, max(ORDERED_MIN_MATCHES, int(np.ceil(ORDERED_FRACTION * n))))
    best = np.argsort(scores, kind="stable")[:size]
    cap = min(int(max_trials), ORDERED_MAX_TRIALS)
    found = estimate_essential(x1[best], x2[best], focal, max_trials=cap, **settings)
    fit = None if found is None else _consensus_fit(found.E, x1, x2, focal, cap, settings)
    nfa = np.inf
    if fit is not None:
        nfa = epipolar_significance(fit.E, x1, x2, K2, image_size).log10_nfa
        if nfa <= FALLBACK_MAX_LOG10_NFA:
            return fit
    if not nfa <= min(max_log10_nfa, ORDERED_TRUSTED_LOG10_NFA):
        if not uniform_when_weak:
            return None
        full = _uniform_fit_to_evidence(
            x1, x2, focal, image_size, max_trials, max_log10_nfa, settings
        )
        return None if full is None else RobustEstimate(full.E, full.inliers, backend, "fallback")
    rival = trials_for_consensus(fit.num_inliers, n, MISSED_CONSENSUS_PROBABILITY)
    cap = int(min(int(max_trials), max(FALLBACK_MAX_TRIALS, rival)))
    full = estimate_essential(x1, x2, focal, max_trials=cap, **settings)
    if full is not None:
        full = _consensus_fit(full.E, x1, x2, focal, cap, settings) or full
    if full is not None and (fit is None or full.num_inliers > fit.num_inliers):
        return RobustEstimate(full.E, full.inliers, backend, "fallback")
    return fit


def _ordered_fit_settings(image_size, K2, focal, uniform_when_weak, max_log10_nfa) -> tuple:
    """:func:`estimate_essential_ordered`'s image size and ``K2`` checked (by default
    ``focal`` with the principal point at the image's centre), with its flag and its
    significance bar (a number, not NaN); ValueError or TypeError naming each."""
    as_flag(uniform_when_weak, "uniform_when_weak")
    if as_number(max_log10_nfa, "max_log10_nfa") != max_log10_nfa:
        raise ValueError("max_log10_nfa must be a number (inf: every consensus), got nan")
    width, height = as_image_size(image_size, "image_size")
    if K2 is None:
        f = as_positive_at_most(focal, "focal", MAX_FOCAL, " pixels")
        K2 = np.array([[f, 0.0, width / 2], [0.0, f, height / 2], [0.0, 0.0, 1.0]])
    return (width, height), as_camera_matrix(K2, "K2")


def _scored_matches(x1, x2, scores) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``x1``, ``x2`` checked by :func:`checked_rays` and ``scores`` as a flat float64 array;
    ValueError unless there is one finite score per match."""
    x1, x2 = checked_rays(x1, x2)
    scores = as_real_array(scores, "scores").reshape(-1)
    if scores.shape[0] != x1.shape[0] or x1.shape != x2.shape:
        raise ValueError(
            f"need one score per match: x1 {x1.shape}, x2 {x2.shape}, scores {scores.shape}"
        )
    if not np.all(np.isfinite(scores)):
        raise ValueError("scores must be finite")
    return x1, x2, scores


def trials_for_consensus(
    consensus: int,
    num_matches: int,
    miss_probability: float,
    sample_size: int = ESSENTIAL_SAMPLE_SIZE,
) -> float:
    """Hypotheses after which a consensus has given an all-inlier sample with probability
    ``1 - miss_probability``.

    Uniform samples of ``sample_size`` distinct matches of ``num_matches`` hold only matches of
    a consensus of ``consensus`` with probability ``q = prod_{i < s} (k - i) / (n - i)``; after
    ``t`` samples none did with probability ``(1 - q)^t``. Returns the smallest ``t`` that
    brings that to ``miss_probability`` or below: ``ceil(log(eta) / log(1 - q))``, ``math.inf``
    when no sample can be all inliers (``consensus`` or ``num_matches`` below ``sample_size``).

    >>> trials_for_consensus(20, 100, 0.05)
    14546.0
    """
    consensus, num_matches = (as_whole_number(value, name, 0, MAX_WHOLE_NUMBER) for name, value
                              in (("consensus", consensus), ("num_matches", num_matches)))
    sample_size = as_whole_number(sample_size, "sample_size", 1, MAX_WHOLE_NUMBER)
    if not 0.0 < as_number(miss_probability, "miss_probability") < 1.0:
        raise ValueError(f"miss_probability must lie in (0, 1), got {miss_probability}")
    if min(consensus, num_matches) < sample_size:
        return math.inf
    i = np.arange(sample_size)
    all_inliers = float(np.prod((consensus - i) / (num_matches - i)))
    if all_inliers >= 1.0:
        return 1.0
    return float(math.ceil(math.log(miss_probability) / math.log1p(-all_inliers)))


def _uniform_fit_to_evidence(x1, x2, focal, image_size, max_trials, max_log10_nfa, settings):
    """The full fit of a weak ordered result, at most ``max_trials`` hypotheses, stopped by the
    evidence it can still gain (module docstring)."""
    n = x1.shape[0]
    smallest = smallest_significant_consensus(n, image_size, settings["threshold"], max_log10_nfa)
    cap = int(min(int(max_trials), trials_for_consensus(smallest, n, MISSED_CONSENSUS_PROBABILITY)))
    stop = {
        **settings,
        "confidence": min(settings["confidence"], 1.0 - MISSED_CONSENSUS_PROBABILITY),
        "trials_multiplier": 1.0,
    }
    return estimate_essential(x1, x2, focal, max_trials=cap, **stop)


def _consensus_fit(E, x1, x2, focal, cap, settings) -> RobustEstimate | None:
    """Refit on the matches near ``E``; inliers over all matches within the threshold."""
    threshold = settings["threshold"] / focal
    near = np.flatnonzero(_sampson_errors(E, x1, x2) < CONSENSUS_FACTOR * threshold)
    if near.size >= 5:
        again = estimate_essential(x1[near], x2[near], focal, max_trials=cap, **settings)
        E = E if again is None else again.E
    inliers = _sampson_errors(E, x1, x2) < threshold
    if not inliers.any():
        return None
    return RobustEstimate(E, inliers, settings["backend"], "ordered")
