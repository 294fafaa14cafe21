"""The radial term of the general refinement on handheld swings: a pan about a pivot behind
the camera, rendered with exact intrinsics and no lens distortion, must keep its rotation; a
lens nobody gave must still be fitted and improve the pose.

On the swings (``|t| / depth`` about 0.01 to 0.03, a 50 degree field) the division
coefficient ``k1`` and the pose trade along the bas-relief valley: a coefficient the
refinement keeps on a distortion-free lens moves the rotation by about 14 degrees per unit of
``k1``, against 0.5 to 2.5 on the translating renders and the real pairs where a lens term
is really present.
"""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import PairOptions, estimate_pair
from ppo_cv.metrics import rotation_error_deg

DEPTH = 4.0
FIELD_DEG = 50.0
SWING_DEG = 6.0


def _swing(scene_name: str, seed: int, pivot_m: float):
    """A pan of :data:`SWING_DEG` about a pivot ``pivot_m`` behind the camera, ``t = (I - R) P``."""
    from ppo_cv.data_gen.motion import intrinsics
    from ppo_cv.data_gen.render import render_pair
    from ppo_cv.data_gen.scenes import make_scene

    K = intrinsics((640, 480), FIELD_DEG)
    angle = np.radians(SWING_DEG)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    pivot = np.array([0.0, 0.0, -pivot_m])
    pair = render_pair(make_scene(scene_name, seed), K, K, R, pivot - R @ pivot, noise_std=2.0,
                       seed=seed)  # fmt: skip
    return pair.image1, pair.image2, K, R


ROTATION_ONLY_CHOSEN = pytest.mark.xfail(
    strict=True,
    reason="|t| / depth 0.031: the general pose is 0.02 degree off with k1 held at 0, but its "
    "matches read k1 0.041 +- 0.027 (0.026 of it the guessed principal point's), 15 degrees of "
    "rotation per unit: released, the rotation moves 0.66 degree; the rotation-only fit's "
    "bias, 0.55 degree and as far off, is the smaller expected error",
)


@pytest.mark.slow
@pytest.mark.parametrize(
    "scene_name, seed, pivot_m",
    [
        ("room", 0, 0.4),
        ("room", 1, 0.4),
        ("backdrop", 0, 0.4),
        pytest.param("room", 1, 1.2, marks=ROTATION_ONLY_CHOSEN),
        ("backdrop", 1, 0.4),
    ],
)
def test_a_handheld_swing_without_distortion_keeps_its_rotation(scene_name, seed, pivot_m):
    image1, image2, K, R = _swing(scene_name, seed, pivot_m)
    result = estimate_pair(image1, image2, K, K)
    assert rotation_error_deg(result.R, R) < 0.15


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 2])
def test_a_lens_nobody_gave_is_still_fitted_and_improves_the_rotation(index):
    from ppo_cv import data_gen

    pair = data_gen.make_pair("general", seed=0, index=index, imperfections=data_gen.REAL_PHOTO)
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    refined = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    held = estimate_pair(image1, image2, pair.K1_given, pair.K2_given,
                         options=PairOptions(refine=False))  # fmt: skip
    assert refined.model == "general"
    assert refined.lens.radial_k1 == pytest.approx(pair.params["k1"], abs=0.03)
    assert rotation_error_deg(refined.R, pair.R) < 0.5 * rotation_error_deg(held.R, pair.R)
