"""PPO against pycolmap's two-view estimators on the same SIFT matches, rendered and real."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pycolmap
import pytest
from twoview import pycolmap_relative_pose

import ppo_cv
from ppo_cv import colmap
from ppo_cv.data_gen import make_pair
from ppo_cv.features import detect_features, match_features
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

Config = pycolmap.TwoViewGeometryConfiguration
SIZE = (480, 360)


def sift_matches(image1: np.ndarray, image2: np.ndarray):
    features1, features2 = detect_features(image1), detect_features(image2)
    matches = np.ascontiguousarray(match_features(features1, features2), dtype=np.uint32)
    return features1.keypoints, features2.keypoints, matches


def both_estimates(camera1, keypoints1, camera2, keypoints2, matches):
    """Ours, and pycolmap's calibrated geometry with its cheirality pose, on the same matches."""
    options = pycolmap.TwoViewGeometryOptions()
    options.ransac.random_seed = 0
    ours = colmap.estimate_two_view_geometry(
        camera1, keypoints1, camera2, keypoints2, matches, options
    )
    theirs = pycolmap.estimate_calibrated_two_view_geometry(
        camera1, keypoints1, camera2, keypoints2, matches, options
    )
    if not pycolmap.estimate_two_view_geometry_pose(
        camera1, keypoints1, camera2, keypoints2, theirs
    ):
        theirs = None
    return ours, theirs


@pytest.fixture(
    scope="module", params=[("general", 0), ("general", 1)], ids=lambda p: f"{p[0]}-{p[1]}"
)
def general_pair(request):
    motion, seed = request.param
    pair = make_pair(motion, seed=seed, size=SIZE, noise_std=1.0)
    return pair, *sift_matches(pair.image1, pair.image2)


@pytest.fixture(scope="module", params=[0, 1], ids=lambda s: f"pure-rotation-{s}")
def rotation_pair(request):
    pair = make_pair("pure-rotation", seed=request.param, size=SIZE, noise_std=1.0)
    return pair, *sift_matches(pair.image1, pair.image2)


def test_rendered_general_motion_agrees_with_pycolmap_and_truth(general_pair):
    pair, keypoints1, keypoints2, matches = general_pair
    camera1, camera2 = colmap.camera_from_K(pair.K1, *SIZE), colmap.camera_from_K(pair.K2, *SIZE)
    ours, theirs = both_estimates(camera1, keypoints1, camera2, keypoints2, matches)
    assert ours.success and theirs is not None
    assert ours.geometry.config == Config.CALIBRATED
    R, t = colmap.pose_from_rigid3d(ours.geometry.cam2_from_cam1)
    R_c, t_c = colmap.pose_from_rigid3d(theirs.cam2_from_cam1)
    # Same essential matrix and inliers: PPO and cheirality must pick the same candidate.
    assert rotation_error_deg(R, R_c) < 0.1 and direction_error_deg(t, t_c) < 0.5
    assert rotation_error_deg(R, pair.R) < 0.3 and direction_error_deg(t, pair.t) < 2.0


def test_rendered_general_motion_from_relative_pose_essential(general_pair):
    pair, keypoints1, keypoints2, matches = general_pair
    camera1, camera2 = colmap.camera_from_K(pair.K1, *SIZE), colmap.camera_from_K(pair.K2, *SIZE)
    points1, points2 = keypoints1[matches[:, 0]], keypoints2[matches[:, 1]]
    R_c, t_c, found = pycolmap_relative_pose(camera1, points1, camera2, points2)
    E = np.cross(np.eye(3), t_c) @ R_c
    result = ppo_cv.recover_pose(E, points1, points2, pair.K1, pair.K2, mask=found["inlier_mask"])
    assert not result.pure_rotation
    assert rotation_error_deg(result.R, R_c) < 1e-4 and direction_error_deg(result.t, t_c) < 1e-4
    assert rotation_error_deg(result.R, pair.R) < 1.0
    assert direction_error_deg(result.t, pair.t) < 5.0


def test_rendered_pure_rotation(rotation_pair):
    pair, keypoints1, keypoints2, matches = rotation_pair
    assert not np.any(pair.t)
    camera1, camera2 = colmap.camera_from_K(pair.K1, *SIZE), colmap.camera_from_K(pair.K2, *SIZE)
    ours, theirs = both_estimates(camera1, keypoints1, camera2, keypoints2, matches)
    assert ours.pose.pure_rotation
    assert ours.geometry.config == Config.PANORAMIC
    R, t = colmap.pose_from_rigid3d(ours.geometry.cam2_from_cam1)
    assert not np.any(t)
    assert rotation_error_deg(R, pair.R) < 0.3
    # pycolmap's five-point solver reports a unit baseline with no sign that it is noise;
    # PPO on its essential matrix keeps the rotation and flags the pure rotation.
    points1, points2 = keypoints1[matches[:, 0]], keypoints2[matches[:, 1]]
    R_c, t_c, found = pycolmap_relative_pose(camera1, points1, camera2, points2)
    assert np.linalg.norm(t_c) == pytest.approx(1.0)
    E = np.cross(np.eye(3), t_c) @ R_c
    result = ppo_cv.recover_pose(E, points1, points2, pair.K1, pair.K2, mask=found["inlier_mask"])
    assert result.pure_rotation
    assert rotation_error_deg(result.R, pair.R) < 1.0


FREIBURG_PAIRS = [
    ("1341847980.722988.png", "1341847981.726650.png"),
    ("1341847981.726650.png", "1341847985.746954.png"),
    ("1341847984.743352.png", "1341847985.746954.png"),
    ("1341847986.762616.png", "1341847987.758741.png"),
    ("1341847988.769740.png", "1341847991.814748.png"),
    ("1341847990.810771.png", "1341847991.814748.png"),
    ("1341847992.818723.png", "1341847994.866828.png"),
    ("1341847993.826735.png", "1341847996.874766.png"),
]


def read_gt(freiburg: Path) -> dict:
    gt = {}
    for line in (freiburg / "pairs_with_gt.txt").read_text().splitlines():
        fields = line.split()
        if fields:
            K = np.array(fields[4:13], dtype=float).reshape(3, 3)
            T = np.array(fields[22:38], dtype=float).reshape(4, 4)
            gt[(fields[0], fields[1])] = (K, T[:3, :3], T[:3, 3])
    return gt


def test_freiburg_pairs_against_pycolmap(freiburg):
    gt = read_gt(freiburg)
    agree, ours_ok = 0, 0
    for name1, name2 in FREIBURG_PAIRS:
        K, R_gt, t_gt = gt[(name1, name2)]
        image1 = cv2.imread(str(freiburg / "images" / name1))
        image2 = cv2.imread(str(freiburg / "images" / name2))
        keypoints1, keypoints2, matches = sift_matches(image1, image2)
        camera = colmap.camera_from_K(K, image1.shape[1], image1.shape[0])
        ours, theirs = both_estimates(camera, keypoints1, camera, keypoints2, matches)
        assert ours.success, (name1, name2)
        R, t = colmap.pose_from_rigid3d(ours.geometry.cam2_from_cam1)
        assert not ours.pose.pure_rotation
        ours_ok += rotation_error_deg(R, R_gt) < 3.0 and direction_error_deg(t, t_gt) < 6.0
        if theirs is not None and theirs.config == Config.CALIBRATED:
            R_c, t_c = colmap.pose_from_rigid3d(theirs.cam2_from_cam1)
            agree += rotation_error_deg(R, R_c) < 1.0 and direction_error_deg(t, t_c) < 3.0
    assert ours_ok == len(FREIBURG_PAIRS)
    assert agree >= 5


def test_freiburg_short_baseline_pair(freiburg):
    """Frames one second apart, the shortest baseline: PPO keeps the translation."""
    name1, name2 = FREIBURG_PAIRS[0]
    K, R_gt, t_gt = read_gt(freiburg)[(name1, name2)]
    image1 = cv2.imread(str(freiburg / "images" / name1))
    image2 = cv2.imread(str(freiburg / "images" / name2))
    keypoints1, keypoints2, matches = sift_matches(image1, image2)
    camera = colmap.camera_from_K(K, 640, 480)
    ours, _ = both_estimates(camera, keypoints1, camera, keypoints2, matches)
    assert not ours.pose.pure_rotation
    assert ours.pose.pri > 2 * ours.pose.pri_threshold
    R, t = colmap.pose_from_rigid3d(ours.geometry.cam2_from_cam1)
    assert rotation_error_deg(R, R_gt) < 0.5 and direction_error_deg(t, t_gt) < 3.0
