"""Input checks at the public boundary: each failure names the argument and the problem."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "MIN_POINTS",
    "as_points",
    "as_point_pair",
    "as_homogeneous_pair",
    "as_camera_matrix",
    "as_distortion",
    "as_essential",
    "as_mask",
    "as_positive",
]

MIN_POINTS = 5


def _as_real_array(value: Any, name: str) -> np.ndarray:
    if value is None:
        raise TypeError(f"{name} is required, got None")
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a numeric array: {exc}") from None
    if array.dtype == np.float64:
        return array
    if array.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {array.dtype}")
    return array.astype(np.float64)


def _require_finite(array: np.ndarray, name: str) -> None:
    if math.isfinite(array.sum()):
        return
    bad = ~np.isfinite(array)  # the sum can also overflow with finite entries
    if bad.any():
        raise ValueError(f"{name} has {int(bad.sum())} NaN or infinite value(s)")


def _point_rows(value: Any, name: str) -> np.ndarray:
    """(N, 2) float64 view or copy of OpenCV-shaped points, not yet checked for finiteness."""
    array = _as_real_array(value, name)
    shape = array.shape
    if array.ndim == 3 and shape[2] == 2 and (shape[1] == 1 or shape[0] == 1):
        return array.reshape(-1, 2)
    if not (array.ndim == 2 and shape[1] == 2):
        raise ValueError(f"{name} must have shape (N, 2), (N, 1, 2) or (1, N, 2), got {shape}")
    return array


def as_points(value: Any, name: str) -> np.ndarray:
    """Image points as float64 (N, 2), from (N, 2), (N, 1, 2) or (1, N, 2), OpenCV's shapes."""
    array = _point_rows(value, name)
    _require_finite(array, name)
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
    _require_finite(p1, "points1")
    _require_finite(p2, "points2")
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
    if not math.isfinite(stack.sum()):
        _require_finite(p1, "points1")
        _require_finite(p2, "points2")
    return stack


def as_camera_matrix(value: Any, name: str = "cameraMatrix") -> np.ndarray:
    """A 3x3 pinhole matrix with nonzero focal lengths and last row (0, 0, 1)."""
    K = _as_real_array(value, name)
    if K.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 matrix, got shape {K.shape}")
    rows = K.tolist()
    if not math.isfinite(sum(rows[0]) + sum(rows[1]) + sum(rows[2])):
        _require_finite(K, name)
    (fx, _, _), (k10, fy, _), last = rows
    if max(abs(last[0]), abs(last[1]), abs(last[2] - 1.0), abs(k10)) > 1e-12:
        raise ValueError(
            f"{name} must be upper triangular with last row (0, 0, 1), got {K.tolist()}"
        )
    if fx == 0 or fy == 0:
        raise ValueError(f"{name} has a zero focal length (fx={fx}, fy={fy})")
    return K


def as_distortion(value: Any, name: str) -> np.ndarray | None:
    """OpenCV distortion coefficients as float64 (n,), or None for none or all zeros."""
    if value is None or np.size(value) == 0:
        return None
    coefficients = _as_real_array(value, name).reshape(-1)
    if coefficients.size not in (4, 5, 8, 12, 14):
        raise ValueError(
            f"{name} must be OpenCV distortion coefficients k1,k2,p1,p2[,k3] (4 or 5 numbers; "
            f"8, 12 or 14 for the rational models), got {coefficients.size}"
        )
    _require_finite(coefficients, name)
    return coefficients if coefficients.any() else None


def as_essential(value: Any) -> np.ndarray:
    """A single finite, nonzero 3x3 essential matrix."""
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
        _require_finite(E, "E")
    if not any(entries):
        raise ValueError("E is all zeros: it defines no pose")
    return E


def as_mask(value: Any, n: int) -> np.ndarray | None:
    """An inlier mask of n entries (any of OpenCV's shapes) as bool (n,), or None."""
    if value is None:
        return None
    mask = np.asarray(value)
    if mask.size == 0:
        return None
    if mask.dtype.kind not in "biuf":
        raise TypeError(f"mask must be numeric or bool, got dtype {mask.dtype}")
    if mask.size != n or (mask.ndim > 1 and max(mask.shape) != n):
        raise ValueError(f"mask must have one entry per point ({n}), got shape {mask.shape}")
    return mask.reshape(-1) != 0


def as_positive(value: Any, name: str) -> float:
    """A finite number > 0."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from None
    if not np.isfinite(number) or number <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {number}")
    return number
