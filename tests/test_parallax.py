"""The parallax of a homography's plane (ppo_cv.parallax) against poses built by hand."""

import numpy as np
import pytest

from ppo_cv.lsq import rotation_increment
from ppo_cv.parallax import fit_plane_parallax, homography_parallax

R = rotation_increment(np.radians([2.0, 15.0, -1.0]))


def _plane(u):
    """``I + u n^T`` of the fronto-parallel plane ``n = (0, 0, 1)``, ``u`` in camera 1."""
    return np.eye(3) + np.outer(u, [0.0, 0.0, 1.0])


def _points(H, n=400, noise=0.0, seed=0, half_width=0.27):
    rng = np.random.default_rng(seed)
    x1 = rng.uniform(-half_width, half_width, (n, 2))
    h = np.column_stack([x1, np.ones(n)]) @ H.T
    return x1, h[:, :2] / h[:, 2:] + rng.normal(0.0, noise, (n, 2))


@pytest.mark.parametrize("direction", [(1, 0, 0), (0, 1, 0), (1, 1, 0)])
def test_parallax_is_the_baseline_over_the_distance_for_a_motion_along_the_plane(direction):
    u = 0.02 * np.asarray(direction, float) / np.linalg.norm(direction)
    assert homography_parallax(R @ _plane(u)) == pytest.approx(0.02, rel=0.001)
    oblique = homography_parallax(R @ _plane(0.02 * np.array([0.6, 0.0, 0.8])))
    assert 0.001 < oblique < 0.6 * 0.02
    assert homography_parallax(R @ _plane([0.0, 0.0, 0.02])) == pytest.approx(0.0, abs=1e-12)


def test_rotation_and_a_change_of_focal_length_have_no_parallax():
    assert homography_parallax(R) == pytest.approx(0.0, abs=1e-12)
    zoom = np.diag([1.03, 1.03, 1.0]) @ R
    assert homography_parallax(zoom) == pytest.approx(0.0, abs=1e-12)
    assert homography_parallax(np.diag([1.0, 1.0, 0.0])) == np.inf


def test_fitted_parallax_and_its_deviation_match_the_truth_over_noise_draws():
    H = R @ _plane([0.0, 0.012, 0.0])
    fits = [fit_plane_parallax(*_points(H, noise=3e-5, seed=seed)) for seed in range(40)]
    values = np.array([f.parallax for f in fits])
    sigmas = np.array([f.sigma for f in fits])
    assert abs(np.mean(values) - 0.012) < 0.5 * np.mean(sigmas)
    assert np.std(values) == pytest.approx(np.mean(sigmas), rel=0.35)
    assert np.median(fits[0].residuals) < 1e-4
    exact = fit_plane_parallax(*_points(R, noise=3e-5))
    assert exact.parallax < 3 * exact.sigma


def test_the_deviation_grows_in_a_narrow_strip_and_with_few_points():
    H = R @ _plane([0.01, 0.0, 0.0])
    wide = fit_plane_parallax(*_points(H, noise=3e-5))
    few = fit_plane_parallax(*_points(H, n=30, noise=3e-5))
    narrow = fit_plane_parallax(*_points(H, noise=3e-5, half_width=0.05))
    assert few.sigma > 2 * wide.sigma
    assert narrow.sigma > 5 * wide.sigma


@pytest.mark.parametrize(
    "x1, x2, noise, message",
    [
        (np.zeros((7, 2)), np.zeros((7, 2)), None, "at least 8"),
        (np.zeros((9, 2)), np.zeros((8, 2)), None, "same shape"),
        (np.zeros((9, 4)), np.zeros((9, 4)), None, "shape"),
        (np.full((9, 2), np.nan), np.zeros((9, 2)), None, "x1 has 18 NaN or infinite"),
        (np.ones((9, 2)), np.ones((9, 2)), -1.0, "noise"),
    ],
)
def test_bad_input_is_named(x1, x2, noise, message):
    with pytest.raises(ValueError, match=message):
        fit_plane_parallax(x1, x2, noise)


def test_each_jacobian_of_the_fit_is_one_stacked_call_with_the_same_figures(monkeypatch):
    import ppo_cv.parallax as parallax

    rng = np.random.default_rng(2)
    x1 = rng.uniform(-0.3, 0.3, (120, 2))
    H = np.array([[1.01, 0.002, 0.03], [-0.003, 0.99, -0.01], [0.02, 0.01, 1.0]])
    h = np.column_stack([x1, np.ones(120)]) @ H.T
    x2 = h[:, :2] / h[:, 2:] + rng.normal(0.0, 1e-3, (120, 2))
    fit = fit_plane_parallax(x1, x2)
    shapes = []
    transfer = parallax._transfer
    monkeypatch.setattr(
        parallax, "_transfer", lambda H, a, b: shapes.append(np.shape(H)) or transfer(H, a, b)
    )
    assert fit_plane_parallax(x1, x2).parallax == fit.parallax
    assert (8, 3, 3) in shapes and shapes.count((3, 3)) < 2 * shapes.count((8, 3, 3)) + 3
    one_at_a_time = parallax._levenberg_marquardt
    monkeypatch.setattr(
        parallax, "_levenberg_marquardt", lambda f, p, steps, many=None: one_at_a_time(f, p, steps)
    )
    alone = fit_plane_parallax(x1, x2)
    assert np.array_equal(alone.H, fit.H)
    assert (alone.parallax, alone.sigma) == (fit.parallax, fit.sigma)
