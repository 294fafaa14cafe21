"""Exact ray-casting renderer of planar scenes, with supersampling anti-aliasing.

Camera model: a point ``X`` (camera-1 coordinates) is ``Xc = Rc X + tc`` in camera ``c`` and
projects to the pixel ``K (x', y', 1)`` where ``(x', y')`` is ``(Xc_x / Xc_z, Xc_y / Xc_z)``
distorted by the OpenCV lens model (``cv2.projectPoints``) when distortion coefficients are
given. Pixel centres are at integer coordinates (OpenCV convention).

Ray casting: every quad ``P(s, q) = O + s U + q V`` maps to camera ``c`` by
``z (x, y, 1)^T = G (s, q, 1)^T`` with ``G = [Rc U, Rc V, Rc O + tc]`` (``tc`` dropped for a
quad at infinity). Hence ``(s, q, 1) w = G^-1 (x, y, 1)^T`` and the depth of the hit is
``z = 1 / w``: each sample needs three dot products and a division per quad, with no
approximation. The nearest hit wins (z-buffer); the texture is sampled bilinearly from the
pyramid level matching the sample footprint (trilinear filtering), then ``n x n`` samples per
pixel are box-averaged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ppo_cv.checks import as_finite_array, as_image_size, as_matrix3, as_vector3
from ppo_cv.result import compact_repr

from .scenes import Quad, Scene

__all__ = ["RenderedPair", "median_depth", "project_points", "render_pair", "render_view"]

BACKGROUND = 0.5
TINY_W = np.float32(1e-30)
_REMAP_COLS = 4096
_LATTICE = 33


@dataclass(frozen=True, repr=False)
class RenderedPair:
    """Two rendered views with exact ground truth.

    Its ``repr`` is one line, the images and depth map by their shape
    (:func:`ppo_cv.result.compact_repr`).

    Attributes
    ----------
    image1, image2 : ndarray, shape (H, W, 3), uint8
        RGB images.
    K1, K2 : ndarray, shape (3, 3), float64
        Intrinsics.
    R : ndarray, shape (3, 3), float64
        Rotation, ``x2 = R x1 + t`` (camera coordinates, as ``cv2.recoverPose``).
    t : ndarray, shape (3,), float64
        Translation (metres; exactly zero for pure rotation).
    depth1 : ndarray, shape (H, W), float32
        Z coordinate in camera 1 of the surface seen at each pixel centre of view 1 (``inf``
        for the backdrop at infinity or empty background; NaN where unknown, as in pairs
        warped from photos).
    dist1, dist2 : ndarray, shape (k,), float64
        OpenCV distortion coefficients of each view (empty if none).
    params : dict
        Scene, motion and rendering parameters (JSON-serialisable).
    K1_given, K2_given : ndarray, shape (3, 3), float64
        The intrinsics an estimator is told (a focal length a few percent off for imperfect
        pairs, see :class:`ppo_cv.data_gen.Imperfections`); ``K1``, ``K2`` by default.
    """

    image1: np.ndarray
    image2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    R: np.ndarray
    t: np.ndarray
    depth1: np.ndarray
    dist1: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dist2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    params: dict = field(default_factory=dict)
    K1_given: np.ndarray | None = None
    K2_given: np.ndarray | None = None

    def __repr__(self) -> str:
        return compact_repr(self)

    def __post_init__(self) -> None:
        for name in ("K1", "K2"):
            object.__setattr__(self, name, as_matrix3(getattr(self, name), name).copy())
        for name, true in (("K1_given", self.K1), ("K2_given", self.K2)):
            given = getattr(self, name)
            value = true.copy() if given is None else as_matrix3(given, name).copy()
            object.__setattr__(self, name, value)


def _check_matrix(name: str, value, shape: tuple) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite")
    return array


def _check_intrinsics(name: str, K) -> np.ndarray:
    K = _check_matrix(name, K, (3, 3))
    if K[0, 0] <= 0 or K[1, 1] <= 0 or np.any(K[1:, 0] != 0) or K[2, 1] != 0 or K[2, 2] != 1:
        raise ValueError(f"{name} must be upper triangular with fx, fy > 0 and K[2, 2] = 1")
    return K


def _check_rotation(R) -> np.ndarray:
    R = _check_matrix("R", R, (3, 3))
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise ValueError("R must be a rotation matrix (orthonormal, det +1)")
    return R


def _check_dist(name: str, dist) -> np.ndarray:
    if dist is None:
        return np.zeros(0)
    dist = np.asarray(dist, dtype=np.float64).ravel()
    if dist.size not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
        raise ValueError(f"{name} must hold 4, 5, 8, 12 or 14 finite OpenCV coefficients")
    return dist


MIN_SIDE, MAX_SIDE = 8, 8192
"""Smallest and largest image side a render takes (pixels)."""


def _check_size(size) -> tuple[int, int]:
    """``(width, height)``, whole numbers of pixels in ``MIN_SIDE..MAX_SIDE``."""
    try:
        return as_image_size(size, "size", MIN_SIDE, MAX_SIDE)
    except ValueError as error:
        raise ValueError(f"{error} pixels") from None


class _Grid:
    """The ``n x n``-per-pixel sample grid of one view.

    Sample ``(a, b)`` of pixel ``(i, j)`` sits at the pixel position
    ``(j - 0.5 + (b + 0.5) / n, i - 0.5 + (a + 0.5) / n)``: a regular grid whose box average
    is the pixel's area integral. Without distortion a linear form of the normalised
    coordinates ``(x, y, 1)`` is a separable sum over columns and rows; with distortion the
    undistorted ``(x, y)`` of every sample are computed with ``cv2.undistortPoints`` iterated to
    convergence.
    """

    def __init__(self, K: np.ndarray, size: tuple[int, int], n: int, dist: np.ndarray) -> None:
        width, height = size
        self.K, self.n = K, n
        self.shape = (height * n, width * n)
        self.us = (np.arange(width * n, dtype=np.float64) + 0.5) / n - 0.5
        self.vs = (np.arange(height * n, dtype=np.float64) + 0.5) / n - 0.5
        self.dense = dist.size > 0 and bool(np.any(dist))
        if self.dense:
            grid = np.stack(np.meshgrid(self.us, self.vs), axis=-1).reshape(-1, 1, 2)
            criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)
            xy = cv2.undistortPoints(grid, K, dist, criteria=criteria).reshape(*self.shape, 2)
            self.x = np.ascontiguousarray(xy[..., 0], dtype=np.float32)
            self.y = np.ascontiguousarray(xy[..., 1], dtype=np.float32)

    def _pixel_form(self, row: np.ndarray) -> tuple[float, float, float]:
        """``row . (x, y, 1) = A u + B v + C`` for the pinhole ``(x, y, 1) = K^-1 (u, v, 1)``."""
        K = self.K
        A = row[0] / K[0, 0]
        B = (row[1] - row[0] * K[0, 1] / K[0, 0]) / K[1, 1]
        return A, B, row[2] - A * K[0, 2] - B * K[1, 2]

    def linear(self, row: np.ndarray, win: tuple[int, int, int, int]) -> np.ndarray:
        """``row . (x, y, 1)`` over the window ``(r0, r1, c0, c1)``, float32."""
        r0, r1, c0, c1 = win
        if self.dense:
            x, y = self.x[r0:r1, c0:c1], self.y[r0:r1, c0:c1]
            return np.float32(row[0]) * x + np.float32(row[1]) * y + np.float32(row[2])
        A, B, C = self._pixel_form(row)
        cols = (A * self.us[c0:c1]).astype(np.float32)
        rows = (B * self.vs[r0:r1] + C).astype(np.float32)
        return np.add.outer(rows, cols)

    def window(self, corners_cam: np.ndarray) -> tuple[int, int, int, int] | None:
        """Sample window covering a convex polygon given in camera coordinates, or None."""
        poly = _clip_near(corners_cam)
        if poly is None:
            return None
        if self.dense:
            return (0, self.shape[0], 0, self.shape[1])
        pix = poly @ self.K.T
        pix = pix[:, :2] / pix[:, 2:3]
        lo = np.floor((pix.min(axis=0) + 0.5) * self.n - 0.5) - 1
        hi = np.ceil((pix.max(axis=0) + 0.5) * self.n - 0.5) + 2
        c0, c1 = (int(np.clip(v, 0, self.shape[1])) for v in (lo[0], hi[0]))
        r0, r1 = (int(np.clip(v, 0, self.shape[0])) for v in (lo[1], hi[1]))
        if r1 <= r0 or c1 <= c0:
            return None
        return (r0, r1, c0, c1)


def _clip_near(poly: np.ndarray, near: float = 1e-6) -> np.ndarray | None:
    """Part of a convex polygon (m, 3) with ``z >= near * scale`` (Sutherland-Hodgman)."""
    scale = max(float(np.abs(poly).max()), 1e-12)
    z = poly[:, 2] - near * scale
    inside = z >= 0
    if inside.all():
        return poly
    if not inside.any():
        return None
    out = []
    for i in range(len(poly)):
        j = (i + 1) % len(poly)
        if inside[i]:
            out.append(poly[i])
        if inside[i] != inside[j]:
            out.append(poly[i] + (poly[j] - poly[i]) * (z[i] / (z[i] - z[j])))
    return np.array(out)


def _quad_inverse(quad: Quad, Rc: np.ndarray, tc: np.ndarray) -> tuple:
    """``G^-1`` (None if seen edge-on), ``G`` and the corners in camera coordinates."""
    offset = Rc @ quad.origin + (0.0 if quad.at_infinity else tc)
    G = np.column_stack([Rc @ quad.u, Rc @ quad.v, offset])
    corners = np.stack([offset, offset + G[:, 0], offset + G[:, 0] + G[:, 1], offset + G[:, 1]])
    if np.linalg.cond(G) > 1e10:
        return None, G, corners
    return np.linalg.inv(G), G, corners


def _trace(scene: Scene, grid: _Grid, Rc: np.ndarray, tc: np.ndarray):
    """Nearest quad of every sample.

    Returns
    -------
    owner : int16 (H n, W n), quad index or -1
    wbuf : float32 (H n, W n), inverse depth ``w = 1 / z`` (``TINY_W``: at infinity, 0: none)
    s, q : float32 (H n, W n), quad coordinates of the hit
    matrices : list of ``G`` per quad
    """
    owner = np.full(grid.shape, -1, np.int16)
    wbuf = np.zeros(grid.shape, np.float32)
    sbuf = np.zeros(grid.shape, np.float32)
    qbuf = np.zeros(grid.shape, np.float32)
    matrices = []
    for index, quad in enumerate(scene.quads):
        Ginv, G, corners = _quad_inverse(quad, Rc, tc)
        matrices.append(G)
        win = None if Ginv is None else grid.window(corners)
        if win is None:
            continue
        r0, r1, c0, c1 = win
        w = grid.linear(Ginv[2], win)
        a = grid.linear(Ginv[0], win)
        b = grid.linear(Ginv[1], win)
        wb = wbuf[r0:r1, c0:c1]
        if quad.at_infinity:
            hit = (w > 0) & (wb < TINY_W)
        else:
            hit = w > wb
        hit &= (a >= 0) & (a <= w) & (b >= 0) & (b <= w)
        np.divide(a, w, out=sbuf[r0:r1, c0:c1], where=hit)
        np.divide(b, w, out=qbuf[r0:r1, c0:c1], where=hit)
        np.copyto(wb, TINY_W if quad.at_infinity else w, where=hit)
        np.copyto(owner[r0:r1, c0:c1], np.int16(index), where=hit)
    return owner, wbuf, sbuf, qbuf, matrices


def _remap(image: np.ndarray, tx: np.ndarray, ty: np.ndarray, wrap: bool) -> np.ndarray:
    """Bilinear lookup of ``image`` at 1-D texel coordinates; returns (m, channels)."""
    m = tx.size
    rows = -(-m // _REMAP_COLS)
    mx = np.zeros(rows * _REMAP_COLS, np.float32)
    my = np.zeros(rows * _REMAP_COLS, np.float32)
    mx[:m], my[:m] = tx, ty
    mx, my = mx.reshape(rows, _REMAP_COLS), my.reshape(rows, _REMAP_COLS)
    border = cv2.BORDER_WRAP if wrap else cv2.BORDER_REFLECT
    chunks = [
        cv2.remap(image, mx[r : r + 4096], my[r : r + 4096], cv2.INTER_LINEAR, borderMode=border)
        for r in range(0, rows, 4096)
    ]
    channels = image.shape[2] if image.ndim == 3 else 1
    return np.concatenate(chunks).reshape(-1, channels)[:m]


def _level_lattice(quad: Quad, G: np.ndarray, K: np.ndarray, n: int) -> np.ndarray:
    """Pyramid level on a regular lattice of quad coordinates, shape (L, L) float32.

    The level is ``log2`` of the footprint of one sample in level-0 texels (the longer axis of
    the footprint), from the Jacobian of the homography ``(x, y) -> (s, q)``:
    ``ds/dx = (Gi_00 - s Gi_20) z`` etc., with ``Gi = G^-1`` and ``z = G_20 s + G_21 q + G_22``.
    Lattice points behind the camera get the coarsest level.
    """
    tw, th = quad.texture.size
    s0, q0, s1, q1 = quad.uv
    sx, qy = (s1 - s0) * tw, (q1 - q0) * th
    top = len(quad.texture.levels) - 1
    Gi = np.linalg.inv(G)
    q, s = np.meshgrid(np.linspace(0, 1, _LATTICE), np.linspace(0, 1, _LATTICE), indexing="ij")
    z = G[2, 0] * s + G[2, 1] * q + G[2, 2]
    zu, zv = z / (K[0, 0] * n), z / (K[1, 1] * n)
    ds_du = (Gi[0, 0] - s * Gi[2, 0]) * zu * sx
    dq_du = (Gi[1, 0] - q * Gi[2, 0]) * zu * qy
    ds_dv = (Gi[0, 1] - s * Gi[2, 1]) * zv * sx
    dq_dv = (Gi[1, 1] - q * Gi[2, 1]) * zv * qy
    footprint2 = np.maximum(ds_du**2 + dq_du**2, ds_dv**2 + dq_dv**2)
    level = 0.5 * np.log2(np.maximum(footprint2, 1e-12))
    level = np.where(z > 0, level, top)
    return np.clip(level, 0.0, top).astype(np.float32)


def _shade(
    quad: Quad, G: np.ndarray, s: np.ndarray, q: np.ndarray, K: np.ndarray, n: int
) -> np.ndarray:
    """Trilinearly filtered texture colour (0-255, float32, shape (m, 3)) of hits ``(s, q)``.

    The pyramid level comes from :func:`_level_lattice`, interpolated bilinearly at ``(s, q)``.
    """
    tw, th = quad.texture.size
    s0, q0, s1, q1 = quad.uv
    sx, qy = np.float32((s1 - s0) * tw), np.float32((q1 - q0) * th)
    top = len(quad.texture.levels) - 1
    lattice = _level_lattice(quad, G, K, n)
    span = np.float32(_LATTICE - 1)
    level = _remap(lattice, s * span, q * span, False)[:, 0]
    tx = np.float32(s0 * tw) + s * sx
    ty = np.float32(q0 * th) + q * qy
    base = np.floor(level)
    lo, hi = int(base.min()), min(int(base.max()) + 1, top)
    if lo == hi or not np.any(level > lo):
        scale = np.float32(2.0**-lo)
        return _remap(quad.texture.levels[lo], (tx - 0.5) * scale, (ty - 0.5) * scale,
                      quad.texture.wrap).astype(np.float32)  # fmt: skip
    # trilinear: every sample blends levels base and base + 1; sorting the samples by base
    # makes each level's samples one contiguous run of the sorted order
    order = np.argsort(base.astype(np.int8), kind="stable")
    base, frac = base[order], (level - base)[order]
    tx, ty = tx[order] - np.float32(0.5), ty[order] - np.float32(0.5)
    starts = np.searchsorted(base, np.arange(lo, hi + 2))
    sorted_colour = np.zeros((s.size, 3), np.float32)
    for lev in range(lo, hi + 1):
        i0, i1 = starts[max(lev - 1 - lo, 0)], starts[lev - lo + 1]
        if i1 <= i0:
            continue
        weight = frac[i0:i1].copy()
        weight[base[i0:i1] == lev] = 1.0 - weight[base[i0:i1] == lev]
        scale = np.float32(2.0**-lev)
        texels = _remap(quad.texture.levels[lev], tx[i0:i1] * scale, ty[i0:i1] * scale,
                        quad.texture.wrap)  # fmt: skip
        sorted_colour[i0:i1] += cv2.merge([weight] * 3).reshape(-1, 3) * texels
    colour = np.empty_like(sorted_colour)
    colour[order] = sorted_colour
    return colour


def render_view(
    scene: Scene,
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    size: tuple[int, int] = (640, 480),
    supersample: int = 3,
    dist: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Render ``scene`` seen by the camera ``Xc = R X + t``.

    Parameters
    ----------
    scene : Scene
    K : array_like, shape (3, 3)
        Intrinsics.
    R : array_like, shape (3, 3)
    t : array_like, shape (3,)
        Pose of the camera relative to camera 1 (``(I, 0)`` renders view 1).
    size : (int, int), default (640, 480)
        Width and height in pixels.
    supersample : int, default 3
        Samples per pixel along each axis (``n x n`` regular grid, box filtered).
    dist : array_like, optional
        OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3[, ...]])``.

    Returns
    -------
    image : ndarray, shape (H, W, 3), float32
        Linear RGB in [0, 1].
    depth : ndarray, shape (H, W), float32
        Z in this camera of the surface seen at each pixel centre (``inf`` if none or at
        infinity).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a Scene, got {type(scene).__name__}")
    K = _check_intrinsics("K", K)
    R = _check_rotation(R)
    t = _check_matrix("t", np.asarray(t, dtype=np.float64).reshape(-1), (3,))
    width, height = _check_size(size)
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)):
        raise TypeError("supersample must be an integer")
    if not 1 <= supersample <= 8:
        raise ValueError(f"supersample must be in 1..8, got {supersample}")
    dist = _check_dist("dist", dist)
    n = int(supersample)

    owner, wbuf, sbuf, qbuf, matrices = _trace(scene, _Grid(K, (width, height), n, dist), R, t)
    colour = np.full(owner.shape + (3,), BACKGROUND, np.float32)
    flat_owner, flat_colour = owner.ravel(), colour.reshape(-1, 3)
    order = np.argsort(flat_owner, kind="stable")
    bounds = np.searchsorted(flat_owner[order], np.arange(len(scene.quads) + 1))
    for index, quad in enumerate(scene.quads):
        idx = order[bounds[index] : bounds[index + 1]]
        if idx.size:
            s, q = sbuf.ravel()[idx], qbuf.ravel()[idx]
            flat_colour[idx] = _shade(quad, matrices[index], s, q, K, n) * np.float32(1 / 255)
    image = cv2.resize(colour, (width, height), interpolation=cv2.INTER_AREA) if n > 1 else colour

    if n % 2 == 1:
        w = wbuf[n // 2 :: n, n // 2 :: n]
    else:
        w = _trace(scene, _Grid(K, (width, height), 1, dist), R, t)[1]
    with np.errstate(divide="ignore"):
        depth = np.where(w > TINY_W, np.float32(1.0) / w, np.float32(np.inf))
    return image, depth.astype(np.float32)


def median_depth(
    scene: Scene, K: np.ndarray, size: tuple[int, int], dist: np.ndarray | None = None
) -> float:
    """Median Z of the finite-depth surfaces seen at the pixel centres of the camera ``(I, 0)``.

    The same ray casting as :func:`render_view` (one sample per pixel centre). Raises
    ValueError if the camera sees no surface at a finite distance.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a Scene, got {type(scene).__name__}")
    grid = _Grid(_check_intrinsics("K", K), _check_size(size), 1, _check_dist("dist", dist))
    w = _trace(scene, grid, np.eye(3), np.zeros(3))[1]
    seen = w[w > TINY_W]
    if seen.size == 0:
        raise ValueError(f"scene {scene.name!r} has no surface at a finite distance in view")
    return float(np.median(np.float32(1.0) / seen))


def _finish(
    image: np.ndarray, blur_sigma: float, noise_std: float, rng: np.random.Generator
) -> np.ndarray:
    """Blur (Gaussian, ``blur_sigma`` px), add noise (``noise_std`` grey levels), quantise."""
    image = image * np.float32(255.0)
    if blur_sigma > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_sigma, borderType=cv2.BORDER_REFLECT)
    if noise_std > 0:
        image = image + rng.standard_normal(image.shape, dtype=np.float32) * np.float32(noise_std)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def render_pair(
    scene: Scene,
    K1: np.ndarray,
    K2: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    size: tuple[int, int] = (640, 480),
    supersample: int = 3,
    dist1: np.ndarray | None = None,
    dist2: np.ndarray | None = None,
    noise_std: float = 0.0,
    blur_sigma: float = 0.0,
    seed: int | tuple = 0,
    params: dict | None = None,
) -> RenderedPair:
    """Render views 1 (``(I, 0)``) and 2 (``x2 = R x1 + t``) of ``scene``.

    Parameters
    ----------
    scene : Scene
    K1, K2 : array_like, shape (3, 3)
        Intrinsics of each view.
    R : array_like, shape (3, 3)
    t : array_like, shape (3,)
        Relative pose, ``x2 = R x1 + t`` in camera coordinates.
    size : (int, int), default (640, 480)
        Width and height of both images.
    supersample : int, default 3
        Anti-aliasing samples per pixel along each axis.
    dist1, dist2 : array_like, optional
        OpenCV distortion coefficients of each view.
    noise_std : float, default 0
        Standard deviation of additive Gaussian noise, in grey levels (0-255).
    blur_sigma : float, default 0
        Standard deviation (pixels) of a Gaussian blur applied before the noise.
    seed : int or sequence of int, default 0
        Seed of the photometric noise.
    params : dict, optional
        Extra parameters to record in the result.

    Returns
    -------
    RenderedPair
    """
    for name, value in (("noise_std", noise_std), ("blur_sigma", blur_sigma)):
        if not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
    K1 = _check_intrinsics("K1", K1)
    K2 = _check_intrinsics("K2", K2)
    R = _check_rotation(R)
    t = _check_matrix("t", np.asarray(t, dtype=np.float64).reshape(-1), (3,))
    dist1, dist2 = _check_dist("dist1", dist1), _check_dist("dist2", dist2)
    image1, depth1 = render_view(scene, K1, np.eye(3), np.zeros(3), size, supersample, dist1)
    image2, _ = render_view(scene, K2, R, t, size, supersample, dist2)
    rng = np.random.default_rng([*np.atleast_1d(seed).tolist(), 7])
    record = {
        "scene": scene.name,
        "scene_params": scene.params,
        "size": list(_check_size(size)),
        "supersample": int(supersample),
        "noise_std": float(noise_std),
        "blur_sigma": float(blur_sigma),
    }
    record.update(params or {})
    return RenderedPair(
        image1=_finish(image1, blur_sigma, noise_std, rng),
        image2=_finish(image2, blur_sigma, noise_std, rng),
        K1=K1,
        K2=K2,
        R=R,
        t=t.copy(),
        depth1=depth1,
        dist1=dist1,
        dist2=dist2,
        params=record,
    )


def project_points(
    X: np.ndarray, K: np.ndarray, R: np.ndarray | None = None, t: np.ndarray | None = None,
    dist: np.ndarray | None = None,
) -> np.ndarray:  # fmt: skip
    """Pixels of 3D points ``X`` (camera-1 coordinates, shape (m, 3)) in camera ``(R, t)``.

    Uses ``cv2.projectPoints``, i.e. the same camera model as :func:`render_view`; returns
    shape (m, 2) float64.
    """
    X = as_finite_array(X, "X")
    if X.ndim not in (1, 2) or X.shape[-1] != 3:
        raise ValueError(f"X must have shape (m, 3), got {X.shape}")
    X = X.reshape(-1, 3)
    R = np.eye(3) if R is None else _check_rotation(R)
    t = np.zeros(3) if t is None else as_vector3(t, "t")
    rvec = cv2.Rodrigues(R)[0]
    dist = _check_dist("dist", dist)
    pts = cv2.projectPoints(X, rvec, t, _check_intrinsics("K", K), dist if dist.size else None)[0]
    return pts.reshape(-1, 2)
