"""estimate_pair on rendered pairs with exact ground truth, and its building blocks."""

from __future__ import annotations

import doctest

import cv2
import numpy as np
import pytest

from ppo_cv import refine as refine_module
from ppo_cv.data_gen import make_pair, make_scene, render_pair, sample_motion
from ppo_cv.features import Features, detect_features, match_features
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.pipeline import PairOptions, estimate_pair
from ppo_cv.refine import fit_rotation, refine_pose, rotation_residuals
from ppo_cv.robust import essential_from_pose, estimate_essential, sampson_errors

SIZE = (640, 480)
DIST = np.array([-0.25, 0.08, 0.0005, -0.0005, 0.0])


def bgr(image):
    return np.ascontiguousarray(image[:, :, ::-1])


@pytest.fixture(scope="module")
def general():
    return make_pair("general", seed=3, index=0, size=SIZE, supersample=2)


@pytest.fixture(scope="module")
def rotation():
    return make_pair("pure-rotation", seed=3, index=0, size=SIZE, supersample=2)


@pytest.fixture(scope="module")
def distorted():
    scene = make_scene("clutter", seed=5)
    motion = sample_motion("general", scene, np.random.default_rng(5), size=SIZE)
    return render_pair(
        scene,
        motion.K1,
        motion.K2,
        motion.R,
        motion.t,
        size=SIZE,
        supersample=2,
        dist1=DIST,
        dist2=DIST,
    )


@pytest.fixture(scope="module")
def general_result(general):
    return estimate_pair(bgr(general.image1), bgr(general.image2), general.K1, general.K2)


def test_general_motion_matches_ground_truth(general, general_result):
    result = general_result
    assert not result.pure_rotation and result.translation_determined
    assert result.pri > result.evidence.selection.pri_threshold
    assert rotation_error_deg(result.R, general.R) < 0.3
    assert direction_error_deg(result.t, general.t) < 2.0
    assert result.num_inliers >= 50 and result.num_inliers <= result.num_matches
    assert set(result.timings) >= {"features", "matching", "ransac", "ppo", "refine"}


def test_progress_names_every_stage_as_it_ends(general, general_result):
    ended = []
    result = estimate_pair(
        bgr(general.image1), bgr(general.image2), general.K1, general.K2, progress=ended.append
    )
    assert set(ended) == set(result.timings) == set(general_result.timings)
    assert ended[0] == "load" and ended[-1] == list(result.timings)[-1]


def test_a_consensus_that_fails_ends_its_stages_before_raising():
    """Matches with no common geometry: the time of the failed fit is the ``ransac`` stage's,
    not the next stage's."""
    from ppo_cv.consensus import _consensus

    rng = np.random.default_rng(5)
    descriptors = rng.random((300, 128)).astype(np.float32)
    keypoints = rng.uniform(0, 480, (2, 300, 2))
    f1 = Features(keypoints[0], descriptors, "sift")
    f2 = Features(keypoints[1], descriptors[::-1].copy(), "sift")
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    ended = []
    with pytest.raises(ValueError, match="no reliable two-view geometry"):
        _consensus(f1, f2, 1.0, K, K, None, None, 500.0, (480, 640), PairOptions(), ended.append)
    assert ended == ["matching", "undistort", "ransac"]


def test_general_motion_points_match_the_depth_map(general, general_result):
    result = general_result
    assert 0.5 * result.num_inliers < result.num_points <= result.num_inliers
    # One row per match, finite exactly at point_matches, all of them inliers.
    assert result.points3d.shape == (result.num_matches, 3)
    finite_rows = np.flatnonzero(np.isfinite(result.points3d).all(axis=1))
    np.testing.assert_array_equal(finite_rows, result.point_matches)
    assert result.inliers[result.point_matches].all()
    points = result.points3d[result.point_matches]
    assert np.all(points[:, 2] > 0)
    # Baseline units to metres, then compare with the rendered depth at the keypoints.
    z = points[:, 2] * np.linalg.norm(general.t)
    uv = np.rint(result.keypoints1[result.matches[result.point_matches, 0]]).astype(int)
    z_true = general.depth1[uv[:, 1], uv[:, 0]]
    finite = np.isfinite(z_true)
    assert finite.mean() > 0.9
    assert np.median(np.abs(z[finite] / z_true[finite] - 1)) < 0.03
    assert result.colours.shape == (result.num_matches, 3) and result.colours.dtype == np.uint8


def test_pure_rotation_is_flagged_and_rotation_refined(rotation):
    result = estimate_pair(bgr(rotation.image1), bgr(rotation.image2), rotation.K1, rotation.K2)
    assert result.pure_rotation and not result.translation_determined
    assert result.pri < result.evidence.selection.pri_threshold
    assert rotation_error_deg(result.R, rotation.R) < 0.1
    assert result.num_points == 0 and result.points3d.shape == (result.num_matches, 3)
    assert np.isnan(result.points3d).all()
    assert np.isclose(np.linalg.norm(result.t), 1.0)


def test_distortion_is_removed_from_the_points(distorted):
    images = bgr(distorted.image1), bgr(distorted.image2)
    K1, K2 = distorted.K1, distorted.K2
    with_dist = estimate_pair(*images, K1, K2, dist1=DIST, dist2=DIST)
    assert rotation_error_deg(with_dist.R, distorted.R) < 0.3
    assert direction_error_deg(with_dist.t, distorted.t) < 2.0
    without = estimate_pair(*images, K1, K2)
    assert with_dist.num_inliers > without.num_inliers


def test_dist2_defaults_to_dist1_for_one_camera(distorted):
    images = bgr(distorted.image1), bgr(distorted.image2)
    result = estimate_pair(*images, distorted.K1, dist1=DIST)
    assert rotation_error_deg(result.R, distorted.R) < 0.3


def test_opencv_backend_agrees(general):
    options = PairOptions(backend="opencv")
    result = estimate_pair(
        bgr(general.image1), bgr(general.image2), general.K1, general.K2, options=options
    )
    assert rotation_error_deg(result.R, general.R) < 0.5
    assert direction_error_deg(result.t, general.t) < 3.0


@pytest.mark.parametrize("features", ["orb", "akaze"])
def test_binary_features(general, features):
    options = PairOptions(features=features)
    result = estimate_pair(general.image1, general.image2, general.K1, general.K2, options=options)
    assert rotation_error_deg(result.R, general.R) < 1.0
    assert direction_error_deg(result.t, general.t) < 5.0


def test_image_paths_are_accepted(tmp_path, general, general_result):
    paths = [tmp_path / "a.png", tmp_path / "b.png"]
    for path, image in zip(paths, (general.image1, general.image2), strict=True):
        cv2.imwrite(str(path), bgr(image))
    result = estimate_pair(*paths, general.K1, general.K2)
    np.testing.assert_allclose(result.R, general_result.R, atol=1e-9)


def test_identical_images_are_rejected(general):
    with pytest.raises(ValueError, match="identical"):
        estimate_pair(general.image1, general.image1.copy(), general.K1)


def test_blank_image_is_rejected(general):
    blank = np.full_like(general.image1, 128)
    with pytest.raises(ValueError, match="too few features"):
        estimate_pair(general.image1, blank, general.K1)


def test_unrelated_images_are_rejected(general):
    noise = np.random.default_rng(0).integers(0, 256, general.image1.shape, dtype=np.uint8)
    with pytest.raises(ValueError, match="too few matches|no reliable two-view geometry"):
        estimate_pair(general.image1, cv2.GaussianBlur(noise, (0, 0), 2), general.K1)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"features": "surf"}, "unknown features"),
        ({"backend": "magic"}, "unknown backend"),
        ({"ratio": 1.5}, "ratio"),
        ({"ransac_threshold": 0}, "ransac_threshold"),
        ({"min_trials": 10, "max_trials": 5}, "min_trials"),
        ({"redetect_below": -1}, "redetect_below"),
    ],
)
def test_pair_options_are_checked(kwargs, message):
    with pytest.raises(ValueError, match=message):
        PairOptions(**kwargs)


def test_bad_arguments(general):
    with pytest.raises(ValueError, match="not found"):
        estimate_pair("/nonexistent/a.png", general.image2, general.K1)
    with pytest.raises(ValueError, match="K1 must be a 3x3"):
        estimate_pair(general.image1, general.image2, np.eye(2))
    with pytest.raises(ValueError, match="dist1"):
        estimate_pair(general.image1, general.image2, general.K1, dist1=[0.1, 0.2])
    with pytest.raises(ValueError, match="image1 must be an image"):
        estimate_pair(np.zeros(5), general.image2, general.K1)


# --- building blocks -------------------------------------------------------------------------


def test_refine_doctest():
    result = doctest.testmod(refine_module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


def test_dense_matcher_equals_opencv_brute_force():
    rng = np.random.default_rng(1)
    d1 = rng.random((300, 128), dtype=np.float32)
    d2 = np.concatenate(
        [
            d1[:200] + 0.02 * rng.random((200, 128), dtype=np.float32),
            rng.random((150, 128), dtype=np.float32),
        ]
    )
    f1 = Features(np.zeros((300, 2)), d1, "sift")
    f2 = Features(np.zeros((350, 2)), d2, "sift")
    ours = match_features(f1, f2, ratio=0.8, mutual=True, unique=False)  # equal keypoints
    bf = cv2.BFMatcher(cv2.NORM_L2, crossCheck=False)
    forward = bf.knnMatch(d1, d2, k=2)
    backward = {m.queryIdx: m.trainIdx for m in bf.match(d2, d1)}
    expected = [
        (a.queryIdx, a.trainIdx)
        for a, b in forward
        if a.distance < 0.8 * b.distance and backward[a.trainIdx] == a.queryIdx
    ]
    assert sorted(map(tuple, ours.tolist())) == sorted(expected)
    assert len(expected) >= 190
    flann = match_features(f1, f2, ratio=0.8, mutual=True, flann=True, unique=False)
    assert len(set(map(tuple, flann.tolist())) & set(expected)) >= 0.95 * len(expected)


def test_downscaled_detection_maps_keypoints_to_full_resolution(general):
    image = bgr(general.image1)
    big = cv2.resize(image, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
    small = detect_features(image, max_features=500)
    mapped = detect_features(big, max_features=500, max_image_size=640)
    expected = (small.keypoints + 0.5) * 2 - 0.5
    nearest = np.min(np.linalg.norm(mapped.keypoints[:, None] - expected[None], axis=2), axis=1)
    assert np.median(nearest) < 0.5


def _synthetic_correspondences(rng, n=200, outliers=0.3, noise=0.3, f=500.0):
    X = rng.uniform([-2, -2, 4], [2, 2, 8], (n, 3))
    angle = np.radians(8)
    R = cv2.Rodrigues(np.array([0.2, 1.0, 0.1]) / np.linalg.norm([0.2, 1.0, 0.1]) * angle)[0]
    t = np.array([1.0, 0.1, 0.2])
    X2 = X @ R.T + t
    x1, x2 = X[:, :2] / X[:, 2:], X2[:, :2] / X2[:, 2:]
    x1 = x1 + rng.normal(0, noise / f, x1.shape)
    x2 = x2 + rng.normal(0, noise / f, x2.shape)
    bad = rng.random(n) < outliers
    x2[bad] = rng.uniform(-0.5, 0.5, (bad.sum(), 2))
    ones = np.ones((n, 1))
    return np.hstack([x1, ones]), np.hstack([x2, ones]), R, t / np.linalg.norm(t), ~bad


@pytest.mark.parametrize("backend", ["pycolmap", "opencv"])
def test_robust_backends_find_the_inliers(backend):
    x1, x2, R, t, good = _synthetic_correspondences(np.random.default_rng(2))
    fit = estimate_essential(x1, x2, 500.0, backend=backend, threshold=1.5)
    assert fit is not None
    E_true = essential_from_pose(R, t)
    assert min(np.linalg.norm(fit.E - E_true), np.linalg.norm(fit.E + E_true)) < 0.1
    assert np.mean(fit.inliers[good]) > 0.95 and np.mean(fit.inliers[~good]) < 0.05


def test_sampson_error_of_exact_matches_is_zero():
    x1, x2, R, t, _ = _synthetic_correspondences(np.random.default_rng(3), outliers=0, noise=0)
    assert np.max(sampson_errors(essential_from_pose(R, t), x1, x2)) < 1e-12


@pytest.mark.parametrize("shape", [(), (7,)])
def test_sampson_residual_equals_its_formula_summed_along_the_last_axis(shape):
    """Bit for bit: the refinements' answers do not move with the way the sums are written."""
    from ppo_cv.robust import sampson_signed

    rng = np.random.default_rng(5)
    E = rng.normal(size=shape + (3, 3))
    x1, x2 = (np.column_stack([rng.normal(size=(300, 2)), np.ones(300)]) for _ in "ab")
    points1 = np.broadcast_to(x1, shape + x1.shape)
    Ex1, Etx2 = points1 @ np.swapaxes(E, -1, -2), x2 @ E
    norm = np.sqrt(np.sum(Ex1[..., :2] ** 2, axis=-1) + np.sum(Etx2[..., :2] ** 2, axis=-1))
    expected = np.sum(x2 * Ex1, axis=-1) / norm
    np.testing.assert_array_equal(sampson_signed(E, points1, x2), expected)


def test_sampson_residual_is_the_first_order_distance_to_the_epipolar_line():
    from ppo_cv.robust import sampson_signed

    x1, x2, R, t, _ = _synthetic_correspondences(np.random.default_rng(3), outliers=0, noise=0)
    E = essential_from_pose(R, t)
    line = x1 @ E.T  # epipolar line of x1 in image 2
    normal = line[:, :2] / np.linalg.norm(line[:, :2], axis=1, keepdims=True)
    moved = x2.copy()
    moved[:, :2] += 1e-4 * normal  # 1e-4 off the line, along its normal, in image 2 only
    signed = sampson_signed(E, x1, moved)
    # both images share the residual: the Sampson distance is about 1e-4 * |l2| / |(l1, l2)|
    share = np.linalg.norm(line[:, :2], axis=1) / np.sqrt(
        np.sum(line[:, :2] ** 2, axis=1) + np.sum((moved @ E)[:, :2] ** 2, axis=1)
    )
    np.testing.assert_allclose(signed, 1e-4 * share, rtol=1e-3)
    np.testing.assert_allclose(sampson_errors(E, x1, moved), np.abs(signed))
    stacked = sampson_signed(np.stack([E, -E]), x1, moved)  # broadcast over a leading axis
    np.testing.assert_allclose(stacked, np.stack([signed, -signed]))


@pytest.mark.parametrize("noise", [0.0, 0.3])
def test_refine_pose_reaches_the_least_squares_optimum(noise):
    x1, x2, R, t, good = _synthetic_correspondences(
        np.random.default_rng(4), outliers=0.2, noise=noise
    )
    R0 = cv2.Rodrigues(np.array([0.01, -0.01, 0.005]))[0] @ R
    t0 = t + np.array([0.05, -0.05, 0.02])
    R1, t1 = refine_pose(R0, t0, x1, x2, good, 500.0)
    assert np.isclose(np.linalg.norm(t1), 1.0)
    if noise == 0:
        assert rotation_error_deg(R1, R) < 1e-5 and direction_error_deg(t1, t) < 1e-4
    else:

        def cost(R_, t_):
            return np.sum(sampson_errors(essential_from_pose(R_, t_), x1[good], x2[good]) ** 2)

        assert cost(R1, t1) <= cost(R, t) < cost(R0, t0)
        assert rotation_error_deg(R1, R) < 0.3 < rotation_error_deg(R0, R)


def test_fit_rotation_ignores_outliers():
    rng = np.random.default_rng(5)
    x1 = np.hstack([rng.uniform(-0.5, 0.5, (100, 2)), np.ones((100, 1))])
    R = cv2.Rodrigues(np.array([0.05, -0.1, 0.02]))[0]
    x2 = x1 @ R.T
    x2 = x2 / x2[:, 2:]
    x2[:20, :2] += rng.uniform(-0.2, 0.2, (20, 2))
    R_start = cv2.Rodrigues(np.array([3e-4, 0.0, -3e-4]))[0] @ R
    R_fit, used = fit_rotation(x1, x2, np.ones(100, bool), threshold=1e-3, R=R_start)
    assert rotation_error_deg(R_fit, R) < 1e-6
    assert not used[:20].any() and used[20:].all()
    assert np.max(rotation_residuals(R_fit, x1[20:], x2[20:])) < 1e-9
