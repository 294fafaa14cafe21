"""A pose that has its consensus seen from directions no descriptor matches across is refused
(:func:`ppo_cv.significance.require_matchable_viewpoints`)."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import ppo_cv.pipeline as pipeline
from ppo_cv import significance
from ppo_cv.calib import ImplausibleCameraWarning
from ppo_cv.significance import (
    MAX_MEDIAN_RAY_ANGLE_DEG,
    ray_angles_deg,
    require_matchable_viewpoints,
)

DATA = Path(pipeline.__file__).parent / "data"


def _twisted(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The other rotation of the essential matrix ``[t]x R``: ``R`` turned half a turn about
    ``t``, which explains every epipolar consensus of ``R`` as well."""
    u = np.asarray(t, float) / np.linalg.norm(t)
    return (2.0 * np.outer(u, u) - np.eye(3)) @ R


def _scene(rng: np.random.Generator):
    """Matches of 200 points 2-6 m before camera 1, camera 2 0.5 m aside turned 10 deg."""
    X = np.column_stack([rng.uniform(-2, 2, (200, 2)), rng.uniform(2, 6, 200)])
    R = cv2.Rodrigues(np.radians([0.0, 10.0, 0.0]))[0]
    t = np.array([-0.5, 0.0, 0.05])
    X2 = X @ R.T + t
    return X / X[:, 2:], X2 / X2[:, 2:], R, t


def test_the_twisted_rotation_of_the_same_essential_matrix_is_refused():
    x1, x2, R, t = _scene(np.random.default_rng(0))
    t_cross = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    twisted = _twisted(R, t)
    assert np.allclose(t_cross @ twisted, -t_cross @ R, atol=1e-12)
    assert np.median(ray_angles_deg(x1, x2, R)) < 10.0
    assert require_matchable_viewpoints(x1, x2, R) < 10.0
    assert np.median(ray_angles_deg(x1, x2, twisted)) > 150.0
    with pytest.raises(ValueError, match="no reliable two-view geometry.*median 1[5-8][0-9] deg"):
        require_matchable_viewpoints(x1, x2, twisted)


def test_a_pure_rotation_has_parallel_rays():
    rng = np.random.default_rng(1)
    x1 = np.column_stack([rng.uniform(-0.5, 0.5, (50, 2)), np.ones(50)])
    R = cv2.Rodrigues(np.radians([5.0, -20.0, 3.0]))[0]
    x2 = x1 @ R.T
    assert np.allclose(ray_angles_deg(x1, x2, R), 0.0, atol=1e-5)
    assert require_matchable_viewpoints(x1[:0], x2[:0], R) == 0.0


def _demo():
    info = json.loads((DATA / "demo.json").read_text(encoding="utf-8"))
    fx, fy, cx, cy = info["intrinsics"]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return str(DATA / info["image1"]), str(DATA / info["image2"]), K


def test_estimate_pair_refuses_a_pose_whose_inliers_it_cannot_have_matched(monkeypatch):
    """The demo pair cut to the left 47 % of image 1 and the right 47 % of image 2 (a sliver of
    overlap) left a chance consensus of 11 matches that passes the significance bar, whose
    pose, 119 deg off, sees them from directions a median 135 deg apart; uncut, the pair's pose
    sees its inliers from a few degrees apart. The significance test now refuses it as not
    locally consistent; set that aside, the viewpoints do."""
    image1, image2, K = _demo()
    whole = pipeline.estimate_pair(image1, image2, K)
    x1, x2 = _normalized(whole, K, K)
    assert np.median(ray_angles_deg(x1, x2, whole.R)) < 20.0
    a, b = cv2.imread(image1), cv2.imread(image2)
    keep = round(0.47 * a.shape[1])
    K2 = K.copy()
    K2[0, 2] -= a.shape[1] - keep
    chance = pytest.raises(ValueError, match="no reliable two-view geometry: the consensus")
    with chance, pytest.warns(ImplausibleCameraWarning, match="principal point"):
        pipeline.estimate_pair(a[:, :keep].copy(), b[:, -keep:].copy(), K, K2)
    monkeypatch.setattr(significance, "MAX_LOCAL_P", 1.0)
    refused = pytest.raises(ValueError, match="no reliable two-view geometry: the pose has its 11 ")
    with refused, pytest.warns(ImplausibleCameraWarning, match="principal point"):
        pipeline.estimate_pair(a[:, :keep].copy(), b[:, -keep:].copy(), K, K2)
    assert MAX_MEDIAN_RAY_ANGLE_DEG == 90.0


def _normalized(result, K1, K2):
    """The inliers of ``result`` as homogeneous normalized coordinates, (N, 3) each."""
    pairs = result.matches[result.inliers]
    points = (result.keypoints1[pairs[:, 0]], result.keypoints2[pairs[:, 1]])
    return tuple(
        np.column_stack([p, np.ones(len(p))]) @ np.linalg.inv(K).T
        for p, K in zip(points, (K1, K2), strict=True)
    )
