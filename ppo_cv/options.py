"""Settings of :func:`ppo_cv.pipeline.estimate_pair`: :class:`PairOptions`, checked when made."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

from .checks import (
    MAX_WHOLE_NUMBER,
    as_confidence,
    as_flag,
    as_number,
    as_pri_threshold,
    as_whole_number,
    shown,
)
from .features import FEATURE_TYPES
from .limits import MAX_KEYPOINTS
from .ppo import DEFAULT_PRI_THRESHOLD
from .robust import ROBUST_BACKENDS
from .significance import DEFAULT_MAX_LOG10_NFA

__all__ = [
    "FOCAL_RATIO_MODES",
    "MAX_RANSAC_THRESHOLD",
    "PRINCIPAL_POINT_MODES",
    "PairOptions",
]

MAX_RANSAC_THRESHOLD = 100.0
"""Largest ``PairOptions.ransac_threshold`` accepted, pixels: a bound on nonsense input."""
PRINCIPAL_POINT_MODES = ("auto", "fit", "given")
"""Choices of ``PairOptions.principal_point``."""
FOCAL_RATIO_MODES = ("auto", "given")
"""Choices of ``PairOptions.focal_ratio``."""


@dataclass(frozen=True)
class PairOptions:
    """Settings of :func:`ppo_cv.pipeline.estimate_pair`.

    Attributes
    ----------
    features : {"sift", "orb", "akaze"}
        Detector and descriptor.
    max_features : int
        Keypoints kept per image, strongest first (8 to :data:`ppo_cv.limits.MAX_KEYPOINTS`).
    max_image_size : int or None
        Detect on a copy whose longer side is at most this (pixels), and align the
        photometric refit's windows on such copies; None keeps full size, at a cost growing
        with the pixel count (a 6000x4000 pair: 5-8 s and 0.9 GB with the default, reported at
        41 s and 11.3 GB with None).
    ratio : float
        Lowe's ratio test bound.
    mutual : bool
        Keep only mutual nearest neighbours.
    backend : {"pycolmap", "opencv"}
        Robust estimator of ``E``: COLMAP LO-RANSAC or OpenCV USAC MAGSAC++.
    ransac_threshold : float
        Inlier threshold on the epipolar error, pixels of the full-size image. An image
        larger than ``max_image_size`` has its keypoints located on a copy reduced ``s``
        times (:func:`ppo_cv.features.detection_scale`), so they carry ``s`` times the copy's
        noise: its pair is fitted at ``s`` times this threshold (the larger ``s`` of the two
        images, at most :data:`MAX_RANSAC_THRESHOLD`), and the refinement, the model decision
        and the Huber bounds read that threshold too (``docs/limits.md``).
    confidence : float
        RANSAC confidence.
    min_trials, max_trials : int
        Bounds on the number of RANSAC hypotheses.
    redetect_below : int
        When the essential matrix has fewer inliers than this (or none could be fitted), detect
        again with the detector threshold scaled by :data:`REDETECT_THRESHOLD_SCALE` and keep
        the fit whose consensus has the lower ``log10`` NFA; 0 never does. Given ``features1``
        and ``features2``, SIFT features detected at that lower threshold serve the second
        consensus themselves; other features have the second detection run on the images, and
        a pose from it is marked ``result.evidence.significance.features == "detected"``, with
        a :class:`ppo_cv.consensus.GivenFeaturesReplacedWarning`.
    detect_once : bool
        Detect SIFT once, at :data:`REDETECT_THRESHOLD_SCALE` (at most
        :data:`FIRST_DETECTION_PER_MEGAPIXEL` keypoints), thinned to the default threshold for
        the first consensus, so that a weak pair's second consensus needs no second detection
        (:func:`ppo_cv.consensus.best_consensus`); the same features, so the same answers. It
        costs a pair that is not weak the descriptors of its weaker keypoints: on the 85
        freiburg pairs (47 weak) the detection's CPU time summed 25 % lower (a weak pair's
        median 398 -> 226 ms, a strong one's 172 -> 230 ms), on 20 renders (none weak) 30 %
        higher, on the
        pano_dev tripod pair of ``benchmarks/cli_time.py`` the whole pair 43 % longer
        (``docs/performance.md``). False detects at the default threshold and again only for
        a weak pair.
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
        Fewer inliers than this is an error, not a pose; at most ``max_features`` (a pair
        has no more matches than keypoints).
    seed : int
        RANSAC seed.
    max_log10_nfa : float
        Significance bar: the robust fit is a pose only when ``log10`` of its number of false
        alarms (:mod:`ppo_cv.significance`) is at most this; lower is stricter, ``inf`` turns
        the test off (``-inf``, which no consensus is below, is refused).
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
    detect_once: bool = False
    refine: bool = True
    pri_threshold: float = DEFAULT_PRI_THRESHOLD
    min_inliers: int = 8
    seed: int = 0
    max_log10_nfa: float = DEFAULT_MAX_LOG10_NFA
    plane: bool = True
    photometric: bool = True
    principal_point: str = "auto"
    focal_ratio: str = "auto"

    def __post_init__(self) -> None:
        put = functools.partial(object.__setattr__, self)  # held as float, bool and int
        for name in ("ratio", "ransac_threshold", "confidence", "pri_threshold", "max_log10_nfa"):
            put(name, as_number(getattr(self, name), name))
        for name in ("mutual", "detect_once", "ordered_sampling", "refine", "plane", "photometric"):
            put(name, as_flag(getattr(self, name), name))
        for name, low in (("max_features", 8), ("min_trials", 1), ("max_trials", 1),
                          ("redetect_below", 0), ("min_inliers", 5), ("seed", 0)):  # fmt: skip
            high = MAX_KEYPOINTS if name == "max_features" else MAX_WHOLE_NUMBER
            put(name, as_whole_number(getattr(self, name), name, low, high))
        size = self.max_image_size
        if size is not None:
            try:
                size = as_whole_number(size, "max_image_size", 32, MAX_WHOLE_NUMBER)
            except ValueError as exc:  # the command line's --max-size 0 is None here
                raise ValueError(f"{exc} (None: full size)") from None
            put("max_image_size", size)
        for name, modes in (
            ("principal_point", PRINCIPAL_POINT_MODES),
            ("focal_ratio", FOCAL_RATIO_MODES),
        ):
            if getattr(self, name) not in modes:
                raise ValueError(
                    f"unknown {name} {shown(getattr(self, name))}; choose one of "
                    f"{', '.join(modes)}"
                )
        if self.features not in FEATURE_TYPES:
            raise ValueError(
                f"unknown features {shown(self.features)}; choose one of "
                f"{', '.join(FEATURE_TYPES)}"
            )
        if self.backend not in ROBUST_BACKENDS:
            raise ValueError(
                f"unknown backend {shown(self.backend)}; choose one of "
                f"{', '.join(ROBUST_BACKENDS)}"
            )
        if not 0 < self.ratio <= 1:
            raise ValueError(f"ratio must be in (0, 1], got {self.ratio}")
        if not 0 < self.ransac_threshold <= MAX_RANSAC_THRESHOLD:
            raise ValueError(
                f"ransac_threshold must be in (0, {MAX_RANSAC_THRESHOLD:g}] pixels, "
                f"got {self.ransac_threshold}"
            )
        as_pri_threshold(self.pri_threshold)
        if self.max_log10_nfa != self.max_log10_nfa:
            raise ValueError("max_log10_nfa must be a number (inf disables the test), got nan")
        if self.max_log10_nfa == -math.inf:
            raise ValueError(
                "max_log10_nfa is -inf: no consensus is below it, so every pair would be refused "
                "(inf disables the test)"
            )
        if not 0 < self.confidence < 1:
            raise ValueError(f"confidence must be in (0, 1), got {self.confidence}")
        as_confidence(self.confidence, "confidence")
        if (
            self.max_features < 8
            or not 1 <= self.min_trials <= self.max_trials
            or self.min_inliers < 5
        ):
            raise ValueError(
                "need max_features >= 8, 1 <= min_trials <= max_trials and min_inliers >= 5"
            )
        if self.min_inliers > self.max_features:
            raise ValueError(
                f"min_inliers ({self.min_inliers}) exceeds max_features ({self.max_features}): "
                "a pair has at most max_features matches, so every pair would be refused"
            )
        if self.redetect_below < 0:
            raise ValueError(f"redetect_below must be >= 0, got {self.redetect_below}")
        if self.max_image_size is not None and self.max_image_size < 32:
            raise ValueError(f"max_image_size must be >= 32, got {self.max_image_size}")
