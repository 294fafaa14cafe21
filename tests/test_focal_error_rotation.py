"""A pair whose matches are a rotation through a focal length outside the lens box.

Tripod pans in a narrow field whose focal length is given far off (an EXIF value for another
crop, a stitcher's estimate) have matches that are a rotation through another focal length:
the rotation-only fit clips that lens to its box and the decision calls them general or a plane.
The result names the focal length the matches want, and the rotation returned is the
rotation-only fit's, within a degree of the given calibration's. A pan about a pivot off the
centre before a vertical wall makes the same homography: swings before walls facing the camera
keep their answer, one before a wall turned to it does not (a strict xfail).
"""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import estimate_pair
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.motion_model import NEGLIGIBLE_PARALLAX
from ppo_cv.parallax import PlaneParallax
from ppo_cv.rotation_choice import (
    FOCAL_ERROR_RANGE,
    across_normal_parallax,
    focal_free_parallax,
    freed_parallax_refused,
)

FIELD_DEG = 20.0
SIZE = (720, 540)
PAN_DEG = 10.0
DEPTH = 4.0


def _pan(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _with_focal_scaled(K: np.ndarray, factor: float) -> np.ndarray:
    scaled = K.copy()
    scaled[0, 0] *= factor
    scaled[1, 1] *= factor
    return scaled


@pytest.mark.parametrize("true_over_given", [0.75, 1.3, 1.0])
def test_a_rotation_through_another_focal_length_reads_no_parallax(true_over_given):
    S = np.diag([true_over_given, true_over_given, 1.0])
    H = S @ _pan(PAN_DEG) @ np.linalg.inv(S)
    measured = PlaneParallax(H, across_normal_parallax(H), 1e-3, np.empty(0))
    freed, scale = focal_free_parallax(measured)
    assert across_normal_parallax(freed.H) < 1e-5 and freed.parallax < 1e-5
    assert freed.sigma == measured.sigma
    assert scale == pytest.approx(1.0 / true_over_given, rel=1e-4)


@pytest.mark.parametrize("pivot", [0.1, 0.4, -0.4])
@pytest.mark.parametrize(("wall_turn_deg", "wall_tilt_deg", "left_at_least"), [
    (0.0, 0.0, 0.0),  # a wall facing the camera
    (30.0, 0.0, 0.0),  # a vertical wall at an angle: the pan's axis lies in it
    (0.0, 20.0, 0.2),  # a wall leaning back: a part of the parallax is left
])  # fmt: skip
def test_a_swing_before_a_wall_is_a_rotation_through_another_focal_length_unless_it_leans(
    pivot, wall_turn_deg, wall_tilt_deg, left_at_least
):
    """``R + t n^T / d`` of a pan about a pivot ``pivot`` wall distances in front of the camera
    (``t = (I - R) P``): with the pan's axis in the wall's plane a focal scale takes all of its
    parallax, which is why the rotation choice does not read the bias with the focal free."""
    R = _pan(PAN_DEG)
    P = np.array([0.0, 0.0, pivot])
    a = np.radians(wall_tilt_deg)
    lean = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    normal = lean @ _pan(wall_turn_deg) @ np.array([0.0, 0.0, 1.0])
    H = R + np.outer(P - R @ P, normal)
    measured = PlaneParallax(H, across_normal_parallax(H), 1e-3, np.empty(0))
    freed, scale = focal_free_parallax(measured)
    assert across_normal_parallax(H) > 0.25 * abs(pivot) * np.radians(PAN_DEG)
    left = across_normal_parallax(freed.H) / across_normal_parallax(H)
    assert left > left_at_least if left_at_least else left < 1e-4
    assert abs(np.log(scale)) > 0.02


@pytest.mark.parametrize(("sideways", "sigma", "refused"), [
    (0.0, 1e-4, False),  # a focal length given off, nothing else
    (0.01, 1e-4, False),  # a translation too small to tell
    (0.05, 1e-4, True),  # one the focal scale cannot take
    (0.05, 3e-3, False),  # the same measured too loosely to tell
])  # fmt: skip
def test_a_translation_the_focal_scale_cannot_take_refuses_the_focal_error_reading(
    sideways, sigma, refused
):
    """A pan seen through a focal length 0.75 times the given one, the camera also moved
    ``sideways`` of the distance of a wall facing it: conjugated by the focal scale the
    homography keeps a part of the translation, tested as a rotation's tracks are."""
    S = np.diag([0.75, 0.75, 1.0])
    moved = np.eye(3) + np.outer([sideways, 0.0, 0.0], [0.0, 0.0, 1.0])
    H = S @ _pan(PAN_DEG) @ moved @ np.linalg.inv(S)
    freed, _ = focal_free_parallax(PlaneParallax(H, across_normal_parallax(H), sigma,
                                                     np.empty(0)))  # fmt: skip
    left = across_normal_parallax(freed.H)
    assert 0.1 * sideways <= left <= 0.25 * sideways + 1e-6
    assert freed_parallax_refused(freed, NEGLIGIBLE_PARALLAX) is refused


def test_a_focal_length_beyond_the_range_is_not_named():
    S = np.diag([3.0, 3.0, 1.0])
    H = S @ _pan(PAN_DEG) @ np.linalg.inv(S)
    _, scale = focal_free_parallax(PlaneParallax(H, 0.0, 1e-3, np.empty(0)))
    assert FOCAL_ERROR_RANGE[1] < 3.0 and np.isnan(scale)


def _render(scene_name: str, seed: int, pivot: float, true_over_given: float = 1.0):
    """A pan of :data:`PAN_DEG` in a :data:`FIELD_DEG` field about a pivot ``pivot`` times
    :data:`DEPTH` in front of the camera (negative: behind), and the camera given with its
    focal length ``1 / true_over_given`` times the true one."""
    from ppo_cv.data_gen.motion import intrinsics
    from ppo_cv.data_gen.render import render_pair
    from ppo_cv.data_gen.scenes import make_scene

    K = intrinsics(SIZE, FIELD_DEG)
    R = _pan(PAN_DEG)
    P = np.array([0.0, 0.0, pivot * DEPTH])
    pair = render_pair(make_scene(scene_name, seed), K, K, R, P - R @ P, size=SIZE,
                       noise_std=2.0, seed=seed)  # fmt: skip
    return pair.image1, pair.image2, K, _with_focal_scaled(K, 1.0 / true_over_given), R


def _given_calibration_rotation(K: np.ndarray, K_given: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation fitted, with ``K_given`` held, to the pixels a pure rotation ``R`` seen
    through ``K`` maps (least squares on the rays): what a user with ``K_given`` stitches with."""
    rng = np.random.default_rng(0)
    pixels = np.column_stack([rng.uniform(0, SIZE[0], 400), rng.uniform(0, SIZE[1], 400),
                              np.ones(400)])  # fmt: skip
    seen = pixels @ np.linalg.inv(K).T @ R.T @ K.T
    rays = [p @ np.linalg.inv(K_given).T for p in (pixels, seen)]
    rays = [r / np.linalg.norm(r, axis=1, keepdims=True) for r in rays]
    U, _, Vt = np.linalg.svd(rays[1].T @ rays[0])
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


THE_FOCAL_ERROR_IT_TAKES = pytest.mark.xfail(
    strict=True,
    reason="a 10 degree swing about a pivot 0.4 of the wall's distance behind the camera before "
    "a vertical wall turned to it reads as a rotation through a focal length outside the box: "
    "the rotation-only fit, 4.3 degrees off, is returned where the essential matrix is 0.2 off "
    "(the price of reading tripod pans whose focal length is given 25 % off as rotations; see "
    "ppo_cv.rotation_choice)",
)


@pytest.mark.slow
@pytest.mark.parametrize(("scene_name", "seed"), [("backdrop", 0), ("clutter", 2)])
def test_a_tripod_pan_with_the_focal_length_given_far_off_names_the_focal_length(scene_name, seed):
    image1, image2, K, K_given, R = _render(scene_name, seed, 0.0, true_over_given=0.75)
    result = estimate_pair(image1, image2, K_given, K_given)
    assert result.lens.lens_excess > 0
    assert 1.0 / result.lens.wanted_focal_scale == pytest.approx(0.75, abs=0.05)


@pytest.mark.slow
@pytest.mark.parametrize(("scene_name", "seed"), [("backdrop", 0), ("clutter", 2)])
def test_a_tripod_pan_with_the_focal_length_given_far_off_returns_the_given_calibrations_rotation(
    scene_name, seed
):
    image1, image2, K, K_given, R = _render(scene_name, seed, 0.0, true_over_given=0.75)
    result = estimate_pair(image1, image2, K_given, K_given)
    reference = _given_calibration_rotation(K, K_given, R)
    assert rotation_error_deg(reference, R) > 2.0  # the focal error moves the rotation
    assert rotation_error_deg(result.R, reference) < 1.0


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "pivot", "within_deg"),
    [
        (0, 0.4, 0.3),
        (0, -0.4, 1.5),
        (1, 0.1, 0.3),
        (2, -0.1, 0.3),
        pytest.param(20, -0.4, 0.3, marks=THE_FOCAL_ERROR_IT_TAKES),
    ],
)
def test_a_swing_before_a_wall_in_a_narrow_field_keeps_its_answer(seed, pivot, within_deg):
    image1, image2, K, _, R = _render("plane", seed, pivot)
    result = estimate_pair(image1, image2, K, K)
    assert result.rotation_source != "rotation"
    assert rotation_error_deg(result.R, R) < within_deg


@pytest.mark.parametrize("centred", [False, True], ids=["principal point given", "centred"])
def test_a_translation_the_focal_scale_took_keeps_the_rotation_at_the_edge_of_the_box(centred):
    """``tiny-baseline`` at baseline / depth 0.02 (seed 0, index 9; focal length given 2.3 %
    short): the rotation-only fit of its matches wins, its focal scale clipped to the edge of
    the box, and the parallax left with the focal length freed refuses the reading as a focal
    length given off. Its rotation is the fit's, 0.94-0.96 degree off; refitted through the
    given focal length it took the whole sideways translation, 1.29-1.30 off."""
    from ppo_cv import data_gen

    imperfections = (
        data_gen.Imperfections(centred_principal_point=True) if centred else data_gen.REAL_PHOTO
    )
    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=9, imperfections=imperfections, baseline_ratio=0.02
    )
    images = [np.ascontiguousarray(image[..., ::-1]) for image in (pair.image1, pair.image2)]
    result = estimate_pair(*images, pair.K1_given, pair.K2_given)
    assert not result.pure_rotation and result.rotation_source == "rotation"
    assert result.lens.lens_excess > 0
    assert rotation_error_deg(result.R, pair.R) < 1.1
