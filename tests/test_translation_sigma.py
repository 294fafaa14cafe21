"""t_sigma_deg: the noise term it removes, and the focal length it does not fit."""

import numpy as np

from ppo_cv.lsq import rotation_increment
from ppo_cv.metrics import direction_error_deg
from ppo_cv.refine import (
    _calibrated_residuals,
    _jacobian_and_noise,
    refine_pose,
    translation_sigma_deg,
)


def _scene(seed: int, noise_px: float, f: float = 1500.0, n: int = 300):
    """Narrow field (about 28 deg), a 5 deg pan and a sideways-forward baseline."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(4, 12, n)])
    R = rotation_increment(np.radians([0.0, 5.0, 0.0]))
    t = np.array([0.1, 0.02, 0.05])
    x1 = X / X[:, 2:]
    X2 = X @ R.T + t
    x2 = X2 / X2[:, 2:]
    x1[:, :2] += rng.normal(0, noise_px / f, (n, 2))
    x2[:, :2] += rng.normal(0, noise_px / f, (n, 2))
    return R, t / np.linalg.norm(t), x1, x2, f


def test_noise_term_is_what_image_noise_adds_to_jtj():
    R, t, x1, x2, f = _scene(0, 0.0, n=120)
    residuals = _calibrated_residuals(R, t)
    J0, noise_info = _jacobian_and_noise(residuals, x1, x2, 1e-6)
    sigma = 0.5 / f
    rng = np.random.default_rng(1)
    excess = np.zeros_like(noise_info)
    draws = 300
    for _ in range(draws):
        y1, y2 = x1.copy(), x2.copy()
        y1[:, :2] += rng.normal(0, sigma, y1[:, :2].shape)
        y2[:, :2] += rng.normal(0, sigma, y2[:, :2].shape)
        J = _jacobian_and_noise(residuals, y1, y2, 1e-6)[0]
        excess += (J.T @ J - J0.T @ J0) / draws
    block = slice(3, 5)  # the translation, where the term decides the cap
    expected = sigma**2 * noise_info[block, block]
    assert np.linalg.norm(excess[block, block] - expected) < 0.15 * np.linalg.norm(expected)


def test_focal_length_held_off_by_three_percent_is_covered():
    within, overconfident = 0, 0
    for seed in range(6):
        R, t, x1, x2, f = _scene(seed, 0.05)
        y1, y2 = x1.copy(), x2.copy()
        y1[:, :2] *= 1.03  # the estimator is told a focal length 3 % too long
        y2[:, :2] *= 1.03
        used = np.ones(len(x1), bool)
        R_est, t_est = refine_pose(R, t, y1, y2, used, f)
        error = direction_error_deg(t_est, t, signed=False)
        exact = translation_sigma_deg(R_est, t_est, y1, y2, used, focal_prior=None)
        sigma = translation_sigma_deg(R_est, t_est, y1, y2, used)
        within += error < 3.0 * sigma
        overconfident += error > 3.0 * exact
    assert within == 6  # the bias, 1.7-3.5 deg, is inside three deviations
    assert overconfident >= 4  # with the focal held exact, the noise alone claims 0.3 deg
