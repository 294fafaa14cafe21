"""Degenerate and malformed input gets a ValueError/TypeError that names the problem."""

from __future__ import annotations

import numpy as np
import pytest
from twoview import make_scene, random_rotation, skew

import ppo_cv

K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(0)
    R = random_rotation(rng, 10.0)
    t = np.array([1.0, 0.0, 0.2])
    _, p1, p2 = make_scene(rng, 30, R, t, K)
    return skew(t) @ R, p1, p2


BOTH_APIS = [
    pytest.param(lambda E, p1, p2, K, **kw: ppo_cv.recover_pose(E, p1, p2, K, **kw), id="rich"),
    pytest.param(lambda E, p1, p2, K, **kw: ppo_cv.recoverPose(E, p1, p2, K, **kw), id="dropin"),
]


@pytest.mark.parametrize("call", BOTH_APIS)
def test_fewer_than_five_points(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match="at least 5 point correspondences.*got 4"):
        call(E, p1[:4], p2[:4], K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_mismatched_lengths(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match="same length, got 30 and 29"):
        call(E, p1, p2[:29], K)


@pytest.mark.parametrize("call", BOTH_APIS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_points(call, pair, bad):
    E, p1, p2 = pair
    p2 = p2.copy()
    p2[3, 1] = bad
    with pytest.raises(ValueError, match="points2 has 1 NaN or infinite"):
        call(E, p1, p2, K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_non_finite_essential_matrix(call, pair):
    E, p1, p2 = pair
    E = E.copy()
    E[0, 0] = np.nan
    with pytest.raises(ValueError, match="E has 1 NaN"):
        call(E, p1, p2, K)


@pytest.mark.parametrize("call", BOTH_APIS)
@pytest.mark.parametrize("shape", [(3,), (2, 3), (3, 4), (4, 4)])
def test_essential_matrix_of_wrong_shape(call, pair, shape):
    _, p1, p2 = pair
    with pytest.raises(ValueError, match=r"E must be a 3x3 matrix, got shape"):
        call(np.ones(shape), p1, p2, K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_all_zero_essential_matrix(call, pair):
    _, p1, p2 = pair
    with pytest.raises(ValueError, match="E is all zeros"):
        call(np.zeros((3, 3)), p1, p2, K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_stack_of_essential_matrices_from_find_essential_mat(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match=r"stack of 3 essential matrices.*E\[:3\]"):
        call(np.vstack([E, E, E]), p1, p2, K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_zero_focal_length(call, pair):
    E, p1, p2 = pair
    K0 = K.copy()
    K0[1, 1] = 0.0
    with pytest.raises(ValueError, match="zero focal length"):
        call(E, p1, p2, K0)


def test_zero_focal_length_in_focal_form(pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match="focal must be a finite number > 0"):
        ppo_cv.recoverPose(E, p1, p2, focal=0.0, pp=(320.0, 240.0))


@pytest.mark.parametrize("call", BOTH_APIS)
def test_camera_matrix_not_a_pinhole(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match="3x3"):
        call(E, p1, p2, np.eye(4))
    bad_row = K.copy()
    bad_row[2] = (0.0, 0.0, 2.0)
    with pytest.raises(ValueError, match="last row"):
        call(E, p1, p2, bad_row)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_a_camera_matrix_scaled_as_a_whole_is_refused_with_the_way_out(call, pair):
    # refused with no hint that K / K[2,2] is the camera matrix meant
    E, p1, p2 = pair
    with pytest.raises(ValueError, match=r"last row \(0, 0, 1\), got .*\(scaled as a whole\? "
                                         r"divide it by K\[2,2\] = 2\)$"):  # fmt: skip
        call(E, p1, p2, 2.0 * K)
    skewed_row = K.copy()
    skewed_row[2] = (0.1, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"last row \(0, 0, 1\), got [^(]*$"):
        call(E, p1, p2, skewed_row)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_points_of_wrong_shape(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match=r"points1 must have shape \(N, 2\)"):
        call(E, np.c_[p1, np.ones(len(p1))], p2, K)
    with pytest.raises(ValueError, match=r"points2 must have shape"):
        call(E, p1, p2.T, K)


@pytest.mark.parametrize("call", BOTH_APIS)
@pytest.mark.parametrize("bad", [None, "points", np.array([["a", "b"]] * 30)])
def test_points_of_wrong_type(call, pair, bad):
    E, p1, _ = pair
    with pytest.raises(TypeError, match="points2"):
        call(E, p1, bad, K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_boolean_points_are_rejected(call, pair):
    E, p1, _ = pair
    with pytest.raises(TypeError, match="points2 must hold real numbers"):
        call(E, p1, np.ones((30, 2), dtype=bool), K)


@pytest.mark.parametrize("call", BOTH_APIS)
def test_mask_of_wrong_length(call, pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match=r"mask must have one entry per point \(30\)"):
        call(E, p1, p2, K, mask=np.ones(29, dtype=np.uint8))


def test_distance_threshold_must_be_positive(pair):
    E, p1, p2 = pair
    with pytest.raises(ValueError, match="distanceThresh must be a finite number > 0"):
        ppo_cv.recoverPose(E, p1, p2, K, distanceThresh=-1.0)
    with pytest.raises(ValueError, match="distance_thresh must be a finite number > 0"):
        ppo_cv.recover_pose(E, p1, p2, K, distance_thresh=0.0)


def test_unknown_keyword_is_a_type_error(pair):
    E, p1, p2 = pair
    with pytest.raises(TypeError, match="unexpected keyword argument 'camera'"):
        ppo_cv.recoverPose(E, p1, p2, camera=K)


def test_distortion_coefficients_of_wrong_length(pair):
    _, p1, p2 = pair
    with pytest.raises(ValueError, match="distortion coefficients"):
        ppo_cv.recoverPose(p1, p2, K, np.zeros(3), K, None)


def test_drop_in_errors_are_exported_at_the_top_level(pair):
    E, p1, p2 = pair
    with pytest.raises(ppo_cv.RecoverPoseError, match="5 point correspondences"):
        ppo_cv.recoverPose(E, p1[:4], p2[:4], K)
    with pytest.raises(ppo_cv.RecoverPoseTypeError):
        ppo_cv.recoverPose(E, p1, p2, "K")
    assert issubclass(ppo_cv.RecoverPoseError, ValueError)
