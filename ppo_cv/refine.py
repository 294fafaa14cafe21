"""Non-linear refinement of a relative pose over its inliers, and the rotation-only fit.

- ``refine_pose``: Levenberg-Marquardt on the tangent Sampson error of ``E = [t]_x R`` over the
  inliers (``pycolmap.refine_relative_pose``), ``t`` kept on the unit sphere.
- ``fit_rotation``: for a pure rotation ``b2 ~ R b1`` on unit bearing vectors; the least-squares
  rotation ``argmin_R sum_i ||b2_i - R b1_i||^2`` (:func:`ppo_cv.ppo.rotation_from_rays`),
  re-fitted on the matches whose angular residual ``angle(b2_i, R b1_i)`` stays below the
  threshold.
"""

from __future__ import annotations

import numpy as np

from .ppo import rotation_from_rays
from .robust import virtual_camera

__all__ = ["refine_pose", "fit_rotation", "rotation_residuals"]


def refine_pose(
    R: np.ndarray,
    t: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    focal: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine ``(R, t)`` by minimising the Sampson error over the inliers.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
        Initial rotation, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Initial translation direction.
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches that enter the cost.
    focal : float
        Focal length (pixels) of the virtual camera in which the error is measured; it scales the
        cost, not the minimiser.

    Returns
    -------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Unit norm. The input pose is returned when the solver fails.
    """
    import pycolmap

    t = np.asarray(t, dtype=np.float64).reshape(3)
    if np.count_nonzero(inliers) < 5:
        return R, t / np.linalg.norm(t)
    camera = virtual_camera(focal)
    start = pycolmap.Rigid3d(pycolmap.Rotation3d(np.asarray(R, dtype=np.float64)), t)
    refined = pycolmap.refine_relative_pose(
        start,
        camera,
        np.ascontiguousarray(focal * x1[:, :2]),
        camera,
        np.ascontiguousarray(focal * x2[:, :2]),
        np.asarray(inliers, dtype=bool),
    )
    if refined is None:
        return R, t / np.linalg.norm(t)
    pose = refined["cam2_from_cam1"] if isinstance(refined, dict) else refined
    t_new = np.asarray(pose.translation, dtype=np.float64).reshape(3)
    return pose.rotation.matrix(), t_new / np.linalg.norm(t_new)


def _bearings(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def rotation_residuals(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Angle (radians) between ``b2_i`` and ``R b1_i`` for each match, shape (N,)."""
    b1, b2 = _bearings(x1), _bearings(x2)
    cross = np.linalg.norm(np.cross(b1 @ R.T, b2), axis=1)
    dot = np.einsum("ij,ij->i", b1 @ R.T, b2)
    return np.arctan2(cross, dot)


def fit_rotation(
    x1: np.ndarray,
    x2: np.ndarray,
    inliers: np.ndarray,
    threshold: float,
    R: np.ndarray | None = None,
    iterations: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation between bearing vectors, re-fitted on its own inliers.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous coordinates (or bearings) of the matches.
    inliers : ndarray of bool, shape (N,)
        Matches allowed in the fit.
    threshold : float
        Largest angular residual (radians) of a match kept in the re-fit.
    R : ndarray, shape (3, 3), optional
        Initial rotation (e.g. from the essential matrix) that selects the first matches;
        without it the first fit uses all allowed matches, which suits outlier-free input only.
    iterations : int
        Number of re-fits.

    Returns
    -------
    R : ndarray, shape (3, 3)
    used : ndarray of bool, shape (N,)
        The matches of the last fit.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> b1 = rng.normal(size=(20, 3)); b1[:, 2] = np.abs(b1[:, 2]) + 2
    >>> c, s = np.cos(0.1), np.sin(0.1)
    >>> R_true = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    >>> R, used = fit_rotation(b1, b1 @ R_true.T, np.ones(20, bool), 1e-3)
    >>> bool(np.allclose(R, R_true)), int(used.sum())
    (True, 20)
    """
    b1, b2 = _bearings(np.asarray(x1, float)), _bearings(np.asarray(x2, float))
    allowed = np.asarray(inliers, dtype=bool)
    used = allowed.copy()
    if R is not None:
        used &= rotation_residuals(R, b1, b2) < threshold
    if np.count_nonzero(used) < 2:
        used = allowed.copy()
    R = rotation_from_rays(b1[used], b2[used])
    for _ in range(iterations):
        keep = allowed & (rotation_residuals(R, b1, b2) < threshold)
        if np.count_nonzero(keep) < 2 or np.array_equal(keep, used):
            break
        used = keep
        R = rotation_from_rays(b1[used], b2[used])
    return R, used
