"""The matches of a pair and the robust essential matrix over them: stages 1-4 of
:func:`ppo_cv.pipeline.estimate_pair` (detection, matching, normalisation, the robust fit and
its significance), and whether a weak consensus is worth a second detection.

A consensus of fewer than ``PairOptions.redetect_below`` inliers is fitted again on features
detected at :data:`REDETECT_THRESHOLD_SCALE` of the detector's threshold, and the fit that
chance explains less (lower ``log10`` NFA, :func:`ppo_cv.significance.require_significance`)
is kept (:func:`best_consensus`). With ``PairOptions.detect_once`` SIFT is detected once at
the lower threshold (at most :data:`FIRST_DETECTION_PER_MEGAPIXEL` keypoints) and thinned to
the default one for the first consensus (:func:`ppo_cv.features.at_threshold`); the same
features, so the same answers.
"""

from __future__ import annotations

import importlib
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from .camera import pixels_to_normalized
from .checks import require_instance
from .features import (
    PIXEL_PAIR_RESOLUTION,
    Features,
    _require_same_descriptors,
    at_threshold,
    detect_features,
    match_features_scored,
)
from .options import PairOptions
from .robust import RobustEstimate, estimate_essential, estimate_essential_ordered
from .significance import Significance, require_significance

__all__ = [
    "FIRST_DETECTION_PER_MEGAPIXEL",
    "MIN_MATCHES",
    "REDETECT_THRESHOLD_SCALE",
    "Consensus",
    "GivenFeaturesReplacedWarning",
    "PairInputs",
    "best_consensus",
    "require_features_of",
    "require_enough_features",
    "require_usable_features",
    "detect_both",
    "ransac_keywords",
]

MIN_MATCHES = 8
"""Fewest features per image, and matches between them, a pair needs."""


class GivenFeaturesReplacedWarning(UserWarning):
    """The pose of a pair given ``features1`` and ``features2`` comes from features detected
    on the images: the given ones gave no consensus, or a weak one that the denser detection
    (``PairOptions.redetect_below``) beat; ``redetect_below=0`` keeps to the given features."""


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
_PARALLEL_DETECTION_PIXELS = 3_000_000
"""Most pixels the detection copies of a pair's two images (each reduced to
``PairOptions.max_image_size``) hold together for :func:`detect_both` to detect them at once on
two threads; a larger pair is detected one image after the other. OpenCV's SIFT builds its
scale space at twice the copy's size, about 210 bytes per pixel of the copy: on a 4000x3000
pair (two 2000x1500 copies, 6 megapixels) detection peaked at 1.18 GB of resident memory on two
threads and 0.80 GB one after the other, in the same time on the loaded 2-core host (3.2-3.3 s
against 3.1-3.9 s); a 640x480 pair (0.6 megapixels) keeps its two threads."""
FIRST_DETECTION_PER_MEGAPIXEL = 13_000
"""Keypoints per megapixel of the detected image that the first SIFT detection of
``PairOptions.detect_once``, run at :data:`REDETECT_THRESHOLD_SCALE`, keeps at most (never
more than ``PairOptions.max_features``): enough for every keypoint of the default
threshold, which it is thinned to, on the images measured (freiburg 2,800-4,800 per
megapixel, pano_dev 2,700-4,500, renders of every preset 4,500-11,700), while a textured
image does not pay the descriptors of all its weak keypoints (a 640x480 render: 5,000-6,500
at the lower threshold, cut to 3,994). An image that holds more at the default threshold is
detected there again (:func:`_first_detection`)."""


def _normalize(points: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Pixels (N, 2) to homogeneous normalized coordinates (N, 3), distortion removed."""
    xy = pixels_to_normalized(points, K, dist)
    return np.column_stack([xy, np.ones(len(xy))])


def _first_detection(image: np.ndarray, options: PairOptions) -> Features:
    """The features of the first consensus. With ``options.detect_once``, SIFT detected once at
    :data:`REDETECT_THRESHOLD_SCALE`, at most :func:`_first_detection_cap` keypoints, which
    thinned to threshold 1 (:func:`ppo_cv.features.at_threshold`) are those of a detection
    there and, unless the cap cut them, serve a weak pair's second consensus without a second
    detection; detected at threshold 1 when the cap cut into those. Otherwise (also for other
    detectors, or without a second consensus) at threshold 1."""
    detect = (image, options.features, options.max_features, options.max_image_size)
    if not options.detect_once or options.features != "sift" or options.redetect_below == 0:
        return detect_features(*detect)
    cap = _first_detection_cap(image.shape, options)
    found = detect_features(image, "sift", cap, options.max_image_size, REDETECT_THRESHOLD_SCALE)
    if found.threshold_scale > 1.0 and len(found) < options.max_features:
        return detect_features(*detect)
    return found


def _first_detection_cap(shape: tuple, options: PairOptions) -> int:
    """Keypoints the first detection keeps (:data:`FIRST_DETECTION_PER_MEGAPIXEL`)."""
    megapixels = _detected_pixels(shape, options) / 1e6
    return min(options.max_features, int(np.ceil(FIRST_DETECTION_PER_MEGAPIXEL * megapixels)))


def _detected_pixels(shape: tuple, options: PairOptions) -> float:
    """Pixels of the copy of an image of ``shape`` (H, W[, C]) that detection runs on, its
    longer side reduced to ``options.max_image_size``."""
    height, width = int(shape[0]), int(shape[1])
    scale = 1.0
    if options.max_image_size is not None and max(height, width) > options.max_image_size:
        scale = options.max_image_size / max(height, width)
    return height * width * scale**2


def detect_both(
    image1, image2, options: PairOptions, threshold_scale: float | None = None
) -> tuple[Features, Features, float]:
    """Features of both images on two threads (OpenCV releases the GIL), one after the other
    when their detection copies hold more than :data:`_PARALLEL_DETECTION_PIXELS` together, and
    when both were done: at ``threshold_scale``, by default those of the first consensus
    (:func:`_first_detection`).

    The first use of pycolmap in a process pays its import; it is overlapped with detection.
    The returned ``time.perf_counter()`` of the end of detection separates the two.
    """
    from concurrent.futures import ThreadPoolExecutor

    require_instance(options, PairOptions, "options", " (ppo_cv.PairOptions(...))")

    def run(image):
        if threshold_scale is None:
            return _first_detection(image, options), time.perf_counter()
        features = detect_features(
            image, options.features, options.max_features, options.max_image_size, threshold_scale
        )
        return features, time.perf_counter()

    with ThreadPoolExecutor(max_workers=3) as pool:
        if options.backend == "pycolmap" and "pycolmap" not in sys.modules:
            pool.submit(importlib.import_module, "pycolmap")
        pixels = sum(_detected_pixels(np.shape(image), options) for image in (image1, image2))
        each = pool.map if pixels <= _PARALLEL_DETECTION_PIXELS else map
        (f1, done1), (f2, done2) = each(run, (image1, image2))
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


def ransac_keywords(options: PairOptions) -> dict:
    """The robust fits' settings in ``options``, as :func:`ppo_cv.robust.estimate_essential`
    and :func:`ppo_cv.homography.estimate_homography` take them."""
    require_instance(options, PairOptions, "options", " (ppo_cv.PairOptions(...))")
    return {
        "backend": options.backend,
        "threshold": options.ransac_threshold,
        "confidence": options.confidence,
        "min_trials": options.min_trials,
        "max_trials": options.max_trials,
        "seed": options.seed,
    }


@dataclass(frozen=True)
class Consensus:
    """The matches of two feature sets and the robust essential matrix over them.

    Attributes
    ----------
    features1, features2 : Features
        The features matched, at ``threshold_scale`` of the detector's threshold.
    threshold_scale : float
        1, or :data:`REDETECT_THRESHOLD_SCALE` for a second detection's.
    matches : ndarray of int, shape (N, 2)
        Indices of the matched keypoints in ``features1`` and ``features2``.
    x1, x2 : ndarray, shape (N, 3)
        The matched points, normalised homogeneous coordinates, distortion removed.
    fit : RobustEstimate
        The robust essential matrix and its inliers.
    significance : Significance
        Its a-contrario test over all N matches.
    source : str
        ``"detected"``: features detected on the images; ``"given"``: the ``features1`` and
        ``features2`` given to :func:`ppo_cv.pipeline.estimate_pair` (thinned or as given).
    """

    features1: Features
    features2: Features
    threshold_scale: float
    matches: np.ndarray
    x1: np.ndarray
    x2: np.ndarray
    fit: RobustEstimate
    significance: Significance
    source: str = "detected"


def _consensus(
    f1, f2, threshold_scale, K1, K2, dist1, dist2, focal, shape2, options, lap, settle=True
) -> Consensus | None:
    """Match, normalise and fit ``E`` robustly (stages 2-4) on the features at
    ``threshold_scale`` (SIFT features detected lower thinned to it); ValueError names what is
    missing. None when ordered sampling does not settle the matches and ``settle`` is False:
    the uniform fit that would settle them is left to the caller (:func:`_robust_essential`)."""
    f1, f2 = _thinned(f1, threshold_scale), _thinned(f2, threshold_scale)
    require_enough_features(f1, "image1")
    require_enough_features(f2, "image2")
    try:  # a stage that fails still ends, so that its time is not the next stage's
        matches, scores = match_features_scored(f1, f2, options.ratio, options.mutual)
        if len(matches) < MIN_MATCHES:
            raise ValueError(
                f"too few matches between the images ({len(matches)}, need {MIN_MATCHES})"
            )
    finally:
        lap("matching")

    x1 = _normalize(f1.keypoints[matches[:, 0]], K1, dist1)
    x2 = _normalize(f2.keypoints[matches[:, 1]], K2, dist2)
    lap("undistort")

    try:
        fit = _robust_essential(x1, x2, focal, scores, K2, shape2, options, settle)
        if fit is None:
            return None
        size2 = (int(shape2[1]), int(shape2[0]))
        significance = require_significance(fit.E, x1, x2, K2, size2, options.max_log10_nfa, scores)
    finally:
        lap("ransac")
    return Consensus(f1, f2, threshold_scale, matches, x1, x2, fit, significance)


def _robust_essential(
    x1, x2, focal, scores, K2, shape2, options: PairOptions, uniform_when_weak: bool = True
) -> RobustEstimate | None:
    """The robust essential matrix of the matches (stage ``ransac``); ValueError when it has
    fewer than ``options.min_inliers`` inliers. None when ordered sampling is weak and
    ``uniform_when_weak`` is False: the uniform fit it would need is left to the caller."""
    ransac = ransac_keywords(options)
    if options.ordered_sampling:
        size2 = (int(shape2[1]), int(shape2[0]))
        fit = estimate_essential_ordered(
            x1, x2, focal, scores, size2, max_log10_nfa=options.max_log10_nfa, K2=K2,
            uniform_when_weak=uniform_when_weak, **ransac,
        )  # fmt: skip
        if fit is None and not uniform_when_weak:
            return None
    else:
        fit = estimate_essential(x1, x2, focal, **ransac)
    if fit is None or fit.num_inliers < options.min_inliers:
        found = 0 if fit is None else fit.num_inliers
        raise ValueError(
            f"no reliable two-view geometry: {found} inliers among {len(x1)} matches "
            f"(need {options.min_inliers})"
        )
    return fit


def require_features_of(f1: Features, f2: Features, shape1: tuple, shape2: tuple) -> None:
    """ValueError unless the features ``f1``, ``f2`` can be those of images of ``shape1`` and
    ``shape2`` (H, W[, C]): keypoints within the images (to a pixel) and descriptors of one
    length. Given features of a resized copy, or of another detector's settings, failed their
    first consensus and were replaced by a detection on the images without a word."""
    for name, f, shape in (("features1", f1, shape1), ("features2", f2, shape2)):
        height, width = int(shape[0]), int(shape[1])
        if len(f) and not (
            f.keypoints.min() >= -1.0
            and f.keypoints[:, 0].max() <= width
            and f.keypoints[:, 1].max() <= height
        ):
            raise ValueError(
                f"{name} has keypoints outside its {width}x{height} image (up to "
                f"({f.keypoints[:, 0].max():.0f}, {f.keypoints[:, 1].max():.0f})): features "
                "of another image, or of a resized copy?"
            )
    _require_same_descriptors(f1, f2)


def require_enough_features(features: Features, image: str) -> None:
    """ValueError naming ``image`` when its detection holds fewer than :data:`MIN_MATCHES`
    features (a blank or textureless image)."""
    if len(features) < MIN_MATCHES:
        raise ValueError(
            f"{image} has too few features ({len(features)}): blank or textureless image"
        )


def require_usable_features(f1: Features, f2: Features) -> None:
    """ValueError naming ``features1`` or ``features2`` when given features cannot give a pair
    its :data:`MIN_MATCHES` matches: fewer keypoints than that, fewer distinct places (matching
    keeps one match per pixel pair, to :data:`~ppo_cv.features.PIXEL_PAIR_RESOLUTION`), or
    fewer distinct descriptors (all zeros, or one value throughout: the ratio test tells no
    keypoint from another). They were replaced by a detection on the images without a word."""
    for name, f in (("features1", f1), ("features2", f2)):
        image = "image" + name[-1]
        if len(f) < MIN_MATCHES:
            raise ValueError(
                f"{name} has too few keypoints ({len(f)}, need {MIN_MATCHES}): blank or "
                f"textureless {image}, or features of nothing?"
            )
        places = _distinct_rows(np.rint(f.keypoints / PIXEL_PAIR_RESOLUTION))
        if places < MIN_MATCHES:
            raise ValueError(
                f"{name} has its {len(f)} keypoints at {places} distinct place(s) (need "
                f"{MIN_MATCHES}): matching keeps one match per pixel pair"
            )
        distinct = _distinct_rows(f.descriptors)
        if distinct < MIN_MATCHES:
            raise ValueError(
                f"{name} has {distinct} distinct descriptor(s) among its {len(f)} (need "
                f"{MIN_MATCHES}; all zeros, or one value throughout?): the ratio test tells "
                "no keypoint from another"
            )


def _distinct_rows(rows: np.ndarray) -> int:
    """How many distinct rows ``rows`` (N, D) holds: exact below :data:`MIN_MATCHES`, a lower
    bound otherwise. Rows projected on fixed weights (square roots) give the bound without
    sorting the rows, as equal rows project alike: those of the first 64 rows, of all when
    they fall short; only a bound below :data:`MIN_MATCHES` is counted exactly."""
    weights = np.sqrt(np.arange(2.0, rows.shape[1] + 2.0))
    for sample in (rows[:64], rows):
        bound = np.unique(np.einsum("ij,j->i", sample, weights)).size  # BLAS threads: slower
        if bound >= MIN_MATCHES:
            return bound
    return len(np.unique(rows, axis=0))


def _warn_replaced(first: Consensus | None, failure: ValueError | None, options: PairOptions):
    """:class:`GivenFeaturesReplacedWarning` saying why the given features' consensus
    (``first``, or its ``failure``) gave way to features detected on the images."""
    if first is not None:
        why = (
            f"a consensus of {first.fit.num_inliers} inliers (fewer than redetect_below="
            f"{options.redetect_below}), which chance explains more than"
        )
    else:
        why = f"no consensus ({failure})" if failure else "no consensus by ordered sampling"
        why += ", unlike"
    warnings.warn(
        f"features1 and features2 gave {why} features detected on the images at threshold "
        f"scale {REDETECT_THRESHOLD_SCALE:g}; the pose comes from those "
        "(result.evidence.significance.features is 'detected'). PairOptions(redetect_below=0) "
        "keeps to the given features",
        GivenFeaturesReplacedWarning,
        stacklevel=4,
    )


def best_consensus(
    f1: Features, f2: Features, inputs: PairInputs, options: PairOptions, lap: Callable,
    given: bool = False,
) -> Consensus:  # fmt: skip
    """The consensus of the features ``f1``, ``f2`` of the images of ``inputs``, or of features
    detected at :data:`REDETECT_THRESHOLD_SCALE` when that one is weak
    (``PairOptions.redetect_below``) and chance explains the denser one less (lower ``log10``
    NFA, which counts the matches each was drawn from); when neither holds, a ValueError
    giving why each was refused (one line). ``lap`` is called with each stage's name as it
    ends (``features`` for a second detection, ``matching``, ``undistort``, ``ransac``).

    The denser features are ``f1`` and ``f2`` themselves when they hold those of
    :data:`REDETECT_THRESHOLD_SCALE` (:func:`_first_detection`), else detected on the images.
    One uniform fit settles a weak pair: when ordered sampling cannot settle the given
    features, the denser ones are fitted first (they hold the given ones: thinned to threshold
    1 they are the given set), and the given features are fitted uniformly only when the
    denser ones give no significant consensus.

    ``given``: ``f1`` and ``f2`` are the caller's (``Consensus.source`` ``"given"``); a
    consensus of features detected on the images replacing theirs is ``"detected"``, with a
    :class:`GivenFeaturesReplacedWarning`."""
    require_instance(inputs, PairInputs, "inputs")
    require_instance(options, PairOptions, "options", " (ppo_cv.PairOptions(...))")
    if not callable(lap):
        raise TypeError(f"lap must be a callable taking a stage name, got {type(lap).__name__}")
    img1, img2 = inputs.img1, inputs.img2
    require_features_of(f1, f2, img1.shape, img2.shape)
    camera = (
        inputs.K1, inputs.K2, inputs.dist1, inputs.dist2, inputs.focal, img2.shape, options, lap
    )  # fmt: skip

    def attempt(features1, features2, scale, settle=True):
        try:
            return _consensus(features1, features2, scale, *camera, settle), None
        except ValueError as exc:
            return None, exc

    redetect = options.redetect_below > 0
    found, failure = attempt(f1, f2, 1.0, settle=not redetect)
    unsettled = found is None and failure is None
    refused, source = None, "given" if given else "detected"
    if redetect and (found is None or found.fit.num_inliers < options.redetect_below):
        d1, d2 = f1, f2
        fresh = not all(_thins_to(f, REDETECT_THRESHOLD_SCALE) for f in (f1, f2))
        if fresh:
            d1, d2, _ = detect_both(img1, img2, options, REDETECT_THRESHOLD_SCALE)
        lap("features")
        denser, refused = attempt(d1, d2, REDETECT_THRESHOLD_SCALE)
        if unsettled and denser is None:
            found, failure = attempt(f1, f2, 1.0)
        if denser is not None and (
            found is None or denser.significance.log10_nfa < found.significance.log10_nfa
        ):
            if given and fresh:
                _warn_replaced(found, failure, options)
                source = "detected"
            found = denser
    if found is None:
        raise failure if refused is None else _both_refused(failure, refused)
    return replace(found, source=source)


def _both_refused(first: ValueError, denser: ValueError) -> ValueError:
    """One ValueError, on one line, giving why the consensus of the given features (``first``)
    and that of the denser ones (``denser``) were refused; ``first`` when the two say the same."""
    if str(denser) == str(first):
        return first
    prefix, reason = "no reliable two-view geometry: ", str(denser)
    if str(first).startswith(prefix) and reason.startswith(prefix):
        reason = reason[len(prefix):]
    scale = f"{REDETECT_THRESHOLD_SCALE:g}"
    return ValueError(f"{first}; with denser features (threshold scale {scale}): {reason}")


@dataclass(frozen=True)
class PairInputs:
    """The two images (H, W) or (H, W, 3) BGR and their cameras, checked: intrinsics ``K1``,
    ``K2`` (3, 3), OpenCV distortion coefficients or None, and ``focal``, the mean of the four
    focal lengths (pixels), which converts pixel thresholds to normalised units."""

    img1: np.ndarray
    img2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    dist1: np.ndarray | None
    dist2: np.ndarray | None
    focal: float
