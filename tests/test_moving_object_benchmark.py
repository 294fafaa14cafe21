"""The moving patch of benchmarks/moving_object.py lands where its docstring says."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest

from ppo_cv import data_gen

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "moving_object.py"


@pytest.fixture(scope="module")
def script():
    if not SCRIPT.is_file():
        pytest.skip("the benchmark script is not in this tree")
    spec = importlib.util.spec_from_file_location("moving_object_benchmark", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _found(image: np.ndarray, patch: np.ndarray) -> np.ndarray:
    """Centre (x, y) of the best match of ``patch`` in ``image``."""
    scores = cv2.matchTemplate(image, patch, cv2.TM_SQDIFF)
    y, x = np.unravel_index(np.argmin(scores), scores.shape)
    return np.array([x + patch.shape[1] / 2.0, y + patch.shape[0] / 2.0])


@pytest.mark.parametrize("shift", [0.0, 12.0])
def test_patch_moves_by_the_rotation_and_the_shift(script, shift):
    pair = data_gen.make_warped_pair(seed=0, index=3, imperfections=None)
    texture = data_gen.make_warped_pair(seed=0, index=10, imperfections=None).image1
    moved = script.with_moving_patch(pair, texture, 0.04, shift)
    image1, image2 = moved.image1, moved.image2
    changed = np.any(image1 != pair.image1, axis=2)
    ys, xs = np.nonzero(changed)
    patch = image1[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    h, w = image1.shape[:2]
    assert patch.shape[0] * patch.shape[1] == pytest.approx(0.04 * w * h, rel=0.05)
    centre1 = _found(image1, patch)
    H = pair.K2_given @ pair.R @ np.linalg.inv(pair.K1_given)
    expected = H @ np.r_[centre1, 1.0]
    expected = expected[:2] / expected[2] + np.array([shift, 0.0])
    np.testing.assert_allclose(_found(image2, patch), expected, atol=1.0)


def test_no_area_leaves_the_views_as_they_are(script):
    pair = data_gen.make_warped_pair(seed=0, index=3, imperfections=None)
    moved = script.with_moving_patch(pair, pair.image2, 0.0, 12.0)
    assert np.array_equal(moved.image1, pair.image1) and np.array_equal(moved.image2, pair.image2)
