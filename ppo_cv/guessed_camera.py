"""A pair decided with a guessed camera, decided again with the focal length its matches imply.

Without a calibration the focal length is guessed (EXIF, or 1.2 times the larger image side).
A guess a few percent off leaves a rotation's matches a residual that a translation explains
better, so a tripod pair is called general motion: on ``pano_dev``'s ``book`` pairs the EXIF
focal length is 8 % short. The homography of the inliers tells the focal length that makes it
a rotation (:func:`ppo_cv.sfm.homography_rotation_focal`, Hartley & Zisserman 8.8 / 19.3); where
that homography is then close to a rotation (:data:`GUESSED_FOCAL_SPREAD`) and the focal
length moves (:data:`MIN_FOCAL_REFIT`), the pair is decided again with it
(:func:`fitted_focal_scale` decides, :func:`decide_with_fitted_focal` runs it), and that
decision is reported only when it is a pure rotation. The homography has no lens: an unmodelled
radial distortion moves its focal length by several percent, beyond the rotation-only fit's
box (:data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`) about it, so where that decision is no rotation
the pair is decided a third time with the focal length of the rotation-only fit with its radial
term, freed about the homography's (:func:`lens_focal_scale`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .camera import pixels_to_normalized
from .checks import MAX_WHOLE_NUMBER, as_positive, as_whole_number, require_instance
from .result import PairResult

__all__ = [
    "GUESSED_FOCAL_SPREAD",
    "LENS_FOCAL_BOX",
    "LENS_FOCAL_PRIOR",
    "LENS_START_THRESHOLD",
    "MIN_FOCAL_REFIT",
    "decide_with_fitted_focal",
    "fitted_focal_scale",
    "lens_focal_scale",
]

GUESSED_FOCAL_SPREAD = 0.05
"""Largest ``log(sigma_1 / sigma_3)`` of the matches' homography, conjugated by the focal length
that makes it nearest a rotation (:func:`ppo_cv.sfm.homography_rotation_focal`), for which a
pair decided with a guessed camera is decided again with that focal length: 0.002 to 0.029 on
14 pano_dev tripod pairs under their EXIF focal lengths, 0.055 to 1.02 on 9 freiburg
translating pairs under the 1.2 x image size guess, where the second run would only cost time."""

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
    from .sfm import homography_rotation_focal

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


def _require_result(result: Any) -> None:
    require_instance(result, PairResult, "result", " (estimate_pair)")


def decide_with_fitted_focal(
    result: PairResult, images: Sequence[Any], options: Any, **features: Any
) -> tuple[PairResult, str | None]:
    """``(result, note)``: for a pair decided with a guessed camera, the decision with the
    focal length of :func:`fitted_focal_scale`, or where that is no pure rotation the one with
    :func:`lens_focal_scale`'s, when it is a pure rotation, and a note saying so; otherwise
    ``result`` unchanged and None.

    ``images`` and ``options`` go to the later :func:`~ppo_cv.pipeline.estimate_pair` runs as
    to the first, with ``features`` (``features1``, ``features2``).
    """
    scale = fitted_focal_scale(result)
    if scale is None:
        return result, None
    again = _decided_at(result, scale, images, options, features)
    how = "fitted to the homography of its matches"
    if again is None or not again.pure_rotation:
        scale = lens_focal_scale(result, scale, options.ransac_threshold, options.seed)
        again = None if scale is None else _decided_at(result, scale, images, options, features)
        how = "fitted to the homography of its matches and then with its lens's radial term"
    if again is None or not again.pure_rotation:
        return result, None
    focal = float(result.cameras.K1[0, 0])
    words = {"general": "a general motion", "plane": "a plane", "rotation": "a rotation"}
    return again, (
        f"the guessed focal length {focal:.1f} px calls this pair {words[result.model]}; "
        f"{scale * focal:.1f} px, {how}, calls it a pure rotation, which is reported; pass --K "
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
