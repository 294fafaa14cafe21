"""Small dense least-squares tools shared by the pose refinements.

The refinements of :mod:`ppo_cv.plane` (a pose on its homography) and :mod:`ppo_cv.refine` (a
pose on its essential matrix with a radial term) have a handful of parameters and many
residuals: Levenberg-Marquardt with forward-difference Jacobians, Huber weights, a basis of
the tangent plane of the unit sphere (for a unit translation or normal) and the rotation
increment ``exp([w]x)`` (for a rotation) are all they need; the rotation-only fit of
:mod:`ppo_cv.rotation` uses the increment too.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .checks import (
    MAX_WHOLE_NUMBER,
    as_finite_array,
    as_finite_rows,
    as_nonnegative,
    as_positive,
    as_real_array,
    as_rotation,
    as_vector3,
    as_whole_number,
    float_range_exponent,
    in_float_range,
    shown,
)

__all__ = [
    "MAX_INCREMENT",
    "cross_matrix",
    "cross_matrices",
    "forward_jacobian",
    "forward_jacobian_stacked",
    "gauss_newton_covariance",
    "huber_weights",
    "levenberg_marquardt",
    "levenberg_marquardt_batched",
    "levenberg_marquardt_stacked",
    "pose_increment",
    "rotation_increment",
    "rotation_increments",
    "row_chunks",
    "stack_by_chunks",
    "stacked_jacobian",
    "tangent_basis",
]


def tangent_basis(n: np.ndarray) -> np.ndarray:
    """Two unit vectors orthogonal to the unit vector ``n`` and to each other, shape (2, 3).

    ``n`` is three finite numbers, not all zero (ValueError or TypeError naming it: a zero
    ``n`` gave a basis of NaN, a 0-d array or two numbers an IndexError). An ``n`` of another
    norm is made unit first (its second row had that norm), scaled by a power of two when its
    entries lie beyond ``[1e-100, 1e100]``, where its norm would overflow or underflow."""
    n = as_vector3(n, "n")
    if not n.any():
        raise ValueError("n is zero: it has no tangent plane")
    n = in_float_range(n)
    norm = math.sqrt(n @ n)
    return _tangent_basis(n if abs(norm - 1.0) <= 1e-9 else n / norm)


def _tangent_basis(n: np.ndarray) -> np.ndarray:
    """:func:`tangent_basis` of a nonzero float64 ``n`` (3,), unchecked."""
    axis = np.eye(3)[int(np.argmin(np.abs(n)))]
    a = _cross(n, axis)
    a /= np.linalg.norm(a)
    return np.array([a, _cross(n, a)])


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u x v`` of two vectors (3,), as ``np.cross`` computes it without its axis handling."""
    return np.array(
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    )


def _as_callable(value, name: str):
    """``value``, a callable; TypeError naming ``name`` otherwise (None included)."""
    if not callable(value):
        raise TypeError(f"{name} must be a callable, got {type(value).__name__}")
    return value


def _as_start(p, ndim: int) -> np.ndarray:
    """The start ``p`` of a fit, finite float64 of ``ndim`` dimensions (one vector or a stack of
    them), the same object when it is one already; ValueError or TypeError naming it."""
    p = as_finite_array(p, "p")
    if p.ndim != ndim or p.size == 0:
        shape = "(P,)" if ndim == 1 else "(S, P)"
        raise ValueError(f"p must be parameters of shape {shape}, got {p.shape}")
    return p


def _as_iterations(iterations) -> int:
    return as_whole_number(iterations, "iterations", 0, MAX_WHOLE_NUMBER)


MAX_INCREMENT = 1e15
"""Largest entry of a rotation vector or pose increment taken by :func:`rotation_increment`,
:func:`rotation_increments` and :func:`pose_increment`: floats near 1e15 are an eighth of a
radian apart, so a larger angle names no rotation (and its square overflows near 1e154)."""


def _as_increment(w: np.ndarray, name: str) -> np.ndarray:
    """``w``, finite float64, unless an entry exceeds :data:`MAX_INCREMENT` (ValueError)."""
    largest = float(np.abs(w).max(initial=0.0))
    if largest > MAX_INCREMENT:
        raise ValueError(
            f"{name} has entries up to {shown(largest)}, beyond {MAX_INCREMENT:.0e}: an angle "
            "that large is not resolved (floats near it are radians apart)"
        )
    return w


def rotation_increment(w: np.ndarray) -> np.ndarray:
    """``exp([w]x)`` (3, 3): the rotation by ``|w|`` radians about ``w / |w|`` (Rodrigues), to
    first order ``I + [w]x`` below 1e-12 rad; the figures of :func:`rotation_increments`.
    ``w`` three finite numbers of magnitude at most :data:`MAX_INCREMENT`; ValueError or
    TypeError naming it otherwise."""
    return _rotation_increment(_as_increment(as_vector3(w, "w"), "w"))


def _rotation_increment(w: np.ndarray) -> np.ndarray:
    """:func:`rotation_increment`, unchecked."""
    w = np.asarray(w, dtype=np.float64)
    theta = np.sqrt(np.add.reduce(w * w))
    K = _cross_matrix(w)
    if theta < 1e-12:
        return np.eye(3) + K
    a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / (theta * theta)
    return np.eye(3) + a * K + b * (K @ K)


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """``[v]_x`` (3, 3) of one vector ``v`` (3,): ``[v]_x u = v x u``; ValueError or TypeError
    naming ``v`` for anything but three finite numbers."""
    return _cross_matrix(as_vector3(v, "v"))


def _cross_matrix(v: np.ndarray) -> np.ndarray:
    """:func:`cross_matrix`, unchecked."""
    v = np.asarray(v, dtype=np.float64).reshape(3)
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def cross_matrices(v: np.ndarray) -> np.ndarray:
    """``[v]_x`` (P, 3, 3) of each row of ``v`` (P, 3): ``[v]_x u = v x u``; ValueError or
    TypeError naming ``v`` for anything but finite rows of three."""
    return _cross_matrices(as_finite_rows(v, "v", 3))


def _cross_matrices(v: np.ndarray) -> np.ndarray:
    """:func:`cross_matrices`, unchecked."""
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    return K - np.swapaxes(K, 1, 2)


def rotation_increments(w: np.ndarray) -> np.ndarray:
    """:func:`rotation_increment` of each row of ``w`` (P, 3), shape (P, 3, 3); ValueError or
    TypeError naming ``w`` for anything but finite rows of three of magnitude at most
    :data:`MAX_INCREMENT`."""
    return _rotation_increments(_as_increment(as_finite_rows(w, "w", 3), "w"))


def _rotation_increments(w: np.ndarray) -> np.ndarray:
    """:func:`rotation_increments`, unchecked."""
    theta = np.linalg.norm(w, axis=1)[:, None, None]
    K = _cross_matrices(w)
    small = theta < 1e-12
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0, np.sin(safe) / safe)
    b = np.where(small, 0.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def pose_increment(
    R: np.ndarray, t: np.ndarray, p: np.ndarray, basis: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The pose ``(R, t)``, ``t`` a unit vector, moved by ``p`` (5,): the rotation increment
    ``p[:3]`` applied on the left and ``t`` stepped by ``p[3:5]`` in ``basis`` (2, 3) of its
    tangent plane (:func:`tangent_basis` of ``t`` when None), then normalised.

    ValueError or TypeError naming the argument unless ``R`` is a rotation, ``t`` three
    numbers of norm 1 (to 1e-6), ``p`` five finite numbers of magnitude at most
    :data:`MAX_INCREMENT` and ``basis`` None or two orthonormal rows orthogonal to ``t`` (to
    1e-6): a 0-d ``p`` raised an IndexError, a complex one a ComplexWarning.
    """
    R, t = as_rotation(R, "R"), as_vector3(t, "t")
    if np.abs(t).max() > 2.0 or abs(math.sqrt(t @ t) - 1.0) > 1e-6:
        raise ValueError(f"t must be a unit vector, got {t.tolist()}")
    p = as_finite_array(p, "p")
    if p.shape != (5,):
        raise ValueError(f"p must be 5 numbers (rotation increment, step of t), got {p.shape}")
    basis = None if basis is None else _as_basis(basis, t)
    return _pose_increment(R, t, _as_increment(p, "p"), basis)


def _as_basis(basis, t: np.ndarray) -> np.ndarray:
    """``basis``, two orthonormal rows (2, 3) orthogonal to the unit ``t``, as float64."""
    basis = as_finite_array(basis, "basis")
    if basis.shape != (2, 3):
        raise ValueError(f"basis must have shape (2, 3), got {basis.shape}")
    frame = np.vstack([t, basis])
    if np.abs(basis).max() > 2.0 or not np.allclose(frame @ frame.T, np.eye(3), atol=1e-6):
        raise ValueError(
            "basis must be two orthonormal rows orthogonal to t (tangent_basis(t) gives them)"
        )
    return basis


def _pose_increment(
    R: np.ndarray, t: np.ndarray, p: np.ndarray, basis: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pose_increment`, unchecked (``p`` may hold more than five entries)."""
    basis = _tangent_basis(t) if basis is None else basis
    tp = t + p[3:5] @ basis
    return _rotation_increment(p[:3]) @ R, tp / np.linalg.norm(tp)


def _pose_increments(
    R: np.ndarray, t: np.ndarray, P: np.ndarray, basis: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pose_increment` of each row of ``P`` (K, 5): rotations (K, 3, 3) and unit
    translations (K, 3), unchecked."""
    tp = t + P[:, 3:5] @ basis
    return _rotation_increments(P[:, :3]) @ R, tp / np.linalg.norm(tp, axis=1, keepdims=True)


_HUBER_RANGE = 1e150
"""Largest ``scale`` and finite size :func:`_huber_weights` takes: ``2 scale s`` and
``scale^2`` overflow beyond."""


def huber_weights(size: np.ndarray, scale: float) -> np.ndarray:
    """``sqrt(rho(s)) / s`` for residual sizes ``s`` (N,): the weighted squares sum to Huber's
    cost ``rho(s) = s^2`` up to ``scale`` and ``2 scale s - scale^2`` beyond. ``size`` numbers
    >= 0 (inf of weight 0), ``scale`` a finite number > 0; ValueError or TypeError naming the
    argument otherwise. Sizes or a scale beyond 1e150, whose products overflow, are weighed
    as ``sqrt(q (2 - q))``, ``q = scale / s``, the same weights."""
    size = as_real_array(size, "size")
    if size.ndim != 1 or np.isnan(size).any():
        raise ValueError(f"size must be residual sizes (N,) without NaN, got {size.shape}")
    if size.size and size.min() < 0:
        raise ValueError(f"size must be residual sizes >= 0 (|r|), got {shown(size.min())}")
    scale = as_positive(scale, "scale")
    if max(scale, float(size.max(initial=0.0))) <= _HUBER_RANGE:
        return _huber_weights(size, scale)
    q = np.divide(scale, size, out=np.ones_like(size), where=size > scale)
    return np.sqrt(q * (2.0 - q))


def _huber_weights(size: np.ndarray, scale: float) -> np.ndarray:
    """:func:`huber_weights`, unchecked."""
    size = np.maximum(size, 1e-300)
    beyond = np.sqrt(np.maximum(2 * scale * size - scale**2, 0)) / size
    return np.where(size <= scale, 1.0, beyond)


CHUNK_VALUES = 12_000
"""Values per chunk of a stacked evaluation cut by :func:`row_chunks`: each of its temporaries
(about 100 KB) then stays in the core's cache, where those of a whole stack of a few hundred
matches' residuals for 96 parameter rows (450 KB each) do not."""


def row_chunks(count: int, width: int) -> list[slice]:
    """Slices that cut ``count`` stacked rows of ``width`` values each into chunks of about
    :data:`CHUNK_VALUES` values, at least one row each."""
    count = as_whole_number(count, "count", 0, MAX_WHOLE_NUMBER)
    width = as_whole_number(width, "width", 0, MAX_WHOLE_NUMBER)
    size = max(1, CHUNK_VALUES // max(width, 1))
    return [slice(start, start + size) for start in range(0, count, size)]


def stack_by_chunks(evaluate: Callable[[slice], np.ndarray], count: int, width: int) -> np.ndarray:
    """``evaluate(s)`` of each slice ``s`` of :func:`row_chunks` ``(count, width)``, stacked
    along the first axis: a stacked evaluation of ``count`` rows (at least 1) computed chunk by
    chunk; ValueError or TypeError naming an argument of another kind."""
    evaluate = _as_callable(evaluate, "evaluate")
    parts = [evaluate(rows) for rows in row_chunks(count, width)]
    if not parts:
        raise ValueError("count must be at least 1: no rows to evaluate")
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _as_residuals(r0) -> np.ndarray:
    """Residuals ``r0`` (M,), finite float64; ValueError or TypeError naming it otherwise."""
    r0 = as_finite_array(r0, "r0")
    if r0.ndim != 1:
        raise ValueError(f"r0 must be residuals of shape (M,), got {r0.shape}")
    return r0


def forward_jacobian(
    f: Callable[[np.ndarray], np.ndarray], p: np.ndarray, r0: np.ndarray, step: float = 1e-7
) -> np.ndarray:
    """Jacobian (M, P) of ``f`` at ``p`` (P,) by forward differences, ``r0 = f(p)`` (M,);
    ValueError or TypeError naming an argument of another kind or shape, or a ``step`` not a
    finite number > 0."""
    f, p, r0 = _as_callable(f, "f"), _as_start(p, 1), _as_residuals(r0)
    return _forward_jacobian(f, p, r0, as_positive(step, "step"))


def _forward_jacobian(f, p: np.ndarray, r0: np.ndarray, step: float = 1e-7) -> np.ndarray:
    """:func:`forward_jacobian`, unchecked."""
    return np.column_stack([(f(p + step * e) - r0) / step for e in np.eye(len(p))])


def levenberg_marquardt_batched(
    many: Callable[[np.ndarray, np.ndarray], np.ndarray],
    p: np.ndarray,
    iterations: int,
    step: float = 1e-7,
) -> np.ndarray:
    """:func:`levenberg_marquardt` of several independent problems of the same shape at once.

    ``many(P, rows)`` gives the residuals (K, M) of the parameter vectors ``P`` (K, P), row
    ``k`` one of problem ``rows[k]``; ``p`` (S, P) are the starts of the S problems. Each
    problem takes the steps, damping and stops it would take alone, up to the rounding of
    the stacked products. Returns the minimisers (S, P). ValueError or TypeError naming an
    argument of another kind or shape.
    """
    many, p = _as_callable(many, "many"), _as_start(p, 2)
    step = as_positive(step, "step")
    iterations = _as_iterations(iterations)
    r0 = _start_residuals(many(p, np.arange(len(p))), "many", 2)
    return _levenberg_marquardt_batched(many, p, iterations, step, r0)


def _start_residuals(r, name: str, ndim: int = 1) -> np.ndarray:
    """The residuals ``r`` of a fit at its start, given by ``name``: finite float64 of ``ndim``
    dimensions whose squares sum to a finite cost; ValueError naming ``name`` otherwise."""
    r = as_finite_array(r, f"{name}(p)")
    if r.ndim != ndim:
        raise ValueError(f"{name}(p) must be residuals of {ndim} dimension(s), got {r.shape}")
    with np.errstate(over="ignore"):
        cost = np.sum(r * r)
    if not np.isfinite(cost):
        raise ValueError(
            f"{name}(p) has residuals up to {float(np.abs(r).max()):.3g} at the start p: "
            "their squares overflow"
        )
    return r


def _levenberg_marquardt_batched(
    many, p, iterations: int, step: float = 1e-7, r0: np.ndarray | None = None
) -> np.ndarray:
    """:func:`levenberg_marquardt_batched`, unchecked (``r0`` the residuals at ``p`` when
    known)."""
    p = np.array(p, dtype=np.float64)
    every = np.arange(len(p))
    r0 = many(p, every) if r0 is None else np.array(r0, dtype=np.float64)
    J = _batched_jacobians(many, p, r0, every, step)
    damping = np.full(len(p), 1e-3)
    active = np.ones(len(p), dtype=bool)
    for _ in range(iterations):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        moved, delta = _batched_damped_step(many, p, r0, J[rows], rows, damping)
        active[rows[~moved]] = False
        done = rows[moved]
        if done.size:
            J[done] = _batched_jacobians(many, p[done], r0[done], done, step)
        active[done[np.linalg.norm(delta[moved], axis=1) < 1e-10]] = False
    return p


def _batched_damped_step(many, p, r0, J, rows, damping) -> tuple[np.ndarray, np.ndarray]:
    """One iteration of :func:`_damped_steps` for the problems ``rows`` with Jacobians ``J``
    (k, M, P), up to 8 increases of each one's damping; ``p``, ``r0`` and ``damping`` are
    updated in place. Returns which problems moved and their steps (k, P)."""
    A = np.swapaxes(J, 1, 2) @ J
    g = np.einsum("kmp,km->kp", J, r0[rows])
    ridge = (np.diagonal(A, axis1=1, axis2=2) + 1e-12)[:, :, None] * np.eye(A.shape[1])
    pending = np.ones(len(rows), dtype=bool)
    delta = np.zeros((len(rows), p.shape[1]))
    for _ in range(8):
        k = np.flatnonzero(pending)
        if k.size == 0:
            break
        system = A[k] + damping[rows[k], None, None] * ridge[k]
        delta[k] = -np.linalg.solve(system, g[k][:, :, None])[:, :, 0]
        trial = many(p[rows[k]] + delta[k], rows[k])
        better = np.sum(trial * trial, axis=1) < np.sum(r0[rows[k]] ** 2, axis=1)
        kept, worse = rows[k[better]], rows[k[~better]]
        p[kept] += delta[k[better]]
        r0[kept] = trial[better]
        damping[kept] = np.maximum(damping[kept] / 10, 1e-9)
        damping[worse] *= 10
        pending[k[better]] = False
    return ~pending, delta


def _batched_jacobians(many, p: np.ndarray, r0: np.ndarray, rows: np.ndarray, step: float):
    """Forward-difference Jacobians (k, M, P) of the problems ``rows`` at ``p`` (k, P)."""
    size = p.shape[1]
    stepped = (p[:, None, :] + step * np.eye(size)).reshape(-1, size)
    r = many(stepped, np.repeat(rows, size)).reshape(len(p), size, -1)
    return np.swapaxes((r - r0[:, None, :]) / step, 1, 2)


def forward_jacobian_stacked(
    many: Callable[[np.ndarray], np.ndarray], p: np.ndarray, r0: np.ndarray, step: float = 1e-7
) -> np.ndarray:
    """:func:`forward_jacobian` (M, P) of a stacked ``f`` (``many``: (K, P) -> (K, M)) in one
    call of it, ``r0 = f(p)``: :func:`stacked_jacobian` with the residuals at ``p`` known,
    laid out in memory as :func:`forward_jacobian`'s, so that the products of the steps that
    use it are the same to the bit. ValueError or TypeError as :func:`forward_jacobian`."""
    many, p, r0 = _as_callable(many, "many"), _as_start(p, 1), _as_residuals(r0)
    return _forward_jacobian_stacked(many, p, r0, as_positive(step, "step"))


def _forward_jacobian_stacked(many, p: np.ndarray, r0: np.ndarray, step: float = 1e-7):
    """:func:`forward_jacobian_stacked`, unchecked."""
    return np.ascontiguousarray(_stacked_jacobian(many, p, step, r0)[1])


def gauss_newton_covariance(J: np.ndarray, variance: float) -> np.ndarray | None:
    """Covariance ``variance (J^T J)^-1`` (P, P) of the parameters of a least-squares fit with
    Jacobian ``J`` (M, P) at its minimum; None when ``J^T J`` is singular or the covariance
    beyond the range of a float. A ``J`` of entries beyond ``[1e-100, 1e100]`` is scaled by a
    power of two (exactly) first, so that ``J^T J`` does not overflow. ValueError or TypeError
    naming the argument for ``J`` not finite (M, P) or ``variance`` not >= 0."""
    J = as_finite_array(J, "J")
    if J.ndim != 2:
        raise ValueError(f"J must be a Jacobian of shape (M, P), got {J.shape}")
    variance = as_nonnegative(variance, "variance")
    shift = float_range_exponent(J)
    with np.errstate(over="ignore"):
        covariance = _gauss_newton_covariance(np.ldexp(J, -shift), variance)
        if covariance is not None:
            covariance = np.ldexp(covariance, -2 * shift)
    return covariance if covariance is None or np.isfinite(covariance).all() else None


def _gauss_newton_covariance(J: np.ndarray, variance: float) -> np.ndarray | None:
    """:func:`gauss_newton_covariance`, unchecked."""
    try:
        return variance * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        return None


def stacked_jacobian(
    f: Callable[[np.ndarray], np.ndarray],
    p: np.ndarray,
    step: float = 1e-7,
    r0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals (M,) at ``p`` (P,) and their forward-difference Jacobian (M, P) in one call of
    ``f``, which maps a stack of parameter vectors (K, P) to a stack of residuals (K, M).

    ``r0``, the residuals at ``p`` when already known, leaves ``p`` out of the call. The
    Jacobian is the transposed view of the differences (Fortran order). ValueError or
    TypeError naming an argument of another kind or shape, or a ``step`` not a finite
    number > 0.
    """
    f, p, step = _as_callable(f, "f"), _as_start(p, 1), as_positive(step, "step")
    return _stacked_jacobian(f, p, step, None if r0 is None else _as_residuals(r0))


def _stacked_jacobian(f, p: np.ndarray, step: float = 1e-7, r0=None):
    """:func:`stacked_jacobian`, unchecked."""
    steps = step * np.eye(len(p))
    if r0 is None:
        r = f(p + np.vstack([np.zeros(len(p)), steps]))
        r0, stepped = r[0], r[1:]
    else:
        stepped = f(p + steps)
    return r0, ((stepped - r0) / step).T


def levenberg_marquardt(
    f: Callable[[np.ndarray], np.ndarray],
    p: np.ndarray,
    iterations: int,
    many: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Minimise ``f(p) @ f(p)`` by Levenberg-Marquardt with forward-difference Jacobians.

    Returns the minimiser and the Jacobian there. A step is taken only when it lowers the cost
    (up to 8 increases of the damping per iteration); the loop stops when none does, when the
    step is below 1e-10 or after ``iterations`` steps. ``many``, when given, is ``f`` of a
    stack of parameter vectors (K, P) -> (K, M): each Jacobian is then one call of it
    (:func:`forward_jacobian_stacked`), the same figures when its rows are ``f``'s.
    ValueError or TypeError naming an argument of another kind or shape.
    """
    f, p, iterations = _as_callable(f, "f"), _as_start(p, 1), _as_iterations(iterations)
    many = None if many is None else _as_callable(many, "many")
    return _levenberg_marquardt(f, p, iterations, many, _start_residuals(f(p), "f"))


def _levenberg_marquardt(
    f, p, iterations: int, many=None, r0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`levenberg_marquardt`, unchecked (``r0`` the residuals at ``p`` when known)."""
    if many is None:
        jacobian = lambda q, r: _forward_jacobian(f, q, r)  # noqa: E731
    else:
        jacobian = lambda q, r: _forward_jacobian_stacked(many, q, r)  # noqa: E731
    r0 = f(p) if r0 is None else r0
    p, _, J = _damped_steps(lambda q: (f(q), None), jacobian, p, r0, jacobian(p, r0), iterations)
    return p, J


def levenberg_marquardt_stacked(
    f: Callable[[np.ndarray], np.ndarray], p: np.ndarray, iterations: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`levenberg_marquardt` (its steps, damping and stops) of a stacked ``f``
    (:func:`stacked_jacobian`): each trial is evaluated with the Jacobian at it, one call per
    trial. Returns the minimiser and the residuals there; ValueError or TypeError naming an
    argument of another kind or shape."""
    f, p, iterations = _as_callable(f, "f"), _as_start(p, 1), _as_iterations(iterations)
    r0, J = _stacked_jacobian(f, p)
    return _levenberg_marquardt_stacked(f, p, iterations, (_start_residuals(r0, "f"), J))


def _levenberg_marquardt_stacked(
    f, p, iterations: int, start=None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`levenberg_marquardt_stacked`, unchecked (``start`` the residuals at ``p`` and
    their Jacobian when known)."""
    r0, J = _stacked_jacobian(f, p) if start is None else start
    p, r0, _ = _damped_steps(lambda q: _stacked_jacobian(f, q), None, p, r0, J, iterations)
    return p, r0


def _damped_steps(trial_at, jacobian_at, p, r0, J, iterations: int) -> tuple:
    """The damped Gauss-Newton loop of :func:`levenberg_marquardt`: ``trial_at(q)`` gives the
    residuals at a trial and the Jacobian there or None, ``jacobian_at(q, r)`` the Jacobian
    of an accepted trial that came without one. Returns ``(p, r0, J)``."""
    damping = 1e-3
    for _ in range(iterations):
        A, g = J.T @ J, J.T @ r0
        for _ in range(8):
            delta = -np.linalg.solve(A + damping * np.diag(np.diag(A) + 1e-12), g)
            trial, trial_J = trial_at(p + delta)
            if trial @ trial < r0 @ r0:
                p, r0, J, damping = p + delta, trial, trial_J, max(damping / 10, 1e-9)
                break
            damping *= 10
        else:
            break
        if J is None:
            J = jacobian_at(p, r0)
        if np.linalg.norm(delta) < 1e-10:
            break
    return p, r0, J
