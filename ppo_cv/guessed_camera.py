"""A pair decided with a guessed camera, decided again with the focal length its matches imply.

Without a calibration the focal length is guessed (EXIF, or 1.2 times the larger image side).
A guess a few percent off leaves a rotation's matches a residual that a translation explains
better, so a tripod pair is called general motion: on ``pano_dev``'s ``book`` pairs the EXIF
focal length is 8 % short. The homography of the inliers tells the focal length that makes it
a rotation (:func:`ppo_cv.sfm.homography_rotation_focal`, Hartley & Zisserman 8.8 / 19.3); where
that homography is then close to a rotation (:data:`GUESSED_FOCAL_SPREAD`) and the focal
length moves (:data:`MIN_FOCAL_REFIT`), the pair is decided again with it
(:func:`fitted_focal_scale` decides, :func:`decide_with_fitted_focal` runs it), and that
decision is reported only when it is a pure rotation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .camera import pixels_to_normalized
from .result import PairResult

__all__ = [
    "GUESSED_FOCAL_SPREAD",
    "MIN_FOCAL_REFIT",
    "decide_with_fitted_focal",
    "fitted_focal_scale",
]

GUESSED_FOCAL_SPREAD = 0.05
"""Largest ``log(sigma_1 / sigma_3)`` of the matches' homography, conjugated by the focal length
that makes it nearest a rotation (:func:`ppo_cv.sfm.homography_rotation_focal`), for which a
pair decided with a guessed camera is decided again with that focal length: 0.002 to 0.029 on
14 pano_dev tripod pairs under their EXIF focal lengths, 0.055 to 1.02 on 9 freiburg
translating pairs under the 1.2 x image size guess, where the second run would only cost time."""

MIN_FOCAL_REFIT = 0.01
"""Relative change of the focal length below which a pair is not decided again."""


def fitted_focal_scale(result: PairResult) -> float | None:
    """Scale of the guessed focal length with which ``result``'s pair is worth deciding again:
    the one that makes the homography of its inliers a rotation, when that homography is then
    within :data:`GUESSED_FOCAL_SPREAD` of one and the scale departs from 1 by at least
    :data:`MIN_FOCAL_REFIT` (log); None otherwise, and for a pure rotation."""
    from .sfm import homography_rotation_focal

    if result.pure_rotation:
        return None
    cameras, used = result.cameras, result.matches[result.inliers]
    x1 = pixels_to_normalized(result.keypoints1[used[:, 0]], cameras.K1, cameras.dist1)
    x2 = pixels_to_normalized(result.keypoints2[used[:, 1]], cameras.K2, cameras.dist2)
    fit = homography_rotation_focal(x1, x2, float(cameras.K1[0, 0]), max(cameras.image_size1))
    if fit is None or fit[1] > GUESSED_FOCAL_SPREAD or abs(math.log(fit[0])) < MIN_FOCAL_REFIT:
        return None
    return float(fit[0])


def decide_with_fitted_focal(
    result: PairResult, images: Sequence[Any], options: Any, **features: Any
) -> tuple[PairResult, str | None]:
    """``(result, note)``: for a pair decided with a guessed camera, the decision with the
    focal length of :func:`fitted_focal_scale` when that decision is a pure rotation, and a note
    saying so; otherwise ``result`` unchanged and None.

    ``images`` and ``options`` go to the second :func:`~ppo_cv.pipeline.estimate_pair` as to
    the first, with ``features`` (``features1``, ``features2``).
    """
    from .pipeline import estimate_pair

    scale = fitted_focal_scale(result)
    if scale is None:
        return result, None
    cameras, focal = result.cameras, float(result.cameras.K1[0, 0])
    S = np.diag([scale, scale, 1.0])
    try:
        again = estimate_pair(
            *images, cameras.K1 @ S, cameras.K2 @ S, cameras.dist1, cameras.dist2,
            options=options, **features,
        )  # fmt: skip
    except ValueError:
        return result, None
    if not again.pure_rotation:
        return result, None
    words = {"general": "a general motion", "plane": "a plane", "rotation": "a rotation"}
    return again, (
        f"the guessed focal length {focal:.1f} px calls this pair {words[result.model]}; "
        f"{scale * focal:.1f} px, fitted to the homography of its matches, calls it a pure "
        "rotation, which is reported; pass --K or --calib to decide"
    )
