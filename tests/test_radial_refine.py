"""The general pose refined with a radial term: recovered when present, absent when not."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import estimate_pair
from ppo_cv.export import result_to_dict
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.plane import undistort_division
from ppo_cv.refine import (
    HUBER_NOISE_FACTOR,
    K1_MIN,
    huber_bound_px,
    refine_pose,
    refine_pose_huber,
    refine_pose_radial,
)

FOCAL = 1000.0


def _distort_division(q: np.ndarray, k1: float) -> np.ndarray:
    """The observed points ``x`` whose division-model undistortion is ``q``."""
    rq = np.linalg.norm(q[:, :2], axis=1)
    rx = (1.0 - np.sqrt(1.0 - 4.0 * k1 * rq**2)) / (2.0 * k1 * rq) if k1 else rq
    return np.column_stack([q[:, :2] * (rx / rq)[:, None], np.ones(len(q))])


def _matches(k1: float, seed: int = 3, n: int = 400, noise_px: float = 0.3):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-2.5, 2.5, (n, 2)), rng.uniform(5.0, 12.0, n)])
    angle, axis = np.radians(6.0), np.array([0.2, 1.0, 0.1])
    axis /= np.linalg.norm(axis)
    Kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * Kx + (1 - np.cos(angle)) * Kx @ Kx
    t = np.array([-1.0, 0.1, 0.2])
    q1, Y = X / X[:, 2:], X @ R.T + t
    q2 = Y / Y[:, 2:]
    x1, x2 = _distort_division(q1, k1), _distort_division(q2, k1)
    for x in (x1, x2):
        x[:, :2] += rng.normal(0.0, noise_px / FOCAL, (n, 2))
    return x1, x2, R, t / np.linalg.norm(t)


def test_distortion_nobody_gave_is_recovered_and_the_pose_improves():
    x1, x2, R, t = _matches(k1=0.08)
    inliers = np.ones(len(x1), bool)
    R0, t0 = refine_pose(R, t, x1, x2, inliers, FOCAL)
    fitted = refine_pose_radial(R0, t0, x1, x2, inliers, scale=1.0 / FOCAL)
    assert fitted.k1 == pytest.approx(0.08, abs=0.01)
    assert abs(fitted.k1) > 3 * fitted.k1_sigma
    assert rotation_error_deg(fitted.R, R) < 0.5 * rotation_error_deg(R0, R)
    before = direction_error_deg(t0, t, signed=False)
    assert direction_error_deg(fitted.t, t, signed=False) < 0.5 * before
    np.testing.assert_allclose(
        undistort_division(_distort_division(x1, 0.08), 0.08)[:, :2], x1[:, :2], atol=1e-12
    )


def test_no_distortion_keeps_the_start():
    x1, x2, R, t = _matches(k1=0.0)
    inliers = np.ones(len(x1), bool)
    R0, t0 = refine_pose(R, t, x1, x2, inliers, FOCAL)
    fitted = refine_pose_radial(R0, t0, x1, x2, inliers, scale=1.0 / FOCAL)
    assert fitted.k1 == 0.0
    np.testing.assert_array_equal(fitted.R, R0)
    np.testing.assert_allclose(fitted.t, t0 / np.linalg.norm(t0))
    few = np.arange(len(x1)) < 11
    assert refine_pose_radial(R0, t0, x1, x2, few, scale=1e-3).k1_sigma == np.inf


def test_imperfect_render_reports_its_radial_term_and_a_better_pose():
    from ppo_cv import data_gen

    pair = data_gen.make_pair("general", seed=0, index=0, imperfections=data_gen.REAL_PHOTO)
    assert pair.params["k1"] < -K1_MIN
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    result = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    assert result.model == "general"
    assert result.lens.radial_k1 == pytest.approx(pair.params["k1"], abs=0.03)
    assert rotation_error_deg(result.R, pair.R) < 0.1
    assert direction_error_deg(result.t, pair.t, signed=False) < 0.5
    assert result_to_dict(result)["lens"]["radial_k1"] == result.lens.radial_k1
    from ppo_cv.cli.pair import _summary

    assert f"radial k1    {result.lens.radial_k1:+.4f}" in _summary(result, "a.png", "b.png", None)


def test_a_small_baseline_is_refined_against_the_noise_not_the_ransac_threshold():
    """Baseline / depth 0.02 in a 26 degree field with k1 -0.08 nobody gave: bounded at the 1 px
    threshold, the inliers' tail trades k1 against t and leaves t 5.5 degrees off (three of its
    deviations); bounded at HUBER_NOISE_FACTOR deviations of the noise it is about one degree."""
    from ppo_cv import data_gen

    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=6, imperfections=data_gen.REAL_PHOTO, baseline_ratio=0.02
    )
    assert pair.params["k1"] < -0.05 and pair.params["hfov_deg"] < 30
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    result = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    assert result.model == "general" and not result.pure_rotation
    error = direction_error_deg(result.t, pair.t, signed=False)
    assert error < 2.0 and error < result.uncertainty.t_sigma_deg
    assert rotation_error_deg(result.R, pair.R) < 0.1


def test_a_tail_of_inliers_does_not_tilt_a_small_baseline_without_a_radial_term():
    """A clean render at baseline / depth 0.04 (no distortion, so no radial term is kept): the
    least-squares pose over the 1 px inliers had t 0.45 degrees off, tilted along the valley by
    the 3 % of them beyond five deviations of the noise; on the Huber cost it is 0.02 off."""
    from ppo_cv import data_gen

    pair = data_gen.make_pair("small-parallax", seed=1, index=4)
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    result = estimate_pair(image1, image2, pair.K1, pair.K2)
    assert result.model == "general" and result.lens.radial_k1 == 0.0
    error = direction_error_deg(result.t, pair.t, signed=False)
    assert error < 0.1 and error < result.uncertainty.t_sigma_deg
    assert rotation_error_deg(result.R, pair.R) < 0.02


def _with_tail(n: int = 1000, tail: int = 15, noise_px: float = 0.03):
    """Matches at ``noise_px`` in a 53 degree field, baseline / depth about 0.004, and the
    ``tail`` matches of one corner moved 0.5-0.95 px across the epipolar lines in image 2,
    inside a 1 px threshold."""
    rng = np.random.default_rng(4)
    X = np.column_stack([rng.uniform(-2.5, 2.5, (n, 2)), rng.uniform(5.0, 12.0, n)])
    R, t = _matches(k1=0.0)[2], np.array([-0.03, 0.0075, 0.00375])
    Y = X @ R.T + t
    x1, x2 = X / X[:, 2:], Y / Y[:, 2:]
    for x in (x1, x2):
        x[:, :2] += rng.normal(0.0, noise_px / FOCAL, (n, 2))
    corner = np.argsort(-(x1[:, 0] + x1[:, 1]))[:tail]
    x2[corner, 1] += rng.uniform(0.5, 0.95, tail) / FOCAL
    return x1, x2, R, t / np.linalg.norm(t)


def test_huber_pose_leaves_the_tail_the_least_squares_pose_follows():
    x1, x2, R, t = _with_tail()
    inliers = np.ones(len(x1), bool)
    R0, t0 = refine_pose(R, t, x1, x2, inliers, FOCAL)
    R1, t1 = refine_pose_huber(R0, t0, x1, x2, inliers, scale=HUBER_NOISE_FACTOR * 0.03 / FOCAL)
    drift = direction_error_deg(t0, t, signed=False)
    assert drift > 1.0
    assert direction_error_deg(t1, t, signed=False) < 0.6 * drift
    assert np.linalg.norm(t1) == pytest.approx(1.0)
    few = np.arange(len(x1)) < 11
    Rf, tf = refine_pose_huber(R0, 3 * t0, x1, x2, few, scale=1e-3)
    np.testing.assert_array_equal(Rf, R0)
    np.testing.assert_allclose(tf, t0 / np.linalg.norm(t0))


def test_huber_bound_is_the_noise_scaled_up_to_the_threshold():
    assert huber_bound_px(1.0, 0.05) == pytest.approx(HUBER_NOISE_FACTOR * 0.05)
    assert huber_bound_px(1.0, 0.5) == 1.0
    assert huber_bound_px(1.0, float("nan")) == 1.0
    assert huber_bound_px(1.0, 0.0) == 1.0


@pytest.mark.parametrize("size", [0.0, 2e-4])
@pytest.mark.parametrize("k1", [0.0, 0.1])
def test_noise_replicates_lie_on_the_model_up_to_the_noise_they_were_given(size, k1):
    from ppo_cv.lsq import cross_matrices
    from ppo_cv.refine import noise_replicates
    from ppo_cv.robust import sampson_signed

    x1, x2, R, t = _matches(k1=k1, noise_px=0.5)
    E = cross_matrices(t[None])[0] @ R
    assert np.sqrt(np.mean(sampson_signed(E, x1, x2) ** 2)) > 2e-4
    sizes = np.full(len(x1), size)
    replicates = list(noise_replicates(E, x1, x2, sizes, 3, k1))
    assert len(replicates) == 3
    for a, b in replicates:
        undistorted = (undistort_division(x, k1) for x in (a, b))
        rms = np.sqrt(np.mean(sampson_signed(E, *undistorted) ** 2))
        assert rms == pytest.approx(size, rel=0.15, abs=1e-8)
    first = next(noise_replicates(E, x1, x2, sizes, 1, k1))[0]
    np.testing.assert_array_equal(replicates[0][0], first)


def _stacked_matches(rng, sets, n):
    xy = rng.uniform(-0.6, 0.6, (sets, n, 2))
    return np.concatenate([xy, np.ones((sets, n, 1))], axis=2)


def test_the_radial_fit_undistorts_coordinate_by_coordinate_with_the_same_figures():
    from ppo_cv.refine import _RadialPoints

    rng = np.random.default_rng(3)
    sets = _stacked_matches(rng, 4, 57)
    k1 = np.array([0.0, 0.07, -0.2, 1e-7, 0.3, -0.05])
    rows = np.array([0, 3, 3, 1, 2, 0])
    laid_out = _RadialPoints(sets).undistorted(k1, rows)
    assert laid_out.shape == (6, 3, 57) and laid_out.flags["C_CONTIGUOUS"]
    for i, (k, row) in enumerate(zip(k1, rows, strict=True)):
        assert np.array_equal(laid_out[i], undistort_division(sets[row], k).T)
    one = _RadialPoints(sets[2]).undistorted(k1)
    assert all(np.array_equal(one[i], undistort_division(sets[2], k).T) for i, k in enumerate(k1))


def test_sampson_residuals_by_coordinate_are_those_of_the_matches_as_rows():
    from ppo_cv.lsq import cross_matrices, rotation_increments
    from ppo_cv.robust import sampson_signed, sampson_signed_rows

    rng = np.random.default_rng(4)
    x1, x2 = _stacked_matches(rng, 8, 213), _stacked_matches(rng, 8, 213)
    x2[..., 2] = rng.uniform(0.5, 2.0, (8, 213))
    t = rng.normal(size=(8, 3))
    E = cross_matrices(t) @ rotation_increments(rng.normal(0.0, 0.2, (8, 3)))
    rows = [np.ascontiguousarray(np.swapaxes(x, 1, 2)) for x in (x1, x2)]
    assert np.array_equal(sampson_signed_rows(E, *rows), sampson_signed(E, x1, x2))
    assert np.array_equal(sampson_signed_rows(E[3], *(r[3] for r in rows)),
                          sampson_signed(E[3], x1[3], x2[3]))  # fmt: skip
    assert np.array_equal(sampson_signed_rows(E, rows[0][:1], rows[1][:1]),
                          sampson_signed(E, x1[:1], x2[:1]))  # fmt: skip


def test_the_radial_residuals_of_a_stack_are_those_of_each_row_alone():
    from ppo_cv.lsq import row_chunks, tangent_basis
    from ppo_cv.refine import _radial_residuals, _RadialPoints

    rng = np.random.default_rng(5)
    n, stack = 600, 96
    assert len(row_chunks(stack, n)) > 1
    A, B = _stacked_matches(rng, 16, n), _stacked_matches(rng, 16, n)
    t = np.array([0.3, -0.1, 0.95]) / np.linalg.norm([0.3, -0.1, 0.95])
    residuals = _radial_residuals(np.eye(3), t, tangent_basis(t), 1e-3, 0.1, 0.02)
    points = [_RadialPoints(x) for x in (A, B)]
    P, rows = rng.normal(0.0, 1e-3, (stack, 6)), np.repeat(np.arange(16), 6)
    weights = rng.uniform(0.5, 2.0, stack)
    stacked = residuals(P, points, weights, rows)
    alone = [residuals(P[i : i + 1], points, weights[i : i + 1], rows[i : i + 1])[0]
             for i in range(stack)]  # fmt: skip
    assert stacked.shape == (stack, n + 1) and np.array_equal(stacked, np.array(alone))
