"""End to end on rendered planar pairs: SIFT matches, homography fit and the PPO choice."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ppo_cv import ppo
from ppo_cv.data_gen import make_pair
from ppo_cv.features import detect_features, match_features
from ppo_cv.homography import estimate_homography
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.plane import planar_pose


@pytest.mark.parametrize("seed", [0, 1])
def test_rendered_plane_pose_from_sift_matches(seed):
    pair = make_pair("planar", seed=seed, size=(320, 240), noise_std=1.0)
    images = [cv2.cvtColor(image, cv2.COLOR_RGB2BGR) for image in (pair.image1, pair.image2)]
    f1, f2 = (detect_features(image) for image in images)
    matches = match_features(f1, f2)
    p1, p2 = f1.keypoints[matches[:, 0]], f2.keypoints[matches[:, 1]]
    x1 = np.column_stack([ppo.normalize(p1, pair.K1), np.ones(len(p1))])
    x2 = np.column_stack([ppo.normalize(p2, pair.K2), np.ones(len(p2))])
    focal = float(pair.K1[0, 0])
    fit = estimate_homography(x1, x2, focal, threshold=1.0)
    assert fit is not None and fit.num_inliers >= 0.8 * len(matches)
    assert np.median(fit.residuals[fit.inliers]) < 1.0
    pose = planar_pose(fit.H, x1, x2, fit.inliers, threshold=1.0 / focal)
    rotation_error = rotation_error_deg(pose.R, pair.R)
    assert rotation_error < 1.0
    assert direction_error_deg(pose.t, pair.t) < 3.0
    assert pose.support >= 0.95 * fit.num_inliers
    # the plane of the scene: n^T X = d at points read off the depth map, d in baselines
    for u, v in ((160, 120), (60, 40), (260, 200)):
        X = pair.depth1[v, u] * np.linalg.inv(pair.K1) @ np.array([u, v, 1.0])
        assert pose.n @ X / np.linalg.norm(pair.t) == pytest.approx(pose.distance, rel=0.05)
