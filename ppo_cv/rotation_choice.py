"""Which rotation to return: the estimate with the smallest expected error.

Every pair has two estimates of its rotation: the rotation-only fit
(:func:`ppo_cv.rotation.fit_rotation_lens`, refitted on intensity-aligned tracks when those
were aligned) and the rotation of the moving model, the essential matrix's refined pose or the
plane's. Each is scored by its expected error, ``|bias| + deviation`` (degrees), and the
smaller wins (:func:`choose_rotation`).

- The moving model explains a translation, so a translation does not bias its rotation; its
  deviation is the root-mean-square angle of the covariance of its final refinement
  (:func:`ppo_cv.refine.pose_sigmas_deg`), which in a narrow field with a tiny baseline is
  large: a sideways translation and a pan make nearly the same flow (the bas-relief
  ambiguity), and a radial term lets the angle slide further. How far it slides is not what
  the linearisation says: there the matches' error is the lens's misfit more than their noise,
  and where along the valley the minimum lies depends on how the lens term is weighed. The
  essential matrix's bias is that dependence, measured: the move of its rotation when ``k1``
  is fitted anew with the pose under its prior in units of the matches' noise, less the move
  the noise alone makes where that was measured (:func:`released_lens_shift_deg`, from
  :mod:`ppo_cv.refine`). Counted there, the value a held ``k1`` was fitted to is not counted
  again in the deviation, which keeps that coefficient's spread only. A plane's bias is 0.
- The rotation-only fit has its own deviation (:attr:`ppo_cv.rotation.LensRotationFit.
  rotation_sigma_deg`, or :func:`rotation_fit_sigma_deg` when its lens was clipped to the box)
  and a bias: the translation it does not model (:func:`translation_bias`), measured on
  intensity-aligned tracks or, where none were aligned, on the feature matches
  (:func:`matches_parallax`), less precisely and with a deviation that says so. The rotation
  its focal scale bought where that scale departs from the given focal length beyond its prior
  (:func:`focal_trade_deg`) is counted in a pure rotation's reported deviation, not in the
  choice.

The bias. A camera moved by ``b`` before a point at depth ``Z`` shifts the point's normalised
image by ``((b_x - x b_z) / Z, (b_y - y b_z) / Z)``; a small rotation ``w`` shifts it by
``(w_y (1 + x^2) - w_x x y - w_z y, -w_x (1 + y^2) + w_y x y + w_z x)``. To first order in the
field (``x, y`` small) the rotation's flow is the uniform shift ``(w_y, -w_x)``, the
translation's the uniform shift ``b_perp / Z`` plus a radial part ``-b_z (x, y) / Z`` that the
fit's focal scale, not its rotation, absorbs. The least-squares rotation over the matches
therefore takes ``|w| = mean(|b_perp| / Z)`` radians of the translation, turned toward the
translation's perpendicular. For a plane of normal ``n`` at distance ``d``, ``b_perp / d`` is
the part of ``u = b / d`` across the normal of the plane of its homography
(:func:`across_normal_parallax`), so the bias is that parallax as the intensity-aligned tracks
measure it, in radians, and its deviation adds to that of the fit:
``expected = parallax + sqrt(sigma_fit^2 + sigma_parallax^2)``.

The lens behind the bias. The tracks are corrected by the fit's lens before their homography
is fitted, so an error of that lens is read as parallax, the more so the thinner the overlap:
in a strip a sixth of a 20 degree field high (an 11 degree turn across it), a ``k1`` of 0.1
left uncorrected reads as 2.1 degrees of parallax on a pure rotation, 0.2 as 3.8 degrees,
against a deviation of 0.2-0.35 degrees from the tracks' noise. So the tracks' refit for this
estimate holds ``k1`` by its prior :data:`ppo_cv.rotation.K1_PRIOR` alone (``keep_clipped``
of :func:`ppo_cv.photometric.refine_rotation_photometric`): the box
:data:`ppo_cv.rotation.MAX_K1` keeps a decision from calling a translation a rotation, and
here the tracks' parallax is what tells them apart. A consumer zoom at its long end has a
pincushion of ``k1`` 0.3-0.5 in a 19-20 degree field (``ppo_cv.data_gen.LONG_ZOOM``); with
``k1`` held at the box, the tracks of its tripod pans at 720 x 540 (baseline / depth
0.0045-0.0066, seed 0, indices 0, 4 and 11) read a parallax of 3.1 degrees or were not
refitted, and the essential matrix's rotation, 7.9-12.5 degrees off, was returned; freed,
``k1`` is fitted within 0.013 of the truth and the rotation-only estimate, 0.09-0.15 degrees
off, is. The windows are searched over the estimate's deviation
(:func:`rotation_fit_sigma_deg` when the fit's lens was clipped), not over the search's cap:
searched over 5 degrees, those of index 4 locked onto repeated texture 2.5-4.9 degrees off.

A focal length given far off. A tripod pan whose focal length is given further off than the
lens box (:data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`) has matches that are a rotation through
another focal length: the fit clips its lens, the decision calls the pair general, and the
corrected matches' homography ``S R S^-1`` (``S = diag(s, s, 1)``) is no rotation, so its
parallax reads the focal error as a translation (3.5-11 degrees on pano_dev's csie pairs, a
19.5 degree field, whose matches want focal lengths about 0.74 times the given ones), and the
essential matrix's rotation, 5-13 degrees off, won. A focal error is no translation. So where
the fit's lens was clipped (:attr:`ppo_cv.motion_model.MotionDecision.lens_clipped`) the bias
of the rotation-only estimate is read on that homography conjugated by the focal scale that
makes it nearest a rotation within :data:`FOCAL_ERROR_RANGE` (:func:`focal_free_parallax`),
and that freedom is charged: the rotation a translation may hide in the focal scale the
matches want (:func:`focal_bias_deg` of :func:`wanted_focal_fit`) is added to the bias. The
rotation is not fitted through that focal length. On csie all nine pairs then returned a
rotation 0.29-0.60 degree from the reference, the fit's with its lens at the edge of the box
(two before); pano_dev 100 % within 1 degree (88 %); freiburg unchanged.

The rotation returned, where the rotation-only estimate of the feature matches wins with its
focal scale clipped to the edge of the box, is not that fit's: that focal scale is neither the
given focal length nor the one the matches want, and its ``k1`` was fitted beside it. A focal
length beyond the box is not what two views of a narrow field measure (a focal scale and ``k1``
trade there), so it is dropped as a principal point beyond its bound is: the rotation is fitted
again through the given focal length, ``k1`` held by its prior alone
(:func:`through_given_focal`, :func:`given_focal_fit`), the rotation a user of the given
calibration stitches with. Its bias and deviation are the model's and stay. On pano_dev's csie
pairs without tracks (the given focal lengths from a bundle adjustment of the whole turn) the
rotation comes 0.02-0.22 degree from the reference instead of 0.29-0.60 (``k1`` -0.07 to 0.55
on normalised points, at most 2.5 % at the corners of a 19.5 degree field), on ``book``
DSC04232 0.02 instead of 0.66; pano_dev's median 0.29 degree (0.36). Where only ``k1`` was
clipped the fitted focal scale is what the matches measure and the fit's rotation stays.

The reading holds only where the homography so conjugated is a rotation's
(:func:`freed_parallax_refused`): the parallax left there, read as :func:`translation_bias`
reads it, must not exceed the bound by which the tracks of a rotation whose lens was clipped
refuse it (:attr:`ppo_cv.motion_model.MotionDecision.track_parallax_bound`) by more than
:data:`ppo_cv.motion_model.PARALLAX_SIGNIFICANCE` of its deviations. A focal length given off
leaves none; a translation before a scene with depth leaves what no focal length explains,
and its focal scale then took part of the translation too. A render translating by 0.05 of
the depth through the strongest lens of ``tests/imperfect.py`` (seed 11, true ``k1``
+0.085), whose homography is nearest a rotation through 1.25 times the given focal length,
keeps 0.80 +- 0.10 degree there (bound 0.47); read with the focal length free, its
rotation-only fit, 3.2 degrees off, had won against the essential matrix, 1.7 off. A handheld
swing in a 50 degree field keeps 1.04 +- 0.13 (1.36 +- 0.12 on its tracks). csie's nine
pairs keep 0.05-0.71 with deviations of 0.12-1.73: at most half their bounds.

Where the reading is refused the rotation is not fitted through the given focal length
either (:attr:`RotationEstimate.focal_error`): the focal scale at the edge of the box took
part of a translation, not a focal error. A camera moved sideways by ``b`` along a pan of
``w`` shifts a point at ``x`` by ``w (1 + x^2) + b / Z``; a pan ``w'`` seen through a focal
length ``1 / k`` times the given one shifts it by ``(w' / k) (1 + k^2 x^2)``, so the fit
takes ``w' = sqrt(w (w + b / Z))``, about ``w + b / 2Z``: with the focal scale free the
rotation takes about half of the translation, through the given focal length all of it.
``data_gen``'s ``tiny-baseline`` at 0.02 (seed 0, index 9, the focal length given 2.3 %
short, a 7 degree turn) leaves 0.26 +- 0.02 degree of parallax (bound 0.17) and returns its
rotation 0.94 degree off from the edge of the box, 1.29 through the given focal length. A
translation too small to be refused is refitted: the ``sweep`` pair at 0.005 (index 0, 0.12
+- 0.02 left) comes 0.46 degree off through the given focal length and 0.28 through the true
one; 0.10 at the edge of the box, where that focal error, the other way, cancelled the
translation's 0.29 degree. ``book`` DSC04232 of pano_dev leaves 0.29 +- 0.05 and is 0.02 off
through the given focal length, 0.66 at the edge: the focal scales the two want, their
parallax and the essential matrix's rotation (nearer the edge's in both) do not tell these
two apart.

What it costs. A homography cannot tell that focal error from a translation: a pan about a
pivot off the centre before a vertical wall is exactly ``S R' S^-1`` on the wall's homography
(the pan's axis in the wall's plane; a tilt about the other axis leaves a third of the
parallax). With the charge, rendered 10 degree swings in a 20 degree field before walls facing
the camera at pivots 0.1-0.4 of their distance keep their answers, but one before a vertical
wall turned to the camera (``plane`` seed 20, pivot 0.4 behind the camera) returns the
rotation-only fit 4.3 degrees off where the essential matrix was 0.2 off
(``tests/test_focal_error_rotation.py``): that homography, conjugated, leaves no parallax.
Which is likelier, a focal length 25 % off or such a swing, is
a prior two views cannot settle; the choice takes the reading real tripod photos need. The
result names the focal length the matches want (:func:`wanted_focal_scale`,
``PairResult.lens.wanted_focal_scale``), so that a user can check the calibration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .checks import (
    as_finite_array,
    as_flag,
    as_nonnegative,
    as_number,
    as_positive,
    as_positive_at_most,
    as_real_array,
    require_instance,
)
from .lsq import _gauss_newton_covariance, _rotation_increment
from .metrics import rotation_error_deg
from .model_selection import robust_sigma
from .motion_model import MAX_TRACK_PARALLAX, MotionDecision, parallax_refuses_rotation
from .parallax import (
    PlaneParallax,
    fit_plane_parallax,
    focal_conjugates,
    homography_parallax,
    nearest_rotation_log_scale,
)
from .photometric import MAX_SEARCH_SIGMA_DEG, PhotometricRotation, _refit_reach_deg
from .refine import released_lens_shift_deg
from .rotation import (
    FOCAL_PRIOR,
    K1_PRIOR,
    MAX_FOCAL_CHANGE,
    MIN_LENS_MATCHES,
    LensRotationFit,
    _checked_matches,
    _checked_used,
    _correct_points,
    _lens_rotation_residuals,
    _seen_through_lens,
    fit_rotation_lens,
)

__all__ = [
    "FOCAL_ERROR_RANGE",
    "GROSS_FOCAL_ERROR",
    "ROTATION_SOURCES",
    "SETTLED_DEVIATIONS",
    "RotationEstimate",
    "across_normal_parallax",
    "choose_rotation",
    "focal_bias_deg",
    "focal_trade_deg",
    "focal_free_parallax",
    "freed_parallax_refused",
    "given_focal_fit",
    "feature_parallax",
    "matches_parallax",
    "released_lens_shift_deg",
    "rotation_only_estimate",
    "rotation_only_fit",
    "through_given_focal",
    "tracks_could_win",
    "rotation_fit_sigma_deg",
    "settled_before_polish",
    "translation_bias",
    "unbiased_bias_deg",
    "wanted_focal_fit",
    "wanted_focal_scale",
]

ROTATION_SOURCES = ("rotation", "essential", "plane")
"""Where a returned rotation comes from: the rotation-only fit, the essential matrix's refined
pose or the plane's (homography) pose."""


FOCAL_ERROR_RANGE = (0.5, 2.0)
"""Scales of the focal length (true over given) within which :func:`focal_free_parallax` looks
for the one that makes a homography a rotation: the errors of a calibration nobody checked,
a focal length read for another crop or zoom (EXIF of a cropped sensor: 1.3-1.6 times; a
digital zoom; a stitcher's estimate from a narrow overlap), not the few percent of
:data:`ppo_cv.rotation.FOCAL_PRIOR`."""


@dataclass(frozen=True)
class RotationEstimate:
    """One estimate of a pair's rotation and its error budget.

    Attributes
    ----------
    source : str
        One of :data:`ROTATION_SOURCES`.
    R : ndarray, shape (3, 3)
    bias_deg : float
        Systematic error (degrees) the model leaves: for the rotation-only fit, the
        translation's parallax (:func:`translation_bias`); for the essential matrix's, the
        move of its rotation with its lens term (:func:`released_lens_shift_deg`); 0 for a
        plane's.
    sigma_deg : float
        Standard deviation (degrees) of its random error; inf when unknown.
    bias_sigma_deg : float
        Deviation (degrees) of the measured ``bias_deg`` (part of ``sigma_deg``).
    focal_error : bool
        Whether the bias was read as that of a rotation through a focal length given off
        (:func:`focal_free_parallax`), the parallax left there not refusing the reading
        (:func:`freed_parallax_refused`); a rotation-only estimate's only.
    """

    source: str
    R: np.ndarray
    bias_deg: float
    sigma_deg: float
    bias_sigma_deg: float = 0.0
    focal_error: bool = False

    def __post_init__(self) -> None:
        if self.source not in ROTATION_SOURCES:
            raise ValueError(
                f"unknown rotation source {self.source!r}; choose one of "
                + ", ".join(ROTATION_SOURCES)
            )
        if as_real_array(self.R, "R").shape != (3, 3):
            raise ValueError(f"R must be a 3x3 rotation matrix, got shape {np.shape(self.R)}")
        for name in ("bias_deg", "sigma_deg", "bias_sigma_deg"):
            as_number(getattr(self, name), name)
        as_flag(self.focal_error, "focal_error")

    @property
    def fit_sigma_deg(self) -> float:
        """Deviation (degrees) of the estimate itself: ``sigma_deg`` without that of the
        measured bias."""
        return float(np.sqrt(max(self.sigma_deg**2 - self.bias_sigma_deg**2, 0.0)))

    @property
    def rms_error_deg(self) -> float:
        """Root-mean-square error (degrees): ``sigma_deg`` with the bias's square, the
        measured ``bias_deg`` squared less its variance (an unbiased estimate of the true
        bias's square, at least 0)."""
        bias = unbiased_bias_deg(self.bias_deg, self.bias_sigma_deg)
        return float(np.hypot(self.sigma_deg, bias))

    @property
    def expected_error_deg(self) -> float:
        """``|bias_deg| + sigma_deg``; inf when either is not a number."""
        value = abs(float(self.bias_deg)) + float(self.sigma_deg)
        return value if value == value else float("inf")


_MAX_STEP = 1e-2  # finite-difference steps beyond it measure no derivative (1e300 overflowed)


def _checked_fit_matches(lens: Any, x1: Any, x2: Any, used: Any) -> tuple:
    """``(x1, x2, used)`` of a rotation-only ``lens`` fit checked: ``lens`` a
    :class:`~ppo_cv.rotation.LensRotationFit`, ``x1``, ``x2`` finite normalised points (N, 2)
    or (N, 3) of one length, ``used`` a bool mask (N,); ValueError or TypeError naming the
    argument."""
    require_instance(lens, LensRotationFit, "lens", " (made by ppo_cv.rotation.fit_rotation_lens)")
    x1, x2 = _checked_matches(x1, x2)
    return x1, x2, _checked_used(used, len(x1))


def _checked_step(step: Any) -> float:
    """A finite-difference step in ``(0, _MAX_STEP]``."""
    return as_positive_at_most(step, "step", _MAX_STEP, " (a finite difference)")


def _checked_homography(H: Any) -> np.ndarray:
    """A finite 3x3 matrix as float64; ValueError or TypeError naming ``H``."""
    H = as_finite_array(H, "H")
    if H.shape != (3, 3):
        raise ValueError(f"H must be a 3x3 homography, got shape {H.shape}")
    return H


def _require_parallax(parallax: Any, name: str, measured: bool = True) -> None:
    """TypeError unless ``parallax`` is a :class:`~ppo_cv.parallax.PlaneParallax`; when
    ``measured``, ValueError unless its ``H`` is a finite 3x3 matrix, else None is accepted
    and so is a fit that failed (NaN)."""
    if parallax is None and not measured:
        return
    require_instance(parallax, PlaneParallax, name, " (made by ppo_cv.parallax.fit_plane_parallax)")
    if measured:
        _checked_homography(parallax.H)


def _require_estimates(estimates: Any, names: tuple[str, ...] | None = None) -> None:
    """TypeError unless ``estimates`` is a sequence of :class:`RotationEstimate`, each named by
    ``names`` (by its place in ``estimates`` otherwise)."""
    if isinstance(estimates, (str, bytes)) or not isinstance(estimates, Sequence):
        raise TypeError(
            f"estimates must be a sequence of RotationEstimate, got {type(estimates).__name__}"
        )
    for index, estimate in enumerate(estimates):
        name = names[index] if names else f"estimates[{index}]"
        require_instance(estimate, RotationEstimate, name)


def _require_motion(motion: Any, tracks: Any = None) -> None:
    """TypeError unless ``motion`` is a :class:`~ppo_cv.motion_model.MotionDecision` and
    ``tracks`` None or a :class:`~ppo_cv.photometric.PhotometricRotation`."""
    require_instance(motion, MotionDecision, "motion", " (decide_motion makes one)")
    if tracks is not None:
        require_instance(tracks, PhotometricRotation, "tracks")


def choose_rotation(estimates: Sequence[RotationEstimate]) -> RotationEstimate:
    """The estimate with the smallest expected error; the first one on a tie.

    Parameters
    ----------
    estimates : sequence of RotationEstimate
        At least one; list the moving model's first, so that it keeps the rotation when
        neither is known (both expected errors infinite).

    Returns
    -------
    RotationEstimate

    Examples
    --------
    >>> import numpy as np
    >>> essential = RotationEstimate("essential", np.eye(3), 0.0, 1.5)
    >>> rotation = RotationEstimate("rotation", np.eye(3), 0.3, 0.1)
    >>> choose_rotation([essential, rotation]).source
    'rotation'
    """
    _require_estimates(estimates)
    if len(estimates) == 0:
        raise ValueError("choose_rotation needs at least one estimate")
    errors = np.array([estimate.expected_error_deg for estimate in estimates])
    return estimates[int(np.argmin(errors))]


def across_normal_parallax(H: np.ndarray) -> float:
    """``|u x n|`` of a homography ``H ~ R (I + u n^T)`` (3, 3): the baseline across the
    plane's normal over its distance, radians.

    ``I + u n^T`` (``|n| = 1``) has its middle singular value 1, the product of the other two
    ``1 + u . n`` and the sum of their squares ``2 + 2 u . n + |u|^2``, so with the singular
    values of ``H`` scaled to ``s2 = 1``: ``|u| = s1 - s3`` and ``u . n = s1 s3 - 1``, hence
    ``|u x n|^2 = (s1 - s3)^2 - (s1 s3 - 1)^2``. A change of focal length (``u`` along ``n``)
    gives 0, as does a rotation. Unlike :func:`ppo_cv.parallax.homography_parallax`, which
    takes the smaller of the two logarithmic gaps and so reads little of a sideways motion
    that comes with a forward one, this is the whole sideways part.

    >>> import numpy as np
    >>> H = np.eye(3) + np.outer([0.05, 0.0, 0.025], [0.0, 0.0, 1.0])
    >>> round(across_normal_parallax(H), 4)
    0.05
    """
    H = _checked_homography(H)
    s = np.linalg.svd(np.asarray(H, dtype=np.float64), compute_uv=False)
    if not s[1] > 0:
        return float("inf")
    s = s / s[1]
    return float(np.sqrt(max((s[0] - s[2]) ** 2 - (s[0] * s[2] - 1.0) ** 2, 0.0)))


def translation_bias(parallax: PlaneParallax | None) -> tuple[float, float]:
    """Bias of a rotation-only fit and its deviation (degrees) from the homography the tracks
    fit (see the module docstring): :func:`across_normal_parallax` of its ``H``, with the
    deviation of its parallax; ``(inf, 0)`` when it was not measured."""
    _require_parallax(parallax, "parallax", measured=False)
    if parallax is None or not np.isfinite(parallax.parallax):
        return float("inf"), 0.0
    return float(np.degrees(_parallax_bias(parallax))), float(np.degrees(parallax.sigma))


def _parallax_bias(parallax: PlaneParallax) -> float:
    """The bias (radians) a ``parallax`` gives a rotation-only fit: :func:`across_normal_parallax`
    of its ``H``, at least its own ``parallax``."""
    return max(across_normal_parallax(parallax.H), abs(parallax.parallax))


def focal_free_parallax(parallax: PlaneParallax) -> tuple[PlaneParallax, float]:
    """The plane parallax of ``parallax.H`` once conjugated by the focal scale that makes it
    nearest a rotation, and that scale (given over true focal length).

    ``S^-1 H S`` with ``S = diag(c, c, 1)``, ``c`` the true focal length over the given one in
    :data:`FOCAL_ERROR_RANGE`, chosen to minimise ``log(sigma_1 / sigma_3)`` as
    :func:`ppo_cv.sfm.rotation_focal_scale` does (Hartley and Zisserman, 8.8): 0 for
    ``H = S R S^-1``, a rotation seen through a focal length ``c`` times the given one. The
    deviation is kept. The scale is NaN when the least spread lies on a bound of the range (no
    focal length in it makes ``H`` a rotation); the parallax is then read at that bound.

    >>> import numpy as np
    >>> from ppo_cv.parallax import PlaneParallax
    >>> c, s = np.cos(0.15), np.sin(0.15)
    >>> S = np.diag([0.75, 0.75, 1.0])
    >>> H = S @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.linalg.inv(S)
    >>> freed, scale = focal_free_parallax(PlaneParallax(H, 0.1, 0.001, np.empty(0)))
    >>> round(freed.parallax, 6), round(across_normal_parallax(freed.H), 6), round(scale, 3)
    (0.0, 0.0, 1.333)
    """
    _require_parallax(parallax, "parallax")
    H = np.asarray(parallax.H, dtype=np.float64)
    grid = np.linspace(*np.log(FOCAL_ERROR_RANGE), _FOCAL_GRID)
    log_scale, _, inside = nearest_rotation_log_scale(H, grid)
    freed = focal_conjugates(H, np.array([log_scale]))[0]
    c = float(np.exp(log_scale))
    freed_parallax = replace(parallax, H=freed, parallax=homography_parallax(freed))
    return freed_parallax, 1.0 / c if inside else float("nan")


_FOCAL_GRID = 61  # focal scales tried, evenly in log scale, before the zooming grids


def unbiased_bias_deg(bias_deg: float, bias_sigma_deg: float) -> float:
    """``sqrt(max(bias^2 - bias_sigma^2, 0))``: the size of a bias measured as ``bias_deg``
    with deviation ``bias_sigma_deg`` (degrees, at least 0, inf when unknown), its noise taken
    out; 0 when not measured (inf). A NaN deviation is a ValueError, a text a TypeError.

    >>> unbiased_bias_deg(0.5, 0.3), unbiased_bias_deg(0.1, 0.2)
    (0.4, 0.0)
    """
    bias_deg = as_number(bias_deg, "bias_deg")
    bias_sigma_deg = as_number(bias_sigma_deg, "bias_sigma_deg")
    if not bias_sigma_deg >= 0:
        raise ValueError(f"bias_sigma_deg must be a number >= 0 or inf, got {bias_sigma_deg}")
    if not np.isfinite(bias_deg):
        return 0.0
    if abs(bias_deg) > 1e150:  # the squares would overflow
        share = min(bias_sigma_deg / abs(bias_deg), 1.0)
        return float(abs(bias_deg) * np.sqrt(1.0 - share * share))
    return float(np.sqrt(max(bias_deg**2 - bias_sigma_deg**2, 0.0)))


def rotation_fit_sigma_deg(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray, step: float = 1e-6
) -> float:
    """Root-mean-square angle error (degrees) of a rotation-only fit's rotation, its focal
    scale and ``k1`` estimated jointly under the priors :data:`ppo_cv.rotation.FOCAL_PRIOR`
    and :data:`ppo_cv.rotation.K1_PRIOR`, at the fit's own values.

    This is the covariance :func:`ppo_cv.rotation.fit_rotation_lens` reports, evaluated where a
    lens clipped to its box left it undefined (``rotation_sigma_deg`` inf): ``v (J^T J)^-1``
    with ``J`` the Jacobian of the transfer errors of the ``used`` matches (normalised
    points, (N, 2) or (N, 3)) and the prior rows, ``v`` the robust variance of a coordinate of
    those errors. inf with fewer than 4 matches or a singular ``J``.
    """
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    step = _checked_step(step)
    found = _lens_jacobian(lens, x1, x2, used, step)
    if found is None:
        return float("inf")
    J, noise = found
    prior = np.diag([0.0, 0.0, 0.0, noise / FOCAL_PRIOR, noise / K1_PRIOR])[3:]
    cov = _gauss_newton_covariance(np.vstack([J, prior]), noise**2)
    if cov is None:
        return float("inf")
    return float(np.degrees(np.sqrt(max(float(np.trace(cov[:3, :3])), 0.0))))


def focal_bias_deg(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray, step: float = 1e-6
) -> float:
    """Rotation (degrees) a translation may have put into a rotation-only fit through its focal
    scale, when that scale departs from the given focal length by more than the deviation
    :data:`ppo_cv.rotation.FOCAL_PRIOR` the given one is trusted to.

    In a narrow field a sideways translation and a pan make nearly the same flow: the
    rotation-only fit, its focal scale free, explains a translation as a larger pan seen
    through another focal length, and the tracks corrected by that lens then show little
    parallax (:func:`translation_bias` reads little of it). The translation that hides so is
    sideways, as a camera turned about a pivot off its centre moves: ``t = (I - R) P``, across
    the optical axis to first order in the angle. The fit's response to a sideways ``t`` (in
    depths of the ``used`` matches, all taken at one depth) is linear:
    ``dp = -(J^T J)^-1 J^T dr/dt t``, ``J`` the Jacobian of the transfer errors in the
    rotation increment, the focal scale and ``k1`` with their prior rows, so its focal scale
    moves by ``g . t`` and its rotation by ``G t``. The departure ``e = s - 1`` is the given
    focal length's error, of deviation ``FOCAL_PRIOR``, plus ``g . t``, whose square is
    estimated as ``eps^2 = max(e^2 - FOCAL_PRIOR^2, 0)`` (as :func:`unbiased_bias_deg`); the
    least translation with ``g . t = eps``, of size ``eps / |g|``, moves the rotation by
    ``eps |G g| / |g|^2``. That size is taken at most
    :data:`ppo_cv.motion_model.MAX_TRACK_PARALLAX`, the largest parallax of a pure rotation's
    tracks: where the focal scale hardly answers a sideways step (``k1`` takes it), a larger
    step would be needed to explain the departure, and the given focal length's error is the
    likelier cause (a 24 degree ``tripod`` render of ``NARROW_LENS``, its focal length given
    2.9 % off and fitted to 0.1 %, asked for 0.09 of the depth and 5.3 degrees).
    0 when the departure is within the prior; inf when the matches do not determine it.

    The rotation choice does not count it for an estimate whose lens lies in the box: on real
    lenses the focal scale also departs to fit a distortion the division model does not have
    (3-5 % on the pano_dev tripod pairs, whose focal lengths a bundle adjustment gave), which
    this reads as a translation, and rotation-only fits 0.2-0.9 degree from the reference lost
    to essential matrices 1.1-1.8 degree off. A pure rotation's reported deviation counts
    :func:`focal_trade_deg` instead: a step before a scene whose depth varies across the view
    moves the focal scale far more than this one-depth response says.

    >>> import numpy as np
    >>> from ppo_cv.rotation import fit_rotation_lens
    >>> rng = np.random.default_rng(0)
    >>> q1 = rng.uniform(-0.25, 0.25, (300, 2))
    >>> c, s = np.cos(np.radians(8.0)), np.sin(np.radians(8.0))
    >>> R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> ray = np.column_stack([q1, np.ones(300)]) @ R.T + [0.01, 0.0, 0.0]  # a 1 % step
    >>> x2 = ray[:, :2] / ray[:, 2:]
    >>> fit = fit_rotation_lens(q1, x2, np.ones(300, bool), np.eye(3), noise=1e-4,
    ...                         max_focal_change=0.2)
    >>> from ppo_cv.metrics import rotation_error_deg
    >>> bias = focal_bias_deg(fit, q1, x2, np.ones(300, bool))
    >>> round(rotation_error_deg(fit.R, R), 2), round(bias, 2)
    (0.17, 0.15)
    """
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    step = _checked_step(step)
    excess, found = _focal_excess(lens, x1, x2, used, step)
    if excess == 0.0 or found is None:
        return 0.0 if excess == 0.0 else float("inf")
    J, noise = found
    prior = np.diag([0.0, 0.0, 0.0, noise / FOCAL_PRIOR, noise / K1_PRIOR])[3:]
    flows = np.column_stack([_translation_flow(lens, x1[used], axis, step) for axis in (0, 1)])
    response = np.linalg.lstsq(np.vstack([J, prior]), np.vstack([flows, np.zeros((2, 2))]),
                               rcond=None)[0]  # fmt: skip
    g, G = response[3], response[:3]
    if not g @ g > 0:
        return float("inf")
    step_size = min(excess / np.linalg.norm(g), MAX_TRACK_PARALLAX)
    return float(np.degrees(step_size * np.linalg.norm(G @ g) / np.linalg.norm(g)))


def focal_trade_deg(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray, step: float = 1e-6
) -> float:
    """Rotation (degrees) a rotation-only fit's focal scale bought, where that scale departs
    from the given focal length by more than the deviation :data:`ppo_cv.rotation.FOCAL_PRIOR`
    the given one is trusted to: a pure rotation's reported deviation counts it.

    Along the fit's valley the rotation follows the focal scale: with the scale moved by
    ``ds`` and the rotation and ``k1`` (under :data:`ppo_cv.rotation.K1_PRIOR`) fitted again,
    the rotation moves by ``|dR/ds| ds``, ``dR/ds = -(J_w^T J_w)^-1 J_w^T J_s`` with ``J_s``
    the transfer errors' derivative in the focal scale and ``J_w`` theirs in the rotation
    increment and ``k1`` (the matches ``used``, normalised points (N, 2) or (N, 3)). In a pan
    of angle ``a`` that slope is about ``sin a`` radians per unit of scale, whatever moved the
    scale: a tripod's step before a scene whose depth varies across the view moves it by
    several percent where one depth would move it by a few tenths of a percent
    (:func:`focal_bias_deg`). The departure ``e = s - 1`` is the given focal length's error,
    of deviation ``FOCAL_PRIOR``, plus what a step put there, whose size is estimated as
    ``sqrt(max(e^2 - FOCAL_PRIOR^2, 0))`` (as :func:`unbiased_bias_deg`), and the rotation it
    bought as that times the slope. 0 when the departure is within the prior; inf when the
    matches do not determine the slope.

    A 40 degree pan about a pivot behind the lens, 0.5 % of the depth off it, before a floor
    and a ceiling (the inverse depth grows with ``|y|``); the fit's focal scale takes up the
    step:

    >>> import numpy as np
    >>> from ppo_cv.rotation import fit_rotation_lens
    >>> from ppo_cv.metrics import rotation_error_deg
    >>> rng = np.random.default_rng(0)
    >>> q1 = rng.uniform(-0.7, 0.7, (400, 2)) * [1.0, 0.75]
    >>> c, s = np.cos(np.radians(40.0)), np.sin(np.radians(40.0))
    >>> R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> pivot = np.array([0.0, 0.0, -1.0])
    >>> t = (pivot - R @ pivot) * 0.005 / np.linalg.norm(pivot - R @ pivot)
    >>> inverse_depth = 1.0 + 2.0 * np.abs(q1[:, 1:])
    >>> ray = np.column_stack([q1, np.ones(400)]) @ R.T + inverse_depth * t
    >>> x2 = ray[:, :2] / ray[:, 2:] + rng.normal(0.0, 1e-4, (400, 2))
    >>> used = np.all(np.abs(x2) < 0.7, axis=1)
    >>> fit = fit_rotation_lens(q1, x2, used, R, noise=1.4e-4, max_focal_change=0.2)
    >>> round(fit.focal_scale, 3), round(rotation_error_deg(fit.R, R), 2)
    (0.968, 0.99)
    >>> round(focal_trade_deg(fit, q1, x2, used), 2), round(focal_bias_deg(fit, q1, x2, used), 2)
    (1.03, 0.28)
    """
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    step = _checked_step(step)
    excess, found = _focal_excess(lens, x1, x2, used, step)
    if excess == 0.0 or found is None:
        return 0.0 if excess == 0.0 else float("inf")
    J, noise = found
    refitted = np.vstack([J[:, [0, 1, 2, 4]], [0.0, 0.0, 0.0, noise / K1_PRIOR]])
    moved = np.r_[-J[:, 3], 0.0]
    slope, _, rank, _ = np.linalg.lstsq(refitted, moved, rcond=None)
    if rank < refitted.shape[1]:
        return float("inf")
    return float(np.degrees(excess * np.linalg.norm(slope[:3])))


def _focal_excess(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray, step: float
) -> tuple[float, tuple[np.ndarray, float] | None]:
    """The departure of a fit's focal scale beyond :data:`ppo_cv.rotation.FOCAL_PRIOR`,
    ``sqrt(max(e^2 - FOCAL_PRIOR^2, 0))`` with ``e = s - 1``, and, where it is not 0, the fit's
    Jacobian and noise (:func:`_lens_jacobian`; None where the matches do not determine it)."""
    departure = float(lens.focal_scale) - 1.0
    excess = float(np.sqrt(max(departure**2 - FOCAL_PRIOR**2, 0.0)))
    return excess, None if excess == 0.0 else _lens_jacobian(lens, x1, x2, used, step)


def _translation_flow(lens: LensRotationFit, x1: np.ndarray, axis: int, step: float):
    """Change (2N,) of view 2's given normalised points under :func:`fit_rotation_lens`'s
    model when the camera moves by ``step`` depths along ``axis``, per unit."""
    q1 = _correct_points(x1, lens.focal_scale, lens.k1, lens.principal_offset)
    terms = (lens.focal_scale, lens.k1, np.asarray(lens.principal_offset), lens.focal_ratio)
    seen = lambda ray: _seen_through_lens(ray, *terms)  # noqa: E731
    ray = q1 @ np.asarray(lens.R, float).T
    return ((seen(ray + step * np.eye(3)[axis]) - seen(ray)) / step).ravel()


def _lens_jacobian(lens: LensRotationFit, x1, x2, used, step: float):
    """Jacobian (2N, 5) of the transfer errors of the ``used`` matches in the rotation
    increment, the focal scale and ``k1`` at the fit's values, and the robust deviation of a
    coordinate of those errors; None with fewer than 4 matches or no noise."""
    a, b = np.asarray(x1, float)[used], np.asarray(x2, float)[used]
    if len(a) < 4:
        return None

    def residuals(p: np.ndarray) -> np.ndarray:
        errors = _lens_rotation_residuals(
            _rotation_increment(p[:3]) @ lens.R, lens.focal_scale + p[3], lens.k1 + p[4],
            a, b, lens.principal_offset, lens.focal_ratio, vectors=True,
        )  # fmt: skip
        return errors.ravel()

    r0 = residuals(np.zeros(5))
    noise = robust_sigma(np.linalg.norm(r0.reshape(-1, 2), axis=1), 2)
    if not noise > 0:
        return None
    J = np.column_stack([(residuals(step * e) - r0) / step for e in np.eye(5)])
    return J, noise


def rotation_only_estimate(
    motion: MotionDecision,
    tracks: PhotometricRotation | None,
    x1: np.ndarray,
    x2: np.ndarray,
    used: np.ndarray,
    to_beat: float = float("inf"),
    parallax: PlaneParallax | None = None,
) -> RotationEstimate:
    """The rotation-only fit of a pair as a :class:`RotationEstimate`.

    Parameters
    ----------
    motion : MotionDecision
        The decision, whose rotation-only fit of the feature matches is taken when no tracks
        were aligned.
    tracks : PhotometricRotation or None
        The rotation refitted on intensity-aligned tracks
        (:func:`ppo_cv.photometric.refine_rotation_photometric`) and their parallax, which
        measures the bias; without them the feature matches' plane measures it
        (:func:`matches_parallax`), inf when it cannot. In a narrow field the homography of a
        few hundred matches located to a few tenths of a pixel reads a parallax of 0.01-0.08
        on pure rotations whose tracks read 0.001-0.005: a bias that large loses to a moving
        model that does not slide, and wins only against one that does.
    x1, x2 : ndarray, shape (N, 3)
        Normalised points of all matches, lens not corrected.
    used : ndarray of bool, shape (N,)
        Matches behind the fit's deviation when it must be recomputed: the union of the
        rotation's and the moving model's inliers.
    to_beat : float, optional
        Expected error (degrees) of the moving model's estimate: the focal-length reading
        below, which can only lower the bias, is taken only where the deviation is below it.
    parallax : PlaneParallax, optional
        The feature matches' parallax (:func:`feature_parallax` of ``motion``) when already
        measured, read when no tracks were aligned; measured here when None.

    Returns
    -------
    RotationEstimate
        Source ``"rotation"``; bias and its deviation from :func:`translation_bias`, the
        deviation of the fit (:func:`rotation_fit_sigma_deg` when the fit has none) combined
        with that of the bias (the fit's alone when the bias is unknown). When the decision's
        lens was clipped to its box (:attr:`ppo_cv.motion_model.MotionDecision.lens_clipped`)
        and a focal length within :data:`FOCAL_ERROR_RANGE` makes the homography a rotation,
        the bias is read with that focal length (:func:`focal_free_parallax`), plus the
        rotation a translation may hide in the focal scale the matches want
        (:func:`focal_bias_deg` of :func:`wanted_focal_fit`), unless the parallax left there
        refuses that reading (:func:`freed_parallax_refused`).
    """
    _require_motion(motion, tracks)
    _require_parallax(parallax, "parallax", measured=False)
    x1, x2 = _checked_matches(x1, x2)
    used = _checked_used(used, len(x1))
    to_beat = as_number(to_beat, "to_beat")
    lens = rotation_only_fit(motion, tracks)
    if tracks is not None and tracks.parallax is not None:
        parallax = tracks.parallax
    elif tracks is not None or parallax is None:
        parallax = matches_parallax(lens, x1, x2, motion.rotation_inliers)
    sigma = float(lens.rotation_sigma_deg)
    if not np.isfinite(sigma):
        sigma = rotation_fit_sigma_deg(lens, x1, x2, used)
    bias, bias_sigma = translation_bias(parallax)
    deviation = float(np.hypot(sigma, bias_sigma))
    focal_error = False
    if motion.lens_clipped and deviation < to_beat:
        focal_error_bias = _focal_error_bias(motion, tracks, lens, parallax, x1, x2)
        focal_error = bool(np.isfinite(focal_error_bias))
        bias = focal_error_bias if focal_error else bias
    return RotationEstimate("rotation", lens.R, bias, deviation, bias_sigma, focal_error)


def through_given_focal(
    estimate: RotationEstimate, motion: MotionDecision, x1: np.ndarray, x2: np.ndarray
) -> RotationEstimate:
    """A rotation-only ``estimate`` of the feature matches with its rotation fitted through the
    given focal length (:func:`given_focal_fit`) where the decision's fit clipped its focal
    scale to the edge of the box (:attr:`ppo_cv.motion_model.MotionDecision.lens_clipped`,
    ``|s - 1| =`` :data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`) and the estimate's bias was read as
    a focal length given off (:attr:`RotationEstimate.focal_error`); ``estimate`` otherwise.
    Its bias and deviation are kept: those of the rotation-only model, whose lens the two views
    do not determine there. Where only ``k1`` was clipped, the fitted focal scale inside the
    box is kept: it is the one the matches measure (a long zoom's pincushion beyond the box
    with a focal length given 2 % short: 0.07 degree off as fitted, 0.67 through the given
    one). Where the parallax left with the focal length freed refuses that reading, the focal
    scale took part of a translation, which the given focal length does not undo: through it
    the rotation takes the whole of the sideways translation (a ``tiny-baseline`` render at
    0.02, seed 0 index 9, 1.29 degrees off against 0.94 at the edge of the box)."""
    _require_estimates([estimate], ("estimate",))
    _require_motion(motion)
    if not (motion.lens_clipped and estimate.focal_error):
        return estimate
    lens = rotation_only_fit(motion, None)
    if abs(lens.focal_scale - 1.0) < MAX_FOCAL_CHANGE * (1 - 1e-9):
        return estimate
    return replace(estimate, R=given_focal_fit(lens, x1, x2, motion.rotation_inliers).R)


def given_focal_fit(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray
) -> LensRotationFit:
    """:func:`ppo_cv.rotation.fit_rotation_lens` of the ``used`` matches through the given focal
    length (``focal_prior`` 0), ``k1`` held by its prior :data:`ppo_cv.rotation.K1_PRIOR`
    alone, started from ``lens``'s rotation; ``lens`` with fewer than
    :data:`ppo_cv.rotation.MIN_LENS_MATCHES` matches.

    The rotation of a fit whose lens was clipped to its box: its focal scale at the edge of
    the box is neither the given focal length nor the one the matches want, and ``k1`` was
    fitted beside it. A focal length beyond the box is not what two views measure (the box
    :data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`), so it is dropped as a principal point beyond
    its bound is, the given one kept and the rest fitted again: the rotation a user of the
    given calibration stitches with.
    """
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    if np.count_nonzero(used) < MIN_LENS_MATCHES:
        return lens
    return fit_rotation_lens(
        x1, x2, used, lens.R, noise=_transfer_noise(lens, x1, x2, used), focal_prior=0.0,
        max_k1=np.inf, check_input=False,
    )  # fmt: skip


def _focal_error_bias(motion, tracks, lens, parallax, x1, x2) -> float:
    """Bias (degrees) of a rotation-only fit whose lens was clipped, read as a rotation through
    a focal length given off (see :func:`rotation_only_estimate`); inf where no focal length in
    :data:`FOCAL_ERROR_RANGE` makes the homography of ``parallax`` a rotation, or where the
    parallax left refuses the reading (:func:`freed_parallax_refused`)."""
    if parallax is None or not np.all(np.isfinite(parallax.H)):
        return float("inf")
    measured_with = lens if tracks is None else tracks.fit
    freed, freed_scale = focal_free_parallax(parallax)
    wanted = measured_with.focal_scale * freed_scale
    if not np.isfinite(wanted) or freed_parallax_refused(freed, motion.track_parallax_bound):
        return float("inf")
    free = wanted_focal_fit(lens, x1, x2, motion.rotation_inliers, wanted)
    return translation_bias(freed)[0] + focal_bias_deg(free, x1, x2, motion.rotation_inliers)


def freed_parallax_refused(freed: PlaneParallax, bound: float) -> bool:
    """Whether the parallax left once the focal length is freed (:func:`focal_free_parallax`)
    refuses the reading of a pair as a rotation through a focal length given off.

    A focal length given off makes the homography ``S R S^-1``, which conjugated by the right
    scale is a rotation; what parallax remains is a translation no focal length explains, and
    the focal scale then took part of it as well (see the module docstring). The test is the
    one by which the tracks of a pure rotation refuse it
    (:func:`ppo_cv.motion_model.with_tracks`) on the parallax the bias is read from
    (:func:`translation_bias`).

    Parameters
    ----------
    freed : PlaneParallax
        The parallax conjugated by the focal scale (:func:`focal_free_parallax`).
    bound : float
        Largest parallax of a rotation (radians):
        :attr:`ppo_cv.motion_model.MotionDecision.track_parallax_bound`.

    Returns
    -------
    bool
        True when that parallax exceeds ``bound`` by more than
        :data:`ppo_cv.motion_model.PARALLAX_SIGNIFICANCE` of its deviations.

    Examples
    --------
    >>> import numpy as np
    >>> from ppo_cv.parallax import PlaneParallax
    >>> sideways = np.eye(3) + np.outer([0.02, 0.0, 0.0], [0.0, 0.0, 1.0])
    >>> freed_parallax_refused(PlaneParallax(sideways, 0.02, 0.001, np.empty(0)), 0.003)
    True
    >>> freed_parallax_refused(PlaneParallax(np.eye(3), 0.0, 0.001, np.empty(0)), 0.003)
    False
    """
    _require_parallax(freed, "freed")
    bound = as_nonnegative(bound, "bound")
    return parallax_refuses_rotation(_parallax_bias(freed), freed.sigma, bound)


def wanted_focal_fit(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray, scale: float
) -> LensRotationFit:
    """:func:`ppo_cv.rotation.fit_rotation_lens` of the ``used`` matches with the focal scale
    free in :data:`FOCAL_ERROR_RANGE` under a prior of deviation :data:`GROSS_FOCAL_ERROR`,
    started from ``lens`` at the focal scale ``scale``: the rotation through the focal length
    the matches want; ``lens`` with fewer than :data:`ppo_cv.rotation.MIN_LENS_MATCHES`
    matches."""
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    scale = as_positive(scale, "scale")
    if np.count_nonzero(used) < MIN_LENS_MATCHES:
        return lens
    start = LensRotationFit(lens.R, scale, lens.k1, float("inf"), np.empty(0))
    return fit_rotation_lens(
        x1, x2, used, lens.R, noise=_transfer_noise(lens, x1, x2, used),
        max_focal_change=1.0 / FOCAL_ERROR_RANGE[0] - 1.0, focal_prior=GROSS_FOCAL_ERROR,
        lens_start=start, check_input=False,
    )  # fmt: skip


GROSS_FOCAL_ERROR = 0.3
"""Deviation of the prior on ``s - 1`` of :func:`wanted_focal_fit`: a focal length given
20-50 % off (an EXIF value for another crop, a stitcher's estimate from a narrow overlap)."""


def _transfer_noise(lens: LensRotationFit, x1, x2, used) -> float:
    """Robust deviation of a coordinate of ``lens``'s transfer errors on the ``used`` matches."""
    transfers = _lens_rotation_residuals(
        lens.R, lens.focal_scale, lens.k1, x1[used], x2[used], lens.principal_offset,
        lens.focal_ratio,
    )  # fmt: skip
    return robust_sigma(transfers, 2)


def wanted_focal_scale(
    motion: MotionDecision, x1: np.ndarray, x2: np.ndarray, parallax: PlaneParallax | None = None
) -> float:
    """Focal scale (given over true) with which the matches of a pair are nearest a rotation,
    when its rotation-only fit's lens was clipped to its box
    (:attr:`ppo_cv.motion_model.MotionDecision.lens_clipped`); NaN otherwise, and when no focal
    length in :data:`FOCAL_ERROR_RANGE` makes their homography a rotation.

    The homography of the rotation's inliers (``x1``, ``x2``: normalised points of all
    matches, lens not corrected) corrected by the fit's lens (:func:`matches_parallax`),
    conjugated by the focal scale that makes it nearest a rotation
    (:func:`focal_free_parallax`), that scale composed with the fit's. A translation before a
    plane makes the same homography (see the module docstring): the scale says which focal
    length would make the pair a rotation, not that it is one. ``parallax``, that homography's
    :func:`feature_parallax` when already measured, is measured here when None.
    """
    _require_motion(motion)
    _require_parallax(parallax, "parallax", measured=False)
    if not motion.lens_clipped:
        return float("nan")
    lens = rotation_only_fit(motion, None)
    if parallax is None:
        parallax = feature_parallax(motion, x1, x2)
    if parallax is None or not np.all(np.isfinite(parallax.H)):
        return float("nan")
    return float(lens.focal_scale * focal_free_parallax(parallax)[1])


def feature_parallax(
    motion: MotionDecision, x1: np.ndarray, x2: np.ndarray
) -> PlaneParallax | None:
    """:func:`matches_parallax` of the decision's own rotation-only fit (no tracks) on its
    rotation inliers among the matches ``x1``, ``x2`` (normalised points of all matches, lens
    not corrected): what :func:`rotation_only_estimate` reads without tracks and
    :func:`wanted_focal_scale` conjugates, measured once for both."""
    _require_motion(motion)
    return matches_parallax(rotation_only_fit(motion, None), x1, x2, motion.rotation_inliers)


def matches_parallax(
    lens: LensRotationFit, x1: np.ndarray, x2: np.ndarray, used: np.ndarray
) -> PlaneParallax | None:
    """:func:`ppo_cv.parallax.fit_plane_parallax` of the ``used`` feature matches corrected by
    the rotation-only fit's ``lens``: the bias of a fit whose tracks were not aligned, measured
    less precisely than on tracks (its deviation says how much less); None with fewer than 8
    matches."""
    x1, x2, used = _checked_fit_matches(lens, x1, x2, used)
    if np.count_nonzero(used) < 8:
        return None
    q1 = _correct_points(x1[used], lens.focal_scale, lens.k1, lens.principal_offset)
    q2 = _correct_points(x2[used], lens.focal_scale2, lens.k1, lens.principal_offset)
    return fit_plane_parallax(q1, q2)


def rotation_only_fit(
    motion: MotionDecision, tracks: PhotometricRotation | None
) -> LensRotationFit:
    """The rotation-only fit of a pair: refitted on intensity-aligned ``tracks`` when there are
    some, otherwise the decision's (:func:`ppo_cv.motion_model.decide_motion`) as a
    :class:`ppo_cv.rotation.LensRotationFit` without residuals."""
    _require_motion(motion, tracks)
    if tracks is not None:
        return tracks.fit
    return LensRotationFit(
        R=motion.R,
        focal_scale=motion.focal_scale,
        k1=motion.k1,
        focal_scale_sigma=float("inf"),
        residuals=np.empty(0),
        rotation_sigma_deg=motion.rotation_sigma_deg,
        principal_offset=motion.principal_offset,
        focal_ratio=motion.focal_ratio,
    )


def tracks_could_win(moving: RotationEstimate, rotation_only: RotationEstimate) -> bool:
    """Whether the rotation-only fit, refitted on tracks, could have the smaller expected error
    while both estimates keep within their expected errors of the truth.

    The two rotations are ``apart`` degrees; the refit moves the rotation-only one by at most
    its reach (:func:`~ppo_cv.photometric.refit_reach_deg` of its deviation, capped at
    :data:`~ppo_cv.photometric.MAX_SEARCH_SIGMA_DEG` as the search is), so refitted they are
    at least ``apart - reach`` apart. Both within their expected errors of the truth, that
    distance is at most the sum of the two, which is below twice the moving model's when the
    refit wins: a rotation-only fit farther than ``2 expected + reach`` from the moving
    model's took a bias the tracks would have to read (or else the moving model is off by
    more than its own budget) and cannot win; its windows are not aligned. A moving model of
    infinite expected error keeps them aligned.
    """
    _require_estimates([moving, rotation_only], ("moving", "rotation_only"))
    apart = float(rotation_error_deg(rotation_only.R, moving.R))
    reach = _refit_reach_deg(min(rotation_only.fit_sigma_deg, MAX_SEARCH_SIGMA_DEG))
    return apart - reach < 2.0 * moving.expected_error_deg


SETTLED_DEVIATIONS = 3.0
"""Deviations of the searched tracks' parallax by which :func:`settled_before_polish` lowers
their bias at its most favourable reading. On the pano_dev and ``tiny-baseline`` pairs whose
windows the rotation choice searched, the polish moved the bias of a searched fit whose lens
lay inside its box by -2.3 to +3.6 of those deviations (see that function)."""


def settled_before_polish(
    moving: RotationEstimate, searched: PhotometricRotation, focal_free: bool = False
) -> bool:
    """Whether the moving model keeps the choice whatever the polish of the searched tracks
    does: the rotation-only estimate loses even at its most favourable reading.

    That reading is the bias :func:`rotation_only_estimate` would read on the tracks
    (:func:`translation_bias` of ``searched.parallax``; where ``focal_free``, the decision's lens
    clipped, the smaller of that and the reading with the focal length freed,
    :func:`focal_free_parallax`, to which the focal-length charge only adds) less
    :data:`SETTLED_DEVIATIONS` of its deviations, at least 0, plus the fit's deviation
    (``searched.fit.rotation_sigma_deg``): the estimate's expected error ``|bias| + deviation``
    is at least that. When it exceeds the moving model's expected error,
    :func:`choose_rotation` keeps the moving model's rotation, and the windows need no polish.

    A searched fit whose lens was clipped to its box (no deviation) settles nothing: the
    tracks are corrected by that lens before their plane is fitted, so its error reads as
    parallax (see the module docstring), and the polish, which fits the lens again, moved such
    readings by -6.8 to +16 of their deviations (pano_dev book DSC04219: 0.33 to 0.12 degree;
    ``tiny-baseline`` seed 0 index 1 at 480 x 360: 2.0 to 3.1).

    Parameters
    ----------
    moving : RotationEstimate
        The moving model's estimate.
    searched : PhotometricRotation
        The tracks as searched, their ``parallax`` measured
        (``settled`` of :func:`ppo_cv.photometric.refine_rotation_photometric`).
    focal_free : bool
        Whether the bias may be read with the focal length freed
        (:attr:`ppo_cv.motion_model.MotionDecision.lens_clipped`).

    Returns
    -------
    bool
        False where the parallax or the fit's deviation is not measured or not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from ppo_cv.parallax import PlaneParallax
    >>> from ppo_cv.photometric import PhotometricRotation, WindowTracks
    >>> from ppo_cv.rotation import LensRotationFit
    >>> fit = LensRotationFit(np.eye(3), 1.0, 0.0, 0.01, np.empty(0), rotation_sigma_deg=0.1)
    >>> none = np.empty((0, 2))
    >>> sideways = np.eye(3) + np.outer([0.02, 0.0, 0.0], [0.0, 0.0, 1.0])  # 1.15 degrees
    >>> plane = PlaneParallax(sideways, 0.02, 0.001, np.empty(0))
    >>> searched = PhotometricRotation(fit, WindowTracks(none, none, none[:, 0] > 0, none[:, 0]),
    ...                                np.empty(0, bool), 0.1, parallax=plane)
    >>> essential = RotationEstimate("essential", np.eye(3), 0.0, 0.5)
    >>> settled_before_polish(essential, searched)  # 1.15 - 3 x 0.057 + 0.1 > 0.5
    True
    """
    _require_estimates([moving], ("moving",))
    require_instance(searched, PhotometricRotation, "searched")
    focal_free = as_flag(focal_free, "focal_free")
    parallax, fit_sigma = searched.parallax, float(searched.fit.rotation_sigma_deg)
    if parallax is None:
        return False
    if not np.all(np.isfinite([*np.ravel(parallax.H), parallax.parallax, parallax.sigma,
                               fit_sigma])):  # fmt: skip
        return False
    readings = [parallax, focal_free_parallax(parallax)[0]] if focal_free else [parallax]
    bias = min(_parallax_bias(reading) for reading in readings)
    least_bias = np.degrees(max(bias - SETTLED_DEVIATIONS * parallax.sigma, 0.0))
    return bool(least_bias + fit_sigma > moving.expected_error_deg)
