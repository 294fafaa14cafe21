"""Tripod pans in a 60-75 degree field, end to end on ``ppo_cv.data_gen`` renders.

Where the lens is not at the pivot the camera steps sideways as it turns, and before a room's
floor and ceiling the rotation-only fit's focal scale takes that step up, its rotation moved
along with it; a pure rotation's ``rotation_sigma_deg`` counts that move
(:func:`ppo_cv.rotation_choice.focal_trade_deg`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ppo_cv import estimate_pair
from ppo_cv.data_gen import REAL_PHOTO, make_pair
from ppo_cv.metrics import rotation_error_deg

WIDE = dataclasses.replace(REAL_PHOTO, hfov_range=(60.0, 75.0))
"""The lenses of ``REAL_PHOTO`` in a phone's field."""


def _estimate(index: int, ratio: float | None):
    pair = make_pair("tripod", seed=0, index=index, imperfections=WIDE, baseline_ratio=ratio)
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    return pair, estimate_pair(image1, image2, pair.K1_given, pair.K2_given)


def test_a_wide_tripod_pan_whose_focal_scale_took_up_the_step_says_so():
    pair, result = _estimate(3, None)  # 75 degree field, 29 degree pan, step 0.0042 of the depth
    assert result.pure_rotation
    error = rotation_error_deg(result.R, pair.R)  # 1.17: focal scale 0.964, truly 1.009
    assert error > 0.8
    assert result.uncertainty.rotation_sigma_deg > 0.6 * error  # 0.92; 0.35 by one depth's step


def test_the_same_pan_without_the_step_keeps_a_small_deviation():
    pair, result = _estimate(3, 0.0)
    assert result.pure_rotation
    assert rotation_error_deg(result.R, pair.R) < 0.01
    assert result.uncertainty.rotation_sigma_deg < 0.02
