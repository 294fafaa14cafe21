"""Other minima of a general pose along its bas-relief valley.

In a narrow field with a small baseline a sideways translation and a pan are nearly the same
flow: the Sampson cost of the essential matrix has a long, nearly flat valley in which the
direction of ``t`` and the rotation move together. A refinement that placed its epipole on
false matches (:func:`ppo_cv.refine.checked_inliers` leaves them out) can sit in that valley
tens of degrees of ``t`` away from where the other matches put the pose, its covariance blind
to the rest of the valley. :func:`valley_minima` walks the valley from the refined pose along
the worst direction of ``t`` on both sides (the rotation re-fitted at each step), polishes the
lowest step of each side when it is a local minimum and returns these minima with their cost
against the start's in units of the residuals' variance. :func:`valley_outcome` takes a minimum
significantly lower than the start as the pose, and the farthest rotation among the minima not
significantly worse than the pose as a spread of the rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import as_positive, as_rotation, as_vector3, require_instance, require_pose_matches
from .lsq import (
    _cross_matrices,
    _cross_matrix,
    _huber_weights,
    _levenberg_marquardt_stacked,
    _pose_increment,
    _rotation_increment,
    _rotation_increments,
    stacked_jacobian,
    tangent_basis,
)
from .metrics import rotation_error_deg
from .plane import K1_SIGNIFICANCE
from .robust import _sampson_signed_rows

__all__ = [
    "VALLEY_STEPS_DEG",
    "VALLEY_SIGNIFICANCE",
    "ValleyMinimum",
    "ValleyOutcome",
    "valley_minima",
    "valley_outcome",
]

VALLEY_STEPS_DEG = np.arange(10.0, 91.0, 10.0)
"""Angles of ``t`` from the refined direction at which the valley's profile is read, on each
side (degrees): the valley of a narrow field spans tens of degrees of ``t``, and the direction
of ``t`` is known up to its sign, so 90 degrees covers it."""

VALLEY_SIGNIFICANCE = K1_SIGNIFICANCE**2
"""A minimum whose cost exceeds the lowest by less than this many residual variances (three
deviations, as for the radial term) is not significantly worse: its rotation's distance
enters the rotation's deviation."""


@dataclass(frozen=True)
class ValleyMinimum:
    """A minimum of the Sampson cost along the valley.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Unit norm.
    excess : float
        Its cost less the start's, in variances of one residual at the start (negative: lower).
    """

    R: np.ndarray
    t: np.ndarray
    excess: float


@dataclass(frozen=True)
class ValleyOutcome:
    """The pose to return and the spread of the rotation over the valley's minima.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        The pose of :func:`valley_outcome`.
    spread_deg : float
        Largest angle between ``R`` and the rotation of a minimum whose cost is within
        :data:`VALLEY_SIGNIFICANCE` variances of the lowest; 0 when there is none.
    """

    R: np.ndarray
    t: np.ndarray
    spread_deg: float


def _cost(x1: np.ndarray, x2: np.ndarray, scale: float):
    """Huber-weighted Sampson residuals of the essential matrix ``E`` (3, 3), or of each of
    a stack (K, 3, 3), the points taken by coordinate (:func:`sampson_signed_rows`)."""
    X1, X2 = np.ascontiguousarray(x1.T), np.ascontiguousarray(x2.T)

    def residuals(E: np.ndarray) -> np.ndarray:
        r = _sampson_signed_rows(E, X1, X2)
        return _huber_weights(np.abs(r), scale) * r

    return residuals


def _pose_costs(cost, R: np.ndarray, t: np.ndarray, basis: np.ndarray):
    """The residuals (K, N) of the poses ``p`` (K, 5) about ``(R, t)``: rotation increment,
    then ``t`` moved in ``basis``."""

    def residuals(p: np.ndarray) -> np.ndarray:
        tp = t + p[:, 3:5] @ basis
        tp = tp / np.linalg.norm(tp, axis=1, keepdims=True)
        return cost(_cross_matrices(tp) @ (_rotation_increments(p[:, :3]) @ R))

    return residuals


def _rotation_costs(cost, R: np.ndarray, cross_t: np.ndarray):
    """The residuals (K, N) of the rotation increments ``q`` (K, 3) of ``R``, ``t`` held
    (``cross_t``)."""

    def residuals(q: np.ndarray) -> np.ndarray:
        return cost(cross_t @ (_rotation_increments(q) @ R))

    return residuals


def _polish(cost, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    basis = tangent_basis(t)
    p, _ = _levenberg_marquardt_stacked(_pose_costs(cost, R, t, basis), np.zeros(5), 20)
    return _pose_increment(R, t, p, basis)


def _worst_direction(cost, R: np.ndarray, t: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """Unit tangent of the sphere at ``t`` along which ``t`` is least determined."""
    basis = tangent_basis(t)
    residuals = _pose_costs(cost, R, t, basis)
    _, J = stacked_jacobian(residuals, np.zeros(5), step)
    covariance = np.linalg.pinv(J.T @ J)
    _, vectors = np.linalg.eigh(covariance[3:5, 3:5])
    u = vectors[:, -1] @ basis
    return u / np.linalg.norm(u)


def _profile(cost, R: np.ndarray, t: np.ndarray, u: np.ndarray) -> list[tuple]:
    """Cost and pose at each step of :data:`VALLEY_STEPS_DEG` along ``u`` (one side), the
    rotation re-fitted from the previous step's."""
    steps = []
    for angle in np.radians(VALLEY_STEPS_DEG):
        ti = np.cos(angle) * t + np.sin(angle) * u
        costs = _rotation_costs(cost, R, _cross_matrix(ti))
        w, r = _levenberg_marquardt_stacked(costs, np.zeros(3), 4)
        R = _rotation_increment(w) @ R
        steps.append((float(r @ r), R, ti))
    return steps


def valley_minima(
    R: np.ndarray, t: np.ndarray, x1: np.ndarray, x2: np.ndarray, scale: float
) -> list[ValleyMinimum]:
    """Minima of the Huber-weighted Sampson cost along the valley of ``t``'s worst direction.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        Refined pose, ``X2 = R X1 + t``, at a minimum of the cost.
    x1, x2 : ndarray, shape (N, 3)
        Normalised homogeneous coordinates of the matches of the cost (undistorted, checked).
    scale : float
        Huber bound, normalised units.

    Returns
    -------
    list of ValleyMinimum
        On each side, the profile's lowest step polished when it is a local minimum away
        from the start (at most two); empty with fewer than 12 matches.
    """
    t = require_pose_matches(R, t, x1, x2)
    scale = as_positive(scale, "scale")
    R = np.asarray(R, dtype=np.float64)
    t = t / np.linalg.norm(t)
    if len(x1) < 12:
        return []
    cost = _cost(np.asarray(x1, float), np.asarray(x2, float), scale)
    r0 = cost(_cross_matrix(t) @ R)
    start, variance = float(r0 @ r0), float(r0 @ r0) / max(len(r0) - 5, 1)
    u = _worst_direction(cost, R, t)
    minima = []
    for side in (u, -u):
        profile = [(start, R, t)] + _profile(cost, R, t, side)
        lowest = 1 + int(np.argmin([value for value, _, _ in profile[1:]]))
        if lowest < len(profile) - 1 and profile[lowest][0] > profile[lowest - 1][0]:
            continue
        Rm, tm = _polish(cost, *profile[lowest][1:])
        r = cost(_cross_matrix(tm) @ Rm)
        minima.append(ValleyMinimum(Rm, tm, (float(r @ r) - start) / variance))
    return minima


def valley_outcome(R: np.ndarray, t: np.ndarray, minima: list[ValleyMinimum]) -> ValleyOutcome:
    """The pose: the lowest of ``minima`` when its cost is below the start's ``(R, t)``
    (excess 0) by more than :data:`VALLEY_SIGNIFICANCE`, else the start; and the spread of the
    rotations of the minima within :data:`VALLEY_SIGNIFICANCE` of the pose's cost."""
    R, t = as_rotation(R, "R"), as_vector3(t, "t")
    if not isinstance(minima, (list, tuple)):
        raise TypeError(f"minima must be a list of ValleyMinimum, got {type(minima).__name__}")
    for minimum in minima:
        require_instance(minimum, ValleyMinimum, "each of minima", " (valley_minima)")
    candidates = [ValleyMinimum(R, t, 0.0), *minima]
    lowest = min(candidates, key=lambda m: m.excess)
    chosen = lowest if lowest.excess < -VALLEY_SIGNIFICANCE else candidates[0]
    near = [m for m in candidates if m.excess - chosen.excess < VALLEY_SIGNIFICANCE]
    spread = max(float(rotation_error_deg(m.R, chosen.R)) for m in near)
    return ValleyOutcome(chosen.R, chosen.t, spread)
