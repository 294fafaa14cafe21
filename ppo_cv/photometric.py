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
   CMU-RI-TR-03-35), the Jacobian of the start reused and taken again where it led for the
   windows it moved by more than a fiftieth of a pixel (:data:`_RETAKE`). The
   windows are solved together, a few tens at a time (arrays of windows x window pixels that
   stay in the cache, two such chunks at once on two threads), with exact bilinear
   interpolation: image 2 is read once per Jacobian as the polynomial of each pixel's cell,
   which the steps then move along (a window is read again where it moved more than a
   hundredth of a pixel); its Scharr derivatives, which only weigh the steps, are sampled by
   ``cv2.remap``. Each window's pixels are transferred
   through the model by interpolating its exact transfer at 5 x 5 points;
3. the lens rotation refitted on the tracks, outliers (moving objects, occlusions, windows that
   did not converge) dropped beyond ``3 sqrt(2)`` times the tracks' own noise per coordinate
   (the 2D residual of an inlier exceeds it with probability ``exp(-9)``). When the search's
   tracks are too rough for it (a narrow strip of overlap, shots a stop apart), they are
   polished through the start model first. The fit's variances are multiplied by the
   windows' overlap (:func:`window_overlap`): overlapping windows are made of the same
   pixels, and their errors are not independent. Then the windows are searched again at full
   size in image 2 seen through the refitted model, and the fit repeated;
4. steps 1-3 with each window side of :data:`WINDOWS` (the sides on two threads), keeping
   the refit whose rotation is the least uncertain: large windows locate tracks better in
   noisy images, small ones are more numerous in weak texture;
5. the windows of that side polished through its fit, from where the search found them, and
   the fit repeated; the next side too while its searched bound is below the polished one,
   the least uncertain polished refit kept. The search is the cheap part (a few tens of
   milliseconds for both sides), the polish the accurate one (on the demo frame warped by a
   rotation the rotation error of the search alone was 0.02-0.05 degrees, 0.001-0.04
   polished); on the sets of ``benchmarks/pure_rotation.py`` checked (56 pairs) one side was
   polished every time. A caller that reads only whether the refit could change its own
   decision may skip this step (``settled`` of :func:`refine_rotation_photometric`): each
   side's searched refit is then measured first, and where no polish could change that
   decision, the least uncertain searched refit is returned.

On renders and warped photos with the imperfections of real ones (distortion, focal 3 % off,
JPEG) this brings the median rotation error of each set of exact pure rotations in full overlap
from 0.02-0.18 to 0.00-0.05 degrees (0.07 with sensor noise and blur), in narrow overlaps as
stitched from 0.25 to 0.09, and from 0.12 to 0.07 against the rotation fitted with an exact given
focal (``docs/pure_rotation.md``, made by ``benchmarks/pure_rotation.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import ArrayLike

from .camera import normalized_to_pixels, pixels_to_normalized
from .checks import (
    MAX_WHOLE_NUMBER,
    as_callback,
    as_camera_matrix,
    as_distortion,
    as_number,
    as_points,
    as_positive,
    as_rotation,
    as_whole_number,
)
from .features import to_gray
from .metrics import rotation_error_deg
from .model_selection import robust_sigma
from .parallax import PlaneParallax, fit_plane_parallax
from .rotation import (
    MAX_FOCAL_CHANGE,
    PRINCIPAL_BOUND,
    LensRotationFit,
    _correct_points,
    _transfer_points,
    fit_rotation_lens,
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
    "refit_reach_deg",
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
_CHUNK = 65536  # window pixels aligned at a time
_THREADS = 2  # aligning chunks of windows, or searching window sides, at once
_SIDES_AT_ONCE_PIXELS = 3_000_000
"""Largest image 1 (pixels) whose window sides are searched on two threads at once, larger ones
one side after the other: each side's search holds image 2 warped and normalised at full size.
On a 4000x3000 pair the peak resident memory of the refit rose from 1.02 to 1.22 GB when the two
sides ran together (each side then also held OpenCV's corner map of image 1)."""
_JACOBIANS = 2  # of the polish: at the start, and where its steps led
_REGATHER = 0.01  # pixels a window moves from where image 2 was read for another read
_RETAKE = 0.02  # pixels a window moves with the first Jacobian of the polish for a second

_DENSE_STEPS = 0.4  # share of a chunk's windows still moving above which all are stepped
_DAMPING = 0.7  # of each Gauss-Newton step: the sampled gradients overshoot by about 1.4
_MAX_BRIGHTNESS = 1e6  # gain or offset of a window's brightness beyond which its steps diverged
_OUTLIER_SIGMAS = 3.0
_CONTRAST_BOX = 31  # pixels
_CORNER_QUALITY = 0.003  # of the strongest corner response, the weakest a corner may have
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


@dataclass(frozen=True)
class _Plane:
    """A grey image as the polish reads it, per pixel cell (the square between four pixels,
    named by its top-left one): ``cells`` (5, H W) float32, a plane per coefficient of the
    cell's exact bilinear interpolation ``base + fx slope_x + fy (slope_y + fx twist)`` of the
    intensity, then 1 where none of its corners lies within :data:`_CLIP_MARGIN` pixels of a
    pixel clipped at white (:data:`SATURATED`), else 0 (no columns when only whole pixels are
    read, from ``intensity``; a gather reads the planes it needs, each into a contiguous
    array); ``clipped`` (H W) non-zero at the pixels within the margin;
    ``gradients`` optionally the Scharr derivatives (H, W) along x and y, which the polish
    samples with ``cv2.remap``: they only weigh its steps, where a sampling position off by
    1/64 pixel does not matter."""

    cells: np.ndarray
    width: int
    height: int
    clipped: np.ndarray
    intensity: np.ndarray
    gradients: tuple[np.ndarray, ...] = ()


_CLEAR = 4  # row of _Plane.cells


def _plane(gray: np.ndarray, gradients: bool, cells: bool = True) -> _Plane:
    import cv2

    image = gray.astype(np.float32)
    h, w = image.shape
    side = 2 * _CLIP_MARGIN + 1
    clipped = cv2.dilate((image >= SATURATED).astype(np.uint8), np.ones((side, side), np.uint8))
    derivatives = (
        tuple(cv2.Scharr(image, cv2.CV_32F, *d, scale=1.0 / 32.0) for d in ((1, 0), (0, 1)))
        if gradients
        else ()
    )
    if not cells:
        return _Plane(np.zeros((5, 0), np.float32), w, h, clipped.ravel(), image.ravel())
    near = np.pad(clipped, ((0, 1), (0, 1)), mode="edge")
    table = _bilinear_coefficients(image)
    table[_CLEAR] = (near[:-1, :-1] | near[:-1, 1:] | near[1:, :-1] | near[1:, 1:]) == 0
    cells_table = table.reshape(5, h * w)  # its first plane is the intensity, not kept twice
    return _Plane(cells_table, w, h, clipped.ravel(), cells_table[0], derivatives)


def _bilinear_coefficients(image: np.ndarray) -> np.ndarray:
    """``base``, ``slope_x``, ``slope_y``, ``twist`` of every pixel cell of ``image`` (H, W),
    the last row and column repeated past the edge: a table (5, H, W) float32 whose last
    plane is left for the caller. Written in place: on a 12-megapixel image, four separate
    planes and their merge peaked 0.15 GB higher."""
    table = np.empty((5, *image.shape), np.float32)
    table[0] = image
    slope_x, slope_y, twist = table[1:4]
    slope_x[:, -1] = slope_y[-1] = twist[-1] = 0.0
    np.subtract(image[:, 1:], image[:, :-1], out=slope_x[:, :-1])
    np.subtract(image[1:], image[:-1], out=slope_y[:-1])
    np.subtract(slope_x[1:], slope_x[:-1], out=twist[:-1])
    return table


@dataclass(frozen=True)
class _Cells:
    """A :class:`_Plane` about points (n, k) of n windows: the first planes of each point's
    cell (``coefficients``, (planes, n, k)) and its place in it, ``fx`` and ``fy`` in [0, 1].

    Moving the points by a shift inside their cells is then a few products (``values``); past
    a cell's edge the polynomial extrapolates, off by the shift past it times the change of
    slope.
    """

    coefficients: np.ndarray
    fx: np.ndarray
    fy: np.ndarray

    @property
    def clear(self) -> np.ndarray:
        """1 where the pixels a point reads are not near a clipped one, else 0."""
        return self.coefficients[_CLEAR]

    def values(self, shift: np.ndarray | None = None, rows=slice(None)) -> np.ndarray:
        """The intensity (m, k) at the points of the windows ``rows`` (m of them) moved by
        ``shift`` (pixels, a row (2,) per window)."""
        fx, fy = self.fx[rows], self.fy[rows]
        base, slope_x, slope_y, twist = self.coefficients[:4, rows]
        if shift is not None:
            shift = shift.astype(np.float32)
            copies = not isinstance(rows, slice)  # then fx and fy are the caller's own
            fx = np.add(fx, shift[:, :1], out=fx if copies else None)
            fy = np.add(fy, shift[:, 1:], out=fy if copies else None)
        value = np.multiply(fx, slope_x)
        value += base
        curve = np.multiply(fx, twist)
        curve += slope_y
        curve *= fy
        value += curve
        return value


def _cells(plane: _Plane, x: np.ndarray, y: np.ndarray, planes: int) -> _Cells:
    """:class:`_Cells` of ``plane`` with its first ``planes`` at points ``(x, y)`` (n, k)
    float32; outside the image, any of its cells (such windows are not valid).

    Exact bilinear weights (``cv2.remap`` rounds them to 1/32 pixel, a bias that matters at the
    hundredths of a pixel sought here)."""

    x0, y0 = np.floor(x), np.floor(y)
    index = np.int32 if plane.cells.shape[1] < 2**31 else np.intp  # a narrower pass
    first = y0.astype(index)
    first *= plane.width
    first += x0.astype(index)
    coefficients = np.take(plane.cells[:planes], first, axis=1, mode="clip")
    return _Cells(coefficients, x - x0, y - y0)


def _template(plane: _Plane, points, offsets) -> tuple[np.ndarray, np.ndarray]:
    """``plane``'s intensities (n, k) at the pixels ``offsets`` (k, 2) of :func:`_offsets`
    about ``points`` (n, 2) and 1 where they are not near a clipped pixel, else 0; read
    directly at whole pixels (the corners), the image's edge repeated beyond it."""
    w, h = plane.width, plane.height
    if not np.array_equal(points, np.round(points)):
        grid = (points[:, None, :] + offsets[None, :, :]).astype(np.float32)
        cells = _cells(plane, grid[..., 0], grid[..., 1], _CLEAR + 1)
        return cells.values(), cells.clear
    side = _side(offsets)
    o = offsets[:side, 0].astype(np.intp)
    x = np.clip(points[:, :1].astype(np.intp) + o, 0, w - 1)
    y = np.clip(points[:, 1:].astype(np.intp) + o, 0, h - 1) * w
    pixels = (y[:, :, None] + x[:, None, :]).reshape(len(points), -1)
    clear = (np.take(plane.clipped, pixels) == 0).astype(np.float32)
    return np.take(plane.intensity, pixels), clear


def _offsets(window: int) -> np.ndarray:
    """Pixels (k, 2) of a ``window`` x ``window`` square about its centre, row by row."""
    half = window // 2
    o = np.arange(-half, half + 1, dtype=np.float64)
    u, v = np.meshgrid(o, o)
    return np.column_stack([u.ravel(), v.ravel()])


def _side(offsets: np.ndarray) -> int:
    """Side of the square window of :func:`_offsets` ``offsets``."""
    return int(round(np.sqrt(len(offsets))))


@dataclass(frozen=True)
class _Aligned:
    """Result of :func:`_align_level`: the shifts (n, 2); image 2's intensities (n, k) there,
    its derivatives and the weights of the pixels not near a clipped one where it was first
    read; and which windows' steps diverged (n,) bool (:class:`_GaussNewton`), unusable."""

    shifts: np.ndarray
    intensity: np.ndarray
    gradients: tuple[np.ndarray, np.ndarray]
    weight: np.ndarray
    diverged: np.ndarray


def _align_level(template, template_clear, positions, d, plane2, ramp, iterations) -> _Aligned:
    """Shift (n, 2) of each window in image 2 from the start ``d``, and image 2 there.

    ``template`` (n, k) holds image 1 at the windows' pixels, ``template_clear`` 1 where none
    is near a clipped pixel, ``positions`` their transfer to image 2 (x and y, (n, k) float32);
    ``ramp``
    (k, 2) is the window's offsets scaled to [-1, 1].

    The brightness model (a gain varying linearly across the window, as vignetting does, and
    an offset) is fitted in closed form to image 2 at the start; then damped Gauss-Newton steps
    update the shift and the brightness together (:class:`_GaussNewton`; the gain ramp and a
    shift trade against each other across a window with an intensity slope: alternating
    between them crawls), with the Jacobian of the start, then again with the Jacobian where
    they led and the gain reached (:data:`_JACOBIANS` in all) for the windows that moved more
    than :data:`_RETAKE` pixels: for the others the Jacobian where they stopped is that of
    their start to a fraction of their noise, and its steps would move them by less than a
    thousandth of a pixel (median). Image 2 is read as the
    bilinear polynomial of each pixel's cell (:class:`_Cells`), which the steps move along; a
    window that moved more than :data:`_REGATHER` pixels from where it was last read is read
    again there. Pixels near one clipped at white in either image are left out
    (:data:`SATURATED`).
    """
    import cv2

    x, y = positions
    ramp_columns = np.column_stack([np.ones(len(ramp)), ramp]).astype(np.float32)

    def solve(windows, shifts, brightness) -> tuple:
        """The ``windows`` (a slice or indices) stepped from ``shifts`` with the Jacobian
        there: the shifts, brightness, image 2 there, its derivatives and weights."""
        x_of, y_of = x[windows], y[windows]

        def reread(cells: _Cells, rows: np.ndarray, at: np.ndarray) -> np.ndarray:
            at = at.astype(np.float32)
            again = _cells(plane2, x_of[rows] + at[:, :1], y_of[rows] + at[:, 1:], 4)
            cells.coefficients[:4, rows] = again.coefficients
            cells.fx[rows], cells.fy[rows] = again.fx, again.fy
            return again.values()

        d32 = shifts.astype(np.float32)
        at_x, at_y = x_of + d32[:, :1], y_of + d32[:, 1:]
        cells = _cells(plane2, at_x, at_y, _CLEAR + 1)
        gradients = tuple(
            cv2.remap(gradient, at_x, at_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            for gradient in plane2.gradients
        )
        weight = cells.clear * template_clear[windows]
        target = template[windows]
        intensity = cells.values()
        jacobian_t, brightness, normal = _jacobian_t(
            intensity, gradients, weight, target, ramp_columns, brightness
        )
        row_sums = normal[:, :, 5].astype(np.float64)
        steps = _GaussNewton(target, _normal_inverse(normal), jacobian_t, row_sums, ramp_columns,
                             iterations)  # fmt: skip
        lost = np.zeros(len(shifts), dtype=bool)
        intensity = steps.run(cells, reread, shifts, brightness, intensity, lost)
        diverged[windows] |= lost
        return shifts, brightness, intensity, *gradients, weight

    diverged = np.zeros(len(d), dtype=bool)

    start = d.copy()
    solved = solve(slice(None), d, None)
    for _ in range(_JACOBIANS - 1):
        moved = np.flatnonzero(np.abs(solved[0] - start).max(axis=1) > _RETAKE)
        if not len(moved):
            break
        start[moved] = solved[0][moved]
        again = solve(moved, solved[0][moved], solved[1][moved])
        for whole, part in zip(solved, again, strict=True):
            whole[moved] = part
    d, _, intensity, gradient_x, gradient_y, weight = solved
    gradients = (gradient_x, gradient_y)
    return _Aligned(d, intensity, gradients, weight, diverged)


def _jacobian_t(
    intensity, gradients, weight, target, ramp_columns, brightness=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, 6, k): the residuals' derivatives along the shift, the gain ramp and the offset,
    the shift's at the gain of ``brightness`` (n, 4), by default fitted in closed form
    (:func:`_brightness_of`); that brightness; and its normal matrices (n, 6, 6) float32."""
    n, k = intensity.shape
    jacobian_t = np.empty((n, 6, k), dtype=np.float32)
    np.multiply(intensity, weight, out=jacobian_t[:, 2])
    for i in (1, 2):
        np.multiply(jacobian_t[:, 2], ramp_columns[:, i], out=jacobian_t[:, 2 + i])
    jacobian_t[:, 5] = weight
    normal = np.empty((n, 6, 6), dtype=np.float32)
    normal[:, 2:, 2:] = np.einsum("nik,njk->nij", jacobian_t[:, 2:], jacobian_t[:, 2:])
    if brightness is None:
        brightness = _brightness_of(jacobian_t, normal[:, 2:, 2:], target)
    gain = brightness[:, :3].astype(np.float32) @ ramp_columns.T
    gain *= weight
    for i in range(2):
        np.multiply(gain, gradients[i], out=jacobian_t[:, i])
    normal[:, :2] = np.einsum("nik,njk->nij", jacobian_t[:, :2], jacobian_t)
    normal[:, 2:, :2] = normal[:, :2, 2:].transpose(0, 2, 1)
    return jacobian_t, brightness, normal


def _brightness_of(jacobian_t, normal, target) -> np.ndarray:
    """Gain ramp and offset (n, 4) float64 fitted in closed form to image 2 as it was read
    (rows 2-5 of ``jacobian_t``, whose normal matrices (n, 4, 4) are ``normal``) against
    ``target`` (n, k), image 1 (the rows carry the pixels' weights)."""
    columns = jacobian_t[:, 2:]
    normal = _regularised(normal.astype(np.float64))
    return np.linalg.solve(normal, (columns @ target[..., None]).astype(np.float64))[..., 0]


def _normal_inverse(normal: np.ndarray) -> np.ndarray:
    """Inverse (n, m, m) float64 of normal matrices (n, m, m), slightly regularised."""
    return np.linalg.inv(_regularised(normal.astype(np.float64)))


def _regularised(normal: np.ndarray) -> np.ndarray:
    """Normal matrices (n, m, m) float64 with a ridge of 1e-9 of their trace (and 1e-12) added
    to the diagonal, in place."""
    ridge = 1e-9 * np.trace(normal, axis1=1, axis2=2) + 1e-12
    normal += np.eye(normal.shape[1]) * ridge[:, None, None]
    return normal


@dataclass(frozen=True)
class _GaussNewton:
    """Damped Gauss-Newton steps of windows' shifts and brightness with a fixed Jacobian:
    ``template`` (n, k) image 1, the inverse normal matrices of :func:`_normal_inverse`, the
    transposed Jacobians (n, 6, k) of :func:`_jacobian_t` and their row sums (n, 6) float64.

    Every row of the Jacobian carries the pixels' weights (0 or 1), so its product with the
    residual ``w (g I2 + b - I1)`` is its product with ``g I2 - I1`` plus ``b`` times its
    row sums: the weights and the offset are not applied pixel by pixel. Its last row is the
    weights, so the row sums are the last column of the normal matrices. While more than
    :data:`_DENSE_STEPS` of the windows still move, a step is computed for all of them and
    kept for those (gathering their rows of the Jacobian costs more than the others' product)."""

    template: np.ndarray
    inverse: np.ndarray
    jacobian_t: np.ndarray
    row_sums: np.ndarray
    ramp_columns: np.ndarray
    iterations: int

    def run(self, cells: _Cells, reread, shifts, brightness, intensity, diverged) -> np.ndarray:
        """Steps from ``shifts`` (updating them and ``brightness`` in place) along the
        polynomials of ``cells``, read at ``shifts`` (``intensity``, their values there, is
        overwritten): the shift at most 2 pixels and damped by :data:`_DAMPING`, until it
        moves less than :data:`_CONVERGED`. A window that moved more than :data:`_REGATHER`
        pixels from where it was read is read again where it is (``reread(cells, windows,
        shifts)``, which returns image 2 there). A window whose brightness would leave
        :data:`_MAX_BRIGHTNESS` (its fixed Jacobian no longer describes it, and the steps grow
        without bound) stops where it is, marked in ``diverged`` (n,) bool. Image 2 at the last
        shifts (n, k)."""
        d, level, read_at = shifts, brightness, shifts.copy()
        active = np.abs(level).max(axis=1) <= _MAX_BRIGHTNESS
        diverged |= ~active
        for iteration in range(self.iterations):
            rows = np.flatnonzero(active)
            if not len(rows):
                break
            if iteration:
                far = np.abs(d[rows] - read_at[rows]).max(axis=1) > _REGATHER
                far, near = rows[far], rows[~far]
                if len(far):
                    intensity[far] = reread(cells, far, d[far])
                    read_at[far] = d[far]
                if len(near):
                    intensity[near] = cells.values(d[near] - read_at[near], near)
            part = slice(None) if len(rows) > _DENSE_STEPS * len(d) else rows
            gain = level[part, :3].astype(np.float32) @ self.ramp_columns.T
            difference = np.multiply(gain, intensity[part], out=gain)
            difference -= self.template[part]
            gradient = (self.jacobian_t[part] @ difference[..., None])[..., 0]
            gradient = gradient + level[part, 3:] * self.row_sums[part]
            step = -_DAMPING * (self.inverse[part] @ gradient[..., None])[..., 0]
            if isinstance(part, slice):
                step = step[rows]
            shift = np.minimum(np.maximum(step[:, :2], -2.0), 2.0)
            moved = level[rows] + step[:, 2:]
            wild = ~(np.abs(moved).max(axis=1) <= _MAX_BRIGHTNESS)
            if wild.any():
                shift[wild], moved[wild] = 0.0, level[rows[wild]]
                diverged[rows[wild]] = True
            d[rows] += shift
            level[rows] = moved
            active[rows] = (np.abs(shift).max(axis=1) > _CONVERGED) & ~wild
        return cells.values(d - read_at)


def _window_transfer(
    transfer, centres: np.ndarray, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``transfer`` of every pixel ``centres + offsets``, interpolated per window (Lagrange,
    tensor product) through its exact transfer at :data:`_NODES` x :data:`_NODES` points spread
    evenly over the window: the weights (k, 25) and the exact transfers (n, 25, 2), whose
    product is the transfer (n, k, 2).

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
    return weights, exact.reshape(len(centres), -1, 2)


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
    images = _prepare(to_gray(image1), to_gray(image2), np.array_equal(points1, np.round(points1)))
    return _align(images, points1, transfer, window, levels, iterations)


@dataclass(frozen=True)
class _Images:
    """The two images as :func:`align_windows` reads them: 8-bit grey, as the polish samples
    them (:class:`_Plane`), and image 1 normalised for the search (:func:`_local_contrast`)."""

    gray1: np.ndarray
    gray2: np.ndarray
    plane1: _Plane
    plane2: _Plane
    contrast1: np.ndarray


def _prepare(gray1: np.ndarray, gray2: np.ndarray, whole: bool = True) -> _Images:
    """The images as the alignment reads them; ``whole`` when every window centre in image 1
    is a whole pixel (then image 1's windows are read directly, without its cells)."""
    contrast1 = _local_contrast(gray1)  # first: its temporaries then come before the planes
    planes = _plane(gray1, gradients=False, cells=not whole), _plane(gray2, gradients=True)
    return _Images(gray1, gray2, *planes, contrast1)


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
    del mapping
    outside = seen < 0
    contrast = _local_contrast(np.maximum(seen, 0.0, out=seen))
    np.copyto(contrast, 0, where=outside)
    return contrast


def _local_contrast(image: np.ndarray) -> np.ndarray:
    """``image`` less its mean over :data:`_CONTRAST_BOX` pixels, over its deviation there,
    as 8-bit grey levels about 128: the search then sees no exposure, gain or vignetting
    change between the images. A float32 ``image`` is overwritten."""
    import cv2

    image = image.astype(np.float32, copy=False)
    box = (_CONTRAST_BOX, _CONTRAST_BOX)
    mean = cv2.blur(image, box)
    square = np.multiply(image, image)
    spread = cv2.blur(square, box)
    spread -= np.multiply(mean, mean, out=square)
    del square
    deviation = np.sqrt(np.maximum(spread, 0.0, out=spread), out=spread)
    deviation += 2.0
    image -= mean
    del mean
    image *= 32.0
    image /= deviation
    image += 128.0
    return np.clip(image, 0, 255, out=np.empty(image.shape, np.uint8), casting="unsafe")


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
    ``start`` (n, 2), from those shifts of image 2's pixels instead of a search. The windows
    are aligned :data:`_CHUNK` pixels at a time, which keeps the arrays in the cache, on
    :data:`_THREADS` threads at most, no more than OpenCV may use (the chunks are independent,
    numpy and OpenCV release the GIL in their array work)."""
    if start is None:
        seen = _seen_through(images, transfer)
        start = _shifts(_search(images, seen, points1, transfer, window, levels), transfer)
    offsets = _offsets(window)
    weights, exact = _window_transfer(transfer, points1, offsets)
    step = max(_CHUNK // len(offsets), 1)
    chunks = [slice(i, i + step) for i in range(0, len(points1), step)]

    def align(rows: slice) -> tuple:
        positions = weights @ exact[rows]
        return _align_chunk(images, points1[rows], positions, start[rows], offsets, iterations)

    parts = _threaded_map(align, chunks)
    d, ncc, usable = (np.concatenate(column) for column in zip(*parts, strict=True))
    valid = usable & np.all(np.isfinite(d), axis=1) & (ncc >= MIN_NCC)
    valid &= np.abs(d).max(axis=1) < _search_range(window, levels)
    return WindowTracks(points1=points1, points2=transfer(points1) + d, valid=valid, ncc=ncc)


def _threaded_map(function: Callable, items: Sequence) -> list:
    """``function`` of each of ``items``, on :data:`_THREADS` threads at most, no more than
    OpenCV may use (numpy and OpenCV release the GIL in their array work)."""
    from concurrent.futures import ThreadPoolExecutor

    import cv2

    threads = min(_THREADS, max(cv2.getNumThreads(), 1), len(items))
    if threads <= 1:
        return [function(item) for item in items]
    with ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(function, items))


def _align_chunk(images: _Images, points1, positions, start, offsets, iterations):
    """Windows around ``points1`` (n, 2) whose pixels ``offsets`` (k, 2) image 2 shows at
    ``positions`` (n, k, 2) less a shift, aligned from the shifts ``start`` (n, 2): the shifts,
    the normalised cross-correlations and whether each window lies inside both images, has
    enough pixels away from clipped ones and enough texture."""
    plane1, plane2 = images.plane1, images.plane2
    template, template_clear = _template(plane1, points1, offsets)
    ramp = offsets / np.abs(offsets).max()
    x, y = (np.ascontiguousarray(positions[..., i], dtype=np.float32) for i in range(2))
    aligned = _align_level(template, template_clear, (x, y), start.copy(), plane2, ramp,
                           iterations)  # fmt: skip
    d, weight = aligned.shifts, aligned.weight
    inside = _within(points1, plane1.width, plane1.height, _side(offsets) // 2)
    inside &= _spans_inside(x, y, d, plane2.width, plane2.height)
    gx, gy = aligned.gradients
    gxw, gyw = gx * weight, gy * weight
    products = ("nk,nk->n", gxw, gx), ("nk,nk->n", gxw, gy), ("nk,nk->n", gyw, gy)
    structure = np.stack([np.einsum(*product) for product in products], axis=1)
    smallest = 0.5 * (structure[:, 0] + structure[:, 2]) - np.sqrt(
        0.25 * (structure[:, 0] - structure[:, 2]) ** 2 + structure[:, 1] ** 2
    )
    ncc = _ncc(template, aligned.intensity, weight)
    usable = (
        inside
        & ~aligned.diverged
        & (weight.mean(axis=1) >= MIN_UNCLIPPED)
        & (smallest > 1e-3 * len(offsets))
    )  # fmt: skip
    return d, ncc, usable


def _as_windows(window) -> tuple[int, ...]:
    """``window`` (one side or a sequence of sides) as a non-empty tuple of checked sides."""
    sides = (window,) if isinstance(window, (int, np.integer)) else tuple(window)
    if not sides:
        raise ValueError("window must name at least one window side")
    for side in sides:
        _require_window(side)
    return sides


def _as_count(max_corners) -> int:
    """``max_corners`` checked, :data:`MAX_CORNERS` for None."""
    if max_corners is None:
        return MAX_CORNERS
    return as_whole_number(max_corners, "max_corners", 1, MAX_WHOLE_NUMBER)


def _require_window(window) -> None:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)):
        raise TypeError(f"window must be an integer, got {type(window).__name__}")
    if window < 5 or window % 2 == 0:
        raise ValueError(f"window must be an odd number of pixels >= 5, got {window}")


def _spans_inside(x: np.ndarray, y: np.ndarray, d: np.ndarray, width: int, height: int):
    """Whether every point ``(x, y)`` (n, k) of each window moved by ``d`` (n, 2) lies inside
    an image of ``width`` x ``height``."""
    low = np.column_stack([x.min(axis=1), y.min(axis=1)]) + d
    high = np.column_stack([x.max(axis=1), y.max(axis=1)]) + d
    return np.all(low >= 0, axis=1) & np.all(high <= [width - 1, height - 1], axis=1)


def _inside(xy: np.ndarray, width: int, height: int) -> np.ndarray:
    x, y = xy[..., 0], xy[..., 1]
    return np.all((x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1), axis=1)


def _corner_candidates(gray1: np.ndarray) -> np.ndarray:
    """Corner candidates of image 1 (n, 2) integer pixels ``(x, y)``, strongest first: the
    local maxima of the minimum eigenvalue of the gradient structure tensor above
    :data:`_CORNER_QUALITY` times its largest, in ``cv2.goodFeaturesToTrack``'s order (equal
    responses the later pixel first), before its spacing (:func:`_spaced`). The response map is
    the same for every window side; only the spacing depends on the side."""
    import cv2

    response = cv2.cornerMinEigenVal(gray1, 3)
    cv2.threshold(response, float(response.max()) * _CORNER_QUALITY, 0.0, cv2.THRESH_TOZERO,
                  dst=response)  # fmt: skip
    keep = response == cv2.dilate(response, None)
    keep &= response != 0
    keep[[0, -1]] = keep[:, [0, -1]] = False
    pixel = np.flatnonzero(keep)
    strength = response.ravel()[pixel].view(np.int32).astype(np.int64)  # > 0: as the floats
    pixel = np.sort((strength << 32) | pixel)[::-1] & 0xFFFFFFFF
    width = response.shape[1]
    return np.column_stack([pixel % width, pixel // width])


def _spaced(candidates: np.ndarray, distance: int) -> np.ndarray:
    """Indices of ``candidates`` (n, 2) integer pixels, strongest first, that
    ``cv2.goodFeaturesToTrack`` keeps with ``minDistance`` ``distance``: each one closer than
    ``distance`` to no stronger one kept. Taken in rounds over the pairs closer than that
    (found in bands of ``distance`` rows, each candidate against its band and the next): a
    candidate none of whose stronger neighbours is undecided or kept is kept, one with a
    stronger neighbour kept is dropped."""
    x, y = candidates[:, 0], candidates[:, 1]
    n = len(candidates)
    stride = int(x.max(initial=0)) + 2 * distance
    place = y // distance * stride + x
    order = np.argsort(place)
    ordered = place[order]
    low = np.concatenate([ordered, ordered + (stride - distance + 1)])
    first = np.searchsorted(ordered, low)
    counts = np.searchsorted(ordered, low + np.repeat([distance, 2 * distance - 1], n)) - first
    near = order[np.arange(counts.sum()) + np.repeat(first - np.cumsum(counts) + counts, counts)]
    one = np.repeat(np.tile(order, 2), counts)
    close = (x[one] - x[near]) ** 2 + (y[one] - y[near]) ** 2 < distance * distance
    close &= one != near
    weaker, stronger = np.maximum(one, near)[close], np.minimum(one, near)[close]
    state = np.zeros(n, np.int8)  # 1 kept, -1 dropped
    while (state == 0).any():
        blocked = np.zeros(n, bool)
        blocked[weaker[state[stronger] >= 0]] = True
        state[(state == 0) & ~blocked] = 1
        beaten = np.zeros(n, bool)
        beaten[weaker[state[stronger] == 1]] = True
        state[beaten & (state == 0)] = -1
    return np.flatnonzero(state == 1)


def _corners(candidates, count, window, transfer, shape1, shape2) -> np.ndarray:
    """The first ``count`` corners of image 1 (of ``shape1``; integer pixels, at least a quarter
    window apart, from :func:`_corner_candidates`) whose window lies inside image 1 and whose
    transfer lies a window inside image 2 (of ``shape2``), among the ``4 count`` strongest so
    spaced: those of ``cv2.goodFeaturesToTrack``. Spaced over the strongest ``4 count``
    candidates, then twice as many while too few corners pass (the spacing of the strongest
    candidates does not depend on the weaker ones)."""
    half = window // 2
    distance, most = max(half // 2, 3), 4 * count
    h, w = shape1[:2]
    taken = most
    while True:
        head = candidates[:taken]
        spaced = head[_spaced(head, distance)][:most].astype(np.float64)
        corners = spaced[_within(spaced, w, h, half)]
        if len(corners):
            corners = corners[_within(transfer(corners), shape2[1], shape2[0], window)]
        if len(corners) >= count or len(spaced) >= most or taken >= len(candidates):
            return corners[:count]
        taken *= 2


def _within(xy: np.ndarray, width: int, height: int, margin: float) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    return (x >= margin) & (x <= width - 1 - margin) & (y >= margin) & (y <= height - 1 - margin)


def window_overlap(points: ArrayLike, window: int = WINDOW) -> float:
    """How many windows cover a pixel of their union, on average: ``n window^2 / |union|``.

    The tracks' residuals are not independent where windows overlap (they are made from the
    same pixels, their noise and interpolation): a least-squares covariance that takes them as
    independent is too small by about this factor, which :func:`refine_rotation_photometric`
    applies to the variances of its fit. 1 for disjoint windows.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Window centres, integer pixels (rounded), finite, spread with their windows over at
        most :data:`ppo_cv.images.DEFAULT_MAX_PIXELS` pixels (the corners of one image).
    window : int
        Window side, pixels, at least 1.

    Examples
    --------
    >>> window_overlap(np.array([[10.0, 10.0], [40.0, 10.0]]), 21)
    1.0
    >>> window_overlap(np.array([[10.0, 10.0], [10.0, 10.0]]), 21)
    2.0
    """
    from .images import DEFAULT_MAX_PIXELS

    points = np.round(as_points(points, "points")).astype(np.int64)
    window = as_whole_number(window, "window", 1, MAX_WHOLE_NUMBER)
    if len(points):
        width, height = (np.ptp(points, axis=0) + window).tolist()
        if width * height > DEFAULT_MAX_PIXELS:
            raise ValueError(
                f"points and their windows span {width}x{height} pixels, beyond "
                f"{DEFAULT_MAX_PIXELS}: not the corners of one image"
            )
    return _window_overlap(points, window)


def _window_overlap(points: np.ndarray, window: int) -> float:
    """:func:`window_overlap`, unchecked."""
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
    its box (its prior alone holds it); ``priors["on_clipped"]`` is called for each lens fit
    clipped to its box. Only the last fit's deviations are computed."""
    priors = dict(priors)
    keep_clipped = priors.pop("keep_clipped", False)
    on_clipped = priors.pop("on_clipped", None)
    if keep_clipped:
        priors["max_k1"] = np.inf
    used, noise, fit = valid.copy(), 0.1 / focal, None
    for attempt in range(5):
        if np.count_nonzero(used) < MIN_TRACKS:
            return None
        start = R if fit is None else fit.R
        last = partial(_last_track_fit, used=used, valid=valid, final=attempt == 4)
        fit = fit_rotation_lens(
            y1, y2, used, start, noise=noise, lens_start=fit, deviations=last, check_input=False,
            **priors,
        )  # fmt: skip
        if on_clipped is not None and np.isinf(fit.rotation_sigma_deg):
            on_clipped()
        noise, within = _track_inliers(fit, used, valid)
        if np.array_equal(within, used):
            break
        used = within
    if not noise > 0 or not (keep_clipped or np.isfinite(fit.rotation_sigma_deg)):
        return None
    return fit, used, noise * focal


def _track_inliers(fit, used, valid) -> tuple[float, np.ndarray]:
    """The noise of a lens fit's ``used`` tracks and the ``valid`` tracks within
    ``3 sqrt(2)`` deviations of it (N,)."""
    noise = robust_sigma(fit.residuals[used], 2)
    return noise, valid & (fit.residuals < _OUTLIER_SIGMAS * np.sqrt(2.0) * noise)


def _last_track_fit(fit, used, valid, final) -> bool:
    """:func:`_fit_tracks`' loop ends after ``fit``: its ``final`` fit, or one whose inliers
    are the ``used`` tracks it was fitted to."""
    return final or np.array_equal(_track_inliers(fit, used, valid)[1], used)


def refine_rotation_photometric(
    image1: np.ndarray,
    image2: np.ndarray,
    K1: np.ndarray, K2: np.ndarray,
    R: np.ndarray,
    *,
    focal_scale: float = 1.0,
    k1: float = 0.0,
    principal_offset: Sequence[float] = (0.0, 0.0),
    principal_prior: float | Sequence[float] | None = None,
    focal_ratio: float = 1.0,
    focal_ratio_prior: float | None = None, focal_ratio_mean: float = 1.0,
    principal_bound: float = PRINCIPAL_BOUND,
    max_focal_change: float = MAX_FOCAL_CHANGE,
    rotation_sigma_deg: float = 1.0,
    dist1: np.ndarray | None = None, dist2: np.ndarray | None = None,
    window: int | Sequence[int] = WINDOWS, max_corners: int | None = None,
    keep_clipped: bool = False, on_clipped: Callable[[], None] | None = None,
    settled: Callable[[PhotometricRotation], bool] | None = None,
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
        Box of the refit's focal scale (and focal ratio), ``|s - 1| <= max_focal_change``
        (in the pipeline :attr:`ppo_cv.motion_model.MotionDecision.track_focal_change`).
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
        Windows aligned at most, a whole number >= 1 (default :data:`MAX_CORNERS`).
    keep_clipped : bool
        ``k1`` held by its prior alone, a clipped focal scale returned (rotation-only refits).
    on_clipped : callable, optional
        Called per lens fit clipped to its box: only those fits depend on ``keep_clipped``.
    settled : callable, optional
        Called with each side's searched refit, its ``parallax`` measured; True for all (no
        polish could change the caller's decision): the least uncertain returned unpolished.

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
    priors.update(keep_clipped=bool(keep_clipped), on_clipped=as_callback(on_clipped, "on_clipped"))
    settled = as_callback(settled, "settled", "a callable taking a PhotometricRotation")
    start = _start_model(R, focal_scale, k1, principal_offset, focal_ratio)
    windows, count = _as_windows(window), _as_count(max_corners)
    return _best_window_refit(
        image1, image2, cameras, start, priors, rotation_sigma_deg, windows, count, settled
    )


def _start_model(R, focal_scale, k1, principal_offset, focal_ratio) -> tuple:
    """The lens rotation the refit starts from, as :func:`_model` gives one, its lens terms
    checked."""
    if not np.isfinite(k1 := as_number(k1, "k1")):
        raise ValueError(f"k1 must be a finite number, got {k1}")
    offset = _as_offset(principal_offset)
    return (R, as_positive(focal_scale, "focal_scale"), k1, offset, focal_ratio)


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


def refit_reach_deg(rotation_sigma_deg: float) -> float:
    """Farthest (degrees) :func:`refine_rotation_photometric` lets a refit move the rotation from
    its start when searched over ``rotation_sigma_deg``: ``4 rotation_sigma_deg + 0.1``; a refit
    beyond is refused. ``rotation_sigma_deg`` a number >= 0 (inf for no bound); ValueError or
    TypeError otherwise.

    >>> refit_reach_deg(0.5)
    2.1
    """
    sigma = as_number(rotation_sigma_deg, "rotation_sigma_deg")
    if not sigma >= 0:
        raise ValueError(f"rotation_sigma_deg must be a number >= 0 (inf for none), got {sigma}")
    return _refit_reach_deg(sigma)


def _refit_reach_deg(rotation_sigma_deg: float) -> float:
    """:func:`refit_reach_deg`, unchecked."""
    return 4.0 * float(rotation_sigma_deg) + 0.1


def _best_window_refit(
    image1, image2, cameras, start, priors: dict, rotation_sigma_deg: float, windows, count: int,
    settled: Callable[[PhotometricRotation], bool] | None = None,
) -> PhotometricRotation | None:  # fmt: skip
    """The refit of least ``rotation_sigma_deg`` among the window sides that give one within
    ``4 rotation_sigma_deg + 0.1`` degrees of the start, each side on at most ``count`` windows,
    with the parallax of its tracks; None when none does. The searched refits are polished
    unless ``settled`` holds for each (:func:`_settled_search`)."""
    K1, K2, dist1, dist2 = cameras
    R = start[0]
    focal = float(np.mean([K2[0, 0], K2[1, 1]]))
    gray1, gray2 = to_gray(image1), to_gray(image2)

    def transfer_with(model) -> Callable[[np.ndarray], np.ndarray]:
        return lambda pixels: normalized_to_pixels(
            _transfer_points(pixels_to_normalized(pixels, K1, dist1), *model), K2, dist2
        )

    shift = max(3.0 * np.radians(min(rotation_sigma_deg, MAX_SEARCH_SIGMA_DEG)) * focal, 1.0)
    levels = {
        side: int(np.clip(np.ceil(np.log2(shift / (side / 8.0))), 0, _MAX_LEVELS))
        for side in windows
    }
    images = _prepare(gray1, gray2)
    candidates = _corner_candidates(gray1)
    seen = _seen_through(images, transfer_with(start))
    normalize2 = lambda pixels: pixels_to_normalized(pixels, K2, dist2)  # noqa: E731
    plausible = lambda refined: (  # noqa: E731
        refined is not None
        and rotation_error_deg(refined.fit.R, R) <= _refit_reach_deg(rotation_sigma_deg)
    )

    def searched(side: int) -> PhotometricRotation | None:
        corners = _corners(candidates, count, side, transfer_with(start), gray1.shape,
                           gray2.shape)  # fmt: skip
        if len(corners) < MIN_TRACKS:
            return None
        y1 = pixels_to_normalized(corners, K1, dist1)
        refined = _search_side(
            (images, seen), corners, y1, side, levels[side], start, transfer_with, normalize2,
            focal, priors,
        )  # fmt: skip
        if refined is not None:
            refined = _search_again(images, refined, y1, transfer_with, normalize2, focal, priors)
        return refined if plausible(refined) else None

    at_once = gray1.size <= _SIDES_AT_ONCE_PIXELS
    found = _threaded_map(searched, windows) if at_once else [searched(side) for side in windows]
    results = [refined for refined in found if refined is not None]
    if not results:
        return None
    if settled is not None:
        measured = _settled_search(results, settled, cameras)
        if measured is not None:
            return measured
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


def _settled_search(
    results: list[PhotometricRotation], settled: Callable[[PhotometricRotation], bool], cameras
) -> PhotometricRotation | None:
    """The searched refit of least ``rotation_sigma_deg`` among ``results`` (one a window
    side), with the parallax of its tracks, when ``settled`` holds for every one of them, each
    with its parallax measured: the polish of any side, whichever one it keeps, could not
    change what the caller decides; None otherwise (the first side that fails ends the
    test)."""
    measured = []
    for refined in sorted(results, key=lambda refined: refined.fit.rotation_sigma_deg):
        measured.append(replace(refined, parallax=_plane_parallax(refined, *cameras)))
        if not settled(measured[-1]):
            return None
    return measured[0]


def _search_side(
    prepared, corners, y1, window, levels, start, transfer_with, normalize2, focal, priors
) -> PhotometricRotation | None:
    """One window side of :func:`refine_rotation_photometric`: the windows around ``corners``
    (normalised ``y1``) searched through the start model over ``levels`` pyramid levels, and
    the fit; None when too few tracks agree."""
    images, seen = prepared
    transfer = transfer_with(start)
    tracks = _search(images, seen, corners, transfer, window, levels)
    found = _fit_windows(tracks, y1, window, start[0], normalize2, focal, priors)
    if found is None:  # the search alone too rough to fit: polish its tracks first
        tracks = _align(images, corners, transfer, window, levels, _ITERATIONS,
                        start=_shifts(tracks, transfer))  # fmt: skip
        found = _fit_windows(tracks, y1, window, start[0], normalize2, focal, priors)
    return found


def _search_again(
    images, refined, y1, transfer_with, normalize2, focal, priors
) -> PhotometricRotation:
    """The windows of ``refined`` searched again at full size in image 2 seen through its fit,
    and the fit again; ``refined`` when too few tracks agree."""
    transfer = transfer_with(_model(refined.fit))
    corners, window = refined.tracks.points1, refined.window
    tracks = _search(images, _seen_through(images, transfer), corners, transfer, window, 0)
    again = _fit_windows(tracks, y1, window, refined.fit.R, normalize2, focal, priors)
    return refined if again is None else again


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
    inflation = np.sqrt(_window_overlap(tracks.points1[used], window))
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
    q1 = _correct_points(y1, fit.focal_scale, fit.k1, fit.principal_offset)
    q2 = _correct_points(y2, fit.focal_scale2, fit.k1, fit.principal_offset)
    found = fit_plane_parallax(q1, q2)
    inflation = np.sqrt(_window_overlap(points1, refined.window))
    return replace(found, sigma=found.sigma * inflation)
