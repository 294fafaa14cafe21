"""Angular errors of an estimated relative pose against a reference.

The rotation error is the angle of the rotation that takes one estimate to the other, the
geodesic distance on SO(3):

    e_R = arccos((trace(R^T R_ref) - 1) / 2).

The translation of a two-view pose is a direction only (the essential matrix fixes its scale
never, and its sign only with the cheirality or PPO choice), so its error is the angle between
two directions,

    e_t = arccos(t . t_ref / (|t| |t_ref|)),

or, with ``signed=False``, between the two lines, ``arccos |t . t_ref| / (|t| |t_ref|)``: the
measure of two-view benchmarks that score the essential matrix rather than the pose. Both clip
the cosine to [-1, 1] so that rounding never yields NaN, and both take stacks of poses.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .checks import _as_real_array, as_flag

__all__ = ["rotation_error_deg", "direction_error_deg"]


def _as_stack(value: ArrayLike, tail: tuple[int, ...], name: str) -> np.ndarray:
    array = _as_real_array(value, name)
    if tail == (3,) and array.shape == (3, 1):
        array = array[:, 0]
    if array.shape[array.ndim - len(tail) :] != tail:
        shape = ", ".join(map(str, tail))
        raise ValueError(f"{name} must have shape (..., {shape}), got {array.shape}")
    return array


def _require_broadcast(shape: tuple, shape_ref: tuple, name: str, name_ref: str) -> None:
    try:
        np.broadcast_shapes(shape, shape_ref)
    except ValueError:
        raise ValueError(
            f"{name} and {name_ref} must be single or stacks of one shape (or broadcastable), "
            f"got stacks of shape {shape} and {shape_ref}"
        ) from None


_ROTATION_TOLERANCE = 1e-3  # |R R^T - I| of a rotation: float32 or six decimals stay within


def _require_rotations(R: np.ndarray, name: str) -> None:
    """ValueError for a matrix of the stack ``R`` (..., 3, 3) that is no rotation (a scaled
    one, an essential or camera matrix, a mirror); NaN matrices pass, giving NaN angles."""
    with np.errstate(over="ignore", invalid="ignore"):
        off = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max(axis=(-2, -1))
        skewed, mirrored = off > _ROTATION_TOLERANCE, np.linalg.det(R) < 0
    if not (np.any(skewed) or np.any(mirrored)):
        return
    count = int(np.count_nonzero(skewed | mirrored))
    why = [f"|R R^T - I| up to {float(np.max(off[skewed])):.3g}"] if np.any(skewed) else []
    why += ["a mirror, of determinant -1"] if np.any(mirrored & ~skewed) else []
    raise ValueError(
        f"{name} must hold rotation matrices (orthonormal, determinant +1), got {count} "
        f"{'matrix' if count == 1 else 'matrices'} that {'is' if count == 1 else 'are'} not: "
        f"{'; '.join(why)}"
    )


def _unit_scaled(t: np.ndarray) -> np.ndarray:
    """``t`` (..., 3) divided by its largest magnitude, so that no norm under- or overflows;
    zero vectors stay zero."""
    largest = np.abs(t).max(axis=-1, keepdims=True)
    with np.errstate(invalid="ignore"):  # inf / inf: NaN, as a NaN entry gives
        return t / np.where(largest > 0, largest, 1.0)


def rotation_error_deg(R: ArrayLike, R_ref: ArrayLike) -> float | np.ndarray:
    """Angle of ``R^T R_ref`` in degrees, in [0, 180].

    Parameters
    ----------
    R, R_ref : array_like, shape (3, 3) or (..., 3, 3)
        Rotation matrices; stacks broadcast against each other.

    Returns
    -------
    float or ndarray
        A float for two single rotations, else an array of the broadcast stack shape.

    Examples
    --------
    >>> import numpy as np
    >>> c, s = np.cos(np.radians(10.0)), np.sin(np.radians(10.0))
    >>> R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    >>> round(rotation_error_deg(R, np.eye(3)), 6)
    10.0
    """
    R, R_ref = _as_stack(R, (3, 3), "R"), _as_stack(R_ref, (3, 3), "R_ref")
    _require_broadcast(R.shape[:-2], R_ref.shape[:-2], "R", "R_ref")
    _require_rotations(R, "R")
    _require_rotations(R_ref, "R_ref")
    cosine = (np.einsum("...ij,...ij->...", R, R_ref) - 1.0) / 2.0
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    return float(angle) if np.ndim(angle) == 0 else angle


def direction_error_deg(
    t: ArrayLike, t_ref: ArrayLike, *, signed: bool = True
) -> float | np.ndarray:
    """Angle between two directions (``signed``) or between their lines, in degrees.

    Parameters
    ----------
    t, t_ref : array_like, shape (3,), (3, 1) or (..., 3)
        Non-zero vectors of any length (OpenCV's column vector too); stacks broadcast against
        each other.
    signed : bool
        False: the angle between the lines, ``t`` and ``-t`` alike (at most 90).

    Returns
    -------
    float or ndarray
        NaN where either vector is zero.

    Examples
    --------
    >>> direction_error_deg([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0])
    180.0
    >>> direction_error_deg([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], signed=False)
    0.0
    """
    t, t_ref = _as_stack(t, (3,), "t"), _as_stack(t_ref, (3,), "t_ref")
    _require_broadcast(t.shape[:-1], t_ref.shape[:-1], "t", "t_ref")
    signed = as_flag(signed, "signed")
    t, t_ref = _unit_scaled(t), _unit_scaled(t_ref)
    norms = np.linalg.norm(t, axis=-1) * np.linalg.norm(t_ref, axis=-1)
    dot = np.einsum("...i,...i->...", t, t_ref)
    if not signed:
        dot = np.abs(dot)
    cosine = np.where(norms > 0, dot / np.where(norms > 0, norms, 1.0), np.nan)
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    return float(angle) if np.ndim(angle) == 0 else angle
