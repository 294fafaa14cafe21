"""The plane in the model decision and the pipeline: rendered pairs with ground truth."""

from __future__ import annotations

import functools
import json

import cv2
import numpy as np
import pytest

from ppo_cv import estimate_pair
from ppo_cv.data_gen import make_pair
from ppo_cv.export import result_to_dict
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.pipeline import PairOptions

SIZE = (320, 240)


@functools.cache
def _rendered(motion: str, seed: int):
    return make_pair(motion, seed=seed, size=SIZE)


@functools.cache
def _estimate(motion: str, seed: int, plane: bool = True):
    pair = _rendered(motion, seed)
    images = [cv2.cvtColor(image, cv2.COLOR_RGB2BGR) for image in (pair.image1, pair.image2)]
    return estimate_pair(*images, pair.K1, pair.K2, options=PairOptions(plane=plane))


@pytest.mark.parametrize("seed", [0, 2])
def test_rendered_plane_is_a_plane_with_the_true_pose(seed):
    pair, result = _rendered("planar", seed), _estimate("planar", seed)
    assert result.model == "plane"
    assert not result.pure_rotation and result.translation_determined
    assert rotation_error_deg(result.R, pair.R) < 0.2
    assert direction_error_deg(result.t, pair.t) < 0.5
    assert result.evidence.selection.gric_plane_difference < 0
    assert result.evidence.selection.plane_epipolar_ratio == pytest.approx(1.0, abs=0.2)
    assert result.uncertainty.t_sigma_deg < 2.0
    # the plane n^T X = d of the scene, read off the depth map, d in baselines
    K_inv = np.linalg.inv(pair.K1)
    for u, v in ((160, 120), (60, 40), (260, 200)):
        X = pair.depth1[v, u] * K_inv @ np.array([u, v, 1.0]) / np.linalg.norm(pair.t)
        assert result.plane.normal @ X == pytest.approx(result.plane.distance, rel=0.02)
    # the analytic points of the inliers lie on that plane
    points = result.points3d[result.point_matches]
    assert result.num_points >= 0.9 * result.num_inliers
    heights = points @ result.plane.normal - result.plane.distance
    assert np.median(np.abs(heights)) < 0.01 * result.plane.distance


def test_plane_beats_the_essential_matrix_on_a_rendered_plane():
    pair = _rendered("planar", 0)
    plane, general = _estimate("planar", 0), _estimate("planar", 0, plane=False)
    assert general.model == "general" and general.plane is None
    error = max(rotation_error_deg(plane.R, pair.R), direction_error_deg(plane.t, pair.t))
    error_e = max(rotation_error_deg(general.R, pair.R), direction_error_deg(general.t, pair.t))
    assert error < error_e


@pytest.mark.parametrize("seed", [0, 1])
def test_pure_rotation_is_a_rotation_not_a_plane(seed):
    pair, result = _rendered("pure-rotation", seed), _estimate("pure-rotation", seed)
    assert result.model == "rotation" and result.pure_rotation
    assert result.plane is None
    assert rotation_error_deg(result.R, pair.R) < 0.2
    assert result.num_points == 0


@pytest.mark.parametrize(("motion", "seed"), [("general", 0), ("forward", 1)])
def test_general_scene_stays_general(motion, seed):
    # forward seed 1: a cluttered scene that a homography fits to 0.09 px; called a plane, its
    # pose error grew from 0.1 to 6 degrees
    pair, result = _rendered(motion, seed), _estimate(motion, seed)
    assert result.model == "general"
    assert result.evidence.selection.gric_plane_difference > 0
    assert result.plane is None
    assert max(rotation_error_deg(result.R, pair.R), direction_error_deg(result.t, pair.t)) < 1.0


def test_json_and_summary_carry_the_plane():
    result = _estimate("planar", 0)
    data = json.loads(json.dumps(result_to_dict(result)))
    assert data["model"] == "plane"
    assert data["plane"]["normal"] == pytest.approx(result.plane.normal.tolist())
    assert data["plane"]["distance"] == pytest.approx(result.plane.distance)
    assert data["plane"]["ambiguous"] is bool(result.plane.ambiguous)
    k1 = data["plane"]["k1"]
    assert (k1 is None) == (not np.isfinite(result.plane.k1))
    assert k1 is None or k1 == pytest.approx(result.plane.k1)
    assert data["evidence"]["selection"]["gric_plane_difference"] < 0
    assert data["evidence"]["selection"]["plane_epipolar_ratio"] < 1.5
    assert data["t"] == pytest.approx(result.t.tolist())
    general = json.loads(json.dumps(result_to_dict(_estimate("general", 0))))
    assert general["model"] == "general" and general["plane"] is None

    from ppo_cv.cli.pair import _summary

    text = _summary(result, "a.png", "b.png", None)
    assert "plane (translation determined" in text
    assert f"distance {result.plane.distance:.3f} baselines" in text


# --- decide_motion on synthetic matches: the rule alone ----------------------------------------


def _synthetic(kind: str, n: int = 300, noise_px: float = 0.5, seed: int = 0):
    """Normalized matches of a plane, a 3D volume or a pure rotation; focal 500 px."""
    rng = np.random.default_rng(seed)
    a = np.deg2rad(4.0)
    R = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    xy = rng.uniform(-1.5, 1.5, (n, 2))
    if kind == "plane":  # tilted plane 0.3 x + z = 5
        X1 = np.column_stack([xy, 5.0 - 0.3 * xy[:, 0]])
    else:
        X1 = np.column_stack([xy, rng.uniform(3.0, 8.0, n)])
    t = np.zeros(3) if kind == "rotation" else np.array([0.5, 0.05, 0.1])
    X2 = X1 @ R.T + t
    focal = 500.0
    x1 = X1 / X1[:, 2:] + np.append(rng.normal(0, noise_px / focal, (n, 2)), np.zeros((n, 1)), 1)
    x2 = X2 / X2[:, 2:] + np.append(rng.normal(0, noise_px / focal, (n, 2)), np.zeros((n, 1)), 1)
    return x1, x2, R, t, focal


@pytest.mark.parametrize(("kind", "expected"), [("plane", "plane"), ("volume", "general"),
                                                ("rotation", "rotation")])  # fmt: skip
def test_decide_motion_with_a_homography(kind, expected):
    from ppo_cv.homography import estimate_homography
    from ppo_cv.motion_model import decide_motion
    from ppo_cv.ppo import select_pose
    from ppo_cv.refine import refine_pose
    from ppo_cv.robust import estimate_essential

    x1, x2, R_true, t_true, focal = _synthetic(kind)
    fit = estimate_essential(x1, x2, focal, threshold=1.0)
    chosen = select_pose(fit.E, x1[fit.inliers], x2[fit.inliers])
    R, t = refine_pose(chosen.R, chosen.t, x1, x2, fit.inliers, focal)
    homography = estimate_homography(x1, x2, focal, threshold=1.0)
    motion = decide_motion(x1, x2, R, t, fit.inliers, focal, homography=homography)
    assert motion.model == expected
    assert motion.pure_rotation == (expected == "rotation")
    assert np.isfinite(motion.gric_plane_difference)
    if expected == "plane":
        assert motion.gric_plane_difference < 0
        assert rotation_error_deg(motion.plane.R, R_true) < 1.0
        assert direction_error_deg(motion.plane.t, t_true) < 5.0
        normal = np.array([0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
        assert direction_error_deg(motion.plane.n, normal) < 5.0
    # without a homography the decision is the rotation-versus-general one
    plain = decide_motion(x1, x2, R, t, fit.inliers, focal)
    assert plain.model == ("rotation" if expected == "rotation" else "general")
    assert plain.plane is None and np.isnan(plain.gric_plane_difference)


def test_dominant_plane_with_structure_off_it_is_general():
    # a wall with boxes in front: GRIC prefers the homography (it saves ln 4 on each match and
    # caps the cost of the boxes), but a tenth of the essential matrix's inliers lie off it
    from ppo_cv.homography import estimate_homography
    from ppo_cv.motion_model import MAX_OFF_PLANE_SHARE, decide_motion
    from ppo_cv.ppo import select_pose
    from ppo_cv.refine import refine_pose
    from ppo_cv.robust import estimate_essential

    p1, p2, R_true, t_true, focal = _synthetic("plane", n=600, seed=3)
    v1, v2, _, _, _ = _synthetic("volume", n=60, seed=13)
    x1, x2 = np.vstack([p1, v1]), np.vstack([p2, v2])
    fit = estimate_essential(x1, x2, focal, threshold=1.0)
    chosen = select_pose(fit.E, x1[fit.inliers], x2[fit.inliers])
    R, t = refine_pose(chosen.R, chosen.t, x1, x2, fit.inliers, focal)
    homography = estimate_homography(x1, x2, focal, threshold=1.0)
    motion = decide_motion(x1, x2, R, t, fit.inliers, focal, homography=homography)
    assert motion.plane_selection.model == "plane"
    assert motion.plane_off_share > MAX_OFF_PLANE_SHARE
    assert motion.model == "general"
    on_plane = decide_motion(
        p1, p2, *refine_pose(*_pose_of(p1, p2, focal), p1, p2, np.ones(len(p1), bool), focal),
        np.ones(len(p1), bool), focal, homography=estimate_homography(p1, p2, focal),
    )  # fmt: skip
    assert on_plane.model == "plane" and on_plane.plane_off_share < MAX_OFF_PLANE_SHARE


def _pose_of(x1, x2, focal):
    from ppo_cv.ppo import select_pose
    from ppo_cv.robust import estimate_essential

    fit = estimate_essential(x1, x2, focal, threshold=1.0)
    chosen = select_pose(fit.E, x1[fit.inliers], x2[fit.inliers])
    return chosen.R, chosen.t


def test_rendered_plane_with_unmodelled_distortion_gets_its_radial_term():
    # k1 alone (true focal length, the preset's field of view): the refined pose recovers what
    # the homography absorbed, and the reported plane.k1 is near the lens's
    from ppo_cv.data_gen import Imperfections

    lens_only = Imperfections(focal_error=0.0, hfov_range=None, jpeg_quality=None,
                              noise_std=0.0, blur_sigma=0.0)  # fmt: skip
    pair = make_pair("planar", seed=0, index=3, size=SIZE, imperfections=lens_only)
    images = [cv2.cvtColor(image, cv2.COLOR_RGB2BGR) for image in (pair.image1, pair.image2)]
    result = estimate_pair(*images, pair.K1_given, pair.K2_given)
    assert result.model == "plane"
    assert result.plane.k1 == pytest.approx(pair.params["k1"], abs=0.03)
    assert rotation_error_deg(result.R, pair.R) < 0.3
    assert direction_error_deg(result.t, pair.t) < 1.5
