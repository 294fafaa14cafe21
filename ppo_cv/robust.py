"""Robust estimation of the essential matrix from putative matches.

Two backends, both fed normalized (undistorted) image coordinates ``x = K^-1 [u, v, 1]``:

- ``"pycolmap"``: COLMAP's LO-RANSAC on the 5-point solver with the tangent Sampson error
  (``pycolmap.estimate_relative_pose``); the default, the more accurate on real pairs.
- ``"opencv"``: OpenCV's USAC with MAGSAC++ scoring (``cv2.findEssentialMat(..., USAC_MAGSAC)``).

The threshold is given in pixels and converted to normalized units with one focal length ``f``:
the points are handed to the backends as those of a virtual pinhole camera ``(f, f, 0, 0)``, so
two cameras with different intrinsics share one error scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ROBUST_BACKENDS",
    "RobustEstimate",
    "estimate_essential",
    "essential_from_pose",
    "sampson_errors",
]

ROBUST_BACKENDS = ("pycolmap", "opencv")


@dataclass(frozen=True)
class RobustEstimate:
    """Essential matrix and inliers of a robust fit.

    Attributes
    ----------
    E : ndarray, shape (3, 3)
        Essential matrix, ``x2^T E x1 = 0``, unit Frobenius norm.
    inliers : ndarray of bool, shape (N,)
        Matches within the threshold of ``E``.
    backend : str
        The backend that produced it.
    """

    E: np.ndarray
    inliers: np.ndarray
    backend: str

    @property
    def num_inliers(self) -> int:
        """Number of inliers."""
        return int(np.count_nonzero(self.inliers))


def essential_from_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``E = [t]_x R`` normalised to unit Frobenius norm."""
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    E = tx @ R
    return E / max(np.linalg.norm(E), 1e-300)


def sampson_errors(E: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Sampson distance (normalized units) of each match to ``E``, shape (N,).

    ``|x2^T E x1| / sqrt((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)``, the first-order
    geometric distance of the match to the epipolar constraint; multiply by the focal length for
    pixels.
    """
    Ex1 = x1 @ E.T
    Etx2 = x2 @ E
    numerator = np.abs(np.einsum("ij,ij->i", x2, Ex1))
    denominator = np.sqrt(np.sum(Ex1[:, :2] ** 2, axis=1) + np.sum(Etx2[:, :2] ** 2, axis=1))
    return numerator / np.maximum(denominator, 1e-300)


def virtual_camera(focal: float, width: int = 0, height: int = 0):
    """A pycolmap pinhole camera ``(f, f, 0, 0)`` in which ``f * x[:, :2]`` are pixel points."""
    import pycolmap

    return pycolmap.Camera(
        model="PINHOLE",
        width=max(int(width), 1),
        height=max(int(height), 1),
        params=[focal, focal, 0.0, 0.0],
    )


def ransac_options(threshold, confidence, min_trials, max_trials, seed):
    """``pycolmap.RANSACOptions`` for a pixel ``threshold``, trial bounds and a seed."""
    import pycolmap

    options = pycolmap.RANSACOptions()
    options.max_error = threshold
    options.confidence = confidence
    options.max_num_trials = int(max_trials)
    options.min_num_trials = min(int(min_trials), int(max_trials))
    options.random_seed = int(seed)
    return options


def _pycolmap(x1, x2, focal, threshold, confidence, min_trials, max_trials, seed):
    import pycolmap

    options = ransac_options(threshold, confidence, min_trials, max_trials, seed)
    camera = virtual_camera(focal)
    found = pycolmap.estimate_relative_pose(
        camera, focal * x1[:, :2], camera, focal * x2[:, :2], options
    )
    if found is None:
        return None
    pose = found["cam2_from_cam1"]
    E = essential_from_pose(pose.rotation.matrix(), np.asarray(pose.translation).ravel())
    return E, np.asarray(found["inlier_mask"]).reshape(-1).astype(bool)


def _opencv(x1, x2, focal, threshold, confidence, min_trials, max_trials, seed):
    import cv2

    cv2.setRNGSeed(int(seed))
    E, mask = cv2.findEssentialMat(
        x1[:, :2],
        x2[:, :2],
        np.eye(3),
        cv2.USAC_MAGSAC,
        confidence,
        threshold / focal,
        int(max_trials),
    )
    if E is None or mask is None or E.shape[0] < 3:
        return None
    E = E[:3]
    return E / np.linalg.norm(E), mask.reshape(-1) != 0


def estimate_essential(
    x1: np.ndarray,
    x2: np.ndarray,
    focal: float,
    *,
    backend: str = "pycolmap",
    threshold: float = 1.0,
    confidence: float = 0.9999,
    min_trials: int = 100,
    max_trials: int = 100_000,
    seed: int = 0,
) -> RobustEstimate | None:
    """Robustly fit an essential matrix to normalized correspondences.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Normalized homogeneous image coordinates (last entry 1) of the matches, N >= 5.
    focal : float
        Focal length (pixels) that converts ``threshold`` to normalized units.
    backend : {"pycolmap", "opencv"}
        Robust estimator.
    threshold : float
        Inlier threshold on the epipolar (Sampson) error, pixels.
    confidence : float
        Stop when a better model is this unlikely to be missed.
    min_trials, max_trials : int
        Bounds on the number of hypotheses (``min_trials`` is ignored by OpenCV).
    seed : int
        Seed of the sampler, for repeatable results.

    Returns
    -------
    RobustEstimate or None
        None when the backend finds no model.
    """
    if backend not in ROBUST_BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(ROBUST_BACKENDS)}")
    fit = _pycolmap if backend == "pycolmap" else _opencv
    found = fit(
        np.ascontiguousarray(x1, dtype=np.float64),
        np.ascontiguousarray(x2, dtype=np.float64),
        float(focal),
        float(threshold),
        float(confidence),
        min_trials,
        max_trials,
        seed,
    )
    if found is None or not found[1].any():
        return None
    return RobustEstimate(E=found[0], inliers=found[1], backend=backend)
