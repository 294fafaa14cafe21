"""Descriptor matching: the dense nearest-neighbour search against a brute-force sort."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv.features import _two_nearest_dense


@pytest.mark.parametrize("block", [7, 2048])
def test_two_nearest_equal_a_full_sort(block):
    rng = np.random.default_rng(3)
    d1 = rng.random((50, 16)).astype(np.float32)
    d2 = rng.random((40, 16)).astype(np.float32)
    index12, dist12, index21 = _two_nearest_dense(d1, d2, block=block)
    full = np.linalg.norm(d1[:, None, :].astype(float) - d2[None, :, :], axis=2)
    order = np.argsort(full, axis=1)[:, :2]
    np.testing.assert_array_equal(index12, order)
    np.testing.assert_allclose(dist12, np.take_along_axis(full, order, axis=1), atol=1e-5)
    np.testing.assert_array_equal(index21, np.argmin(full, axis=0))
