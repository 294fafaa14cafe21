"""``recoverPose``: OpenCV's call forms, with the PPO inequalities in place of cheirality.

The four call forms of OpenCV 5's ``cv2.recoverPose`` are accepted with the same argument names,
defaults, array shapes and return tuples::

    recoverPose(E, points1, points2, cameraMatrix[, R[, t[, mask]]]) -> retval, R, t, mask
    recoverPose(E, points1, points2[, R[, t[, focal[, pp[, mask]]]]]) -> retval, R, t, mask
    recoverPose(E, points1, points2, cameraMatrix, distanceThresh[, R[, t[, mask[,
                triangulatedPoints]]]]) -> retval, R, t, mask, triangulatedPoints
    recoverPose(points1, points2, cameraMatrix1, distCoeffs1, cameraMatrix2, distCoeffs2[, E[,
                R[, t[, method[, prob[, threshold[, mask]]]]]]]) -> retval, E, R, t, mask

``retval`` counts the points that satisfy both PPO inequalities, and the output ``mask`` marks
them (keeping the values of the input mask, 255 where none was given, as OpenCV does; in the
fourth form OpenCV overwrites the input mask with the robust estimator's, and so does this).
A ``mask`` given as a contiguous ``uint8`` array of shape (N, 1) receives the output mask in
place and is returned, as OpenCV's input-output arrays are.
``install()`` puts this function in place of ``cv2.recoverPose``.

As in OpenCV, a positional number after ``cameraMatrix`` is the ``R`` output buffer (first
form, four outputs); ``distanceThresh`` selects the third form by keyword (or with eight or nine
positional arguments), and so does a ``triangulatedPoints`` keyword, which only the third form
has (the number after ``cameraMatrix`` is then ``distanceThresh``). ``E`` may have any shape
of nine entries (``(9,)``, ``(1, 9)``, ...), a camera matrix the shape (3, 3, 1) OpenCV also
reads, and ``cv2.UMat`` inputs give ``cv2.UMat`` outputs.

Bad input raises :class:`RecoverPoseError` (a ``ValueError``) or :class:`RecoverPoseTypeError`
(a ``TypeError``), both subclasses of ``cv2.error``, so code written for OpenCV that catches
``cv2.error`` keeps working under :func:`install`. Unlike OpenCV, a mask selecting fewer than
five points, mask values other than 0..255 whole numbers, non-positive focal lengths and an
``E`` far from every essential matrix (a fundamental matrix in pixels, the identity) are errors
rather than silent zeros, mirrored poses or poses of no meaning; so is a camera matrix given
with ``focal`` or ``pp`` (it stands in the place of the ``R`` output, and OpenCV writes the
rotation over it). A ``cameraMatrix`` of None (``recoverPose(E, p1, p2, None)``) is refused as
OpenCV refuses it; normalized points take the form without it, ``recoverPose(E, p1, p2)``.
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np

from . import ppo
from .checks import (
    MAX_COORDINATE,
    MAX_FOCAL,
    MIN_FOCAL,
    as_camera_matrix,
    as_distance_threshold,
    as_distortion,
    as_essential,
    as_homogeneous_pair,
    as_mask,
    as_point_pair,
    as_positive,
    as_positive_at_most,
    require_essential_spread,
    shown,
)
from .pose import _inverse

__all__ = [
    "recoverPose",
    "install",
    "uninstall",
    "installed",
    "is_installed",
    "RecoverPoseError",
    "RecoverPoseTypeError",
]


class RecoverPoseError(cv2.error, ValueError):
    """Invalid input to :func:`recoverPose`: a ``ValueError`` and a ``cv2.error``."""


class RecoverPoseTypeError(cv2.error, TypeError):
    """Input of the wrong type to :func:`recoverPose`: a ``TypeError`` and a ``cv2.error``."""


_OPENCV_RECOVER_POSE = cv2.recoverPose
_replaced: list = []  # what install() replaced, restored by uninstall()
_METHODS = {
    name: getattr(cv2, name)
    for name in (
        "RANSAC",
        "LMEDS",
        "USAC_DEFAULT",
        "USAC_PARALLEL",
        "USAC_FM_8PTS",
        "USAC_FAST",
        "USAC_ACCURATE",
        "USAC_PROSAC",
        "USAC_MAGSAC",
    )
    if hasattr(cv2, name)
}
_MAX_THRESHOLD = 100.0
_FLIP_XY = np.array([-1.0, -1.0, 1.0])
_MASK_ON = np.uint8(255)
_FORM1 = ("E", "points1", "points2", "cameraMatrix", "R", "t", "mask")
_FORM2 = ("E", "points1", "points2", "R", "t", "focal", "pp", "mask")
_FORM3 = (
    "E",
    "points1",
    "points2",
    "cameraMatrix",
    "distanceThresh",
    "R",
    "t",
    "mask",
    "triangulatedPoints",
)
_FORM4 = (
    "points1",
    "points2",
    "cameraMatrix1",
    "distCoeffs1",
    "cameraMatrix2",
    "distCoeffs2",
    "E",
    "R",
    "t",
    "method",
    "prob",
    "threshold",
    "mask",
)


def _bind(names: tuple[str, ...], args: tuple, kwargs: dict) -> dict[str, Any]:
    if len(args) > len(names):
        raise TypeError(
            f"recoverPose({', '.join(names[:4])}, ...) takes at most {len(names)} positional "
            f"arguments, got {len(args)}"
        )
    bound = dict(zip(names, args, strict=False))
    for key, value in kwargs.items():
        if key not in names:
            raise TypeError(f"recoverPose got an unexpected keyword argument {shown(key)}")
        if key in bound:
            raise TypeError(f"recoverPose got multiple values for argument {shown(key)}")
        bound[key] = value
    return bound


def _is_3x3(value: Any) -> bool:
    shape = getattr(value, "shape", None)
    return value is not None and (np.shape(value) if shape is None else shape) == (3, 3)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _are_points(value: Any) -> bool:
    """Whether ``value`` has a shape of points, (N, 2) or (N, 1, 2), which no ``E`` has."""
    try:
        shape = np.shape(value)
    except ValueError:  # ragged
        return False
    return len(shape) in (2, 3) and shape[-1] == 2


def _form(args: tuple, kwargs: dict) -> tuple[str, ...]:
    if "cameraMatrix1" in kwargs or (len(args) > 2 and _is_3x3(args[2])):
        return _FORM4
    if args and _are_points(args[0]):
        return _FORM4
    if "focal" in kwargs or "pp" in kwargs:
        return _FORM2
    if len(args) in (4, 5) and args[3] is None:  # OpenCV reads it as the camera matrix
        return _FORM1
    has_camera = "cameraMatrix" in kwargs or (len(args) > 3 and args[3] is not None)
    if not has_camera:
        return _FORM2
    third = "distanceThresh" in kwargs or "triangulatedPoints" in kwargs
    if third or (len(args) > len(_FORM1) and _is_number(args[4])):
        return _FORM3
    return _FORM1


def _out_matrix(buffer: Any, value: np.ndarray) -> np.ndarray:
    """Write into a caller's output array when it fits, as OpenCV's bindings do: same shape
    and dtype, contiguous and writable (an input-output ``mask`` of shape (N, 1) included)."""
    if not isinstance(buffer, np.ndarray) or buffer.shape != value.shape:
        return value
    if buffer.dtype == value.dtype and buffer.flags.writeable and buffer.flags.c_contiguous:
        buffer[...] = value
        return buffer
    return value


def _out_mask(inliers: np.ndarray, mask_in: Any) -> np.ndarray:
    if mask_in is None or np.size(mask_in) != inliers.size:
        return (inliers.view(np.uint8) * _MASK_ON).reshape(-1, 1)
    values = np.asarray(mask_in).reshape(-1).astype(np.uint8)
    return _out_matrix(mask_in, np.where(inliers, values, 0).astype(np.uint8).reshape(-1, 1))


def _homogeneous_points(X1: np.ndarray, X2: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4xN analytic points; a point at infinity is its camera-1 ray with w = 0."""
    points = ppo._points(X1, X2, R, t, 1e-12)
    finite = np.isfinite(points[0])
    return np.vstack([np.where(finite, points, X1), finite.astype(np.float64)])


def _outputs(
    R: np.ndarray, t: np.ndarray, inliers: np.ndarray, bound: dict
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    R = _out_matrix(bound.get("R"), R)
    t = _out_matrix(bound.get("t"), t.reshape(3, 1))
    return int(np.count_nonzero(inliers)), R, t, _out_mask(inliers, bound.get("mask"))


def _require_no_camera_as_R(R: Any) -> None:
    """TypeError for a camera matrix in the ``R`` place of the focal, pp form (``recoverPose(E,
    p1, p2, K, focal=f)``): OpenCV takes it as the output buffer and writes the rotation over
    the caller's camera matrix. A rotation has no entry beyond 1; a camera matrix has a last
    row (0, 0, 1) and focal lengths beyond 1."""
    if not (isinstance(R, np.ndarray) and R.shape == (3, 3) and R.dtype.kind in "iuf"):
        return
    if np.array_equal(R[2], [0, 0, 1]) and R[1, 0] == 0 and min(R[0, 0], R[1, 1]) > 1:
        raise TypeError(
            "recoverPose got a camera matrix in the place of the R output (fourth argument) of "
            "the focal, pp form, which would write the rotation over it: pass cameraMatrix "
            "alone, or focal and pp alone"
        )


def _camera_from_focal(focal: Any, pp: Any) -> np.ndarray:
    f = 1.0 if focal is None else as_positive(focal, "focal")
    if not MIN_FOCAL <= f <= MAX_FOCAL:
        raise ValueError(f"focal must be in [{MIN_FOCAL:g}, {MAX_FOCAL:g}] pixels, got {f}")
    try:
        if pp is not None and np.asarray(pp).dtype.kind in "bcSU":  # True, complex, text
            raise TypeError
        cx, cy = (0.0, 0.0) if pp is None else np.asarray(pp, dtype=np.float64).reshape(2)
    except (TypeError, ValueError):
        raise TypeError(f"pp must be two numbers (cx, cy), got {shown(pp)}") from None
    except OverflowError:  # an integer beyond float64
        cx = cy = math.inf
    if not (abs(cx) <= MAX_COORDINATE and abs(cy) <= MAX_COORDINATE):
        raise ValueError(
            f"pp must be two finite numbers within {MAX_COORDINATE:.0e}, got {shown(pp)}"
        )
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def _method(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"method must be an int flag such as cv2.RANSAC, got {shown(value)}")
    if int(value) not in _METHODS.values():
        raise ValueError(
            f"method must be one of cv2.{', cv2.'.join(_METHODS)}, got {shown(value)}"
        )
    return int(value)


def _probability(value: Any) -> float:
    prob = as_positive(value, "prob")
    if not prob < 1:
        raise ValueError(f"prob must be in (0, 1), got {prob}")
    return prob


def _threshold(value: Any) -> float:
    return as_positive_at_most(value, "threshold", _MAX_THRESHOLD, " pixels")


def _essential(value: Any) -> np.ndarray:
    """``E`` as OpenCV reads it: any array of nine entries is one 3x3 matrix."""
    shape = getattr(value, "shape", None)
    if shape is not None and len(shape) != 2 and np.size(value) == 9:
        value = np.reshape(value, (3, 3))
    elif shape in ((1, 9), (9, 1)):
        value = np.reshape(value, (3, 3))
    return as_essential(value, check_spread=False)  # checked on the SVD of _identify


def _recover_from_points(bound: dict) -> tuple:
    """Form 4: undistort, estimate E with OpenCV's robust estimator, then choose by PPO."""
    p1, p2 = as_point_pair(bound.get("points1"), bound.get("points2"))
    K1 = as_camera_matrix(_required_camera(bound, "cameraMatrix1"), "cameraMatrix1")
    K2 = as_camera_matrix(_required_camera(bound, "cameraMatrix2"), "cameraMatrix2")
    n1 = _undistort(p1, K1, bound.get("distCoeffs1"), "distCoeffs1")
    n2 = _undistort(p2, K2, bound.get("distCoeffs2"), "distCoeffs2")
    threshold = _threshold(bound.get("threshold", 1.0))
    method = _method(bound.get("method", cv2.RANSAC))
    prob = _probability(bound.get("prob", 0.999))
    focal = (K1[0, 0] + K1[1, 1] + K2[0, 0] + K2[1, 1]) / 4.0
    E, ransac_mask = cv2.findEssentialMat(n1, n2, np.eye(3), method, prob, threshold / focal)
    if E is None or ransac_mask is None or not ransac_mask.any():
        raise ValueError("no essential matrix could be estimated from these points")
    used = ransac_mask.reshape(-1) != 0  # OpenCV overwrites the input mask with this one
    points, K_inv = as_homogeneous_pair(n1, n2), np.eye(3)
    candidates = [E[i : i + 3] for i in range(0, E.shape[0], 3)]
    results = [_identify(Ei, points, K_inv, used) for Ei in candidates]
    best = int(np.argmax([np.count_nonzero(inliers) for _, _, inliers in results]))
    retval, R, t, mask = _outputs(*results[best], {**bound, "mask": used})
    mask = _write_mask(bound.get("mask"), mask)
    return retval, _out_matrix(bound.get("E"), candidates[best].copy()), R, t, mask


_POINT_FORMS = (
    "the form with points is recoverPose(points1, points2, cameraMatrix1, distCoeffs1, "
    "cameraMatrix2, distCoeffs2), recoverPose(p1, p2, K, None, K, None) for one camera without "
    "distortion; with an essential matrix, recoverPose(E, points1, points2, cameraMatrix)"
)


def _required_camera(bound: dict, name: str) -> Any:
    """The camera matrix ``name`` of the form with points; TypeError naming it when missing,
    with the call forms, and a 3x3 matrix given in the place of ``distCoeffs1``
    (``recoverPose(p1, p2, K1, K2)``)."""
    value = bound.get(name)
    if value is not None:
        return _one_channel(value)
    place = ":"
    if name == "cameraMatrix2" and _is_3x3(bound.get("distCoeffs1")):
        place = ", and distCoeffs1 is a 3x3 matrix: the second camera's in its place?"
    raise TypeError(f"{name} is required, got None{place} {_POINT_FORMS}")


def _required_camera_matrix(K: Any) -> Any:
    """``cameraMatrix`` of the forms with ``E``; TypeError for None, as OpenCV refuses it,
    saying how normalized points are passed (a camera matrix that failed to load, taken for
    the focal length 1 of those points, gave a pose of pixels read as normalized points)."""
    if K is None:
        raise TypeError(
            "cameraMatrix is required, got None: for normalized points leave it out, "
            "recoverPose(E, points1, points2), or pass focal=1.0"
        )
    return _one_channel(K)


def _one_channel(K: Any) -> Any:
    """A camera matrix of shape (3, 3, 1) as (3, 3): OpenCV reads that array as a 3x3
    one-channel matrix and takes it."""
    return K.reshape(3, 3) if isinstance(K, np.ndarray) and K.shape == (3, 3, 1) else K


def _write_mask(buffer: Any, mask: np.ndarray) -> np.ndarray:
    """OpenCV writes the (N, 1) output mask into a caller's writable 8-bit array of N entries
    whatever its shape, and returns that array itself only when it is (N, 1)."""
    if not (isinstance(buffer, np.ndarray) and buffer.dtype == np.uint8):
        return mask
    if buffer.size != mask.size or not (buffer.flags.writeable and buffer.flags.c_contiguous):
        return mask
    buffer.reshape(-1)[...] = mask.reshape(-1)
    return buffer if buffer.shape == mask.shape else mask


def _identify(
    E: np.ndarray, points: np.ndarray, K_inv: np.ndarray, used: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R, t, inliers)`` chosen among the candidates of ``E`` by the PPO inequalities.

    ``points`` (2, 3, N) holds the homogeneous pixels of both views by coordinate rows and
    ``K_inv`` (3, 3) their inverse intrinsics, folded into the maps of :func:`ppo.frame_scores`.
    """
    w, U, Vt = cv2.SVDecomp(E)  # several times faster than numpy's for one 3x3 matrix
    require_essential_spread(w)
    maps = ppo._frame_maps(U, ppo._proper_svd(U, Vt))
    m1, m2 = ppo._blocked_frame_scores(maps @ K_inv, points)
    keep_R1, same_side, _, _ = ppo._vote(m1, used)
    keep_t, intersecting, _, _ = ppo._vote(m2, used)
    inliers = same_side & intersecting
    if used is not None:
        inliers &= used
    R = U @ maps[0] if keep_R1 else (U * _FLIP_XY) @ maps[0]  # W2^T = diag(-1, -1, 1) W1^T
    return R, U[:, 2] * (1.0 if keep_t else -1.0), inliers


def _inverse_camera_matrix(K: Any) -> np.ndarray:
    """The checked ``cameraMatrix`` inverted, from a small cache for float64 3x3 arrays
    (a video or a matcher loop passes the same matrix call after call)."""
    if isinstance(K, np.ndarray) and K.dtype == np.float64 and K.shape == (3, 3):
        return _cached_inverse(K.tobytes())
    return _inverse(as_camera_matrix(K, "cameraMatrix"))


@functools.lru_cache(maxsize=16)
def _cached_inverse(K_bytes: bytes) -> np.ndarray:
    K_inv = _inverse(as_camera_matrix(np.frombuffer(K_bytes).reshape(3, 3), "cameraMatrix"))
    K_inv.flags.writeable = False
    return K_inv


def _undistort(points: np.ndarray, K: np.ndarray, coefficients: Any, name: str) -> np.ndarray:
    """Pixel points (N, 2) to normalized points (N, 2) with OpenCV's distortion model."""
    coefficients = as_distortion(coefficients, name)
    return cv2.undistortPoints(points.reshape(-1, 1, 2), K, coefficients).reshape(-1, 2)


def recoverPose(*args: Any, **kwargs: Any) -> tuple:  # noqa: N802 - OpenCV's name
    """Drop-in for ``cv2.recoverPose`` choosing the pose by the PPO inequalities.

    See the module docstring for the call forms; arguments, shapes and return tuples follow
    OpenCV 5. ``R`` is 3x3 and ``t`` 3x1 float64; ``t`` has unit length.

    Raises
    ------
    RecoverPoseError, RecoverPoseTypeError
        With a message naming the offending argument; subclasses of ``ValueError`` and
        ``TypeError`` respectively, and both of ``cv2.error``.

    Examples
    --------
    Existing OpenCV code switches with one line:

    >>> import cv2, numpy as np, ppo_cv
    >>> rng = np.random.default_rng(0)
    >>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> X = rng.uniform([-2, -2, 5], [2, 2, 9], (100, 3))
    >>> R, _ = cv2.Rodrigues(np.array([0.0, 0.1, 0.0]))
    >>> t = np.array([[1.0], [0.0], [0.0]])
    >>> p1 = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K, None)[0]
    >>> p2 = cv2.projectPoints(X, cv2.Rodrigues(R)[0], t, K, None)[0]
    >>> E, mask = cv2.findEssentialMat(p1, p2, K, cv2.RANSAC, 0.999, 1.0)
    >>> with ppo_cv.installed():
    ...     retval, R_est, t_est, mask = cv2.recoverPose(E, p1, p2, K, mask=mask)
    >>> retval, bool(np.allclose(R_est, R, atol=1e-6)), t_est.ravel().round(6).tolist()
    (100, True, [1.0, 0.0, 0.0])
    """
    try:
        if any(isinstance(value, cv2.UMat) for value in (*args, *kwargs.values())):
            return _on_umats(args, kwargs)
        return _recover_pose(args, kwargs)
    except cv2.error:
        raise
    except ValueError as exc:
        raise RecoverPoseError(str(exc)) from None
    except TypeError as exc:
        raise RecoverPoseTypeError(str(exc)) from None


def _on_umats(args: tuple, kwargs: dict) -> tuple:
    """OpenCV's UMat contract: UMat inputs are read, and array outputs come back as UMats."""

    def read(value: Any) -> Any:
        return value.get() if isinstance(value, cv2.UMat) else value

    outputs = _recover_pose(
        tuple(read(value) for value in args), {key: read(v) for key, v in kwargs.items()}
    )
    return tuple(cv2.UMat(np.ascontiguousarray(out)) if isinstance(out, np.ndarray) else out
                 for out in outputs)  # fmt: skip


def _recover_pose(args: tuple, kwargs: dict) -> tuple:
    form = _form(args, kwargs)
    bound = _bind(form, args, kwargs)
    if form is _FORM4:
        return _recover_from_points(bound)
    if form is _FORM2:
        _require_no_camera_as_R(bound.get("R"))
        K = _camera_from_focal(bound.get("focal", 1.0), bound.get("pp"))
    else:
        K = _required_camera_matrix(bound.get("cameraMatrix"))
    E = _essential(bound.get("E"))
    points = as_homogeneous_pair(bound.get("points1"), bound.get("points2"))
    K_inv = _inverse_camera_matrix(K)
    used = as_mask(bound.get("mask"), points.shape[2])
    R, t, inliers = _identify(E, points, K_inv, used)
    if form is not _FORM3:
        return _outputs(R, t, inliers, bound)
    distance = as_distance_threshold(bound.get("distanceThresh"), "distanceThresh")
    X1, X2 = K_inv @ points
    if distance < math.inf:
        z1, z2, _ = ppo._depths(X1, X2, R, t, 1e-12)
        inliers &= (z1 < distance) & (z2 < distance)
    points = _out_matrix(bound.get("triangulatedPoints"), _homogeneous_points(X1, X2, R, t))
    return (*_outputs(R, t, inliers, bound), points)


def is_installed() -> bool:
    """Whether ``cv2.recoverPose`` is currently ppo_cv's."""
    return cv2.recoverPose is recoverPose


def install() -> None:
    """Replace ``cv2.recoverPose`` with :func:`recoverPose` for all code in this process.

    Installing twice is harmless; :func:`uninstall` restores what was there before. A name
    bound to OpenCV's function before the call (``from cv2 import recoverPose``) keeps it:
    install first, or call ``cv2.recoverPose``.
    """
    if cv2.recoverPose is not recoverPose:
        _replaced[:] = [cv2.recoverPose]
        cv2.recoverPose = recoverPose


def uninstall() -> None:
    """Restore the ``cv2.recoverPose`` that :func:`install` replaced (OpenCV's, or another
    wrapper installed before); nothing to do when ppo_cv's is not installed."""
    if cv2.recoverPose is recoverPose:
        cv2.recoverPose = _replaced.pop() if _replaced else _OPENCV_RECOVER_POSE


@contextlib.contextmanager
def installed() -> Iterator[None]:
    """Context manager: ``cv2.recoverPose`` is ppo_cv's inside the block, as before after it."""
    previous = cv2.recoverPose
    cv2.recoverPose = recoverPose
    try:
        yield
    finally:
        cv2.recoverPose = previous
