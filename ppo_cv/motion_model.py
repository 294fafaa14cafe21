"""Pure rotation or general motion: the decision of :func:`ppo_cv.estimate_pair`.

Two tests that fail differently are combined:

1. Model comparison (:mod:`ppo_cv.model_selection`, GRIC with a mismatch floor): the rotation,
   with a focal scale and radial distortion absorbed (:func:`ppo_cv.rotation.fit_rotation_lens`),
   against the refined essential matrix, on the union of their inliers. Scale-free.
2. The paper's pure-rotation indicator, PRI = mean ``|M2|`` (eq. 84-85), evaluated on the
   rotation the decision would keep and the translation direction most consistent with it
   (the unit ``t`` minimising ``sum (t . (R b1 x b2))^2``, the epipolar constraint eq. 1 with
   ``R`` fixed).

The pair is a pure rotation when the rotation wins the comparison and the PRI of the kept
rotation is below the threshold. So a small PRI alone cannot flag a pair whose parallax GRIC
sees (the PRI of an essential matrix fitted to a narrow-field rotation is not reliable either
way: its rotation is degrees off), and a GRIC win alone cannot flag a pair whose rays plainly do
not meet at the centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import ppo
from .model_selection import (
    JOINT_DIMENSION,
    MODEL_DIMENSIONS,
    ModelResiduals,
    ModelSelection,
    robust_sigma,
    select_model,
)
from .robust import essential_from_pose, sampson_errors
from .rotation import correct_points, fit_rotation_lens, ransac_rotation

__all__ = ["MotionDecision", "decide_motion", "translation_for_rotation"]

TRANSFER_FACTOR = 2.0
"""Inlier bound on the rotation's transfer error, in units of the essential matrix's threshold:
a transfer error carries the noise of both images (a Sampson distance is about half of it)."""

RANSAC_FACTOR = 3.0
"""The plain rotation of the 2-point RANSAC does not model the lens: its consensus is taken
this many times wider, then the lens-absorbing fit re-selects at the normal bound."""


@dataclass(frozen=True)
class MotionDecision:
    """Rotation-only fit and the rotation-versus-general decision of one pair.

    Attributes
    ----------
    model : str
        ``"rotation"`` or ``"general"``.
    pure_rotation : bool
        ``model == "rotation"``.
    R : ndarray, shape (3, 3)
        Rotation of the rotation-only fit over its inliers: with the lens terms when the data
        determine a focal scale other than 1 (beyond three standard deviations), otherwise the
        least-squares rotation of the given rays (the focal the user gave is kept).
    t : ndarray, shape (3,)
        Unit translation most consistent with ``R`` (undetermined for a pure rotation).
    rotation_inliers : ndarray of bool, shape (N,)
        Matches within the threshold of the rotation-only fit.
    pri : float
        PRI (eq. 84) of ``(R, t)`` over ``rotation_inliers``.
    pri_general : float
        PRI of the essential matrix's pose over its inliers.
    focal_scale, k1 : float
        Lens terms of the rotation-only fit.
    selection : ModelSelection
        GRIC of each model, median residuals (pixels), noise estimate.
    """

    model: str
    pure_rotation: bool
    R: np.ndarray
    t: np.ndarray
    rotation_inliers: np.ndarray
    pri: float
    pri_general: float
    focal_scale: float
    k1: float
    selection: ModelSelection

    @property
    def gric_difference(self) -> float:
        """``(GRIC(rotation) - GRIC(general)) / n``: negative when the rotation explains more."""
        return self.selection.relative_gric("rotation", "general")


def translation_for_rotation(R: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Unit ``t`` minimising ``sum_i (t . (R x1_i x x2_i))^2``, sign with ``sum M2 >= 0``.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalised points.

    Returns
    -------
    ndarray, shape (3,)
    """
    normals = np.cross(x1 @ R.T, x2)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    t = np.linalg.svd(normals, full_matrices=False)[2][-1]
    if np.sum(ppo.intersection_scores(x1, x2, R, t)) < 0:
        t = -t
    return t


def decide_motion(
    x1: np.ndarray,
    x2: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    inliers: np.ndarray,
    focal: float,
    *,
    threshold_px: float = 1.0,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
    seed: int = 0,
) -> MotionDecision:
    """Fit a rotation to the matches and decide between pure rotation and general motion.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalised points of all putative matches.
    R, t : ndarray
        Refined pose of the essential matrix, ``X2 = R X1 + t``.
    inliers : ndarray of bool, shape (N,)
        Inliers of that pose.
    focal : float
        Focal length (pixels) that turns normalised errors into pixels.
    threshold_px : float
        Inlier threshold (pixels) of the essential matrix; the rotation's transfer error uses
        :data:`TRANSFER_FACTOR` times it.
    pri_threshold : float
        PRI threshold (paper: 0.015).
    seed : int
        RANSAC seed.

    Returns
    -------
    MotionDecision
    """
    threshold = TRANSFER_FACTOR * threshold_px / focal
    general_all = sampson_errors(essential_from_pose(R, t), x1, x2)
    noise = robust_sigma(general_all[inliers], JOINT_DIMENSION - MODEL_DIMENSIONS["general"][0])
    fit = ransac_rotation(x1, x2, RANSAC_FACTOR * threshold, seed=seed)
    lens = fit_rotation_lens(x1, x2, fit.inliers, fit.R, noise=noise)
    rotation_inliers = lens.residuals < threshold
    for _ in range(4):
        if np.count_nonzero(rotation_inliers) < 5:
            break
        lens = fit_rotation_lens(x1, x2, rotation_inliers, lens.R, noise=noise)
        within = lens.residuals < threshold
        if np.array_equal(within, rotation_inliers):
            break
        rotation_inliers = within
    scored = inliers | rotation_inliers
    general = general_all[scored] * focal
    rotation = lens.residuals[scored] * focal / np.sqrt(2.0)
    d_rot, k_rot = MODEL_DIMENSIONS["rotation"]
    d_gen, k_gen = MODEL_DIMENSIONS["general"]
    selection = select_model(
        [
            ModelResiduals("rotation", rotation, d_rot, k_rot),
            ModelResiduals("general", general, d_gen, k_gen),
        ]
    )
    R_rot, t_rot, pri = lens.R, np.asarray(t, dtype=np.float64), float("inf")
    if np.count_nonzero(rotation_inliers) >= 5:
        if lens.focal_significant:
            c1 = correct_points(x1[rotation_inliers], lens.focal_scale, lens.k1)
            c2 = correct_points(x2[rotation_inliers], lens.focal_scale, lens.k1)
        else:
            c1, c2 = x1[rotation_inliers], x2[rotation_inliers]
            R_rot = ppo.rotation_from_rays(c1, c2)
        t_rot = translation_for_rotation(R_rot, c1, c2)
        pri = ppo.pure_rotation_indicator(ppo.intersection_scores(c1, c2, R_rot, t_rot))
    pri_general = ppo.pure_rotation_indicator(
        ppo.intersection_scores(x1[inliers], x2[inliers], R, t)
    )
    pure = bool(selection.model == "rotation" and pri < pri_threshold)
    return MotionDecision(
        model="rotation" if pure else "general",
        pure_rotation=pure,
        R=R_rot,
        t=t_rot,
        rotation_inliers=rotation_inliers,
        pri=float(pri),
        pri_general=float(pri_general),
        focal_scale=lens.focal_scale,
        k1=lens.k1,
        selection=selection,
    )
