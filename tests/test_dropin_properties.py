"""Property tests of the drop-in against cv2.recoverPose and the ground truth.

Random poses, scales of E, point shapes and dtypes, and masks: the same R, t and mask as
OpenCV wherever OpenCV finds the true pose (it can fail near a pure rotation or at extreme
scales of E, where the ground truth decides), and a named error where the input is invalid.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from twoview import make_scene, random_rotation, skew

import ppo_cv
from ppo_cv.metrics import rotation_error_deg

OPENCV_RECOVER_POSE = cv2.recoverPose
K = np.array([[700.0, 0.0, 320.0], [0.0, 690.0, 240.0], [0.0, 0.0, 1.0]])
SETTINGS = settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None
)


def _shape(points: np.ndarray, shape: str, dtype) -> np.ndarray:
    n = len(points)
    reshaped = {"N2": points, "N12": points.reshape(n, 1, 2), "1N2": points.reshape(1, n, 2)}
    return reshaped[shape].astype(dtype)


def _scene(seed: int, n: int, pure: bool):
    rng = np.random.default_rng(seed)
    R = random_rotation(rng, 25.0)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    if pure:
        t *= 1e-7
    _, p1, p2 = make_scene(rng, n, R, t, K)
    return R, t / np.linalg.norm(t), p1, p2, rng


def _opencv_is_right(out, R, t) -> bool:
    """OpenCV's R and t match the truth entrywise (at extreme scales of E its SVD returns a
    matrix that is not even a rotation)."""
    return np.allclose(out[1], R, atol=1e-5) and np.allclose(out[2].ravel(), t, atol=1e-5)


@SETTINGS
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(8, 150),
    log_scale=st.floats(-250, 250),
    sign=st.sampled_from([1.0, -1.0]),
    shape=st.sampled_from(["N2", "N12", "1N2"]),
    dtype=st.sampled_from([np.float32, np.float64]),
    mask_kind=st.sampled_from(["none", "255", "01", "bool"]),
    pure=st.booleans(),
)
def test_same_pose_and_mask_as_opencv_where_it_is_right(
    seed, n, log_scale, sign, shape, dtype, mask_kind, pure
):
    R, t, p1, p2, rng = _scene(seed, n, pure)
    E = sign * 10.0**log_scale * (skew(t) @ R)
    mask = None
    if mask_kind != "none":
        chosen = rng.random(n) < 0.7
        chosen[:5] = True
        mask = {"255": chosen * np.uint8(255), "01": chosen.astype(np.uint8), "bool": chosen}[
            mask_kind
        ].reshape(-1, 1)
    x1, x2 = _shape(p1, shape, dtype), _shape(p2, shape, dtype)
    given = None if mask is None else mask.copy()  # an (N, 1) uint8 mask receives the output
    retval, R_out, t_out, mask_out = ppo_cv.recoverPose(E, x1, x2, K, mask=given)
    assert R_out.shape == (3, 3) and t_out.shape == (3, 1) and mask_out.shape == (n, 1)
    assert rotation_error_deg(R_out, R) < 1e-3  # right even for a pure rotation
    assert retval == np.count_nonzero(mask_out)
    if mask is not None:
        assert not np.any(mask_out.ravel()[mask.ravel() == 0])
    if pure:
        return  # the translation of a pure rotation is undetermined
    assert float(t_out.ravel() @ t) > 0.9999
    if mask_kind == "bool":
        return  # OpenCV rejects bool masks
    reference = OPENCV_RECOVER_POSE(E, x1, x2, K, mask=None if mask is None else mask.copy())
    event(f"OpenCV right: {_opencv_is_right(reference, R, t)}")
    if _opencv_is_right(reference, R, t):
        np.testing.assert_allclose(R_out, reference[1], atol=2e-5)
        np.testing.assert_allclose(t_out, reference[2], atol=2e-5)
        np.testing.assert_array_equal(mask_out, reference[3])
        assert retval == reference[0]


@SETTINGS
@given(
    seed=st.integers(0, 2**31),
    bad=st.sampled_from(
        [
            ("E", lambda E: E * 0.0, "E is all zeros"),
            ("E", lambda E: E * np.nan, "E has 9 NaN"),
            ("E", lambda E: np.vstack([E, E]), "stack of 2 essential matrices"),
            ("mask", lambda n: np.zeros(n, np.uint8), "mask selects 0"),
            ("mask", lambda n: np.r_[np.ones(4), np.zeros(n - 4)].astype(np.uint8), "selects 4"),
            ("mask", lambda n: np.full(n, 0.5), "mask values"),
            ("mask", lambda n: np.full(n, 300.0), "mask values"),
            ("K", lambda K: K * [[-1], [1], [1]], "negative focal length"),
            ("K", lambda K: K * [[1e-210], [1e-210], [1]], "focal length"),
            ("p2", lambda p: p * 1e12, "points2 has coordinates up to"),
            ("p2", lambda p: p[:-1], "same length"),
        ]
    ),
)
def test_invalid_input_is_a_named_error_catchable_as_cv2_error(seed, bad):
    R, t, p1, p2, _ = _scene(seed, 30, False)
    args = {"E": skew(t) @ R, "p1": p1, "p2": p2, "K": K.copy(), "mask": None}
    target, make, words = bad
    args[target] = make(len(p1) if target == "mask" else args[target])
    with ppo_cv.installed(), pytest.raises(cv2.error) as info:
        cv2.recoverPose(args["E"], args["p1"], args["p2"], args["K"], mask=args["mask"])
    assert isinstance(info.value, ValueError) and words in str(info.value)
