"""Point-level Monte-Carlo generator of the paper's simulation protocol (Section 5).

Setting
-------
* Camera 1 is ``(I | 0)``; both cameras share
  ``K = [[800, 0, 512], [0, 800, 512], [0, 0, 1]]``.
* 3D points are drawn from ``U((0, 0, d), (30, 30, d))``: the box centred at ``(0, 0, d)`` with
  side lengths 30 m, 30 m and ``d`` along X, Y and Z, i.e. ``X, Y ~ U(-15, 15)`` and
  ``Z ~ U(d/2, 3d/2)``.
* The rotation of camera 2 has Euler angles (about the camera X, Y and Z axes, degrees)
  ``~ N(0, diag(5^2, 5^2, 20^2))`` and ``R = Rz(gz) @ Ry(gy) @ Rx(gx)``.
* Camera 2's centre lies in the OXY plane of camera 1, ``C2 = ||t|| (cos phi, sin phi, 0)``
  with ``phi ~ U(0, 2 pi)`` and ``||t|| = alpha * 4.2``; the translation of the convention
  ``x2 = R x1 + t`` is ``t = -R C2`` (so ``||t|| = alpha * 4.2``).
* Pixels are ``p ~ K X / Z`` plus i.i.d. Gaussian noise of standard deviation ``noise_px`` on
  each coordinate of both views.

Random streams are split so that the scene and the poses depend only on ``seed`` (and the
array sizes and ``depth``) and the noise only on ``(seed, mc_run)``: sweeping
``alpha`` and ``noise_px`` with a fixed seed keeps the same points, rotations and translation
directions, as in the paper's parameter grid, and ``mc_run`` selects the Monte-Carlo noise draw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ppo_cv.checks import as_finite_array, as_flag
from ppo_cv.result import compact_repr

__all__ = [
    "PAPER_K",
    "PAPER_T_MAX",
    "MAX_ALPHA",
    "MAX_NOISE_PX",
    "DEPTH_RANGE",
    "MAX_PROTOCOL_POINTS",
    "ProtocolSample",
    "euler_to_matrix",
    "paper_protocol",
]

PAPER_K = np.array([[800.0, 0.0, 512.0], [0.0, 800.0, 512.0], [0.0, 0.0, 1.0]])
"""Intrinsics of both cameras in the paper's simulations."""

PAPER_T_MAX = 4.2
"""Maximum translation length ``||t||max`` (metres) of the paper's simulations."""

PAPER_EULER_SIGMA_DEG = (5.0, 5.0, 20.0)
PAPER_BOX = (30.0, 30.0)
MAX_ALPHA = 100.0
"""Largest parallax factor: a translation of 420 m, 14 times the paper's nearest scene depth
(the paper's factors end at 1); 1e300 overflowed the projections."""
MAX_NOISE_PX = 1024.0
"""Largest noise deviation, pixels: the side of the image of :data:`PAPER_K`."""
DEPTH_RANGE = (1.0, 1e6)
"""Scene depths accepted, metres (the paper's are 30, 50 and 80): nearer, the 30 m box of points
projects ever farther outside the image (1e-300 gave coordinates of 1e303)."""
MAX_PROTOCOL_POINTS = 10_000_000
"""Largest ``n_poses * n_points``: the sample holds 11 numbers per point, 880 MB at the bound."""


@dataclass(frozen=True, repr=False)
class ProtocolSample:
    """Point correspondences with exact ground truth for ``n_poses`` two-view problems.

    Its ``repr`` is one line, the arrays by their shape (:func:`ppo_cv.result.compact_repr`).

    Attributes
    ----------
    points1, points2 : ndarray, shape (n_poses, n_points, 2)
        Noisy pixel coordinates in views 1 and 2.
    points1_clean, points2_clean : ndarray, shape (n_poses, n_points, 2)
        Noise-free pixel coordinates.
    points3d : ndarray, shape (n_poses, n_points, 3)
        True 3D points in camera-1 coordinates.
    R : ndarray, shape (n_poses, 3, 3)
        True rotations, ``x2 = R x1 + t``.
    t : ndarray, shape (n_poses, 3)
        True translations, ``||t|| = alpha * 4.2``.
    K : ndarray, shape (3, 3)
        Intrinsics shared by both views.
    euler_deg : ndarray, shape (n_poses, 3)
        Euler angles (about X, Y, Z, degrees) that generated ``R``.
    alpha, noise_px, depth : float
        Parallax factor, pixel noise standard deviation and scene depth ``d``.
    seed, mc_run : int
        Seed of scene and poses, and index of the noise draw.
    """

    points1: np.ndarray
    points2: np.ndarray
    points1_clean: np.ndarray
    points2_clean: np.ndarray
    points3d: np.ndarray
    R: np.ndarray
    t: np.ndarray
    K: np.ndarray
    euler_deg: np.ndarray
    alpha: float
    noise_px: float
    depth: float
    seed: int
    mc_run: int

    def __repr__(self) -> str:
        return compact_repr(self)


def euler_to_matrix(angles_deg: np.ndarray) -> np.ndarray:
    """Rotation matrices ``R = Rz(gz) @ Ry(gy) @ Rx(gx)`` from Euler angles.

    Parameters
    ----------
    angles_deg : array_like, shape (..., 3)
        Finite angles ``(gx, gy, gz)`` in degrees about the X, Y and Z axes.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Proper rotation matrices (float64).
    """
    a = np.deg2rad(as_finite_array(angles_deg, "angles_deg"))
    if a.shape[-1:] != (3,):
        raise ValueError(f"angles_deg must have shape (..., 3), got {a.shape}")
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(c[..., 0]), np.zeros_like(c[..., 0])
    rx = np.stack([one, zero, zero, zero, c[..., 0], -s[..., 0], zero, s[..., 0], c[..., 0]], -1)
    ry = np.stack([c[..., 1], zero, s[..., 1], zero, one, zero, -s[..., 1], zero, c[..., 1]], -1)
    rz = np.stack([c[..., 2], -s[..., 2], zero, s[..., 2], c[..., 2], zero, zero, zero, one], -1)
    shape = a.shape[:-1] + (3, 3)
    return rz.reshape(shape) @ ry.reshape(shape) @ rx.reshape(shape)


def _check_count(name: str, value: int, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _check_real(name: str, value: float, minimum: float, maximum: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value) if abs(value) < 2**1024 else math.inf  # an int beyond a float
    if not np.isfinite(value) or value < minimum:
        raise ValueError(f"{name} must be finite and >= {minimum:g}, got {value}")
    if value > maximum:
        raise ValueError(f"{name} must be at most {maximum:g}, got {value:g}")
    return value


def _project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pixels ``(K X)[:2] / (K X)[2]`` of points ``X`` of shape (..., 3)."""
    x = X @ K.T
    return x[..., :2] / x[..., 2:3]


def paper_protocol(
    n_poses: int,
    n_points: int,
    alpha: float,
    noise_px: float,
    depth: float = 30.0,
    seed: int = 0,
    mc_run: int = 0,
    shared_points: bool = True,
) -> ProtocolSample:
    """Draw ``n_poses`` two-view problems of the paper's Monte-Carlo study (Section 5).

    Parameters
    ----------
    n_poses : int
        Number of camera-2 poses ``N_s`` (>= 1).
    n_points : int
        Number of 3D points ``N_pts`` per pose (>= 1; ``n_poses * n_points`` at most
        :data:`MAX_PROTOCOL_POINTS`).
    alpha : float
        Parallax factor ``||t|| / ||t||max`` (0 to :data:`MAX_ALPHA`; the paper uses 1e-3 ...
        1, 0 is pure rotation with ``t`` exactly zero).
    noise_px : float
        Standard deviation (pixels, 0 to :data:`MAX_NOISE_PX`) of the Gaussian noise added to
        every coordinate.
    depth : float, default 30.0
        Scene depth ``d`` in metres (in :data:`DEPTH_RANGE`; the paper uses 30, 50 and 80).
    seed : int, default 0
        Seed of points and poses (non-negative).
    mc_run : int, default 0
        Index of the Monte-Carlo noise realisation (non-negative).
    shared_points : bool, default True
        One point cloud for all poses (as in the paper) if True, a fresh cloud per pose if
        False.

    Returns
    -------
    ProtocolSample
        Pixel points of shape (n_poses, n_points, 2), noise-free versions, 3D points in
        camera 1 of shape (n_poses, n_points, 3), ``R`` (n_poses, 3, 3), ``t`` (n_poses, 3)
        and ``K`` (3, 3), with ``x2 = R x1 + t``.

    Examples
    --------
    >>> s = paper_protocol(200, 50, alpha=0.2, noise_px=1.0, seed=1)
    >>> s.points1.shape, s.R.shape, s.t.shape
    ((200, 50, 2), (200, 3, 3), (200, 3))
    """
    n_poses = _check_count("n_poses", n_poses, 1)
    n_points = _check_count("n_points", n_points, 1)
    if n_poses * n_points > MAX_PROTOCOL_POINTS:
        raise ValueError(
            f"n_poses * n_points must be at most {MAX_PROTOCOL_POINTS}, got {n_poses} * {n_points}"
        )
    alpha = _check_real("alpha", alpha, 0.0, MAX_ALPHA)
    noise_px = _check_real("noise_px", noise_px, 0.0, MAX_NOISE_PX)
    depth = _check_real("depth", depth, DEPTH_RANGE[0], DEPTH_RANGE[1])
    seed = _check_count("seed", seed, 0)
    mc_run = _check_count("mc_run", mc_run, 0)
    shared_points = as_flag(shared_points, "shared_points")

    rng_points = np.random.default_rng([seed, 0, int(shared_points)])
    rng_euler = np.random.default_rng([seed, 1])
    rng_phi = np.random.default_rng([seed, 3])
    rng_noise = np.random.default_rng([seed, 2, mc_run])

    half = np.array([PAPER_BOX[0] / 2, PAPER_BOX[1] / 2, depth / 2])
    centre = np.array([0.0, 0.0, depth])
    n_clouds = 1 if shared_points else n_poses
    unit = rng_points.random((n_clouds, n_points, 3))
    X = centre + (2.0 * unit - 1.0) * half
    X = np.broadcast_to(X, (n_poses, n_points, 3)).copy()

    euler = rng_euler.standard_normal((n_poses, 3)) * np.asarray(PAPER_EULER_SIGMA_DEG)
    phi = rng_phi.uniform(0.0, 2.0 * np.pi, n_poses)
    R = euler_to_matrix(euler)
    direction = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=-1)
    centre2 = alpha * PAPER_T_MAX * direction
    t = -np.einsum("nij,nj->ni", R, centre2)
    if alpha == 0.0:
        t = np.zeros_like(t)

    K = PAPER_K.copy()
    X2 = np.einsum("nij,npj->npi", R, X) + t[:, None, :]
    p1 = _project(K, X)
    p2 = _project(K, X2)
    noise = rng_noise.standard_normal((2, n_poses, n_points, 2)) * noise_px
    return ProtocolSample(
        points1=p1 + noise[0],
        points2=p2 + noise[1],
        points1_clean=p1,
        points2_clean=p2,
        points3d=X,
        R=R,
        t=t,
        K=K,
        euler_deg=euler,
        alpha=alpha,
        noise_px=noise_px,
        depth=depth,
        seed=seed,
        mc_run=mc_run,
    )
