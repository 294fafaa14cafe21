"""A pair decided with a guessed camera, decided again with the focal length its matches imply.

Without a calibration the focal length is guessed (EXIF, or 1.2 times the larger image side).
A guess a few percent off leaves a rotation's matches a residual that a translation explains
better, so a tripod pair is called general motion: on ``pano_dev``'s ``book`` pairs the EXIF
focal length is 8 % short. The homography of the inliers tells the focal length that makes it
a rotation (:func:`homography_rotation_focal`, Hartley & Zisserman 8.8 / 19.3); where
that homography is then close to a rotation (:data:`GUESSED_FOCAL_SPREAD`) and the focal
length moves (:data:`MIN_FOCAL_REFIT`), the pair is decided again with it
(:func:`fitted_focal_scale` decides, :func:`decided_again` runs it), and that
decision is reported only when it is a pure rotation. The homography has no lens: an unmodelled
radial distortion moves its focal length by several percent, beyond the rotation-only fit's
box (:data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`) about it, so where that decision is no rotation
the pair is decided a third time with the focal length of the rotation-only fit with its radial
term, freed about the homography's (:func:`lens_focal_scale`). Focal length and radial term
trade against each other along a valley of almost equal residuals, and where that fit stays
at the homography's focal length, or its decision is no rotation either, the second decision's
own rotation-only fit may have asked for a focal length beyond its box: its inliers'
homography, corrected by the lens that fit found, made a rotation by one focal length
(:func:`clipped_lens_focal_scale`). The pair is then decided with that one, the fit inside its
box, both models on that camera. ``ppo-cv pair`` and ``pairs`` report the rotation so found
(:func:`decide_with_fitted_focal`), and ``ppo-cv sfm`` refuses it as an initial pair
(:mod:`ppo_cv.sfm`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .camera import pixels_to_normalized
from .checks import (
    MAX_WHOLE_NUMBER,
    as_finite_rows,
    as_positive,
    as_whole_number,
    require_instance,
    shown,
)
from .homography import estimate_homography
from .parallax import nearest_rotation_log_scale, rotation_spread
from .result import PairResult

__all__ = [
    "FIELD_RANGE_DEG",
    "GUESSED_FOCAL_SPREAD",
    "HOMOGRAPHY_CONFIDENCE",
    "LENS_FOCAL_BOX",
    "LENS_FOCAL_PRIOR",
    "LENS_START_THRESHOLD",
    "MIN_FOCAL_REFIT",
    "clipped_lens_focal_scale",
    "decide_with_fitted_focal",
    "decided_again",
    "fitted_focal_scale",
    "homography_rotation_focal",
    "lens_focal_scale",
    "rotation_focal_scale",
]

GUESSED_FOCAL_SPREAD = 0.05
"""Largest ``log(sigma_1 / sigma_3)`` of the matches' homography, conjugated by the focal length
that makes it nearest a rotation (:func:`homography_rotation_focal`), for which a
pair decided with a guessed camera is decided again with that focal length: 0.0018 to 0.031 on
the 53 pano_dev tripod pairs their EXIF focal lengths call no rotation, 0.047 to 3.3 on the 79
freiburg translating pairs with a homography under the 1.2 x image size guess, where the later
runs only cost time (the one at 0.047 stays general motion)."""

MIN_FOCAL_REFIT = 0.01
"""Relative change of the focal length below which a pair is not decided again."""

LENS_FOCAL_PRIOR = 0.2
"""Deviation of the prior on the focal scale of :func:`lens_focal_scale`'s rotation-only fit,
about the homography's focal length: that one is 2-9 % off on rendered tripod pans through
lenses of ``k1`` -0.04 to +0.09 (``ppo_cv.data_gen.REAL_PHOTO``), the fit within 4.4 %; the
prior only regularises."""

LENS_FOCAL_BOX = 0.5
"""Box of that fit's ``|s - 1|``; a focal scale clipped to it is no focal length."""

LENS_START_THRESHOLD = 3.0
"""Bound on the transfer error of that fit's matches, in RANSAC thresholds: the homography's
focal length and the radial term it lacks leave a rotation's edge matches a few pixels off (at 1,
one of those pans was fitted 6.4 % short)."""


def fitted_focal_scale(result: PairResult) -> float | None:
    """Scale of the guessed focal length with which ``result``'s pair is worth deciding again:
    the one that makes the homography of its inliers a rotation, when that homography is then
    within :data:`GUESSED_FOCAL_SPREAD` of one and the scale departs from 1 by at least
    :data:`MIN_FOCAL_REFIT` (log); None otherwise, and for a pure rotation."""
    _require_result(result)
    if result.pure_rotation:
        return None
    cameras, used = result.cameras, result.matches[result.inliers]
    x1 = pixels_to_normalized(result.keypoints1[used[:, 0]], cameras.K1, cameras.dist1)
    x2 = pixels_to_normalized(result.keypoints2[used[:, 1]], cameras.K2, cameras.dist2)
    fit = homography_rotation_focal(x1, x2, float(cameras.K1[0, 0]), max(cameras.image_size1))
    if fit is None or fit[1] > GUESSED_FOCAL_SPREAD or abs(math.log(fit[0])) < MIN_FOCAL_REFIT:
        return None
    return float(fit[0])


def lens_focal_scale(
    result: PairResult, scale: float, threshold_px: float, seed: int = 0
) -> float | None:
    """Scale of the guessed focal length that the rotation-only fit with its lens
    (:func:`ppo_cv.rotation.fit_rotation_lens`: focal scale and radial ``k1``, under
    :data:`LENS_FOCAL_PRIOR` within :data:`LENS_FOCAL_BOX`) finds on ``result``'s inliers,
    normalized with the guessed focal length times ``scale``: on the inliers of their robust
    rotation (:func:`ppo_cv.rotation.ransac_rotation`, ``seed``) within
    :data:`LENS_START_THRESHOLD` times ``threshold_px``, then on those of the fit.

    Returns
    -------
    float or None
        The scale; None without a noise estimate or enough inliers, for a focal scale clipped
        to the box, and within :data:`MIN_FOCAL_REFIT` (log) of ``scale``.
    """
    from .rotation import MIN_LENS_MATCHES, fit_rotation_lens, ransac_rotation

    scale, threshold_px = as_positive(scale, "scale"), as_positive(threshold_px, "threshold_px")
    seed = as_whole_number(seed, "seed", 0, MAX_WHOLE_NUMBER)
    _require_result(result)
    cameras, used = result.cameras, result.matches[result.inliers]
    focal = scale * float(cameras.K1[0, 0])
    noise, bound = result.evidence.selection.noise_sigma_px / focal, threshold_px / focal
    if not (math.isfinite(noise) and noise > 0.0) or len(used) < MIN_LENS_MATCHES:
        return None
    x1 = pixels_to_normalized(result.keypoints1[used[:, 0]], cameras.K1, cameras.dist1) / scale
    x2 = pixels_to_normalized(result.keypoints2[used[:, 1]], cameras.K2, cameras.dist2) / scale
    fit = ransac_rotation(x1, x2, LENS_START_THRESHOLD * bound, seed=seed)
    inliers = fit.inliers
    for _ in range(2):
        if np.count_nonzero(inliers) < MIN_LENS_MATCHES:
            return None
        fit = fit_rotation_lens(
            x1, x2, inliers, fit.R, noise=noise, focal_prior=LENS_FOCAL_PRIOR,
            max_focal_change=LENS_FOCAL_BOX, deviations=False,
        )  # fmt: skip
        inliers = fit.residuals < LENS_START_THRESHOLD * bound
    change = abs(math.log(fit.focal_scale))
    if abs(fit.focal_scale - 1.0) >= LENS_FOCAL_BOX * (1.0 - 1e-9) or change < MIN_FOCAL_REFIT:
        return None
    return float(scale / fit.focal_scale)


def clipped_lens_focal_scale(decision: PairResult, scale: float) -> float | None:
    """Scale of the guessed focal length that ``decision``'s rotation-only fit asked for
    beyond its box, ``decision`` made with the guessed focal length times ``scale``.

    That fit clipped its lens to the box (``decision.lens.lens_excess`` above 0); the focal
    length its matches want is the one that makes the homography of its inliers, corrected by
    the lens it found, a rotation (``decision.lens.wanted_focal_scale``, given over true:
    :func:`ppo_cv.rotation_choice.wanted_focal_scale`), here ``scale`` over it.

    Returns
    -------
    float or None
        The scale; None for a pure rotation, where the fit kept its lens in the box or no such
        focal length exists (NaN), and within :data:`MIN_FOCAL_REFIT` (log) of ``scale``.
    """
    _require_result(decision)
    scale = as_positive(scale, "scale")
    wanted = float(decision.lens.wanted_focal_scale)
    if decision.pure_rotation or not (math.isfinite(wanted) and wanted > 0.0):
        return None
    if abs(math.log(wanted)) < MIN_FOCAL_REFIT:
        return None
    return scale / wanted


def _require_result(result: Any) -> None:
    require_instance(result, PairResult, "result", " (estimate_pair)")


def decided_again(
    result: PairResult, images: Sequence[Any], options: Any, **features: Any
) -> tuple[PairResult, float, str] | None:
    """``(decision, focal, how)``: for a pair decided with a guessed camera, the first pure
    rotation among the decisions with the focal lengths of :func:`fitted_focal_scale`, then
    of :func:`lens_focal_scale` and of :func:`clipped_lens_focal_scale` of the decision with
    the first (each skipped within :data:`MIN_FOCAL_REFIT` of one already tried), that focal length
    (pixels, of camera 1) and how it was found (``"fitted to the homography of its matches"``,
    then ``" and then with its lens's radial term"`` or ``" and then to that of its matches
    corrected by their rotation-only fit's lens"``); None when none is. These are the
    decisions ``ppo-cv pair``, ``pairs`` and ``sfm`` make without intrinsics after the guessed
    camera's.

    ``images`` and ``options`` go to the later :func:`~ppo_cv.pipeline.estimate_pair` runs as
    to the first, with ``features`` (``features1``, ``features2``).
    """
    scale = fitted_focal_scale(result)
    if scale is None:
        return None
    focal, how = float(result.cameras.K1[0, 0]), "fitted to the homography of its matches"
    again = _decided_at(result, scale, images, options, features)
    if again is not None and again.pure_rotation:
        return again, scale * focal, how
    lens = lens_focal_scale(result, scale, options.ransac_threshold, options.seed)
    clipped = None if again is None else clipped_lens_focal_scale(again, scale)
    later = (
        (lens, f"{how} and then with its lens's radial term"),
        (clipped, f"{how} and then to that of its matches corrected by their rotation-only "
                  "fit's lens"),
    )  # fmt: skip
    tried = [scale]
    for other, how in later:
        if other is None or any(abs(math.log(other / s)) < MIN_FOCAL_REFIT for s in tried):
            continue
        tried.append(other)
        again = _decided_at(result, other, images, options, features)
        if again is not None and again.pure_rotation:
            return again, other * focal, how
    return None


def decide_with_fitted_focal(
    result: PairResult, images: Sequence[Any], options: Any, **features: Any
) -> tuple[PairResult, str | None]:
    """``(result, note)``: for a pair decided with a guessed camera, the pure rotation of
    :func:`decided_again` and a note saying so; otherwise ``result`` unchanged and None.

    ``images``, ``options`` and ``features`` as for :func:`decided_again`.
    """
    found = decided_again(result, images, options, **features)
    if found is None:
        return result, None
    again, fitted, how = found
    focal = float(result.cameras.K1[0, 0])
    words = {"general": "a general motion", "plane": "a plane", "rotation": "a rotation"}
    return again, (
        f"the guessed focal length {focal:.1f} px calls this pair {words[result.model]}; "
        f"{fitted:.1f} px, {how}, calls it a pure rotation, which is reported; pass --K "
        "or --calib to decide"
    )


def _decided_at(
    result: PairResult, scale: float, images: Sequence[Any], options: Any, features: dict
) -> PairResult | None:
    """``result``'s pair decided again with its focal lengths times ``scale``; None when the
    pipeline refuses it."""
    from .pipeline import estimate_pair

    cameras, S = result.cameras, np.diag([scale, scale, 1.0])
    try:
        return estimate_pair(
            *images, cameras.K1 @ S, cameras.K2 @ S, cameras.dist1, cameras.dist2,
            options=options, **features,
        )  # fmt: skip
    except ValueError:
        return None


HOMOGRAPHY_CONFIDENCE = 0.9999
"""Confidence of the robust homography of :func:`homography_rotation_focal`."""


def homography_rotation_focal(
    x1: np.ndarray, x2: np.ndarray, focal: float, size: float
) -> tuple[float, float] | None:
    """The focal-length scale that makes the homography of matches a rotation, and how far
    from a rotation it then is.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2)
        Normalized coordinates of the matches under a guessed focal length, N >= 8.
    focal : float
        The guessed focal length, pixels.
    size : float
        The larger image side, pixels.

    Returns
    -------
    tuple of float or None
        ``(s, spread)``: :func:`rotation_focal_scale` of the robust homography of the matches
        and ``log(sigma_1 / sigma_3)`` of the homography conjugated by ``s`` (0 for an exact
        rotation); None with fewer than 8 matches, no homography or no such ``s``.
    """
    x1, x2 = as_finite_rows(x1, "x1", (2, 3)), as_finite_rows(x2, "x2", (2, 3))
    focal, size = as_positive(focal, "focal"), as_positive(size, "size")
    if len(x1) != len(x2):
        raise ValueError(f"x1 and x2 must have the same length, got {len(x1)} and {len(x2)}")
    if len(x1) < 8:
        return None
    x1, x2 = (np.column_stack([xy[:, :2], np.ones(len(xy))]) for xy in (x1, x2))
    homography = estimate_homography(x1, x2, focal, confidence=HOMOGRAPHY_CONFIDENCE)
    if homography is None:
        return None
    scale = rotation_focal_scale(homography.H, focal, size)
    if scale is None:
        return None
    return scale, float(rotation_spread(homography.H, np.array([np.log(scale)]))[0])


FIELD_RANGE_DEG = (5.0, 150.0)
"""Fields of view, across the larger image side, within which :func:`rotation_focal_scale`
looks for a focal length: a long telephoto to a wide lens short of a fisheye."""

_SCALE_GRID = 401  # focal lengths tried, evenly in log scale, before the finer grids


def rotation_focal_scale(H: Any, focal: float, size: float) -> float | None:
    """The scale of the focal length for which a homography is nearest a rotation.

    Between two views of a camera turning about its centre, with intrinsics ``K`` and a
    centred principal point, the homography of the pixels is the conjugate rotation
    ``K R K^-1``. On points normalized with a guessed focal length ``focal``, a true focal
    length ``s * focal`` makes it ``S R S^-1`` with ``S = diag(s, s, 1)``: the scale ``s`` is
    the one for which ``S^-1 H S`` is a rotation times a scalar, its three singular values
    equal. It is found by minimising ``log(sigma_1 / sigma_3)`` of ``S^-1 H S`` over ``s``,
    first on a grid, then by finer grids around the grid's best (Hartley and
    Zisserman, *Multiple View Geometry*, 2nd ed., sec. 8.8 and 19.3: the homography of a
    rotating camera is ``K R K^-1``, and its constraints on ``K``).

    Parameters
    ----------
    H : array_like, shape (3, 3)
        Homography ``x2 ~ H x1`` of normalized points.
    focal : float
        The focal length that normalized the points, pixels.
    size : float
        The larger image side, pixels: bounds the focal lengths tried to the fields of view of
        :data:`FIELD_RANGE_DEG`.

    Returns
    -------
    float or None
        ``s``; None when ``H`` is not finite or singular, or the best scale lies on a bound of
        the range (no focal length inside it makes ``H`` a rotation, or the rotation is about
        the optical axis, which says nothing of the focal length). ``H`` of another shape is a
        ValueError, one of no numbers a TypeError.
    """
    focal, size = as_positive(focal, "focal"), as_positive(size, "size")
    try:
        H = np.asarray(H, dtype=np.float64)
    except OverflowError:  # an integer of more digits than a float holds
        raise ValueError("H holds a number beyond the range of a float") from None
    except (TypeError, ValueError):
        raise TypeError(f"H must be a 3x3 array of numbers, got {shown(H)}") from None
    if H.shape != (3, 3):
        raise ValueError(f"H must have shape (3, 3), got {H.shape}")
    if not np.all(np.isfinite(H)) or np.linalg.svd(H, compute_uv=False)[-1] == 0:
        return None
    low, high = (
        np.log(0.5 * size / np.tan(np.radians(0.5 * field)) / focal)
        for field in FIELD_RANGE_DEG[::-1]
    )
    log_scales = np.linspace(low, high, _SCALE_GRID)
    log_scale, grid_spread, interior = nearest_rotation_log_scale(H, log_scales)
    if not (interior and np.isfinite(grid_spread)):
        return None
    return float(np.exp(log_scale))
