"""Pure rotation, plane or general motion: the decision of :func:`ppo_cv.estimate_pair`.

Two tests that fail differently are combined:

1. Model comparison (:mod:`ppo_cv.model_selection`, GRIC with a mismatch floor) of up to three
   models fitted to the same matches, each residual a distance in the joint image space (pixels):

   - ``"rotation"`` (``d = 2``, ``k = 3 + 2``): the rotation with a focal scale and radial
     distortion absorbed, the principal point under its prior when it was only guessed, and
     the ratio of the two focal lengths (``k + 1``) when they were given different
     (:func:`ppo_cv.rotation.fit_rotation_lens`), transfer error / sqrt(2);
   - ``"plane"`` (``d = 2``, ``k = 8``): the robust homography
     (:func:`ppo_cv.homography.estimate_homography`), its Sampson error;
   - ``"general"`` (``d = 3``, ``k = 5``): the refined essential matrix, its Sampson error.

   The noise ``sigma`` is that of the essential matrix's residuals, or, when larger, the part of
   the rotation's residuals that changes from a match to its nearest neighbour
   (:func:`ppo_cv.model_selection.incoherent_sigma`): noise, which parallax is not.
2. The paper's pure-rotation indicator, PRI = mean ``|M2|`` (eq. 84-85), evaluated on the
   rotation the decision would keep and the translation direction most consistent with it
   (the unit ``t`` minimising ``sum (t . (R b1 x b2))^2``, the epipolar constraint eq. 1 with
   ``R`` fixed).

Rule, the models being nested (a rotation is a homography ``H = R``, and a homography with its
plane is one special case of an essential matrix's scene):

- **rotation** when GRIC, on the union of the rotation's and the essential matrix's inliers and
  with :data:`ppo_cv.model_selection.MISMATCH_FLOOR`, prefers the rotation to the essential
  matrix, the PRI of the kept rotation is below the threshold, and the lens the rotation needed
  is a plausible one: its focal scale, ``k1`` and focal ratio lie no more than
  :data:`LENS_SIGNIFICANCE` posterior deviations beyond the box of
  :func:`ppo_cv.rotation.fit_rotation_lens` (:attr:`MotionDecision.lens_excess`), and the
  matches the essential matrix explains and the rotation does not are scattered, not a
  surface: at most :data:`MAX_COHERENT_SHARE` of the compared matches are such matches that
  move with their nearest neighbour (:attr:`MotionDecision.coherent_share`).
  The homography is not consulted: its three extra parameters absorb the lens errors of a real
  panorama (its residuals are then below the rotation's), and it cannot tell a distant plane
  from a rotation, so only the rotation-only model may call a pair a rotation, and a plane with
  a translation GRIC sees is never one;
- otherwise **plane** when GRIC, on the union of the three models' inliers and with the smaller
  floor :data:`PLANE_MISMATCH_FLOOR`, prefers the homography to the essential matrix, and the
  PPO choice among the homography's decomposition candidates (:func:`ppo_cv.plane.planar_pose`)
  is a translation with at least :data:`MIN_PLANE_SUPPORT` matches in front of both cameras,
  and that pose is one of the scene: its essential matrix ``[t]x R`` explains the matches almost
  as well as the refined one (:attr:`MotionDecision.plane_epipolar_ratio` at most
  :data:`PLANE_EPIPOLAR_TOLERANCE`; on a plane every ``[t]x R`` of a true decomposition fits all
  matches, off a plane the matches with parallax betray a wrong pose), and at most
  :data:`MAX_OFF_PLANE_SHARE` of the essential matrix's inliers lie off the homography (a
  dominant plane with structure beside it is general motion, whose pose those matches fix). The
  homography saves ``ln 4`` per match (one dimension less) and loses on every match off its
  plane: a scene mostly on one plane with some structure off it stays general once that
  structure's parallax pays for the extra dimension. The floor is smaller than the rotation's
  because both models here have a translation to absorb unmodelled errors with;
- otherwise **general**.

The rotation of a pair judged a pure rotation is the lens fit's: the maximum a posteriori
rotation with the focal scale under the prior :data:`ppo_cv.rotation.FOCAL_PRIOR` (and ``k1``
under :data:`ppo_cv.rotation.K1_PRIOR`). The given focal alone leaves an error of about
``angle x focal error`` (0.4 degrees for a 20 degree turn with the focal 2 % off); the fitted
focal follows the matches where they pin it down and stays near the given one where they do not.
Where the truth is itself a rotation fitted under the given focal (real tripod panoramas
measured against a ``K R K^-1`` homography), the price is ``angle x |focal_scale - 1|``: measured
in ``docs/pure_rotation.md`` on warped photos with the focal given exactly.

A pair so called is revisited once its windows are aligned by intensity
(:mod:`ppo_cv.photometric`, :func:`with_tracks`): tracks located to a few hundredths of a pixel
fit a homography whose plane's parallax (:mod:`ppo_cv.parallax`, the baseline over the plane's
distance, blind to a change of focal length) a rotation leaves near zero; beyond
:data:`MAX_TRACK_PARALLAX` by :data:`PARALLAX_SIGNIFICANCE` deviations the pair is a plane or
general motion after all. This catches the sideways translation before a wall that a narrow
field shows as an almost uniform shift, which the rotation with its lens terms absorbs to the
matches' accuracy.

A rotation whose lens the matches asked beyond the box (:attr:`MotionDecision.lens_clipped`)
may be such a translation absorbed at the edge of the box, or a focal length given further off
than the box allows. Its tracks settle which: they are refitted in the wider focal box
:data:`ppo_cv.rotation.TRACK_FOCAL_CHANGE`, which tracks pin down, and the pair stays a rotation
only while their parallax does not exceed :data:`NEGLIGIBLE_PARALLAX` by
:data:`PARALLAX_SIGNIFICANCE` deviations. The wider box serves that veto only: a common focal
scale absorbs much of a translation toward a back wall, and a translation at baseline / depth
0.02 whose matches want a focal 9 % short (``ppo_cv.data_gen`` ``tiny-baseline`` index 32,
``REAL_PHOTO``, lens 12 deviations beyond the box) has tracks that fit 0.91 in it and read
0.0022 +- 0.0001, which would confirm it as a negligible translation. A candidate's tracks keep
the box.

The same tracks settle the opposite case. GRIC asks whether a translation is significant, and
with many well-located matches it is even when it is tiny: a tripod turning the camera about
its screw, a few centimetres behind the lens, in 1600 px wide images. The label is about size
instead, so a pair GRIC calls general or a plane, whose rotation-only fit passes every other
test and explains the matches to :data:`MAX_CANDIDATE_RESIDUAL` radians, while the essential
matrix bent its rotation more than a negligible translation would
(:data:`MIN_CANDIDATE_ROTATION_GAP`; :attr:`MotionDecision.rotation_candidate`), has its windows
aligned too. Its parallax must stay below :data:`NEGLIGIBLE_PARALLAX` with
:data:`NEGLIGIBLE_SIGNIFICANCE` deviations to spare for the pair to be called a pure
rotation, with the tracks' rotation. Tracks that fit no rotation leave the decision as it was.

A principal point guessed at the image centre gets the same treatment. The rotation-only fit
moves it within :data:`ppo_cv.rotation.PRINCIPAL_BOUND` prior deviations, and drops an offset
the matches place beyond (a translation's parallax, or a lens near the bound that the noise
carried over it). When it was dropped and the pair is no pure rotation, the rotation is fitted
again within :data:`ppo_cv.rotation.PRINCIPAL_WIDE_BOUND`; if that fit passes the tests of a
candidate, GRIC aside, the pair is a candidate under the wider bound, and its tracks, refitted
under it too, decide as above.

So a small PRI alone cannot flag a pair whose parallax GRIC sees and the tracks measure (the
PRI of an essential matrix fitted to a narrow-field rotation is not reliable either way: its
rotation is degrees off), and a GRIC win alone cannot flag a pair whose rays plainly do not meet
at the centre. Without a homography the decision is between "rotation" and "general".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from . import ppo
from .checks import (
    MAX_FOCAL,
    as_positive,
    as_positive_at_most,
    require_instance,
    require_pose_matches,
)
from .homography import HomographyEstimate
from .metrics import rotation_error_deg
from .model_selection import (
    JOINT_DIMENSION,
    MODEL_DIMENSIONS,
    ModelResiduals,
    ModelSelection,
    coherent_share,
    incoherent_sigma,
    model_noise,
    nearest_neighbours,
    robust_sigma,
    select_model,
)
from .parallax import PlaneParallax
from .plane import PlanarPose, planar_pose
from .robust import _essential_from_pose, _sampson_errors
from .rotation import (
    MAX_FOCAL_CHANGE,
    MIN_LENS_MATCHES,
    PRINCIPAL_BOUND,
    PRINCIPAL_SIGNIFICANCE,
    PRINCIPAL_WIDE_BOUND,
    TRACK_FOCAL_CHANGE,
    LensRotationFit,
    _correct_points,
    _lens_rotation_residuals,
    fit_rotation_lens,
    ransac_rotation,
)

__all__ = [
    "EPIPOLAR_CAP_FACTOR",
    "LENS_SIGNIFICANCE",
    "MAX_CANDIDATE_RESIDUAL",
    "MIN_CANDIDATE_ROTATION_GAP",
    "MAX_COHERENT_SHARE",
    "MAX_OFF_PLANE_SHARE",
    "OFF_PLANE_SIGMAS",
    "MIN_PLANE_INLIER_RATIO",
    "MIN_PLANE_SUPPORT",
    "PLANE_EPIPOLAR_TOLERANCE",
    "PLANE_MISMATCH_FLOOR",
    "MAX_TRACK_PARALLAX",
    "NEGLIGIBLE_PARALLAX",
    "NEGLIGIBLE_SIGNIFICANCE",
    "PARALLAX_SIGNIFICANCE",
    "MotionDecision",
    "decide_motion",
    "parallax_refuses_rotation",
    "plane_ransac_trials",
    "translation_for_rotation",
    "with_rotation",
    "with_tracks",
]

LENS_SIGNIFICANCE = PRINCIPAL_SIGNIFICANCE
"""How far, in its own posterior deviations, the lens a rotation-only fit needs may lie beyond
the box of plausible lenses (``|s - 1|, |rho - 1| <= 0.05``, ``|k1| <= 0.2``) for the pair to
be called a pure rotation, as :data:`ppo_cv.rotation.PRINCIPAL_SIGNIFICANCE` is for the
principal point. The fit clips such a lens and refits the rotation, whose residuals may then
still win GRIC against an essential matrix: a translation at baseline / depth 0.02 toward a
back wall with boxes before it (``ppo_cv.data_gen`` ``tiny-baseline`` index 32,
``REAL_PHOTO``) wanted a focal 9.3 % short with a deviation of 0.34 %, 12.6 deviations beyond
the box, and was called a rotation. On 70 pure rotations with the same imperfections
(``pure-rotation``, ``panorama``, tripod pivots 8 and 15 cm, warped photos; 14 each) no fit
lay beyond the box (the largest excess -0.1 deviations, a focal 4.9 % off on a warped photo);
translations at 0.02 that GRIC already calls general lie 16-136 deviations beyond it."""

MAX_COHERENT_SHARE = 0.2
"""Largest :attr:`MotionDecision.coherent_share` of a pure rotation: the share of the compared
matches that the essential matrix explains, the rotation does not, and that move with their
nearest neighbour. GRIC caps the cost of a match the rotation leaves, and saves ``ln 4`` on
every match for the dimension the rotation does not need, so a rotation wins with up to about a
third of the matches off it. Scattered, those are noise in a tail or mismatches; in patches they
are a surface with parallax or something that moved, which two views cannot tell apart.

Measured on ``docs/pure_rotation.md``'s sets: pure rotations (warped photos, with sensor noise
and blur, narrow overlaps as stitched, the harness renders and warped freiburg frames) have
0-0.06 even where a quarter of the matches lie off the rotation (noisy narrow warps: their
outliers are scattered). The translations at baseline / depth 0.02 that GRIC called rotations
have a box face before a back wall whose matches, a quarter of them, all lie 17.7 px off the
rotation (``tiny-baseline`` index 6 with focal lengths per photo or as stitched: 0.27; at 0.05:
0.22; the harness render 0.02 seed 105: 0.22). The price is an object that moved and holds
more than a fifth of the matches: in ``benchmarks/moving_object.py`` a patch of 4 % of the
image moved 12 px holds up to 40 % of them, and 5 of 14 such pairs are no longer flagged."""

MAX_TRACK_PARALLAX = 0.01
"""Largest parallax of a pure rotation's intensity-aligned tracks (:func:`with_tracks`): the
baseline over the distance of the plane their homography describes (:mod:`ppo_cv.parallax`),
half the baseline / depth of 0.02 from which a translation must not be called a rotation.

A translation sideways before a back wall at baseline / depth 0.02 moves a 30 degree field
almost uniformly, and the rotation with a focal scale, ``k1`` and a principal point absorbs it
to 0.1-0.2 px on feature matches; GRIC then prefers the rotation (``ppo_cv.data_gen``
``tiny-baseline`` 0.02 indices 1, 5 and 8 with the principal point guessed, the focal lengths
per photo, or sensor noise). Their tracks, located to 0.02-0.06 px, fit a homography whose
plane moved 0.0115-0.018 of its distance, each to 0.0003. Pure rotations leave 0.0000-0.0004
(exact ones) and tripod pans, which do move, 0.0003-0.002 (pivot 8 and 15 cm); the largest seen
on a rotation is 0.0108 +- 0.0005 on a tripod pan in a narrow overlap as stitched with sensor
noise, where an error of the principal point times the 20 degree turn mimics a translation
(``S R S^-1`` with ``S`` the shift of the principal point is not a rotation). A radial term
``k2 = -+2 k1`` that no model has keeps narrow pans under 0.008. Per set:
``docs/pure_rotation.md``, made by ``benchmarks/pure_rotation.py``."""

PARALLAX_SIGNIFICANCE = 3.0
"""Deviations by which the tracks' parallax must exceed :data:`MAX_TRACK_PARALLAX`: narrow
overlaps with sensor noise leave 36-360 tracks in a strip, whose homography's parallax reads
0.002-0.022 with deviations of 0.003-0.013 on exact rotations."""

NEGLIGIBLE_PARALLAX = 0.003
"""Parallax of the intensity-aligned tracks below which, with :data:`NEGLIGIBLE_SIGNIFICANCE`
deviations to spare, a :attr:`MotionDecision.rotation_candidate` is called a pure rotation
(:func:`with_tracks`): a sixth of the baseline / depth of 0.02 from which a translation must
not be called a rotation, the translation's effect on the scene's plane too small to matter.

A tripod pan at 1600 x 1200 px, 15 cm before the axis, told the centre and a focal length per
photo (``ppo_cv.data_gen`` panorama seed 1 index 25) is called general by GRIC, its essential
matrix's rotation 4.4 degrees off; its tracks read 0.0007 +- 0.0001, and flagged its rotation
is 0.43 degrees off. Translations at baseline / depth 0.02-0.05 that are candidates read
0.0060-0.035 with deviations of 0.0002-0.0007, 0.0080 at least with three of them added
(``tiny-baseline``, every way of telling the intrinsics, ``docs/pure_rotation.md``), and
forced through the windows at 0.01 they read 0.0067-0.0070. Freiburg's pairs are no
candidates, and forced through the windows 82 of 83 have their rotation refit refused (the
tracks fit no rotation)."""

NEGLIGIBLE_SIGNIFICANCE = 2.0
"""Deviations by which the tracks' parallax of a rotation candidate must stay below
:data:`NEGLIGIBLE_PARALLAX` (a one-sided bound at 97.7 %). Fewer than the
:data:`PARALLAX_SIGNIFICANCE` of the opposite test: the bound already lies at half the smallest
parallax a translation at baseline / depth 0.02 has shown, and a strip of tracks in a narrow
overlap is uncertain. A tripod pan 15 cm before the axis in a 28 degree field, turned 20
degrees, as stitched (``ppo_cv.data_gen`` panorama seed 3 index 38), has its tracks read
0.0010 +- 0.0009: with three deviations it stayed a general motion 3.7 degrees off."""

MAX_CANDIDATE_RESIDUAL = 2e-3
"""Largest median residual of the rotation-only fit (radians: pixels of the joint image space
over the focal length) of a :attr:`MotionDecision.rotation_candidate`, so that the windows
(1.5-1.9 s at 640 x 480 on 2 cores) are aligned only where a rotation is close. Translations at
baseline / depth 0.02-0.05 that pass the other tests leave 1.8e-4 to 5.3e-4, the tripod pan
of :data:`NEGLIGIBLE_PARALLAX` 0.8e-4; the rotation-only fits of freiburg's pairs leave
3.5e-3 at least (median 3.7e-2)."""

MIN_CANDIDATE_ROTATION_GAP = NEGLIGIBLE_PARALLAX
"""Least angle (radians) between the essential matrix's rotation and the rotation-only fit of a
:attr:`MotionDecision.rotation_candidate`. A translation ``t`` seen at distance ``d`` tilts the
rotation that best explains its flow by about ``|t| / d``, so under a negligible translation
the two rotations agree to about :data:`NEGLIGIBLE_PARALLAX` radians. An essential matrix whose
rotation lies further off bent it to let a spurious translation absorb what the rotation's lens
terms explain (the 4-7 degrees of real tripod panoramas in a narrow field); one that agrees
measured its small translation consistently, and its ``t`` with ``t_sigma_deg`` is the better
answer. A clean 61 degree render at baseline / depth 0.004 (``ppo_cv.data_gen``
``small-parallax`` seed 0 index 2, ``benchmarks/compare.py``) has rotations 0.03 degrees apart
and ``t`` 1.1 degrees off as a general motion, though its tracks' parallax, 0.0011 +- 0.0006,
would pass as negligible; the tripod pans at 1600 x 1200 px that GRIC calls general are 0.65 and
4.8 degrees apart."""

PLANE_MISMATCH_FLOOR = 0.5
"""Mismatch floor of the plane-versus-general comparison (see the module docstring).

Chosen on ``ppo_cv.data_gen`` renders (seeds 0-4, 320x240): with 1.0 (the rotation's floor) two
of five ``forward`` pairs, cluttered scenes, were called planes and their pose error grew from
0.1-0.7 to 6-7 degrees (homography residual 2.2 times the essential matrix's, against 1.75 for
pure noise on a plane); with 0 one of five ``planar`` pairs stayed general; with 0.5 every
``forward`` pair is general and every ``planar`` pair a plane."""

PLANE_EPIPOLAR_TOLERANCE = 3.0
"""Largest :attr:`MotionDecision.plane_epipolar_ratio` of a plane (see the module docstring).

First chosen at 2.0 on renders of seeds 5 and 6, when the planar pose was reported as
decomposed: imperfect ``general`` and ``forward`` renders called planes then lost accuracy.
With the pose refined on the homography and its radial term
(:func:`ppo_cv.plane.refine_planar_pose`) and the off-plane test
(:data:`MAX_OFF_PLANE_SHARE`) those pairs keep or gain accuracy as planes, while the ratio of
true planes reaches 2.0-7.0 when the refined essential matrix, degenerate on a plane, drifts
onto mismatches (2 of 12 clean planar renders of seeds 0-2, pose errors 1.7 and 50 degrees as
general motion against 0.1 as planes). Set to 3.0 on renders of seeds 0-2 (``general``,
``forward``, ``planar``, ``small-parallax``, ``tiny-baseline``, clean and ``REAL_PHOTO``, 4
per seed), where no preset then loses AUC@5 against the decision without a plane."""

EPIPOLAR_CAP_FACTOR = 5.0
"""Cap of the squared Sampson errors of that ratio, in inlier thresholds (outliers count once)."""

MAX_OFF_PLANE_SHARE = 0.05
"""Largest :attr:`MotionDecision.plane_off_share` of a plane (see the module docstring).

GRIC saves ``ln 4`` on every match for the homography's missing dimension and its robust cost
of a match off the plane is capped, so a dominant plane with a quarter of the matches off it
still wins (a clean ``general`` render of seed 0: 435 of 1703 essential-matrix inliers off the
plane, pose error 0.26 degrees as a plane against 0.04 as general motion). Clean renders of a
single plane have 0.2-2.2 % of the essential matrix's inliers off the homography (mismatches);
with ``REAL_PHOTO`` 1.4-6 % on most, up to 16 % (the corners, where distortion exceeds the
threshold); clean ``general`` and ``forward`` renders that GRIC calls planes 24-26 % (shares
measured with the homography's RANSAC inliers as the plane, a stricter count than
:data:`OFF_PLANE_SIGMAS` now makes)."""

MIN_PLANE_INLIER_RATIO = 0.2
"""Least share of the essential matrix's inliers that a homography called a plane holds within
its RANSAC threshold: a plane leaves at most :data:`MAX_OFF_PLANE_SHARE` of them off it (by a
bound at least as wide), so its robust fit on those inliers need not search longer than finding
a model this well supported takes (:func:`plane_ransac_trials`). A transfer error carries the
noise of both images: with 0.3-0.5 px per coordinate (SIFT on sharp photos) 63-94 % of a true
plane's matches lie within a 1 px threshold, with 1 px about 20 %. The essential matrix's
inliers of freiburg's pairs hold 14-21 % on their best homography, which the unbounded search
took 18,000-50,000 hypotheses to settle."""

OFF_PLANE_SIGMAS = 3.0
"""An inlier of the essential matrix is off the plane when its Sampson error to the homography
(pixels) exceeds the inlier threshold and this many noise standard deviations (the noise of the
essential matrix's residuals): about the 99 % bound of a 2-dimensional residual, so that the
noise of a true plane alone puts about 1 % of its matches off it, whatever the feature accuracy.
The homography's RANSAC inliers would not do: they bound the transfer error in one image, which
carries the noise of both and exceeds the threshold on many plane matches of a noisy image."""

MIN_PLANE_SUPPORT = 8
"""Fewest homography inliers in front of both cameras (``M1 > 0`` and ``M2 > 0``) for a plane."""

TRANSFER_FACTOR = 2.0
"""Inlier bound on the rotation's transfer error, in units of the essential matrix's threshold:
a transfer error carries the noise of both images (a Sampson distance is about half of it)."""

RANSAC_FACTOR = 3.0
"""The plain rotation of the 2-point RANSAC does not model the lens: its consensus is taken
this many times wider, then the lens-absorbing fit re-selects at the normal bound."""


@dataclass(frozen=True)
class MotionDecision:
    """Rotation-only fit and the choice among rotation, plane and general motion of one pair.

    Attributes
    ----------
    model : str
        ``"rotation"``, ``"plane"`` or ``"general"``.
    pure_rotation : bool
        ``model == "rotation"``.
    R : ndarray, shape (3, 3)
        Rotation of the rotation-only fit over its inliers, with its lens terms: the maximum a
        posteriori rotation under the prior that the given focal length is off by about
        :data:`ppo_cv.rotation.FOCAL_PRIOR` (see :func:`ppo_cv.rotation.fit_rotation_lens`).
    t : ndarray, shape (3,)
        Unit translation most consistent with ``R`` (undetermined for a pure rotation).
    rotation_inliers : ndarray of bool, shape (N,)
        Matches within the threshold of the rotation-only fit.
    pri : float
        PRI (eq. 84) of ``(R, t)`` over ``rotation_inliers``.
    pri_general : float
        PRI of the essential matrix's pose over its inliers.
    focal_scale, k1 : float
        Lens terms of the rotation-only fit.
    focal_ratio : float
        View 2's focal scale over view 1's in that fit (1 unless ``focal_ratio_prior`` freed it).
    rotation_sigma_deg : float
        Root-mean-square angle error (degrees) of ``R`` of the rotation-only fit, from its
        covariance with the lens terms under their priors
        (:attr:`ppo_cv.rotation.LensRotationFit.rotation_sigma_deg`).
    principal_offset : ndarray, shape (2,)
        Principal-point offset of the rotation-only fit (normalised units; zero when not
        fitted).
    lens_excess : float
        :attr:`ppo_cv.rotation.LensRotationFit.lens_excess` of the rotation-only fit: above
        :data:`LENS_SIGNIFICANCE` the pair is not a pure rotation.
    selection : ModelSelection
        GRIC of each model, median residuals (pixels), the noise GRIC divided by: the larger
        of ``noise_px`` and ``rotation_noise_px``.
    noise_px : float
        Noise per image coordinate (pixels) of the essential matrix's residuals
        (:func:`ppo_cv.model_selection.model_noise`).
    rotation_noise_px : float
        Noise per image coordinate (pixels) of the rotation's residuals that changes from a
        match to its nearest neighbour (:func:`ppo_cv.model_selection.incoherent_sigma`).
    coherent_share : float
        Share of the compared matches that the essential matrix explains and the rotation does
        not, and that move with their nearest neighbour
        (:func:`ppo_cv.model_selection.coherent_share`): above :data:`MAX_COHERENT_SHARE` the
        pair is not a pure rotation.
    track_parallax, track_parallax_sigma : float
        Parallax of the plane of the homography fitted to the intensity-aligned tracks of a
        rotation, and its deviation (:attr:`ppo_cv.photometric.PhotometricRotation.parallax`,
        :func:`with_tracks`); NaN when no tracks were aligned.
    rotation_candidate : bool
        Not a pure rotation, but only because GRIC preferred the essential matrix, or because
        the rotation needs a principal point beyond :data:`ppo_cv.rotation.PRINCIPAL_BOUND`
        (``principal_bound``): the rotation-only fit passed the PRI, lens and coherent-share
        tests, explains the matches to :data:`MAX_CANDIDATE_RESIDUAL` radians and lies more
        than :data:`MIN_CANDIDATE_ROTATION_GAP` from the essential matrix's rotation. The
        intensity-aligned tracks then measure the translation's size (:func:`with_tracks`).
    rotation_gap : float
        Angle (radians) between the essential matrix's rotation ``R`` and the rotation-only fit.
    principal_bound : float
        Bound of the principal-point offset of the rotation-only fit, in prior deviations
        (:func:`ppo_cv.rotation.fit_rotation_lens`): :data:`ppo_cv.rotation.PRINCIPAL_BOUND`,
        or :data:`ppo_cv.rotation.PRINCIPAL_WIDE_BOUND` for a rotation candidate only the
        wider bound admits. The tracks' refit uses the same.
    plane : PlanarPose or None
        PPO choice among the decomposition candidates of the homography, when one was given.
    homography_inliers : ndarray of bool, shape (N,) or None
        Inliers of that homography.
    plane_selection : ModelSelection or None
        GRIC of the homography against the essential matrix (floor :data:`PLANE_MISMATCH_FLOOR`).
    plane_epipolar_ratio : float
        How much worse ``E = [t]x R`` of the planar pose explains the matches than the refined
        essential matrix: the ratio of their mean squared Sampson errors, each capped at
        :data:`EPIPOLAR_CAP_FACTOR` times the threshold (about 1 on a plane, NaN without a
        homography).
    """

    model: str
    pure_rotation: bool
    R: np.ndarray
    t: np.ndarray
    rotation_inliers: np.ndarray
    pri: float
    pri_general: float
    focal_scale: float
    k1: float
    selection: ModelSelection
    plane: PlanarPose | None = None
    homography_inliers: np.ndarray | None = None
    plane_selection: ModelSelection | None = None
    plane_epipolar_ratio: float = float("nan")
    plane_off_share: float = float("nan")
    rotation_sigma_deg: float = float("inf")
    principal_offset: np.ndarray = field(default_factory=lambda: np.zeros(2))
    focal_ratio: float = 1.0
    lens_excess: float = float("-inf")
    noise_px: float = float("nan")
    rotation_noise_px: float = float("nan")
    coherent_share: float = 0.0
    track_parallax: float = float("nan")
    track_parallax_sigma: float = float("nan")
    rotation_candidate: bool = False
    rotation_gap: float = float("nan")
    principal_bound: float = PRINCIPAL_BOUND

    @property
    def lens_clipped(self) -> bool:
        """The lens of the rotation-only fit lay beyond the box of plausible lenses and was
        clipped to it (``lens_excess > 0``, within :data:`LENS_SIGNIFICANCE` for a rotation):
        the rotation may be a translation's, absorbed at the edge of the box."""
        return self.lens_excess > 0

    @property
    def track_focal_change(self) -> float:
        """Box of the focal scale for the refit on intensity-aligned tracks
        (:func:`ppo_cv.photometric.refine_rotation_photometric`):
        :data:`ppo_cv.rotation.TRACK_FOCAL_CHANGE` for a pure rotation whose lens was clipped
        (:attr:`lens_clipped`), else :data:`ppo_cv.rotation.MAX_FOCAL_CHANGE`. Tracks in the
        wider box may refuse a rotation, never confirm a candidate (see the module
        docstring)."""
        return TRACK_FOCAL_CHANGE if self.pure_rotation and self.lens_clipped else MAX_FOCAL_CHANGE

    @property
    def track_parallax_bound(self) -> float:
        """Parallax of the tracks beyond which, by :data:`PARALLAX_SIGNIFICANCE` deviations, a
        pure rotation is refused (:func:`with_tracks`): :data:`MAX_TRACK_PARALLAX`, or
        :data:`NEGLIGIBLE_PARALLAX` when :attr:`lens_clipped`."""
        return NEGLIGIBLE_PARALLAX if self.lens_clipped else MAX_TRACK_PARALLAX

    @property
    def gric_difference(self) -> float:
        """``(GRIC(rotation) - GRIC(general)) / n``: negative when the rotation explains more."""
        return self.selection.relative_gric("rotation", "general")

    @property
    def gric_plane_difference(self) -> float:
        """``(GRIC(plane) - GRIC(general)) / n``: negative when the plane explains more; NaN
        without a homography."""
        if self.plane_selection is None:
            return float("nan")
        return self.plane_selection.relative_gric("plane", "general")


def plane_ransac_trials(confidence: float) -> int:
    """Hypotheses (4-match samples) after which a homography holding
    :data:`MIN_PLANE_INLIER_RATIO` of the matches is missed with probability ``1 - confidence``,
    ``confidence`` in (0, 1).

    >>> plane_ransac_trials(0.9999)
    5752
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    return int(np.ceil(np.log1p(-confidence) / np.log1p(-(MIN_PLANE_INLIER_RATIO**4))))


def translation_for_rotation(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Unit ``t`` minimising ``sum_i (t . (R x1_i x x2_i))^2``, sign with ``sum M2 >= 0``.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalised points.

    Returns
    -------
    ndarray, shape (3,)
    """
    require_pose_matches(R, np.zeros(3), x1, x2, moving=False, bearings=True)
    normals = np.cross(x1 @ R.T, x2)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    t = np.linalg.svd(normals, full_matrices=False)[2][-1]
    if np.sum(ppo.intersection_scores(x1, x2, R, t)) < 0:
        t = -t
    return t


def decide_motion(
    x1: np.ndarray,
    x2: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    inliers: np.ndarray,
    focal: float,
    *,
    threshold_px: float = 1.0,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
    seed: int = 0,
    homography: HomographyEstimate | None = None,
    principal_prior: float | np.ndarray | None = None,
    focal_ratio_prior: float | None = None,
    focal_ratio_mean: float = 1.0,
) -> MotionDecision:
    """Fit a rotation to the matches and decide among pure rotation, plane and general motion.

    The rule is the module's: GRIC over the candidate models on the union of their inliers,
    a rotation only with a PRI below ``pri_threshold``, a plane only with a PPO pose.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalised points of all putative matches.
    R, t : ndarray
        Refined pose of the essential matrix, ``X2 = R X1 + t``.
    inliers : ndarray of bool, shape (N,)
        Inliers of that pose.
    focal : float
        Focal length (pixels) that turns normalised errors into pixels.
    threshold_px : float
        Inlier threshold (pixels) of the essential matrix; the rotation's transfer error uses
        :data:`TRANSFER_FACTOR` times it.
    pri_threshold : float
        PRI threshold (paper: 0.015).
    seed : int
        RANSAC seed.
    homography : HomographyEstimate, optional
        Robust homography of the same matches (:func:`ppo_cv.homography.estimate_homography`,
        ``H`` on normalised points, residuals in pixels); without it no plane is considered.
    principal_prior : float or array_like of 2 floats, optional
        Let the rotation-only fit move the principal point, with this prior (normalised
        units, one for both coordinates or ``(x, y)``,
        :func:`ppo_cv.rotation.fit_rotation_lens`). GRIC counts no parameter for it: in a
        narrow field the offset is nearly a rotation, and the prior, not the matches, holds it
        (counted as two, 3 of 12 warped pans with 7-23 matches were called general).
        None keeps the given principal point.
    focal_ratio_prior : float, optional
        Deviation of the prior on view 2's focal scale over view 1's, whose mean is
        ``focal_ratio_mean``: the rotation-only fit then scales view 2's focal length against
        view 1's (:func:`ppo_cv.rotation.fit_rotation_lens`) and GRIC counts it as a
        parameter. :func:`ppo_cv.rotation.focal_ratio_prior` of the ratio of the given focal
        lengths is the rule for focal lengths estimated per photo. None keeps the given ratio.
    focal_ratio_mean : float
        Mean of that prior.

    Returns
    -------
    MotionDecision
    """
    threshold = TRANSFER_FACTOR * threshold_px / focal
    general_all = _sampson_errors(_essential_from_pose(R, t), x1, x2)
    noise = robust_sigma(general_all[inliers], JOINT_DIMENSION - MODEL_DIMENSIONS["general"][0])
    noise *= np.sqrt(2.0)  # a transfer error coordinate carries the noise of both images
    fit = ransac_rotation(x1, x2, RANSAC_FACTOR * threshold, seed=seed)
    priors = {
        "principal_prior": principal_prior,
        "focal_ratio_prior": focal_ratio_prior,
        "focal_ratio_mean": focal_ratio_mean,
    }
    context = _Context(x1, x2, R, t, inliers, general_all, noise, focal, threshold, pri_threshold)
    rotation = _rotation_evidence(fit.inliers, fit.R, priors, context)
    pure = rotation.admissible and rotation.selection.model == "rotation"
    candidate = rotation.admissible and not pure and rotation.close
    principal_bound, scored = PRINCIPAL_BOUND, inliers | rotation.inliers
    if not pure and rotation.lens.offset_dropped:
        wide = _rotation_evidence(
            fit.inliers, fit.R, {**priors, "principal_bound": PRINCIPAL_WIDE_BOUND}, context
        )
        if wide.admissible and wide.close and not wide.lens.offset_dropped:
            rotation, candidate, principal_bound = wide, True, PRINCIPAL_WIDE_BOUND
    plane = _PlaneEvidence()
    if homography is not None:
        plane = _plane_evidence(homography, scored, threshold_px, context)
    model = (
        "rotation"
        if pure
        else _plane_or_general(plane.selection, plane.pose, plane.epipolar_ratio, plane.off_share)
    )
    pri_general = ppo.pure_rotation_indicator(
        ppo.intersection_scores(x1[inliers], x2[inliers], R, t)
    )
    return _decision(
        model, rotation, plane,
        pure_rotation=pure,
        pri_general=float(pri_general),
        rotation_candidate=bool(candidate),
        principal_bound=principal_bound,
    )  # fmt: skip


@dataclass(frozen=True)
class _Context:
    """What :func:`_rotation_evidence` compares a rotation with: the matches (normalised, all),
    the essential matrix's pose, inliers and Sampson errors (all matches), the transfer-error
    noise, the focal length (pixels), the transfer bound (normalised) and the PRI threshold."""

    x1: np.ndarray
    x2: np.ndarray
    R: np.ndarray
    t: np.ndarray
    inliers: np.ndarray
    general_all: np.ndarray
    noise: float
    focal: float
    threshold: float
    pri_threshold: float


@dataclass(frozen=True)
class _RotationEvidence:
    """A rotation-only fit of :func:`decide_motion` and the tests on it: ``admissible`` (PRI,
    plausible lens, scattered outlying matches), ``close`` (residual within
    :data:`MAX_CANDIDATE_RESIDUAL`, rotation beyond :data:`MIN_CANDIDATE_ROTATION_GAP` from the
    essential matrix's)."""

    lens: LensRotationFit
    inliers: np.ndarray
    selection: ModelSelection
    noise_px: float
    rotation_noise_px: float
    share: float
    t: np.ndarray
    pri: float
    gap: float
    admissible: bool
    close: bool


@dataclass(frozen=True)
class _PlaneEvidence:
    """The homography's side of :func:`decide_motion`: the PPO pose of its decomposition, GRIC
    against the essential matrix, the epipolar ratio and the off-plane share (None and NaN
    without a homography)."""

    pose: PlanarPose | None = None
    inliers: np.ndarray | None = None
    selection: ModelSelection | None = None
    epipolar_ratio: float = float("nan")
    off_share: float = float("nan")


def _settled_lens_fit(
    start_inliers, start_R, priors: dict, context: _Context
) -> tuple[LensRotationFit, np.ndarray]:
    """Lens rotation from a RANSAC consensus, its inliers re-selected at the transfer bound
    until they settle (at most five fits, while at least four remain); the deviations of the
    last fit only."""
    x1, x2, noise, threshold = context.x1, context.x2, context.noise, context.threshold
    last = partial(_settled, used=None, threshold=threshold, final=False)
    lens = fit_rotation_lens(
        x1, x2, start_inliers, start_R, noise=noise, deviations=last, check_input=False, **priors
    )
    rotation_inliers = lens.residuals < threshold
    for attempt in range(4):
        if np.count_nonzero(rotation_inliers) < MIN_LENS_MATCHES:
            break
        last = partial(_settled, used=rotation_inliers, threshold=threshold, final=attempt == 3)
        lens = fit_rotation_lens(
            x1, x2, rotation_inliers, lens.R, noise=noise, deviations=last, check_input=False,
            **priors,
        )  # fmt: skip
        within = lens.residuals < threshold
        if np.array_equal(within, rotation_inliers):
            break
        rotation_inliers = within
    return lens, rotation_inliers


def _settled(lens, used, threshold, final) -> bool:
    """:func:`_settled_lens_fit` ends after ``lens``: its ``final`` fit, or one whose matches
    within the transfer bound ``threshold`` are the ``used`` ones it was fitted to or too few
    for another."""
    within = lens.residuals < threshold
    return final or np.count_nonzero(within) < MIN_LENS_MATCHES or np.array_equal(within, used)


def _rotation_evidence(
    start_inliers, start_R, priors: dict, context: _Context
) -> _RotationEvidence:
    """The settled lens rotation (:func:`_settled_lens_fit`) compared by GRIC with the essential
    matrix on the union of their inliers, and the tests of a rotation and of a candidate."""
    lens, rotation_inliers = _settled_lens_fit(start_inliers, start_R, priors, context)
    x1, x2, focal = context.x1, context.x2, context.focal
    scored = context.inliers | rotation_inliers
    candidates = [
        _candidate(
            "rotation",
            lens.residuals[scored] * focal / np.sqrt(2.0),
            extra=int(priors["focal_ratio_prior"] is not None),
        ),
        _candidate("general", context.general_all[scored] * focal),
    ]
    noise_px = model_noise(candidates)
    outlying = (context.inliers & ~rotation_inliers)[scored]
    rotation_noise_px, share = _rotation_residual_field(
        lens, x1[scored], x2[scored], outlying, focal
    )
    selection = select_model(
        candidates, sigma=rotation_noise_px if rotation_noise_px > noise_px else noise_px
    )
    t_rot, pri = _rotation_translation(lens, x1, x2, rotation_inliers, context.t)
    gap = float(np.radians(rotation_error_deg(context.R, lens.R)))
    residual = selection.median_residual_px["rotation"] / focal
    return _RotationEvidence(
        lens=lens,
        inliers=rotation_inliers,
        selection=selection,
        noise_px=float(noise_px),
        rotation_noise_px=float(rotation_noise_px),
        share=share,
        t=t_rot,
        pri=float(pri),
        gap=gap,
        admissible=bool(
            pri < context.pri_threshold
            and lens.lens_excess <= LENS_SIGNIFICANCE
            and share <= MAX_COHERENT_SHARE
        ),
        close=bool(residual <= MAX_CANDIDATE_RESIDUAL and gap > MIN_CANDIDATE_ROTATION_GAP),
    )


def _plane_evidence(
    homography: HomographyEstimate, scored: np.ndarray, threshold_px: float, context: _Context
) -> _PlaneEvidence:
    """The homography's PPO pose and the tests of a plane, on the union of ``scored`` (the
    essential matrix's and the rotation's inliers) and the homography's inliers."""
    x1, x2, focal = context.x1, context.x2, context.focal
    pose = planar_pose(homography.H, x1, x2, homography.inliers, threshold=threshold_px / focal)
    union = scored | homography.inliers
    general_px = context.general_all[union] * focal
    selection = select_model(
        [_candidate("plane", homography.residuals[union]), _candidate("general", general_px)],
        mismatch_floor=PLANE_MISMATCH_FLOOR,
    )
    ratio = _epipolar_ratio(pose, x1[union], x2[union], general_px, threshold_px, focal)
    bound = max(threshold_px, OFF_PLANE_SIGMAS * context.noise * focal)
    off = np.count_nonzero(context.inliers & (homography.residuals > bound))
    off_share = off / max(int(np.count_nonzero(context.inliers)), 1)
    return _PlaneEvidence(pose, homography.inliers, selection, ratio, off_share)


def _decision(
    model: str,
    rotation: _RotationEvidence,
    plane: _PlaneEvidence,
    *,
    pure_rotation: bool,
    pri_general: float,
    rotation_candidate: bool,
    principal_bound: float,
) -> MotionDecision:
    """The :class:`MotionDecision` of ``model`` from the evidence of the rotation and the
    plane."""
    lens = rotation.lens
    return MotionDecision(
        model=model,
        pure_rotation=pure_rotation,
        pri_general=pri_general,
        rotation_candidate=rotation_candidate,
        principal_bound=principal_bound,
        R=lens.R,
        t=rotation.t,
        rotation_inliers=rotation.inliers,
        pri=rotation.pri,
        focal_scale=lens.focal_scale,
        k1=lens.k1,
        selection=rotation.selection,
        plane=plane.pose,
        homography_inliers=plane.inliers,
        plane_selection=plane.selection,
        plane_epipolar_ratio=plane.epipolar_ratio,
        plane_off_share=plane.off_share,
        rotation_sigma_deg=lens.rotation_sigma_deg,
        principal_offset=lens.principal_offset,
        focal_ratio=lens.focal_ratio,
        lens_excess=lens.lens_excess,
        noise_px=rotation.noise_px,
        rotation_noise_px=rotation.rotation_noise_px,
        coherent_share=rotation.share,
        rotation_gap=rotation.gap,
    )


def _rotation_residual_field(
    lens: LensRotationFit, x1, x2, outlying, focal: float
) -> tuple[float, float]:
    """Of the rotation's transfer errors: the noise per image coordinate (pixels) that varies
    from a match to its nearest neighbour (:func:`ppo_cv.model_selection.incoherent_sigma`; a
    transfer error carries the noise of both images), and the share of ``outlying`` matches
    that move with their neighbour (:func:`ppo_cv.model_selection.coherent_share`)."""
    if len(x1) < 3:
        return float("nan"), 0.0
    transfers = _lens_rotation_residuals(
        lens.R, lens.focal_scale, lens.k1, x1, x2, lens.principal_offset, lens.focal_ratio,
        vectors=True,
    )  # fmt: skip
    neighbours = nearest_neighbours(x1[:, :2])
    noise = incoherent_sigma(transfers * focal, neighbours) / np.sqrt(2.0)
    return noise, coherent_share(transfers, neighbours, outlying)


def _rotation_translation(lens: LensRotationFit, x1, x2, used, t_fallback):
    """Unit ``t`` most consistent with the lens rotation over ``used`` and its PRI;
    ``t_fallback`` and inf with fewer than 5 matches."""
    if np.count_nonzero(used) < 5:
        return np.asarray(t_fallback, dtype=np.float64), float("inf")
    c1 = _correct_points(x1[used], lens.focal_scale, lens.k1, lens.principal_offset)
    c2 = _correct_points(x2[used], lens.focal_scale2, lens.k1, lens.principal_offset)
    t = translation_for_rotation(lens.R, c1, c2)
    pri = ppo.pure_rotation_indicator(ppo.intersection_scores(c1, c2, lens.R, t))
    return t, float(pri)


def with_rotation(
    motion: MotionDecision,
    lens: LensRotationFit,
    x1: np.ndarray,
    x2: np.ndarray,
    focal: float,
    *,
    threshold_px: float = 1.0,
) -> MotionDecision:
    """The decision with its rotation replaced by a better fit of the same model.

    For a pair judged a pure rotation whose rotation was refitted on other evidence
    (:func:`ppo_cv.photometric.refine_rotation_photometric`): ``R``, the lens terms and
    ``rotation_sigma_deg`` are ``lens``'s; the rotation inliers among the matches (transfer error
    below :data:`TRANSFER_FACTOR` times ``threshold_px``), ``t`` and PRI are recomputed
    under it. The model, the statistics that chose it and the plane are kept.

    Parameters
    ----------
    motion : MotionDecision
    lens : LensRotationFit
        The new rotation with its focal scale and ``k1`` (its residuals are not used).
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalised points of all putative matches (as for :func:`decide_motion`).
    focal : float
        Focal length, pixels.
    threshold_px : float
        Inlier threshold of the essential matrix, pixels.

    Returns
    -------
    MotionDecision
    """
    focal, threshold_px = _require_revisit(motion, lens, None, x1, x2, focal, threshold_px)
    residuals = _lens_rotation_residuals(
        lens.R, lens.focal_scale, lens.k1, x1, x2, lens.principal_offset, lens.focal_ratio
    )
    lens = replace(lens, residuals=residuals)
    inliers = residuals < TRANSFER_FACTOR * threshold_px / focal
    t, pri = _rotation_translation(lens, x1, x2, inliers, motion.t)
    return replace(
        motion,
        R=lens.R,
        t=t,
        rotation_inliers=inliers,
        pri=pri,
        focal_scale=lens.focal_scale,
        k1=lens.k1,
        rotation_sigma_deg=lens.rotation_sigma_deg,
        principal_offset=lens.principal_offset,
        focal_ratio=lens.focal_ratio,
    )


def parallax_refuses_rotation(parallax: float, sigma: float, bound: float) -> bool:
    """Whether a ``parallax`` (radians) with deviation ``sigma`` exceeds the ``bound`` of a
    rotation's (:attr:`MotionDecision.track_parallax_bound`) by more than
    :data:`PARALLAX_SIGNIFICANCE` deviations, refusing the pure rotation it was measured for
    (False for NaN)."""
    return bool(parallax - PARALLAX_SIGNIFICANCE * sigma > bound)


def _require_revisit(motion, lens, parallax, x1, x2, focal, threshold_px) -> tuple[float, float]:
    """TypeError or ValueError naming the argument of :func:`with_rotation` or
    :func:`with_tracks` that is not of its kind: a decision, a lens fit, a parallax or None,
    matches as :func:`translation_for_rotation` takes them, a focal length and a threshold
    (positive, pixels); the last two checked."""
    require_instance(motion, MotionDecision, "motion")
    require_instance(lens, LensRotationFit, "lens")
    require_instance(parallax, (PlaneParallax, type(None)), "parallax")
    require_pose_matches(lens.R, np.zeros(3), x1, x2, moving=False, bearings=True)
    return as_positive_at_most(focal, "focal", MAX_FOCAL, " pixels"), as_positive(
        threshold_px, "threshold_px"
    )


def with_tracks(
    motion: MotionDecision,
    lens: LensRotationFit,
    parallax: PlaneParallax | None,
    x1: np.ndarray,
    x2: np.ndarray,
    focal: float,
    *,
    threshold_px: float = 1.0,
) -> MotionDecision:
    """A decision revisited on the intensity-aligned tracks of its rotation.

    The tracks (:func:`ppo_cv.photometric.refine_rotation_photometric`) are located far better
    than feature matches, and a homography fitted to them says how far the scene's dominant
    plane moved against its distance (:mod:`ppo_cv.parallax`).

    - A pure rotation whose parallax exceeds :data:`MAX_TRACK_PARALLAX` by more than
      :data:`PARALLAX_SIGNIFICANCE` of its deviations is not one: its model becomes the plane
      or general motion that :func:`decide_motion` would have chosen without the rotation.
      Its lens clipped at the box (:attr:`MotionDecision.lens_clipped`), the bound is
      :data:`NEGLIGIBLE_PARALLAX`: the matches' fit may have bent the lens to absorb a
      translation, and the tracks, refitted in the wider box, measure it.
    - A :attr:`MotionDecision.rotation_candidate` whose parallax stays below
      :data:`NEGLIGIBLE_PARALLAX` with :data:`NEGLIGIBLE_SIGNIFICANCE` deviations to spare
      is a pure rotation: the translation GRIC saw is real but negligible.

    A pair that is or becomes a pure rotation takes the tracks' rotation
    (:func:`with_rotation`); any other keeps its decision.

    Parameters
    ----------
    motion : MotionDecision
        A decision of a pure rotation, or of a rotation candidate.
    lens : LensRotationFit
        The rotation refitted on the tracks.
    parallax : PlaneParallax or None
        :attr:`ppo_cv.photometric.PhotometricRotation.parallax` of those tracks.
    x1, x2, focal, threshold_px
        As for :func:`with_rotation`.

    Returns
    -------
    MotionDecision
        With ``track_parallax`` and ``track_parallax_sigma`` set.
    """
    _require_revisit(motion, lens, parallax, x1, x2, focal, threshold_px)
    value = float("nan") if parallax is None else parallax.parallax
    sigma = float("nan") if parallax is None else parallax.sigma
    motion = replace(motion, track_parallax=value, track_parallax_sigma=sigma)
    if motion.pure_rotation:
        if parallax_refuses_rotation(value, sigma, motion.track_parallax_bound):
            model = _plane_or_general(
                motion.plane_selection, motion.plane, motion.plane_epipolar_ratio,
                motion.plane_off_share,
            )  # fmt: skip
            return replace(motion, model=model, pure_rotation=False)
    elif (
        motion.rotation_candidate and value + NEGLIGIBLE_SIGNIFICANCE * sigma <= NEGLIGIBLE_PARALLAX
    ):
        motion = replace(motion, model="rotation", pure_rotation=True)
    else:
        return motion
    return with_rotation(motion, lens, x1, x2, focal, threshold_px=threshold_px)


def _candidate(name: str, residuals: np.ndarray, extra: int = 0) -> ModelResiduals:
    dimension, num_params = MODEL_DIMENSIONS[name]
    return ModelResiduals(name, residuals, dimension, num_params + extra)


def _epipolar_ratio(plane, x1, x2, general_px, threshold_px: float, focal: float) -> float:
    """Mean of ``min(e^2, (5 threshold)^2)`` over the Sampson errors (pixels) of ``[t]x R`` of
    the planar pose, over the same for the refined essential matrix (``general_px``)."""
    if not float(np.linalg.norm(plane.t)) > 0:
        return float("inf")
    cap = (EPIPOLAR_CAP_FACTOR * threshold_px) ** 2
    planar_px = _sampson_errors(_essential_from_pose(plane.R, plane.t), x1, x2) * focal
    rho = [np.mean(np.minimum(e**2, cap)) for e in (planar_px, general_px)]
    return float(rho[0] / max(rho[1], 1e-300))


def _plane_or_general(
    selection: ModelSelection | None,
    plane: PlanarPose | None,
    epipolar_ratio: float,
    off_share: float,
) -> str:
    """``"plane"`` when it wins ``selection``, its pose is a translation, that pose's
    essential matrix explains the matches almost as well as the refined one, and few of the
    refined one's inliers lie off the plane."""
    if plane is None or selection is None or selection.model != "plane":
        return "general"
    moving = float(np.linalg.norm(plane.t)) > 0 and np.isfinite(plane.distance)
    consistent = epipolar_ratio <= PLANE_EPIPOLAR_TOLERANCE and off_share <= MAX_OFF_PLANE_SHARE
    return "plane" if moving and consistent and plane.support >= MIN_PLANE_SUPPORT else "general"
