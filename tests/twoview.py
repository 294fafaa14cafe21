"""Synthetic two-view scenes with exact ground truth, shared by the tests."""

from __future__ import annotations

import cv2
import numpy as np


def skew(v):
    """The cross-product matrix ``[v]x``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def random_rotation(rng, max_angle_deg: float = 30.0):
    """A rotation about a random axis by an angle up to ``max_angle_deg``."""
    axis = rng.normal(size=3)
    angle = np.radians(rng.uniform(0.5, max_angle_deg))
    return cv2.Rodrigues(axis / np.linalg.norm(axis) * angle)[0]


def project(K, X):
    """Pixel projections (N, 2) of camera-frame points X (N, 3)."""
    return (X @ K.T)[:, :2] / X[:, 2:]


def pan_matches(K_true, K1_given, K2_given, R, size, grid=(30, 20)):
    """Exact matches of a pure rotation ``R`` seen by ``K_true``, normalised with the given
    intrinsics: a ``grid`` of pixels of image 1 (``size = (width, height)``) and where they
    land inside image 2. Returns homogeneous normalised points ``(x1, x2)``, each (N, 3)."""
    width, height = size
    axes = np.linspace(0, width - 1, grid[0]), np.linspace(0, height - 1, grid[1])
    u1 = np.column_stack(
        [np.stack(np.meshgrid(*axes), -1).reshape(-1, 2), np.ones(grid[0] * grid[1])]
    )
    u2 = u1 @ np.linalg.inv(K_true).T @ R.T @ K_true.T
    u2 = u2 / u2[:, 2:]
    inside = (u2[:, 0] >= 0) & (u2[:, 0] < width) & (u2[:, 1] >= 0) & (u2[:, 1] < height)
    return u1[inside] @ np.linalg.inv(K1_given).T, u2[inside] @ np.linalg.inv(K2_given).T


def make_scene(rng, n, R, t, K1, K2=None, noise_px=0.0, depth=(4.0, 12.0)):
    """Points in front of both cameras: returns (X1 (N, 3), pixels1, pixels2)."""
    K2 = K1 if K2 is None else K2
    X = np.empty((0, 3))
    while len(X) < n:
        Y = rng.uniform([-4, -3, depth[0]], [4, 3, depth[1]], (4 * n, 3))
        Y2 = Y @ R.T + t
        keep = Y2[:, 2] > 0.5
        X = np.vstack([X, Y[keep]])
    X = X[:n]
    p1 = project(K1, X) + rng.normal(0, noise_px, (n, 2)) * (noise_px > 0)
    p2 = project(K2, X @ R.T + t) + rng.normal(0, noise_px, (n, 2)) * (noise_px > 0)
    return X, p1, p2


def pycolmap_relative_pose(camera1, points1, camera2, points2):
    """pycolmap's LO-RANSAC relative pose (1 px, seed 0): ``(R, t, found)``, ``X2 = R X1 + t``."""
    import pycolmap

    from ppo_cv import colmap

    options = pycolmap.RANSACOptions()
    options.max_error = 1.0
    options.random_seed = 0
    found = pycolmap.estimate_relative_pose(camera1, points1, camera2, points2, options)
    R, t = colmap.pose_from_rigid3d(found["cam2_from_cam1"])
    return R, t, found
