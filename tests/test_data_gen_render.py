"""Rendered image pairs: exact geometry, depth, motion presets, and poses recovered by SIFT."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

import ppo_cv
from ppo_cv.data_gen import (
    MOTIONS,
    RenderedPair,
    Scene,
    checker_plane,
    intrinsics,
    look_at,
    make_pair,
    make_scene,
    project_points,
    render_pair,
    sample_motion,
)
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

SIZE = (640, 480)


def _checker_corners(scene: Scene) -> np.ndarray:
    quad = scene.quads[0]
    nx, ny = scene.params["squares"]
    i, j = np.meshgrid(np.arange(1, nx), np.arange(1, ny))
    return quad.origin + i.reshape(-1, 1) * quad.u / nx + j.reshape(-1, 1) * quad.v / ny


def _corner_errors(image, X, K, R, t, dist=None, pattern=(9, 7)):
    gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    found, corners = cv2.findChessboardCornersSB(gray, pattern, flags=cv2.CALIB_CB_ACCURACY)
    assert found, "OpenCV must find the rendered checkerboard"
    projected = project_points(X, K, R, t, dist)
    distances = np.linalg.norm(corners.reshape(-1, 1, 2) - projected[None], axis=2)
    assert np.all(distances.argmin(axis=0) != -1)
    return distances.min(axis=0)


def _checker_pose():
    centre = np.array([0.45, -0.25, 0.2])
    R = look_at(centre, np.array([0.0, 0.0, 3.0]), roll_deg=7.0)
    return R, -R @ centre


def test_checker_corners_land_on_their_projections():
    scene = checker_plane(distance=3.0, squares=(10, 8), square_m=0.25)
    K1 = intrinsics(SIZE, 60.0, (4.3, -3.1))
    K2 = intrinsics(SIZE, 52.0, (-6.0, 2.5))
    R, t = _checker_pose()
    pair = render_pair(scene, K1, K2, R, t, SIZE, supersample=3)
    X = _checker_corners(scene)
    e1 = _corner_errors(pair.image1, X, K1, np.eye(3), np.zeros(3))
    e2 = _corner_errors(pair.image2, X, K2, R, t)
    assert e1.max() < 0.3 and e2.max() < 0.3
    assert e1.mean() < 0.1 and e2.mean() < 0.1
    np.testing.assert_allclose(pair.depth1[pair.depth1 < np.inf], 3.0, rtol=1e-5)


def test_checker_corners_with_lens_distortion():
    scene = checker_plane(distance=3.0, squares=(10, 8), square_m=0.25)
    K = intrinsics(SIZE, 62.0)
    dist1 = np.array([-0.25, 0.08, 0.001, -0.0015, 0.0])
    dist2 = np.array([0.12, -0.03, -0.001, 0.001, 0.0])
    R, t = _checker_pose()
    pair = render_pair(scene, K, K, R, t, SIZE, supersample=2, dist1=dist1, dist2=dist2)
    X = _checker_corners(scene)
    assert _corner_errors(pair.image1, X, K, np.eye(3), np.zeros(3), dist1).max() < 0.3
    assert _corner_errors(pair.image2, X, K, R, t, dist2).max() < 0.3
    undistorted = project_points(X, K)
    assert np.abs(project_points(X, K, dist=dist1) - undistorted).max() > 3.0


def test_blur_and_noise_keep_the_geometry():
    scene = checker_plane(distance=3.0, squares=(10, 8), square_m=0.25)
    K = intrinsics(SIZE, 60.0)
    R, t = _checker_pose()
    clean = render_pair(scene, K, K, R, t, SIZE, supersample=2)
    pair = render_pair(scene, K, K, R, t, SIZE, supersample=2, noise_std=3.0, blur_sigma=1.2,
                       seed=1)  # fmt: skip
    residual = pair.image2.astype(float) - clean.image2
    assert 2.0 < residual.std() < 20.0
    again = render_pair(scene, K, K, R, t, SIZE, supersample=2, noise_std=3.0, blur_sigma=1.2,
                        seed=1)  # fmt: skip
    np.testing.assert_array_equal(pair.image2, again.image2)
    X = _checker_corners(scene)
    assert _corner_errors(pair.image1, X, K, np.eye(3), np.zeros(3)).max() < 0.3
    assert _corner_errors(pair.image2, X, K, R, t).max() < 0.3


def test_depth_map_lies_on_the_tilted_plane():
    scene = make_scene("plane", 4)
    quad = scene.quads[0]
    K = intrinsics(SIZE, 65.0)
    pair = render_pair(scene, K, K, np.eye(3), np.zeros(3), SIZE, supersample=2)
    assert pair.depth1.shape == SIZE[::-1] and pair.depth1.dtype == np.float32
    assert np.isfinite(pair.depth1).all()
    v, u = np.mgrid[: SIZE[1], : SIZE[0]]
    rays = np.stack([u, v, np.ones_like(u)], -1).reshape(-1, 3) @ np.linalg.inv(K).T
    X = rays * pair.depth1.reshape(-1, 1)
    normal = np.cross(quad.u, quad.v)
    normal /= np.linalg.norm(normal)
    assert np.abs((X - quad.origin) @ normal).max() < 1e-5 * pair.depth1.max()


def test_backdrop_at_infinity_moves_by_the_infinite_homography():
    backdrop = make_scene("backdrop", 2)
    sky = Scene("sky", tuple(q for q in backdrop.quads if q.at_infinity), backdrop.target, 5.0)
    K = intrinsics((320, 240), 60.0)
    R = look_at(np.zeros(3), np.array([0.2, -0.1, 1.0]), roll_deg=4.0)
    t = np.array([2.0, -1.0, 0.5])
    pair = render_pair(sky, K, K, R, t, (320, 240), supersample=2)
    assert np.isinf(pair.depth1).all()
    H = K @ R @ np.linalg.inv(K)
    warped = cv2.warpPerspective(pair.image1, H, (320, 240), flags=cv2.INTER_LINEAR)
    valid = cv2.warpPerspective(np.ones((240, 320), np.uint8), H, (320, 240)) > 0
    valid = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    diff = np.abs(warped.astype(float) - pair.image2.astype(float))[valid]
    shifted = np.abs(np.roll(warped, 2, axis=1).astype(float) - pair.image2)[valid]
    assert diff.mean() < 2.0 and shifted.mean() > 3 * diff.mean()


def test_presets_have_the_promised_motion():
    scene = make_scene("room", 0)
    for seed in range(5):
        rng = np.random.default_rng(seed)
        rotation = sample_motion("pure-rotation", scene, rng)
        assert np.all(rotation.t == 0.0) and rotation.t.shape == (3,)
        forward = sample_motion("forward", scene, rng)
        assert forward.t[0] == 0.0 and forward.t[1] == 0.0 and forward.t[2] < 0
        parallax = sample_motion("small-parallax", scene, rng, alpha=0.01)
        np.testing.assert_allclose(np.linalg.norm(parallax.t), 0.01 * 0.14 * scene.depth)
        assert parallax.params["alpha"] == 0.01
        general = sample_motion("general", scene, rng, same_intrinsics=False)
        assert not np.allclose(general.K1, general.K2)
        for motion in (rotation, forward, parallax, general):
            np.testing.assert_allclose(motion.R @ motion.R.T, np.eye(3), atol=1e-12)
            assert np.linalg.det(motion.R) > 0
    with pytest.raises(ValueError, match="unknown motion"):
        sample_motion("sideways", scene, np.random.default_rng(0))


def test_bad_render_inputs_are_rejected():
    scene = checker_plane()
    K = intrinsics((64, 48), 60.0)
    with pytest.raises(ValueError, match="R must be a rotation"):
        render_pair(scene, K, K, 2 * np.eye(3), np.zeros(3), (64, 48))
    with pytest.raises(ValueError, match="t must have shape"):
        render_pair(scene, K, K, np.eye(3), np.zeros(4), (64, 48))
    with pytest.raises(ValueError, match="K2"):
        render_pair(scene, K, -K, np.eye(3), np.zeros(3), (64, 48))
    with pytest.raises(ValueError, match="noise_std"):
        render_pair(scene, K, K, np.eye(3), np.zeros(3), (64, 48), noise_std=-1.0)
    with pytest.raises(TypeError, match="scene"):
        render_pair("room", K, K, np.eye(3), np.zeros(3), (64, 48))
    with pytest.raises(ValueError, match="unknown scene"):
        make_scene("garden")


def _matches(pair: RenderedPair):
    sift = cv2.SIFT_create(nfeatures=4000)
    k1, d1 = sift.detectAndCompute(cv2.cvtColor(pair.image1, cv2.COLOR_RGB2GRAY), None)
    k2, d2 = sift.detectAndCompute(cv2.cvtColor(pair.image2, cv2.COLOR_RGB2GRAY), None)
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m for m, n in knn if m.distance < 0.8 * n.distance]
    p1 = np.array([k1[m.queryIdx].pt for m in good], np.float64)
    p2 = np.array([k2[m.trainIdx].pt for m in good], np.float64)
    return p1, p2


@pytest.fixture(scope="module")
def general_pair() -> RenderedPair:
    return make_pair("general", seed=11, size=SIZE)


@pytest.fixture(scope="module")
def rotation_pair() -> RenderedPair:
    return make_pair("pure-rotation", seed=12, size=SIZE)


def test_rendered_pair_structure(general_pair, rotation_pair):
    for pair in (general_pair, rotation_pair):
        assert pair.image1.shape == (480, 640, 3) and pair.image1.dtype == np.uint8
        assert pair.R.shape == (3, 3) and pair.R.dtype == np.float64 and pair.t.shape == (3,)
        with pytest.raises(dataclasses.FrozenInstanceError):
            pair.R = np.eye(3)
    assert np.all(rotation_pair.t == 0.0)
    assert general_pair.params["motion"] == "general"


def test_sift_recovers_the_general_motion(general_pair):
    pair = general_pair
    p1, p2 = _matches(pair)
    assert len(p1) > 800
    E, mask = cv2.findEssentialMat(p1, p2, pair.K1, cv2.USAC_MAGSAC, 0.9999, 1.0)
    _, R, t, _ = ppo_cv.recoverPose(E[:3], p1, p2, pair.K1, mask=mask)
    assert rotation_error_deg(R, pair.R) < 0.5
    assert direction_error_deg(t, pair.t) < 2.0
    # the depth map and the pose predict where the matched points go
    inliers = mask.ravel() > 0
    u, v = np.rint(p1[inliers]).astype(int).T
    depth = pair.depth1[v, u]
    rays = np.column_stack([p1[inliers], np.ones(len(u))]) @ np.linalg.inv(pair.K1).T
    predicted = project_points(rays * depth[:, None], pair.K2, pair.R, pair.t)
    assert np.median(np.linalg.norm(predicted - p2[inliers], axis=1)) < 0.5


def test_sift_on_pure_rotation_flags_it(rotation_pair):
    pair = rotation_pair
    p1, p2 = _matches(pair)
    assert len(p1) > 800
    E, mask = cv2.findEssentialMat(p1, p2, pair.K1, cv2.USAC_MAGSAC, 0.9999, 1.0)
    result = ppo_cv.recover_pose(E[:3], p1, p2, pair.K1, mask=mask)
    assert result.pure_rotation
    assert rotation_error_deg(result.R, pair.R) < 0.5


@pytest.mark.parametrize("motion", MOTIONS)
def test_every_preset_renders_textured_views(motion):
    pair = make_pair(motion, seed=3, size=(160, 120), supersample=1)
    for image in (pair.image1, pair.image2):
        gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        assert cv2.Laplacian(gray, cv2.CV_64F).std() > 5.0
    assert np.isfinite(pair.depth1).mean() > 0.9
