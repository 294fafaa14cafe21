"""Local features and their matching: SIFT (default), ORB or AKAZE, mutual nearest neighbours.

Keypoints are returned in full-resolution pixel coordinates even when detection ran on a
downscaled copy of the image. SIFT descriptors are mapped to RootSIFT (L1-normalise, square
root), under which the Euclidean distance is the Hellinger kernel distance of the histograms.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import (
    MAX_WHOLE_NUMBER,
    as_finite_array,
    as_finite_rows,
    as_flag,
    as_number,
    as_points,
    as_positive,
    as_whole_number,
    require_finite,
    require_instance,
    shown,
)
from .limits import MAX_KEYPOINTS

__all__ = [
    "FEATURE_TYPES",
    "MIN_IMAGE_SIDE",
    "MIN_FLOAT_LEVELS",
    "PIXEL_PAIR_RESOLUTION",
    "Features",
    "to_uint8",
    "to_gray",
    "require_detectable",
    "detect_features",
    "at_threshold",
    "match_features",
    "match_features_scored",
    "unique_pixel_pairs",
]

FEATURE_TYPES = ("sift", "orb", "akaze")
_FLANN_MIN_FEATURES = 12000
_MATCH_BLOCK_ROWS = 256
PIXEL_PAIR_RESOLUTION = 0.01
MIN_IMAGE_SIDE = 16
_SIFT_CONTRAST = 0.04
_SIFT_LAYERS = 3
"""Shortest image side, pixels, that detection accepts (also on the reduced copy)."""


@dataclass(frozen=True)
class Features:
    """Keypoints and descriptors of one image.

    Attributes
    ----------
    keypoints : ndarray, shape (N, 2)
        Pixel coordinates ``(u, v)`` in the full-resolution image.
    descriptors : ndarray, shape (N, D)
        float32 (SIFT, RootSIFT-normalised) or uint8 (ORB, AKAZE: binary, Hamming distance).
    kind : str
        The detector, one of ``FEATURE_TYPES``.
    responses : ndarray, shape (N,), optional
        The detector's response of each keypoint (for SIFT the contrast of its extremum).
    threshold_scale : float
        The detector threshold scale down to which they hold every keypoint of the detection:
        the one they were detected at (:func:`detect_features`), or for SIFT cut to
        ``max_features`` that of the weakest keypoint kept.
    """

    keypoints: np.ndarray
    descriptors: np.ndarray
    kind: str
    responses: np.ndarray | None = None
    threshold_scale: float = 1.0

    def __post_init__(self) -> None:
        for name in ("keypoints", "descriptors"):  # lists are taken as arrays
            if not isinstance(getattr(self, name), np.ndarray):
                object.__setattr__(self, name, _as_array(getattr(self, name), name))
        _require_features(self)

    @property
    def binary(self) -> bool:
        """Whether the descriptors compare by Hamming distance."""
        return self.descriptors.dtype == np.uint8

    def __len__(self) -> int:
        return int(self.keypoints.shape[0])


def _as_array(value: Any, name: str) -> np.ndarray:
    if value is None:
        raise TypeError(f"Features.{name} is required, got None")
    try:
        return np.asarray(value)
    except (TypeError, ValueError) as exc:  # a ragged list
        raise TypeError(f"Features.{name} must be an array: {exc}") from None


def _require_same_descriptors(features1: Features, features2: Features) -> None:
    """ValueError unless the two sets' descriptors have one length (computed alike)."""
    length1, length2 = features1.descriptors.shape[1], features2.descriptors.shape[1]
    if length1 != length2:
        raise ValueError(
            f"features1 and features2 have descriptors of {length1} and {length2} values: "
            "they were not computed alike"
        )


def _require_features(features: Features) -> None:
    """ValueError or TypeError naming the field of ``features`` that no detection gives: an
    unknown kind, keypoints that are not finite (N, 2) pixels, descriptors not one row of the
    kind's type per keypoint (float for SIFT, uint8 for ORB and AKAZE), responses not one
    finite number per keypoint, a threshold scale that is no positive number. The pipeline read
    NaN keypoints, (N, 3) rows and mismatched lengths without a word or failed on them deep
    inside (an IndexError)."""
    if features.kind not in FEATURE_TYPES:
        raise ValueError(
            f"Features.kind must be one of {', '.join(FEATURE_TYPES)}, got {shown(features.kind)}"
        )
    n = len(as_finite_rows(features.keypoints, "Features.keypoints", 2))
    descriptors = features.descriptors
    wanted = "f" if features.kind == "sift" else "u"
    if descriptors.ndim != 2 or len(descriptors) != n or descriptors.shape[1] == 0:
        raise ValueError(
            f"Features.descriptors must have one row per keypoint ({n}, D), got {descriptors.shape}"
        )
    if descriptors.dtype.kind != wanted or (wanted == "u" and descriptors.dtype != np.uint8):
        kind = "floats" if wanted == "f" else "uint8 (binary)"
        raise TypeError(
            f"Features.descriptors of {features.kind} must be {kind}, got dtype {descriptors.dtype}"
        )
    if wanted == "f":
        require_finite(descriptors, "Features.descriptors")
    if features.responses is not None and np.shape(features.responses) != (n,):
        raise ValueError(
            f"Features.responses must have one per keypoint ({n},), got "
            f"{np.shape(features.responses)}"
        )
    if features.responses is not None:
        as_finite_array(features.responses, "Features.responses")
    as_positive(features.threshold_scale, "Features.threshold_scale")


MIN_FLOAT_LEVELS = 16.0
"""Fewest grey levels a float image beyond [0, 1] spans for :func:`to_uint8` to read it as
0..255 values; one spanning fewer (a unit image that overshoots 1, as after an exposure or
gamma change: [0, 1.2] kept would be two grey levels, no features) is scaled by its range."""


def to_uint8(image: np.ndarray, name: str = "image") -> np.ndarray:
    """An image of any depth as uint8, scaled by its actual range.

    uint8 passes through and bool maps to {0, 255}. Values already within 0..255 (integers, or
    floats beyond 1 spanning at least :data:`MIN_FLOAT_LEVELS`) are kept; floats within [0, 1]
    are multiplied by 255; anything else (16-bit, 12-bit in 16, signed, floats of any other
    range, such as [0, 1.2]) maps ``[min, max]`` linearly onto ``[0, 255]``, so a 12-bit image
    keeps its contrast; a constant image beyond that range maps to 0. NaN or infinite pixels
    are a ValueError naming ``name``.
    """
    image = np.asarray(image)
    if image.dtype == np.uint8:
        return image
    if image.dtype == np.bool_:
        return image.view(np.uint8) * np.uint8(255)
    if image.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold numbers, got dtype {image.dtype}")
    low, high = (float(image.min()), float(image.max())) if image.size else (0.0, 0.0)
    if not (np.isfinite(low) and np.isfinite(high)):
        bad = int(np.count_nonzero(~np.isfinite(image)))
        if bad:
            raise ValueError(f"{name} has {bad} NaN or infinite pixel value(s)")
        beyond = int(np.count_nonzero(np.abs(image) > np.finfo(np.float64).max))
        raise ValueError(f"{name} has {beyond} pixel value(s) beyond the range of float64")
    if image.dtype.kind == "f" and low >= 0.0 and high <= 1.0:
        return np.rint(image * 255.0).astype(np.uint8)
    kept = image.dtype.kind != "f" or high - low >= MIN_FLOAT_LEVELS
    if low >= 0.0 and high <= 255.0 and kept:
        return np.rint(image).astype(np.uint8)
    if high == low:
        return np.zeros(image.shape, dtype=np.uint8)
    work = np.float64 if image.dtype.itemsize > 2 else np.float32
    shifted = np.subtract(image, low, dtype=work)
    return np.rint(shifted * work(255.0 / (high - low))).astype(np.uint8)


def to_gray(image: np.ndarray, name: str = "image") -> np.ndarray:
    """An 8-bit single-channel copy of an image of shape (H, W), (H, W, 3) BGR or (H, W, 4),
    of any depth (scaled by :func:`to_uint8`); errors name the image ``name``."""
    import cv2

    image = to_uint8(image, name)
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0]
    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        return cv2.cvtColor(image, code)
    raise ValueError(f"{name} must have shape (H, W), (H, W, 3) or (H, W, 4), got {image.shape}")


def require_detectable(shape: tuple, name: str, max_image_size: int | None = None) -> None:
    """ValueError naming ``name`` and its size when an image of ``shape`` (H, W[, C]) is too
    small or too thin to detect features on: a side below :data:`MIN_IMAGE_SIDE`, also on the
    copy whose longer side is reduced to ``max_image_size``."""
    if isinstance(shape, (str, bytes)) or not hasattr(shape, "__len__") or len(shape) < 2:
        raise TypeError(f"shape must be an image's shape (H, W[, C]), got {shown(shape)}")
    height, width = (as_whole_number(side, "shape", 0, MAX_WHOLE_NUMBER) for side in shape[:2])
    if max_image_size is not None:
        max_image_size = as_whole_number(max_image_size, "max_image_size", 1, MAX_WHOLE_NUMBER)
    shorter = min(height, width)
    if max_image_size is not None and max(height, width) > max_image_size:
        shorter = shorter * max_image_size / max(height, width)
    if shorter < MIN_IMAGE_SIDE:
        reduced = (
            f", also once its longer side is reduced to {max_image_size}: a larger "
            "max_image_size (--max-size), or 0 for the full size, keeps it"
            if max_image_size is not None and max(height, width) > max_image_size
            else ""
        )
        raise ValueError(
            f"{name} is {width}x{height} pixels: too small or too thin to detect features on "
            f"(each side needs at least {MIN_IMAGE_SIDE} pixels{reduced})"
        )


def _detector(kind: str, max_features: int, threshold_scale: float = 1.0):
    import cv2

    if kind == "sift":
        return cv2.SIFT_create(
            nfeatures=max_features,
            nOctaveLayers=_SIFT_LAYERS,
            contrastThreshold=_SIFT_CONTRAST * threshold_scale,
        )
    if kind == "orb":
        return cv2.ORB_create(
            nfeatures=max_features, fastThreshold=max(1, round(10 * threshold_scale))
        )
    if kind == "akaze":
        # OpenCV 5 moved AKAZE to the contrib module xfeatures2d.
        create = getattr(cv2, "AKAZE_create", None) or cv2.xfeatures2d.AKAZE_create
        return create(threshold=5e-4 * threshold_scale)
    _require_kind(kind)
    raise ValueError(f"no detector for feature type {shown(kind)}")


def _require_kind(kind: Any) -> None:
    """TypeError for a ``kind`` that is no text (options passed where the detector's name
    belongs), ValueError for an unknown name; the value quoted cut (:func:`shown`)."""
    if not isinstance(kind, str):
        raise TypeError(
            f"kind must be a detector name ({', '.join(FEATURE_TYPES)}), got "
            f"{type(kind).__name__} {shown(kind)}"
        )
    if kind not in FEATURE_TYPES:
        raise ValueError(
            f"unknown feature type {shown(kind)}; choose one of {', '.join(FEATURE_TYPES)}"
        )


def _root_sift(descriptors: np.ndarray) -> np.ndarray:
    l1 = np.maximum(np.abs(descriptors).sum(axis=1, keepdims=True), 1e-12)
    return np.sqrt(descriptors / l1).astype(np.float32)


def detection_size(shape: tuple, max_image_size: int | None) -> tuple[int, int] | None:
    """``(width, height)`` of the copy of an image of ``shape`` (H, W[, C]) that
    :func:`detect_features` detects on, its longer side reduced to ``max_image_size``; None
    when the image is no larger (or ``max_image_size`` is None) and is detected as it is."""
    height, width = int(shape[0]), int(shape[1])
    if max_image_size is not None:
        max_image_size = as_whole_number(max_image_size, "max_image_size", 1, MAX_WHOLE_NUMBER)
    if max_image_size is None or max(height, width) <= max_image_size:
        return None
    scale = max(height, width) / float(max_image_size)
    return round(width / scale), round(height / scale)


def detection_scale(shape: tuple, max_image_size: int | None) -> float:
    """How many full-size pixels of an image of ``shape`` (H, W[, C]) one pixel of its
    detection copy spans (:func:`detection_size`): ``max(H, W) / max_image_size``, 1.0 when
    the image is detected as it is."""
    if detection_size(shape, max_image_size) is None:
        return 1.0
    return max(int(shape[0]), int(shape[1])) / float(max_image_size)


def detect_features(
    image: np.ndarray,
    kind: str = "sift",
    max_features: int = 8000,
    max_image_size: int | None = None,
    threshold_scale: float = 1.0,
    name: str = "image",
) -> Features:
    """Detect keypoints and compute descriptors.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        8-bit grey or BGR image.
    kind : {"sift", "orb", "akaze"}
        Detector and descriptor.
    max_features : int
        Keep at most this many keypoints, the strongest first (at most
        :data:`ppo_cv.limits.MAX_KEYPOINTS`).
    max_image_size : int, optional
        Detect on a copy whose longer side is at most this many pixels; keypoints are mapped back
        to full resolution (``u_full = (u + 0.5) * s - 0.5``).
    threshold_scale : float
        Multiplies the detector's response threshold (SIFT contrast 0.04, ORB FAST 10, AKAZE
        5e-4): below 1 it keeps weaker keypoints, for images that give few.

    Returns
    -------
    Features
        SIFT keypoints cut to ``max_features`` are put back in the order of an uncut
        detection, and their ``threshold_scale`` is that of the weakest kept
        (:func:`_cut_sift`), so :func:`at_threshold` finds those of a higher threshold.
    """
    import cv2

    _require_kind(kind)
    max_features = as_whole_number(max_features, "max_features", 1, MAX_KEYPOINTS)
    if max_image_size is not None:
        max_image_size = as_whole_number(max_image_size, "max_image_size", 32, MAX_WHOLE_NUMBER)
    if not 0 < as_number(threshold_scale, "threshold_scale") < np.inf:
        raise ValueError(f"threshold_scale must be a positive number, got {shown(threshold_scale)}")
    if image is None:
        raise TypeError(f"{name} is required: an image array (H, W) or (H, W, 3), got None")
    if isinstance(image, (str, bytes, os.PathLike)):
        raise TypeError(
            f"{name} must be an image array (H, W) or (H, W, 3), got a path {shown(image)}: "
            "read it with ppo_cv.images.load_image"
        )
    gray = to_gray(image, name)
    require_detectable(gray.shape, name, max_image_size)
    size = detection_size(gray.shape, max_image_size)
    scale = detection_scale(gray.shape, max_image_size)
    if size is not None:
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_AREA)
    detector = _detector(kind, int(max_features), float(threshold_scale))
    keypoints, descriptors = detector.detectAndCompute(gray, None)
    if descriptors is None or not keypoints:
        dim = 32 if kind != "sift" else 128
        dtype = np.uint8 if kind != "sift" else np.float32
        empty = np.zeros((0, 2)), np.zeros((0, dim), dtype)
        return Features(*empty, kind, np.zeros(0, np.float32), float(threshold_scale))
    if kind == "akaze" and len(keypoints) > max_features:
        order = np.argsort([-k.response for k in keypoints])[: int(max_features)]
        keypoints = [keypoints[i] for i in order]
        descriptors = descriptors[order]
    uv = cv2.KeyPoint_convert(keypoints).astype(np.float64).reshape(-1, 2)
    responses = np.fromiter((k.response for k in keypoints), np.float32, len(keypoints))
    if scale != 1.0:
        uv = (uv + 0.5) * scale - 0.5
    if kind == "sift":
        descriptors = _root_sift(descriptors)
        if len(keypoints) >= max_features:
            return _cut_sift(keypoints, uv, descriptors, responses, threshold_scale)
    return Features(uv, descriptors, kind, responses, float(threshold_scale))


def _cut_sift(keypoints, uv, descriptors, responses, threshold_scale: float) -> Features:
    """SIFT features that ``max_features`` cut, in the order of an uncut detection and with
    the threshold scale of their weakest keypoint.

    OpenCV sorts the keypoints of a SIFT detection by ``x``, ``y``, decreasing size,
    angle, decreasing response and octave when it removes duplicates, then keeps the strongest
    ``max_features`` by a partial sort that scrambles that order; sorting them again restores
    it. The keypoints kept are all those whose response reaches the weakest one's (ties
    included), so they are those of a detection at the threshold scale of that response.
    """
    import cv2

    octaves = np.array([k.octave for k in keypoints], dtype=np.int64)
    sizes = np.array([k.size for k in keypoints], dtype=np.float32)
    angles = np.array([k.angle for k in keypoints], dtype=np.float32)
    points = cv2.KeyPoint_convert(keypoints).reshape(-1, 2)
    order = np.lexsort((-octaves, -responses, angles, -sizes, points[:, 1], points[:, 0]))
    weakest = float(responses.min()) * _SIFT_LAYERS / _SIFT_CONTRAST
    return Features(
        uv[order], descriptors[order], "sift", responses[order],
        max(float(threshold_scale), weakest),
    )  # fmt: skip


def at_threshold(features: Features, threshold_scale: float) -> Features:
    """The SIFT features a detection at ``threshold_scale`` finds, taken from ``features``
    detected at a threshold scale no higher, without detecting again.

    OpenCV's SIFT keeps an extremum whose contrast times the number of layers per octave (3)
    reaches ``0.04 threshold_scale``, and reports that contrast as the keypoint's response;
    a detection at a lower threshold finds the same keypoints with the same descriptors and
    more. Those whose response passes the higher threshold are the keypoints of a detection
    there, in the same order (on freiburg and pano_dev photos and the demo pair, every one
    of 20 detections the same keypoints and descriptors, one of them with a keypoint more: a
    second extremum that refined to the same place, which matching keeps once). A detection
    cut to its ``max_features`` holds them down to its own ``threshold_scale``, that of its
    weakest keypoint (:func:`detect_features`; on four freiburg images and two renders cut at
    1000 to 4000 keypoints, the same keypoints and descriptors as a detection at threshold 1,
    cut likewise when the cut reached them).

    Parameters
    ----------
    features : Features
        SIFT features of :func:`detect_features` at ``features.threshold_scale``.
    threshold_scale : float
        At least ``features.threshold_scale``.

    Returns
    -------
    Features

    Raises
    ------
    ValueError
        Features of another detector or without responses, or a threshold scale below theirs.
    """
    require_instance(features, Features, "features", " (ppo_cv.features.detect_features)")
    if features.kind != "sift" or features.responses is None:
        raise ValueError("only SIFT features with their responses can be thinned to a threshold")
    if not features.threshold_scale <= as_number(threshold_scale, "threshold_scale") < np.inf:
        raise ValueError(
            f"threshold_scale must be at least the features' {features.threshold_scale:g}, "
            f"got {shown(threshold_scale)}"
        )
    bound = np.float32(_SIFT_CONTRAST * threshold_scale)
    keep = features.responses * np.float32(_SIFT_LAYERS) >= bound
    return Features(
        features.keypoints[keep], features.descriptors[keep], features.kind,
        features.responses[keep], float(threshold_scale),
    )  # fmt: skip


def _knn_opencv(query: np.ndarray, train: np.ndarray, k: int, binary: bool, flann: bool):
    """Indices (Nq, k) and distances (Nq, k) of the k nearest train descriptors, by OpenCV;
    float descriptors as float32, the only float type its matchers take (float64 or float16
    ones failed in FLANN's index with an OpenCV error)."""
    import cv2

    if not binary:
        query, train = (np.ascontiguousarray(d, dtype=np.float32) for d in (query, train))

    if flann and not binary:
        matcher = cv2.FlannBasedMatcher({"algorithm": 1, "trees": 4}, {"checks": 128})
    else:
        matcher = cv2.BFMatcher(cv2.NORM_HAMMING if binary else cv2.NORM_L2)
    rows = matcher.knnMatch(query, train, k=k)
    full = np.array([len(row) == k for row in rows], dtype=bool)
    index = np.full((len(query), k), -1, dtype=np.int64)
    distance = np.full((len(query), k), np.inf)
    if full.any():  # OpenCV returns a list of DMatch lists
        found = [m for row, ok in zip(rows, full, strict=True) if ok for m in row]
        index[full] = np.array([m.trainIdx for m in found]).reshape(-1, k)
        distance[full] = np.array([m.distance for m in found]).reshape(-1, k)
    return index, distance


def _two_nearest_dense(d1: np.ndarray, d2: np.ndarray, block: int = _MATCH_BLOCK_ROWS):
    """Exact 2-NN of each row of d1 among d2, and whether each row is the nearest in d1 of its
    nearest in d2 (the first such row when several are).

    Squared Euclidean distances ``|a|^2 + |b|^2 - 2 a.b`` by blocks of ``block`` rows, each a
    matrix product into one reused buffer (``2 a`` is exact, so the product of the doubled rows
    is the doubled product). A block of 256 rows stays in the cache through the passes that
    follow the product (the sum, two row minima, the column minima), which by blocks of 2048
    rows cost 1.7 times the product itself (1989 x 2177 freiburg descriptors: 25 ms, 18 ms by
    256 rows, the same matches). The mutual test compares each row's nearest distance
    with its column's minimum, a reduction along rows; numpy's ``argmin`` down the columns of a
    row-major block is strided and cost more than the matrix product itself.

    Returns
    -------
    index12 : (N1, 2) int, dist12 : (N1, 2) float, mutual12 : (N1,) bool
    """
    n1, n2 = len(d1), len(d2)
    sq1 = np.einsum("ij,ij->i", d1, d1)
    sq2 = np.einsum("ij,ij->i", d2, d2)
    doubled1 = d1 * np.asarray(2, d1.dtype)
    train = np.ascontiguousarray(d2.T)
    dtype = np.result_type(d1, d2, np.float32)
    index12 = np.empty((n1, 2), dtype=np.int64)
    squared12 = np.empty((n1, 2), dtype=dtype)
    best21 = np.full(n2, np.inf, dtype=dtype)
    product_buffer = np.empty((min(block, n1), n2), dtype=np.result_type(d1, d2))
    dist_buffer = np.empty((min(block, n1), n2), dtype=dtype)
    for start in range(0, n1, block):
        stop = min(start + block, n1)
        product, dist = product_buffer[: stop - start], dist_buffer[: stop - start]
        np.matmul(doubled1[start:stop], train, out=product)
        np.add(sq1[start:stop, None], sq2[None, :], out=dist)
        dist -= product
        block_rows = np.arange(stop - start)
        first = np.argmin(dist, axis=1)  # two row minima: far faster than a partition
        nearest = dist[block_rows, first]
        dist[block_rows, first] = np.inf
        second = np.argmin(dist, axis=1)
        squared12[start:stop, 0] = nearest
        squared12[start:stop, 1] = dist[block_rows, second]
        dist[block_rows, first] = nearest
        index12[start:stop, 0] = first
        index12[start:stop, 1] = second
        np.minimum(best21, dist.min(axis=0), out=best21)
    achieves = squared12[:, 0] == best21[index12[:, 0]]
    rows = np.flatnonzero(achieves)
    _, first_row = np.unique(index12[rows, 0], return_index=True)
    mutual12 = np.zeros(n1, dtype=bool)
    mutual12[rows[first_row]] = True
    return index12, np.sqrt(np.maximum(squared12, 0)).astype(np.float64), mutual12


def match_features(
    features1: Features,
    features2: Features,
    ratio: float = 0.8,
    mutual: bool = True,
    flann: bool | None = None,
    unique: bool = True,
) -> np.ndarray:
    """Match descriptors by nearest neighbour with Lowe's ratio test.

    A match ``(i, j)`` is kept when ``d(i, j) < ratio * d(i, j')`` for the second nearest ``j'``
    and, with ``mutual``, when ``i`` is also the nearest neighbour of ``j`` in image 1.
    SIFT detects one location several times (one keypoint per dominant orientation), so
    several matches can join the same two pixels; with ``unique`` each pixel pair (rounded to
    ``PIXEL_PAIR_RESOLUTION``) is kept once, by its smallest descriptor distance.

    Parameters
    ----------
    features1, features2 : Features
        Features of image 1 and image 2, of the same kind.
    ratio : float
        Lowe's ratio, in (0, 1].
    mutual : bool
        Keep only mutual nearest neighbours.
    flann : bool, optional
        Approximate search with FLANN kd-trees (float descriptors only); by default used when
        both sets hold more than 12000 descriptors.
    unique : bool
        Keep one match per pixel pair.

    Returns
    -------
    ndarray of int, shape (M, 2)
        Index pairs ``(i, j)`` into ``features1.keypoints`` and ``features2.keypoints``.
    """
    return match_features_scored(features1, features2, ratio, mutual, flann, unique)[0]


def match_features_scored(
    features1: Features,
    features2: Features,
    ratio: float = 0.8,
    mutual: bool = True,
    flann: bool | None = None,
    unique: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`match_features` and the distance ratio of each match, its quality score.

    Returns
    -------
    matches : ndarray of int, shape (M, 2)
        As :func:`match_features` returns them.
    ratios : ndarray, shape (M,)
        ``d(i, j) / d(i, j')``, nearest over second-nearest descriptor distance, in [0, 1):
        the lower, the more distinctive the match and the likelier an inlier (Lowe 2004; the
        ranking PROSAC samples by, Chum and Matas 2005).
    """
    for name, given in (("features1", features1), ("features2", features2)):
        require_instance(given, Features, name, " (ppo_cv.features.detect_features)")
    if features1.kind != features2.kind:
        raise ValueError(f"cannot match {features1.kind} features with {features2.kind} features")
    if not 0 < as_number(ratio, "ratio") <= 1:
        raise ValueError(f"ratio must be in (0, 1], got {shown(ratio)}")
    mutual, unique = as_flag(mutual, "mutual"), as_flag(unique, "unique")
    flann = None if flann is None else as_flag(flann, "flann")
    _require_same_descriptors(features1, features2)
    d1, d2 = features1.descriptors, features2.descriptors
    if len(d1) < 2 or len(d2) < 2:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    binary = features1.binary
    if flann is None:
        flann = min(len(d1), len(d2)) > _FLANN_MIN_FEATURES
    if binary or flann:
        index12, dist12 = _knn_opencv(d1, d2, 2, binary, flann)
        if mutual:
            index21 = _knn_opencv(d2, d1, 1, binary, flann)[0][:, 0]
            mutual12 = index21[np.maximum(index12[:, 0], 0)] == np.arange(len(d1))
    else:
        index12, dist12, mutual12 = _two_nearest_dense(d1, d2)
    keep = (index12[:, 0] >= 0) & (dist12[:, 0] < ratio * dist12[:, 1])
    if mutual:
        keep &= mutual12
    rows = np.flatnonzero(keep)
    matches = np.stack([rows, index12[rows, 0]], axis=1).astype(np.int64)
    ratios = dist12[rows, 0] / np.maximum(dist12[rows, 1], 1e-300)
    if unique:
        kept = _unique_rows(matches, features1.keypoints, features2.keypoints, dist12[rows, 0])
        matches, ratios = matches[kept], ratios[kept]
    return matches, ratios


def unique_pixel_pairs(
    matches: np.ndarray,
    keypoints1: np.ndarray,
    keypoints2: np.ndarray,
    distances: np.ndarray,
    resolution: float | None = None,
) -> np.ndarray:
    """One match per pixel pair: the one with the smallest descriptor distance.

    Parameters
    ----------
    matches : ndarray of int, shape (M, 2)
        Index pairs into ``keypoints1`` (N1, 2) and ``keypoints2`` (N2, 2).
    distances : ndarray, shape (M,)
        Descriptor distance of each match.
    resolution : float, optional
        Pixel coordinates are compared after rounding to this step (default
        ``PIXEL_PAIR_RESOLUTION``).

    Returns
    -------
    ndarray of int, shape (U, 2)
        The kept rows of ``matches``, in their original order.
    """
    checked = _checked_pixel_pairs(matches, keypoints1, keypoints2, distances, resolution)
    return np.asarray(matches)[_unique_rows(*checked)]


def _checked_pixel_pairs(matches, keypoints1, keypoints2, distances, resolution) -> tuple:
    """:func:`unique_pixel_pairs`'s arguments checked: index pairs (M, 2) of whole numbers
    within the keypoints, image points, one finite distance per match, a step of at least
    1e-6 pixels; ValueError or TypeError naming the argument otherwise."""
    keypoints = [as_points(k, name) for k, name in ((keypoints1, "keypoints1"),
                                                    (keypoints2, "keypoints2"))]  # fmt: skip
    pairs = np.asarray(matches)
    if pairs.dtype.kind not in "iu":
        raise TypeError(f"matches must be index pairs of integers, got dtype {pairs.dtype}")
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"matches must have shape (M, 2), got {pairs.shape}")
    for column, points in enumerate(keypoints):
        indices = pairs[:, column]
        if indices.size and not (0 <= indices.min() and indices.max() < len(points)):
            raise ValueError(
                f"matches column {column} must index keypoints{column + 1} (0..{len(points) - 1})"
            )
    distances = as_finite_array(distances, "distances")
    if distances.shape != (len(pairs),):
        raise ValueError(
            f"distances must have one per match ({len(pairs)},), got {distances.shape}"
        )
    if resolution is not None and as_positive(resolution, "resolution") < 1e-6:
        raise ValueError(f"resolution must be at least 1e-6 pixels, got {shown(resolution)}")
    return pairs, *keypoints, distances, resolution


def _unique_rows(matches, keypoints1, keypoints2, distances, resolution=None) -> np.ndarray:
    """Sorted indices of the rows :func:`unique_pixel_pairs` keeps."""
    step = PIXEL_PAIR_RESOLUTION if resolution is None else float(resolution)
    if len(matches) < 2:
        return np.arange(len(matches))
    pixels = np.hstack([keypoints1[matches[:, 0]], keypoints2[matches[:, 1]]])
    keys = np.rint(pixels / step).astype(np.int64)
    by_distance = np.argsort(distances, kind="stable")
    _, first = np.unique(keys[by_distance], axis=0, return_index=True)
    return np.sort(by_distance[first])
