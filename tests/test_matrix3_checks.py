"""A 3x3 matrix argument is checked by one function, ``checks.as_matrix3``, wherever it is taken:
the same hostile value (another shape, NaN, a text, None, an object array, an integer beyond a
float, a ragged list) gets the same error, naming the argument, from each."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import colmap, parallax, plane, ppo
from ppo_cv.checks import as_matrix3
from ppo_cv.data_gen import RenderedPair

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
X = np.column_stack([np.linspace(-0.2, 0.2, 8), np.linspace(0.1, -0.1, 8), np.ones(8)])


def _rendered(K1):
    image, depth = np.zeros((8, 8, 3), np.uint8), np.ones((8, 8), np.float32)
    return RenderedPair(image, image, K1, K, np.eye(3), np.zeros(3), depth)


TAKERS = {
    "parallax.homography_parallax H": ("H", parallax.homography_parallax),
    "parallax.focal_conjugates H": ("H", lambda H: parallax.focal_conjugates(H, [0.0])),
    "parallax.rotation_spread H": ("H", lambda H: parallax.rotation_spread(H, [0.0, 0.1])),
    "plane.planar_pose H": ("H", lambda H: plane.planar_pose(H, X, X)),
    "plane.normalize_homography H": ("H", plane.normalize_homography),
    "plane.decompose_homography H": ("H", plane.decompose_homography),
    "ppo.analytic_points R": ("R", lambda R: ppo.analytic_points(X, X, R, [1.0, 0.0, 0.0])),
    "ppo.same_side_scores R": ("R", lambda R: ppo.same_side_scores(X, X, R, [1.0, 0.0, 0.0])),
    "ppo.candidates_from_svd U": ("U", lambda U: ppo.candidates_from_svd(U, [1, 1, 0], np.eye(3))),
    "RenderedPair K1": ("K1", _rendered),
    "colmap geometry E": (
        "geometry.E", lambda E: colmap._require_essential_geometry(E, np.zeros((0, 2), int))),
}  # fmt: skip
HOSTILE = {
    "2x2": np.eye(2),
    "row": np.ones(9),
    "NaN": np.full((3, 3), np.nan),
    "inf": np.diag([1.0, np.inf, 1.0]),
    "text": "1,0,0,0,1,0,0,0,1",
    "None": None,
    "object": np.array([[1, None, 0], [0, 1, 0], [0, 0, 1]], dtype=object),
    "beyond a float": [[10**400, 0, 0], [0, 1, 0], [0, 0, 1]],
    "ragged": [[1.0, 0.0], [0.0]],
    "bool": np.eye(3, dtype=bool),
}


@pytest.mark.parametrize("value", list(HOSTILE), ids=list(HOSTILE))
@pytest.mark.parametrize("taker", list(TAKERS), ids=list(TAKERS))
def test_a_hostile_3x3_matrix_gets_the_words_of_as_matrix3(taker, value):
    name, call = TAKERS[taker]
    with pytest.raises((ValueError, TypeError)) as expected:
        as_matrix3(HOSTILE[value], name)
    with pytest.raises(expected.type) as found:
        call(HOSTILE[value])
    assert str(found.value) == str(expected.value)
    assert str(found.value).startswith(name)


def test_an_integer_beyond_a_float_is_named_as_such():
    """numpy keeps 10**400 as a Python object: it was a TypeError of dtype object, and in
    ``plane`` and ``colmap`` Python's OverflowError."""
    with pytest.raises(ValueError, match="^H holds a number beyond the range of a float$"):
        as_matrix3([[10**400, 0, 0], [0, 1, 0], [0, 0, 1]], "H")
    with pytest.raises(ValueError, match="^x1 holds a number beyond the range of a float$"):
        ppo.analytic_points([[10**400, 0.0, 1.0]] * 8, X, np.eye(3), [1.0, 0.0, 0.0])
