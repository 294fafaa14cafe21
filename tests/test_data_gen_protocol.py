"""The paper's point-level Monte-Carlo generator (Section 5)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ppo_cv.data_gen import PAPER_K, ProtocolSample, euler_to_matrix, paper_protocol


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def test_shapes_types_and_frozen():
    s = paper_protocol(7, 11, alpha=0.3, noise_px=1.0, seed=3)
    assert isinstance(s, ProtocolSample)
    for array in (s.points1, s.points2, s.points1_clean, s.points2_clean):
        assert array.shape == (7, 11, 2) and array.dtype == np.float64
    assert s.points3d.shape == (7, 11, 3)
    assert s.R.shape == (7, 3, 3) and s.t.shape == (7, 3) and s.euler_deg.shape == (7, 3)
    np.testing.assert_array_equal(s.K, PAPER_K)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.alpha = 1.0


@pytest.mark.parametrize("depth", [30.0, 50.0, 80.0])
def test_geometry_matches_the_paper(depth):
    alpha = 0.37
    s = paper_protocol(300, 50, alpha=alpha, noise_px=0.0, depth=depth, seed=1)
    X = s.points3d
    assert np.all(np.abs(X[..., :2]) <= 15.0)
    assert X[..., 2].min() >= depth / 2 and X[..., 2].max() <= 1.5 * depth
    assert np.all(X == X[:1]), "one point cloud shared by all poses"
    RtR = np.einsum("nji,njk->nik", s.R, s.R)
    np.testing.assert_allclose(RtR, np.broadcast_to(np.eye(3), s.R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(s.R), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.t, axis=1), alpha * 4.2, rtol=1e-12)
    centres = -np.einsum("nji,nj->ni", s.R, s.t)
    np.testing.assert_allclose(centres[:, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(s.R, euler_to_matrix(s.euler_deg), atol=1e-15)
    # projections are exact and satisfy the epipolar constraint x2^T [t]x R x1 = 0
    x1 = X @ PAPER_K.T
    np.testing.assert_allclose(s.points1_clean, x1[..., :2] / x1[..., 2:], rtol=1e-12)
    X2 = np.einsum("nij,npj->npi", s.R, X) + s.t[:, None]
    x2 = X2 @ PAPER_K.T
    np.testing.assert_allclose(s.points2_clean, x2[..., :2] / x2[..., 2:], rtol=1e-12)
    Kinv = np.linalg.inv(PAPER_K)
    h1 = np.concatenate([s.points1_clean, np.ones((300, 50, 1))], -1) @ Kinv.T
    h2 = np.concatenate([s.points2_clean, np.ones((300, 50, 1))], -1) @ Kinv.T
    E = np.stack([_skew(t) @ R for R, t in zip(s.R, s.t, strict=True)])
    assert np.abs(np.einsum("npi,nij,npj->np", h2, E, h1)).max() < 1e-12
    assert X2[..., 2].min() > 0


def test_rotation_and_noise_statistics():
    s = paper_protocol(20000, 4, alpha=1.0, noise_px=2.5, seed=5)
    np.testing.assert_allclose(s.euler_deg.std(axis=0), [5.0, 5.0, 20.0], rtol=0.03)
    np.testing.assert_allclose(s.euler_deg.mean(axis=0), 0.0, atol=0.5)
    noise = np.concatenate([s.points1 - s.points1_clean, s.points2 - s.points2_clean])
    assert abs(noise.std() - 2.5) < 0.03 and abs(noise.mean()) < 0.03
    phi = np.arctan2(*(-np.einsum("nji,nj->ni", s.R, s.t))[:, 1::-1].T)
    hist = np.histogram(phi, bins=8, range=(-np.pi, np.pi))[0]
    assert hist.min() > 0.9 * 20000 / 8, "translation direction uniform in the OXY plane"


def test_seeded_and_reproducible():
    a = paper_protocol(5, 20, alpha=0.5, noise_px=1.0, seed=9)
    b = paper_protocol(5, 20, alpha=0.5, noise_px=1.0, seed=9)
    for field in ("points1", "points2", "points3d", "R", "t"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    c = paper_protocol(5, 20, alpha=0.5, noise_px=1.0, seed=10)
    assert not np.allclose(a.R, c.R)


def test_sweeping_alpha_and_noise_keeps_scene_and_pose_directions():
    a = paper_protocol(6, 30, alpha=0.9, noise_px=0.1, seed=2)
    b = paper_protocol(6, 30, alpha=0.001, noise_px=5.0, seed=2)
    np.testing.assert_array_equal(a.points3d, b.points3d)
    np.testing.assert_array_equal(a.R, b.R)
    np.testing.assert_allclose(a.t / 0.9, b.t / 0.001, rtol=1e-9)
    c = paper_protocol(6, 30, alpha=0.9, noise_px=0.1, seed=2, mc_run=1)
    np.testing.assert_array_equal(a.points1_clean, c.points1_clean)
    assert not np.allclose(a.points1, c.points1)


def test_zero_parallax_is_exact_pure_rotation():
    s = paper_protocol(4, 10, alpha=0.0, noise_px=0.0, seed=0)
    assert np.all(s.t == 0.0)
    H = PAPER_K @ s.R @ np.linalg.inv(PAPER_K)
    h = np.concatenate([s.points1_clean, np.ones((4, 10, 1))], -1) @ np.transpose(H, (0, 2, 1))
    np.testing.assert_allclose(h[..., :2] / h[..., 2:], s.points2_clean, atol=1e-9)


def test_fresh_points_per_pose():
    s = paper_protocol(3, 10, alpha=0.2, noise_px=0.0, seed=0, shared_points=False)
    assert not np.allclose(s.points3d[0], s.points3d[1])


@pytest.mark.parametrize(
    "kwargs, error",
    [
        ({"n_poses": 0}, ValueError),
        ({"n_points": 2.5}, TypeError),
        ({"alpha": -0.1}, ValueError),
        ({"noise_px": float("nan")}, ValueError),
        ({"depth": 0.0}, ValueError),
        ({"seed": -1}, ValueError),
    ],
)
def test_bad_arguments_are_rejected(kwargs, error):
    args = {"n_poses": 2, "n_points": 5, "alpha": 0.5, "noise_px": 1.0, **kwargs}
    with pytest.raises(error):
        paper_protocol(**args)
