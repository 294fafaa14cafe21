"""Angular pose errors of ppo_cv.metrics against OpenCV's angle-axis and known angles."""

import cv2
import numpy as np
import pytest

from ppo_cv.metrics import direction_error_deg, rotation_error_deg


def _random_rotations(count: int, seed: int = 0) -> np.ndarray:
    vectors = np.random.default_rng(seed).normal(size=(count, 3))
    return np.stack([cv2.Rodrigues(v)[0] for v in vectors])


def test_rotation_error_is_the_angle_of_the_relative_rotation_opencv_reports():
    Ra, Rb = _random_rotations(20, seed=1), _random_rotations(20, seed=2)
    pairs = zip(Ra, Rb, strict=True)
    expected = [np.degrees(np.linalg.norm(cv2.Rodrigues(a.T @ b)[0])) for a, b in pairs]
    np.testing.assert_allclose(rotation_error_deg(Ra, Rb), expected, atol=1e-6)
    assert rotation_error_deg(Ra[0], Rb[0]) == pytest.approx(expected[0], abs=1e-6)
    assert isinstance(rotation_error_deg(Ra[0], Rb[0]), float)


def test_rotation_error_of_identical_and_opposite_rotations_stays_finite():
    R = _random_rotations(1)[0]
    half_turn = np.diag([1.0, -1.0, -1.0])
    assert rotation_error_deg(R, R * (1 + 1e-15)) == pytest.approx(0.0, abs=1e-5)
    assert rotation_error_deg(R, R @ half_turn) == pytest.approx(180.0, abs=1e-5)


def test_direction_error_signed_and_between_lines():
    t, t_ref = np.array([1.0, 0.0, 0.0]), np.array([-2.0, 2.0, 0.0])
    assert direction_error_deg(t, t_ref) == pytest.approx(135.0)
    assert direction_error_deg(t, t_ref, signed=False) == pytest.approx(45.0)
    assert direction_error_deg(t.reshape(3, 1), t_ref) == pytest.approx(135.0)
    stacked = direction_error_deg(np.stack([t, -t]), t_ref, signed=False)
    np.testing.assert_allclose(stacked, [45.0, 45.0])


def test_direction_error_of_a_zero_vector_is_nan():
    assert np.isnan(direction_error_deg(np.zeros(3), [0.0, 0.0, 1.0]))


@pytest.mark.parametrize(
    ("function", "a", "b"),
    [
        (rotation_error_deg, np.eye(2), np.eye(2)),
        (rotation_error_deg, np.eye(3), np.zeros(9)),
        (direction_error_deg, np.zeros(2), np.ones(3)),
    ],
)
def test_wrong_shapes_are_named(function, a, b):
    with pytest.raises(ValueError, match="must have shape"):
        function(a, b)


@pytest.mark.parametrize("scale", [1e200, 1e-200, 1e-170])
def test_direction_error_of_vectors_of_any_finite_length(scale):
    # 1e200 overflowed its norm (90 degrees where the directions agree, with a RuntimeWarning),
    # 1e-200 underflowed it (NaN, as for a zero vector)
    t = np.array([scale, scale, 0.0])
    assert direction_error_deg(t, [1.0, 1.0, 0.0]) == pytest.approx(0.0, abs=1e-5)
    assert direction_error_deg(t, [0.0, 0.0, scale]) == pytest.approx(90.0)
    assert direction_error_deg(-t, t, signed=False) == pytest.approx(0.0, abs=1e-5)


@pytest.mark.parametrize(
    ("call", "error", "words"),
    [
        (lambda: rotation_error_deg(np.eye(3) + 0j, np.eye(3)), TypeError,
         "R must hold real numbers, got dtype complex128"),
        (lambda: rotation_error_deg(np.eye(3), np.eye(3, dtype=bool)), TypeError,
         "R_ref must hold real numbers, got dtype bool"),
        (lambda: direction_error_deg("1,0,0", [1, 0, 0]), TypeError,
         "t must be an array of real numbers, got str"),
        (lambda: direction_error_deg([1, 0, 0], None), TypeError, "t_ref is required"),
        (lambda: direction_error_deg([1, 0, 0], [1, 0, 0], signed="no"), TypeError,
         "signed must be True or False"),
        (lambda: rotation_error_deg(np.stack([np.eye(3)] * 2), np.stack([np.eye(3)] * 3)),
         ValueError, "R and R_ref must be single or stacks of one shape (or broadcastable), "
         "got stacks of shape (2,) and (3,)"),
        (lambda: direction_error_deg(np.ones((2, 3)), np.ones((3, 3))), ValueError,
         "got stacks of shape (2,) and (3,)"),
    ],
    ids=["complex", "bool", "text", "None", "signed text", "rotation stacks", "vector stacks"],
)  # fmt: skip
def test_arguments_that_are_no_rotations_or_vectors_are_named(call, error, words):
    # complex and bool arrays were read as numbers (a ComplexWarning), a text as numpy's
    # "could not convert string to float", stacks of two lengths as numpy's broadcast message,
    # and signed="no" as True
    with pytest.raises(error) as info:
        call()
    assert words in str(info.value)


@pytest.mark.parametrize(
    ("matrix", "words"),
    [(2.0 * np.eye(3), "|R R^T - I| up to 3"),
     (np.diag([1.0, 1.0, -1.0]), "a mirror, of determinant -1"),
     (np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]), "|R R^T - I| up to 1")],
    ids=["scaled", "mirror", "essential matrix"],
)  # fmt: skip
def test_a_matrix_that_is_no_rotation_is_refused(matrix, words):
    # a scaled rotation, a mirror or an essential matrix gave an angle (0, 180 or 90 degrees)
    with pytest.raises(ValueError) as info:
        rotation_error_deg(matrix, np.eye(3))
    assert str(info.value).startswith("R must hold rotation matrices") and words in str(info.value)
    stack = np.stack([np.eye(3), np.full((3, 3), np.nan)])
    assert np.isnan(rotation_error_deg(stack, np.eye(3))[1])  # NaN stays NaN
    assert rotation_error_deg(_random_rotations(1)[0].astype(np.float32), np.eye(3)) > 0
