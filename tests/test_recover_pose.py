"""ppo_cv.recover_pose against ground truth and against cv2.recoverPose."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from twoview import make_scene, random_rotation, skew

import ppo_cv
from ppo_cv.metrics import direction_error_deg, rotation_error_deg


def _general_motion(rng, K1, K2=None, noise_px=0.0, n=200):
    R = random_rotation(rng, 20.0)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    X, p1, p2 = make_scene(rng, n, R, t, K1, K2, noise_px=noise_px)
    return X, p1, p2, R, t


def test_result_is_frozen_with_named_fields(K):
    rng = np.random.default_rng(0)
    X, p1, p2, R, t = _general_motion(rng, K)
    result = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.R = np.eye(3)
    assert result.R.shape == (3, 3) and result.t.shape == (3,)
    assert result.inliers.dtype == bool and result.inliers.shape == (len(X),)
    assert result.points3d.shape == (len(X), 3) and result.depths.shape == (len(X), 2)
    assert result.num_inliers == len(X) and not result.pure_rotation
    assert result.pri_threshold == ppo_cv.DEFAULT_PRI_THRESHOLD


def test_two_cameras_with_different_intrinsics(K):
    rng = np.random.default_rng(1)
    K2 = np.array([[1200.0, 0.0, 600.0], [0.0, 1150.0, 410.0], [0.0, 0.0, 1.0]])
    for _ in range(20):
        X, p1, p2, R, t = _general_motion(rng, K, K2)
        result = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, K2)
        np.testing.assert_allclose(result.R, R, atol=1e-9)
        np.testing.assert_allclose(result.t, t, atol=1e-9)
        np.testing.assert_allclose(result.points3d, X, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(result.depths[:, 0], X[:, 2], rtol=1e-8)
        assert result.support_R == result.support_t == len(X)
        assert result.support_R_rejected == result.support_t_rejected == 0


def test_agrees_with_opencv_on_noisy_general_motion(K):
    rng = np.random.default_rng(2)
    for _ in range(60):
        _, p1, p2, R, t = _general_motion(rng, K, noise_px=0.5)
        E, ransac = cv2.findEssentialMat(p1, p2, K, cv2.RANSAC, 0.999, 1.0)
        E = E[:3]
        ours = ppo_cv.recover_pose(E, p1, p2, K, mask=ransac)
        count, R_cv, t_cv, mask_cv = cv2.recoverPose(E, p1, p2, K, mask=ransac.copy())
        assert rotation_error_deg(ours.R, R_cv) < 1e-4
        assert direction_error_deg(ours.t, t_cv) < 1e-4
        assert abs(ours.num_inliers - count) <= 0.02 * len(p1)
        assert rotation_error_deg(ours.R, R) < 1.0


def test_pure_rotation_keeps_the_right_rotation_where_cheirality_fails(K):
    rng = np.random.default_rng(7)
    opencv_wrong = 0
    for _ in range(40):
        R = random_rotation(rng, 15.0)
        _, p1, p2 = make_scene(rng, 200, R, np.zeros(3), K, noise_px=0.5)
        E, ransac = cv2.findEssentialMat(p1, p2, K, cv2.RANSAC, 0.999, 1.0)
        result = ppo_cv.recover_pose(E[:3], p1, p2, K, mask=ransac)
        assert result.pure_rotation and result.pri < ppo_cv.DEFAULT_PRI_THRESHOLD
        assert rotation_error_deg(result.R, R) < 0.1
        assert np.isnan(result.points3d).all()
        assert result.num_inliers >= 0.9 * np.count_nonzero(ransac)
        _, R_dropin, _, _ = ppo_cv.recoverPose(E[:3], p1, p2, K, mask=ransac.copy())
        assert rotation_error_deg(R_dropin, R) < 1.0
        _, R_cv, _, _ = cv2.recoverPose(E[:3], p1, p2, K, mask=ransac.copy())
        opencv_wrong += rotation_error_deg(R_cv, R) > 5.0
    assert opencv_wrong >= 4


def test_general_motion_is_not_flagged(K):
    rng = np.random.default_rng(8)
    for _ in range(20):
        _, p1, p2, R, t = _general_motion(rng, K, noise_px=0.5)
        E, ransac = cv2.findEssentialMat(p1, p2, K, cv2.RANSAC, 0.999, 1.0)
        result = ppo_cv.recover_pose(E[:3], p1, p2, K, mask=ransac)
        assert not result.pure_rotation
        assert direction_error_deg(result.t, t) < 5.0


def test_threshold_is_exposed(K):
    rng = np.random.default_rng(9)
    _, p1, p2, R, t = _general_motion(rng, K)
    loose = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, pri_threshold=1.0)
    assert loose.pure_rotation and loose.pri_threshold == 1.0


def test_mask_selects_the_voting_points(K):
    rng = np.random.default_rng(10)
    _, p1, p2, R, t = _general_motion(rng, K)
    p2_bad = p2.copy()
    p2_bad[:120] = rng.uniform(0, 640, (120, 2))
    E = skew(t) @ R
    mask = np.r_[np.zeros(120), np.ones(80)].astype(np.uint8)
    result = ppo_cv.recover_pose(E, p1, p2_bad, K, mask=mask)
    np.testing.assert_allclose(result.R, R, atol=1e-9)
    assert not result.inliers[:120].any() and result.inliers[120:].all()
    assert result.support_R + result.support_R_rejected <= 80


def test_distance_threshold_drops_far_points(K):
    rng = np.random.default_rng(11)
    _, p1, p2, R, t = _general_motion(rng, K)
    near = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, distance_thresh=8.0)
    assert near.inliers.any() and not near.inliers.all()
    assert np.all(near.depths[near.inliers] < 8.0)


def test_an_infinite_distance_threshold_drops_no_point(K):
    # refused as not finite, where recoverPose's distanceThresh takes infinity as OpenCV does
    rng = np.random.default_rng(11)
    _, p1, p2, R, t = _general_motion(rng, K)
    free = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K)
    endless = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, distance_thresh=np.inf)
    np.testing.assert_array_equal(endless.inliers, free.inliers)
    with pytest.raises(ValueError, match="distance_thresh must be a finite number > 0"):
        ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, distance_thresh=-np.inf)


def test_repr_is_one_line_with_the_per_point_arrays_by_shape(K):
    """Printing a result dumped every inlier flag, point and depth: 32,000 characters for
    309 matches of the demo pair. Now R and t are shown, the rest by shape."""
    rng = np.random.default_rng(2)
    X, p1, p2, R, t = _general_motion(rng, K, n=2000)
    result = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K)
    text = repr(result)
    assert "\n" not in text and len(text) < 700
    assert text.startswith("PoseResult(R=array([[") and f"{result.R[0, 0]:.6f}"[:7] in text
    for name, array in (("inliers", result.inliers), ("points3d", result.points3d)):
        assert f"{name}=<ndarray {array.dtype}, shape {array.shape}>" in text
    assert f"support_R={result.support_R}," in text and str(result) == text
