"""Pure rotation on imperfect images: the rotation-only fit, the model decision and t_sigma_deg."""

from __future__ import annotations

from importlib import resources

import cv2
import numpy as np
import pytest
from imperfect import imperfect_render, warped_rotation_pair

from ppo_cv import PairOptions, estimate_pair
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.model_selection import (
    ModelResiduals,
    incoherent_sigma,
    nearest_neighbours,
    robust_sigma,
    select_model,
)
from ppo_cv.motion_model import (
    LENS_SIGNIFICANCE,
    MAX_TRACK_PARALLAX,
    PARALLAX_SIGNIFICANCE,
    decide_motion,
)
from ppo_cv.refine import translation_sigma_deg
from ppo_cv.rotation import (
    fit_rotation_lens,
    ransac_rotation,
    rotation_residuals,
    rotations_from_two_rays,
)

K_DEMO = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


def _random_rotations(rng: np.random.Generator, n: int, max_angle: float = 0.5) -> np.ndarray:
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(0, max_angle, n)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axes[:, 2], axes[:, 1], -axes[:, 0]
    K -= np.swapaxes(K, 1, 2)
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * K @ K


def _bearings(rng: np.random.Generator, n: int, half_fov: float = 0.3) -> np.ndarray:
    x = np.column_stack([rng.uniform(-half_fov, half_fov, (n, 2)), np.ones(n)])
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def test_two_ray_solver_exact_on_noise_free_rays():
    rng = np.random.default_rng(1)
    Rs = _random_rotations(rng, 200)
    a1, a2 = _bearings(rng, 200), _bearings(rng, 200)
    b1, b2 = np.einsum("kij,kj->ki", Rs, a1), np.einsum("kij,kj->ki", Rs, a2)
    found = rotations_from_two_rays(a1, a2, b1, b2)
    assert np.abs(found - Rs).max() < 1e-10
    assert np.allclose(np.linalg.det(found), 1.0)


def test_ransac_rotation_finds_rotation_among_outliers_and_is_seeded():
    rng = np.random.default_rng(2)
    R = _random_rotations(rng, 1, 0.4)[0]
    b1 = _bearings(rng, 400)
    b2 = b1 @ R.T
    b2[:, :2] += rng.normal(0, 0.3 / 800, (400, 2))  # 0.3 px at f = 800
    outliers = rng.random(400) < 0.5
    b2[outliers] = _bearings(rng, int(outliers.sum()))
    fit = ransac_rotation(b1, b2, 1.5 / 800, seed=3)
    assert rotation_error_deg(fit.R, R) < 0.01
    assert np.array_equal(fit.inliers, rotation_residuals(fit.R, b1, b2) < 1.5 / 800)
    assert fit.inliers[~outliers].mean() > 0.97 and fit.inliers[outliers].mean() < 0.02
    again = ransac_rotation(b1, b2, 1.5 / 800, seed=3)
    assert np.array_equal(again.R, fit.R) and again.trials == fit.trials


def test_lens_fit_recovers_focal_scale_and_radial_coefficient():
    rng = np.random.default_rng(4)
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ _random_rotations(rng, 1, 0.05)[0]
    true1 = rng.uniform(-0.3, 0.3, (300, 2))
    ray = np.column_stack([true1, np.ones(300)]) @ R.T
    true2 = ray[:, :2] / ray[:, 2:]
    scale, k1 = 1.025, -0.08  # OpenCV radial distortion, then the focal given 2.5 % short

    def observe(q):
        return q * (1 + k1 * np.sum(q * q, axis=1, keepdims=True)) / scale

    x1, x2 = observe(true1), observe(true2)
    rough = ransac_rotation(x1, x2, 1e-3).R
    lens = fit_rotation_lens(x1, x2, np.ones(300, bool), rough)
    assert abs(lens.focal_scale - scale) < 1e-6 and abs(lens.k1 - k1) < 1e-5
    assert rotation_error_deg(lens.R, R) < 0.01 and rotation_error_deg(rough, R) > 0.2
    assert np.median(lens.residuals) < 1e-9
    assert lens.focal_significant


def test_lens_fit_with_priors_works_from_a_few_matches():
    rng = np.random.default_rng(9)
    c, s = np.cos(0.25), np.sin(0.25)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    true1 = rng.uniform(-0.25, 0.25, (6, 2))
    ray = np.column_stack([true1, np.ones(6)]) @ R.T
    x1, x2 = true1, ray[:, :2] / ray[:, 2:]
    x2 = x2 + rng.normal(0, 0.2 / 900, x2.shape)
    without = fit_rotation_lens(x1, x2, np.ones(6, bool), np.eye(3))
    with_priors = fit_rotation_lens(x1, x2, np.ones(6, bool), np.eye(3), noise=0.3 / 900)
    assert not np.isfinite(without.focal_scale_sigma)  # too few matches for free lens terms
    assert np.isfinite(with_priors.focal_scale_sigma) and with_priors.focal_scale_sigma < 0.03
    assert abs(with_priors.focal_scale - 1.0) < 0.02 and abs(with_priors.k1) < 0.1
    assert rotation_error_deg(with_priors.R, R) < 0.1


@pytest.mark.parametrize("ratio_prior", [None, 0.02])
def test_lens_fit_started_from_an_earlier_fit_reaches_the_same_fit(ratio_prior):
    # Every lens term free (focal, k1, principal point, focal ratio): the fit of the inliers
    # started from the lens of the fit with outliers lands where the fit from scratch does,
    # its deviations included (the analytic Jacobian of the transfer at the same minimum).
    rng = np.random.default_rng(21)
    c, s = np.cos(np.radians(12.0)), np.sin(np.radians(12.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    q1 = rng.uniform(-0.35, 0.35, (400, 2))
    ray = np.column_stack([q1, np.ones(400)]) @ R.T
    q2 = ray[:, :2] / ray[:, 2:]
    k1, offset, noise = -0.06, np.array([0.004, -0.003]), 0.3 / 800

    def observe(q, scale):
        return (offset + q * (1 + k1 * np.sum(q * q, axis=1, keepdims=True))) / scale

    x1 = observe(q1, 1.02) + rng.normal(0, noise, q1.shape)
    ratio = 1.01 if ratio_prior else 1.0
    x2 = observe(q2, 1.02 * ratio) + rng.normal(0, noise, q2.shape)
    x2[:40] += rng.normal(0, 0.02, (40, 2))  # outliers
    priors = {"noise": noise * np.sqrt(2), "principal_prior": 0.01}
    priors["focal_ratio_prior"] = ratio_prior
    everything = fit_rotation_lens(x1, x2, np.ones(400, bool), np.eye(3), **priors)
    inliers = np.arange(400) >= 40
    fresh = fit_rotation_lens(x1, x2, inliers, everything.R, **priors)
    started = fit_rotation_lens(x1, x2, inliers, everything.R, lens_start=everything, **priors)
    assert rotation_error_deg(fresh.R, R) < 0.1
    assert rotation_error_deg(started.R, fresh.R) < 1e-3 * fresh.rotation_sigma_deg
    for name in ("focal_scale", "k1", "focal_ratio", "rotation_sigma_deg", "focal_scale_sigma"):
        assert getattr(started, name) == pytest.approx(getattr(fresh, name), rel=1e-5), name
    np.testing.assert_allclose(started.principal_offset, fresh.principal_offset, atol=1e-7)
    assert abs(fresh.k1 - k1) < 0.02 and abs(fresh.focal_ratio - ratio) < 0.005
    assert not fresh.offset_dropped


def test_lens_excess_is_the_distance_beyond_the_box_in_posterior_deviations():
    # A 25 deg pan over 400 matches pins the focal to about 0.2 %: the clipped fit reports how
    # far the free one lay beyond |s - 1| <= 0.05, the free one measured with a wider box.
    rng = np.random.default_rng(12)
    c, s = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    noise = 0.3 / 800
    q1 = np.column_stack([rng.uniform(-0.5, 0.05, 400), rng.uniform(-0.35, 0.35, 400)])
    ray = np.column_stack([q1, np.ones(400)]) @ R.T
    q2, used = ray[:, :2] / ray[:, 2:], np.ones(400, bool)
    excesses = []
    for scale in (1.03, 1.10, 0.90):
        x1, x2 = (q / scale + rng.normal(0, noise, q.shape) for q in (q1, q2))
        fit = fit_rotation_lens(x1, x2, used, np.eye(3), noise=noise * np.sqrt(2))
        free = fit_rotation_lens(
            x1, x2, used, np.eye(3), noise=noise * np.sqrt(2), max_focal_change=0.2
        )
        assert abs(free.focal_scale - scale) < 0.01
        beyond = (abs(free.focal_scale - 1.0) - 0.05) / free.focal_scale_sigma
        assert fit.lens_excess == pytest.approx(beyond, rel=0.15)
        excesses.append(fit.lens_excess)
    assert excesses[0] < 0 < LENS_SIGNIFICANCE < min(excesses[1:])
    assert fit.focal_scale == pytest.approx(0.95) and fit.focal_scale_sigma == np.inf
    assert fit_rotation_lens(x1, x2, used, np.eye(3)).lens_excess == -np.inf  # no noise, no prior


def test_rotation_sigma_matches_the_spread_of_the_fitted_rotations():
    # Narrow field, 10 deg pan; focal scale and k1 drawn from the priors the fit assumes, so its
    # posterior covariance is the mean squared error of the rotation (Bayesian Cramer-Rao).
    rng = np.random.default_rng(11)
    c, s = np.cos(np.radians(10.0)), np.sin(np.radians(10.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    noise = 0.3 / 900
    errors, sigmas = [], []
    for _ in range(60):
        scale, k1 = 1.0 + rng.normal(0, 0.02), rng.normal(0, 0.1)
        q1 = np.column_stack([rng.uniform(-0.25, 0.05, 80), rng.uniform(-0.2, 0.2, 80)])
        ray = np.column_stack([q1, np.ones(80)]) @ R.T
        q2 = ray[:, :2] / ray[:, 2:]
        x1, x2 = (q * (1 + k1 * np.sum(q * q, 1, keepdims=True)) / scale for q in (q1, q2))
        x2 = x2 + rng.normal(0, noise, x2.shape)
        fit = fit_rotation_lens(x1, x2, np.ones(80, bool), np.eye(3), noise=noise)
        errors.append(rotation_error_deg(fit.R, R))
        sigmas.append(fit.rotation_sigma_deg)
    rms = float(np.sqrt(np.mean(np.square(errors))))
    # the bound is far above what noise alone would give: the focal dominates it
    assert 0.05 < np.median(sigmas) < 0.5
    assert 0.7 < rms / float(np.median(sigmas)) < 1.4


def test_select_model_on_synthetic_residuals():
    rng = np.random.default_rng(5)
    sigma = 0.4
    general = np.abs(rng.normal(0, sigma, 800))  # Sampson: 1 dof
    noise = np.linalg.norm(rng.normal(0, sigma, (800, 2)), axis=1)  # transfer, 2 dof
    rotation_like = noise * 1.1  # a rotation with a little unmodelled error
    parallax = np.hypot(noise, rng.uniform(0.5, 4.0, 800))  # depth-dependent parallax
    pick = select_model(
        [ModelResiduals("rotation", rotation_like, 2, 5), ModelResiduals("general", general, 3, 5)]
    )
    assert pick.model == "rotation" and pick.relative_gric("rotation", "general") < 0
    assert abs(pick.sigma_px - sigma) < 0.05
    pick = select_model(
        [ModelResiduals("rotation", parallax, 2, 5), ModelResiduals("general", general, 3, 5)]
    )
    assert pick.model == "general" and pick.margin > 0.5
    assert abs(robust_sigma(noise, 2) - sigma) < 0.05
    with pytest.raises(ValueError, match="same matches"):
        select_model(
            [ModelResiduals("rotation", noise[:5], 2, 5), ModelResiduals("general", general, 3, 5)]
        )
    with pytest.raises(ValueError, match="at least one"):
        select_model([])


def test_noise_estimate_is_corrected_for_the_parameters_the_general_model_fitted():
    """Residuals of a 5-parameter least-squares fit to 20 matches understate the noise by
    sqrt(15 / 20); the estimate GRIC divides by must not."""
    rng = np.random.default_rng(8)
    sigma, n, k = 0.5, 20, 5
    corrected, raw = [], []
    for _ in range(600):
        A = rng.normal(size=(n, k))
        noise = rng.normal(0, sigma, n)
        fitted = noise - A @ np.linalg.lstsq(A, noise, rcond=None)[0]
        rotation = np.linalg.norm(rng.normal(0, sigma, (n, 2)), axis=1)
        pick = select_model(
            [ModelResiduals("rotation", rotation, 2, 5), ModelResiduals("general", fitted, 3, k)]
        )
        corrected.append(pick.sigma_px)
        raw.append(robust_sigma(fitted, 1))
    assert np.median(corrected) == pytest.approx(sigma, rel=0.05)
    assert np.median(raw) < 0.92 * sigma
    assert np.median(corrected) / np.median(raw) == pytest.approx(np.sqrt(n / (n - k)))


def test_incoherent_sigma_sees_noise_and_not_a_smooth_field():
    rng = np.random.default_rng(9)
    points = rng.uniform(0, 640, (1500, 2))
    neighbours = nearest_neighbours(points)
    distances = np.linalg.norm(points[:, None] - points[None], axis=2)
    np.fill_diagonal(distances, np.inf)
    np.testing.assert_array_equal(neighbours, np.argmin(distances, axis=1))
    parallax = np.column_stack([2.0 + np.sin(points[:, 0] / 90), 0.5 * np.cos(points[:, 1] / 70)])
    noise = rng.normal(0, 0.3, (1500, 2))
    assert incoherent_sigma(parallax, neighbours) < 0.03
    assert incoherent_sigma(noise, neighbours) == pytest.approx(0.3, rel=0.1)
    assert incoherent_sigma(parallax + noise, neighbours) == pytest.approx(0.3, rel=0.1)
    # noise along x only: the estimate per coordinate is its root mean square over both
    along = noise * [np.sqrt(2.0), 0.0]
    assert incoherent_sigma(along, neighbours) == pytest.approx(0.3, rel=0.15)
    assert np.isnan(incoherent_sigma(noise[:2], neighbours[:2] % 2))
    twins = nearest_neighbours(np.array([[0.0, 0.0], [0.0, 0.0], [5.0, 5.0]]))
    assert twins[0] == 1 and twins[1] == 0 and twins[2] in (0, 1)


def _two_view(rng, baseline: float, n: int = 400, noise_px: float = 0.5, f: float = 800.0):
    X = np.column_stack([rng.uniform(-2, 2, (n, 2)), rng.uniform(4, 12, n)])
    R = _random_rotations(rng, 1, 0.2)[0]
    t = np.array([baseline, 0.1 * baseline, 0.0])
    x1 = X / X[:, 2:]
    X2 = X @ R.T + t
    x2 = X2 / X2[:, 2:]
    x1[:, :2] += rng.normal(0, noise_px / f, (n, 2))
    x2[:, :2] += rng.normal(0, noise_px / f, (n, 2))
    return R, t / np.linalg.norm(t), x1, x2


def test_t_sigma_grows_as_the_baseline_shrinks():
    rng = np.random.default_rng(6)
    sigmas = []
    for baseline in (1.0, 0.1, 0.01):
        R, t, x1, x2 = _two_view(rng, baseline)
        sigmas.append(translation_sigma_deg(R, t, x1, x2, np.ones(len(x1), bool)))
    assert sigmas[0] < 1.0 < sigmas[2]
    assert sigmas[0] < sigmas[1] < sigmas[2]
    # t = 0: every direction fits; the Hessian (not J^T J) sees the flat cost
    R, _, x1, x2 = _two_view(rng, 1e-12)
    flat = translation_sigma_deg(R, np.array([1.0, 0.0, 0.0]), x1, x2, np.ones(len(x1), bool))
    assert flat > 30.0


def test_decide_motion_on_synthetic_matches():
    rng = np.random.default_rng(7)
    R, t, x1, x2 = _two_view(rng, 0.0 + 1e-9)
    used = np.ones(len(x1), bool)
    rotation = decide_motion(x1, x2, R, np.array([1.0, 0, 0]), used, 800.0)
    # the focal is estimated with the rotation (prior 2 %): its uncertainty costs a little here
    assert rotation.pure_rotation and rotation_error_deg(rotation.R, R) < 0.1
    assert abs(rotation.focal_scale - 1.0) < 0.01
    R, t, x1, x2 = _two_view(rng, 0.5)
    general = decide_motion(x1, x2, R, t, used, 800.0)
    assert general.model == "general" and general.gric_difference > 0.5


def _demo_photo() -> np.ndarray:
    data = resources.files("ppo_cv.data").joinpath("demo1.png").read_bytes()
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)


@pytest.mark.parametrize("seed", [0, 1])
def test_warped_photo_rotation_is_flagged_with_accurate_rotation(seed):
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, seed, angle_range=(10.0, 15.0))
    result = estimate_pair(pair.image1, pair.image2, pair.K_given)
    assert result.pure_rotation and result.model == "rotation"
    assert not result.translation_determined and result.num_points == 0
    # the given focal alone would leave |angle * focal_error| (up to 0.45 deg here); the fitted
    # focal of a few dozen matches recovers part of it
    assert rotation_error_deg(result.R, pair.R) < 0.5
    assert result.uncertainty.t_sigma_deg > 30.0
    assert 0.0 < result.uncertainty.rotation_sigma_deg < 1.0


@pytest.mark.parametrize("seed", [0, pytest.param(3, marks=pytest.mark.slow)])
def test_imperfect_render_rotation_is_flagged(seed):
    pair = imperfect_render(seed)
    result = estimate_pair(pair.image1, pair.image2, pair.K_given)
    assert result.pure_rotation and result.model == "rotation"
    assert rotation_error_deg(result.R, pair.R) < 0.5
    assert result.evidence.selection.rotation_residual_px < 1.0


def test_imperfect_render_with_baseline_is_not_flagged():
    wide = imperfect_render(1, 0.15)
    narrow = imperfect_render(1, 0.05)
    wide_result = estimate_pair(wide.image1, wide.image2, wide.K_given)
    narrow_result = estimate_pair(narrow.image1, narrow.image2, narrow.K_given)
    for result in (wide_result, narrow_result):
        assert not result.pure_rotation and result.model == "general"
        assert result.evidence.selection.gric_difference > 0 and result.num_points > 0
    assert wide_result.uncertainty.t_sigma_deg < narrow_result.uncertainty.t_sigma_deg < 180.0


def test_score_pose_rejects_a_pair_the_model_comparison_calls_a_rotation():
    from ppo_cv import recover_pose, sfm

    rng = np.random.default_rng(8)
    R, t, x1, x2 = _two_view(rng, 1e-9)
    used = np.ones(len(x1), bool)
    motion = decide_motion(x1, x2, R, np.array([1.0, 0.0, 0.0]), used, 800.0)
    _, _, x1g, x2g = _two_view(rng, 1.0)
    E = np.cross(np.eye(3), np.array([1.0, 0.1, 0.0])) @ R
    pose = recover_pose(E, x1g[:, :2], x2g[:, :2], np.eye(3))
    assert sfm.score_pose(pose, min_inliers=10)[2] == ""
    score, _, rejection = sfm.score_pose(pose, motion=motion, min_inliers=10)
    assert score == 0.0 and rejection.startswith("pure rotation (rotation model")


def _data_gen_result(pair):
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    return estimate_pair(image1, image2, pair.K1_given, pair.K2_given)


@pytest.mark.slow
def test_data_gen_panorama_and_warped_photo_are_flagged():
    from ppo_cv import data_gen

    for pair in (
        data_gen.make_pair("panorama", seed=0, index=1, imperfections=data_gen.REAL_PHOTO),
        data_gen.make_warped_pair(seed=0, index=1),
    ):
        result = _data_gen_result(pair)
        assert result.pure_rotation and result.model == "rotation"
        assert rotation_error_deg(result.R, pair.R) < 0.5


@pytest.mark.parametrize(
    "index", [pytest.param(0, marks=pytest.mark.slow), pytest.param(1, marks=pytest.mark.slow), 2]
)
def test_tripod_pan_about_a_point_behind_the_lens_is_flagged(index):
    """A real tripod turns the camera about its screw, not the lens's centre: t of a few cm."""
    from ppo_cv import data_gen

    pair = data_gen.make_pair(
        "panorama", seed=5, index=index, imperfections=data_gen.REAL_PHOTO, pivot_offset=0.08
    )
    assert 0.005 < np.linalg.norm(pair.t) < 0.03
    result = _data_gen_result(pair)
    assert result.pure_rotation and result.model == "rotation"
    assert rotation_error_deg(result.R, pair.R) < 0.3
    assert result.uncertainty.rotation_tracks > 100
    assert result.evidence.tracks.parallax < 0.5 * MAX_TRACK_PARALLAX


@pytest.mark.parametrize(
    ("kind", "index", "k2_fraction"),
    [("warp", 1, 2.0), pytest.param("panorama", 3, -2.0, marks=pytest.mark.slow)],
)
def test_unmodelled_higher_order_distortion_in_a_narrow_overlap_keeps_the_flag(
    kind, index, k2_fraction, request
):
    """A lens with ``k2 = -+2 k1``, which neither the rotation's lens terms nor a homography
    model, told all a stitcher tells, turning 0.6 of its 25-35 degree field: the tracks' plane
    does not pass for one that moved."""
    from ppo_cv import data_gen

    stitched = data_gen.Imperfections(
        centred_principal_point=True, view_focal_error=0.01, exposure_ev=1.0, vignetting=0.35,
        k2_fraction=k2_fraction,
    )  # fmt: skip
    if kind == "warp":
        photos = request.getfixturevalue("freiburg_photos")
        pair = data_gen.make_warped_pair(
            seed=1, index=index, imperfections=stitched, source=photos
        )
    else:
        pair = data_gen.make_pair(
            "panorama", seed=1, index=index, imperfections=stitched, pivot_offset=0.08
        )
    assert abs(pair.params["yaw_deg"]) >= 0.6 * pair.params["hfov_deg"]
    assert pair.params["k2"] == pytest.approx(k2_fraction * pair.params["k1"])
    result = _data_gen_result(pair)
    assert result.pure_rotation and result.model == "rotation"
    assert rotation_error_deg(result.R, pair.R) < 0.3
    assert result.uncertainty.rotation_tracks > 100
    assert result.evidence.tracks.parallax < 0.5 * MAX_TRACK_PARALLAX


def test_data_gen_tiny_baseline_of_five_percent_is_not_flagged():
    from ppo_cv import data_gen

    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=1, imperfections=data_gen.REAL_PHOTO, baseline_ratio=0.05
    )
    result = _data_gen_result(pair)
    assert not result.pure_rotation and result.evidence.selection.gric_difference > 0
    assert result.uncertainty.t_sigma_deg < 10.0


def test_a_small_baseline_whose_rotation_needs_an_implausible_focal_is_not_flagged():
    """Baseline / depth 0.02 toward a back wall with boxes before it: the rotation explains the
    matches only with a focal 9 % short, far beyond the 5 % a given focal may be off."""
    from ppo_cv import data_gen

    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=32, imperfections=data_gen.REAL_PHOTO, baseline_ratio=0.02
    )
    assert abs(pair.params["focal_factor"] - 1.0) < 0.01 and pair.params["scene"] == "clutter"
    result = _data_gen_result(pair)
    assert not result.pure_rotation and result.model != "rotation"
    assert result.translation_determined
    # the rotation won the comparison; its lens, clipped to the box, is what refused it
    assert result.evidence.selection.gric_difference < 0
    assert result.lens.lens_excess > LENS_SIGNIFICANCE
    from ppo_cv.cli.pair import _summary
    from ppo_cv.export import result_to_dict

    record = result_to_dict(result)["lens"]
    assert record["lens_excess"] == pytest.approx(result.lens.lens_excess)
    text = _summary(result, "a.png", "b.png", None)
    assert f"lens {result.lens.lens_excess:.1f} deviations beyond the plausible" in text


@pytest.mark.slow
def test_a_sideways_step_before_a_wall_that_the_matches_take_for_a_rotation_is_not_flagged():
    """Baseline / depth 0.02 across a back wall, principal point guessed at the centre: the
    rotation absorbs the nearly uniform shift on the feature matches and wins, but the plane of
    the intensity-aligned tracks moved about 1.3 % of its distance."""
    from ppo_cv import data_gen
    from ppo_cv.cli.pair import _summary
    from ppo_cv.export import result_to_dict

    told = data_gen.Imperfections(centred_principal_point=True)
    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=8, imperfections=told, baseline_ratio=0.02
    )
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    matches = estimate_pair(
        image1, image2, pair.K1_given, pair.K2_given, options=PairOptions(photometric=False)
    )
    assert matches.pure_rotation and np.isnan(matches.evidence.tracks.parallax)
    result = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    assert not result.pure_rotation and result.model != "rotation"
    assert result.uncertainty.rotation_tracks == 0 and result.translation_determined
    bound = MAX_TRACK_PARALLAX + PARALLAX_SIGNIFICANCE * result.evidence.tracks.parallax_sigma
    assert bound < result.evidence.tracks.parallax < 0.02
    assert result.uncertainty.t_sigma_deg < matches.uncertainty.t_sigma_deg
    record = result_to_dict(result)["evidence"]["tracks"]
    assert record["parallax"] == pytest.approx(result.evidence.tracks.parallax)
    assert f"moved {result.evidence.tracks.parallax:.4f} +-" in _summary(
        result, "a.png", "b.png", None
    )


@pytest.mark.parametrize("index", [8, pytest.param(11, marks=pytest.mark.slow)])
def test_a_rotation_whose_features_are_worse_along_the_pan_is_flagged(index, freiburg_photos):
    """Sensor noise and blur on a warped photo locate the features worse along the pan than
    across it; the essential matrix, seeing only the component across its epipolar lines,
    understated the noise and won GRIC (+0.02 and +0.10 per match). The rotation's residuals,
    incoherent from a match to its neighbour, carry the noise GRIC divides by."""
    import dataclasses

    from ppo_cv import data_gen

    noisy = dataclasses.replace(data_gen.REAL_PHOTO, noise_std=6.0, blur_sigma=1.2)
    pair = data_gen.make_warped_pair(
        seed=0, index=index, imperfections=noisy, source=freiburg_photos
    )
    result = _data_gen_result(pair)
    assert result.pure_rotation and result.model == "rotation"
    assert result.evidence.selection.gric_difference < -0.2
    assert rotation_error_deg(result.R, pair.R) < 0.3
    assert (
        result.evidence.selection.rotation_noise_px > 1.4 * result.evidence.selection.noise_sigma_px
    )
    from ppo_cv.export import result_to_dict

    record = result_to_dict(result)["evidence"]["selection"]
    assert record["rotation_noise_px"] == pytest.approx(result.evidence.selection.rotation_noise_px)


def _foliage_pair(seed: int, ratio: float):
    """Three hundred small quads 3-12 m away before a backdrop, as leaves: depth changes from
    one feature to the next. A translation of ``ratio`` times the median depth."""
    from imperfect import _jpeg, _rotation, _virtual_K

    from ppo_cv.data_gen.render import median_depth, render_pair
    from ppo_cv.data_gen.scenes import Scene, _textured_quad, _vec, make_scene

    rng = np.random.default_rng([seed, 77])
    quads = list(make_scene("backdrop", rng).quads)
    for _ in range(300):
        z = rng.uniform(3, 12)
        side = rng.uniform(0.1, 0.35) * z / 5
        x, y = rng.uniform(-0.3, 0.3, 2) * z
        quads.append(_textured_quad(rng, _vec(x, y, z), _vec(side, 0, 0), _vec(0, side, side / 5)))
    scene = Scene("foliage", tuple(quads), _vec(0, 0, 6), 6.0, {})
    K = _virtual_K((640, 480), rng.uniform(25, 35))
    R = _rotation(rng.uniform(2, 8) * rng.choice([-1, 1]), rng.normal(0, 2), rng.normal(0, 2))
    dist = np.array([rng.uniform(0.02, 0.1) * rng.choice([-1.0, 1.0]), 0, 0, 0, 0])
    direction = rng.normal(size=3) * [1.0, 0.5, 0.5]
    baseline = ratio * median_depth(scene, K, (640, 480), dist)
    t = -R @ (baseline * direction / np.linalg.norm(direction))
    pair = render_pair(scene, K, K, R, t, (640, 480), 2, dist, dist, noise_std=1.0, seed=seed)
    image1, image2 = (
        _jpeg(np.ascontiguousarray(v[:, :, ::-1]), 85) for v in (pair.image1, pair.image2)
    )
    K_given = K * [[1.02], [1.02], [1.0]]
    return image1, image2, K_given, R


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.0, 0.02])
def test_leaves_at_many_depths_do_not_pass_for_noise(ratio):
    """The rotation's incoherent noise is measured between nearest neighbours; before foliage,
    where the depth jumps from one feature to the next, it must still see a translation's
    parallax as parallax, and a rotation as a rotation."""
    image1, image2, K, R = _foliage_pair(3, ratio)
    result = estimate_pair(image1, image2, K, K)
    assert result.pure_rotation == (ratio == 0.0)
    assert (
        result.evidence.selection.rotation_noise_px < 1.5 * result.evidence.selection.noise_sigma_px
    )
    if ratio == 0.0:
        assert rotation_error_deg(result.R, R) < 0.1
    else:
        assert result.evidence.selection.gric_difference > 0.5


@pytest.mark.slow
def test_automatic_exposure_and_vignetting_keep_the_decision():
    """Shots one stop apart at most, clipped at white, corners 35 % darker: a warped photo and
    a tripod pan stay flagged with an accurate rotation, a 2 % baseline stays general."""
    from ppo_cv import data_gen

    lit = data_gen.Imperfections(exposure_ev=1.0, vignetting=0.35)
    warped = data_gen.make_warped_pair(seed=0, index=6, imperfections=lit)
    tripod = data_gen.make_pair("panorama", seed=0, index=3, imperfections=lit, pivot_offset=0.08)
    for pair, bound in ((warped, 0.1), (tripod, 0.2)):
        assert abs(pair.params["exposure_ev"]) > 0.7
        result = _data_gen_result(pair)
        assert result.pure_rotation and rotation_error_deg(result.R, pair.R) < bound
    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=4, imperfections=lit, baseline_ratio=0.02
    )
    assert abs(pair.params["exposure_ev"]) > 0.7
    result = _data_gen_result(pair)
    assert not result.pure_rotation and result.evidence.selection.gric_difference > 0.5


def test_the_flag_does_not_rest_on_a_loosely_refined_essential_matrix(monkeypatch):
    """Refined from its RANSAC model, an essential matrix may stop in a worse minimum of the
    Sampson error than one whose translation lies along the pan, which absorbs the larger
    along-pan part of the feature noise. Kept at the best of 48 starting translations, the
    general model fits a warped pan far more closely, and the rotation must still win."""
    import ppo_cv.pipeline as pipeline
    from ppo_cv import data_gen
    from ppo_cv.refine import refine_pose
    from ppo_cv.robust import essential_from_pose, sampson_errors

    loose = pipeline._refine
    theta, phi = np.meshgrid(np.linspace(0.15, np.pi - 0.15, 6), np.linspace(0, 2 * np.pi, 9)[:-1])
    starts = np.column_stack(
        [
            np.sin(theta.ravel()) * np.cos(phi.ravel()),
            np.sin(theta.ravel()) * np.sin(phi.ravel()),
            np.cos(theta.ravel()),
        ]
    )

    def best_of_starts(R, t, x1, x2, inliers, focal, options, rounds=3):
        R, t, inliers = loose(R, t, x1, x2, inliers, focal, options, rounds)

        def median_error(pose):
            return np.median(sampson_errors(essential_from_pose(*pose), x1[inliers], x2[inliers]))

        poses = [(R, t)] + [refine_pose(R, start, x1, x2, inliers, focal) for start in starts]
        return (*min(poses, key=median_error), inliers)

    pair = data_gen.make_warped_pair(seed=0, index=13)
    views = (
        np.ascontiguousarray(pair.image1[..., ::-1]),
        np.ascontiguousarray(pair.image2[..., ::-1]),
    )
    single = PairOptions(redetect_below=0)  # the matches of one detection, 59 inliers
    before = estimate_pair(*views, pair.K1_given, pair.K2_given, options=single)
    monkeypatch.setattr(pipeline, "_refine", best_of_starts)
    after = estimate_pair(*views, pair.K1_given, pair.K2_given, options=single)
    assert (
        after.evidence.selection.general_residual_px
        < 0.6 * before.evidence.selection.general_residual_px
    )
    assert after.evidence.selection.gric_difference > before.evidence.selection.gric_difference
    assert after.pure_rotation and rotation_error_deg(after.R, pair.R) < 0.3


@pytest.mark.slow
def test_t_sigma_over_the_tiny_baseline_sweep():
    from ppo_cv import data_gen

    def sigmas(motion, ratio):
        return [
            _data_gen_result(
                data_gen.make_pair(
                    motion,
                    seed=0,
                    index=index,
                    imperfections=data_gen.REAL_PHOTO,
                    baseline_ratio=ratio,
                )  # fmt: skip
            ).uncertainty.t_sigma_deg
            for index in (0, 2)
        ]

    rotation = sigmas("pure-rotation", None)
    tiny, small, clear = (sigmas("tiny-baseline", r) for r in (0.001, 0.01, 0.05))
    assert min(rotation) > 30.0
    assert np.mean(tiny) > np.mean(small) > np.mean(clear)
    assert max(clear) < 2.0
