"""Pairs with the imperfections of real photos, for the pure-rotation tests and benchmark.

- :func:`warped_rotation_pair`: two narrow-field views cut from one photo by ``K R K^-1`` (an
  exact pure rotation with real image statistics), with radial distortion nobody models.
- :func:`imperfect_render`: a rendered pair (pure rotation or a given baseline / depth) with a
  narrow field, radial distortion, noise and JPEG.

Both return the intrinsics to give the estimator: the focal length scaled by ``focal_error``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class ImperfectPair:
    image1: np.ndarray  # BGR uint8
    image2: np.ndarray
    K_given: np.ndarray  # intrinsics given to the estimator (focal off by focal_error)
    R: np.ndarray  # ground truth, x2 = R x1 + t
    t: np.ndarray
    k1: float
    focal_error: float
    hfov_deg: float
    baseline_ratio: float  # |baseline| / scene depth, 0 for a pure rotation


def _rotation(yaw_deg: float, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> np.ndarray:
    y, p, r = np.radians([yaw_deg, pitch_deg, roll_deg])
    Ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(p), -np.sin(p)], [0, np.sin(p), np.cos(p)]])
    Rz = np.array([[np.cos(r), -np.sin(r), 0], [np.sin(r), np.cos(r), 0], [0, 0, 1]])
    return Rz @ Rx @ Ry


def _virtual_K(size: tuple[int, int], hfov_deg: float) -> np.ndarray:
    w, h = size
    f = 0.5 * w / np.tan(np.radians(hfov_deg) / 2)
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def _undistort_normalised(xd: np.ndarray, k1: float) -> np.ndarray:
    x = xd.copy()
    for _ in range(10):
        x = xd / (1.0 + k1 * np.sum(x * x, axis=-1, keepdims=True))
    return x


def _view(photo, K_photo, M, K, k1, size):
    """View with rays ``d = M d_photo`` through a camera ``K`` with radial ``k1``."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    xd = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]], axis=-1)
    x = _undistort_normalised(xd, k1)
    rays = np.concatenate([x, np.ones((h, w, 1))], axis=-1) @ M  # M^T d, row vectors
    pix = rays @ K_photo.T
    map_x = (pix[..., 0] / pix[..., 2]).astype(np.float32)
    map_y = (pix[..., 1] / pix[..., 2]).astype(np.float32)
    return cv2.remap(photo, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    return cv2.imdecode(data, cv2.IMREAD_COLOR)


def warped_rotation_pair(
    photo: np.ndarray,
    K_photo: np.ndarray,
    seed: int,
    *,
    size: tuple[int, int] = (480, 360),
    hfov_range: tuple[float, float] = (25.0, 35.0),
    angle_range: tuple[float, float] = (8.0, 20.0),
    k1_range: tuple[float, float] = (0.02, 0.1),
    focal_error: float = 0.03,
    jpeg_quality: tuple[int, int] = (75, 95),
) -> ImperfectPair:
    """Exact pure rotation cut from ``photo`` (BGR, pinhole ``K_photo``) with imperfections.

    The two views turn by ``+-angle/2`` about a random axis near the vertical, so both stay
    inside the photo's field; the estimator is to be given ``K_given`` whose focal is off by up
    to ``focal_error`` (relative), and neither view's distortion.
    """
    rng = np.random.default_rng([seed, 10])
    hfov = rng.uniform(*hfov_range)
    angle = rng.uniform(*angle_range) * rng.choice([-1.0, 1.0])
    tilt, roll = rng.normal(0.0, abs(angle) / 6.0), rng.normal(0.0, 2.0)
    k1 = rng.uniform(*k1_range) * rng.choice([-1.0, 1.0])
    scale = 1.0 + rng.uniform(-focal_error, focal_error)
    K = _virtual_K(size, hfov)
    M1 = _rotation(-angle / 2, -tilt / 2, -roll / 2)
    M2 = _rotation(angle / 2, tilt / 2, roll / 2)
    quality = int(rng.integers(*jpeg_quality))
    image1 = _jpeg(_view(photo, K_photo, M1, K, k1, size), quality)
    image2 = _jpeg(_view(photo, K_photo, M2, K, k1, size), quality)
    K_given = K.copy()
    K_given[0, 0] *= scale
    K_given[1, 1] *= scale
    return ImperfectPair(
        image1, image2, K_given, M2 @ M1.T, np.zeros(3), k1, scale - 1.0, hfov, 0.0
    )


def imperfect_render(
    seed: int,
    baseline_ratio: float = 0.0,
    *,
    size: tuple[int, int] = (480, 360),
    scene: str | None = None,
    k1_range: tuple[float, float] = (0.02, 0.1),
    focal_error: float = 0.03,
) -> ImperfectPair:
    """Rendered pair, pure rotation (``baseline_ratio = 0``) or a baseline of that many depths.

    Narrow field (25-35 deg), one radial ``k1`` for both views, focal given off by up to
    ``focal_error``, grey-level noise 2, JPEG 75-95. The translation is sideways-dominant in a
    random direction, ``|C2| = baseline_ratio`` times the median depth seen by view 1 (the
    label of the pure-rotation flag); the rotation is 5-20 deg of pan (pure rotation) or 2-10 deg.
    """
    from ppo_cv.data_gen.render import median_depth, render_pair
    from ppo_cv.data_gen.scenes import make_scene

    rng = np.random.default_rng([seed, 20])
    names = ("room", "clutter", "plane", "backdrop") if baseline_ratio == 0 else ("room", "clutter")
    world = make_scene(scene or names[seed % len(names)], rng)
    hfov = rng.uniform(25.0, 35.0)
    K = _virtual_K(size, hfov)
    if baseline_ratio == 0:
        R = _rotation(rng.uniform(5, 20) * rng.choice([-1, 1]), rng.normal(0, 2), rng.normal(0, 2))
        t = np.zeros(3)
    else:
        R = _rotation(rng.uniform(2, 10) * rng.choice([-1, 1]), rng.normal(0, 2), rng.normal(0, 2))
        direction = rng.normal(size=3) * np.array([1.0, 0.5, 0.5])
    k1 = rng.uniform(*k1_range) * rng.choice([-1.0, 1.0])
    dist = np.array([k1, 0.0, 0.0, 0.0, 0.0])
    if baseline_ratio != 0:
        depth = median_depth(world, K, size, dist)
        t = -R @ (baseline_ratio * depth * direction / np.linalg.norm(direction))
    pair = render_pair(
        world, K, K, R, t, size, 2, dist1=dist, dist2=dist, noise_std=2.0, seed=[seed, 21]
    )
    quality = int(rng.integers(75, 95))
    scale = 1.0 + rng.uniform(-focal_error, focal_error)
    K_given = K.copy()
    K_given[0, 0] *= scale
    K_given[1, 1] *= scale
    image1 = _jpeg(np.ascontiguousarray(pair.image1[:, :, ::-1]), quality)
    image2 = _jpeg(np.ascontiguousarray(pair.image2[:, :, ::-1]), quality)
    return ImperfectPair(
        image1, image2, K_given, R, t, k1, scale - 1.0, hfov, float(baseline_ratio)
    )
