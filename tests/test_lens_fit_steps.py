"""The steps of the lens rotation fit (``ppo_cv.rotation.fit_rotation_lens``): its analytic
Jacobian, and the deviations at its minimum computed only when asked, which the loops that drop
outliers (the tracks' refit and the settled rotation of the model decision) ask of their last fit
only."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from ppo_cv import lsq, motion_model, photometric, rotation
from ppo_cv.rotation import MAX_FOCAL_CHANGE, fit_rotation_lens

FOCAL = 1000.0
NOISE = 0.1 / FOCAL


def _pan(focal_error: float = 0.02, k1: float = 0.05, outliers: int = 20, seed: int = 0):
    """Normalised matches (N, 2) of a 12 degree pan about a tilted axis through a lens with
    ``k1``, the principal point 5 px off and the focal length ``1 + focal_error`` too short,
    located to 0.1 px, the last ``outliers`` of them moved by 3-10 px."""
    rng = np.random.default_rng(seed)
    q1 = rng.uniform(-0.35, 0.35, (500, 2))
    R = lsq.rotation_increment(np.radians([2.0, 12.0, 1.0]))
    ray = np.column_stack([q1, np.ones(len(q1))]) @ R.T
    q2 = ray[:, :2] / ray[:, 2:]
    keep = np.all(np.abs(q2) < 0.35, axis=1)
    offset = np.array([5.0, -3.0]) / FOCAL
    x1, x2 = (
        (offset + q * (1 + k1 * np.sum(q * q, axis=1, keepdims=True))) * (1 + focal_error)
        for q in (q1[keep], q2[keep])
    )
    x2 = x2 + rng.normal(0.0, NOISE, x2.shape)
    x2[-outliers:] += rng.choice([-1, 1], (outliers, 2)) * rng.uniform(3, 10, (outliers, 2)) / FOCAL
    return R, x1, x2


def _fields(fit) -> dict:
    return {f.name: getattr(fit, f.name) for f in dataclasses.fields(fit)}


def _same(a, b) -> bool:
    return all(np.array_equal(a[k], b[k], equal_nan=True) for k in a)


def test_the_analytic_jacobian_is_the_derivative_of_the_residuals():
    _, x1, x2 = _pan()
    free, prior, centre, _, _ = rotation._lens_terms_setup(
        NOISE, 0.02, 0.1, 0.01, 0.01, 1.0, 2.0, MAX_FOCAL_CHANGE, 0.2
    )
    assert np.all(free)
    problem = rotation._problem(x1, x2, np.ones(len(x1), bool), np.eye(3), prior, free, centre)[0]
    params = np.array([0.01, -0.2, 0.03, 0.02, 0.05, 0.004, -0.003, 0.01])
    J = rotation._jacobian(params, problem, rotation._forward(params, problem[0], problem[1]))
    step = 1e-7
    for k in range(8):
        up, down = params.copy(), params.copy()
        up[k] += step
        down[k] -= step
        numeric = (rotation._objective(up, problem)[0] - rotation._objective(down, problem)[0]) / (
            2 * step
        )
        np.testing.assert_allclose(J[:, k], numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max())


def test_deviations_left_out_leave_the_fit_and_are_the_same_when_asked():
    _, x1, x2 = _pan()
    used = np.ones(len(x1), bool)
    used[-20:] = False
    kwargs = {"noise": NOISE, "principal_prior": 0.01}
    full = _fields(fit_rotation_lens(x1, x2, used, np.eye(3), **kwargs))
    left_out = _fields(fit_rotation_lens(x1, x2, used, np.eye(3), deviations=False, **kwargs))
    deviations = ("focal_scale_sigma", "rotation_sigma_deg", "lens_excess")
    assert all(np.isfinite(full[k]) for k in deviations)
    assert all(np.isnan(left_out[k]) for k in deviations)
    assert _same({k: full[k] for k in full if k not in deviations}, {
        k: left_out[k] for k in full if k not in deviations
    })  # fmt: skip
    seen = []
    asked = fit_rotation_lens(x1, x2, used, np.eye(3), deviations=seen.append, **kwargs)
    assert len(seen) == 1 and _same(_fields(seen[0]), left_out)
    assert _same(_fields(asked), left_out)  # the callable's None says no
    granted = fit_rotation_lens(x1, x2, used, np.eye(3), deviations=lambda fit: True, **kwargs)
    assert _same(_fields(granted), full)


def test_a_clipped_fit_without_deviations_still_says_it_was_clipped():
    _, x1, x2 = _pan(focal_error=0.09, outliers=1)
    used = np.ones(len(x1), bool)
    full = fit_rotation_lens(x1, x2, used, np.eye(3), noise=NOISE)
    left_out = fit_rotation_lens(x1, x2, used, np.eye(3), noise=NOISE, deviations=False)
    assert full.focal_scale == pytest.approx(1 - MAX_FOCAL_CHANGE) and full.lens_excess > 0
    assert np.isinf(left_out.rotation_sigma_deg) and np.isinf(left_out.focal_scale_sigma)
    assert np.isnan(left_out.lens_excess) and np.array_equal(left_out.R, full.R)


def _recorded(monkeypatch, module):
    """The fits ``module`` makes through ``fit_rotation_lens``, each with its arguments."""
    calls = []
    fit_rotation_lens = rotation.fit_rotation_lens

    def recording(*args, **kwargs):
        fit = fit_rotation_lens(*args, **kwargs)
        calls.append((args, kwargs, fit))
        return fit

    monkeypatch.setattr(module, "fit_rotation_lens", recording)
    return calls


def _only_the_last_has_deviations(calls, result):
    assert len(calls) >= 2
    assert all(np.isnan(fit.rotation_sigma_deg) for _, _, fit in calls[:-1])
    args, kwargs, last = calls[-1]
    assert last is result and np.isfinite(last.rotation_sigma_deg)
    kwargs = {k: v for k, v in kwargs.items() if k != "deviations"}
    assert _same(_fields(fit_rotation_lens(*args, **kwargs)), _fields(last))


def test_the_tracks_refit_computes_the_deviations_of_its_last_fit_only(monkeypatch):
    _, y1, y2 = _pan()
    calls = _recorded(monkeypatch, photometric)
    priors = {"principal_prior": 0.01, "on_clipped": lambda: pytest.fail("not clipped")}
    valid = np.ones(len(y1), bool)
    fit, used, _ = photometric._fit_tracks(y1, y2, valid, np.eye(3), FOCAL, priors)
    assert not used[-20:].any() and used[:-20].all()
    _only_the_last_has_deviations(calls, fit)


def test_the_settled_rotation_computes_the_deviations_of_its_last_fit_only(monkeypatch):
    _, x1, x2 = _pan()
    calls = _recorded(monkeypatch, motion_model)
    context = SimpleNamespace(x1=x1, x2=x2, noise=NOISE, threshold=4 * NOISE)
    start = np.ones(len(x1), bool)
    priors = {"principal_prior": 0.01}
    lens, inliers = motion_model._settled_lens_fit(start, np.eye(3), priors, context)
    assert not inliers[-20:].any() and inliers[:-20].all()
    _only_the_last_has_deviations(calls, lens)


def test_the_lens_maps_give_the_same_points_whatever_the_layout_of_the_given_ones():
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-0.5, 0.5, (300, 2)), np.ones(300)])
    lens = (1.03, 0.05, (0.004, -0.002))
    given = [points[:, :2].copy(), np.asfortranarray(points[:, :2]), points, points[:, :2]]
    rays = [rotation.correct_points(x, *lens) for x in given]
    moved = [rotation.transfer_points(x, np.eye(3), *lens) for x in given]
    assert all(np.array_equal(r, rays[0]) for r in rays) and np.all(rays[0][:, 2] == 1.0)
    assert all(np.array_equal(m, moved[0]) for m in moved)
    q = rays[0][:, :2]
    distorted = np.asarray(lens[2]) + q * (1 + lens[1] * np.sum(q * q, axis=1, keepdims=True))
    np.testing.assert_allclose(distorted, lens[0] * points[:, :2], atol=1e-9)
    np.testing.assert_allclose(moved[0], points[:, :2], atol=1e-9)
