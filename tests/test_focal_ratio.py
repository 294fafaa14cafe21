"""Focal lengths given per photo: the rotation-only model may scale one against the other.

Ground truth: exact correspondences of a pan whose second view's focal length is given off
against the first's, and ``ppo_cv.data_gen`` pairs with ``Imperfections(view_focal_error=...)``
(each view's focal length given with an error of its own, as a panorama stitcher estimates
them).
"""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest
from twoview import pan_matches

from ppo_cv import PairOptions, data_gen, estimate_pair
from ppo_cv.cli.pair import _lens_lines
from ppo_cv.export import result_to_dict
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.photometric import refine_rotation_photometric
from ppo_cv.rotation import (
    FOCAL_RATIO_BOUND,
    FOCAL_RATIO_GAP,
    fit_rotation_lens,
    focal_ratio_prior,
)

WIDTH, HEIGHT = 640, 480


def _exact_matches(ratio_given: float, hfov=30.0, yaw=20.0):
    """Normalised matches of a pan by one camera, view 2 normalised with its focal length
    given ``ratio_given`` times the true one; the true rotation and the focal length."""
    focal = WIDTH / 2 / np.tan(np.radians(hfov / 2))
    K = np.array([[focal, 0, (WIDTH - 1) / 2], [0, focal, (HEIGHT - 1) / 2], [0, 0, 1.0]])
    K2_given = K.copy()
    K2_given[:2, :2] *= ratio_given
    R = cv2.Rodrigues(np.radians([1.5, yaw, 0.5]))[0]
    return (*pan_matches(K, K, K2_given, R, (WIDTH, HEIGHT)), R, focal)


def test_lens_fit_absorbs_focal_lengths_given_one_percent_apart():
    x1, x2, R, focal = _exact_matches(1.01)
    used = np.ones(len(x1), dtype=bool)
    noise = 0.3 / focal
    mean, sigma = focal_ratio_prior(1.01)
    held = fit_rotation_lens(x1, x2, used, R, noise=noise)
    freed = fit_rotation_lens(
        x1, x2, used, R, noise=noise, focal_ratio_prior=sigma, focal_ratio_mean=mean
    )
    assert np.median(held.residuals) * focal > 0.5  # a zoom no rotation explains
    assert rotation_error_deg(held.R, R) > 0.1
    assert np.median(freed.residuals) * focal < 0.02
    assert freed.focal_ratio == pytest.approx(1.01, abs=2e-4)
    assert freed.focal_scale2 == pytest.approx(freed.focal_scale * 1.01, abs=3e-4)
    assert rotation_error_deg(freed.R, R) < 0.005
    assert held.focal_ratio == 1.0


def test_a_ratio_beyond_its_bound_is_dropped():
    # the matches need 1.03, the prior (mean 1.005, deviation 0.005) allows 1.015 at most
    x1, x2, R, focal = _exact_matches(1.03)
    fit = fit_rotation_lens(
        x1, x2, np.ones(len(x1), bool), R, noise=0.3 / focal,
        focal_ratio_prior=0.005, focal_ratio_mean=1.005,
    )  # fmt: skip
    assert abs(1.03 - 1.005) > FOCAL_RATIO_BOUND * 0.005
    assert fit.focal_ratio == 1.0
    assert np.median(fit.residuals) * focal > 1.0


def test_prior_lies_between_the_given_lengths_and_one_lens():
    assert focal_ratio_prior(1.0) is None
    assert focal_ratio_prior(1.0 + 2 * FOCAL_RATIO_GAP) is None  # two lenses: kept as given
    mean, sigma = focal_ratio_prior(0.98)
    assert mean == pytest.approx(0.99) and sigma == pytest.approx(0.01)
    assert mean - sigma == pytest.approx(0.98) and mean + sigma == pytest.approx(1.0)


def _bgr(pair):
    return (
        np.ascontiguousarray(pair.image1[..., ::-1]),
        np.ascontiguousarray(pair.image2[..., ::-1]),
    )


@pytest.fixture(scope="module")
def per_photo_pan():
    """A warped photo (exact pure rotation) told the centre and a focal length per view."""
    told = data_gen.Imperfections(centred_principal_point=True, view_focal_error=0.01)
    pair = data_gen.make_warped_pair(seed=0, index=2, imperfections=told)
    return pair, estimate_pair(*_bgr(pair), pair.K1_given, pair.K2_given)


def test_pure_rotation_with_focal_lengths_given_per_photo_is_flagged(per_photo_pan):
    pair, result = per_photo_pan
    given = pair.K2_given[0, 0] / pair.K1_given[0, 0]
    assert abs(given - 1.0) > 0.005  # the two views were told focal lengths 0.5 % apart or more
    assert result.pure_rotation and not result.translation_determined
    assert rotation_error_deg(result.R, pair.R) < 0.1
    true_ratio = pair.params["view_factors"][1] / pair.params["view_factors"][0]
    assert result.lens.focal_ratio == pytest.approx(true_ratio, abs=0.002)
    record = json.loads(json.dumps(result_to_dict(result)))
    assert record["lens"]["focal_ratio"] == pytest.approx(result.lens.focal_ratio)
    assert f"image 2 / image 1 {result.lens.focal_ratio:.4f}" in _lens_lines(result)[0]


def test_the_ratio_held_leaves_the_zoom_and_calls_the_pan_general(per_photo_pan):
    pair, freed = per_photo_pan
    options = PairOptions(focal_ratio="given", photometric=False)
    held = estimate_pair(*_bgr(pair), pair.K1_given, pair.K2_given, options=options)
    assert held.lens.focal_ratio == 1.0
    assert held.evidence.selection.rotation_residual_px > max(
        0.5, 2 * freed.evidence.selection.rotation_residual_px
    )
    assert not held.pure_rotation and held.model == "general"


def test_command_line_chooses_the_focal_ratio(tmp_path, freiburg_photos):
    from typer.testing import CliRunner

    from ppo_cv.cli.main import app

    told = data_gen.Imperfections(centred_principal_point=True, view_focal_error=0.01)
    pair = data_gen.make_warped_pair(seed=0, index=4, imperfections=told, source=freiburg_photos)
    paths = [str(tmp_path / "a.png"), str(tmp_path / "b.png")]
    for path, image in zip(paths, _bgr(pair), strict=True):
        cv2.imwrite(path, image)
    k_text = [f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}" for K in (pair.K1_given, pair.K2_given)]
    base = ["pair", *paths, "--K", k_text[0], "--K2", k_text[1], "--json", "--no-photometric"]
    records = {}
    for mode in ("auto", "given"):
        run = CliRunner().invoke(app, [*base, "--focal-ratio", mode])
        assert run.exit_code == 0, run.output
        records[mode] = json.loads(run.stdout)
    true_ratio = pair.params["view_factors"][1] / pair.params["view_factors"][0]
    assert records["auto"]["pure_rotation"]
    assert records["auto"]["lens"]["focal_ratio"] == pytest.approx(true_ratio, abs=0.002)
    assert not records["given"]["pure_rotation"]
    assert records["given"]["lens"]["focal_ratio"] == 1.0
    run = CliRunner().invoke(app, [*base, "--focal-ratio", "fit"])
    assert run.exit_code == 2
    assert "unknown focal_ratio 'fit'" in run.output
    assert "Traceback" not in run.output


def test_the_same_pan_told_one_focal_length_keeps_the_ratio():
    told = data_gen.Imperfections(centred_principal_point=True)
    pair = data_gen.make_warped_pair(seed=0, index=2, imperfections=told)
    result = estimate_pair(*_bgr(pair), pair.K1_given, pair.K2_given)
    assert result.pure_rotation and result.lens.focal_ratio == 1.0
    assert "image 2 / image 1" not in _lens_lines(result)[0]


def test_translation_with_focal_lengths_given_per_photo_stays_general():
    told = data_gen.Imperfections(view_focal_error=0.01)
    pair = data_gen.make_pair("general", seed=0, index=0, imperfections=told)
    result = estimate_pair(*_bgr(pair), pair.K1_given, pair.K2_given)
    assert pair.K1_given[0, 0] != pair.K2_given[0, 0]
    assert not result.pure_rotation and result.model == "general"
    assert rotation_error_deg(result.R, pair.R) < 1.0
    assert _lens_lines(result) == []


def test_bad_ratio_settings_are_named():
    with pytest.raises(ValueError, match="unknown focal_ratio 'fit'; choose one of auto, given"):
        PairOptions(focal_ratio="fit")
    image = np.zeros((60, 80), np.uint8)
    K = np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]])
    with pytest.raises(ValueError, match="focal_ratio"):
        refine_rotation_photometric(image, image, K, K, np.eye(3), focal_ratio=0.0)
    with pytest.raises(ValueError, match="focal_ratio_prior"):
        refine_rotation_photometric(image, image, K, K, np.eye(3), focal_ratio_prior=-0.01)
    with pytest.raises(ValueError, match="focal_ratio_mean"):
        refine_rotation_photometric(
            image, image, K, K, np.eye(3), focal_ratio_prior=0.01, focal_ratio_mean=float("nan")
        )


def test_the_lens_fit_line_names_the_focal_length_the_matches_fit(per_photo_pan):
    """The summary said ``focal scale 0.9950 (given / true)``: a newcomer read of a true focal
    length nobody had given. It names the fitted focal length in pixels, near the true one."""
    pair, result = per_photo_pan
    line = _lens_lines(result)[0]
    fitted = float(re.search(r"the matches fit fx ([\d.]+) px", line).group(1))
    assert fitted == pytest.approx(pair.K1[0, 0], rel=0.005)
    assert fitted == pytest.approx(pair.K1_given[0, 0] / result.lens.focal_scale, abs=0.006)
    assert "given over fitted" in line and "true" not in line
