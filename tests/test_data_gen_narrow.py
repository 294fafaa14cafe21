"""Narrow-field renders: the ``tripod`` motion preset and the ``NARROW_LENS`` imperfections.

Each render is checked against its own ground truth: the field of view of its true ``K1``, the
baseline against the depth map of view 1, and the lens against the division model the
estimator's radial refinements use (``ppo_cv.plane.undistort_division``).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ppo_cv.data_gen import NARROW_LENS, REAL_PHOTO, Imperfections, division_dist, make_pair
from ppo_cv.plane import undistort_division

SIZE = (320, 240)


def _distort(q: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Normalised pinhole points (N, 2) through OpenCV's lens ``dist``."""
    rays = np.column_stack([q, np.ones(len(q))])
    pixels = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), np.eye(3), dist)[0]
    return pixels.reshape(-1, 2)


@pytest.mark.parametrize("k1", [-0.15, -0.05, 0.1, 0.15])
def test_division_dist_is_the_division_model(k1):
    q = np.random.default_rng(0).uniform(-0.21, 0.21, (500, 2))
    recovered = undistort_division(_distort(q, division_dist(k1)), k1)[:, :2]
    assert np.max(np.abs(recovered - q)) < 2e-7
    assert np.max(np.abs(_distort(q, division_dist(k1)) - q)) > 0.1 * abs(k1) * 0.21**3


def test_narrow_lens_draws_strong_lenses_mostly_barrel():
    drawn = [NARROW_LENS.draw(np.random.default_rng([7, i])) for i in range(600)]
    k1 = np.array([d.k1 for d in drawn])
    assert np.all((np.abs(k1) >= 0.05) & (np.abs(k1) <= 0.15))
    assert 0.64 < np.mean(k1 < 0) < 0.76
    assert all(d.division for d in drawn)
    np.testing.assert_array_equal(drawn[0].dist, division_dist(drawn[0].k1))


def test_real_photo_draws_are_unchanged_by_the_barrel_share():
    for i in range(50):
        a = REAL_PHOTO.draw(np.random.default_rng([3, i]))
        b = Imperfections(barrel_share=0.5).draw(np.random.default_rng([3, i]))
        assert a == b and not a.division


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"barrel_share": 1.5}, "barrel_share"),
        ({"division": 1}, "division"),
        ({"division": True, "k2_fraction": -1.0}, "k2_fraction"),
    ],
)
def test_bad_lens_settings_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Imperfections(**kwargs)


def _tripod(index: int, ratio: float | None, size=SIZE, supersample: int = 1):
    return make_pair("tripod", seed=4, index=index, size=size, baseline_ratio=ratio,
                     imperfections=NARROW_LENS, supersample=supersample)  # fmt: skip


@pytest.mark.parametrize("index, ratio", [(0, 0.0), (1, 0.002), (2, 0.005), (3, 0.01), (4, None)])
def test_tripod_render_has_its_field_baseline_and_lens(index, ratio):
    pair = _tripod(index, ratio)
    width = SIZE[0]
    hfov = np.degrees(2.0 * np.arctan(width / (2.0 * pair.K1[0, 0])))
    assert 15.0 <= hfov <= 25.0
    assert hfov == pytest.approx(pair.params["hfov_deg"], abs=1e-9)
    depth = np.median(pair.depth1[np.isfinite(pair.depth1)])
    baseline = np.linalg.norm(pair.t) / depth
    if ratio is None:
        assert 0.002 <= baseline <= 0.01
    else:
        assert baseline == pytest.approx(ratio, rel=1e-3, abs=1e-12)
    pivot = np.array([0.0, 0.0, -pair.params["pivot_offset"]])
    np.testing.assert_allclose(pair.R @ pivot + pair.t, pivot, atol=1e-12)
    yaw = abs(pair.params["yaw_deg"])
    assert 0.35 * hfov <= yaw <= 0.7 * hfov
    k1 = pair.params["k1"]
    assert 0.05 <= abs(k1) <= 0.15
    np.testing.assert_array_equal(pair.dist1, division_dist(k1))
    np.testing.assert_array_equal(pair.dist2, pair.dist1)


def test_a_given_baseline_ratio_changes_nothing_but_the_translation():
    still, moved = _tripod(5, 0.0), _tripod(5, 0.008)
    np.testing.assert_array_equal(still.t, np.zeros(3))
    np.testing.assert_array_equal(still.R, moved.R)
    np.testing.assert_array_equal(still.K1_given, moved.K1_given)
    np.testing.assert_array_equal(still.image1, moved.image1)
    assert still.params["k1"] == moved.params["k1"]
    assert not np.array_equal(still.image2, moved.image2)


def test_tripod_renders_are_deterministic_by_seed():
    a, b = _tripod(6, None, size=(96, 72)), _tripod(6, None, size=(96, 72))
    np.testing.assert_array_equal(a.image1, b.image1)
    np.testing.assert_array_equal(a.image2, b.image2)
    assert a.params == b.params
    other = make_pair("tripod", seed=5, index=6, size=(96, 72), imperfections=NARROW_LENS)
    assert other.params["k1"] != a.params["k1"]


def _view2_pixels(pair, k1: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of view 1 with a finite depth, and where the division lens ``k1`` puts them in
    view 2 under the pair's true pose and intrinsics."""
    height, width = pair.depth1.shape
    v, u = np.mgrid[8 : height - 8 : 2, 8 : width - 8 : 2]
    pixels = np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)
    depth = pair.depth1[v.ravel(), u.ravel()].astype(np.float64)
    keep = np.isfinite(depth)
    pixels, depth = pixels[keep], depth[keep]
    x1 = np.column_stack([pixels, np.ones(len(pixels))]) @ np.linalg.inv(pair.K1).T
    points = undistort_division(x1, k1) * depth[:, None]
    seen = points @ pair.R.T + pair.t
    q2 = seen[:, :2] / seen[:, 2:]
    x2 = _distort(q2, division_dist(k1))
    return pixels, x2 @ pair.K2[:2, :2].T + pair.K2[:2, 2]


def _colour_difference(pair, k1: float) -> float:
    """Median grey-level difference of view 1 and view 2 sampled where ``k1`` maps view 1,
    over the outer half of the image (where the lens moves points most), at its steepest
    quarter of pixels (where a shift shows)."""
    pixels, target = _view2_pixels(pair, k1)
    height, width = pair.depth1.shape
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    inside = np.all((target > 2) & (target < [width - 3, height - 3]), axis=1)
    outer = np.linalg.norm((pixels - centre) / centre, axis=1) > 0.5
    grey1 = cv2.cvtColor(pair.image1, cv2.COLOR_RGB2GRAY).astype(np.float32)
    grey2 = cv2.cvtColor(pair.image2, cv2.COLOR_RGB2GRAY).astype(np.float32)
    gradient = np.hypot(cv2.Sobel(grey1, cv2.CV_32F, 1, 0), cv2.Sobel(grey1, cv2.CV_32F, 0, 1))
    edges = gradient[pixels[:, 1].astype(int), pixels[:, 0].astype(int)]
    use = inside & outer & (edges > np.percentile(edges[inside & outer], 75))
    maps = target[use].astype(np.float32).reshape(-1, 1, 2)
    sampled = cv2.remap(grey2, maps, None, cv2.INTER_LINEAR).ravel()
    source = grey1[pixels[use, 1].astype(int), pixels[use, 0].astype(int)]
    return float(np.median(np.abs(sampled - source)))


@pytest.mark.slow
def test_the_images_carry_the_stated_lens():
    pair = make_pair("tripod", seed=0, index=9, size=(640, 480), baseline_ratio=0.0,
                     imperfections=NARROW_LENS)  # fmt: skip
    k1 = pair.params["k1"]
    assert abs(k1) > 0.1
    stated = _colour_difference(pair, k1)
    assert stated < 0.5 * _colour_difference(pair, 0.0)
    assert stated < 0.5 * _colour_difference(pair, -k1)
    assert stated < 0.8 * _colour_difference(pair, 0.5 * k1)
