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

import numpy as np

__all__ = [
    "JOINT_DIMENSION",
    "MISMATCH_FLOOR",
    "MODEL_DIMENSIONS",
    "ModelResiduals",
    "ModelSelection",
    "gric",
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
        Noise estimated from the most general model (pixels), before the floor.
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
    e = np.abs(np.asarray(residuals, dtype=np.float64))
    if e.size == 0:
        return float("nan")
    return float(np.median(e) / np.sqrt(_chi2_median(int(codimension))))


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
    e = np.asarray(residuals, dtype=np.float64)
    n = e.size
    r = JOINT_DIMENSION
    rho = np.minimum((e / sigma) ** 2, _LAMBDA3 * (r - dimension))
    return float(np.sum(rho) + np.log(r) * dimension * n + np.log(r * n) * num_params)


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
        Noise in pixels; by default :func:`robust_sigma` of the candidate of largest dimension,
        corrected for the ``k`` parameters it fitted: ``sqrt(n / (n - k))``.
    mismatch_floor : float
        Unmodelled residual relative to ``sigma``, added in quadrature (:data:`MISMATCH_FLOOR`).

    Returns
    -------
    ModelSelection
    """
    if not candidates:
        raise ValueError("select_model needs at least one candidate model")
    sizes = {np.asarray(c.residuals).size for c in candidates}
    if len(sizes) != 1:
        raise ValueError(f"candidates must score the same matches, got sizes {sorted(sizes)}")
    n = sizes.pop()
    if sigma is None:
        general = max(candidates, key=lambda c: (c.dimension, c.num_params))
        sigma = robust_sigma(general.residuals, JOINT_DIMENSION - general.dimension)
        if n > general.num_params:
            sigma *= float(np.sqrt(n / (n - general.num_params)))
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
