"""Input checks at the public boundary: each failure names the argument and the problem."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "MIN_POINTS",
    "as_points",
    "as_finite_rows",
    "as_finite_array",
    "as_matched_rows",
    "as_image_rows",
    "as_matrix3",
    "as_real_array",
    "as_point_pair",
    "as_homogeneous_pair",
    "as_camera_matrix",
    "as_distortion",
    "as_rotation",
    "as_essential",
    "require_essential_spread",
    "as_mask",
    "as_positive",
    "as_positive_at_most",
    "as_ransac_settings",
    "as_confidence",
    "as_vector3",
    "in_float_range",
    "float_range_exponent",
    "require_pose_matches",
    "MAX_RAY_SLOPE",
    "as_deviation",
    "as_deviation_pair",
    "as_nonnegative",
    "as_pri_threshold",
    "as_number",
    "as_whole_number",
    "as_image_size",
    "as_flag",
    "as_path",
    "require_instance",
    "as_callback",
    "require_finite",
    "shown",
    "cut",
    "MAX_COORDINATE",
    "MIN_FOCAL",
    "MAX_FOCAL",
    "MAX_WHOLE_NUMBER",
    "ESSENTIAL_SPREAD",
]

MIN_POINTS = 5
MAX_COORDINATE = 1e8
"""Largest accepted point coordinate or principal point, pixels: beyond it products overflow."""
MIN_FOCAL, MAX_FOCAL = 1e-6, 1e8
"""Accepted focal lengths, pixels (1 for a camera of normalized coordinates)."""
MAX_WHOLE_NUMBER = 2**31 - 1
"""Largest whole-number option (a seed, a count): OpenCV and pycolmap take them as 32-bit
signed integers."""
ESSENTIAL_SPREAD = 10.0
"""An essential matrix has two equal singular values and a zero one. ``E`` is refused when its
largest singular value exceeds the middle one by more than this factor (a fundamental matrix in
pixels: about 190 for a 500 px focal length; a rank-1 matrix) or its smallest one exceeds the
middle one over this factor (rank 3, as the identity). A linear eight-point ``E`` of noisy points,
never projected onto the essential matrices, stays within 1.13 and 0.004 (5 px of noise)."""
MAX_RADIAL, MAX_RADIAL_RATIONAL, MAX_TANGENTIAL, MAX_PRISM, MAX_TILT = 10.0, 100.0, 1.0, 1.0, 1.0


def shown(value: Any, width: int = 40) -> str:
    """``value`` as an error message quotes it: a number as printed, anything else as its
    ``repr``, cut to ``width`` characters (``...`` marks the cut); an integer too long to print
    whole (Python prints at most 4300 digits) as ``<N-digit integer>``."""
    if isinstance(value, (int, np.integer)) and int(value).bit_length() > 4 * width:
        size = abs(int(value))
        digits = int(math.log10(size)) + 1
        digits -= size < 10 ** (digits - 1)  # log10 rounds up just below a power of ten
        return f"<{'negative ' if value < 0 else ''}{digits}-digit integer>"
    try:
        text = str(value) if isinstance(value, (int, float, np.number)) else repr(value)
    except Exception:  # a broken __repr__ must not replace the message it belongs to
        text = f"<{type(value).__name__}>"
    return cut(text, width)


def cut(text: str, width: int = 40) -> str:
    """``text`` cut to ``width`` characters, ``...`` marking the cut."""
    return text if len(text) <= width else text[: width - 3] + "..."


_PARSE_INTRINSICS = "parse a text with ppo_cv.parse_intrinsics"
_PARSE_DISTORTION = "parse a text with ppo_cv.calib.parse_distortion"


def _as_array(value: Any, name: str) -> np.ndarray:
    """``np.asarray(value)``; TypeError naming ``name`` for what numpy cannot make one array
    of (a ragged list)."""
    try:
        return np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a numeric array: {exc}") from None


def _as_real_array(value: Any, name: str, text_hint: str = "") -> np.ndarray:
    if value is None:
        raise TypeError(f"{name} is required, got None")
    array = _as_array(value, name)
    if array.dtype == np.float64:
        return array
    if array.dtype.kind not in "iuf":
        if array.dtype == object:
            _require_float_range(array, name)
        raise TypeError(_not_numbers(value, array, name, text_hint))
    return array.astype(np.float64)


def _require_float_range(array: np.ndarray, name: str) -> None:
    """ValueError naming ``name`` when an object array holds an integer beyond the range of a
    float (10**400), which numpy keeps as a Python object."""
    try:
        array.astype(np.float64)
    except OverflowError:
        raise ValueError(f"{name} holds a number beyond the range of a float") from None
    except (TypeError, ValueError):
        pass


def _not_numbers(value: Any, array: np.ndarray, name: str, text_hint: str = "") -> str:
    """The message for an argument that holds no real numbers: its dtype, or for a single
    object (a text, a record) its type and how to pass what it stands for (``text_hint`` for a
    text: how to parse it, for the arguments a text can describe); for a list or tuple holding
    a camera record (what ``camera_from_exif`` and ``load_calibration`` return) how to pass
    it."""
    held = value if isinstance(value, (list, tuple)) else ()
    camera = next((v for v in held if hasattr(v, "K") and hasattr(v, "dist")), None)
    if camera is not None:
        return (
            f"{name} must be an array of real numbers, got a {type(value).__name__} holding a "
            f"{type(camera).__name__} (as camera_from_exif and load_calibration return them): "
            "pass the camera's .K (and its .dist as the distortion)"
        )
    if array.ndim or isinstance(value, np.ndarray):
        return f"{name} must hold real numbers, got dtype {array.dtype}"
    hint = (
        f": {text_hint}"
        if isinstance(value, str) and text_hint
        else ": pass its .K (and its .dist as the distortion)"
        if hasattr(value, "K")
        else ""
    )
    return f"{name} must be an array of real numbers, got {type(value).__name__}{hint}"


def require_finite(array: np.ndarray, name: str) -> None:
    """ValueError counting the NaN or infinite entries of ``array``, named ``name``."""
    with np.errstate(over="ignore", invalid="ignore"):  # finite entries may overflow the sum
        if math.isfinite(array.sum()):
            return
    bad = ~np.isfinite(array)  # the sum can also overflow with finite entries
    if bad.any():
        raise ValueError(f"{name} has {int(bad.sum())} NaN or infinite value(s)")


def _require_coordinates(array: np.ndarray, name: str) -> None:
    """Finite entries of magnitude at most :data:`MAX_COORDINATE`."""
    if array.size and -MAX_COORDINATE <= array.min() and array.max() <= MAX_COORDINATE:
        return
    require_finite(array, name)
    if array.size:
        largest = float(np.abs(array).max())
        raise ValueError(
            f"{name} has coordinates up to {largest:.3g} px, beyond {MAX_COORDINATE:.0e}: "
            "not image points"
        )


def _point_rows(value: Any, name: str) -> np.ndarray:
    """(N, 2) float64 view or copy of OpenCV-shaped points, not yet checked for finiteness."""
    array = _as_real_array(value, name)
    shape = array.shape
    if array.ndim == 3 and shape[2] == 2 and (shape[1] == 1 or shape[0] == 1):
        return array.reshape(-1, 2)
    if array.ndim == 3 and shape[1:] == (2, 1):  # column vectors, as OpenCV also reads them
        return array.reshape(-1, 2)
    if not (array.ndim == 2 and shape[1] == 2):
        raise ValueError(
            f"{name} must have shape (N, 2), (N, 1, 2), (1, N, 2) or (N, 2, 1), got {shape}"
        )
    return array


def as_finite_rows(value: Any, name: str, width: int | tuple[int, ...]) -> np.ndarray:
    """Real numbers as float64 (N, ``width``), all finite, ``width`` one of a tuple of widths
    if given one; ValueError or TypeError naming ``name`` otherwise."""
    array = _as_real_array(value, name)
    widths = width if isinstance(width, tuple) else (width,)
    if array.ndim != 2 or array.shape[1] not in widths:
        shapes = " or ".join(f"(N, {side})" for side in widths)
        raise ValueError(f"{name} must have shape {shapes}, got {array.shape}")
    require_finite(array, name)
    return array


def as_vector3(value: Any, name: str) -> np.ndarray:
    """Three finite numbers (a row, a column or a flat triple) as float64 (3,); ValueError or
    TypeError naming ``name`` otherwise."""
    if value is None:
        raise TypeError(f"{name} is required, got None")
    if np.size(value) != 3:
        raise ValueError(f"{name} must be 3 numbers, got shape {np.shape(value)}")
    return as_finite_rows(np.reshape(value, (1, 3)), name, 3)[0]


def in_float_range(array: np.ndarray) -> np.ndarray:
    """``array`` divided by a power of two, exactly, when its largest magnitude lies beyond
    ``[1e-100, 1e100]``, where its squares and norms would overflow or underflow; unchanged
    otherwise (all zeros too). For quantities whose scale does not matter (a direction, a
    homography, a normal)."""
    shift = float_range_exponent(array)
    return np.ldexp(array, -shift) if shift else array


def float_range_exponent(array: np.ndarray) -> int:
    """The power of two :func:`in_float_range` divides ``array`` by: that of its largest
    magnitude beyond ``[1e-100, 1e100]``, else 0."""
    largest = float(np.abs(array).max(initial=0.0))
    return math.frexp(largest)[1] if largest and not 1e-100 <= largest <= 1e100 else 0


def require_pose_matches(
    R: Any, t: Any, x1: Any, x2: Any, inliers: Any = None, *, moving: bool = True,
    bearings: bool = False, max_slope: float = math.inf,
) -> np.ndarray:
    """ValueError or TypeError naming the argument unless ``R`` is a rotation, ``t`` three
    finite numbers (not all zero when ``moving``), ``x1`` and ``x2`` finite (N, 3) rows of one
    length and ``inliers`` (when given) a bool mask of N. Unless ``bearings``, the rows are
    homogeneous image points: ``w`` nonzero and ``|(x, y)| <= max_slope |w|``. The pose
    functions of :mod:`ppo_cv.refine` and :mod:`ppo_cv.valley` failed on NaN in numpy's SVD
    (LinAlgError), read a mask of indices as one of flags, answered NaN for a zero ``t`` (the
    translation's direction is their unknown) and divided by a zero ``w``; pycolmap's
    refinement stopped the process for rays all beyond :data:`MAX_RAY_SLOPE`.

    Returns
    -------
    ndarray, shape (3,)
        ``t`` as float64, divided by a power of two (exactly) when its largest entry is
        beyond ``[1e-100, 1e100]``: its norm would under- or overflow, and any scale of ``t``
        is the same direction. Otherwise ``t`` unchanged.
    """
    as_rotation(R, "R")
    translation = as_vector3(t, "t")
    if moving and not translation.any():
        raise ValueError("t is zero: these need a translation (a pure rotation has none)")
    translation = in_float_range(translation)
    a, b = as_finite_rows(x1, "x1", 3), as_finite_rows(x2, "x2", 3)
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"x1 and x2 must have the same length, got {a.shape[0]} and {b.shape[0]}")
    if not bearings:
        _require_rays(a, "x1", max_slope)
        _require_rays(b, "x2", max_slope)
    if inliers is not None:
        mask = np.asarray(inliers)
        if mask.dtype != bool:
            raise TypeError(f"inliers must be a mask of bool, got dtype {mask.dtype}")
        if mask.shape != (a.shape[0],):
            raise ValueError(
                f"inliers must have one flag per match ({a.shape[0]}), got {mask.shape}"
            )
    return translation


MAX_RAY_SLOPE = 1e6
"""Largest normalised coordinate ``|(x, y) / w|`` of an image point, the tangent of its angle
from the optical axis: 1e6 is a ray a microradian from the image plane. pycolmap's relative-pose
refinement stops the process (a failed check in Ceres) where all rays lie beyond about 1e7."""


def _require_rays(rows: np.ndarray, name: str, max_slope: float) -> None:
    """ValueError naming ``name`` unless every homogeneous row (N, 3) has ``w`` nonzero and
    ``|(x, y)| <= max_slope |w|``."""
    w = np.abs(rows[:, 2])
    bad = w == 0
    if math.isfinite(max_slope):
        bad |= np.abs(rows[:, :2]).max(axis=1, initial=0.0) > max_slope * w
    if bad.any():
        beyond = f" or |(x, y)| beyond {max_slope:.0e} |w|" if math.isfinite(max_slope) else ""
        raise ValueError(
            f"{name} has {int(bad.sum())} row(s) with w = 0{beyond} (a point at or near "
            f"infinity), e.g. {rows[np.flatnonzero(bad)[0]].tolist()}: not normalised image "
            "points"
        )


def as_real_array(value: Any, name: str) -> np.ndarray:
    """Real numbers of any shape as float64, NaN and infinities kept (a residual may be
    infinite); TypeError naming ``name`` for None, text, complex or bool values."""
    return _as_real_array(value, name)


def as_finite_array(value: Any, name: str) -> np.ndarray:
    """Real numbers of any shape as float64, all finite; ValueError or TypeError naming
    ``name`` otherwise."""
    array = _as_real_array(value, name)
    require_finite(array, name)
    return array


def as_matched_rows(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Two arrays of matched rows as finite float64 (N, 3) of one N; ValueError or TypeError
    naming ``x1`` or ``x2`` otherwise."""
    x1, x2 = as_finite_rows(x1, "x1", 3), as_finite_rows(x2, "x2", 3)
    if len(x1) != len(x2):
        raise ValueError(f"x1 and x2 must have the same length, got {len(x1)} and {len(x2)}")
    return x1, x2


def as_image_rows(x1: Any, x2: Any) -> tuple[np.ndarray, np.ndarray]:
    """Two arrays of matched homogeneous image points as finite float64 (N, 3) of one N, each
    row divided by its ``w`` (rows of ``w = 1`` kept as they are); ValueError or TypeError
    naming ``x1`` or ``x2`` otherwise, or for a row with ``w = 0`` or ``|(x, y)|`` beyond
    :data:`MAX_RAY_SLOPE` ``|w|``. The robust fits read ``x[:, :2]`` as the image point, which
    is a wrong point for a row of another ``w`` (a bearing vector: no error, a wrong pose)."""
    x1, x2 = as_matched_rows(x1, x2)
    return _on_image_plane(x1, "x1"), _on_image_plane(x2, "x2")


def _on_image_plane(rows: np.ndarray, name: str) -> np.ndarray:
    _require_rays(rows, name, MAX_RAY_SLOPE)
    w = rows[:, 2]
    return rows if (w == 1.0).all() else rows / w[:, None]


def as_matrix3(value: Any, name: str) -> np.ndarray:
    """Real numbers of shape (3, 3) as float64, all finite; ValueError or TypeError naming
    ``name`` otherwise."""
    matrix = as_finite_array(value, name)
    if matrix.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 matrix, got shape {matrix.shape}")
    return matrix


def as_points(value: Any, name: str) -> np.ndarray:
    """Image points as float64 (N, 2), from (N, 2), (N, 1, 2), (1, N, 2) or (N, 2, 1), OpenCV's
    shapes."""
    array = _point_rows(value, name)
    _require_coordinates(array, name)
    return array


def _paired_rows(points1: Any, points2: Any, min_points: int) -> tuple[np.ndarray, np.ndarray]:
    p1, p2 = _point_rows(points1, "points1"), _point_rows(points2, "points2")
    if p1.shape[0] != p2.shape[0]:
        raise ValueError(
            f"points1 and points2 must have the same length, got {p1.shape[0]} and {p2.shape[0]}"
        )
    if p1.shape[0] < min_points:
        raise ValueError(
            f"at least {min_points} point correspondences are needed, got {p1.shape[0]}"
        )
    return p1, p2


def as_point_pair(
    points1: Any, points2: Any, min_points: int = MIN_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """Both point sets, checked for shape, finiteness, equal length and a minimum count."""
    p1, p2 = _paired_rows(points1, points2, min_points)
    _require_coordinates(p1, "points1")
    _require_coordinates(p2, "points2")
    return p1, p2


def as_homogeneous_pair(points1: Any, points2: Any, min_points: int = MIN_POINTS) -> np.ndarray:
    """Both point sets checked as by :func:`as_point_pair`, as homogeneous coordinate rows.

    Returns
    -------
    ndarray, shape (2, 3, N)
        ``[[u1], [v1], [1]]`` and ``[[u2], [v2], [1]]``.
    """
    p1, p2 = _paired_rows(points1, points2, min_points)
    stack = np.empty((2, 3, p1.shape[0]))
    stack[0, :2] = p1.T
    stack[1, :2] = p2.T
    stack[:, 2] = 1.0
    if not (-MAX_COORDINATE <= stack.min() and stack.max() <= MAX_COORDINATE):
        _require_coordinates(p1, "points1")
        _require_coordinates(p2, "points2")
    return stack


_FLAT_CAMERA_HINTS = {
    (4,): " (fx, fy, cx, cy? give [[fx, 0, cx], [0, fy, cy], [0, 0, 1]])",
    (9,): " (the 9 entries of K? reshape them to (3, 3), row by row)",
}
"""The remedy for a camera given flat, as the command line's --K takes it."""


def as_camera_matrix(value: Any, name: str = "cameraMatrix") -> np.ndarray:
    """A 3x3 pinhole matrix, last row (0, 0, 1), focal lengths in [MIN_FOCAL, MAX_FOCAL].

    A negative focal length mirrors the image and flips the sign of the recovered ``t``; a
    focal length near zero or a principal point beyond ``MAX_COORDINATE`` overflows: all are
    errors naming ``name``.
    """
    if value is None:
        raise TypeError(
            f"{name} is required, got None (no calibration? ppo_cv.camera_from_exif(image)[0].K "
            "is the camera of the image's EXIF focal length, as ppo-cv guesses it)"
        )
    K = _as_real_array(value, name, _PARSE_INTRINSICS)
    if K.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 matrix, got shape {K.shape}"
                         + _FLAT_CAMERA_HINTS.get(K.shape, ""))  # fmt: skip
    rows = K.tolist()
    if not math.isfinite(sum(rows[0]) + sum(rows[1]) + sum(rows[2])):
        require_finite(K, name)
    (fx, _, _), (k10, fy, _), last = rows
    if max(abs(last[0]), abs(last[1]), abs(last[2] - 1.0), abs(k10)) > 1e-12:
        raise ValueError(
            f"{name} must be upper triangular with last row (0, 0, 1), got {K.tolist()}"
            f"{_not_camera_hint(K)}"
        )
    if not (MIN_FOCAL <= fx <= MAX_FOCAL and MIN_FOCAL <= fy <= MAX_FOCAL):
        kind = (
            "a zero"
            if fx == 0 or fy == 0
            else "a negative"
            if min(fx, fy) < 0
            else "an implausible"
        )
        raise ValueError(
            f"{name} has {kind} focal length (fx={fx}, fy={fy}); focal lengths must be "
            f"positive, in [{MIN_FOCAL:g}, {MAX_FOCAL:g}] pixels"
        )
    if max(abs(rows[0][1]), abs(rows[0][2]), abs(rows[1][2])) > MAX_COORDINATE:
        raise ValueError(
            f"{name} has a skew or principal point beyond {MAX_COORDINATE:.0e} px: {K.tolist()}"
        )
    return K


def _not_camera_hint(K: np.ndarray) -> str:
    """What a finite 3x3 matrix that is no camera matrix likely is, for its error message: a
    camera matrix scaled as a whole, one transposed (MATLAB's ``IntrinsicMatrix``, principal
    point in the last row), or an essential matrix (two equal singular values and a zero one)
    given in its place; empty otherwise."""
    upper, lower = np.abs(K[[1, 2, 2], [0, 0, 1]]), np.abs(K[[0, 0, 1], [1, 2, 2]])
    if upper.max() <= 1e-12 and K[2, 2] != 0:
        return f" (scaled as a whole? divide it by K[2,2] = {K[2, 2]:g})"
    if lower.max() <= 1e-12 and K[2, 2] == 1.0 and K[0, 0] > 0 and K[1, 1] > 0:
        return " (transposed, as MATLAB's IntrinsicMatrix? pass its transpose)"
    s1, s2, s3 = np.linalg.svd(K, compute_uv=False)
    if s1 > 0 and s2 >= 0.9 * s1 and s3 <= 1e-3 * s1:
        return " (an essential matrix? the arguments may be out of order)"
    return ""


def as_rotation(value: Any, name: str = "R") -> np.ndarray:
    """A 3x3 rotation matrix as float64: orthonormal to 1e-6 and of determinant +1 (a mirror is
    an error naming ``name``)."""
    R = _as_real_array(value, name)
    if R.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 rotation matrix, got shape {R.shape}")
    require_finite(R, name)
    if np.abs(R).max() > 2 or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or (
        np.linalg.det(R) < 0
    ):  # entries beyond 2 are no rotation's, and their product could overflow
        raise ValueError(f"{name} is not a rotation matrix (orthonormal, determinant +1)")
    return R


def as_distortion(value: Any, name: str) -> np.ndarray | None:
    """OpenCV distortion coefficients as float64 (n,), or None for none or all zeros."""
    if value is None or _as_array(value, name).size == 0:
        return None
    coefficients = _as_real_array(value, name, _PARSE_DISTORTION)
    if sum(side > 1 for side in coefficients.shape) > 1:
        raise ValueError(
            f"{name} must be one row or column of coefficients, got shape {coefficients.shape}: "
            "the coefficients of several cameras? pass one camera's"
        )
    coefficients = coefficients.reshape(-1)
    if coefficients.size not in (4, 5, 8, 12, 14):
        hint = " (k1 alone, or k1,k2: give k1,0,0,0 or k1,k2,0,0)" if coefficients.size < 4 else ""
        raise ValueError(
            f"{name} must be OpenCV distortion coefficients k1,k2,p1,p2[,k3] (4 or 5 numbers; "
            f"8, 12 or 14 for the rational models), got {coefficients.size}{hint}"
        )
    require_finite(coefficients, name)
    _require_physical_distortion(coefficients, name)
    return coefficients if coefficients.any() else None


def _require_physical_distortion(coefficients: np.ndarray, name: str) -> None:
    """OpenCV's order: k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tau_x, tau_y]]]].

    Bounds: ``|k1|, |k2|, |k3| <= 10`` (the polynomial model; a radial factor beyond 10 at the
    edge of a normal field of view folds the image over itself), ``<= 100`` for the rational
    model, whose numerator and denominator terms grow together; ``|p| <= 1``, ``|s| <= 1`` and
    the sensor tilt ``|tau| <= 1`` radian.
    """
    radial_bound = MAX_RADIAL_RATIONAL if coefficients.size >= 8 else MAX_RADIAL
    groups = (
        ("radial k1, k2", coefficients[:2], radial_bound),
        ("tangential p1, p2", coefficients[2:4], MAX_TANGENTIAL),
        ("radial k3..k6", coefficients[4:8], radial_bound),
        ("thin prism s1..s4", coefficients[8:12], MAX_PRISM),
        ("tilt tau_x, tau_y", coefficients[12:14], MAX_TILT),
    )
    for label, values, bound in groups:
        if values.size and np.abs(values).max() > bound:
            raise ValueError(
                f"{name}: {label} {values.tolist()} outside the physical range |value| <= {bound:g}"
            )


def as_essential(value: Any, check_spread: bool = True) -> np.ndarray:
    """A single finite, nonzero 3x3 essential matrix, rescaled to a largest entry of 1.

    A matrix far from every essential matrix (:data:`ESSENTIAL_SPREAD`), such as a fundamental
    matrix in pixels, is a ValueError: its decomposition would give a pose without a warning.

    The pose does not depend on the scale of ``E``; the rescaling keeps any finite scale
    (1e-200, 1e300 or a subnormal 1e-310) clear of underflow and overflow in the
    decomposition. It divides by a power of two, exactly, so that a subnormal ``E``, whose
    reciprocal overflows, is rescaled too. ``check_spread=False`` leaves the spread to a
    caller that decomposes ``E`` anyway (:func:`require_essential_spread` on its singular values).
    """
    E = _as_real_array(value, "E")
    if E.ndim == 2 and E.shape[1] == 3 and E.shape[0] % 3 == 0 and E.shape[0] > 3:
        raise ValueError(
            f"E has shape {E.shape}: a stack of {E.shape[0] // 3} essential matrices as "
            "cv2.findEssentialMat returns them; pass one 3x3 matrix, e.g. E[:3]"
        )
    if E.shape != (3, 3):
        raise ValueError(f"E must be a 3x3 matrix, got shape {E.shape}")
    entries = E.ravel().tolist()
    if not math.isfinite(sum(entries)):
        require_finite(E, "E")
    largest = max(map(abs, entries))
    if largest == 0:
        raise ValueError("E is all zeros: it defines no pose")
    if largest != 1.0:
        E = np.ldexp(E, -math.frexp(largest)[1]) * (1.0 / math.frexp(largest)[0])
    if check_spread:
        require_essential_spread(np.linalg.svd(E, compute_uv=False))
    return E


def require_essential_spread(singular_values: np.ndarray) -> None:
    """ValueError when the singular values (3,) of an ``E`` are far from an essential
    matrix's two equal and one zero (:data:`ESSENTIAL_SPREAD`)."""
    s1, s2, s3 = np.ravel(singular_values).tolist()
    if ESSENTIAL_SPREAD * s2 >= s1 and ESSENTIAL_SPREAD * s3 <= s2:
        return
    if s2 <= 1e-9 * s1:
        reason = "it has rank 1"
    elif s1 > ESSENTIAL_SPREAD * s2:
        reason = (
            f"the two largest differ by a factor {s1 / s2:.3g} (a fundamental matrix in "
            "pixels? pass E = K2^T F K1)"
        )
    else:
        reason = "it has rank 3"
    raise ValueError(
        f"E is not an essential matrix: its singular values ({s1:.3g}, {s2:.3g}, {s3:.3g}) "
        f"should be two equal and one zero, and {reason}"
    )


def as_mask(value: Any, n: int, min_selected: int = MIN_POINTS) -> np.ndarray | None:
    """An inlier mask of n entries (any of OpenCV's shapes) as bool (n,), or None.

    Entries are bool or whole numbers in 0..255, OpenCV's 8-bit masks (nonzero selects the
    point); anything else (0.5, 256, -1, NaN) is an error rather than a guess, and so is a mask
    selecting fewer than ``min_selected`` points.
    """
    if value is None:
        return None
    mask = _as_array(value, "mask")
    if mask.size == 0:
        return None
    if mask.dtype.kind not in "biuf":
        raise TypeError(f"mask must be numeric or bool, got dtype {mask.dtype}")
    if mask.size != n or (mask.ndim > 1 and max(mask.shape) != n):
        raise ValueError(f"mask must have one entry per point ({n}), got shape {mask.shape}")
    mask = mask.reshape(-1)
    if mask.dtype.kind not in "bu" or mask.dtype.itemsize > 1:
        _require_byte_values(mask)
    used = mask != 0
    selected = int(np.count_nonzero(used))
    if selected < min_selected:
        raise ValueError(
            f"mask selects {selected} of {n} points; at least {min_selected} are needed"
        )
    return used


def _require_byte_values(mask: np.ndarray) -> None:
    with np.errstate(invalid="ignore"):
        bad = ~((mask >= 0) & (mask <= 255) & (mask == np.round(mask)))
    if bad.any():
        example = mask[np.flatnonzero(bad)[0]].item()
        raise ValueError(
            f"mask values must be 0..255 whole numbers or bool (nonzero selects a point), "
            f"got {example} ({int(bad.sum())} such entries)"
        )


def as_positive(value: Any, name: str) -> float:
    """A finite number > 0."""
    number = _as_float(value, name)
    if not np.isfinite(number) or number <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {number}")
    return number


def as_positive_at_most(value: Any, name: str, upper: float, unit: str = "") -> float:
    """A finite number in ``(0, upper]``; the message names ``unit`` after the interval."""
    number = as_positive(value, name)
    if number > upper:
        raise ValueError(f"{name} must be in (0, {upper:g}]{unit}, got {number:g}")
    return number


def as_distance_threshold(value: Any, name: str) -> float:
    """A distance beyond which points are dropped: a number > 0, infinity for no cut (as
    OpenCV's ``distanceThresh`` takes it)."""
    number = _as_float(value, name)
    if number == np.inf:
        return number
    return as_positive(number, name)


def as_nonnegative(value: Any, name: str) -> float:
    """A finite number >= 0."""
    number = _as_float(value, name)
    if not np.isfinite(number) or number < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {number}")
    return number


def as_deviation(value: Any, name: str, *, positive: bool = False) -> float | None:
    """None, or the deviation of a prior: a finite number >= 0 (> 0 when ``positive``, for a
    prior that weighs a parameter by its inverse)."""
    if value is None:
        return None
    return as_positive(value, name) if positive else as_nonnegative(value, name)


def as_deviation_pair(value: Any, name: str) -> np.ndarray | None:
    """None, or deviations ``(x, y)``: one finite number >= 0 for both or two, as float64
    (2,)."""
    if value is None:
        return None
    pair = as_finite_array(value, name)
    if pair.size not in (1, 2) or pair.ndim > 1:
        raise ValueError(f"{name} must be one number or two (x, y), got shape {pair.shape}")
    if (pair < 0).any():
        raise ValueError(f"{name} must be deviations >= 0, got {pair.tolist()}")
    return np.broadcast_to(pair, (2,)).copy()


def as_pri_threshold(value: Any, name: str = "pri_threshold") -> float:
    """A pure-rotation threshold on PRI in ``[0, 1]``: the paper's is 0.015, and one above 1
    would call nearly every pair a pure rotation."""
    number = _as_float(value, name)
    if not 0 <= number <= 1:
        raise ValueError(f"{name} must be a number in [0, 1] (the paper's is 0.015), got {number}")
    return number


def _as_float(value: Any, name: str) -> float:
    if isinstance(value, (bool, np.bool_)):  # True would read as 1.0
        raise TypeError(f"{name} must be a number, got {value!r}")
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__} {shown(value)}")
    if getattr(getattr(value, "dtype", None), "kind", "") == "c":
        # float() of a numpy complex drops its imaginary part, with a warning
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {shown(value)}")
    try:
        return float(value)
    except OverflowError:
        raise ValueError(f"{name} is beyond the range of a float: {shown(value)}") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from None


def as_number(value: Any, name: str) -> float:
    """A real number (NaN and infinities included); TypeError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    return _as_float(value, name)


def as_ransac_settings(
    threshold: Any, confidence: Any, min_trials: Any, max_trials: Any, seed: Any
) -> tuple[float, float, int, int, int]:
    """``(threshold, confidence, min_trials, max_trials, seed)`` of a RANSAC fit checked: a
    positive threshold, a confidence in (0, 1], whole trial counts and seed from 0 (a negative
    count ran pycolmap's sampler without end); ValueError or TypeError naming the argument."""
    threshold = as_positive(threshold, "threshold")
    confidence = as_confidence(confidence, "confidence")
    counts = {"min_trials": min_trials, "max_trials": max_trials, "seed": seed}
    counts = [as_whole_number(value, name, 0, MAX_WHOLE_NUMBER) for name, value in counts.items()]
    return (threshold, confidence, *counts)


def as_confidence(value: Any, name: str) -> float:
    """A RANSAC confidence in ``(0, 1]`` whose complement ``1 - value`` is below 1: one of
    2**-54 (5.6e-17) or less leaves ``1 - value`` equal to 1, whose logarithm, 0, stopped
    pycolmap's sampler before its first hypothesis: no model, read as 0 inliers."""
    number = as_positive(value, name)
    if not (1.0 - number < 1.0 and number <= 1.0):
        raise ValueError(
            f"{name} must be in (0, 1] with 1 - {name} below 1 (above {2.0**-54:.2g}), "
            f"got {shown(number)}"
        )
    return number


def as_whole_number(value: Any, name: str, low: int, high: int) -> int:
    """A whole number in ``low..high``: an int, a numpy integer or an integral float."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be a whole number, got {type(value).__name__} {shown(value)}")
    number = int(value) if isinstance(value, (int, np.integer)) else float(value)
    integral = isinstance(number, int) or (math.isfinite(number) and number.is_integer())
    if not (integral and low <= number <= high):
        raise ValueError(f"{name} must be a whole number in {low}..{high}, got {shown(value)}")
    return int(value)


def as_image_size(
    size: Any, name: str, low: int = 1, high: int = MAX_WHOLE_NUMBER
) -> tuple[int, int]:
    """An image size ``(width, height)``: two whole numbers in ``low..high``; TypeError for
    anything but two values (a 0-d array, a text)."""
    sized = hasattr(size, "__len__") and getattr(size, "ndim", 1) != 0  # not a 0-d array
    if isinstance(size, (str, bytes)) or not sized or len(size) != 2:
        raise TypeError(f"{name} must be (width, height), got {shown(size)}")
    width, height = (as_whole_number(v, f"{name} {side}", low, high)
                     for v, side in zip(size, ("width", "height"), strict=True))  # fmt: skip
    return width, height


def as_flag(value: Any, name: str) -> bool:
    """A bool (or numpy bool); TypeError naming ``name`` for anything else, such as the
    string ``"no"``, which would read as true."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(
            f"{name} must be True or False, got {type(value).__name__} {shown(value)}"
        )
    return bool(value)


def as_path(value: Any, name: str) -> Path:
    """``value`` as a Path; TypeError naming ``name`` for anything but a str or PathLike,
    ValueError for the empty path, which ``Path`` reads as the current folder."""
    if not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be a path (str or os.PathLike), got {type(value).__name__}")
    if not os.fspath(value):
        raise ValueError(f"{name} is an empty path, not a file or folder name")
    return Path(value)


def require_instance(value: Any, kinds: type | tuple[type, ...], name: str, hint: str = "") -> None:
    """TypeError unless ``value`` is one of ``kinds``, naming ``name``, the types wanted (by
    module and name, private modules left out: ``pycolmap.Camera``, ``ppo_cv.sfm.PairScore``)
    and the type got, then ``hint`` (how to make one)."""
    kinds = kinds if isinstance(kinds, tuple) else (kinds,)
    if not isinstance(value, kinds):
        wanted = " or ".join(_public_name(kind) for kind in kinds)
        raise TypeError(f"{name} must be a {wanted}, got {type(value).__name__}{hint}")


def as_callback(value: Any, name: str, wanted: str = "callable") -> Any:
    """``value``, an optional hook: None or a callable; TypeError otherwise, naming ``name``,
    what it must be (``wanted``, e.g. ``"a callable taking a stage name"``) and the type got."""
    if value is not None and not callable(value):
        raise TypeError(f"{name} must be {wanted}, got {type(value).__name__}")
    return value


def _public_name(kind: type) -> str:
    if kind is type(None):
        return "None"
    if kind.__module__ == "builtins":
        return kind.__qualname__
    modules = [part for part in kind.__module__.split(".") if not part.startswith("_")]
    return ".".join([*modules, kind.__qualname__])
