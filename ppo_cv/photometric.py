"""Sub-pixel tracks of a pure rotation from the image intensities.

Feature matches locate a point to a few tenths of a pixel, and in a narrow field the focal length
and the rotation angle trade off (the image moves by about ``f x angle`` either way): a few
hundred matches leave the rotation of a pure rotation 0.1-0.5 degrees uncertain
(:attr:`ppo_cv.rotation.LensRotationFit.rotation_sigma_deg`). Once a pair is judged a pure
rotation, the lens rotation (:func:`ppo_cv.rotation.fit_rotation_lens`) says where every pixel of
image 1 lands in image 2, and the intensities fix it far better:

1. corners of image 1 (the minimum eigenvalue of the gradient structure tensor, Shi and Tomasi,
   "Good features to track", CVPR 1994) whose window the model maps inside image 2;
2. each window aligned with image 2 seen through the model, up to a shift ``d`` (pixels of
   image 2): ``min sum_k (g_k I2(T(p + o_k) + d) + b - I1(p + o_k))^2`` over the window's pixels
   ``o_k``, with ``T`` the model's pixel transfer, ``b`` an offset and a gain ``g_k = g0 + g . o_k``
   that may vary linearly across the window (exposure changes, vignetting); pixels within two
   of one clipped at white in either image are left out (:data:`SATURATED`). The model carries
   each window's rotation, scale and distortion, so only a small shift is left to estimate.
   First the search: image 2 is warped once into image 1's frame through the model, both
   images are normalised by their local mean and deviation (no exposure or vignetting left
   between them), and pyramidal Lucas-Kanade (``cv2.calcOpticalFlowPyrLK``, translation only)
   covers the few pixels the model is off at first, to a few hundredths of a pixel. Then the
   polish of the full objective from there: the gain and offset fitted in closed form, and
   damped Gauss-Newton steps of the shift and brightness together (Lucas-Kanade; the
   brightness terms as in Baker, Gross and Matthews, "Lucas-Kanade 20 years on", part 3,
   CMU-RI-TR-03-35), the Jacobian of the start reused and taken again where it led. All
   windows are solved at once
   (arrays of windows x window pixels), with exact bilinear interpolation; each window's
   pixels are transferred through the model by interpolating its exact transfer at 5 x 5
   points;
3. the lens rotation refitted on the tracks, outliers (moving objects, occlusions, windows that
   did not converge) dropped beyond ``3 sqrt(2)`` times the tracks' own noise per coordinate
   (the 2D residual of an inlier exceeds it with probability ``exp(-9)``); then the windows
   are searched again at full size in image 2 seen through the refitted model, and the fit
   repeated. When the search's tracks are too rough for the first fit (a narrow strip of
   overlap, shots a stop apart), they are polished through the start model first. The fit's
   variances are multiplied by the windows' overlap (:func:`window_overlap`): overlapping
   windows are made of the same pixels, and their errors are not independent;
4. steps 1-3 with each window side of :data:`WINDOWS`, keeping the refit whose rotation is
   the least uncertain: large windows locate tracks better in noisy images, small ones are
   more numerous in weak texture;
5. the windows of that side polished through its fit, from where the search found them, and
   the fit repeated; the next side too while its searched bound is below the polished one,
   the least uncertain polished refit kept. The search is the cheap part (a few tens of
   milliseconds for both sides), the polish the accurate one (on the demo frame warped by a
   rotation the rotation error of the search alone was 0.02-0.05 degrees, 0.001-0.04
   polished); on the sets of ``benchmarks/pure_rotation.py`` checked (56 pairs) one side was
   polished every time.

On renders and warped photos with the imperfections of real ones (distortion, focal 3 % off,
JPEG) this brings the median rotation error of each set of exact pure rotations in full overlap
from 0.02-0.18 to 0.00-0.05 degrees (0.07 with sensor noise and blur), in narrow overlaps as
stitched from 0.25 to 0.09, and from 0.12 to 0.07 against the rotation fitted with an exact given
focal (``docs/pure_rotation.md``, made by ``benchmarks/pure_rotation.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .camera import normalized_to_pixels, pixels_to_normalized
from .checks import as_camera_matrix, as_distortion, as_points, as_positive, as_rotation
from .features import to_gray
from .metrics import rotation_error_deg
from .model_selection import robust_sigma
from .parallax import PlaneParallax, fit_plane_parallax
from .rotation import (
    MAX_FOCAL_CHANGE,
    PRINCIPAL_BOUND,
    LensRotationFit,
    correct_points,
    fit_rotation_lens,
    transfer_points,
)

__all__ = [
    "WINDOW",
    "WINDOWS",
    "MIN_TRACKS",
    "MAX_CORNERS",
    "WindowTracks",
    "PhotometricRotation",
    "MAX_SEARCH_SIGMA_DEG",
    "align_windows",
    "refine_rotation_photometric",
    "window_overlap",
]

WINDOW = 21
"""Side (pixels) of the square window aligned around each corner by :func:`align_windows`."""

WINDOWS = (WINDOW, 31)
"""Window sides :func:`refine_rotation_photometric` searches; it polishes the side whose
searched fit has the least uncertain rotation (``rotation_sigma_deg``, the Cramer-Rao bound of
the tracks' fit with their overlap counted), another only when the polish left it more
uncertain than that side's search, and keeps the least uncertain polished refit.

Larger windows gather more gradient and locate a track better in a noisy image, smaller ones
are more numerous in a weakly textured one (the corners are spaced by a quarter window). On
``ppo_cv.data_gen``'s warped photos with sensor noise and blur (``benchmarks/pure_rotation.py``)
the median rotation error was 0.14 degrees with 21 pixels, 0.10 with 31 and 0.11 with 41, and
0.08 keeping the less uncertain of 21 and 31; 0.23, 0.16 and 0.10 on the same photos narrowly
overlapping, as stitched. On the demo frame warped by a rotation (``tests/test_photometric.py``)
31 pixels halve the tracks and the bound chooses 21 on every pair."""

MIN_TRACKS = 20
"""Fewest tracks that agree with the refitted rotation for its result to be used."""

MAX_SEARCH_SIGMA_DEG = 5.0
"""Cap of the rotation uncertainty that sizes the search (3 times it), also what the pipeline
hands over when the lens fit has none (a lens clipped to its box); a refit further than
``4 rotation_sigma_deg + 0.1`` degrees from the start is refused."""

MAX_CORNERS = 600
"""Windows aligned at most: beyond a few hundred the rotation's error is set by what the
windows share (interpolation, JPEG blocks, the lens model's residual), not by their number."""

MIN_NCC = 0.8
"""Lowest normalised cross-correlation of an aligned window with its template."""

SATURATED = 250.0
"""Grey level (of 255) from which a pixel counts as clipped at white: it takes no part in the
alignment of its window. A highlight clipped in one shot and not in the other (an exposure
that changed between the shots) breaks the gain-and-offset model, and clipped edges move
with the exposure. On warped photos up to 1 EV apart, windows holding such pixels were
located several times worse than the others (median 0.09-0.18 px against 0.02); on the demo
frame one stop brighter, leaving out the pixels within two of a clipped one brings the 90th
percentile error of those windows from 0.39 to 0.11 px
(``tests/test_photometric.py``). JPEG rings a few levels below 255 next to a clipped area,
hence the margin below 255."""

MIN_UNCLIPPED = 0.5
"""Smallest share of a window's pixels below :data:`SATURATED` in both images for a track."""

_MAX_LEVELS = 4
_ITERATIONS = 12
_CONVERGED = 1e-3  # pixels of shift update
_JACOBIANS = 2  # of the polish: at the start, and where its steps led

_DAMPING = 0.7  # of each Gauss-Newton step: the sampled gradients overshoot by about 1.4
_OUTLIER_SIGMAS = 3.0
_CONTRAST_BOX = 31  # pixels
_DENSE_STEP = 8  # pixels between exact transfers of the search's warp
_NODES = 5  # per side of a window, where _window_transfer transfers exactly
_CLIP_MARGIN = 2  # pixels: the bilinear samples and the 3x3 gradients reach past a clipped one


@dataclass(frozen=True)
class WindowTracks:
    """Windows of image 1 aligned with image 2 (:func:`align_windows`).

    Attributes
    ----------
    points1 : ndarray, shape (N, 2)
        Window centres in image 1 (pixels).
    points2 : ndarray, shape (N, 2)
        Where they were found in image 2: the transfer of ``points1`` plus the fitted shift.
    valid : ndarray of bool, shape (N,)
        Inside both images, a shift within the range the pyramid searched, well conditioned
        and ``ncc >= MIN_NCC``.
    ncc : ndarray, shape (N,)
        Normalised cross-correlation of each aligned window with its template.
    """

    points1: np.ndarray
    points2: np.ndarray
    valid: np.ndarray
    ncc: np.ndarray


@dataclass(frozen=True)
class PhotometricRotation:
    """Lens rotation refitted on intensity-aligned tracks (:func:`refine_rotation_photometric`).

    Attributes
    ----------
    fit : LensRotationFit
        Rotation, focal scale and ``k1`` over the tracks' inliers, residuals for every track.
    tracks : WindowTracks
        The tracks of the last alignment.
    inliers : ndarray of bool, shape (N,)
        Tracks used by ``fit``.
    noise_px : float
        Standard deviation of one coordinate of a track's position (pixels of image 2),
        estimated robustly from the residuals.
    window : int
        Side of the aligned windows (pixels).
    parallax : PlaneParallax or None
        The homography of the same tracks, lens corrected by ``fit``, and the parallax of its
        plane (:func:`ppo_cv.parallax.fit_plane_parallax`), its deviation multiplied by the
        square root of the windows' overlap as the fit's are; None when not measured.
        A rotation leaves it near zero; a translation before a surface that the rotation
        absorbed to a fraction of a pixel does not (:data:`ppo_cv.motion_model.MAX_TRACK_PARALLAX`).
    """

    fit: LensRotationFit
    tracks: WindowTracks
    inliers: np.ndarray
    noise_px: float
    window: int = WINDOW
    parallax: PlaneParallax | None = None

    @property
    def num_tracks(self) -> int:
        """Number of tracks used by the fit."""
        return int(np.count_nonzero(self.inliers))


def _bilinear(stack: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Channels of ``stack`` (H, W, C) float32 at points ``xy`` (n, k, 2), clamped to the image.

    Exact bilinear weights (``cv2.remap`` rounds them to 1/32 pixel, a bias that matters at the
    hundredths of a pixel sought here): the four neighbours are gathered by nearest-neighbour
    remaps at integer positions and weighted here.
    """
    import cv2

    h, w = stack.shape[:2]
    x = np.clip(xy[..., 0], 0.0, w - 1.0).astype(np.float32)
    y = np.clip(xy[..., 1], 0.0, h - 1.0).astype(np.float32)
    x0, y0 = np.minimum(np.floor(x), w - 2), np.minimum(np.floor(y), h - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]

    def gather(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return cv2.remap(stack, u, v, cv2.INTER_NEAREST).reshape(*u.shape, stack.shape[2])

    top_left, top_right = gather(x0, y0), gather(x0 + 1, y0)
    bottom_left, bottom_right = gather(x0, y0 + 1), gather(x0 + 1, y0 + 1)
    top = top_left + fx * (top_right - top_left)
    return top + fy * (bottom_left + fx * (bottom_right - bottom_left) - top)


def _channels(gray: np.ndarray, gradients: bool) -> np.ndarray:
    """(H, W, C) float32: the intensity, with ``gradients`` its Scharr derivatives, and last a
    mask, non-zero within :data:`_CLIP_MARGIN` pixels of a pixel clipped at white
    (:data:`SATURATED`)."""
    import cv2

    image = gray.astype(np.float32)
    side = 2 * _CLIP_MARGIN + 1
    clipped = cv2.dilate((image >= SATURATED).astype(np.float32), np.ones((side, side), np.uint8))
    channels = [image]
    if gradients:
        channels += [
            cv2.Scharr(image, cv2.CV_32F, 1, 0, scale=1.0 / 32.0),
            cv2.Scharr(image, cv2.CV_32F, 0, 1, scale=1.0 / 32.0),
        ]
    return np.dstack([*channels, clipped])


def _offsets(window: int) -> np.ndarray:
    half = window // 2
    o = np.arange(-half, half + 1, dtype=np.float64)
    u, v = np.meshgrid(o, o)
    return np.column_stack([u.ravel(), v.ravel()])


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares ``min |A x - b|`` per window: ``A`` (n, k, m), ``b`` (n, k) -> (n, m)."""
    A, b = A.astype(np.float64), b.astype(np.float64)
    At = A.transpose(0, 2, 1)
    H = At @ A
    H += np.eye(A.shape[2]) * (1e-9 * np.trace(H, axis1=1, axis2=2) + 1e-12)[:, None, None]
    return np.linalg.solve(H, At @ b[..., None])[..., 0]


def _unclipped(template: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Weights (n, k), 1 where neither the template nor the sample (:func:`_channels` channels,
    (n, k, C)) is near a pixel clipped at white."""
    return ((template[..., -1] == 0) & (samples[..., -1] == 0)).astype(np.float32)


def _align_level(template, positions, d, stack2, ramp, iterations):
    """Shift (n, 2) of each window in image 2 from the start ``d``, and the samples there
    (n, k, 4).

    ``template`` (n, k, 2) and the samples hold the channels of :func:`_channels`; ``ramp``
    (k, 2) is the window's offsets scaled to [-1, 1].

    The brightness model (a gain varying linearly across the window, as vignetting does, and
    an offset) is fitted in closed form to the samples at the start; then Gauss-Newton steps
    update the shift and the brightness together (the gain ramp and a shift trade against
    each other across a window with an intensity slope: alternating between them crawls),
    damped by :data:`_DAMPING`, the shift at most 2 pixels per step. Each step reuses the
    Jacobian of the start (the search leaves the shift a few hundredths of a pixel off, over
    which the gradients barely change) and samples the intensity only; the Jacobian is taken
    again where the steps led (:data:`_JACOBIANS` in all). Pixels near one clipped at white in
    either image where the Jacobian was taken are left out (:data:`SATURATED`).
    """
    ramp_columns = np.column_stack([np.ones(len(ramp)), ramp]).astype(np.float32)
    brightness, values2 = None, np.ascontiguousarray(stack2[..., :1])
    for _ in range(_JACOBIANS):
        s = _bilinear(stack2, positions + d[:, None, :])
        weight = _unclipped(template, s)
        target = template[..., 0] * weight
        columns = np.concatenate([s[..., :1] * ramp_columns, weight[..., None]], axis=-1)
        columns *= weight[..., None]
        if brightness is None:
            brightness = _solve(columns, target)
        gain = brightness[:, :3].astype(np.float32) @ ramp_columns.T
        shifting = np.stack([gain * s[..., 1], gain * s[..., 2]], axis=-1) * weight[..., None]
        inverse, jacobian_t = _normal_inverse(np.concatenate([shifting, columns], axis=-1))
        intensity, active = s[..., 0], np.ones(len(template), dtype=bool)
        for iteration in range(iterations):
            if not active.any():
                break
            idx = slice(None) if active.all() else np.flatnonzero(active)  # views while all move
            if iteration:
                intensity = _bilinear(values2, positions[idx] + d[idx, None, :])[..., 0]
            level = brightness[idx].astype(np.float32)
            modelled = (level[:, :3] @ ramp_columns.T) * intensity + level[:, 3:]
            residual = modelled * weight[idx] - target[idx]
            gradient = jacobian_t[idx] @ residual[..., None]
            step = -_DAMPING * (inverse[idx] @ gradient.astype(np.float64))[..., 0]
            shift = np.clip(step[:, :2], -2.0, 2.0)
            d[idx] += shift
            brightness[idx] += step[:, 2:]
            active[idx] = np.abs(shift).max(axis=1) > _CONVERGED
    return d, _bilinear(stack2, positions + d[:, None, :])


def _normal_inverse(jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse normal matrices (n, m, m) of Jacobians (n, k, m), slightly regularised, and the
    transposed Jacobians (n, m, k) float32 (for the gradients: the inverses need float64)."""
    transposed = np.ascontiguousarray(jacobian.transpose(0, 2, 1), dtype=np.float64)
    normal = transposed @ transposed.transpose(0, 2, 1)
    ridge = 1e-9 * np.trace(normal, axis1=1, axis2=2) + 1e-12
    normal += np.eye(normal.shape[1]) * ridge[:, None, None]
    return np.linalg.inv(normal), transposed.astype(np.float32)


def _window_transfer(transfer, centres: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """``transfer`` of every pixel ``centres + offsets`` (n, k, 2), interpolated per window
    (Lagrange, tensor product) through its exact transfer at :data:`_NODES` x :data:`_NODES`
    points spread evenly over the window.

    Across a window a lens rotation's transfer is a perspective map with a gentle radial term:
    the interpolation is off by its fifth derivatives (under 0.001 pixel over a 31-pixel window
    in the corner of a 640 x 480 image distorted by ``k1 = -0.2``), and costs 25 transfers per
    window instead of one per pixel.
    """
    half = np.abs(offsets).max(axis=0)
    nodes = np.linspace(-1.0, 1.0, _NODES)
    node_offsets = np.stack(np.meshgrid(nodes, nodes), axis=-1).reshape(-1, 2) * half
    exact = transfer((centres[:, None, :] + node_offsets).reshape(-1, 2))
    t = offsets / np.where(half > 0, half, 1.0)

    def basis(x: np.ndarray) -> np.ndarray:
        apart = nodes[:, None] - nodes[None, :] + np.eye(_NODES)
        terms = (x[:, None, None] - nodes[None, None, :]) / apart
        terms[:, np.arange(_NODES), np.arange(_NODES)] = 1.0
        return terms.prod(axis=2)

    weights = (basis(t[:, 1])[:, :, None] * basis(t[:, 0])[:, None, :]).reshape(len(t), -1)
    return weights @ exact.reshape(len(centres), -1, 2)


def _ncc(a: np.ndarray, b: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Normalised cross-correlation (n,) of windows ``a``, ``b`` (n, k) over pixels of weight 1."""
    count = np.maximum(weight.sum(axis=1, keepdims=True), 1.0)
    a = (a - np.sum(a * weight, axis=1, keepdims=True) / count) * weight
    b = (b - np.sum(b * weight, axis=1, keepdims=True) / count) * weight
    den = np.sqrt(np.sum(a * a, axis=1) * np.sum(b * b, axis=1))
    return np.sum(a * b, axis=1) / np.maximum(den, 1e-12)


def align_windows(
    image1: np.ndarray,
    image2: np.ndarray,
    points1: np.ndarray,
    transfer: Callable[[np.ndarray], np.ndarray],
    *,
    window: int = WINDOW,
    levels: int = 0,
    iterations: int = _ITERATIONS,
) -> WindowTracks:
    """Align a window of image 1 around each point with image 2 seen through ``transfer``.

    For each point ``p``, ``min sum_k (g_k I2(T(p + o_k) + d) + b - I1(p + o_k))^2`` over the
    shift ``d`` (pixels of image 2), the gain ``g_k`` and the offset ``b``, ``o_k`` the pixels of a
    ``window x window`` square, the gain varying linearly across the window: all windows at
    once, from where pyramidal Lucas-Kanade over ``levels + 1`` levels found them in image 2
    seen through ``transfer`` (the module's step 2).

    Parameters
    ----------
    image1, image2 : ndarray, shape (H, W) or (H, W, 3) BGR
    points1 : ndarray, shape (N, 2)
        Window centres in image 1, pixels.
    transfer : callable
        Pixels of image 1 (M, 2) to their predicted pixels in image 2 (M, 2).
    window : int
        Odd window side, pixels.
    levels : int
        Pyramid levels above the images (0: the images only). Each level doubles the shift the
        alignment can recover from (about a quarter of the window at the finest).
    iterations : int
        Gauss-Newton steps of the polish at most.

    Returns
    -------
    WindowTracks

    Raises
    ------
    ValueError
        Points that are not (N, 2) finite pixels, an even or tiny window, levels outside 0..8.
    TypeError
        ``transfer`` that is not callable.
    """
    points1 = as_points(points1, "points1")
    _require_window(window)
    if not callable(transfer):
        raise TypeError(f"transfer must be callable, got {type(transfer).__name__}")
    if (
        isinstance(levels, bool)
        or not isinstance(levels, (int, np.integer))
        or not 0 <= levels <= 8
    ):
        raise ValueError(f"levels must be an integer in 0..8, got {levels!r}")
    if not len(points1):
        empty = np.zeros((0, 2))
        return WindowTracks(empty, empty, np.zeros(0, dtype=bool), np.zeros(0))
    images = _prepare(to_gray(image1), to_gray(image2))
    return _align(images, points1, transfer, window, levels, iterations)


@dataclass(frozen=True)
class _Images:
    """The two images as :func:`align_windows` reads them: 8-bit grey, and the channels of
    :func:`_channels` at full size (image 1 without gradients, image 2 with)."""

    gray1: np.ndarray
    gray2: np.ndarray
    stack1: np.ndarray
    stack2: np.ndarray
    contrast1: np.ndarray


def _prepare(gray1: np.ndarray, gray2: np.ndarray) -> _Images:
    stack1, stack2 = _channels(gray1, gradients=False), _channels(gray2, gradients=True)
    return _Images(gray1, gray2, stack1, stack2, _local_contrast(gray1))


def _dense_transfer(transfer, shape: tuple[int, ...]) -> np.ndarray:
    """``transfer`` of every pixel of an image of ``shape`` (H, W, 2) float32: exact at the
    centres of :data:`_DENSE_STEP`-pixel cells (and of a ring of cells around the image),
    bilinear in between (a start for the search)."""
    import cv2

    h, w = shape[:2]
    rows, cols = -(-h // _DENSE_STEP) + 2, -(-w // _DENSE_STEP) + 2
    x, y = np.meshgrid(
        (np.arange(cols) - 0.5) * _DENSE_STEP - 0.5, (np.arange(rows) - 0.5) * _DENSE_STEP - 0.5
    )
    coarse = transfer(np.column_stack([x.ravel(), y.ravel()])).reshape(rows, cols, 2)
    coarse = np.nan_to_num(coarse, nan=-1e6, posinf=1e6, neginf=-1e6).clip(-1e6, 1e6)
    size = (cols * _DENSE_STEP, rows * _DENSE_STEP)
    dense = cv2.resize(coarse.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    return dense[_DENSE_STEP : _DENSE_STEP + h, _DENSE_STEP : _DENSE_STEP + w]


def _seen_through(images: _Images, transfer) -> np.ndarray:
    """Image 2 seen through ``transfer`` in image 1's frame, normalised as
    :func:`_local_contrast`, 0 outside image 2."""
    import cv2

    mapping = _dense_transfer(transfer, images.gray1.shape)
    seen = cv2.remap(images.gray2.astype(np.float32), mapping, None, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)  # fmt: skip
    overlap = seen >= 0
    return np.where(overlap, _local_contrast(np.where(overlap, seen, 0.0)), 0).astype(np.uint8)


def _local_contrast(image: np.ndarray) -> np.ndarray:
    """``image`` less its mean over :data:`_CONTRAST_BOX` pixels, over its deviation there,
    as 8-bit grey levels about 128: the search then sees no exposure, gain or vignetting
    change between the images."""
    import cv2

    image = image.astype(np.float32)
    box = (_CONTRAST_BOX, _CONTRAST_BOX)
    mean = cv2.blur(image, box)
    deviation = np.sqrt(np.maximum(cv2.blur(image * image, box) - mean * mean, 0.0))
    return np.clip(128.0 + 32.0 * (image - mean) / (deviation + 2.0), 0, 255).astype(np.uint8)


def _search(images: _Images, seen, points1, transfer, window, levels) -> WindowTracks:
    """Windows found by pyramidal Lucas-Kanade (``cv2.calcOpticalFlowPyrLK``, ``levels``
    levels above the images, translation only) between image 1 and ``seen``, image 2 seen
    through ``transfer``, both as :func:`_local_contrast` (:func:`_seen_through`): valid where
    the search kept the window within its range and inside image 2; ``ncc`` not measured."""
    import cv2

    start = points1.astype(np.float32).reshape(-1, 1, 2)
    found, status, _ = cv2.calcOpticalFlowPyrLK(
        images.contrast1, seen, start, start.copy(), winSize=(window, window), maxLevel=levels,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01),
        flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )  # fmt: skip
    moved = found.reshape(-1, 2).astype(np.float64)
    valid = (
        (status.ravel() == 1)
        & np.all(np.isfinite(moved), axis=1)
        & (np.abs(moved - points1).max(axis=1) < _search_range(window, levels))
    )
    points2 = transfer(np.where(valid[:, None], moved, points1))
    h2, w2 = images.gray2.shape
    valid &= np.all(np.isfinite(points2), axis=1) & _inside(points2[:, None, :], w2, h2)
    return WindowTracks(points1, points2, valid, np.full(len(points1), np.nan))


def _shifts(tracks: WindowTracks, transfer) -> np.ndarray:
    """Shifts (n, 2) of image 2's pixels from ``transfer``'s prediction to the valid
    ``tracks``; zero for the others."""
    shifts = tracks.points2 - transfer(tracks.points1)
    return np.where(tracks.valid[:, None] & np.isfinite(shifts), shifts, 0.0)


def _search_range(window: int, levels: int) -> float:
    """Largest shift (pixels) a search over ``levels`` levels above the images recovers."""
    return window / 4.0 * 2.0**levels + 1.0


def _align(images: _Images, points1, transfer, window, levels, iterations, start=None):
    """:func:`align_windows` on prepared images (checked arguments, at least one point); with
    ``start`` (n, 2), from those shifts of image 2's pixels instead of a search."""
    offsets = _offsets(window)
    ramp = offsets / (window // 2)
    k = len(offsets)
    grid = points1[:, None, :] + offsets[None, :, :]
    positions = _window_transfer(transfer, points1, offsets)
    template = _bilinear(images.stack1, grid)
    if start is None:
        seen = _seen_through(images, transfer)
        start = _shifts(_search(images, seen, points1, transfer, window, levels), transfer)
    d, s = _align_level(template, positions, start.copy(), images.stack2, ramp, iterations)
    h1, w1 = images.stack1.shape[:2]
    h2, w2 = images.stack2.shape[:2]
    final = positions + d[:, None, :]
    inside = _inside(grid, w1, h1) & _inside(final, w2, h2)
    weight = _unclipped(template, s)
    gx, gy = s[..., 1] * weight, s[..., 2] * weight
    structure = np.stack([np.sum(gx * gx, 1), np.sum(gx * gy, 1), np.sum(gy * gy, 1)], axis=1)
    smallest = 0.5 * (structure[:, 0] + structure[:, 2]) - np.sqrt(
        0.25 * (structure[:, 0] - structure[:, 2]) ** 2 + structure[:, 1] ** 2
    )
    ncc = _ncc(template[..., 0], s[..., 0], weight)
    valid = (
        inside
        & (weight.mean(axis=1) >= MIN_UNCLIPPED)
        & np.all(np.isfinite(d), axis=1)
        & (np.abs(d).max(axis=1) < _search_range(window, levels))
        & (smallest > 1e-3 * k)
        & (ncc >= MIN_NCC)
    )
    points2 = transfer(points1) + d
    return WindowTracks(points1=points1, points2=points2, valid=valid, ncc=ncc)


def _as_windows(window) -> tuple[int, ...]:
    """``window`` (one side or a sequence of sides) as a non-empty tuple of checked sides."""
    sides = (window,) if isinstance(window, (int, np.integer)) else tuple(window)
    if not sides:
        raise ValueError("window must name at least one window side")
    for side in sides:
        _require_window(side)
    return sides


def _require_window(window) -> None:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)):
        raise TypeError(f"window must be an integer, got {type(window).__name__}")
    if window < 5 or window % 2 == 0:
        raise ValueError(f"window must be an odd number of pixels >= 5, got {window}")


def _inside(xy: np.ndarray, width: int, height: int) -> np.ndarray:
    x, y = xy[..., 0], xy[..., 1]
    return np.all((x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1), axis=1)


def _corners(gray1, count, window, transfer, shape2) -> np.ndarray:
    """Strongest corners of image 1 (integer pixels, at least a quarter window apart) whose
    window lies inside image 1 and whose transfer lies a window inside image 2."""
    import cv2

    half = window // 2
    found = cv2.goodFeaturesToTrack(gray1, 4 * count, 0.003, max(half // 2, 3))
    if found is None:
        return np.zeros((0, 2))
    corners = np.round(found.reshape(-1, 2).astype(np.float64))
    h, w = gray1.shape
    corners = corners[_within(corners, w, h, half)]
    if len(corners):
        corners = corners[_within(transfer(corners), shape2[1], shape2[0], window)]
    return corners[:count]


def _within(xy: np.ndarray, width: int, height: int, margin: float) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    return (x >= margin) & (x <= width - 1 - margin) & (y >= margin) & (y <= height - 1 - margin)


def window_overlap(points: np.ndarray, window: int = WINDOW) -> float:
    """How many windows cover a pixel of their union, on average: ``n window^2 / |union|``.

    The tracks' residuals are not independent where windows overlap (they are made from the
    same pixels, their noise and interpolation): a least-squares covariance that takes them as
    independent is too small by about this factor, which :func:`refine_rotation_photometric`
    applies to the variances of its fit. 1 for disjoint windows.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Window centres, integer pixels.
    window : int
        Window side, pixels.

    Examples
    --------
    >>> window_overlap(np.array([[10.0, 10.0], [40.0, 10.0]]), 21)
    1.0
    >>> window_overlap(np.array([[10.0, 10.0], [10.0, 10.0]]), 21)
    2.0
    """
    import cv2

    points = np.round(np.asarray(points, dtype=np.float64)).astype(np.int64).reshape(-1, 2)
    if not len(points):
        return 1.0
    half = window // 2
    origin = points.min(axis=0) - half
    span = points.max(axis=0) - origin + half + 1
    centres = np.zeros((span[1], span[0]), dtype=np.uint8)
    centres[points[:, 1] - origin[1], points[:, 0] - origin[0]] = 1
    covered = cv2.dilate(centres, np.ones((window, window), np.uint8))
    return float(len(points) * window * window / np.count_nonzero(covered))


def _as_offset(value) -> np.ndarray:
    try:
        offset = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"principal_offset must be two numbers, got {value!r}") from None
    if offset.shape != (2,) or not np.all(np.isfinite(offset)):
        raise ValueError(f"principal_offset must be two finite numbers, got {value!r}")
    return offset


def _as_prior(value) -> np.ndarray:
    try:
        prior = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"principal_prior must be one or two numbers, got {value!r}") from None
    if prior.size not in (1, 2) or prior.ndim > 1:
        raise ValueError(f"principal_prior must be one or two numbers, got {value!r}")
    prior = np.broadcast_to(prior, (2,))
    if not np.all(np.isfinite(prior) & (prior > 0)):
        raise ValueError(f"principal_prior must be finite numbers > 0, got {value!r}")
    return prior


def _fit_tracks(y1, y2, valid, R, focal, priors):
    """Lens rotation over the tracks, outliers beyond ``3 sqrt(2)`` noise deviations dropped;
    ``(fit, used, noise_px)`` or None when too few tracks remain, or when the lens was clipped
    to its box (no deviation) unless ``priors["keep_clipped"]``, which also frees ``k1`` of
    its box (its prior alone holds it)."""
    priors = dict(priors)
    keep_clipped = priors.pop("keep_clipped", False)
    if keep_clipped:
        priors["max_k1"] = np.inf
    used, noise, fit = valid.copy(), 0.1 / focal, None
    for _ in range(5):
        if np.count_nonzero(used) < MIN_TRACKS:
            return None
        start = R if fit is None else fit.R
        fit = fit_rotation_lens(y1, y2, used, start, noise=noise, **priors)
        noise = robust_sigma(fit.residuals[used], 2)
        within = valid & (fit.residuals < _OUTLIER_SIGMAS * np.sqrt(2.0) * noise)
        if np.array_equal(within, used):
            break
        used = within
    if not noise > 0 or not (keep_clipped or np.isfinite(fit.rotation_sigma_deg)):
        return None
    return fit, used, noise * focal


def refine_rotation_photometric(
    image1: np.ndarray,
    image2: np.ndarray,
    K1: np.ndarray,
    K2: np.ndarray,
    R: np.ndarray,
    *,
    focal_scale: float = 1.0,
    k1: float = 0.0,
    principal_offset: Sequence[float] = (0.0, 0.0),
    principal_prior: float | Sequence[float] | None = None,
    focal_ratio: float = 1.0,
    focal_ratio_prior: float | None = None,
    focal_ratio_mean: float = 1.0,
    principal_bound: float = PRINCIPAL_BOUND,
    max_focal_change: float = MAX_FOCAL_CHANGE,
    rotation_sigma_deg: float = 1.0,
    dist1: np.ndarray | None = None,
    dist2: np.ndarray | None = None,
    window: int | Sequence[int] = WINDOWS,
    max_corners: int | None = None,
    keep_clipped: bool = False,
) -> PhotometricRotation | None:
    """Refit a pure rotation's lens rotation on windows aligned by intensity.

    Parameters
    ----------
    image1, image2 : ndarray, shape (H, W) or (H, W, 3) BGR
    K1, K2 : ndarray, shape (3, 3)
        Intrinsics given for the images.
    R : ndarray, shape (3, 3)
        Rotation fitted to feature matches, ``b2 = R b1``, with its lens terms ``focal_scale``,
        ``k1`` and ``principal_offset`` (:func:`ppo_cv.rotation.fit_rotation_lens`).
    principal_prior : float or array_like of 2 floats, optional
        Refit the principal-point offset too, under this prior (normalised units, one for both
        coordinates or ``(x, y)``); None keeps ``principal_offset``.
    focal_ratio : float
        View 2's focal scale over view 1's in that fit.
    focal_ratio_prior, focal_ratio_mean : float, optional
        Refit the focal ratio too, under a prior of this deviation about this mean; None (the
        deviation) keeps ``focal_ratio``.
    principal_bound : float
        Largest principal-point offset, in ``principal_prior`` deviations (that of the matches).
    max_focal_change : float
        Box of the refit's focal scale (and focal ratio), ``|s - 1| <= max_focal_change``:
        the pipeline passes :data:`ppo_cv.rotation.TRACK_FOCAL_CHANGE` for a pure rotation
        whose matches' fit was clipped at :data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`
        (:attr:`ppo_cv.motion_model.MotionDecision.track_focal_change`).
    rotation_sigma_deg : float
        Its uncertainty: how far (three times this) the first alignment must search, and the
        bound on the change: a refit further than ``4 rotation_sigma_deg + 0.1`` degrees from
        ``R`` is refused (windows locked onto repeated texture).
    dist1, dist2 : ndarray, optional
        OpenCV distortion coefficients of the given cameras.
    window : int or sequence of int
        Window side, pixels, or the sides to try (default :data:`WINDOWS`): the refit of least
        ``rotation_sigma_deg`` is returned.
    max_corners : int, optional
        Windows aligned at most (default :data:`MAX_CORNERS`).
    keep_clipped : bool
        A rotation-only estimate's refit (:mod:`ppo_cv.rotation_choice`): ``k1`` held by its
        prior alone, and a focal scale clipped to its box returned too (no deviation).

    Returns
    -------
    PhotometricRotation or None
        None when with every window side under :data:`MIN_TRACKS` tracks agree or it is refused.

    Raises
    ------
    ValueError
        Invalid intrinsics or distortion, ``R`` not a rotation, ``rotation_sigma_deg`` <= 0.

    Examples
    --------
    A 2 degree pan of a random texture, started from the identity:

    >>> import cv2
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> image1 = cv2.GaussianBlur(rng.uniform(0, 255, (240, 320)), (0, 0), 2).astype(np.uint8)
    >>> K = np.array([[400.0, 0, 159.5], [0, 400.0, 119.5], [0, 0, 1]])
    >>> c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    >>> R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> image2 = cv2.warpPerspective(image1, K @ R @ np.linalg.inv(K), (320, 240))
    >>> refined = refine_rotation_photometric(image1, image2, K, K, np.eye(3))
    >>> from ppo_cv.metrics import rotation_error_deg
    >>> bool(rotation_error_deg(refined.fit.R, R) < 0.02), refined.num_tracks > 100
    (True, True)
    """
    cameras, R, rotation_sigma_deg, focal_ratio, priors = _checked_inputs(
        K1, K2, dist1, dist2, R, rotation_sigma_deg, principal_prior, focal_ratio,
        focal_ratio_prior, focal_ratio_mean, principal_bound, max_focal_change,
    )  # fmt: skip
    priors["keep_clipped"] = bool(keep_clipped)
    start = (R, float(focal_scale), float(k1), _as_offset(principal_offset), focal_ratio)
    return _best_window_refit(
        image1, image2, cameras, start, priors, rotation_sigma_deg, _as_windows(window),
        max_corners,
    )  # fmt: skip


def _checked_inputs(
    K1, K2, dist1, dist2, R, rotation_sigma_deg, principal_prior, focal_ratio, focal_ratio_prior,
    focal_ratio_mean, principal_bound, max_focal_change,
) -> tuple[tuple, np.ndarray, float, float, dict]:  # fmt: skip
    """The cameras ``(K1, K2, dist1, dist2)``, ``R``, ``rotation_sigma_deg``, ``focal_ratio``
    and the priors of :func:`refine_rotation_photometric`, checked."""
    K1, K2 = as_camera_matrix(K1, "K1"), as_camera_matrix(K2, "K2")
    dist1, dist2 = as_distortion(dist1, "dist1"), as_distortion(dist2, "dist2")
    R = as_rotation(R, "R")
    rotation_sigma_deg = as_positive(rotation_sigma_deg, "rotation_sigma_deg")
    if principal_prior is not None:
        principal_prior = _as_prior(principal_prior)
    focal_ratio = as_positive(focal_ratio, "focal_ratio")
    if focal_ratio_prior is not None:
        focal_ratio_prior = as_positive(focal_ratio_prior, "focal_ratio_prior")
    focal_ratio_mean = as_positive(focal_ratio_mean, "focal_ratio_mean")
    principal_bound = as_positive(principal_bound, "principal_bound")
    max_focal_change = as_positive(max_focal_change, "max_focal_change")
    priors = {
        "principal_prior": principal_prior,
        "focal_ratio_prior": focal_ratio_prior,
        "focal_ratio_mean": focal_ratio_mean,
        "principal_bound": principal_bound,
        "max_focal_change": max_focal_change,
    }
    return (K1, K2, dist1, dist2), R, rotation_sigma_deg, focal_ratio, priors


def _best_window_refit(
    image1, image2, cameras, start, priors: dict, rotation_sigma_deg: float, windows, max_corners
) -> PhotometricRotation | None:
    """The refit of least ``rotation_sigma_deg`` among the window sides that give one within
    ``4 rotation_sigma_deg + 0.1`` degrees of the start, with the parallax of its tracks; None
    when none does."""
    K1, K2, dist1, dist2 = cameras
    R = start[0]
    focal = float(np.mean([K2[0, 0], K2[1, 1]]))
    gray1, gray2 = to_gray(image1), to_gray(image2)

    def transfer_with(model) -> Callable[[np.ndarray], np.ndarray]:
        return lambda pixels: normalized_to_pixels(
            transfer_points(pixels_to_normalized(pixels, K1, dist1), *model), K2, dist2
        )

    count = MAX_CORNERS if max_corners is None else int(max_corners)
    shift = max(3.0 * np.radians(min(rotation_sigma_deg, MAX_SEARCH_SIGMA_DEG)) * focal, 1.0)
    levels = {
        side: int(np.clip(np.ceil(np.log2(shift / (side / 8.0))), 0, _MAX_LEVELS))
        for side in windows
    }
    images = _prepare(gray1, gray2)
    seen = _seen_through(images, transfer_with(start))
    normalize2 = lambda pixels: pixels_to_normalized(pixels, K2, dist2)  # noqa: E731
    plausible = lambda refined: (  # noqa: E731
        refined is not None
        and rotation_error_deg(refined.fit.R, R) <= 4.0 * rotation_sigma_deg + 0.1
    )
    results = []
    for side in windows:
        corners = _corners(gray1, count, side, transfer_with(start), gray2.shape)
        if len(corners) < MIN_TRACKS:
            continue
        refined = _refine_side(
            (images, seen), corners, pixels_to_normalized(corners, K1, dist1), side,
            levels[side], start, transfer_with, normalize2, focal, priors,
        )  # fmt: skip
        if plausible(refined):
            results.append(refined)
    if not results:
        return None
    sigma = lambda refined: refined.fit.rotation_sigma_deg  # noqa: E731
    polished = []
    for searched in sorted(results, key=sigma):
        if polished and min(map(sigma, polished)) <= sigma(searched):
            break
        y1 = pixels_to_normalized(searched.tracks.points1, K1, dist1)
        refined = _polish(images, searched, y1, transfer_with, normalize2, focal, priors)
        if plausible(refined):
            polished.append(refined)
    if not polished:
        return None
    best = min(polished, key=sigma)
    return replace(best, parallax=_plane_parallax(best, K1, K2, dist1, dist2))


def _refine_side(
    prepared, corners, y1, window, levels, start, transfer_with, normalize2, focal, priors
) -> PhotometricRotation | None:
    """One window side of :func:`refine_rotation_photometric`: search the windows around
    ``corners`` (normalised ``y1``) through the start model over ``levels`` pyramid levels,
    fit, search them again at full size in image 2 seen through the fit, and fit again (the
    first fit when too few tracks agree with the second)."""
    images, seen = prepared
    transfer = transfer_with(start)
    tracks = _search(images, seen, corners, transfer, window, levels)
    found = _fit_windows(tracks, y1, window, start[0], normalize2, focal, priors)
    if found is None:  # the search alone too rough to fit: polish its tracks first
        tracks = _align(images, corners, transfer, window, levels, _ITERATIONS,
                        start=_shifts(tracks, transfer))  # fmt: skip
        found = _fit_windows(tracks, y1, window, start[0], normalize2, focal, priors)
    if found is None:
        return None
    transfer = transfer_with(_model(found.fit))
    tracks = _search(images, _seen_through(images, transfer), corners, transfer, window, 0)
    again = _fit_windows(tracks, y1, window, found.fit.R, normalize2, focal, priors)
    return found if again is None else again


def _polish(
    images, refined, y1, transfer_with, normalize2, focal, priors
) -> PhotometricRotation | None:
    """The windows of ``refined`` (normalised centres ``y1``) aligned on the intensities
    through its fit (:func:`_align`, from where the search found them), and the fit again;
    None when too few tracks agree."""
    transfer = transfer_with(_model(refined.fit))
    tracks = _align(images, refined.tracks.points1, transfer, refined.window, 0, _ITERATIONS,
                    start=_shifts(refined.tracks, transfer))  # fmt: skip
    return _fit_windows(tracks, y1, refined.window, refined.fit.R, normalize2, focal, priors)


def _model(fit: LensRotationFit) -> tuple:
    """The arguments of :func:`ppo_cv.rotation.transfer_points` after ``R`` and the points."""
    return (fit.R, fit.focal_scale, fit.k1, fit.principal_offset, fit.focal_ratio)


def _fit_windows(tracks, y1, window, R, normalize2, focal, priors) -> PhotometricRotation | None:
    """The lens rotation refitted on ``tracks`` of windows of side ``window`` around points of
    normalised ``y1`` (:func:`_fit_tracks`, from ``R``), its deviations multiplied by the square
    root of the windows' overlap; None when too few tracks agree."""
    fitted = _fit_tracks(y1, normalize2(tracks.points2), tracks.valid, R, focal, priors)
    if fitted is None:
        return None
    fit, used, noise_px = fitted
    inflation = np.sqrt(window_overlap(tracks.points1[used], window))
    fit = replace(
        fit,
        focal_scale_sigma=fit.focal_scale_sigma * inflation,
        rotation_sigma_deg=fit.rotation_sigma_deg * inflation,
    )
    return PhotometricRotation(
        fit=fit, tracks=tracks, inliers=used, noise_px=noise_px, window=window
    )


def _plane_parallax(refined: PhotometricRotation, K1, K2, dist1, dist2) -> PlaneParallax:
    """:func:`ppo_cv.parallax.fit_plane_parallax` of the tracks ``refined`` used, corrected by
    its lens terms, the deviation multiplied by the square root of the windows' overlap as the
    fit's are (``_fit_tracks`` keeps at least :data:`MIN_TRACKS` tracks)."""
    fit, used = refined.fit, refined.inliers
    points1, points2 = refined.tracks.points1[used], refined.tracks.points2[used]
    y1 = pixels_to_normalized(points1, K1, dist1)
    y2 = pixels_to_normalized(points2, K2, dist2)
    q1 = correct_points(y1, fit.focal_scale, fit.k1, fit.principal_offset)
    q2 = correct_points(y2, fit.focal_scale2, fit.k1, fit.principal_offset)
    found = fit_plane_parallax(q1, q2)
    inflation = np.sqrt(window_overlap(points1, refined.window))
    return replace(found, sigma=found.sigma * inflation)
