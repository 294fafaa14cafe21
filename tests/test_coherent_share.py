"""A surface of matches off the rotation, moving together, is parallax: not a pure rotation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ppo_cv import PairOptions, data_gen, estimate_pair, motion_model
from ppo_cv.cli.pair import _summary
from ppo_cv.export import result_to_dict
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.model_selection import coherent_share, nearest_neighbours

PER_PHOTO = data_gen.Imperfections(centred_principal_point=True, view_focal_error=0.01)
"""The centre and a focal length per photo given, as a panorama stitcher reports them."""


def _estimate(pair, **options):
    return estimate_pair(
        np.ascontiguousarray(pair.image1[..., ::-1]),
        np.ascontiguousarray(pair.image2[..., ::-1]),
        pair.K1_given, pair.K2_given, options=PairOptions(**options),
    )  # fmt: skip


def test_coherent_share_counts_patches_and_not_scattered_outliers():
    rng = np.random.default_rng(3)
    points = rng.uniform(0, 640, (2000, 2))
    neighbours = nearest_neighbours(points)
    vectors = rng.normal(0, 0.3, (2000, 2))
    scattered = rng.random(2000) < 0.2
    vectors[scattered] = rng.normal(0, 4.0, (np.count_nonzero(scattered), 2))
    # a fifth of the matches off, in random directions: only chance neighbours agree
    assert coherent_share(vectors, neighbours, scattered) < 0.02
    patch = np.all((points > 100) & (points < 330), axis=1)  # about 13 % of the image
    vectors[patch] = np.array([12.0, 0.5]) + rng.normal(0, 0.3, (np.count_nonzero(patch), 2))
    share = coherent_share(vectors, neighbours, patch)
    assert share == pytest.approx(np.mean(patch), abs=0.01)
    assert coherent_share(vectors[:0], neighbours[:0], patch[:0]) == 0.0


@pytest.fixture(scope="module")
def box_before_wall():
    """``tiny-baseline`` index 6 at baseline / depth 0.02: a quarter of the matches, on a box
    face before the back wall, lie 17-19 px off the best rotation, all the same way."""
    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=6, imperfections=PER_PHOTO, baseline_ratio=0.02
    )
    return pair, _estimate(pair)


def test_a_translation_with_a_surface_off_the_rotation_is_not_flagged(box_before_wall, monkeypatch):
    pair, result = box_before_wall
    assert not result.pure_rotation and result.model != "rotation"
    assert result.translation_determined and result.uncertainty.t_sigma_deg < 10.0
    # the rotation won the comparison and its lens is plausible: the share refused it
    assert (
        result.evidence.selection.gric_difference < 0
        and result.lens.lens_excess < motion_model.LENS_SIGNIFICANCE
    )
    assert result.evidence.selection.coherent_share > motion_model.MAX_COHERENT_SHARE
    assert rotation_error_deg(result.R, pair.R) < 0.5
    monkeypatch.setattr(motion_model, "MAX_COHERENT_SHARE", 1.0)
    assert _estimate(pair).pure_rotation


def test_the_share_is_reported(box_before_wall):
    share = box_before_wall[1].evidence.selection.coherent_share
    assert result_to_dict(box_before_wall[1])["evidence"]["selection"]["coherent_share"] == share
    line = f"parallax     {100 * share:.0f} % of the matches move together off the rotation"
    assert line in _summary(box_before_wall[1], "a.png", "b.png", None)


@pytest.mark.parametrize("index", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_a_noisy_rotation_with_scattered_outliers_is_flagged(index):
    """Sensor noise and blur put many matches of a warped photo beyond the rotation's bound,
    scattered over the image."""
    noisy = dataclasses.replace(data_gen.REAL_PHOTO, noise_std=6.0, blur_sigma=1.2)
    pair = data_gen.make_warped_pair(seed=0, index=index, imperfections=noisy)
    result = _estimate(pair)
    assert result.pure_rotation and rotation_error_deg(result.R, pair.R) < 0.5
    assert result.evidence.selection.coherent_share < 0.5 * motion_model.MAX_COHERENT_SHARE
