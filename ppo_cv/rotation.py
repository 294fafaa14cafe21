"""Rotation-only two-view model: robust fit, and a variant that absorbs the lens imperfections.

Under a pure rotation the bearings of a match obey ``b2 = R b1`` (paper eq. 3 with ``t = 0``).

- :func:`rotations_from_two_rays`: the minimal solver. Two rays fix ``R``: the orthonormal
  triads ``(m, c, m x c)`` built from the bisector ``m`` and the normal ``c`` of each image's pair
  of rays are mapped onto each other, ``R = T2 T1^T``. Exact on noise-free data, vectorised over
  hypotheses.
- :func:`ransac_rotation`: RANSAC over that solver (batches of hypotheses scored against all
  matches at once, trials adapted to the inlier ratio), then the least-squares rotation (Wahba,
  :func:`ppo_cv.ppo.rotation_from_rays`) over its inliers, re-selected until they settle.
- :func:`fit_rotation_lens`: rotation plus one focal-length scale ``s``, one radial
  coefficient ``k1`` and optionally a principal-point offset ``p``, shared by the two views,
  and optionally a focal ratio ``rho`` of view 2 to view 1, by Gauss-Newton over the inliers.
  The given normalised point ``x`` of view 1 is taken as ``s x = p + q (1 + k1 |q|^2)`` of the
  true ray ``(q, 1)`` (OpenCV's radial model, inverted exactly by fixed-point iteration), that
  of view 2 as ``s rho x = ...``, and ``(q2, 1) ~ R (q1, 1)``.
  A tripod panorama taken with intrinsics a few percent off and unmodelled distortion is this
  model; the depth-dependent parallax of a translation is not, so the two models keep apart.
  Given the noise, ``s``, ``k1`` and ``p`` get Gaussian priors (:data:`FOCAL_PRIOR`,
  :data:`K1_PRIOR`, :data:`PRINCIPAL_PRIOR`): the fit is then the maximum a posteriori one,
  defined from 4 matches on. ``p`` matters only with a turn (``A R A^-1 = I`` for ``R = I``,
  ``A`` the shift of the normalised plane by ``p``), and in a narrow field it is nearly a
  rotation itself, which is why the prior, not the matches, bounds it. ``rho`` is for focal
  lengths given per image (a panorama stitcher estimates one per photo): a relative error of
  the two, uncorrected, is a radial flow that an essential matrix explains as a forward
  translation (held, it made 8 of 14 warped pans told focal lengths per photo general,
  :func:`focal_ratio_prior`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .checks import (
    MAX_COORDINATE,
    MAX_RADIAL,
    MAX_RAY_SLOPE,
    _on_image_plane,
    as_finite_array,
    as_finite_rows,
    as_flag,
    as_nonnegative,
    as_number,
    as_positive,
    as_ransac_settings,
    as_rotation,
    as_whole_number,
    require_instance,
    shown,
)
from .lsq import (
    _cross_matrix,
    _gauss_newton_covariance,
    _rotation_increment,
)
from .ppo import rotation_from_rays

__all__ = [
    "FOCAL_PRIOR",
    "FOCAL_RATIO_BOUND",
    "FOCAL_RATIO_GAP",
    "K1_PRIOR",
    "MAX_FOCAL_CHANGE",
    "MAX_K1",
    "PRINCIPAL_BOUND",
    "PRINCIPAL_PRIOR",
    "MIN_LENS_MATCHES",
    "PRINCIPAL_SIGNIFICANCE",
    "PRINCIPAL_WIDE_BOUND",
    "TRACK_FOCAL_CHANGE",
    "RotationFit",
    "LensRotationFit",
    "rotations_from_two_rays",
    "rotation_residuals",
    "ransac_rotation",
    "fit_rotation_lens",
    "focal_ratio_keywords",
    "focal_ratio_prior",
    "lens_rotation_residuals",
    "correct_points",
    "transfer_points",
    "seen_through_lens",
]

_BLOCK = 1 << 18  # hypotheses x matches scored per block
_BATCH = 64  # hypotheses drawn at once
_NPARAMS = 8  # rotation increment (3), focal scale, k1, principal point offset (2), focal ratio
_ROTATION = np.arange(_NPARAMS) < 3
_LENS = np.arange(_NPARAMS) < 5  # rotation, focal scale and k1
_OFFSET = np.isin(np.arange(_NPARAMS), (5, 6))
_RATIO = np.arange(_NPARAMS) == 7
_SETTLED = 0.05  # deviations of the parameters: a smaller Gauss-Newton step ends the steps
FOCAL_PRIOR = 0.02
"""Standard deviation of the relative error of a focal length given by a user (calibration
files, EXIF, autostitch): "a few percent". The prior of :func:`fit_rotation_lens` on ``s - 1``.
With it the returned rotation is the maximum a posteriori one: a focal the matches pin down
(many matches, a wide turn) is followed, a focal they hardly constrain stays near the given one.
"""

K1_PRIOR = 0.1
"""Standard deviation of the radial coefficient nobody modelled (OpenCV's ``k1``; consumer lenses
at 25-35 degrees of field lie within about +-0.1). The prior of :func:`fit_rotation_lens`."""

MAX_FOCAL_CHANGE = 0.05
"""Largest ``|s - 1|`` (and ``|rho - 1|``) of a plausible lens: the box :func:`fit_rotation_lens`
clips the focal scale to on feature matches. Beyond it a translation's parallax is more likely
than a focal length given that far off (2.5 :data:`FOCAL_PRIOR`), and the fit's
``lens_excess`` says by how much the matches asked for more."""

MAX_K1 = 0.2
"""Largest ``|k1|`` of a plausible lens: the box :func:`fit_rotation_lens` clips ``k1`` to, on
feature matches and on tracks. Consumer lenses reach ``|k1|`` of about 0.15 in the division
model ``q = x / (1 + k1 |x|^2)`` (the model of the radial refinements,
:func:`ppo_cv.plane.undistort_division`); this fit's one-term model ``x = q (1 + k1 |q|^2)``
needs ``k1 + 2 k1^2 |q|^2 + ...`` for the same lens (the series of the division model's
inverse, ``ppo_cv.data_gen.division_dist``), up to 0.2 for a division ``k1`` of +0.15 at
``|q| = 1`` (a 90 degree diagonal). With the box at 0.15, pure rotations through such lenses
(``ppo_cv.data_gen`` ``tripod`` at baseline 0, division ``k1`` +0.13 to +0.15, 45-60 degree
fields, seed 0 indices 0-7) wanted 0.15-0.17: three lay 4.5-17 deviations beyond the box and
were called general, 2.6-7.9 degrees off; in this box all eight are rotations, 0.005-0.10
degrees off. In a 15-25 degree field (``NARROW_LENS``) lenses of 0.14-0.15 were fitted at the
edge of the old box, where the tracks' refit was refused on three of ten (0.034-0.10 degrees
off); here they are refitted (0.007-0.043)."""

TRACK_FOCAL_CHANGE = 0.15
"""Box of the focal scale when intensity-aligned tracks refit a pure rotation whose fit on the
matches was clipped at :data:`MAX_FOCAL_CHANGE`, to test it
(:attr:`ppo_cv.motion_model.MotionDecision.track_focal_change`,
:func:`ppo_cv.photometric.refine_rotation_photometric`). Tracks located to a few hundredths of
a pixel pin the focal length where matches do not, and a rotation under a focal held at the box
is no rotation of the tracks: a 20 degree turn with the focal 2 % off reads a parallax of
0.0136 (``S R S^-1``, ``S = diag(s, s, 1)``), and such tracks were refused. Warped photos
and renders turned with the focal given 5.8-7.7 % short (``ppo_cv.data_gen`` ``REAL_PHOTO``
with ``focal_error`` 0.08, seed 0, indices 0, 8, 10 and 11), flagged on their matches
0.05-0.54 degrees off, have tracks that fit focal scales 0.92-0.94 in this box and read a
parallax of 0.0001-0.0008; their rotations are then 0.005-0.034 degrees off."""

PRINCIPAL_PRIOR = 0.01
"""Standard deviation of each coordinate of the offset of the true principal point from the
image centre, as a fraction of that image side (the width for ``x``, the height for ``y``):
consumer cameras put it within about 2 % of each side, and a principal point given at the
centre is a guess. In a narrow field a 1 % offset leaves 0.3 px of median residual on a
rotation fitted with the centre (640 px wide, 30 degrees, a 20 degree pan), growing with the
image size; the pipeline converts it to normalised units for :func:`fit_rotation_lens`."""

PRINCIPAL_BOUND = 2.0
"""Largest principal-point offset :func:`fit_rotation_lens` accepts, in prior deviations per
coordinate: beyond it the offset explains parallax, not a lens, and the given point is kept.
With :data:`PRINCIPAL_PRIOR` per side that is 2 % of the width across and 2 % of the height
down: one prior for both axes (1 % of the larger side) let a translation at baseline / depth
0.02 move the point 11.8 px down a 480 px high image, beyond 2 % of it, and be called a pure
rotation (``ppo_cv.data_gen`` ``tiny-baseline`` index 5 with the centre given). An offset is
beyond the bound only when the matches place it there (:data:`PRINCIPAL_SIGNIFICANCE`)."""

PRINCIPAL_WIDE_BOUND = 3.0
"""Wider bound (prior deviations per coordinate) of a second rotation-only fit, for a pair whose
offset the first fit dropped: 3 % of each side. The fitted offset of a lens whose principal
point lies 1.9 % of a side off the centre overshoots 2 % in a narrow overlap (20 degree pans in
a 30 degree field, as stitched: ``ppo_cv.data_gen`` panorama seed 1, 640 x 480 index 51, 30 px
across at 1600 x 1200 index 11), and without it the rotation leaves a translation's parallax
(1.3-1.9 degrees off as general motions). Translations use the same freedom: at baseline / depth
0.02 with the centre given (``tiny-baseline`` index 5) a bound of 3 lets the rotation win GRIC.
So a pair that passes only under this bound is no more than a rotation candidate, settled by the
parallax of its intensity-aligned tracks (:func:`ppo_cv.motion_model.decide_motion`)."""

PRINCIPAL_SIGNIFICANCE = 3.0
"""How far, in its own posterior deviations, a fitted offset must lie beyond
:data:`PRINCIPAL_BOUND` on a coordinate to be dropped. With a third of the image overlapping
(a 20 degree pan in a 30 degree field) a few dozen matches fix the offset to only 0.3-0.9
prior deviations, so a lens whose principal point is 1.7-1.96 % of a side off the centre was
fitted beyond 2 % and dropped on 3 of 20 such pans (``ppo_cv.data_gen`` seed 1, focal lengths
per photo, exposure and vignetting); focal and ``k1`` then ran to the edges of their box and the
pans were called general motions, 0.5-3.2 degrees off. Those offsets lie 0.1-2.7 deviations
beyond the bound; the offsets of translations at baseline / depth 0.02 that fitted beyond it
lie 3.5-95 deviations beyond (``tiny-baseline`` and the harness renders, centre given), with
one exception at 0.6 that no rule on the offset tells from a lens (index 8 with the centre
given: fitted 2.07 deviations across, true -0.66)."""

FOCAL_RATIO_GAP = 0.05
"""Largest relative difference of two given focal lengths that :func:`focal_ratio_prior` takes
for one lens at one zoom, estimated per photo (as a panorama stitcher does); further apart
they are two lenses or zooms, each given to within :data:`FOCAL_PRIOR`, and the ratio is kept:
the freedom costs translations along the optical axis (see :func:`focal_ratio_prior`), and a
few percent of error in each is already what :data:`FOCAL_PRIOR` allows for both."""

FOCAL_RATIO_BOUND = 2.0
"""Farthest ``rho`` :func:`fit_rotation_lens` accepts from the mean of its prior, in prior
deviations: beyond it the ratio explains parallax (a forward translation seen at the scene's
mean depth is a zoom), and the given ratio is kept (``rho = 1``)."""

MIN_LENS_MATCHES = 4
"""Fewest matches for the lens terms once priors regularise them (8 rows, 5 unknowns)."""


@dataclass(frozen=True)
class RotationFit:
    """Robust rotation-only fit.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation, ``b2 = R b1``.
    inliers : ndarray of bool, shape (N,)
        Matches whose angular residual is below the threshold.
    residuals : ndarray, shape (N,)
        Angle (radians) between ``b2`` and ``R b1`` for every match.
    trials : int
        RANSAC hypotheses drawn.
    """

    R: np.ndarray
    inliers: np.ndarray
    residuals: np.ndarray
    trials: int

    @property
    def num_inliers(self) -> int:
        """Number of inliers."""
        return int(np.count_nonzero(self.inliers))


@dataclass(frozen=True)
class LensRotationFit:
    """Rotation with a shared focal scale and radial coefficient (:func:`fit_rotation_lens`).

    Attributes
    ----------
    R : ndarray, shape (3, 3)
    focal_scale : float
        ``s``: the given focal length over the true one.
    k1 : float
        Radial coefficient (OpenCV's ``k1``) of the true camera.
    focal_scale_sigma : float
        Standard deviation of ``focal_scale`` from the Gauss-Newton covariance (inf when not
        estimated, NaN when left out: :func:`fit_rotation_lens`'s ``deviations``).
    rotation_sigma_deg : float
        Root-mean-square angle (degrees) of the rotation's error from the same covariance, the
        lens terms estimated jointly under their priors (inf when they are not estimated): the
        Cramer-Rao bound of the rotation given these matches, their noise and the priors (NaN
        when left out).
    residuals : ndarray, shape (N,)
        Transfer error ``|pi(R c(x1)) - c(x2)| / s`` (normalised units of the given camera) of
        every match.
    principal_offset : ndarray, shape (2,)
        ``p``: the true principal point minus the given one over the true focal length (zero
        when not fitted).
    focal_ratio : float
        ``rho``: view 2's focal scale over view 1's (1 when not fitted).
    lens_excess : float
        How far the fitted ``s``, ``k1`` and ``rho`` lay beyond their box before they were
        clipped to it, in their own posterior deviations (``noise^2 (J^T J)^-1``): the largest
        of ``(|s - 1| - max_focal_change) / sd(s)`` and its likes, negative inside the box,
        ``-inf`` when the lens terms were not estimated, NaN when left out.
    offset_dropped : bool
        A principal-point offset was to be fitted and lay beyond its bound: the given
        principal point was kept.
    """

    R: np.ndarray
    focal_scale: float
    k1: float
    focal_scale_sigma: float
    residuals: np.ndarray
    rotation_sigma_deg: float = float("inf")
    principal_offset: np.ndarray = field(default_factory=lambda: np.zeros(2))
    focal_ratio: float = 1.0
    lens_excess: float = float("-inf")
    offset_dropped: bool = False

    @property
    def focal_scale2(self) -> float:
        """``s rho``: the focal scale of view 2 (given focal length over the true one)."""
        return self.focal_scale * self.focal_ratio

    @property
    def focal_significant(self) -> bool:
        """The focal scale differs from 1 by more than three standard deviations."""
        return bool(abs(self.focal_scale - 1.0) > 3.0 * self.focal_scale_sigma)


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def _bearings(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.shape[-1] == 2:
        x = np.concatenate([x, np.ones(x.shape[:-1] + (1,))], axis=-1)
    return _unit_rows(x)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of vectors (..., 3), written out as ``np.cross`` computes it."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _triads(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orthonormal frames (..., 3, 3) with columns bisector, normal, their cross product."""
    m = _unit_rows(a + b)
    c = _unit_rows(_cross(a, b))
    return np.stack([m, c, _cross(m, c)], axis=-1)


def rotations_from_two_rays(
    a1: ArrayLike, a2: ArrayLike, b1: ArrayLike, b2: ArrayLike
) -> np.ndarray:
    """Rotations mapping the ray pair ``(a1, a2)`` of view 1 onto ``(b1, b2)`` of view 2.

    Parameters
    ----------
    a1, a2 : array_like, shape (K, 3) or (K, 2)
        Bearings (made unit) or normalised points of two matches in view 1.
    b1, b2 : array_like, shape (K, 3) or (K, 2)
        Their bearings or normalised points in view 2.

    Returns
    -------
    ndarray, shape (K, 3, 3)
        ``R_k = T(b1_k, b2_k) T(a1_k, a2_k)^T`` with ``T`` the triad of bisector and normal;
        ``b_j = R a_j`` exactly when the angle between the two rays is the same in both views.
    """
    named = {"a1": a1, "a2": a2, "b1": b1, "b2": b2}
    rays = [_bearings(_checked_rows(x, name)) for name, x in named.items()]
    if len({len(ray) for ray in rays}) > 1:
        lengths = ", ".join(f"{name} {len(ray)}" for name, ray in zip(named, rays, strict=True))
        raise ValueError(f"a1, a2, b1 and b2 must have the same length, got {lengths}")
    return _two_ray_rotations(*rays)


def _two_ray_rotations(a1, a2, b1, b2) -> np.ndarray:
    """:func:`rotations_from_two_rays` of unit bearings (K, 3), unchecked."""
    return _triads(b1, b2) @ np.swapaxes(_triads(a1, a2), -1, -2)


def _checked_rows(value: Any, name: str) -> np.ndarray:
    """Normalised points (N, 2) or rays (N, 3) as finite float64 of magnitude at most
    :data:`ppo_cv.checks.MAX_COORDINATE`, no ray zero (it has no direction: every rotation
    maps it onto its match at angle 0); ValueError or TypeError naming ``name`` otherwise."""
    rows = as_finite_rows(value, name, (2, 3))
    if rows.size and not -MAX_COORDINATE <= rows.min() <= rows.max() <= MAX_COORDINATE:
        raise ValueError(
            f"{name} has coordinates up to {float(np.abs(rows).max()):.3g}, beyond "
            f"{MAX_COORDINATE:.0e}: not normalised points or rays"
        )
    if rows.shape[1] == 3 and not rows.any(axis=1).all():
        zero = int(np.count_nonzero(~rows.any(axis=1)))
        raise ValueError(f"{name} has {zero} zero row(s): a ray needs a direction")
    return rows


def _require_ahead(rows: np.ndarray, name: str) -> None:
    """ValueError naming ``name`` unless every ray (N, 3) has ``w > 0``: the least-squares
    rotation (:func:`ppo_cv.ppo.rotation_from_rays`) reads a ray as the image point ``x / w``,
    which turns a ray behind the image plane around and divides by a zero ``w``."""
    if rows.shape[1] == 3 and rows.size and rows[:, 2].min() <= 0:
        behind = int(np.count_nonzero(rows[:, 2] <= 0))
        raise ValueError(
            f"{name} has {behind} row(s) with w <= 0 (a ray at or behind the image plane): "
            "ransac_rotation takes normalised points or rays ahead of the camera"
        )


def _checked_matches(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Matches ``x1``, ``x2`` checked by :func:`_checked_rows`, of one length."""
    x1, x2 = _checked_rows(x1, "x1"), _checked_rows(x2, "x2")
    if len(x1) != len(x2):
        raise ValueError(f"x1 and x2 must have the same length, got {len(x1)} and {len(x2)}")
    return x1, x2


def rotation_residuals(R: ArrayLike, x1: ArrayLike, x2: ArrayLike) -> np.ndarray:
    """Angle (radians) between ``b2_i`` and ``R b1_i`` for every match, shape (N,).

    ``R`` is a rotation (3, 3); ``x1, x2`` are normalised points (N, 2), homogeneous points or
    bearings (N, 3).
    """
    R = as_rotation(R, "R")
    x1, x2 = _checked_matches(x1, x2)
    return _angles(R, x1, x2)


def _angles(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """:func:`rotation_residuals`, unchecked."""
    b1, b2 = _bearings(x1) @ np.asarray(R).T, _bearings(x2)
    cross = np.linalg.norm(_cross(b1, b2), axis=1)
    return np.arctan2(cross, np.einsum("ij,ij->i", b1, b2))


def _count_inliers(Rs: np.ndarray, b1: np.ndarray, b2: np.ndarray, cos_threshold: float):
    """Inlier count of each hypothesis (K,), all matches scored in blocks."""
    counts = np.zeros(len(Rs), dtype=np.int64)
    step = max(1, _BLOCK // max(len(b1), 1))
    for start in range(0, len(Rs), step):
        rotated = np.einsum("kij,nj->kni", Rs[start : start + step], b1)
        cosines = np.einsum("kni,ni->kn", rotated, b2)
        counts[start : start + step] = np.count_nonzero(cosines > cos_threshold, axis=1)
    return counts


def _required_trials(inlier_ratio: float, confidence: float) -> float:
    """Trials after which an all-inlier pair is missed with probability ``1 - confidence``."""
    p_good = inlier_ratio**2
    if p_good >= 1.0:
        return 1.0
    if p_good <= 0.0:
        return np.inf
    return np.log1p(-confidence) / np.log1p(-p_good)


def _least_squares(b1, b2, used, threshold, rounds: int = 10):
    R = rotation_from_rays(b1[used], b2[used])
    for _ in range(rounds):
        within = _angles(R, b1, b2) < threshold
        if np.count_nonzero(within) < 2 or np.array_equal(within, used):
            break
        used = within
        R = rotation_from_rays(b1[used], b2[used])
    return R


def ransac_rotation(
    x1: ArrayLike,
    x2: ArrayLike,
    threshold: float,
    *,
    confidence: float = 0.9999,
    min_trials: int = 50,
    max_trials: int = 10_000,
    seed: int = 0,
) -> RotationFit | None:
    """Robust rotation ``b2 = R b1`` from putative matches.

    Parameters
    ----------
    x1, x2 : array_like, shape (N, 2) or (N, 3)
        Normalised (undistorted) points or bearings of the matches, N >= 2; rows of three
        have ``w > 0`` (a ray ahead of the camera).
    threshold : float
        Inlier bound on the angle between ``b2`` and ``R b1``, radians (pixels over focal), > 0.
    confidence : float
        Stop once a better hypothesis is this unlikely to be missed, in (0, 1].
    min_trials, max_trials : int
        Bounds on the number of hypotheses, >= 0.
    seed : int
        Seed of the sampler, >= 0; the result is a function of the inputs and the seed.

    Returns
    -------
    RotationFit or None
        None when fewer than two matches are given.
    """
    x1, x2 = _checked_matches(x1, x2)
    _require_ahead(x1, "x1")
    _require_ahead(x2, "x2")
    settings = as_ransac_settings(threshold, confidence, min_trials, max_trials, seed)
    return _ransac(_bearings(x1), _bearings(x2), *settings)


def _ransac(b1, b2, threshold, confidence, min_trials, max_trials, seed) -> RotationFit | None:
    """:func:`ransac_rotation` of checked bearings ``b1``, ``b2`` (N, 3) and settings."""
    n = len(b1)
    if n < 2:
        return None
    rng = np.random.default_rng(seed)
    cos_threshold = float(np.cos(threshold))
    best_R, best_count, trials, needed = np.eye(3), -1, 0, float(max_trials)
    while trials < max(min_trials, min(needed, max_trials)):
        first = rng.integers(0, n, _BATCH)
        second = (first + rng.integers(1, n, _BATCH)) % n
        Rs = _two_ray_rotations(b1[first], b1[second], b2[first], b2[second])
        counts = _count_inliers(Rs, b1, b2, cos_threshold)
        trials += _BATCH
        k = int(np.argmax(counts))
        if counts[k] > best_count:
            best_R, best_count = Rs[k], int(counts[k])
            needed = _required_trials(best_count / n, confidence)
    used = _angles(best_R, b1, b2) < threshold
    R = _least_squares(b1, b2, used, threshold) if np.count_nonzero(used) >= 2 else best_R
    residuals = _angles(R, b1, b2)
    return RotationFit(R=R, inliers=residuals < threshold, residuals=residuals, trials=trials)


def correct_points(
    x: ArrayLike, focal_scale: float, k1: float, principal_offset: ArrayLike = (0.0, 0.0)
) -> np.ndarray:
    """Normalised points of the given camera (N, 2 or 3) to homogeneous true rays (N, 3); a
    row of three is the point ``(x / w, y / w)``.

    The inverse of ``s x = p + q (1 + k1 |q|^2)``: the lens terms of :func:`fit_rotation_lens`
    (``focal_scale`` ``s`` in [0.001, 1000], ``|k1| <= 10``, ``principal_offset`` ``p`` (2,)).
    """
    scale, k1, offset, _ = _checked_lens_terms(focal_scale, k1, principal_offset, 1.0)
    return _correct_points(_image_points(_checked_rows(x, "x"), "x"), scale, k1, offset)


def _image_points(rows: np.ndarray, name: str) -> np.ndarray:
    """Checked rows (N, 2) or (N, 3) as the lens maps read them: a row of three as the image
    point ``(x / w, y / w)`` it stands for (rows of ``w = 1`` as they are), where they read its
    ``x`` and ``y`` as they stood; ValueError naming ``name`` for ``w = 0`` or ``|(x, y)|``
    beyond :data:`ppo_cv.checks.MAX_RAY_SLOPE` ``|w|``."""
    return rows if rows.shape[1] == 2 else _on_image_plane(rows, name)


def _lens_matches(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Matches checked by :func:`_checked_matches`, rows of three as :func:`_image_points`."""
    x1, x2 = _checked_matches(x1, x2)
    return _image_points(x1, "x1"), _image_points(x2, "x2")


_SCALE_RANGE = (1e-3, 1e3)
"""Accepted focal scales and focal ratios of the public lens maps: beyond, the lens terms
mean no lens, and the maps would overflow."""


def _checked_lens_terms(focal_scale, k1, principal_offset, focal_ratio) -> tuple:
    """``(focal_scale, k1, principal_offset (2,), focal_ratio)`` of the lens maps checked;
    ValueError or TypeError naming the argument."""
    scale, ratio = as_number(focal_scale, "focal_scale"), as_number(focal_ratio, "focal_ratio")
    for value, name in ((scale, "focal_scale"), (ratio, "focal_ratio")):
        if not _SCALE_RANGE[0] <= value <= _SCALE_RANGE[1]:
            raise ValueError(
                f"{name} must be a number in [{_SCALE_RANGE[0]:g}, {_SCALE_RANGE[1]:g}] (a given "
                f"focal length over the true one), got {value}"
            )
    k1 = as_number(k1, "k1")
    if not abs(k1) <= MAX_RADIAL:
        raise ValueError(f"k1 must be a finite number within +-{MAX_RADIAL:g}, got {k1}")
    if principal_offset is None or np.shape(principal_offset) not in ((), (2,)):
        raise TypeError(
            f"principal_offset must be two numbers (x, y), got {shown(principal_offset)}"
        )
    offset = as_finite_array(np.broadcast_to(principal_offset, (2,)), "principal_offset")
    if np.abs(offset).max() > MAX_COORDINATE:
        raise ValueError(
            f"principal_offset must be within {MAX_COORDINATE:.0e}, got {offset.tolist()}"
        )
    return scale, k1, offset, ratio


def _correct_points(x: np.ndarray, focal_scale, k1, principal_offset) -> np.ndarray:
    """:func:`correct_points`, unchecked."""
    xy = np.asarray(x, dtype=np.float64)[:, :2]
    offset = np.broadcast_to(np.asarray(principal_offset, dtype=np.float64), (2,))[:, None]
    q = np.empty_like(xy)  # laid out as the given points, which the products of the rays follow
    q.T[...] = _true_rows(np.ascontiguousarray(xy.T), focal_scale, k1, offset)
    return np.column_stack([q, np.ones(len(q))])


def seen_through_lens(ray: ArrayLike, scale, k1, offset, ratio) -> np.ndarray:
    """Given normalised points (..., N, 2) where view 2 sees rays (..., N, 3) of its frame
    through the lens of :func:`fit_rotation_lens`: ``x2 = (p + q2 (1 + k1 |q2|^2)) / (s rho)``,
    ``q2`` the ray's projection, at most :data:`ppo_cv.checks.MAX_RAY_SLOPE` (beyond it
    ``|q2|^2`` overflows); the lens terms (finite, ``scale`` and ``ratio`` > 0) broadcast
    against ``q2``."""
    ray = as_finite_array(ray, "ray")
    if ray.ndim < 2 or ray.shape[-1] != 3:
        raise ValueError(f"ray must have shape (..., N, 3), got {ray.shape}")
    beyond = np.abs(ray[..., :2]).max(axis=-1) / MAX_RAY_SLOPE > np.abs(ray[..., 2])
    if beyond.any():
        raise ValueError(
            f"ray has {int(beyond.sum())} ray(s) at or near right angles to the optical axis "
            f"(|(x, y)| beyond {MAX_RAY_SLOPE:.0e} |z|): they meet the image plane nowhere"
        )
    names = ("scale", "k1", "offset", "ratio")
    terms = [as_finite_array(value, name)
             for value, name in zip((scale, k1, offset, ratio), names, strict=True)]  # fmt: skip
    for value, name in ((terms[0], "scale"), (terms[3], "ratio")):
        if value.size and value.min() <= 0:
            raise ValueError(f"{name} must be > 0, got {value.min()}")
    try:
        np.broadcast_shapes(ray.shape[:-1] + (2,), *(term.shape for term in terms))
    except ValueError:
        shapes = ", ".join(f"{name} {term.shape}" for name, term in zip(names, terms, strict=True))
        raise ValueError(
            f"the lens terms ({shapes}) do not broadcast against the points "
            f"{ray.shape[:-1] + (2,)} of ray {ray.shape}"
        ) from None
    return _seen_through_lens(ray, *terms)


def _seen_through_lens(ray: np.ndarray, scale, k1, offset, ratio) -> np.ndarray:
    """:func:`seen_through_lens`, unchecked."""
    z = np.where(np.abs(ray[..., 2:]) > 1e-9, ray[..., 2:], 1e-9)
    q2 = ray[..., :2] / z
    distorted = q2 * (1.0 + k1 * (q2[..., :1] * q2[..., :1] + q2[..., 1:] * q2[..., 1:])) + offset
    return distorted / (scale * ratio)


def _lens_transfer(params: np.ndarray, R0: np.ndarray, xy1: np.ndarray, xy2: np.ndarray):
    """Residual vectors (N, 2) in view 2, given normalised units, of the lens terms ``params``
    (8,) (:func:`_transfer_rows`): ``x2`` minus the transfer of ``x1`` (N, 2), laid out as the
    difference of a C-ordered array and ``x2``."""
    distorted = _forward(params, R0, np.ascontiguousarray(xy1.T))[-1]
    return np.ascontiguousarray((distorted / ((1.0 + params[3]) * (1.0 + params[7]))).T) - xy2


def _lens_params(
    focal_scale: float, k1: float, principal_offset: ArrayLike, focal_ratio: float = 1.0
) -> np.ndarray:
    offset = np.broadcast_to(np.asarray(principal_offset, dtype=np.float64), (2,))
    return np.r_[0.0, 0.0, 0.0, focal_scale - 1.0, k1, offset, focal_ratio - 1.0]


def transfer_points(
    x1: ArrayLike,
    R: ArrayLike,
    focal_scale: float,
    k1: float,
    principal_offset: ArrayLike = (0.0, 0.0),
    focal_ratio: float = 1.0,
) -> np.ndarray:
    """Where the lens rotation of :func:`fit_rotation_lens` takes normalised points of view 1.

    ``x1`` (N, 2 or 3, given camera; a row of three the point ``(x / w, y / w)``) is corrected
    to the true ray ``q1``, rotated by ``R`` (3, 3) and put back through the lens:
    ``x2 = (p + q2 (1 + k1 |q2|^2)) / (s rho)``, the lens terms as :func:`correct_points` takes
    them (``rho`` as ``s``). Returns ``x2``, (N, 2).
    """
    R = as_rotation(R, "R")
    terms = _checked_lens_terms(focal_scale, k1, principal_offset, focal_ratio)
    return _transfer_points(_image_points(_checked_rows(x1, "x1"), "x1"), R, *terms)


def _transfer_points(x1, R, focal_scale, k1, principal_offset, focal_ratio) -> np.ndarray:
    """:func:`transfer_points`, unchecked."""
    xy1 = np.asarray(x1, float)[:, :2]
    params = _lens_params(focal_scale, k1, principal_offset, focal_ratio)
    return _lens_transfer(params, np.asarray(R, float), xy1, np.zeros_like(xy1))


def lens_rotation_residuals(
    R: ArrayLike,
    focal_scale: float,
    k1: float,
    x1: ArrayLike,
    x2: ArrayLike,
    principal_offset: ArrayLike = (0.0, 0.0),
    focal_ratio: float = 1.0,
    *,
    vectors: bool = False,
) -> np.ndarray:
    """Transfer error (N,) of matches under :func:`fit_rotation_lens`'s model, normalised units
    of view 2; with ``vectors`` the error vectors (N, 2), ``x2`` minus the transfer of ``x1``
    (N, 2 or 3), the rotation (3, 3) and lens terms as :func:`transfer_points` takes them."""
    R = as_rotation(R, "R")
    terms = _checked_lens_terms(focal_scale, k1, principal_offset, focal_ratio)
    x1, x2 = _lens_matches(x1, x2)
    vectors = as_flag(vectors, "vectors")
    return _lens_rotation_residuals(R, terms[0], terms[1], x1, x2, *terms[2:], vectors=vectors)


def _lens_rotation_residuals(
    R, focal_scale, k1, x1, x2, principal_offset=(0.0, 0.0), focal_ratio=1.0, *, vectors=False
) -> np.ndarray:
    """:func:`lens_rotation_residuals`, unchecked."""
    params = _lens_params(focal_scale, k1, principal_offset, focal_ratio)
    xy1, xy2 = np.asarray(x1, float)[:, :2], np.asarray(x2, float)[:, :2]
    transfers = _lens_transfer(params, np.asarray(R, float), xy1, xy2)
    return transfers if vectors else np.linalg.norm(transfers, axis=1)


def focal_ratio_prior(given_ratio: float) -> tuple[float, float] | None:
    """Mean and deviation of the prior on ``rho`` of :func:`fit_rotation_lens` for two focal
    lengths given in the ratio ``r`` (view 2 over view 1); None to keep ``rho = 1``.

    One focal length given for both views (``r = 1``) states one lens at one zoom: the ratio is
    kept. Two that differ by at most :data:`FOCAL_RATIO_GAP` are taken as two estimates of one
    lens, each with its own error: the truth lies between ``rho = 1`` (the given lengths right)
    and ``rho = r`` (the lens the same), so the prior is centred between them with half their
    distance as deviation. With the ratio held, 8 of 14 warped pans (``ppo_cv.data_gen``, the
    principal point given at the centre and each focal length off by a further +-1 %) were
    called general motions; with it none (``docs/pure_rotation.md``). The price falls on
    translations along the optical axis, whose flow at the scene's mean depth is a zoom that a
    misreported ratio can cancel: 3 of 14 ``tiny-baseline`` pairs at baseline / depth 0.02
    told focal lengths so were flagged (2 with the ratio held, none told one focal length).

    Examples
    --------
    >>> focal_ratio_prior(1.0) is None, focal_ratio_prior(1.2) is None
    (True, True)
    >>> mean, sigma = focal_ratio_prior(1.01)
    >>> round(mean, 4), round(sigma, 4)
    (1.005, 0.005)
    """
    gap = abs(as_positive(given_ratio, "given_ratio") - 1.0)
    if not 1e-6 < gap <= FOCAL_RATIO_GAP:
        return None
    return (1.0 + float(given_ratio)) / 2.0, gap / 2.0


def focal_ratio_keywords(prior: tuple[float, float] | None) -> dict:
    """A prior ``(mean, deviation)`` of :func:`focal_ratio_prior` as keyword arguments of
    :func:`fit_rotation_lens` (and of ``ppo_cv.photometric.refine_rotation_photometric``): empty
    for None, the ratio kept.

    >>> focal_ratio_keywords(None)
    {}
    >>> sorted(focal_ratio_keywords(focal_ratio_prior(1.01)))
    ['focal_ratio_mean', 'focal_ratio_prior']
    """
    if prior is None:
        return {}
    sized = hasattr(prior, "__len__") and getattr(prior, "ndim", 1) != 0  # not a 0-d array
    if isinstance(prior, (str, bytes)) or not sized or len(prior) != 2:
        raise TypeError(
            f"prior must be None or (mean, deviation), as focal_ratio_prior returns it, got "
            f"{shown(prior)}"
        )
    mean, deviation = as_positive(prior[0], "prior mean"), as_positive(prior[1], "prior deviation")
    return {"focal_ratio_mean": mean, "focal_ratio_prior": deviation}


def fit_rotation_lens(
    x1: ArrayLike,
    x2: ArrayLike,
    used: ArrayLike,
    R: ArrayLike,
    *,
    iterations: int = 15,
    max_focal_change: float = MAX_FOCAL_CHANGE,
    max_k1: float = MAX_K1,
    noise: float | None = None,
    focal_prior: float = FOCAL_PRIOR,
    k1_prior: float = K1_PRIOR,
    principal_prior: float | np.ndarray | None = None,
    focal_ratio_prior: float | None = None,
    focal_ratio_mean: float = 1.0,
    principal_bound: float = PRINCIPAL_BOUND,
    lens_start: LensRotationFit | None = None,
    deviations: bool | Callable[[LensRotationFit], bool] = True,
    check_input: bool = True,
) -> LensRotationFit:
    """Rotation, focal scale, radial coefficient (principal point, focal ratio) by Gauss-Newton.

    The model of the module docstring (``s x1 = p + q1 (1 + k1 |q1|^2)``, ``s rho x2 = ...``,
    ``(q2, 1) ~ R (q1, 1)``, ``R = exp([w]_x) R0``) minimising the squared transfer error in
    view 2. Lens terms outside the box of plausible lenses (``|s - 1|, |rho - 1| <=
    max_focal_change``, ``|k1| <= max_k1``) are clipped to it and the rotation alone refitted;
    an offset beyond ``principal_bound`` priors on either coordinate by more than
    :data:`PRINCIPAL_SIGNIFICANCE` posterior deviations, and a ratio beyond
    :data:`FOCAL_RATIO_BOUND` priors from its mean, are dropped: a translation's parallax must
    not be explained away by an implausible lens. Given the ``noise`` of a transfer-error
    coordinate the lens terms get Gaussian priors ``s - 1 ~ N(0, focal_prior^2)``, ``k1 ~ N(0,
    k1_prior^2)``, ``p ~ N(0, principal_prior^2 I)``, ``rho ~ N(focal_ratio_mean,
    focal_ratio_prior^2)`` (a few matches, or matches near the centre, do not determine them).

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalised points of the matches; a row of three is the point ``(x / w, y / w)``.
    used : ndarray of bool, shape (N,)
        Matches in the cost (at least 12 for the lens terms).
    R : ndarray, shape (3, 3)
        Starting rotation (e.g. :func:`ransac_rotation`'s).
    iterations : int
        Gauss-Newton steps (each a Levenberg-damped solve, the transfer's Jacobian analytic).
    max_focal_change, max_k1, principal_bound : float
        Bounds on ``|s - 1|`` (and ``|rho - 1|``), ``|k1|`` and the offset ``p`` kept (in
        ``principal_prior`` deviations per coordinate).
    noise : float, optional
        Deviation of a transfer-error coordinate (normalised units); None fits without priors.
    focal_prior, k1_prior : float
        Deviations of the priors on ``s - 1`` and ``k1`` (a ``focal_prior`` of 0 holds ``s`` at 1).
    principal_prior : float or array_like of 2 floats, optional
        Deviation of each coordinate of ``p`` (pixels over the focal length), one for both or
        ``(x, y)``; None keeps the given principal point (``p = 0``). Needs ``noise``.
    focal_ratio_prior, focal_ratio_mean : float
        Deviation (None keeps ``rho = 1``; needs ``noise``) and mean of the prior on ``rho``.
    lens_start : LensRotationFit, optional
        A fit of nearly the same matches whose lens terms the steps start from (fewer steps).
    deviations : bool or callable
        Compute the deviations and ``lens_excess`` (else NaN, inf when clipped), or a callable
        given the fit without them that says whether to.
    check_input : bool
        False skips the checks, for callers of checked arrays (the refit's outlier loops).

    Returns
    -------
    LensRotationFit
        Residuals for all N matches.

    Examples
    --------
    A 10 degree pan seen through a focal length given 3 % long for view 2 only:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> q1 = rng.uniform(-0.3, 0.3, (200, 2))
    >>> c, s = np.cos(np.radians(10.0)), np.sin(np.radians(10.0))
    >>> R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> ray = np.column_stack([q1, np.ones(200)]) @ R.T
    >>> x2 = ray[:, :2] / ray[:, 2:] / 1.03
    >>> fit = fit_rotation_lens(q1, x2, np.ones(200, bool), np.eye(3), noise=1e-4,
    ...                         focal_ratio_prior=0.02)
    >>> round(fit.focal_ratio, 4), bool(np.allclose(fit.R, R, atol=1e-6))
    (1.03, True)
    """
    if check_input:
        x1, x2 = _lens_matches(x1, x2)
        used, R = _checked_used(used, len(x1)), as_rotation(R, "R")
        keywords = _checked_fit_keywords(
            iterations, max_k1, noise, focal_prior, k1_prior, principal_prior, focal_ratio_prior,
            focal_ratio_mean, lens_start, deviations, max_focal_change, principal_bound,
        )  # fmt: skip
        return fit_rotation_lens(x1, x2, used, R, **keywords, check_input=False)
    free, prior, centre, bounds, offset_bound = _lens_terms_setup(
        noise, focal_prior, k1_prior, principal_prior, focal_ratio_prior, focal_ratio_mean,
        principal_bound, max_focal_change, max_k1,
    )  # fmt: skip
    problem, rows1, rows2 = _problem(x1, x2, used, R, prior, free, centre)
    limits = bounds, offset_bound, noise, focal_ratio_prior
    return _solve_rotation_lens(problem, rows1, rows2, *limits, iterations, lens_start, deviations)


def _checked_used(used: Any, count: int) -> np.ndarray:
    """``used`` as a boolean mask (``count``,); TypeError or ValueError naming it otherwise
    (an integer array would index the matches, not select them)."""
    if used is None:
        raise TypeError("used is required, got None")
    mask = np.asarray(used)
    if mask.dtype != np.bool_:
        raise TypeError(f"used must be a boolean mask of the matches, got dtype {mask.dtype}")
    if mask.shape != (count,):
        raise ValueError(f"used must have one entry per match ({count}), got shape {mask.shape}")
    return mask


def _checked_fit_keywords(
    iterations, max_k1, noise, focal_prior, k1_prior, principal_prior, focal_ratio_prior,
    focal_ratio_mean, lens_start, deviations, max_focal_change, principal_bound,
) -> dict:  # fmt: skip
    """The keywords of :func:`fit_rotation_lens` checked (``max_focal_change`` and
    ``principal_bound`` where they are used); ValueError or TypeError naming each."""
    if lens_start is not None:
        require_instance(lens_start, LensRotationFit, "lens_start")
    if not (isinstance(deviations, (bool, np.bool_)) or callable(deviations)):
        raise TypeError(
            f"deviations must be True, False or a callable taking the fit, got "
            f"{type(deviations).__name__} {shown(deviations)}"
        )
    max_k1 = as_number(max_k1, "max_k1")
    if not max_k1 > 0:  # infinite: k1 unbounded
        raise ValueError(f"max_k1 must be a number > 0 (inf for no bound), got {max_k1}")
    optional = {"noise": noise, "focal_ratio_prior": focal_ratio_prior}
    optional = {name: None if value is None else as_nonnegative(value, name)
                for name, value in optional.items()}  # fmt: skip
    return {
        "iterations": as_whole_number(iterations, "iterations", 0, 10_000),
        "max_k1": max_k1,
        "focal_prior": as_nonnegative(focal_prior, "focal_prior"),
        "k1_prior": as_positive(k1_prior, "k1_prior"),
        "principal_prior": _checked_principal_prior(principal_prior),
        "focal_ratio_mean": as_positive(focal_ratio_mean, "focal_ratio_mean"),
        "lens_start": lens_start, "deviations": deviations, **optional,
        "max_focal_change": max_focal_change, "principal_bound": principal_bound,
    }  # fmt: skip


def _checked_principal_prior(value: Any) -> Any:
    """A ``principal_prior`` of :func:`fit_rotation_lens`: None, or one or two finite numbers
    >= 0, returned as given."""
    if value is None:
        return None
    if np.shape(value) not in ((), (2,)):
        raise ValueError(
            f"principal_prior must be one number or two (x, y), got shape {np.shape(value)}"
        )
    prior = as_finite_array(value, "principal_prior")
    if prior.min() < 0:
        raise ValueError(f"principal_prior must be >= 0, got {prior.tolist()}")
    return value


def _problem(x1, x2, used, R, prior, free, centre) -> tuple:
    """The least-squares problem of :func:`fit_rotation_lens` (the start rotation, the ``used``
    matches' coordinates as rows (2, I) of each view, the priors' weights, the free terms and
    the priors' means) and the coordinates of all matches, rows (2, N) of each view."""
    rows1, rows2 = (np.ascontiguousarray(np.asarray(x, float)[:, :2].T) for x in (x1, x2))
    return (np.asarray(R, float), rows1[:, used], rows2[:, used], prior, free, centre), rows1, rows2


def _start_params(lens_start: LensRotationFit | None, free, centre, bounds) -> np.ndarray:
    """Parameters (8,) the steps start from: ``lens_start``'s free lens terms when it lies
    in the box, else the priors' means ``centre``; no rotation increment."""
    if lens_start is None:
        return centre.copy()
    lens = _lens_params(lens_start.focal_scale, lens_start.k1, lens_start.principal_offset,
                        lens_start.focal_ratio)  # fmt: skip
    return np.where(free & ~_ROTATION & np.all(np.abs(lens) <= bounds), lens, centre)


def _solve_rotation_lens(
    problem, rows1, rows2, bounds, offset_bound, noise, focal_ratio_prior, iterations,
    lens_start, deviations,
) -> LensRotationFit:  # fmt: skip
    """:func:`fit_rotation_lens` on its ``problem``, the steps started from ``lens_start``
    (:func:`_start_params`): lens terms beyond their box clipped and the rotation alone
    refitted; residuals over all matches, whose coordinates are the rows of ``rows1``,
    ``rows2`` (2, N); the deviations at the minimum before the clipping when ``deviations``
    asks for them."""
    R0, a, b, prior, free, centre = problem
    with_noise = noise is not None and noise > 0
    count = a.shape[1]
    enough = count >= (MIN_LENS_MATCHES if with_noise else 2 * int(np.count_nonzero(_LENS)))
    params = _start_params(lens_start, free, centre, bounds) if enough else centre.copy()
    minimum = None
    if enough:
        fitted = _gauss_newton(params, problem, iterations)
        params, problem, forward = _without_implausible_terms(
            fitted, problem, offset_bound, noise, focal_ratio_prior, iterations
        )
        minimum = params, problem, forward
    clipped = bool(np.any(np.abs(params) > bounds)) or not enough
    if clipped:
        params = np.clip(params, -bounds, bounds)
        params[:3] = 0.0
        if count >= 2:
            params = _gauss_newton(params, (R0, a, b, prior, _ROTATION, centre), iterations)[0]
    R_final = _rotation_increment(params[:3]) @ R0
    lens_only = np.r_[0.0, 0.0, 0.0, params[3:]]
    error = _transfer_rows(lens_only, R_final, rows1, rows2)
    unknown = np.inf if clipped else np.nan
    fit = LensRotationFit(
        R=R_final,
        focal_scale=1.0 + float(params[3]),
        k1=float(params[4]),
        focal_scale_sigma=unknown,
        residuals=np.sqrt(error[0] * error[0] + error[1] * error[1]),
        rotation_sigma_deg=unknown,
        principal_offset=params[5:7].copy(),
        focal_ratio=1.0 + float(params[7]),
        lens_excess=np.nan if minimum is not None and with_noise else -np.inf,
        offset_dropped=bool(free[5] and not problem[4][5]),
    )
    if minimum is None or not (deviations(fit) if callable(deviations) else deviations):
        return fit
    sigma, rotation_sigma, excess = _deviations(*minimum, bounds, noise if with_noise else None)
    if clipped:
        sigma = rotation_sigma = np.inf
    return replace(fit, focal_scale_sigma=sigma, rotation_sigma_deg=rotation_sigma,
                   lens_excess=excess)  # fmt: skip


def _deviations(params, problem, forward, bounds, noise) -> tuple[float, float, float]:
    """The focal scale's and the rotation's deviations (:func:`_sigmas`) and the lens excess
    (:func:`_lens_excess`, -inf without the ``noise``) of the minimum ``params`` of
    ``problem``, its :func:`_forward` pass ``forward``."""
    residual = _residual(params, problem, forward)
    inverse = _gauss_newton_covariance(_jacobian(params, problem, forward), 1.0)
    sigma, rotation_sigma = _sigmas(residual, inverse, problem)
    if noise is None:
        return sigma, rotation_sigma, float("-inf")
    return sigma, rotation_sigma, _lens_excess(params, inverse, problem, bounds, noise)


def _lens_terms_setup(
    noise, focal_prior, k1_prior, principal_prior, focal_ratio_prior, focal_ratio_mean,
    principal_bound, max_focal_change, max_k1,
):  # fmt: skip
    """Free terms, prior weights, prior means and bounds of :func:`fit_rotation_lens`'s
    parameters (the offset and the ratio free only with their priors and the noise), and the
    largest offset per coordinate (None when it is not fitted)."""
    with_noise = noise is not None and noise > 0
    if principal_prior is not None:
        principal_prior = np.broadcast_to(np.asarray(principal_prior, dtype=float), (2,))
    fit_offset = principal_prior is not None and bool(np.all(principal_prior > 0)) and with_noise
    principal_bound = as_positive(principal_bound, "principal_bound")
    max_focal_change = as_positive(max_focal_change, "max_focal_change")
    offset_bound = principal_bound * principal_prior if fit_offset else None
    fit_ratio = focal_ratio_prior is not None and focal_ratio_prior > 0 and with_noise
    free = _LENS | (_OFFSET if fit_offset else False) | (_RATIO if fit_ratio else False)
    free[3] = focal_prior != 0
    bounds = np.full(_NPARAMS, np.inf)
    bounds[[3, 4, 7]] = max_focal_change, max_k1, max_focal_change
    prior = np.zeros(_NPARAMS)
    if with_noise:
        prior[3:5] = noise / np.array([focal_prior if free[3] else np.inf, k1_prior])
    if fit_offset:
        prior[5:7] = noise / principal_prior
    centre = np.zeros(_NPARAMS)
    if fit_ratio:
        prior[7], centre[7] = noise / focal_ratio_prior, focal_ratio_mean - 1.0
    return free, prior, centre, bounds, offset_bound


def _without_implausible_terms(fitted, problem, offset_bound, noise, focal_ratio_prior, iterations):
    """Parallax, not a lens: an offset beyond its bound or a ratio beyond
    :data:`FOCAL_RATIO_BOUND` priors from its mean is dropped (no offset, ratio 1) and the rest
    fitted again; ``fitted`` is :func:`_gauss_newton`'s ``(params, forward)``. Returns
    ``(params, problem, forward)`` with the terms left free."""
    R0, a, b, prior, free, centre = problem
    params, forward = fitted
    for _ in range(2):
        implausible = np.zeros(_NPARAMS, dtype=bool)
        if free[5] and _offset_beyond_bound(params, problem, offset_bound, noise, forward):
            implausible |= _OFFSET
        if free[7] and abs(params[7] - centre[7]) > FOCAL_RATIO_BOUND * focal_ratio_prior:
            implausible |= _RATIO
        if not np.any(implausible):
            break
        free = free & ~implausible
        problem = (R0, a, b, prior, free, centre)
        params, forward = _gauss_newton(np.where(free, centre, 0.0), problem, iterations)
    return params, problem, forward


def _objective(params, problem) -> tuple[np.ndarray, tuple]:
    """:func:`_residual` at ``params`` (8,) and the :func:`_forward` pass it came from."""
    forward = _forward(params, problem[0], problem[1])
    return _residual(params, problem, forward), forward


def _residual(params, problem, forward) -> np.ndarray:
    """Transfer residuals (2I,), x and y of each match in turn, followed by the prior rows of
    the fitted parameters, at ``params`` (8,) from its :func:`_forward` pass."""
    R0, a, b, prior, free, centre = problem
    transfer = forward[-1] / ((1.0 + params[3]) * (1.0 + params[7])) - b
    return np.concatenate([transfer.T.ravel(), prior[free] * (params - centre)[free]])


def _forward(params: np.ndarray, R0: np.ndarray, rows1: np.ndarray) -> tuple:
    """The transfer of view 1's points ``rows1`` (2, N) at ``params`` (8,): the rotation
    (3, 3), true points ``q1`` (2, N), rays (3, N), their depths (N,), projections ``q2``
    (2, N), ``|q2|^2`` (N,) and view 2's distorted points (2, N), before the focal scale."""
    R = _rotation_increment(params[:3]) @ R0
    k1, offset = params[4], params[5:7, None]
    q1 = _true_rows(rows1, 1.0 + params[3], k1, offset)
    ray = R[:, :2] @ q1 + R[:, 2:]
    z = np.where(np.abs(ray[2]) > 1e-9, ray[2], 1e-9)
    q2 = ray[:2] / z
    norm2 = q2[0] * q2[0] + q2[1] * q2[1]
    return R, q1, ray, z, q2, norm2, q2 * (1.0 + k1 * norm2) + offset


def _true_rows(rows: np.ndarray, scale, k1, offset, iterations: int = 6) -> np.ndarray:
    """True normalised points ``q`` (2, N) of the given points ``rows`` (2, N),
    ``s x = p + q (1 + k1 |q|^2)`` solved by fixed-point iteration; ``offset`` ``p`` (2, 1)."""
    distorted = scale * rows - offset
    q = distorted
    for _ in range(iterations):
        q = distorted / (1.0 + k1 * (q[0] * q[0] + q[1] * q[1]))
    return q


def _transfer_rows(params: np.ndarray, R0: np.ndarray, rows1: np.ndarray, rows2: np.ndarray):
    """Residuals (2, N) in view 2 of the points ``rows1``, ``rows2`` (2, N) at ``params`` (8,):
    ``x2`` minus the transfer of ``x1`` (``q1`` rotated, distorted and scaled back by view 2's
    focal scale)."""
    distorted = _forward(params, R0, rows1)[-1]
    return distorted / ((1.0 + params[3]) * (1.0 + params[7])) - rows2


def _jacobian(params, problem, forward) -> np.ndarray:
    """Jacobian of :func:`_residual` in the free parameters of ``problem``, Fortran order:
    analytic (:func:`_transfer_jacobian`, from the :func:`_forward` pass at ``params``) with
    the prior rows below."""
    R0, a, b, prior, free, centre = problem
    transfer = _transfer_jacobian(params, a, forward)
    count, size = a.shape[1], int(np.count_nonzero(free))
    if np.all(free[:size]):
        transfer = transfer[:, :size]
    else:
        transfer = transfer[:, free]
    columns = np.empty((size, 2 * count + size))
    columns[:, : 2 * count].reshape(size, count, 2)[...] = transfer.transpose(1, 2, 0)
    columns[:, 2 * count :] = np.diag(prior[free])
    return columns.T


def _transfer_jacobian(params: np.ndarray, rows1: np.ndarray, forward) -> np.ndarray:
    """Derivatives (2, 8, N) of the residuals of :func:`_transfer_rows` at ``params`` (8,) in
    every parameter, from the :func:`_forward` pass of ``rows1`` there.

    ``q1`` solves ``s x1 - p = q1 (1 + k1 |q1|^2)``, so ``D1 dq1 = x1 ds - dp - q1 |q1|^2 dk1``
    with ``D = (1 + k1 |q|^2) I + 2 k1 q q^T``; a rotation increment moves the ray ``R q1`` by
    ``-[R q1]_x J(w) dw``, ``J`` the left Jacobian of the rotation's exponential; view 2's
    distortion of the projection ``q2`` changes by ``D2 dq2 + q2 |q2|^2 dk1 + dp``, and the
    transfer is that over ``s rho``."""
    scale, k1, ratio = 1.0 + params[3], params[4], 1.0 + params[7]
    R, q1, ray, z, q2, norm2, distorted = forward
    d_ray = np.empty((3, 7, q1.shape[1]))
    _rotation_rays(_left_jacobian(params[:3]), ray, d_ray[:, :3])
    d_q1 = _distortion_solve(q1, k1, rows1)
    np.multiply(R[:, 0, None, None], d_q1[0], out=d_ray[:, 3:])
    d_ray[:, 3:] += R[:, 1, None, None] * d_q1[1]
    d_q2 = np.multiply(q2[:, None], d_ray[2])
    np.subtract(d_ray[:2], d_q2, out=d_q2)
    d_q2 /= z
    derivative = np.empty((2, _NPARAMS, q1.shape[1]))
    _distortion_apply(q2, norm2, k1, d_q2, derivative[:, :7])
    derivative[:, 4] += q2 * norm2
    derivative[0, 5] += 1.0
    derivative[1, 6] += 1.0
    derivative[:, :7] /= scale * ratio
    derivative[:, 3] -= distorted / (scale * scale * ratio)
    derivative[:, 7] = -distorted / (scale * ratio * ratio)
    return derivative


def _rotation_rays(J: np.ndarray, ray: np.ndarray, out: np.ndarray) -> None:
    """``J[:, k] x ray`` into ``out`` (3, 3, N) for each column ``k`` of ``J`` (3, 3) and ray
    (3, N): the change of the rays under the rotation increments, written out as ``np.cross``
    computes it."""
    other = np.empty(out.shape[1:])
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.multiply(J[j, :, None], ray[k], out=out[i])
        np.multiply(J[k, :, None], ray[j], out=other)
        out[i] -= other


def _distortion_apply(q: np.ndarray, norm2: np.ndarray, k1: float, d: np.ndarray, out) -> None:
    """``D d`` into ``out`` (2, M, N), ``D = d (q (1 + k1 |q|^2)) / dq`` at points ``q`` (2, N),
    ``norm2`` their ``|q|^2`` (N,), ``d`` (2, M, N)."""
    x, y = q
    radial = 1.0 + k1 * norm2
    kx, ky = 2.0 * k1 * x, 2.0 * k1 * y
    cross = kx * y
    np.multiply(radial + kx * x, d[0], out=out[0])
    out[0] += cross * d[1]
    np.multiply(cross, d[0], out=out[1])
    out[1] += (radial + ky * y) * d[1]


def _distortion_solve(q: np.ndarray, k1: float, rows: np.ndarray) -> np.ndarray:
    """``D^-1 d`` (2, 4, N), ``D`` that of :func:`_distortion_apply` at ``q`` (2, N), of the
    changes ``d`` of ``D dq`` per unit of the focal scale (the given points ``rows`` (2, N)),
    of ``k1`` and of the offset's two coordinates."""
    x, y = q
    norm2 = x * x + y * y
    radial = 1.0 + k1 * norm2
    kx, ky = 2.0 * k1 * x, 2.0 * k1 * y
    cross = kx * y
    xx, yy = radial + kx * x, radial + ky * y
    det = xx * yy - cross * cross
    dx, dy = -(x * norm2), -(y * norm2)
    solved = np.empty((2, 4, len(x)))
    solved[0, 0], solved[1, 0] = yy * rows[0] - cross * rows[1], xx * rows[1] - cross * rows[0]
    solved[0, 1], solved[1, 1] = yy * dx - cross * dy, xx * dy - cross * dx
    solved[0, 2], solved[1, 2], solved[0, 3], solved[1, 3] = -yy, cross, cross, -xx
    solved /= det
    return solved


def _left_jacobian(w: np.ndarray) -> np.ndarray:
    """``J(w)`` (3, 3) with ``exp([w + dw]x) = exp([J(w) dw]x) exp([w]x)`` to first order."""
    theta = float(np.linalg.norm(w))
    K = _cross_matrix(w)
    if theta < 1e-8:
        return np.eye(3) + 0.5 * K
    a = (1.0 - np.cos(theta)) / theta**2
    b = (theta - np.sin(theta)) / theta**3
    return np.eye(3) + a * K + b * (K @ K)


def _sigmas(residual, inverse, problem) -> tuple[float, float]:
    """Deviations of the focal scale and of the rotation angle (degrees, root-mean-square) from
    the covariance ``v (J^T J)^-1``, ``v = |r|^2 / (2I - P)``, of the residual ``r`` and the
    ``inverse`` ``(J^T J)^-1`` of its Jacobian ``J`` at the minimum (:func:`_jacobian`, with
    the prior rows; None when singular)."""
    count = int(np.count_nonzero(problem[4]))
    transfer = residual[:-count]
    if len(transfer) <= count or inverse is None:
        return float("inf"), float("inf")
    cov = float(transfer @ transfer) / (len(transfer) - count) * inverse
    rotation = np.degrees(np.sqrt(max(float(np.trace(cov[:3, :3])), 0.0)))
    return float(np.sqrt(max(cov[3, 3], 0.0))), float(rotation)


def _offset_beyond_bound(params, problem, bound, noise, forward) -> bool:
    """A coordinate of the fitted offset lies beyond ``bound`` (2,) by more than
    :data:`PRINCIPAL_SIGNIFICANCE` posterior deviations, ``noise^2 (J^T J)^-1`` with ``J`` the
    Jacobian of the residuals and the prior rows (the plain bound when it is singular)."""
    excess = np.abs(params[5:7]) - bound
    if not np.any(excess > 0):
        return False
    inverse = _gauss_newton_covariance(_jacobian(params, problem, forward), 1.0)
    deviation = _posterior_deviations(inverse, problem, noise)
    deviation = np.zeros(2) if deviation is None else deviation[5:7]
    return bool(np.any(excess > PRINCIPAL_SIGNIFICANCE * deviation))


def _lens_excess(params, inverse, problem, bounds, noise) -> float:
    """Largest ``(|param| - bound) / deviation`` over the free focal scale, ``k1`` and focal
    ratio, the deviations those of :func:`_posterior_deviations` (inf beyond the box when the
    covariance is singular; -inf when none is bounded)."""
    bounded = np.flatnonzero(problem[4] & np.isfinite(bounds))
    if bounded.size == 0:
        return float("-inf")
    excess = np.abs(params[bounded]) - bounds[bounded]
    deviation = _posterior_deviations(inverse, problem, noise)
    if deviation is None:
        return float("inf") if np.any(excess > 0) else float("-inf")
    return float(np.max(excess / np.maximum(deviation[bounded], np.sqrt(1e-300))))


def _posterior_deviations(inverse, problem, noise) -> np.ndarray | None:
    """Posterior deviation of each parameter (8,), from ``noise^2 (J^T J)^-1`` with ``J`` the
    Jacobian of the residuals and the prior rows, ``inverse`` its ``(J^T J)^-1`` (NaN for the
    held ones); None when singular (``inverse`` None)."""
    free = problem[4]
    if inverse is None:
        return None
    cov = noise**2 * inverse
    deviation = np.full(free.size, np.nan)
    deviation[free] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return deviation


def _gauss_newton(params, problem, iterations):
    """Levenberg-Marquardt on the free parameters of ``problem`` (its boolean mask ``free``);
    a rejected step keeps the Jacobian of the point it left from. The steps end after one
    shorter than :data:`_SETTLED` deviations of the parameters (``u^T H u`` against the
    residual's variance per degree of freedom): Gauss-Newton converges quadratically, so the
    next would move them by a far smaller fraction of their uncertainty, at the price of a
    Jacobian. Returns the parameters and the :func:`_forward` pass there."""
    free = problem[4]
    damping = 1e-6
    residual, forward = _objective(params, problem)
    cost = residual @ residual
    freedom = max(len(residual) - int(np.count_nonzero(free)), 1)
    normal = None
    for _ in range(iterations):
        if normal is None:
            J = _jacobian(params, problem, forward)
            normal = J.T @ J, J.T @ residual
        H, g = normal
        update = np.linalg.solve(H + damping * np.diag(np.diag(H) + 1e-12), -g)
        trial = params.copy()
        trial[free] += update
        new_residual, trial_forward = _objective(trial, problem)
        new_cost = new_residual @ new_residual
        if new_cost < cost:
            params, residual, damping, normal = trial, new_residual, damping * 0.1, None
            forward = trial_forward
            settled = update @ H @ update < _SETTLED**2 * new_cost / freedom
            if settled or cost - new_cost < 1e-12 * cost:
                break
            cost = new_cost
        else:
            damping *= 10.0
    return params, forward
