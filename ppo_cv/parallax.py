"""How far from a rotation a homography is: the baseline over the distance of its plane.

A plane ``n^T X1 = d`` seen from two centres ``t`` apart maps normalised points by
``Hn = R + t n^T / d = R (I + u n^T)`` with ``u = R^T t / d``, the baseline in camera 1 over
the plane's distance (:mod:`ppo_cv.plane`). A rotation has three equal singular values.
``I + u n^T`` with ``u`` across ``n`` has ``(sqrt(1 + tau^2 / 4) + tau / 2, 1,
sqrt(1 + tau^2 / 4) - tau / 2)``, ``tau = |u|``; with ``u`` along ``n`` it has
``(1 + tau, 1, 1)``, which is also what a change of focal length between the views makes
(``diag(r, r, 1) R``), so the images cannot tell a move toward the plane from a zoom. Hence

``parallax = 2 min(ln(s1 / s2), ln(s2 / s3)) = 2 asinh(tau / 2) = tau + O(tau^3)``

for a motion along the plane, less for an oblique one, and zero for a rotation with or without a
zoom. A sideways translation before a wall is the hard case of a narrow field of view: to first
order in the field it moves every point alike, as a rotation does, and only the second-order
terms (``tau x^2``, ``tau x y`` in normalised units) tell the two apart; on tracks located to a
few hundredths of a pixel (:mod:`ppo_cv.photometric`) they are plain (``docs/pure_rotation.md``).

:func:`fit_plane_parallax` fits the homography to such tracks (the direct linear transform on
normalised coordinates, Hartley 1997, then Gauss-Newton on the transfer error) and gives the
parallax with its standard deviation from the fit's covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import as_finite_array, as_finite_rows, as_matrix3, as_positive, shown
from .lsq import _forward_jacobian, _gauss_newton_covariance, _levenberg_marquardt
from .model_selection import robust_sigma

__all__ = [
    "PlaneParallax",
    "focal_conjugates",
    "fit_plane_parallax",
    "homography_parallax",
    "nearest_rotation_log_scale",
    "rotation_spread",
]

_MIN_POINTS = 8
_ITERATIONS = 5


@dataclass(frozen=True)
class PlaneParallax:
    """Homography fitted to precise point pairs and the parallax of its plane.

    Attributes
    ----------
    H : ndarray, shape (3, 3)
        ``x2 ~ H x1`` on the normalised points, ``det H = 1``.
    parallax : float
        :func:`homography_parallax` of ``H``: about the baseline over the plane's distance.
    sigma : float
        Its standard deviation under the noise the fit was given (inf when the fit is
        singular).
    residuals : ndarray, shape (N,)
        Transfer error of each pair in view 2, normalised units.
    """

    H: np.ndarray
    parallax: float
    sigma: float
    residuals: np.ndarray


def homography_parallax(H: np.ndarray) -> float:
    """``2 min(ln(s1 / s2), ln(s2 / s3))`` of the singular values of ``H`` (3, 3): zero for a
    rotation, with or without a change of focal length, about ``|t| / d`` for
    ``R + t n^T / d`` with ``t`` along the plane (see the module docstring).

    >>> import numpy as np
    >>> H = np.eye(3) + np.outer([0.02, 0.0, 0.0], [0.0, 0.0, 1.0])
    >>> round(homography_parallax(H), 4)
    0.02
    """
    return _homography_parallax(as_matrix3(H, "H"))


def _homography_parallax(H: np.ndarray) -> float:
    s = np.linalg.svd(np.asarray(H, dtype=np.float64), compute_uv=False)
    if not s[2] > 0:
        return float("inf")
    return float(2.0 * min(np.log(s[0] / s[1]), np.log(s[1] / s[2])))


def focal_conjugates(H: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    """``S^-1 H S`` (K, 3, 3) of a homography ``H`` (3, 3) for each ``S = diag(s, s, 1)``,
    ``s = exp(log_scales)`` (K,): ``H`` on points normalised with a focal length ``s`` times
    the one that normalised them."""
    return _focal_conjugates(as_matrix3(H, "H"), _checked_log_scales(log_scales))


_MAX_LOG_SCALE = 50.0
"""Largest ``|log_scales|`` of :func:`focal_conjugates` and its callers: a focal scale beyond
``e^50`` (5e21) is no camera's, and ``exp`` overflows past 709."""


def _checked_log_scales(log_scales: np.ndarray) -> np.ndarray:
    """One or more finite log focal scales in ascending order, at most :data:`_MAX_LOG_SCALE`."""
    scales = as_finite_array(log_scales, "log_scales")
    if scales.ndim != 1 or not scales.size:
        raise ValueError(f"log_scales must be a sequence of numbers, got shape {scales.shape}")
    if np.abs(scales).max() > _MAX_LOG_SCALE or (np.diff(scales) < 0).any():
        raise ValueError(
            f"log_scales must ascend within +-{_MAX_LOG_SCALE:g}, got {shown(scales.tolist())}"
        )
    return scales


def _focal_conjugates(H: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    s = np.exp(np.asarray(log_scales, dtype=np.float64))[:, None]
    ones = np.ones_like(s)
    rows = np.hstack([1.0 / s, 1.0 / s, ones])
    columns = np.hstack([s, s, ones])
    return np.asarray(H, dtype=np.float64)[None] * rows[:, :, None] * columns[:, None, :]


_ZOOM_POINTS = 33
_ZOOM_ROUNDS = 4
"""Refinement of :func:`nearest_rotation_log_scale`: four grids of 33 scales narrow the
neighbours of the coarse grid's best by 16 each, to 1/131,072 of their span between samples
(``rotation_choice``'s grid of 61 over a factor of 4: 3.5e-7 in log scale), in four calls of
:func:`rotation_spread`; a scalar search from ``scipy.optimize`` did it to 1e-5, but importing
that package cost each process 0.4 s of CPU."""


def rotation_spread(H: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    """``log(sigma_1 / sigma_3)`` of ``S^-1 H S`` for each ``S = diag(s, s, 1)``
    (:func:`focal_conjugates`): 0 where it is a rotation times a scalar.

    >>> c, s = np.cos(0.2), np.sin(0.2)
    >>> S = np.diag([0.8, 0.8, 1.0])
    >>> H = S @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.linalg.inv(S)
    >>> np.round(rotation_spread(H, np.log([0.8, 1.0])), 4)
    array([0.    , 0.0894])
    """
    return _rotation_spread(as_matrix3(H, "H"), _checked_log_scales(log_scales))


def _rotation_spread(H: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    singular = np.linalg.svd(_focal_conjugates(H, log_scales), compute_uv=False)
    with np.errstate(divide="ignore"):
        return np.log(singular[:, 0] / singular[:, 2])


def nearest_rotation_log_scale(H: np.ndarray, log_scales: np.ndarray) -> tuple[float, float, bool]:
    """The log focal scale that makes ``S^-1 H S`` nearest a rotation (:func:`rotation_spread`):
    the best of the sorted grid ``log_scales`` (K,), refined between its neighbours by
    :data:`_ZOOM_ROUNDS` grids of :data:`_ZOOM_POINTS` scales, each spanning the neighbours of
    the previous one's best (Hartley and Zisserman, 8.8 and 19.3).

    Returns
    -------
    log_scale : float
    grid_spread : float
        The spread at the grid's best.
    interior : bool
        Whether the grid's best lies inside the grid, not on one of its ends (where no scale in
        the range makes ``H`` a rotation).
    """
    H, log_scales = as_matrix3(H, "H"), _checked_log_scales(log_scales)
    spreads = _rotation_spread(H, log_scales)
    best = int(np.argmin(spreads))
    last = len(log_scales) - 1
    low, high = log_scales[max(best - 1, 0)], log_scales[min(best + 1, last)]
    for _ in range(_ZOOM_ROUNDS):
        scales = np.linspace(low, high, _ZOOM_POINTS)
        nearest = int(np.argmin(_rotation_spread(H, scales)))
        low, high = scales[max(nearest - 1, 0)], scales[min(nearest + 1, _ZOOM_POINTS - 1)]
    return float(scales[nearest]), float(spreads[best]), 0 < best < last


def _conditioner(xy: np.ndarray) -> np.ndarray:
    """Similarity (3, 3) moving ``xy`` (N, 2) to zero mean and mean distance ``sqrt(2)``."""
    centre = xy.mean(axis=0)
    spread = np.mean(np.linalg.norm(xy - centre, axis=1))
    s = np.sqrt(2.0) / max(spread, 1e-300)
    return np.array([[s, 0.0, -s * centre[0]], [0.0, s, -s * centre[1]], [0.0, 0.0, 1.0]])


def _direct_linear(xy1: np.ndarray, xy2: np.ndarray) -> np.ndarray:
    """Least-squares homography of the direct linear transform on conditioned points."""
    T1, T2 = _conditioner(xy1), _conditioner(xy2)
    a = np.column_stack([xy1, np.ones(len(xy1))]) @ T1.T
    b = np.column_stack([xy2, np.ones(len(xy2))]) @ T2.T
    A = np.zeros((2 * len(a), 9))
    A[0::2, 0:3], A[0::2, 6:9] = a, -b[:, :1] * a
    A[1::2, 3:6], A[1::2, 6:9] = a, -b[:, 1:2] * a
    H = np.linalg.svd(A, full_matrices=False)[2][-1].reshape(3, 3)
    return np.linalg.inv(T2) @ H @ T1


def _unit_determinant(H: np.ndarray) -> np.ndarray:
    return H / np.cbrt(np.linalg.det(H))


def _transfer(H: np.ndarray, xy1: np.ndarray, xy2: np.ndarray) -> np.ndarray:
    """Transfer error vectors (..., N, 2) of ``xy1`` through ``H`` (3, 3) or each of a stack
    (K, 3, 3) against ``xy2``."""
    h = xy1 @ np.swapaxes(H[..., :2], -1, -2) + H[..., None, :, 2]
    z = np.where(np.abs(h[..., 2:]) > 1e-12, h[..., 2:], 1e-12)
    return h[..., :2] / z - xy2


def _perturbed(H0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``H0 (I + P)`` with the 8 entries of ``P`` other than the last given by ``p`` (8,), or
    each of a stack for ``p`` (K, 8)."""
    P = np.concatenate([p, np.zeros(p.shape[:-1] + (1,))], axis=-1)
    return H0 @ (np.eye(3) + P.reshape(p.shape[:-1] + (3, 3)))


def fit_plane_parallax(x1: np.ndarray, x2: np.ndarray, noise: float | None = None) -> PlaneParallax:
    """Homography of point pairs and the parallax of its plane, with its uncertainty.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 2) or (N, 3)
        Normalised points of the two views (lens corrected), ``N >= 8``, outliers removed.
    noise : float, optional
        Standard deviation of one coordinate of a transfer error (normalised units), > 0;
        by default estimated robustly from the fit's own residuals
        (:func:`ppo_cv.model_selection.robust_sigma`).

    Returns
    -------
    PlaneParallax
        ``sigma`` is ``sqrt(g^T C g)``: ``C = noise^2 (J^T J)^-1`` the covariance of the
        homography's 8 parameters, ``g`` the gradient of the parallax in them.

    Raises
    ------
    ValueError
        Fewer than 8 pairs, mismatched shapes, or a noise that is not a finite number > 0.
    TypeError
        A noise that is not a number.

    Examples
    --------
    A translation of 2 % of the distance of a wall, seen by a 30 degree field of view:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x1 = rng.uniform(-0.27, 0.27, (300, 2))
    >>> H = np.eye(3) + np.outer([0.02, 0.0, 0.0], [0.0, 0.0, 1.0])
    >>> h = np.column_stack([x1, np.ones(300)]) @ H.T
    >>> x2 = h[:, :2] / h[:, 2:] + rng.normal(0.0, 2e-5, (300, 2))
    >>> fit = fit_plane_parallax(x1, x2)
    >>> bool(abs(fit.parallax - 0.02) < 3 * fit.sigma), bool(fit.sigma < 0.001)
    (True, True)
    """
    xy1, xy2 = _as_points(x1, "x1"), _as_points(x2, "x2")
    if xy1.shape != xy2.shape:
        raise ValueError(f"x1 and x2 must have the same shape, got {xy1.shape} and {xy2.shape}")
    if len(xy1) < _MIN_POINTS:
        raise ValueError(f"at least {_MIN_POINTS} point pairs are needed, got {len(xy1)}")
    if noise is not None:
        noise = as_positive(noise, "noise")
    H0 = _unit_determinant(_direct_linear(xy1, xy2))

    def many(P: np.ndarray) -> np.ndarray:
        return _transfer(_perturbed(H0, P), xy1, xy2).reshape(len(P), -1)

    def residuals(p: np.ndarray) -> np.ndarray:
        return _transfer(_perturbed(H0, p), xy1, xy2).ravel()

    p, J = _levenberg_marquardt(residuals, np.zeros(8), _ITERATIONS, many=many)
    H = _unit_determinant(_perturbed(H0, p))
    parallax = _homography_parallax(H)
    errors = np.linalg.norm(_transfer(H, xy1, xy2), axis=1)
    if noise is None:
        noise = robust_sigma(errors, 2)
    covariance = _gauss_newton_covariance(J, noise**2) if noise > 0 else None
    sigma = float("inf")
    if covariance is not None:
        g = _forward_jacobian(
            lambda q: np.array([_homography_parallax(_perturbed(H0, q))]), p, np.array([parallax])
        )[0]
        sigma = float(np.sqrt(max(g @ covariance @ g, 0.0)))
    return PlaneParallax(H=H, parallax=parallax, sigma=sigma, residuals=errors)


def _as_points(x: np.ndarray, name: str) -> np.ndarray:
    x = as_finite_rows(x, name, (2, 3))
    return x[:, :2] / x[:, 2:] if x.shape[1] == 3 else x
