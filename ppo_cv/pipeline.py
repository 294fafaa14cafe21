"""From two photos to ``(R, t)``, the model (rotation, plane or general) and 3D points.

Stages (each timed in ``PairResult.timings``, seconds):

1. ``features``: SIFT (RootSIFT) keypoints, or ORB / AKAZE (:mod:`ppo_cv.features`);
   ``pycolmap_import`` is the wait for the first import of pycolmap that runs beside it.
   When the essential matrix (stage 4) finds fewer than ``PairOptions.redetect_below``
   inliers, stages 1-4 run again on features detected at a lower threshold
   (:data:`REDETECT_THRESHOLD_SCALE`) and the fit that chance explains less (lower ``log10``
   NFA, :mod:`ppo_cv.significance`) is kept; each stage's time is the sum of both runs. With
   ``PairOptions.detect_once`` SIFT is detected once at the lower threshold and thinned to the
   default one for the first consensus, and stage 1 does not run again unless
   :data:`FIRST_DETECTION_PER_MEGAPIXEL` cut the denser features. When
   ordered sampling cannot settle the first features, the denser ones are fitted first and
   the first ones' uniform fit runs only if the denser give no significant consensus.
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
    significant (:func:`ppo_cv.refine.refine_pose_radial`), or else on the same Huber cost
    without it (:func:`ppo_cv.refine.refine_pose_huber`), and its analytic points. The
    uncertainty of the direction of ``t`` comes from the Sampson cost of ``E = [t]x R`` at the
    reported pose in both moving cases.

:func:`estimate_pair` calls one function per stage (``_load_inputs``, ``_features``,
``best_consensus`` (:mod:`ppo_cv.consensus`), ``_essential_pose``, ``_homography``, ``_decide``,
``_revisit_with_tracks``), then the finisher of the chosen model (:data:`FINISHERS`), the
choice of the rotation with the smallest expected error (``_choose_rotation``,
:mod:`ppo_cv.rotation_choice`), and ``_assemble`` builds the :class:`~ppo_cv.result.PairResult`.

Given features. ``features1`` and ``features2`` (as :func:`~ppo_cv.features.detect_features`
gives with the ``options``, or a detector's own of the same kind) skip the first detection.
Features that cannot give a pair :data:`MIN_MATCHES` matches (fewer keypoints, distinct places
or distinct descriptors than that) are a ValueError naming them
(:func:`~ppo_cv.consensus.require_usable_features`), as are keypoints outside their image. A
weak consensus (``PairOptions.redetect_below``) or none is fitted again on denser features:
SIFT features detected at :data:`REDETECT_THRESHOLD_SCALE` serve both consensuses, as those
of the first detection do (thinned to threshold 1 for the first,
:func:`ppo_cv.features.at_threshold`, as they are for the second); other features have the
second detection run on the images. When its consensus is the one kept, the pose no longer
comes from the given features: ``result.evidence.significance.features`` is ``"detected"``
(``"given"`` otherwise) and a :class:`~ppo_cv.consensus.GivenFeaturesReplacedWarning` says
why; ``PairOptions(redetect_below=0)`` keeps to the given features. Batch runs use them to
detect each image once.

Errors. ``estimate_pair`` raises ValueError for an unreadable or oversized image
(:func:`ppo_cv.images.load_image`), NaN pixels, an image too small or thin to detect features
on (a side below :data:`~ppo_cv.features.MIN_IMAGE_SIDE` pixels), images of different sizes
without ``K2``, identical images, too few features, matches or inliers, a consensus that chance
could explain (``PairOptions.max_log10_nfa``: "no reliable two-view geometry" with the
figures) or a moving pose that has its inliers seen from directions too far apart for their
descriptors to have matched (:func:`~ppo_cv.significance.require_matchable_viewpoints`), a
general pose that too few of its inliers test
(:func:`~ppo_cv.significance.require_checked_consensus`), and one image a mirror image of the
other
(:func:`~ppo_cv.homography.require_unmirrored` says what is and is not caught).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property, partial
from typing import Any

import numpy as np

from . import ppo
from .calib import warn_implausible
from .camera import principal_point_is_centre, reduced_view
from .checks import (
    as_callback,
    as_camera_matrix,
    as_distortion,
)
from .consensus import (
    FIRST_DETECTION_PER_MEGAPIXEL,
    MIN_MATCHES,
    REDETECT_THRESHOLD_SCALE,
    Consensus,
    PairInputs,
    best_consensus,
    detect_both,
    ransac_keywords,
    require_usable_features,
)
from .features import (
    Features,
    detection_scale,
    require_detectable,
)
from .homography import (
    MIRROR_MIN_INLIERS,
    HomographyEstimate,
    estimate_homography,
    require_unmirrored,
)
from .images import as_image as _as_image
from .images import load_image
from .motion_model import MotionDecision, decide_motion, plane_ransac_trials, with_tracks
from .options import (
    FOCAL_RATIO_MODES,
    MAX_RANSAC_THRESHOLD,
    PRINCIPAL_POINT_MODES,
    PairOptions,
)
from .parallax import PlaneParallax
from .photometric import (
    MAX_SEARCH_SIGMA_DEG,
    PhotometricRotation,
    refine_rotation_photometric,
)
from .plane import _undistort_division, held_k1_deviation, refine_planar_pose
from .pose import _recover_normalized
from .refine import (
    K1_BIAS_REPLICATES,
    T_SIGMA_CAP_DEG,
    PoseSigmas,
    RadialPose,
    checked_inliers,
    huber_bound_px,
    pose_information,
    pose_sigmas_deg,
    refine_pose,
    refine_pose_huber,
    refine_pose_radial,
)
from .result import (
    ConsensusSignificance,
    DecisionEvidence,
    LensTerms,
    ModelComparison,
    PairCameras,
    PairResult,
    PlaneGeometry,
    PoseUncertainty,
    TrackParallax,
)
from .robust import (
    _essential_from_pose,
    _sampson_errors,
)
from .rotation import (
    K1_PRIOR,
    PRINCIPAL_PRIOR,
    focal_ratio_keywords,
    focal_ratio_prior,
)
from .rotation_choice import (
    RotationEstimate,
    choose_rotation,
    feature_parallax,
    focal_trade_deg,
    released_lens_shift_deg,
    rotation_only_estimate,
    rotation_only_fit,
    settled_before_polish,
    through_given_focal,
    tracks_could_win,
    translation_bias,
    unbiased_bias_deg,
    wanted_focal_scale,
)
from .significance import (
    DEFAULT_MAX_LOG10_NFA,
    require_checked_consensus,
    require_matchable_viewpoints,
)
from .valley import ValleyOutcome, valley_minima, valley_outcome

__all__ = [
    "PairOptions",
    "PairResult",
    "FINISHERS",
    "estimate_pair",
    "load_image",
    "MIN_MATCHES",
    "MIRROR_MIN_INLIERS",
    "REDETECT_THRESHOLD_SCALE",
    "FIRST_DETECTION_PER_MEGAPIXEL",
    "MAX_RANSAC_THRESHOLD",
    "PRINCIPAL_POINT_MODES",
    "FOCAL_RATIO_MODES",
    "DEFAULT_MAX_LOG10_NFA",
]


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


def _refine(R, t, x1, x2, inliers, focal, options: PairOptions, rounds: int = 3):
    """Refine over the inliers, re-select the inliers of the refined pose, until they settle."""
    threshold = options.ransac_threshold / focal
    for _ in range(rounds):
        R, t = refine_pose(R, t, x1, x2, inliers, focal)
        within = _sampson_errors(_essential_from_pose(R, t), x1, x2) < threshold
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


class _Stopwatch:
    """Seconds per stage, summed when a stage runs again, each reported to ``progress`` as it
    ends."""

    def __init__(self, progress: Callable[[str], None] | None) -> None:
        self.timings: dict[str, float] = {}
        self.progress = progress
        self.clock = time.perf_counter()

    def lap(self, stage: str, now: float | None = None) -> None:
        """End ``stage`` now (or at ``now``, a ``time.perf_counter()``)."""
        now = time.perf_counter() if now is None else now
        self.timings[stage] = self.timings.get(stage, 0.0) + now - self.clock
        self.clock = now
        if self.progress is not None:
            self.progress(stage)


@dataclass(frozen=True)
class _EssentialPose:
    """The PPO pose of the robust essential matrix, refined, and its inliers."""

    R: np.ndarray
    t: np.ndarray
    inliers: np.ndarray


@dataclass(frozen=True)
class _LensPriors:
    """Priors of the rotation-only fit's principal point (None: kept) and focal ratio."""

    principal: np.ndarray | None
    ratio_keywords: dict


@dataclass(frozen=True)
class _Finishing:
    """What a model's finisher starts from: the consensus, the essential matrix's pose and the
    decision."""

    inputs: PairInputs
    found: Consensus
    pose: _EssentialPose
    motion: MotionDecision
    priors: _LensPriors
    tracks: PhotometricRotation | None
    options: PairOptions
    unclipped_miss: bool = False
    """Whether the refit of ``motion`` aligned no tracks without clipping a lens fit to its box:
    with ``keep_clipped`` it would align none either (:func:`_misses_again`)."""

    @property
    def focal(self) -> float:
        return self.inputs.focal

    @cached_property
    def feature_parallax(self) -> PlaneParallax | None:
        """The plane parallax of the decision's rotation-only fit on the feature matches
        (:func:`~ppo_cv.rotation_choice.feature_parallax`), measured once for the rotation
        choice and the lens terms."""
        return feature_parallax(self.motion, self.found.x1, self.found.x2)


@dataclass(frozen=True)
class _ModelPart:
    """The part of the result a model's finisher gives: the pose, its inliers and points, its
    uncertainty and the model's own lens or plane terms; for a general pose the inliers the
    others check (``checked``, (N,) bool, :class:`~ppo_cv.refine.PoseInformation`)."""

    R: np.ndarray
    t: np.ndarray
    pri: float
    inliers: np.ndarray
    points3d: np.ndarray
    point_matches: np.ndarray
    t_sigma_deg: float
    rotation_sigma_deg: float = float("nan")
    radial_k1: float = float("nan")
    plane: PlaneGeometry | None = None
    radial: RadialPose | None = None
    checked: np.ndarray | None = None


def _load_inputs(image1, image2, K1, K2, dist1, dist2, detect: bool, options) -> PairInputs:
    """Images and cameras checked (stage ``load``); ``detect`` when features are to be found."""
    img1, img2 = _as_image(image1, "image1"), _as_image(image2, "image2")
    if detect:
        for image, name in ((img1, "image1"), (img2, "image2")):
            require_detectable(image.shape, name, options.max_image_size)
    _require_no_distortion_as_K2(K2)
    K1 = as_camera_matrix(K1, "K1")
    dist1 = as_distortion(dist1, "dist1")
    if K2 is None:
        _require_same_size(img1, img2)
        K2, dist2 = K1, dist1 if dist2 is None else as_distortion(dist2, "dist2")
    else:
        K2, dist2 = as_camera_matrix(K2, "K2"), as_distortion(dist2, "dist2")
    if img1.shape == img2.shape and np.array_equal(img1, img2):
        raise ValueError("the two images are identical: they carry no relative pose")
    warn_implausible(K1, img1.shape, "K1", stacklevel=3)
    if K2 is not K1:
        warn_implausible(K2, img2.shape, "K2", stacklevel=3)
    focal = float(np.mean([K1[0, 0], K1[1, 1], K2[0, 0], K2[1, 1]]))
    return PairInputs(img1, img2, K1, K2, dist1, dist2, focal)


def _require_no_distortion_as_K2(K2: Any) -> None:
    """ValueError when ``K2`` holds a flat 5, 8, 12 or 14 numbers: OpenCV's distortion
    coefficients, given in the place that follows ``K1`` as OpenCV's functions take them."""
    flat = (isinstance(K2, np.ndarray) and K2.ndim == 1) or (
        isinstance(K2, (list, tuple)) and all(isinstance(v, (int, float, np.number)) for v in K2)
    )
    if flat and len(K2) in (5, 8, 12, 14):
        raise ValueError(
            f"K2 must be a 3x3 matrix, got {len(K2)} numbers: distortion coefficients? "
            "estimate_pair takes image1, image2, K1, K2, dist1, dist2; pass them as dist1="
        )


def _in_detection_pixels(inputs: PairInputs, options: PairOptions) -> PairOptions:
    """``options`` with ``ransac_threshold`` in pixels of the detection copy: multiplied by
    the larger :func:`~ppo_cv.features.detection_scale` of the two images (at most
    :data:`MAX_RANSAC_THRESHOLD`), since keypoints located on a copy reduced ``s`` times carry
    ``s`` times its noise in full-size pixels; ``options`` itself for images no larger than
    ``options.max_image_size``. Every stage bounded by the threshold (the robust fits and
    their significance, ``refine``, the model decision, the Huber bounds) reads it here."""
    scale = max(
        detection_scale(image.shape, options.max_image_size) for image in (inputs.img1, inputs.img2)
    )
    if scale == 1.0:
        return options
    threshold = min(options.ransac_threshold * scale, MAX_RANSAC_THRESHOLD)
    return replace(options, ransac_threshold=threshold)


def _checked_options(options: Any) -> PairOptions:
    """``options``, the defaults for None; TypeError for anything but a :class:`PairOptions`."""
    options = PairOptions() if options is None else options
    if not isinstance(options, PairOptions):
        raise TypeError(f"options must be a PairOptions, got {type(options).__name__}")
    return options


def _check_hooks(features1: Any, features2: Any, progress: Any) -> None:
    """Given features come as a pair of :class:`Features` (one alone was ignored), and
    ``progress`` is a callable (an int failed at the first stage as 'not callable')."""
    for name, f in (("features1", features1), ("features2", features2)):
        if f is not None and not isinstance(f, Features):
            raise TypeError(f"{name} must be ppo_cv.features.Features, got {type(f).__name__}")
    if (features1 is None) != (features2 is None):
        raise ValueError("give both features1 and features2, or neither (one is not used alone)")
    as_callback(progress, "progress", "a callable taking a stage name")


def _features(
    inputs: PairInputs, features1, features2, options: PairOptions, watch: _Stopwatch
) -> tuple[Features, Features]:
    """Features of both images (stage ``features``, and ``pycolmap_import``), or the given ones
    checked against ``options``."""
    if features1 is None or features2 is None:
        f1, f2, detected = detect_both(inputs.img1, inputs.img2, options)
        watch.lap("features", detected)
        watch.lap("pycolmap_import")
        return f1, f2
    for name, f in (("features1", features1), ("features2", features2)):
        if not isinstance(f, Features):
            raise TypeError(f"{name} must be ppo_cv.features.Features, got {type(f).__name__}")
        if f.kind != options.features:
            raise ValueError(
                f"{name} are {f.kind} features but options.features is {options.features}"
            )
    require_usable_features(features1, features2)
    watch.lap("features")
    return features1, features2


def _essential_pose(
    found: Consensus, focal: float, options: PairOptions, watch: _Stopwatch
) -> _EssentialPose:
    """The PPO choice among the four poses of ``E`` (stage ``ppo``), refined over its inliers
    (stage ``refine``)."""
    inliers = found.fit.inliers
    chosen = ppo.select_pose(found.fit.E, found.x1[inliers], found.x2[inliers])
    watch.lap("ppo")
    R, t = chosen.R, chosen.t
    if options.refine:
        R, t, inliers = _refine(R, t, found.x1, found.x2, inliers, focal, options)
    watch.lap("refine")
    return _EssentialPose(R, t, inliers)


def _homography(
    found: Consensus, pose: _EssentialPose, focal: float, options: PairOptions
) -> HomographyEstimate | None:
    """The robust homography of the matches, ValueError when it mirrors the image; None when
    ``options.plane`` is off."""
    ranked = options.ordered_sampling and np.count_nonzero(pose.inliers) >= MIN_MATCHES
    plane_ransac = ransac_keywords(options)
    if ranked:  # on the essential matrix's inliers a plane is the bulk of them
        bound = plane_ransac_trials(options.confidence)
        plane_ransac["max_trials"] = min(options.max_trials, bound)
    fit_on = pose.inliers if ranked else None
    homography = estimate_homography(found.x1, found.x2, focal, **plane_ransac, fit_on=fit_on)
    require_unmirrored(homography)
    return homography if options.plane else None


def _lens_priors(inputs: PairInputs, options: PairOptions) -> _LensPriors:
    """Priors of the principal point and focal ratio the rotation-only fit may move."""
    principal = _principal_prior(
        options.principal_point, inputs.K1, inputs.K2, inputs.img1.shape, inputs.img2.shape,
        inputs.focal,
    )  # fmt: skip
    given_ratio = float(np.mean(np.diag(inputs.K2)[:2]) / np.mean(np.diag(inputs.K1)[:2]))
    ratio_keywords = focal_ratio_keywords(
        focal_ratio_prior(given_ratio) if options.focal_ratio == "auto" else None
    )
    return _LensPriors(principal, ratio_keywords)


def _decide(
    found: Consensus, pose: _EssentialPose, homography, priors: _LensPriors, focal: float,
    options: PairOptions,
) -> MotionDecision:  # fmt: skip
    """Rotation, plane or general motion on the feature matches (:func:`decide_motion`)."""
    return decide_motion(
        found.x1, found.x2, pose.R, pose.t, pose.inliers, focal,
        threshold_px=options.ransac_threshold,
        pri_threshold=float(options.pri_threshold),
        seed=options.seed,
        homography=homography,
        principal_prior=priors.principal,
        **priors.ratio_keywords,
    )  # fmt: skip


def _align_tracks(
    inputs: PairInputs, motion: MotionDecision, priors: _LensPriors, keep_clipped: bool = False,
    sigma_deg: float | None = None, on_clipped: Callable[[], None] | None = None,
    max_image_size: int | None = None,
    settled: Callable[[PhotometricRotation], bool] | None = None,
) -> PhotometricRotation | None:  # fmt: skip
    """The rotation-only fit refitted on intensity-aligned windows around ``motion.R``
    (:func:`refine_rotation_photometric`, ``on_clipped`` called for each lens fit clipped to
    its box; the searched windows returned unpolished where ``settled`` holds), None when too
    few windows align; searched over ``sigma_deg``, by default the fit's own deviation (both
    capped); on the images reduced as the features were (``PairOptions.max_image_size``,
    :func:`~ppo_cv.camera.reduced_view`)."""
    sigma_deg = motion.rotation_sigma_deg if sigma_deg is None else sigma_deg
    img1, K1 = reduced_view(inputs.img1, inputs.K1, max_image_size)
    img2, K2 = reduced_view(inputs.img2, inputs.K2, max_image_size)
    return refine_rotation_photometric(
        img1, img2, K1, K2, motion.R,
        focal_scale=motion.focal_scale, k1=motion.k1,
        principal_offset=motion.principal_offset, principal_prior=priors.principal,
        focal_ratio=motion.focal_ratio, **priors.ratio_keywords,
        principal_bound=motion.principal_bound,
        max_focal_change=motion.track_focal_change, keep_clipped=keep_clipped,
        rotation_sigma_deg=min(sigma_deg, MAX_SEARCH_SIGMA_DEG),
        dist1=inputs.dist1, dist2=inputs.dist2, on_clipped=on_clipped, settled=settled,
    )  # fmt: skip


def _revisit_with_tracks(
    inputs: PairInputs, found: Consensus, motion: MotionDecision, priors: _LensPriors,
    options: PairOptions,
) -> tuple[MotionDecision, PhotometricRotation | None, int, bool]:  # fmt: skip
    """For a pure rotation or a rotation candidate: the rotation refitted on intensity-aligned
    windows and the decision revisited on their parallax (:func:`with_tracks`); with the
    tracks (None when none were aligned), the number behind a pure rotation's ``R`` and
    whether a refit aligned none without clipping a lens fit
    (:attr:`_Finishing.unclipped_miss`)."""
    if not options.photometric or not (motion.pure_rotation or motion.rotation_candidate):
        return motion, None, 0, False
    clipped = []
    tracks = _align_tracks(
        inputs, motion, priors, on_clipped=lambda: clipped.append(True),
        max_image_size=options.max_image_size,
    )  # fmt: skip
    if tracks is None:
        return motion, None, 0, not clipped
    motion = with_tracks(
        motion, tracks.fit, tracks.parallax, found.x1, found.x2, inputs.focal,
        threshold_px=options.ransac_threshold,
    )  # fmt: skip
    return motion, tracks, tracks.num_tracks if motion.pure_rotation else 0, False


def _finish_rotation(state: _Finishing) -> _ModelPart:
    """A pure rotation: the rotation-only fit, no point, ``t`` undetermined (its sigma the cap);
    the rotation's deviation with the tracks' parallax beyond its noise
    (:func:`~ppo_cv.rotation_choice.unbiased_bias_deg`) and the rotation its focal scale may
    have bought (:func:`~ppo_cv.rotation_choice.focal_trade_deg`)."""
    motion, num_matches = state.motion, len(state.found.matches)
    bias = translation_bias(None if state.tracks is None else state.tracks.parallax)
    lens = rotation_only_fit(motion, state.tracks)
    focal = focal_trade_deg(lens, state.found.x1, state.found.x2, motion.rotation_inliers)
    deviations = [motion.rotation_sigma_deg, unbiased_bias_deg(*bias), focal]
    return _ModelPart(
        R=motion.R,
        t=motion.t,
        pri=motion.pri,
        inliers=motion.rotation_inliers,
        points3d=np.full((num_matches, 3), np.nan),
        point_matches=np.flatnonzero(np.zeros(num_matches, dtype=bool)),
        t_sigma_deg=T_SIGMA_CAP_DEG,
        rotation_sigma_deg=float(np.linalg.norm(deviations)),
    )


def _finish_plane(state: _Finishing) -> _ModelPart:
    """A plane: the PPO pose of the homography refined on it with a radial term, and the
    analytic points of its inliers."""
    plane, x1, x2 = state.motion.plane, state.found.x1, state.found.x2
    inliers = state.motion.homography_inliers
    refined = refine_planar_pose(
        plane.R, plane.candidates.T[plane.candidate], plane.n, x1, x2, inliers,
        scale=state.options.ransac_threshold / state.focal, fit_k1=True,
    )  # fmt: skip
    R, t, k1 = refined.R, refined.t, refined.k1
    c1, c2 = _undistort_division(x1, k1), _undistort_division(x2, k1)
    pri = ppo.pure_rotation_indicator(ppo.intersection_scores(c1[inliers], c2[inliers], R, t))
    points3d = ppo.analytic_points(c1, c2, R, t)
    keep = plane.inliers & np.all(np.isfinite(points3d), axis=1)
    return _ModelPart(
        R=R,
        t=t,
        pri=pri,
        inliers=inliers,
        points3d=np.where(keep[:, None], points3d, np.nan),
        point_matches=np.flatnonzero(keep),
        t_sigma_deg=pose_sigmas_deg(
            R, t, c1, c2, inliers, k1_prior=K1_PRIOR, principal_prior=state.priors.principal
        ).translation_deg,
        rotation_sigma_deg=refined.rotation_sigma_deg,
        plane=PlaneGeometry(refined.n, refined.distance, bool(plane.ambiguous), k1),
    )


def _finish_general(state: _Finishing) -> _ModelPart:
    """A general motion: the essential matrix's pose refined with a radial term when one is
    significant, otherwise on the same Huber cost without it (:func:`refine_pose_huber`), and
    the analytic points of its inliers. That cost runs over every inlier: a match that sets a
    direction of the pose by itself (:func:`checked_inliers`) is left in, for the valley
    (:func:`_valley`) to weigh the pose without it by its significance; dropped here, the pose
    moved along a valley it alone had held (``t`` 24 degrees on a tripod pan whose focal
    ratio was held, and a rotation choice on a released lens shift not yet converged)."""
    options, x1, x2 = state.options, state.found.x1, state.found.x2
    R, t, inliers, radial_k1, radial = state.pose.R, state.pose.t, state.pose.inliers, 0.0, None
    if options.refine:
        bound = huber_bound_px(options.ransac_threshold, state.motion.noise_px)
        radial = refine_pose_radial(
            R, t, x1, x2, checked_inliers(R, t, x1, x2, inliers), scale=bound / state.focal,
            principal_prior=state.priors.principal,
        )  # fmt: skip
        R, t, radial_k1 = radial.R, radial.t, radial.k1
        if radial_k1 == 0.0:
            R, t = refine_pose_huber(R, t, x1, x2, inliers, scale=bound / state.focal)
    c1, c2 = _undistort_division(x1, radial_k1), _undistort_division(x2, radial_k1)
    information = pose_information(R, t, c1, c2, inliers)
    valley = _valley(state, R, t, c1, c2, inliers, information.checked)
    final = _recover_normalized(
        _essential_from_pose(valley.R, valley.t), c1[:, :2], c2[:, :2], inliers, 0.0
    )
    if not _same_pose(final.R, final.t, R, t):
        information = pose_information(final.R, final.t, c1, c2, inliers)
    keep = final.inliers & np.all(np.isfinite(final.points3d), axis=1)

    def sigmas(spread_only: bool) -> PoseSigmas:
        return information.sigmas_deg(
            principal_prior=state.priors.principal, **_radial_priors(radial, spread_only)
        )

    pose_sigmas = sigmas(False)
    held = radial is not None and radial.k1 == 0.0 and radial.noise_bias_measured
    rotation_deg = sigmas(True).rotation_deg if held else pose_sigmas.rotation_deg
    return _ModelPart(
        R=final.R,
        t=final.t,
        pri=final.pri,
        inliers=inliers,
        points3d=np.where(keep[:, None], final.points3d, np.nan),
        point_matches=np.flatnonzero(keep),
        t_sigma_deg=pose_sigmas.translation_deg,
        rotation_sigma_deg=float(np.hypot(rotation_deg, valley.spread_deg)),
        radial_k1=radial_k1,
        radial=radial,
        checked=information.checked,
    )


def _with_points_of(state: _Finishing, part: _ModelPart, rotation: RotationEstimate) -> _ModelPart:
    """``part`` with its analytic points (eq. 36) recomputed through the returned ``rotation``
    where the rotation choice took the rotation-only fit's over the moving model's, so that the
    points, the PLY and the COLMAP model are those of the pose returned."""
    if state.motion.model == "rotation" or rotation.source != "rotation":
        return part
    R = rotation.R
    k1 = part.radial_k1 if part.plane is None else part.plane.k1
    k1 = float(k1) if np.isfinite(k1) else 0.0
    c1 = _undistort_division(state.found.x1, k1)
    c2 = _undistort_division(state.found.x2, k1)
    points3d = ppo.analytic_points(c1, c2, R, part.t)
    keep = np.zeros(len(points3d), bool)
    keep[part.point_matches] = np.all(np.isfinite(points3d[part.point_matches]), axis=1)
    return replace(
        part,
        points3d=np.where(keep[:, None], points3d, np.nan),
        point_matches=np.flatnonzero(keep),
    )


def _same_pose(R, t, R_other, t_other) -> bool:
    """Whether two poses (``t`` unit vectors) are one up to rounding (1e-9)."""
    return bool(np.allclose(R, R_other, rtol=0.0, atol=1e-9)
                and np.allclose(t, t_other, rtol=0.0, atol=1e-9))  # fmt: skip


def _valley(
    state: _Finishing, R, t, c1, c2, inliers: np.ndarray, checked: np.ndarray
) -> ValleyOutcome:  # fmt: skip
    """The refined general pose ``(R, t)`` (points ``c1``, ``c2`` undistorted by its radial
    term) checked along its bas-relief valley (:func:`~ppo_cv.valley.valley_outcome` of
    :func:`~ppo_cv.valley.valley_minima` on the ``checked`` inliers) when some of its inliers
    set a direction of the pose by themselves (:func:`checked_inliers`, which
    :class:`~ppo_cv.refine.PoseInformation` holds): the sign of an epipole placed on false
    matches. Otherwise, or without refinement, the pose with no spread."""
    if not state.options.refine or np.array_equal(checked, inliers):
        return ValleyOutcome(R, t, 0.0)
    scale = huber_bound_px(state.options.ransac_threshold, state.motion.noise_px) / state.focal
    return valley_outcome(R, t, valley_minima(R, t, c1[checked], c2[checked], scale))


def _radial_priors(radial: RadialPose | None, spread_only: bool = False) -> dict[str, float | None]:
    """How :func:`pose_sigmas_deg` counts the radial term of a general pose: none without a
    refinement; estimated under :data:`K1_PRIOR` when the refinement kept it; when it held
    ``k1`` at 0, the held value's error a considered parameter (:func:`held_k1_deviation` of
    the coefficient the refinement reached less its noise bias) beside the focal length's and
    the principal point's, or with ``spread_only`` that coefficient's deviation alone: the
    rotation's where the refinement measured the coefficient's noise bias, whose move to the
    value the matches want is then the essential matrix's bias, measured with its own deviation
    on the noise replicates (:func:`~ppo_cv.rotation_choice.released_lens_shift_deg`), and is
    not counted twice. Without those replicates the shift is one reading, and the held value
    stays in the deviation."""
    if radial is None:
        return {"k1_prior": None}
    if radial.k1 == 0.0 and np.isfinite(radial.k1_sigma):
        held = 0.0 if spread_only else radial.k1_fitted - radial.k1_noise_bias
        return {"held_k1_prior": held_k1_deviation(held, radial.k1_sigma)}
    return {"k1_prior": K1_PRIOR}


FINISHERS: dict[str, Callable[[_Finishing], _ModelPart]] = {
    "rotation": _finish_rotation,
    "plane": _finish_plane,
    "general": _finish_general,
}
"""Model name (:attr:`ppo_cv.motion_model.MotionDecision.model`) -> the function that finishes
its pose, points and uncertainty (stage ``decision``)."""


def _choose_rotation(state: _Finishing, part: _ModelPart) -> RotationEstimate:
    """The rotation with the smallest expected error (:func:`choose_rotation`): a pure
    rotation's own; otherwise the moving model's, with the deviation it reports (the given
    intrinsics' errors counted, as the rotation-only fit's lens priors count them) and its
    bias (:func:`_moving_estimate`), or the rotation-only fit's, whose bias is then measured
    on intensity-aligned tracks, searched over the fit's own deviation, when that deviation is
    below the moving model's expected error and the two rotations are near enough for the
    refit to win (:func:`~ppo_cv.rotation_choice.tracks_could_win`), and on the feature matches
    when no tracks were aligned. Where the feature matches' estimate loses, the searched
    windows are not polished when the tracks' estimate would lose however the polish read them
    (:func:`~ppo_cv.rotation_choice.settled_before_polish`)."""
    motion = state.motion
    if motion.pure_rotation:
        return RotationEstimate("rotation", part.R, 0.0, part.rotation_sigma_deg)
    x1, x2, used = state.found.x1, state.found.x2, state.pose.inliers | motion.rotation_inliers
    moving = _moving_estimate(state, part)
    to_beat = moving.expected_error_deg
    tracks = state.tracks
    parallax = state.feature_parallax if tracks is None else None
    rotation_only = rotation_only_estimate(motion, tracks, x1, x2, used, to_beat, parallax)
    if (
        tracks is None
        and state.options.photometric
        and rotation_only.fit_sigma_deg < moving.expected_error_deg
        and tracks_could_win(moving, rotation_only)
        and not _misses_again(state, rotation_only.fit_sigma_deg)
    ):
        settled = None
        if choose_rotation([moving, rotation_only]) is moving:
            settled = partial(settled_before_polish, moving, focal_free=motion.lens_clipped)
        tracks = _align_tracks(
            state.inputs, motion, state.priors, keep_clipped=True,
            sigma_deg=rotation_only.fit_sigma_deg, max_image_size=state.options.max_image_size,
            settled=settled,
        )  # fmt: skip
        if tracks is not None:  # none aligned: the estimate above stands
            rotation_only = rotation_only_estimate(motion, tracks, x1, x2, used, to_beat)
    chosen = choose_rotation([moving, rotation_only])
    if chosen is rotation_only and tracks is None:
        return through_given_focal(chosen, motion, x1, x2)
    return chosen


def _misses_again(state: _Finishing, sigma_deg: float) -> bool:
    """Whether the refit of :func:`_revisit_with_tracks` already aligned no tracks from the
    same start over the same search deviation (``sigma_deg`` against the decision's
    ``rotation_sigma_deg``, both capped; equal to within float rounding) without clipping a
    lens fit: ``keep_clipped`` changes only clipped fits
    (:func:`~ppo_cv.photometric.refine_rotation_photometric`), so the refit again would
    repeat the same searches, fits and answer."""
    searched, missed = (min(sigma, MAX_SEARCH_SIGMA_DEG)
                        for sigma in (sigma_deg, state.motion.rotation_sigma_deg))  # fmt: skip
    return state.unclipped_miss and math.isclose(searched, missed, rel_tol=1e-12)


def _moving_estimate(state: _Finishing, part: _ModelPart) -> RotationEstimate:
    """The moving model's rotation with the deviation it reports; the essential matrix's
    biased by the move of its rotation when its lens term is fitted anew
    (:func:`~ppo_cv.rotation_choice.released_lens_shift_deg`), less the move the matches'
    noise makes where the refinement measured its coefficient's noise bias (that coefficient
    passed its first test: :attr:`~ppo_cv.refine.RadialPose.noise_bias_measured`), on as many
    replicates."""
    if state.motion.model == "plane":
        return RotationEstimate("plane", part.R, 0.0, part.rotation_sigma_deg)
    bound = huber_bound_px(state.options.ransac_threshold, state.motion.noise_px) / state.focal
    k1 = part.radial_k1 if np.isfinite(part.radial_k1) else 0.0
    measured = part.radial is not None and part.radial.noise_bias_measured
    shift, shift_sigma = released_lens_shift_deg(
        part.R, part.t, k1, state.found.x1, state.found.x2, part.inliers, bound,
        replicates=K1_BIAS_REPLICATES if measured else 0,
    )  # fmt: skip
    sigma = float(np.hypot(part.rotation_sigma_deg, shift_sigma))
    return RotationEstimate("essential", part.R, shift, sigma, shift_sigma)


def _lens_terms(state: _Finishing, radial_k1: float) -> LensTerms:
    """The result's lens terms: the decision's rotation-only fit's, the radial coefficient of
    the finished pose and the focal scale the matches want (from the feature matches' parallax
    the rotation choice measured, where the fit's lens was clipped)."""
    motion, found, focal = state.motion, state.found, state.inputs.focal
    parallax = state.feature_parallax if motion.lens_clipped else None
    return LensTerms(
        focal_scale=motion.focal_scale,
        focal_ratio=motion.focal_ratio,
        principal_offset_px=motion.principal_offset * focal / motion.focal_scale,
        principal_bound=motion.principal_bound,
        lens_excess=motion.lens_excess if motion.lens_excess > -np.inf else float("nan"),
        radial_k1=radial_k1,
        wanted_focal_scale=wanted_focal_scale(motion, found.x1, found.x2, parallax),
    )


def _evidence(motion: MotionDecision, found: Consensus, options: PairOptions) -> DecisionEvidence:
    residual_px = motion.selection.median_residual_px
    plane_px = (
        float("nan")
        if motion.plane_selection is None
        else motion.plane_selection.median_residual_px["plane"]
    )
    selection = ModelComparison(
        pri_threshold=float(options.pri_threshold),
        rotation_residual_px=residual_px["rotation"],
        general_residual_px=residual_px["general"],
        plane_residual_px=plane_px,
        gric_difference=motion.gric_difference,
        gric_plane_difference=motion.gric_plane_difference,
        plane_epipolar_ratio=motion.plane_epipolar_ratio,
        noise_sigma_px=motion.noise_px,
        rotation_noise_px=motion.rotation_noise_px,
        coherent_share=motion.coherent_share,
        rotation_gap_deg=float(np.degrees(motion.rotation_gap)),
    )
    return DecisionEvidence(
        selection=selection,
        tracks=TrackParallax(motion.track_parallax, motion.track_parallax_sigma),
        significance=ConsensusSignificance(
            found.significance.log10_nfa,
            found.threshold_scale,
            options.ransac_threshold,
            found.source,
        ),
    )


def _assemble(
    state: _Finishing, part: _ModelPart, rotation: RotationEstimate, tracks: int,
    timings: dict[str, float],
) -> PairResult:  # fmt: skip
    """The :class:`PairResult` of a finished model with its chosen rotation; ValueError when a
    moving pose has its inliers seen from directions no descriptor matches across
    (:func:`~ppo_cv.significance.require_matchable_viewpoints`) or a general pose is tested by
    too few of its inliers (:func:`~ppo_cv.significance.require_checked_consensus`)."""
    inputs, found, motion = state.inputs, state.found, state.motion
    if not motion.pure_rotation:
        require_matchable_viewpoints(found.x1[part.inliers], found.x2[part.inliers], rotation.R)
    if part.checked is not None:
        require_checked_consensus(part.inliers, part.checked)
    img1, img2 = inputs.img1, inputs.img2
    cameras = PairCameras(
        inputs.K1, inputs.K2, inputs.dist1, inputs.dist2,
        (int(img1.shape[1]), int(img1.shape[0])), (int(img2.shape[1]), int(img2.shape[0])),
    )  # fmt: skip
    return PairResult(
        R=rotation.R,
        t=part.t,
        pure_rotation=motion.pure_rotation,
        model=motion.model,
        rotation_source=rotation.source,
        pri=float(part.pri),
        keypoints1=found.features1.keypoints,
        keypoints2=found.features2.keypoints,
        matches=found.matches,
        inliers=part.inliers,
        points3d=part.points3d,
        point_matches=part.point_matches,
        colours=_colours(img1, found.features1.keypoints[found.matches[:, 0]]),
        cameras=cameras,
        uncertainty=PoseUncertainty(
            part.t_sigma_deg, rotation.rms_error_deg, tracks, rotation.bias_deg
        ),
        lens=_lens_terms(state, part.radial_k1),
        evidence=_evidence(motion, found, state.options),
        plane=part.plane,
        timings=timings,
    )


def estimate_pair(
    image1: Any, image2: Any, K1: Any, K2: Any = None, dist1: Any = None, dist2: Any = None,
    options: PairOptions | None = None, *, features1: Features | None = None,
    features2: Features | None = None, progress: Callable[[str], None] | None = None,
) -> PairResult:  # fmt: skip
    """Relative pose of two calibrated images (the stages: module docstring).

    Parameters
    ----------
    image1, image2 : ndarray or path
        Shape (H, W), (H, W, 1), (H, W, 3) BGR or (H, W, 4) BGRA, any depth, or an image file.
    K1, K2 : array_like, shape (3, 3)
        Intrinsics of the cameras; ``K2`` defaults to ``K1``.
    dist1, dist2 : array_like, optional
        OpenCV distortion coefficients; ``dist2`` defaults to ``dist1`` when ``K2`` is not given.
    options : PairOptions, optional
        Its ``ransac_threshold`` applies times the reduction of an image detected downsized.
    features1, features2 : Features, optional
        Precomputed features (module docstring, "Given features"): the first detection is skipped.
    progress : callable, optional
        Called with each stage's name as it ends (the keys of ``PairResult.timings``).

    Returns
    -------
    PairResult
        ``R``, ``t``, ``pure_rotation``, ``points3d[point_matches]``; saved by ``write_outputs``.

    Raises
    ------
    ValueError
        Input that is not what it claims, or no reliable geometry (module docstring, "Errors").
    TypeError
        ``options`` that is not a :class:`PairOptions`, non-numeric images.
    """
    options = _checked_options(options)
    _check_hooks(features1, features2, progress)
    watch = _Stopwatch(progress)
    detect = features1 is None or features2 is None
    inputs = _load_inputs(image1, image2, K1, K2, dist1, dist2, detect, options)
    options = _in_detection_pixels(inputs, options)
    watch.lap("load")
    f1, f2 = _features(inputs, features1, features2, options, watch)
    found = best_consensus(f1, f2, inputs, options, watch.lap, given=not detect)
    pose = _essential_pose(found, inputs.focal, options, watch)
    homography = _homography(found, pose, inputs.focal, options)
    watch.lap("homography")
    priors = _lens_priors(inputs, options)
    motion = _decide(found, pose, homography, priors, inputs.focal, options)
    watch.lap("model")
    motion, tracks, num_tracks, missed = _revisit_with_tracks(
        inputs, found, motion, priors, options
    )
    watch.lap("photometric")
    state = _Finishing(inputs, found, pose, motion, priors, tracks, options, missed)
    part = FINISHERS[motion.model](state)
    rotation = _choose_rotation(state, part)
    part = _with_points_of(state, part, rotation)
    watch.lap("decision")
    return _assemble(state, part, rotation, num_tracks, watch.timings)
