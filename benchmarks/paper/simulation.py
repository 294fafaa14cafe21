"""Monte-Carlo cells of the paper's simulation study (Section 5), measured with ppo_cv and OpenCV.

One *cell* is a (parallax factor, noise) point of the paper's grid at one scene depth: ``n_mc``
noise draws of ``n_poses`` two-view problems of 50 points from
:func:`ppo_cv.data_gen.paper_protocol`. Every problem is solved from the same linear
essential matrix ``Q`` (the least-squares solution of ``X'^T Q X = 0``, eq. 42) by

* the PPO inequalities (:func:`ppo_cv.ppo.select_pose`, Table II),
* OpenCV's cheirality test, ``cv2.recoverPose`` (default ``distanceThresh = 50``),
* cheirality without a distance cut (``cv2.recoverPose`` with ``distanceThresh = 1e12``), the
  positive-depth test of Hartley and Zisserman that the paper calls the traditional method,

and the 3D points of the PPO pose by eq. 36 (:func:`ppo_cv.ppo.analytic_points`) and by DLT
triangulation (``cv2.triangulatePoints``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ppo_cv import ppo
from ppo_cv.data_gen import paper_protocol
from ppo_cv.metrics import direction_error_deg

__all__ = [
    "CellResult",
    "linear_essential",
    "euler_zyx_deg",
    "rotation_discrepancy_deg",
    "translation_discrepancy_deg",
    "simulate_cell",
    "rmse",
]

NO_DISTANCE_CUT = 1e12


@dataclass(frozen=True)
class CellResult:
    """Per-problem measurements of one cell, arrays of shape (n_mc * n_poses,).

    ``rot_*`` and ``t_*`` are the discrepancies of eq. 80 and eq. 81 in degrees; ``*_ppo``,
    ``*_cv`` and ``*_cheir`` are the PPO pose, ``cv2.recoverPose`` and cheirality without
    distance cut. ``rot_right_ppo`` / ``rot_right_cv`` tell whether the method picked the
    candidate rotation closer to the truth. ``err3d_anal`` and ``err3d_dlt`` hold the sum of
    squared 3D errors (m^2) of the problem's points and ``n3d`` how many points entered it.
    """

    alpha: float
    noise_px: float
    depth: float
    rot_ppo: np.ndarray
    t_ppo: np.ndarray
    rot_cv: np.ndarray
    t_cv: np.ndarray
    t_cheir: np.ndarray
    rot_right_ppo: np.ndarray
    rot_right_cv: np.ndarray
    pri: np.ndarray
    m3: np.ndarray
    sq3d_anal: np.ndarray
    sq3d_dlt: np.ndarray
    med3d_anal: np.ndarray
    med3d_dlt: np.ndarray
    n3d: np.ndarray


def linear_essential(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Least-squares ``Q`` with ``x2^T Q x1 = 0`` for a batch of problems (eq. 42).

    Parameters
    ----------
    x1, x2 : ndarray, shape (P, N, 3)
        Normalized homogeneous points, N >= 8.

    Returns
    -------
    ndarray, shape (P, 3, 3)
        Unit Frobenius norm; no rank or singular-value constraint is imposed.
    """
    A = (x2[:, :, :, None] * x1[:, :, None, :]).reshape(x1.shape[0], x1.shape[1], 9)
    _, _, Vt = np.linalg.svd(A, full_matrices=False)
    return Vt[:, -1].reshape(-1, 3, 3)


def euler_zyx_deg(R: np.ndarray) -> np.ndarray:
    """Angles ``(gx, gy, gz)`` in degrees, ``R = Rz(gz) Ry(gy) Rx(gx)``; R shape (..., 3, 3)."""
    gy = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    gx = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    gz = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.degrees(np.stack([gx, gy, gz], axis=-1))


def rotation_discrepancy_deg(R_true: np.ndarray, R_est: np.ndarray) -> np.ndarray:
    """Eq. 80: one third of the L1 norm of the Euler angles of ``R_true^T R_est``, degrees."""
    error = np.swapaxes(R_true, -1, -2) @ R_est
    return np.abs(euler_zyx_deg(error)).sum(axis=-1) / 3.0


def translation_discrepancy_deg(t_true: np.ndarray, t_est: np.ndarray) -> np.ndarray:
    """Eq. 81: angle between the true and estimated translation, degrees; shapes (..., 3)."""
    return direction_error_deg(t_est, t_true)


def rmse(values: np.ndarray) -> float:
    """Root mean square of the finite entries (NaN when there are none)."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def _closer_rotation(E: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    cand = ppo.decompose_essential(E)
    d1 = rotation_discrepancy_deg(R_true, cand.R1)
    d2 = rotation_discrepancy_deg(R_true, cand.R2)
    return cand.R1 if d1 <= d2 else cand.R2


def _homogeneous(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pixel points (..., N, 2) to normalized homogeneous rays (..., N, 3)."""
    x = (points - K[:2, 2]) / np.array([K[0, 0], K[1, 1]])
    return np.concatenate([x, np.ones(x.shape[:-1] + (1,))], axis=-1)


def _errors_3d(P: np.ndarray, X: np.ndarray) -> tuple[float, float, int]:
    """Sum of squared errors, median error and count over the points where P is finite."""
    ok = np.isfinite(P).all(axis=1)
    d = np.linalg.norm(P[ok] - X[ok], axis=1)
    return float(np.sum(d**2)), float(np.median(d)) if d.size else float("nan"), int(ok.sum())


def simulate_cell(
    alpha: float,
    noise_px: float,
    depth: float = 30.0,
    n_poses: int = 40,
    n_mc: int = 3,
    n_points: int = 50,
    seed: int = 0,
    with_3d: bool = True,
) -> CellResult:
    """Solve every problem of one cell with PPO and with OpenCV's cheirality (see module doc)."""
    out: dict[str, list] = {
        k: [] for k in CellResult.__dataclass_fields__ if k not in ("alpha", "noise_px", "depth")
    }
    eye = np.eye(3)
    P1 = np.hstack([eye, np.zeros((3, 1))])
    for mc in range(n_mc):
        s = paper_protocol(n_poses, n_points, alpha, noise_px, depth=depth, seed=seed, mc_run=mc)
        X1 = _homogeneous(s.points1, s.K)
        X2 = _homogeneous(s.points2, s.K)
        Q = linear_essential(X1, X2)
        for i in range(n_poses):
            x1, x2, E, R_true, t_true = X1[i], X2[i], Q[i], s.R[i], s.t[i]
            sel = ppo.select_pose(E, x1, x2)
            n1, n2 = x1[:, :2], x2[:, :2]
            _, R_cv, t_cv, _ = cv2.recoverPose(E, n1, n2, eye)
            _, _, t_ch, _, _ = cv2.recoverPose(E, n1, n2, eye, distanceThresh=NO_DISTANCE_CUT)
            R_right = _closer_rotation(E, R_true)
            out["rot_ppo"].append(rotation_discrepancy_deg(R_true, sel.R))
            out["rot_cv"].append(rotation_discrepancy_deg(R_true, R_cv))
            out["t_ppo"].append(translation_discrepancy_deg(t_true, sel.t))
            out["t_cv"].append(translation_discrepancy_deg(t_true, t_cv.ravel()))
            out["t_cheir"].append(translation_discrepancy_deg(t_true, t_ch.ravel()))
            out["rot_right_ppo"].append(np.allclose(sel.R, R_right))
            out["rot_right_cv"].append(np.allclose(R_cv, R_right, atol=1e-9))
            out["pri"].append(ppo.pure_rotation_indicator(sel.m2))
            out["m3"].append(ppo.m3_indicator(x1, x2, sel.R))
            if with_3d:
                scale = np.linalg.norm(t_true)
                anal = ppo.analytic_points(x1, x2, sel.R, sel.t) * scale
                P2 = np.hstack([sel.R, sel.t.reshape(3, 1)])
                X4 = cv2.triangulatePoints(P1, P2, n1.T.copy(), n2.T.copy())
                with np.errstate(divide="ignore", invalid="ignore"):
                    dlt = (X4[:3] / X4[3]).T * scale
                sq_a, med_a, n_a = _errors_3d(anal, s.points3d[i])
                sq_d, med_d, n_d = _errors_3d(dlt, s.points3d[i])
                out["sq3d_anal"].append(sq_a)
                out["sq3d_dlt"].append(sq_d)
                out["med3d_anal"].append(med_a)
                out["med3d_dlt"].append(med_d)
                out["n3d"].append(min(n_a, n_d))
    arrays = {k: np.asarray(v) for k, v in out.items()}
    return CellResult(alpha=float(alpha), noise_px=float(noise_px), depth=float(depth), **arrays)
