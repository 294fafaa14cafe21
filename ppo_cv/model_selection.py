"""Which two-view model explains the matches: pure rotation, (plane,) or general motion.

The comparison is Torr's Geometric Robust Information Criterion (P. H. S. Torr, "Geometric
motion segmentation and model selection", Phil. Trans. R. Soc. A 356, 1998; and "An assessment
of information criteria for motion model selection", CVPR 1997). A match is a point in the joint
image space of dimension ``r = 4``; a model is a variety of dimension ``d`` in it (``d = 3`` for
the essential matrix, ``d = 2`` for a rotation or a homography) with ``k`` parameters, and

    GRIC = sum_i min(e_i^2 / sigma^2, lambda3 (r - d)) + lambda1 d n + lambda2 k,
    lambda1 = ln r,  lambda2 = ln(r n),  lambda3 = 2,

with ``e_i`` the distance of match ``i`` to the variety. The model of least GRIC wins: a
lower-dimensional model pays for every residual it leaves but saves ``lambda1`` per match for
each dimension it does not need.

What real photos add, and how it is handled:

- The noise ``sigma`` is estimated from the residuals of the most general model (largest ``d``),
  robustly: ``median(e) / sqrt(median of chi2 with r - d degrees of freedom)``, the median of the
  chi2 quantile taken by the Wilson-Hilferty approximation, times ``sqrt(n / (n - k))`` for the
  ``k`` parameters that model fitted to the same ``n`` residuals (the degrees-of-freedom
  correction of a least-squares variance: an essential matrix fitted to 20 matches of a pure
  rotation absorbs a quarter of their noise, and the rotation would then pay for noise the
  essential matrix only appeared to explain). Dividing every residual by it makes the rule
  scale-free: independent of image size, focal length and feature accuracy.
- Features located worse along one image direction than across it (a view stretched against the
  other along a pan) leave the essential matrix, whose Sampson error sees only the component
  across its epipolar lines, free to put those lines along the worse direction: its residuals
  then understate the noise the rotation's two-dimensional residuals carry. That noise changes
  from a match to its nearest neighbour, where parallax, smooth over a surface, hardly does;
  :func:`incoherent_sigma` measures it on the rotation's residual vectors, and the larger of
  the two estimates is the ``sigma`` of the comparison (``ppo_cv.motion_model``). On
  ``ppo_cv.data_gen``'s warped photos with sensor noise and blur the rotation's is 1.5-2.2
  times the essential matrix's estimate where the rotation lost, 0.7-1.4 on translating pairs
  at baseline / depth 0.02 (``tiny-baseline``, the harness renders) and 0.9-1.3 on tripod pans.
- ``sigma`` has a floor, :data:`MISMATCH_FLOOR` times ``sigma`` itself, for the part of the
  residuals no candidate models (higher-order distortion, rolling shutter, a tripod head that
  does not turn about the optical centre): ``sigma_eff = sigma sqrt(1 + MISMATCH_FLOOR^2)``.
  An essential matrix, two dimensions more general, absorbs these with a spurious translation;
  without the floor GRIC would call every real panorama a general motion.
- The rotation candidate should absorb a focal scale and radial distortion
  (:func:`ppo_cv.rotation.fit_rotation_lens`): the imperfections themselves, which a translation's
  depth-dependent parallax is not.

The statistic recorded per pair is ``(GRIC(model) - GRIC(best other)) / n`` for each model and
the chosen model's margin; :func:`select_model` is pure numpy and takes any number of models, so a
homography (``"plane"``, ``d = 2``, ``k = 8``) slots in beside ``"rotation"`` and ``"general"``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from .checks import (
    MAX_WHOLE_NUMBER,
    as_number,
    as_real_array,
    as_whole_number,
    require_finite,
    require_instance,
)

__all__ = [
    "COHERENT_AGREEMENT",
    "JOINT_DIMENSION",
    "MISMATCH_FLOOR",
    "MODEL_DIMENSIONS",
    "ModelResiduals",
    "ModelSelection",
    "coherent_share",
    "gric",
    "incoherent_sigma",
    "model_noise",
    "nearest_neighbours",
    "robust_sigma",
    "select_model",
]

JOINT_DIMENSION = 4
"""``r``: a match is a point of R^4 (two image points)."""

MISMATCH_FLOOR = 1.0
"""Unmodelled residual, as a fraction of the fitted noise, added in quadrature to ``sigma``.

Measured on imperfect renders, photos warped by ``K R K^-1`` and the freiburg translating pairs
(``benchmarks/pure_rotation.py``, ``docs/pure_rotation.md``), with the rotation absorbing a
focal scale and ``k1``: with 0.5, 17 % of the harness's true rotations (renders and warped
photos) are called general, with 0.75 still 8 %, with 1.0 none; with 1.25 one of 14 of
``ppo_cv.data_gen``'s ``tiny-baseline`` pairs at baseline / depth 0.02 is flagged, with 1.0 none
(its least GRIC difference is +0.03 per match). Freiburg stays general at every value (least
GRIC difference +0.9). Real tripods do not turn about the optical centre exactly, so the larger
of the values that keep translating pairs general is the one that holds on real panoramas.
"""

MODEL_DIMENSIONS = {"rotation": (2, 5), "plane": (2, 8), "general": (3, 5)}
"""Variety dimension ``d`` and parameter count ``k`` of the named models (the rotation absorbs a
focal scale and a radial coefficient: ``k = 3 + 2``)."""

_LAMBDA3 = 2.0


@dataclass(frozen=True)
class ModelResiduals:
    """One candidate model and the distance of every match to it.

    Attributes
    ----------
    name : str
        ``"rotation"``, ``"plane"`` or ``"general"``.
    residuals : ndarray, shape (N,)
        Distance of each match to the model's variety in the joint image space (pixels); for a
        transfer error ``|x2 - h(x1)|`` with noise in both images that is ``|.| / sqrt(2)``.
    dimension : int
        ``d``, dimension of the variety (2 for rotation or homography, 3 for the essential matrix).
    num_params : int
        ``k``, the model's degrees of freedom.
    """

    name: str
    residuals: np.ndarray
    dimension: int
    num_params: int


@dataclass(frozen=True)
class ModelSelection:
    """Outcome of :func:`select_model`.

    Attributes
    ----------
    model : str
        Name of the model of least GRIC.
    gric : dict of str to float
        GRIC of each model.
    median_residual_px : dict of str to float
        Median residual of each model (pixels).
    sigma_px : float
        Noise GRIC divided by (pixels), before the floor: :func:`model_noise` unless given.
    margin : float
        ``(GRIC(second best) - GRIC(chosen)) / n`` >= 0: the evidence per match for the choice.
    num_matches : int
        ``n``.
    """

    model: str
    gric: dict[str, float]
    median_residual_px: dict[str, float]
    sigma_px: float
    margin: float
    num_matches: int

    def relative_gric(self, name: str, other: str) -> float:
        """``(GRIC(name) - GRIC(other)) / n``: negative when ``name`` explains the data better."""
        return (self.gric[name] - self.gric[other]) / max(self.num_matches, 1)


def _chi2_median(dof: int) -> float:
    """Median of a chi2 distribution (Wilson-Hilferty), exact to 1.3 % for ``dof = 1, 2``."""
    return dof * (1.0 - 2.0 / (9.0 * dof)) ** 3


def robust_sigma(residuals: np.ndarray, codimension: int) -> float:
    """Noise standard deviation from distances to a variety of codimension ``r - d``.

    ``e^2 / sigma^2`` follows chi2 with ``codimension`` degrees of freedom for inliers, so
    ``sigma = median(e) / sqrt(median chi2)``; the median ignores up to half outliers.
    """
    e = np.abs(as_real_array(residuals, "residuals"))
    codimension = as_whole_number(codimension, "codimension", 1, JOINT_DIMENSION)
    if e.size == 0:
        return float("nan")
    return float(np.median(e) / np.sqrt(_chi2_median(codimension)))


def nearest_neighbours(points: np.ndarray) -> np.ndarray:
    """Index of the nearest other point of each point, shape (N,), for points (N, 2), N >= 2.

    Exact, by a grid: each point is compared with the points of the 3 x 3 cells around its
    own, the cell side chosen so that a point shares its cell with few others
    (:data:`_CROWDING`), and is settled once the best distance found is below its distance to
    the border of those cells; the unsettled ones are searched again on a grid of twice the
    side, the last few against every point. Coincident points are each other's nearest.

    Examples
    --------
    >>> nearest_neighbours(np.array([[0.0, 0.0], [10.0, 0.0], [1.0, 1.0], [10.0, 2.0]]))
    array([2, 3, 0, 1])
    """
    p = as_real_array(points, "points")
    if p.ndim != 2 or p.shape[1] < 2 or len(p) < 2:
        raise ValueError(f"points must have shape (N, 2) with N >= 2, got {p.shape}")
    require_finite(p[:, :2], "points")
    p = p[:, :2]
    n = len(p)
    low = p.min(axis=0)
    extent = np.maximum(p.max(axis=0) - low, 1e-12)
    side = max(float(np.sqrt(extent[0] * extent[1] / n)), float(extent.max()) / n)
    for _ in range(8):
        counts = _cell_counts(np.floor((p - low) / side))
        crowding = float(np.sum(counts.astype(np.float64) ** 2)) / n
        if crowding <= _CROWDING:
            break
        side *= np.sqrt(0.5 * _CROWDING / crowding)
    best, best_d2 = np.full(n, -1, dtype=np.intp), np.full(n, np.inf)
    queries = np.arange(n)
    while queries.size > _BRUTE_FORCE and side < 4.0 * extent.max():
        queries = _grid_pass(p, queries, low, side, best, best_d2)
        side *= 2.0
    for start in range(0, queries.size, _BRUTE_FORCE):
        chunk = queries[start : start + _BRUTE_FORCE]
        d2 = np.sum((p[chunk, None] - p[None]) ** 2, axis=2)
        d2[np.arange(chunk.size), chunk] = np.inf
        best[chunk] = np.argmin(d2, axis=1)
    return best


_CROWDING = 8.0  # mean number of points in the cell of a point
_MAX_SLOTS = 32  # points of one cell compared; a fuller cell leaves the query unsettled
_BRUTE_FORCE = 256  # unsettled points compared with every point, this many at a time


def _cell_counts(cell: np.ndarray) -> np.ndarray:
    """Points in each occupied cell, cells ``cell`` (N, 2) of whole numbers >= 0 (float)."""
    columns, rows = cell.max(axis=0) + 1.0
    if columns * rows > 2.0**53:  # one float key per cell would not be exact
        return np.unique(cell, axis=0, return_counts=True)[1]
    return np.unique(cell[:, 1] * columns + cell[:, 0], return_counts=True)[1]


def _grid_pass(p, queries, low, side, best, best_d2) -> np.ndarray:
    """Update ``best`` and ``best_d2`` of ``queries`` from the 3 x 3 cells of ``side`` around
    each (in place); return the queries a point beyond those cells may still be nearer to."""
    cell = np.floor((p - low) / side).astype(np.int64)
    width = int(cell[:, 0].max()) + 3
    key = (cell[:, 1] + 1) * width + cell[:, 0] + 1
    order = np.argsort(key, kind="stable")
    sorted_key, cells = key[order], int(key.max()) + width + 3
    if cells <= _CELL_TABLE_PER_POINT * len(p):  # a table of every cell's place: one lookup
        first_at = np.searchsorted(sorted_key, np.arange(cells)).__getitem__
    else:
        first_at = partial(np.searchsorted, sorted_key)
    steps = _NEIGHBOUR_CELLS[0] * width + _NEIGHBOUR_CELLS[1]
    crowded = np.zeros(queries.size, dtype=bool)
    for start in range(0, queries.size, _QUERY_CHUNK):
        chunk = queries[start : start + _QUERY_CHUNK]
        targets = key[chunk, None] + steps
        crowded[start : start + _QUERY_CHUNK] = _nearest_in_cells(
            p, chunk, targets, (order, first_at), best, best_d2
        )
    offset = (p[queries] - low) / side % 1.0
    margin = side * (1.0 + np.minimum(offset, 1.0 - offset).min(axis=1))
    return queries[crowded | (best_d2[queries] > margin**2)]


_NEIGHBOUR_CELLS = np.stack([np.arange(9) // 3 - 1, np.arange(9) % 3 - 1])
"""Row and column steps (2, 9) from a cell to the 3 x 3 cells about it, in the order searched."""
_QUERY_CHUNK = 1024  # queries whose candidates are compared at once (a few MB)
_CELL_TABLE_PER_POINT = 16  # cells per point up to which a table finds each cell's points


def _nearest_in_cells(p, queries, targets, grid, best, best_d2) -> np.ndarray:
    """Update ``best`` and ``best_d2`` of ``queries`` (Q,) from the points of the cells
    ``targets`` (Q, 9), at most :data:`_MAX_SLOTS` of each, in place; whether a cell held more
    (Q,) bool. ``grid``: the points ordered by cell, and the place in that order of the first
    point of each cell at or after the given ones.

    A query's candidates are taken cell by cell, by index within a cell; it takes the first
    of them at its least distance when that is below its best so far, as comparing them one by
    one would."""
    order, first_at = grid
    start = first_at(targets)
    count = first_at(targets + 1) - start
    crowded = np.any(count > _MAX_SLOTS, axis=1)
    count = np.minimum(count, _MAX_SLOTS).ravel()
    within = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    j = order[np.repeat(start.ravel(), count) + within]
    sizes = count.reshape(len(queries), 9).sum(axis=1)
    i = np.repeat(queries, sizes)
    d2 = np.sum((p[j] - p[i]) ** 2, axis=1)
    d2[j == i] = np.inf
    searched = sizes > 0
    queries, sizes = queries[searched], sizes[searched]
    if queries.size:
        starts = np.cumsum(sizes) - sizes
        least = np.minimum.reduceat(d2, starts)
        at_least = np.flatnonzero(d2 == np.repeat(least, sizes))
        first = at_least[np.searchsorted(at_least, starts)]
        better = least < best_d2[queries]
        best[queries[better]], best_d2[queries[better]] = j[first[better]], least[better]
    return crowded


def incoherent_sigma(vectors: np.ndarray, neighbours: np.ndarray) -> float:
    """Noise per coordinate of residual vectors, from their differences between neighbours.

    The nugget of the residuals' variogram: a residual field that varies smoothly across the
    image (the parallax of a surface, a lens the model misses) cancels in the difference
    ``d_i = v_i - v_j(i)`` of a match and its nearest neighbour ``j(i)`` in the image, noise
    independent from match to match does not; ``|d_i|^2 / (2 sigma^2)`` then follows chi2
    with 2 degrees of freedom and ``sigma = median |d| / sqrt(2 median chi2)``.

    Parameters
    ----------
    vectors : ndarray, shape (N, 2)
        Residual vectors of the matches.
    neighbours : ndarray of int, shape (N,)
        Index of the nearest other match of each in the image
        (:func:`nearest_neighbours`).

    Returns
    -------
    float
        NaN for fewer than 3 matches.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = np.linspace(0, 100, 2001)
    >>> smooth = np.column_stack([np.sin(x / 30), np.cos(x / 30)])
    >>> noise = rng.normal(0, 0.1, (2001, 2))
    >>> neighbours = np.r_[1:2001, 1999]  # the next point, the last one's previous
    >>> round(incoherent_sigma(smooth + noise, neighbours), 1)
    0.1
    """
    v = np.asarray(vectors, dtype=np.float64)
    if len(v) < 3:
        return float("nan")
    differences = np.linalg.norm(v - v[np.asarray(neighbours)], axis=1)
    return float(np.median(differences) / np.sqrt(2.0 * _chi2_median(2)))


COHERENT_AGREEMENT = 0.5
"""Two residual vectors move together when their difference is below this fraction of the
first one's length (:func:`coherent_share`)."""


def coherent_share(vectors: np.ndarray, neighbours: np.ndarray, outlying: np.ndarray) -> float:
    """Share of the matches that are outlying and move with their nearest neighbour.

    Outliers a model leaves by chance (noise in a tail, a mismatch) are scattered: the nearest
    neighbour of one is most likely an inlier, or an outlier displaced another way. Outliers of a
    surface the model does not explain (parallax, a moving object) come in patches whose
    residuals agree. Match ``i`` counts when it and its neighbour ``j(i)`` are both outlying and
    ``|v_i - v_j(i)| < COHERENT_AGREEMENT |v_i|``.

    Parameters
    ----------
    vectors : ndarray, shape (N, 2)
        Residual vectors of the matches under the model.
    neighbours : ndarray of int, shape (N,)
        Index of the nearest other match of each in the image (:func:`nearest_neighbours`).
    outlying : ndarray of bool, shape (N,)
        Matches the model does not explain.

    Returns
    -------
    float
        In [0, 1]; 0 for no matches.

    Examples
    --------
    >>> v = np.array([[5.0, 0.0], [5.2, 0.1], [0.0, 0.1], [-4.0, 3.0]])
    >>> coherent_share(v, np.array([1, 0, 1, 2]), np.array([True, True, False, True]))
    0.5
    """
    v = np.asarray(vectors, dtype=np.float64)
    outlying = np.asarray(outlying, dtype=bool)
    if len(v) == 0:
        return 0.0
    j = np.asarray(neighbours)
    agree = np.linalg.norm(v - v[j], axis=1) < COHERENT_AGREEMENT * np.linalg.norm(v, axis=1)
    return float(np.mean(outlying & outlying[j] & agree))


def gric(residuals: np.ndarray, sigma: float, dimension: int, num_params: int) -> float:
    """Torr's GRIC of one model (see the module docstring); lower is better.

    Parameters
    ----------
    residuals : ndarray, shape (N,)
        Distances of the matches to the model's variety.
    sigma : float
        Noise standard deviation, same unit, > 0.
    dimension, num_params : int
        ``d`` and ``k``.
    """
    e = as_real_array(residuals, "residuals")
    sigma = as_number(sigma, "sigma")
    dimension = as_whole_number(dimension, "dimension", 0, JOINT_DIMENSION)
    num_params = as_whole_number(num_params, "num_params", 0, MAX_WHOLE_NUMBER)
    n = e.size
    r = JOINT_DIMENSION
    rho = np.minimum((e / sigma) ** 2, _LAMBDA3 * (r - dimension))
    return float(np.sum(rho) + np.log(r) * dimension * n + np.log(r * n) * num_params)


def model_noise(candidates: Sequence[ModelResiduals]) -> float:
    """Noise (pixels) of the candidate of largest dimension: :func:`robust_sigma` of its
    residuals times ``sqrt(n / (n - k))`` for the ``k`` parameters it fitted to them."""
    _require_candidates(candidates)
    general = max(candidates, key=lambda c: (c.dimension, c.num_params))
    sigma = robust_sigma(general.residuals, JOINT_DIMENSION - general.dimension)
    n = np.asarray(general.residuals).size
    if n > general.num_params:
        sigma *= float(np.sqrt(n / (n - general.num_params)))
    return sigma


def _require_candidates(candidates: Any) -> None:
    """TypeError unless ``candidates`` is a non-empty list or tuple of
    :class:`ModelResiduals` (ValueError when empty)."""
    if not isinstance(candidates, (list, tuple)):
        raise TypeError(
            f"candidates must be a list of ModelResiduals, got {type(candidates).__name__}"
        )
    if not candidates:
        raise ValueError("candidates is empty: at least one candidate model is needed")
    for candidate in candidates:
        require_instance(candidate, ModelResiduals, "each of candidates")


def select_model(
    candidates: Sequence[ModelResiduals],
    *,
    sigma: float | None = None,
    mismatch_floor: float = MISMATCH_FLOOR,
) -> ModelSelection:
    """Choose among candidate models of the same matches by GRIC with a mismatch floor.

    Parameters
    ----------
    candidates : sequence of ModelResiduals
        At least one; all with residuals of the same N matches.
    sigma : float, optional
        Noise in pixels; by default :func:`model_noise`.
    mismatch_floor : float
        Unmodelled residual relative to ``sigma``, added in quadrature (:data:`MISMATCH_FLOOR`).

    Returns
    -------
    ModelSelection
    """
    _require_candidates(candidates)
    sizes = {np.asarray(c.residuals).size for c in candidates}
    if len(sizes) != 1:
        raise ValueError(f"candidates must score the same matches, got sizes {sorted(sizes)}")
    n = sizes.pop()
    if sigma is None:
        sigma = model_noise(candidates)
    if not np.isfinite(sigma) or sigma <= 0:
        sigma = 1e-12
    effective = sigma * float(np.sqrt(1.0 + mismatch_floor**2))
    scores = {c.name: gric(c.residuals, effective, c.dimension, c.num_params) for c in candidates}
    order = sorted(scores, key=scores.get)
    margin = (scores[order[1]] - scores[order[0]]) / max(n, 1) if len(order) > 1 else np.inf
    medians = {c.name: float(np.median(c.residuals)) if n else float("nan") for c in candidates}
    return ModelSelection(
        model=order[0],
        gric=scores,
        median_residual_px=medians,
        sigma_px=float(sigma),
        margin=float(margin),
        num_matches=int(n),
    )
