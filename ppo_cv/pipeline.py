"""From two photos to ``(R, t)``, the model (rotation, plane or general) and 3D points.

Stages (each timed in ``PairResult.timings``, seconds):

1. ``features``: SIFT (RootSIFT) keypoints, or ORB / AKAZE (:mod:`ppo_cv.features`);
   ``pycolmap_import`` is the wait for the first import of pycolmap that runs beside it.
   When the essential matrix (stage 4) finds fewer than ``PairOptions.redetect_below``
   inliers, stages 1-4 run again on features detected at a lower threshold
   (:data:`REDETECT_THRESHOLD_SCALE`) and the fit that chance explains less (lower ``log10``
   NFA, :mod:`ppo_cv.significance`) is kept; each stage's time is the sum of both runs.
2. ``matching``: mutual nearest neighbours with Lowe's ratio test, one match per pixel pair.
3. ``undistort``: matched pixels to normalized coordinates ``K^-1 [u, v, 1]``, lens distortion
   removed from the points (never from the images).
4. ``ransac``: robust essential matrix (:mod:`ppo_cv.robust`).
5. ``ppo``: the pose among the four candidates of ``E`` by the PPO inequalities (same-side M1
   for ``R``, intersection M2 for ``t``), without triangulation.
6. ``refine``: non-linear refinement of ``(R, t)`` over the inliers (:mod:`ppo_cv.refine`).
7. ``homography``: robust homography on the same matches (:mod:`ppo_cv.homography`); with
   ordered sampling it samples the essential matrix's inliers only (a plane's matches are
   nearly all of them) and takes its inliers among all matches.
8. ``model``: rotation-only fit on the same matches (2-point RANSAC, then rotation with a focal
   scale and radial distortion, :mod:`ppo_cv.rotation`), the PPO choice among the homography's
   decomposition candidates (:mod:`ppo_cv.plane`) and the choice among "rotation", "plane" and
   "general" (:mod:`ppo_cv.motion_model`).
9. ``photometric``: for a pure rotation or a rotation candidate, the rotation refitted on
   windows of the images aligned by intensity through the rotation-only fit
   (:mod:`ppo_cv.photometric`), and the decision revisited on the parallax of those tracks
   (:func:`ppo_cv.motion_model.with_tracks`).
10. ``decision``: for a pure rotation the rotation of the rotation-only fit and no point; for a
    plane the PPO pose of the homography refined on the homography itself with a radial term
    (:func:`ppo_cv.plane.refine_planar_pose`; not on ``E``: plane matches leave the essential
    matrix nearly degenerate), and the analytic points (Prop. 3) of its inliers;
    otherwise the PPO pose of ``E`` refined with a radial distortion term when one is
    significant (:func:`ppo_cv.refine.refine_pose_radial`) and its analytic points. The
    uncertainty of the direction of ``t`` comes from the Sampson cost of ``E = [t]x R`` at the
    reported pose in both moving cases.
"""

from __future__ import annotations

import importlib
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import ppo
from .camera import pixels_to_normalized, principal_point_is_centre
from .checks import as_camera_matrix, as_distortion
from .features import (
    FEATURE_TYPES,
    Features,
    at_threshold,
    detect_features,
    match_features_scored,
    require_detectable,
)
from .homography import estimate_homography
from .images import as_image as _as_image
from .images import load_image
from .motion_model import decide_motion, plane_ransac_trials, with_tracks
from .photometric import refine_rotation_photometric
from .plane import refine_planar_pose, undistort_division
from .pose import _recover_normalized
from .refine import (
    T_SIGMA_CAP_DEG,
    huber_bound_px,
    refine_pose,
    refine_pose_radial,
    translation_sigma_deg,
)
from .robust import (
    ROBUST_BACKENDS,
    RobustEstimate,
    essential_from_pose,
    estimate_essential,
    estimate_essential_ordered,
    sampson_errors,
)
from .rotation import (
    K1_PRIOR,
    PRINCIPAL_BOUND,
    PRINCIPAL_PRIOR,
    focal_ratio_keywords,
    focal_ratio_prior,
)
from .significance import (
    CONFIDENT_LOG10_NFA,
    DEFAULT_MAX_LOG10_NFA,
    Significance,
    distinctiveness,
    epipolar_significance,
)

__all__ = [
    "PairOptions",
    "PairResult",
    "estimate_pair",
    "load_image",
    "MIN_MATCHES",
    "MIRROR_MIN_INLIERS",
    "MAX_RANSAC_THRESHOLD",
    "DEFAULT_MAX_LOG10_NFA",
]

MIN_MATCHES = 8
MIRROR_MIN_INLIERS = 8
"""Inliers a homography that reverses orientation needs before :func:`estimate_pair` calls the
pair mirrored: a few more than its minimal sample of 4 may fit matches of either sign (one of
the 85 freiburg pairs has a reversing homography of 5 inliers, none of more)."""
MAX_RANSAC_THRESHOLD = 100.0
PRINCIPAL_POINT_MODES = ("auto", "fit", "given")
FOCAL_RATIO_MODES = ("auto", "given")
REDETECT_THRESHOLD_SCALE = 0.25
"""Detector threshold scale of the second detection, for pairs whose first consensus is weak.
A few dozen matches can neither tell a rotation from a general motion nor pin a pose. On the
narrow overlaps with sensor noise of ``benchmarks/pure_rotation.py`` (24-78 matches at
OpenCV's SIFT contrast threshold 0.04) 9 of 14 pure rotations were flagged, 14 of 14 at 0.01;
on freiburg the AUC@5/10/20 rises from 62.4 / 74.7 / 82.7 to 65.2 / 77.6 / 85.3 (46 of 85
pairs detected again, 37 keeping the denser features; at 0.02 the gain at AUC@5 and @10 was
about half). Detecting at a lower
threshold on every pair costs the pairs with many inliers accuracy, weak keypoints being
located worse: at 0.02 throughout, freiburg's AUC@5 fell to 60.6."""
MAX_SEARCH_SIGMA_DEG = 5.0
"""Rotation uncertainty handed to the photometric refit when the lens fit has none (a lens
clipped to its box): the refit searches 3 times this and accepts a change of 4 times it."""


@dataclass(frozen=True)
class PairOptions:
    """Settings of :func:`estimate_pair`.

    Attributes
    ----------
    features : {"sift", "orb", "akaze"}
        Detector and descriptor.
    max_features : int
        Keypoints kept per image, strongest first.
    max_image_size : int or None
        Detect on a copy whose longer side is at most this (pixels); None keeps full size, at
        a cost growing with the pixel count (a 6000x4000 pair: 4.7 s and 1.1 GB with the
        default, reported at 41 s and 11.3 GB with None).
    ratio : float
        Lowe's ratio test bound.
    mutual : bool
        Keep only mutual nearest neighbours.
    backend : {"pycolmap", "opencv"}
        Robust estimator of ``E``: COLMAP LO-RANSAC or OpenCV USAC MAGSAC++.
    ransac_threshold : float
        Inlier threshold on the epipolar error, pixels.
    confidence : float
        RANSAC confidence.
    min_trials, max_trials : int
        Bounds on the number of RANSAC hypotheses.
    redetect_below : int
        When the essential matrix has fewer inliers than this (or none could be fitted), detect
        again with the detector threshold scaled by :data:`REDETECT_THRESHOLD_SCALE` and keep
        the fit whose consensus has the lower ``log10`` NFA; 0 never does. Given ``features1``
        and ``features2``, the second detection runs on the images.
    ordered_sampling : bool
        Fit ``E`` on the best-ranked matches (ratio test) first and over all of them only when
        that is not significant (:func:`ppo_cv.robust.estimate_essential_ordered`), and sample
        the homography on the essential matrix's inliers; False runs each fit over all
        matches, up to ``max_trials`` hypotheses.
    refine : bool
        Refine ``(R, t)`` over the inliers.
    pri_threshold : float
        Pure rotation when PRI is below it (paper: 0.015).
    min_inliers : int
        Fewer inliers than this is an error, not a pose.
    seed : int
        RANSAC seed.
    max_log10_nfa : float
        Significance bar: the robust fit is a pose only when ``log10`` of its number of false
        alarms (:mod:`ppo_cv.significance`) is at most this; lower is stricter, ``inf`` turns
        the test off.
    plane : bool
        Fit a homography too and let the model decision call the pair a plane (on by default:
        with it no rendered preset and no freiburg AUC drops, ``docs/benchmarks.md`` section
        6); False decides between rotation and general only.
    photometric : bool
        For a pair judged a pure rotation, refit the rotation on windows of the images aligned
        by intensity through the rotation of the matches (:mod:`ppo_cv.photometric`): on
        imperfect renders and warped photos in full overlap the median rotation error of each
        set drops from 0.02-0.18 to 0.00-0.04 degrees, and from 0.12 to 0.07 against the
        given-focal rotation
        (``benchmarks/pure_rotation.py``). The same tracks veto a rotation whose plane moved
        and call a rotation candidate whose parallax is negligible a pure rotation
        (:func:`ppo_cv.motion_model.with_tracks`). False keeps the rotation and the decision of
        the feature matches.
    principal_point : {"auto", "fit", "given"}
        Whether the rotation-only model may move the principal point
        (:func:`ppo_cv.rotation.fit_rotation_lens`, prior :data:`ppo_cv.rotation.PRINCIPAL_PRIOR`
        of the image width across and of its height down). ``"auto"`` fits it when both
        cameras are given theirs at the image centre (within half a pixel of ``(w - 1) / 2`` or
        ``w / 2``, likewise ``h``): a guess, as from an EXIF or panorama-stitcher focal
        length, where an offset of 1 % of the image leaves residuals that turn a narrow-field
        pure rotation into a general motion; a calibrated principal point is kept. ``"fit"``
        always, ``"given"`` never.
    focal_ratio : {"auto", "given"}
        Whether the rotation-only model may scale image 2's focal length against image 1's.
        ``"auto"`` does when the two given focal lengths differ by at most
        :data:`ppo_cv.rotation.FOCAL_RATIO_GAP` (two estimates of one lens, as a panorama
        stitcher gives them, whose difference is a zoom no rotation explains), under the prior
        of :func:`ppo_cv.rotation.focal_ratio_prior`; ``"given"`` keeps the given ratio (two
        calibrated cameras).
    """

    features: str = "sift"
    max_features: int = 8000
    max_image_size: int | None = 2000
    ratio: float = 0.9
    mutual: bool = True
    backend: str = "pycolmap"
    ransac_threshold: float = 1.0
    confidence: float = 0.9999
    min_trials: int = 100
    # Kept at 100_000 for the uniform fit: on the freiburg pairs a cap of 50_000, 30_000 or
    # 10_000 lowered the mean AUC@5 over seeds 0-2, as did ratio 0.8 or 0.85; ordered sampling
    # (docs/cli.md, batch runs) is what makes the hard pairs (10-20 % inliers) cheap.
    max_trials: int = 100_000
    ordered_sampling: bool = True
    redetect_below: int = 100
    refine: bool = True
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD
    min_inliers: int = 8
    seed: int = 0
    max_log10_nfa: float = DEFAULT_MAX_LOG10_NFA
    plane: bool = True
    photometric: bool = True
    principal_point: str = "auto"
    focal_ratio: str = "auto"

    def __post_init__(self) -> None:
        for name, modes in (
            ("principal_point", PRINCIPAL_POINT_MODES),
            ("focal_ratio", FOCAL_RATIO_MODES),
        ):
            if getattr(self, name) not in modes:
                raise ValueError(
                    f"unknown {name} {getattr(self, name)!r}; choose one of {', '.join(modes)}"
                )
        if self.features not in FEATURE_TYPES:
            raise ValueError(
                f"unknown features {self.features!r}; choose one of {', '.join(FEATURE_TYPES)}"
            )
        if self.backend not in ROBUST_BACKENDS:
            raise ValueError(
                f"unknown backend {self.backend!r}; choose one of {', '.join(ROBUST_BACKENDS)}"
            )
        if not 0 < self.ratio <= 1:
            raise ValueError(f"ratio must be in (0, 1], got {self.ratio}")
        if not 0 < self.ransac_threshold <= MAX_RANSAC_THRESHOLD:
            raise ValueError(
                f"ransac_threshold must be in (0, {MAX_RANSAC_THRESHOLD:g}] pixels, "
                f"got {self.ransac_threshold}"
            )
        if not (0 <= self.pri_threshold < float("inf")):
            raise ValueError(
                f"pri_threshold must be a finite number >= 0, got {self.pri_threshold}"
            )
        if self.max_log10_nfa != self.max_log10_nfa:
            raise ValueError("max_log10_nfa must be a number (inf disables the test), got nan")
        if not 0 < self.confidence < 1:
            raise ValueError(f"confidence must be in (0, 1), got {self.confidence}")
        if (
            self.max_features < 8
            or not 1 <= self.min_trials <= self.max_trials
            or self.min_inliers < 5
        ):
            raise ValueError(
                "need max_features >= 8, 1 <= min_trials <= max_trials and min_inliers >= 5"
            )
        if self.redetect_below < 0:
            raise ValueError(f"redetect_below must be >= 0, got {self.redetect_below}")
        if self.max_image_size is not None and self.max_image_size < 32:
            raise ValueError(f"max_image_size must be >= 32, got {self.max_image_size}")


@dataclass(frozen=True)
class PairResult:
    """Relative pose of two images and its evidence.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation from camera 1 to camera 2, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Unit translation direction. When ``pure_rotation`` is True it is the best unit estimate
        but undetermined (``translation_determined`` is False).
    pure_rotation : bool
        The views share a centre, or the baseline is negligible (:mod:`ppo_cv.motion_model`:
        the rotation model wins GRIC and its PRI is below ``pri_threshold``, or GRIC sees a
        translation whose parallax the intensity-aligned windows measure as negligible, with
        ``gric_difference`` then positive).
    pri : float
        Pure-rotation indicator (mean ``|M2|``, eq. 84) of the returned pose over the inliers:
        the essential matrix's refined pose, for a plane the homography's PPO pose, or for a
        pure rotation the rotation-only fit with the ``t`` most consistent with it.
    keypoints1, keypoints2 : ndarray, shape (N1, 2), (N2, 2)
        All detected keypoints, full-resolution pixels.
    matches : ndarray of int, shape (M, 2)
        Putative matches, indices into ``keypoints1`` and ``keypoints2``.
    inliers : ndarray of bool, shape (M,)
        Matches consistent with the estimated two-view geometry (for a plane, the homography).
    points3d : ndarray, shape (M, 3)
        Analytic point (Proposition 3) of each match in camera-1 coordinates with unit
        baseline; NaN outside the inliers, where the PPO inequalities fail or the rays are
        parallel, and everywhere for a pure rotation (as ``PoseResult.points3d``).
    point_matches : ndarray of int, shape (P,)
        Rows of ``matches`` with a finite point: ``points3d[point_matches]``.
    colours : ndarray of uint8, shape (M, 3)
        RGB colour of each match, sampled from image 1.
    K1, K2 : ndarray, shape (3, 3)
        Intrinsics used.
    dist1, dist2 : ndarray or None
        OpenCV distortion coefficients removed from the points; None for none.
    image_size1, image_size2 : tuple of int
        ``(width, height)`` of each image.
    pri_threshold : float
        PRI threshold used.
    model : str
        ``"rotation"``, ``"plane"`` (the matches lie on one plane: pose from its homography)
        or ``"general"`` (:mod:`ppo_cv.motion_model`).
    t_sigma_deg : float
        One standard deviation of the direction of ``t`` (degrees, at most 90) from the
        Jacobian of the Sampson cost of ``E = [t]x R`` at the reported pose over its inliers,
        less what the image noise alone puts there, the given focal length off by
        :data:`ppo_cv.rotation.FOCAL_PRIOR` and the radial term under
        :data:`ppo_cv.rotation.K1_PRIOR` (:func:`ppo_cv.refine.translation_sigma_deg`); grows
        as the baseline shrinks. For a pure rotation it is the cap: the decision is that the
        matches do not determine ``t``, and the essential matrix's apparent confidence there
        comes from lens errors its translation absorbs.
    rotation_sigma_deg : float
        For a pure rotation: root-mean-square angle error (degrees) of ``R``, from the
        covariance of the rotation-only fit with its focal scale and radial term under their
        priors (:attr:`ppo_cv.rotation.LensRotationFit.rotation_sigma_deg`): how well these
        matches determine the rotation when the focal length is known only to a few percent.
        When ``R`` was refitted on intensity-aligned windows (``rotation_tracks > 0``), the
        same bound over those tracks, its variance multiplied by how many windows share a pixel
        (:func:`ppo_cv.photometric.window_overlap`). NaN otherwise.
    rotation_tracks : int
        For a pure rotation whose rotation was refitted on windows aligned by intensity
        (:mod:`ppo_cv.photometric`, ``PairOptions.photometric``): the number of tracks behind
        ``R``, ``focal_scale`` and ``rotation_sigma_deg``. 0 when ``R`` is that of the feature
        matches.
    rotation_residual_px, general_residual_px : float
        Median residual (pixels, distance in the joint image space) of the rotation-only fit
        and of the essential matrix over the union of their inliers.
    gric_difference : float
        ``(GRIC(rotation) - GRIC(general)) / n``: the decision statistic, negative for a rotation.
    lens_excess : float
        How far the lens the rotation-only fit needed (focal scale, ``k1``, focal ratio) lay
        beyond the box of plausible lenses, in its own posterior deviations
        (:attr:`ppo_cv.motion_model.MotionDecision.lens_excess`): above
        :data:`ppo_cv.motion_model.LENS_SIGNIFICANCE` no pair is a pure rotation, whatever
        ``gric_difference`` says. Negative inside the box; NaN when not estimated.
    plane_residual_px : float
        Median residual (pixels, homography Sampson error) of the homography over the same
        matches; NaN when no homography was fitted.
    gric_plane_difference : float
        ``(GRIC(plane) - GRIC(general)) / n``: negative when the plane explains more.
    plane_epipolar_ratio : float
        How much worse the essential matrix of the homography's pose explains the matches than
        the refined one (about 1 on a plane; a plane needs at most
        :data:`ppo_cv.motion_model.PLANE_EPIPOLAR_TOLERANCE`); NaN without a homography.
    plane_normal : ndarray, shape (3,) or None
        For a plane: its unit normal ``n`` in camera 1, the plane being ``n^T X1 = d``.
    plane_distance : float
        For a plane: ``d`` in baselines (the unit of ``points3d``); NaN otherwise.
    plane_ambiguous : bool
        For a plane: a second decomposition candidate also keeps every point in front of both
        cameras (the two-fold ambiguity of a homography), and the tie was broken by the matches
        off the plane or by the prior that the plane faces the cameras
        (:func:`ppo_cv.plane.select_plane_pose`). False otherwise.
    plane_k1 : float
        For a plane: the radial (division-model) coefficient fitted with its homography
        (:func:`ppo_cv.plane.refine_planar_pose`; 0 when not significant), NaN otherwise.
    radial_k1 : float
        For a general motion: the radial (division-model) coefficient fitted with the pose
        (:func:`ppo_cv.refine.refine_pose_radial`; 0 when not kept); ``R``, ``t`` and the
        points are those of the points it undistorts. NaN otherwise.
    noise_sigma_px : float
        Noise estimated from the essential matrix's residuals (pixels).
    rotation_noise_px : float
        Noise of the rotation-only fit's residuals that changes from a match to its nearest
        neighbour (pixels, :func:`ppo_cv.model_selection.incoherent_sigma`); the model
        comparison divides by the larger of the two.
    coherent_share : float
        Share of the compared matches that the essential matrix explains, the rotation-only
        fit does not, and that move with their nearest neighbour (a surface with parallax or a
        moving object, :func:`ppo_cv.model_selection.coherent_share`); above
        :data:`ppo_cv.motion_model.MAX_COHERENT_SHARE` the pair is not a pure rotation.
    track_parallax, track_parallax_sigma : float
        For a pair the matches called a pure rotation, or a rotation candidate
        (:attr:`ppo_cv.motion_model.MotionDecision.rotation_candidate`), whose windows were
        aligned by intensity: the baseline over the distance of the plane those tracks fit
        best, and its deviation (:mod:`ppo_cv.parallax`). Beyond
        :data:`ppo_cv.motion_model.MAX_TRACK_PARALLAX` by
        :data:`ppo_cv.motion_model.PARALLAX_SIGNIFICANCE` deviations a pure rotation is not
        one; below :data:`ppo_cv.motion_model.NEGLIGIBLE_PARALLAX` with
        :data:`ppo_cv.motion_model.NEGLIGIBLE_SIGNIFICANCE` deviations to spare a candidate
        is one (:func:`ppo_cv.motion_model.with_tracks`). NaN otherwise.
    rotation_gap_deg : float
        Angle (degrees) between the refined essential matrix's rotation and the rotation-only
        fit. Beyond :data:`ppo_cv.motion_model.MIN_CANDIDATE_ROTATION_GAP` the essential matrix
        bent its rotation more than a negligible translation would, and a pair GRIC calls
        general may be a rotation candidate (``track_parallax``).
    focal_scale : float
        Focal scale absorbed by the rotation-only fit (given focal length over the true one).
    focal_ratio : float
        Scale of image 2's focal length against image 1's absorbed by the rotation-only fit
        when the two were given slightly different (focal lengths estimated per photo, as by a
        panorama stitcher; :func:`ppo_cv.rotation.focal_ratio_prior`,
        ``PairOptions.focal_ratio``); 1 otherwise.
    principal_offset_px : ndarray, shape (2,)
        Offset of the true principal point from the given one found by the rotation-only fit
        (pixels; zero when it was not fitted, ``PairOptions.principal_point``).
    principal_bound : float
        Largest offset that fit accepted, in deviations of its prior per coordinate:
        :data:`ppo_cv.rotation.PRINCIPAL_BOUND`, or :data:`ppo_cv.rotation.PRINCIPAL_WIDE_BOUND`
        for a pair that only the wider bound makes a rotation candidate (a pure rotation only
        if its tracks confirm it, ``track_parallax``).
    timings : dict
        Seconds per stage; ``features`` is detection alone and ``pycolmap_import`` the wait for
        the first import of pycolmap that overlaps it.
    threshold_scale : float
        Detector threshold scale of the features behind the result: 1, or
        :data:`REDETECT_THRESHOLD_SCALE` when the second detection (``PairOptions.redetect_below``)
        gave a fit that chance explains less.
    log10_nfa : float
        ``log10`` of the number of false alarms of the robust fit's consensus
        (:mod:`ppo_cv.significance`): how many consensus sets this good chance alone would
        produce; the pose is reported only when it is at most ``PairOptions.max_log10_nfa``.
    """

    R: np.ndarray
    t: np.ndarray
    pure_rotation: bool
    pri: float
    keypoints1: np.ndarray
    keypoints2: np.ndarray
    matches: np.ndarray
    inliers: np.ndarray
    points3d: np.ndarray
    point_matches: np.ndarray
    colours: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    image_size1: tuple[int, int]
    image_size2: tuple[int, int]
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD
    model: str = "general"
    t_sigma_deg: float = float("nan")
    rotation_sigma_deg: float = float("nan")
    rotation_tracks: int = 0
    rotation_residual_px: float = float("nan")
    general_residual_px: float = float("nan")
    gric_difference: float = float("nan")
    lens_excess: float = float("nan")
    noise_sigma_px: float = float("nan")
    rotation_noise_px: float = float("nan")
    coherent_share: float = 0.0
    track_parallax: float = float("nan")
    track_parallax_sigma: float = float("nan")
    rotation_gap_deg: float = float("nan")
    focal_scale: float = 1.0
    focal_ratio: float = 1.0
    principal_offset_px: np.ndarray = field(default_factory=lambda: np.zeros(2))
    principal_bound: float = PRINCIPAL_BOUND
    timings: dict[str, float] = field(default_factory=dict)
    threshold_scale: float = 1.0
    dist1: np.ndarray | None = None
    dist2: np.ndarray | None = None
    log10_nfa: float = float("nan")
    plane_residual_px: float = float("nan")
    gric_plane_difference: float = float("nan")
    plane_epipolar_ratio: float = float("nan")
    plane_normal: np.ndarray | None = None
    plane_distance: float = float("nan")
    plane_ambiguous: bool = False
    plane_k1: float = float("nan")
    radial_k1: float = float("nan")

    @property
    def translation_determined(self) -> bool:
        """False for a pure rotation, whose translation direction the images do not fix."""
        return not self.pure_rotation

    @property
    def num_matches(self) -> int:
        """Number of putative matches."""
        return int(self.matches.shape[0])

    @property
    def num_inliers(self) -> int:
        """Number of inlier matches."""
        return int(np.count_nonzero(self.inliers))

    @property
    def num_points(self) -> int:
        """Number of finite 3D points."""
        return int(self.point_matches.shape[0])

    @property
    def inlier_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (I, 2) of the inlier matches in image 1 and image 2."""
        m = self.matches[self.inliers]
        return self.keypoints1[m[:, 0]], self.keypoints2[m[:, 1]]


def _principal_prior(mode: str, K1, K2, shape1, shape2, focal: float) -> np.ndarray | None:
    """Prior ``(x, y)`` of the principal-point offset in normalised units of ``focal`` (pixels),
    :data:`PRINCIPAL_PRIOR` of the larger width and height, None to keep the given point."""
    sizes = [(int(shape[1]), int(shape[0])) for shape in (shape1, shape2)]
    guessed = all(
        principal_point_is_centre(K, size) for K, size in zip((K1, K2), sizes, strict=True)
    )
    if mode == "given" or (mode == "auto" and not guessed):
        return None
    return PRINCIPAL_PRIOR * np.max(np.array(sizes, dtype=float), axis=0) / focal


def _normalize(points: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Pixels (N, 2) to homogeneous normalized coordinates (N, 3), distortion removed."""
    xy = pixels_to_normalized(points, K, dist)
    return np.column_stack([xy, np.ones(len(xy))])


def _colours(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    h, w = image.shape[:2]
    u = np.clip(np.rint(points[:, 0]).astype(int), 0, w - 1)
    v = np.clip(np.rint(points[:, 1]).astype(int), 0, h - 1)
    pixels = image[v, u]
    if image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 1):
        pixels = np.repeat(pixels.reshape(-1, 1), 3, axis=1)
    else:
        pixels = pixels[:, 2::-1]  # BGR(A) -> RGB
    return np.clip(pixels, 0, 255).astype(np.uint8)


def _detect_both(
    image1, image2, options: PairOptions, threshold_scale: float = 1.0
) -> tuple[Features, Features, float]:
    """Features of both images on two threads (OpenCV releases the GIL), and when both were done.

    One pair detects at threshold 1 and again lower only when its consensus is weak: SIFT
    detected once at :data:`REDETECT_THRESHOLD_SCALE` and thinned to 1
    (:func:`ppo_cv.features.at_threshold`, what the feature cache of ``ppo-cv pairs`` holds)
    costs a weak pair less but a strong one more, up to twice as much on finely textured
    images (a 640x480 render 141 -> 228 ms per image, the 611x918 pano_dev pair 147 -> 282),
    and left the median whole-pair time of ten freiburg pairs unchanged (0.39-0.41 s CPU).

    The first use of pycolmap in a process pays its import; it is overlapped with detection.
    The returned ``time.perf_counter()`` of the end of detection separates the two.
    """
    from concurrent.futures import ThreadPoolExecutor

    def run(image):
        features = detect_features(
            image, options.features, options.max_features, options.max_image_size, threshold_scale
        )
        return features, time.perf_counter()

    with ThreadPoolExecutor(max_workers=3) as pool:
        if options.backend == "pycolmap" and "pycolmap" not in sys.modules:
            pool.submit(importlib.import_module, "pycolmap")
        (f1, done1), (f2, done2) = pool.map(run, (image1, image2))
    return f1, f2, max(done1, done2)


def _thins_to(features: Features, threshold_scale: float) -> bool:
    """Whether ``features`` hold those of a detection at ``threshold_scale``
    (:func:`ppo_cv.features.at_threshold`)."""
    return (
        features.kind == "sift"
        and features.responses is not None
        and features.threshold_scale <= threshold_scale
    )


def _thinned(features: Features, threshold_scale: float) -> Features:
    """``features`` at ``threshold_scale`` when they were detected lower; else as they are."""
    if _thins_to(features, threshold_scale) and features.threshold_scale < threshold_scale:
        return at_threshold(features, threshold_scale)
    return features


def _refine(R, t, x1, x2, inliers, focal, options: PairOptions, rounds: int = 3):
    """Refine over the inliers, re-select the inliers of the refined pose, until they settle."""
    threshold = options.ransac_threshold / focal
    for _ in range(rounds):
        R, t = refine_pose(R, t, x1, x2, inliers, focal)
        within = sampson_errors(essential_from_pose(R, t), x1, x2) < threshold
        if np.count_nonzero(within) < options.min_inliers or np.array_equal(within, inliers):
            break
        inliers = within
    return R, t, inliers


def _require_same_size(image1: np.ndarray, image2: np.ndarray) -> None:
    """One camera matrix for two image sizes is almost surely wrong (a resized or rotated
    image moves the principal point and scales the focal length): an error, not a guess."""
    if image1.shape[:2] != image2.shape[:2]:
        (h1, w1), (h2, w2) = image1.shape[:2], image2.shape[:2]
        raise ValueError(
            f"image1 is {w1}x{h1} and image2 {w2}x{h2} pixels but K2 was not given: one camera "
            "matrix cannot fit both sizes; pass K2 for image2"
        )


def _require_significance(E, x1, x2, K2, shape2, options: PairOptions, ratios):
    """The a-contrario test of the fit over all matches, and for a weak consensus the
    distinctiveness test of its matches by their Lowe ``ratios`` (:mod:`ppo_cv.significance`);
    ValueError when the consensus may be chance."""
    significance = epipolar_significance(E, x1, x2, K2, (int(shape2[1]), int(shape2[0])))
    refused = not significance.log10_nfa <= options.max_log10_nfa
    detail = f"log10 NFA {significance.log10_nfa:.1f} > {options.max_log10_nfa:g}"
    if not refused and CONFIDENT_LOG10_NFA < significance.log10_nfa < np.inf:
        p_value = distinctiveness(ratios, significance.consistent)
        joint = significance.log10_nfa + np.log10(max(p_value, 1e-300))
        refused = not joint <= CONFIDENT_LOG10_NFA
        detail = (
            f"log10 NFA {significance.log10_nfa:.1f} and distinctiveness p = {p_value:.2f} of its "
            f"matches: {joint:.1f} > {CONFIDENT_LOG10_NFA:g}"
        )
    if refused:
        raise ValueError(
            f"no reliable two-view geometry: the consensus may be chance ({detail}; best "
            f"{significance.num_consistent} of {significance.num_matches} matches within "
            f"{significance.threshold:.2f} px)"
        )
    return significance


def _require_unmirrored(homography) -> None:
    """ValueError when the homography of the matches (:func:`ppo_cv.homography.
    estimate_homography`, scaled to positive depths) reverses orientation with at least
    :data:`MIRROR_MIN_INLIERS` inliers: one image is a mirror image of the other.

    A plane seen by two cameras maps between the images by ``H = R + t n^T / d``, with
    ``det H = 1 - n^T c2 / d`` for camera 2's centre ``c2``: positive while both centres lie on
    the plane's visible side, as they must to see it; a pure rotation's ``H = R`` has
    determinant 1. A reflection (``image[:, ::-1]``) has determinant -1 and still fits an
    essential matrix, so without this test it reads as a confident general motion of 80-84 deg.
    """
    if homography is None or homography.num_inliers < MIRROR_MIN_INLIERS:
        return
    determinant = float(np.linalg.det(homography.H))
    if determinant < 0:
        raise ValueError(
            "the images are mirror images of each other: the homography of "
            f"{homography.num_inliers} matches reverses the orientation of the image "
            f"(determinant {determinant:.2f} < 0), which no camera motion does; flip one image "
            "back (left-right: image[:, ::-1])"
        )


def _ransac_keywords(options: PairOptions) -> dict:
    return {
        "backend": options.backend,
        "threshold": options.ransac_threshold,
        "confidence": options.confidence,
        "min_trials": options.min_trials,
        "max_trials": options.max_trials,
        "seed": options.seed,
    }


@dataclass(frozen=True)
class _Consensus:
    """The matches of two feature sets and the robust essential matrix over them."""

    features1: Features
    features2: Features
    threshold_scale: float
    matches: np.ndarray
    x1: np.ndarray
    x2: np.ndarray
    fit: RobustEstimate
    significance: Significance


def _consensus(
    f1, f2, threshold_scale, K1, K2, dist1, dist2, focal, shape2, options, lap
) -> _Consensus:
    """Match, normalise and fit ``E`` robustly (stages 2-4) on the features at
    ``threshold_scale`` (SIFT features detected lower thinned to it); ValueError names what is
    missing."""
    f1, f2 = _thinned(f1, threshold_scale), _thinned(f2, threshold_scale)
    for name, f in (("image1", f1), ("image2", f2)):
        if len(f) < MIN_MATCHES:
            raise ValueError(f"{name} has too few features ({len(f)}): blank or textureless image")
    matches, scores = match_features_scored(f1, f2, ratio=options.ratio, mutual=options.mutual)
    if len(matches) < MIN_MATCHES:
        raise ValueError(f"too few matches between the images ({len(matches)}, need {MIN_MATCHES})")
    lap("matching")

    x1 = _normalize(f1.keypoints[matches[:, 0]], K1, dist1)
    x2 = _normalize(f2.keypoints[matches[:, 1]], K2, dist2)
    lap("undistort")

    ransac = _ransac_keywords(options)
    if options.ordered_sampling:
        size2 = (int(shape2[1]), int(shape2[0]))
        fit = estimate_essential_ordered(
            x1, x2, focal, scores, size2, max_log10_nfa=options.max_log10_nfa, K2=K2, **ransac
        )
    else:
        fit = estimate_essential(x1, x2, focal, **ransac)
    if fit is None or fit.num_inliers < options.min_inliers:
        found = 0 if fit is None else fit.num_inliers
        raise ValueError(
            f"no reliable two-view geometry: {found} inliers among {len(matches)} matches "
            f"(need {options.min_inliers})"
        )
    significance = _require_significance(fit.E, x1, x2, K2, shape2, options, scores)
    lap("ransac")
    return _Consensus(f1, f2, threshold_scale, matches, x1, x2, fit, significance)


def _best_consensus(f1, f2, img1, img2, K1, K2, dist1, dist2, focal, options, lap) -> _Consensus:
    """The consensus of the given features, or of features detected at
    :data:`REDETECT_THRESHOLD_SCALE` when that one is weak (``PairOptions.redetect_below``)
    and chance explains the denser one less (lower ``log10`` NFA, which counts the matches
    each was drawn from); the first failure's ValueError when neither holds."""
    camera = (K1, K2, dist1, dist2, focal, img2.shape, options, lap)
    try:
        found, failure = _consensus(f1, f2, 1.0, *camera), None
    except ValueError as exc:
        found, failure = None, exc
    weak = found is None or found.fit.num_inliers < options.redetect_below
    if options.redetect_below > 0 and weak:
        d1, d2 = f1, f2
        if not all(_thins_to(f, REDETECT_THRESHOLD_SCALE) for f in (f1, f2)):
            d1, d2, _ = _detect_both(img1, img2, options, REDETECT_THRESHOLD_SCALE)
        lap("features")
        try:
            denser = _consensus(d1, d2, REDETECT_THRESHOLD_SCALE, *camera)
        except ValueError:
            denser = None
        if denser is not None and (
            found is None or denser.significance.log10_nfa < found.significance.log10_nfa
        ):
            found = denser
    if found is None:
        raise failure
    return found


def estimate_pair(
    image1: Any,
    image2: Any,
    K1: Any,
    K2: Any = None,
    dist1: Any = None,
    dist2: Any = None,
    options: PairOptions | None = None,
    *,
    features1: Features | None = None,
    features2: Features | None = None,
    progress: Callable[[str], None] | None = None,
) -> PairResult:
    """Relative pose of two calibrated images.

    Parameters
    ----------
    image1, image2 : ndarray (H, W) / (H, W, 3) BGR, or path
        The two photos.
    K1 : array_like, shape (3, 3)
        Intrinsics of camera 1.
    K2 : array_like, shape (3, 3), optional
        Intrinsics of camera 2; defaults to ``K1``.
    dist1, dist2 : array_like, optional
        OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3, ...])``; ``dist2`` defaults to
        ``dist1`` when ``K2`` is not given.
    options : PairOptions, optional
    features1, features2 : Features, optional
        Precomputed features of the images (as :func:`~ppo_cv.features.detect_features` gives
        with the ``options``); given both, the first detection is skipped (a second one, on
        the images, follows a weak consensus: ``PairOptions.redetect_below``). SIFT features
        detected at :data:`REDETECT_THRESHOLD_SCALE` serve both: thinned to threshold 1 for
        the first consensus (:func:`ppo_cv.features.at_threshold`), as they are for the
        second. Batch runs use it to detect each image once.
    progress : callable, optional
        Called with the name of each stage as it ends (the keys of ``PairResult.timings``,
        some more than once), to show progress during long work.

    Returns
    -------
    PairResult

    Raises
    ------
    ValueError
        Unreadable or oversized image (:func:`ppo_cv.images.load_image`), NaN pixels, an image
        too small or thin to detect features on (a side below
        :data:`~ppo_cv.features.MIN_IMAGE_SIDE` pixels), images of different sizes without
        ``K2``, identical images, too few features, matches or inliers, or a consensus that
        chance could explain (``PairOptions.max_log10_nfa``): "no reliable
        two-view geometry" with the figures; one image a mirror image of the other (Notes).
    TypeError
        ``options`` that is not a :class:`PairOptions`, non-numeric images.

    Notes
    -----
    Mirrored images. No motion of a camera mirrors its image, but a reflection of one image
    (a front camera's saved selfie, ``image[:, ::-1]``) still fits an essential matrix. The
    pair is refused when the homography of its matches, with positive depths, reverses
    orientation (determinant < 0) on at least :data:`MIRROR_MIN_INLIERS` inliers: a plane or a
    rotation seen by two cameras keeps it. Measured on the 85 freiburg pairs: none of the
    pairs as they are is refused (83 poses, 2 refused as chance consensus, as before); every
    first frame against its own mirror image is refused (85 of 85, 73 to 136 inliers). Not
    caught: a mirrored image of another viewpoint whose few matches hold no such homography
    (the descriptors do not match mirrored patches): of the 85 pairs with image 2 mirrored,
    13 are refused as mirrored and 26 as chance consensus, but 46 still return a (wrong) pose;
    both images mirrored (a mirrored world is a rigid scene: the pose returned is the mirror
    image of the true one); a mirror inside the scene.
    """
    options = PairOptions() if options is None else options
    if not isinstance(options, PairOptions):
        raise TypeError(f"options must be a PairOptions, got {type(options).__name__}")
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[stage] = timings.get(stage, 0.0) + now - clock
        clock = now
        if progress is not None:
            progress(stage)

    img1, img2 = _as_image(image1, "image1"), _as_image(image2, "image2")
    if features1 is None or features2 is None:
        for image, name in ((img1, "image1"), (img2, "image2")):
            require_detectable(image.shape, name, options.max_image_size)
    K1 = as_camera_matrix(K1, "K1")
    dist1 = as_distortion(dist1, "dist1")
    if K2 is None:
        _require_same_size(img1, img2)
        K2, dist2 = K1, dist1 if dist2 is None else as_distortion(dist2, "dist2")
    else:
        K2, dist2 = as_camera_matrix(K2, "K2"), as_distortion(dist2, "dist2")
    if img1.shape == img2.shape and np.array_equal(img1, img2):
        raise ValueError("the two images are identical: they carry no relative pose")
    lap("load")

    if features1 is None or features2 is None:
        f1, f2, detected = _detect_both(img1, img2, options)
        timings["features"], clock = detected - clock, detected
        if progress is not None:
            progress("features")
        lap("pycolmap_import")
    else:
        f1, f2 = features1, features2
        for name, f in (("features1", f1), ("features2", f2)):
            if not isinstance(f, Features):
                raise TypeError(f"{name} must be ppo_cv.features.Features, got {type(f).__name__}")
            if f.kind != options.features:
                raise ValueError(
                    f"{name} are {f.kind} features but options.features is {options.features}"
                )
        lap("features")
    focal = float(np.mean([K1[0, 0], K1[1, 1], K2[0, 0], K2[1, 1]]))
    found = _best_consensus(f1, f2, img1, img2, K1, K2, dist1, dist2, focal, options, lap)
    f1, f2, matches, x1, x2 = found.features1, found.features2, found.matches, found.x1, found.x2
    fit, significance, inliers = found.fit, found.significance, found.fit.inliers
    p1 = f1.keypoints[matches[:, 0]]

    chosen = ppo.select_pose(fit.E, x1[inliers], x2[inliers])
    lap("ppo")

    R, t = chosen.R, chosen.t
    if options.refine:
        R, t, inliers = _refine(R, t, x1, x2, inliers, focal, options)
    lap("refine")

    ranked = options.ordered_sampling and np.count_nonzero(inliers) >= MIN_MATCHES
    plane_ransac = _ransac_keywords(options)
    if ranked:  # on the essential matrix's inliers a plane is the bulk of them
        bound = plane_ransac_trials(options.confidence)
        plane_ransac["max_trials"] = min(options.max_trials, bound)
    fit_on = inliers if ranked else None
    homography = estimate_homography(x1, x2, focal, **plane_ransac, fit_on=fit_on)
    _require_unmirrored(homography)
    if not options.plane:
        homography = None
    lap("homography")

    principal_prior = _principal_prior(
        options.principal_point, K1, K2, img1.shape, img2.shape, focal
    )
    given_ratio = float(np.mean(np.diag(K2)[:2]) / np.mean(np.diag(K1)[:2]))
    ratio_keywords = focal_ratio_keywords(
        focal_ratio_prior(given_ratio) if options.focal_ratio == "auto" else None
    )
    motion = decide_motion(
        x1, x2, R, t, inliers, focal,
        threshold_px=options.ransac_threshold,
        pri_threshold=float(options.pri_threshold),
        seed=options.seed,
        homography=homography,
        principal_prior=principal_prior,
        **ratio_keywords,
    )  # fmt: skip
    lap("model")

    rotation_tracks = 0
    if options.photometric and (motion.pure_rotation or motion.rotation_candidate):
        refined = refine_rotation_photometric(
            img1, img2, K1, K2, motion.R,
            focal_scale=motion.focal_scale, k1=motion.k1,
            principal_offset=motion.principal_offset, principal_prior=principal_prior,
            focal_ratio=motion.focal_ratio, **ratio_keywords,
            principal_bound=motion.principal_bound,
            max_focal_change=motion.track_focal_change,
            rotation_sigma_deg=min(motion.rotation_sigma_deg, MAX_SEARCH_SIGMA_DEG),
            dist1=dist1, dist2=dist2,
        )  # fmt: skip
        if refined is not None:
            motion = with_tracks(
                motion, refined.fit, refined.parallax, x1, x2, focal,
                threshold_px=options.ransac_threshold,
            )  # fmt: skip
            rotation_tracks = refined.num_tracks if motion.pure_rotation else 0
    lap("photometric")

    plane = motion.plane if motion.model == "plane" else None
    plane_k1, plane_normal, plane_distance = float("nan"), None, float("nan")
    radial_k1 = float("nan")
    if motion.pure_rotation:
        R, t, pri = motion.R, motion.t, motion.pri
        inliers = motion.rotation_inliers
        t_sigma = T_SIGMA_CAP_DEG
        points3d, keep = np.full((len(matches), 3), np.nan), np.zeros(len(matches), dtype=bool)
    elif plane is not None:
        inliers = motion.homography_inliers
        refined = refine_planar_pose(
            plane.R, plane.candidates.T[plane.candidate], plane.n, x1, x2, inliers,
            scale=options.ransac_threshold / focal, fit_k1=True,
        )  # fmt: skip
        R, t, plane_k1 = refined.R, refined.t, refined.k1
        plane_normal, plane_distance = refined.n, refined.distance
        c1, c2 = undistort_division(x1, plane_k1), undistort_division(x2, plane_k1)
        pri = ppo.pure_rotation_indicator(ppo.intersection_scores(c1[inliers], c2[inliers], R, t))
        points3d = ppo.analytic_points(c1, c2, R, t)
        keep = plane.inliers & np.all(np.isfinite(points3d), axis=1)
        points3d = np.where(keep[:, None], points3d, np.nan)
        t_sigma = translation_sigma_deg(R, t, c1, c2, inliers, k1_prior=K1_PRIOR)
    else:
        radial_k1 = 0.0
        if options.refine:
            bound = huber_bound_px(options.ransac_threshold, motion.noise_px)
            radial = refine_pose_radial(R, t, x1, x2, inliers, scale=bound / focal)
            R, t, radial_k1 = radial.R, radial.t, radial.k1
        c1, c2 = undistort_division(x1, radial_k1), undistort_division(x2, radial_k1)
        final = _recover_normalized(essential_from_pose(R, t), c1[:, :2], c2[:, :2], inliers, 0.0)
        R, t, pri = final.R, final.t, final.pri
        keep = final.inliers & np.all(np.isfinite(final.points3d), axis=1)
        points3d = np.where(keep[:, None], final.points3d, np.nan)
        k1_prior = K1_PRIOR if options.refine else None
        t_sigma = translation_sigma_deg(R, t, c1, c2, inliers, k1_prior=k1_prior)
    point_matches = np.flatnonzero(keep)
    lap("decision")

    return PairResult(
        R=R,
        t=t,
        pure_rotation=motion.pure_rotation,
        pri=float(pri),
        keypoints1=f1.keypoints,
        keypoints2=f2.keypoints,
        matches=matches,
        inliers=inliers,
        points3d=points3d,
        point_matches=point_matches,
        colours=_colours(img1, p1),
        K1=K1,
        K2=K2,
        image_size1=(int(img1.shape[1]), int(img1.shape[0])),
        image_size2=(int(img2.shape[1]), int(img2.shape[0])),
        pri_threshold=float(options.pri_threshold),
        model=motion.model,
        t_sigma_deg=t_sigma,
        rotation_sigma_deg=motion.rotation_sigma_deg if motion.pure_rotation else float("nan"),
        rotation_tracks=rotation_tracks,
        rotation_residual_px=motion.selection.median_residual_px["rotation"],
        general_residual_px=motion.selection.median_residual_px["general"],
        gric_difference=motion.gric_difference,
        lens_excess=motion.lens_excess if motion.lens_excess > -np.inf else float("nan"),
        noise_sigma_px=motion.noise_px,
        rotation_noise_px=motion.rotation_noise_px,
        coherent_share=motion.coherent_share,
        track_parallax=motion.track_parallax,
        track_parallax_sigma=motion.track_parallax_sigma,
        rotation_gap_deg=float(np.degrees(motion.rotation_gap)),
        focal_scale=motion.focal_scale,
        focal_ratio=motion.focal_ratio,
        principal_offset_px=motion.principal_offset * focal / motion.focal_scale,
        principal_bound=motion.principal_bound,
        timings=timings,
        threshold_scale=found.threshold_scale,
        dist1=dist1,
        dist2=dist2,
        log10_nfa=significance.log10_nfa,
        plane_residual_px=(
            float("nan")
            if motion.plane_selection is None
            else motion.plane_selection.median_residual_px["plane"]
        ),
        gric_plane_difference=motion.gric_plane_difference,
        plane_epipolar_ratio=motion.plane_epipolar_ratio,
        plane_normal=plane_normal,
        plane_distance=plane_distance,
        plane_ambiguous=bool(plane is not None and plane.ambiguous),
        plane_k1=plane_k1,
        radial_k1=radial_k1,
    )
