"""Is a two-view geometry better than chance? An a-contrario test of the epipolar consensus.

A robust estimator always returns its best model, even from matches between unrelated images.
The question here is whether that model's support could be explained by chance. Following the
a-contrario model of Moisan and Stival (2004, "A probabilistic criterion to detect rigid point
matches between two images and estimate the fundamental matrix") and its ORSA form (Moisan,
Moulon and Monasse, 2012, "Automatic homographic registration of a pair of images, with a
contrario elimination of outliers"), under the background hypothesis the point of image 2 of
each match is uniform over image 2, independently of image 1. A point then falls within ``eps``
pixels of the epipolar line ``l_i`` of match ``i`` with probability

    p_i(eps) <= 2 eps L_i / A              (A: area of image 2),

``L_i`` the chord of ``l_i`` inside image 2 grown by ``eps`` on every side (every pixel of the
band projects onto that chord), at least one pixel. The chord is per match: an epipolar line
that only grazes a corner is a much smaller target than one across the image, and the global
bound ``L_i <= D`` (the diagonal) overstates chance by a factor of about 2 per match. With
``n`` matches, a model built from a minimal sample of ``s`` of them, and ``k`` matches (the
sample included) within ``eps_k``, the ``k``-th smallest image-2 distance, the number
of false alarms is

    NFA(k) = N_out (n - s) C(n, k) C(k, s) prod_{k - s largest of the k} p_i(eps_k),

``N_out`` the number of models a minimal sample can yield (up to 10 for the five-point solver),
``n - s`` the number of values ``k`` tried, and the product taken over the ``k - s`` matches
with the largest chords, whichever ``s`` formed the sample (bounded from above through the
smallest chord, so that it vectorises). ``C(n, k) C(k, s) N_out`` counts every consensus set
and every model a sample of it can yield, so the search of RANSAC over hypotheses is counted.
The geometry is significant when ``min_k NFA(k)`` is small.

Measured separation (``log10 NFA`` at the default pipeline settings, 320x240 unless stated;
``p`` the :func:`distinctiveness` p-value, computed above :data:`CONFIDENT_LOG10_NFA` only):

=====================================================  ===================================
pairs                                                  log10 NFA; p
=====================================================  ===================================
20 random-noise pairs                                  none reaches 8 inliers
20 unrelated scikit-image photographs (``tests``)      14 < 8 inliers; 6: +3.0..+7.2;
                                                       p 0.26..0.98
20 renders of different scenes, disjoint textures      +3.0..+7.9; p 0.54..0.97
freiburg (640x480): 75 pairs, rotation within 10 deg   -1201..+1.9; one +4.4, p 0.015
freiburg: 7 pairs, rotation 11-32 deg off              -6.3..+3.9 (p 0.52 at +3.9)
freiburg: 3 pairs, rotation 102-155 deg off            +1.8; +4.2, p 0.42; +7.0
rendered presets (``data_gen.MOTIONS``)                below -100
=====================================================  ===================================

No bar on ``log10 NFA`` alone separates chance from the weakest real pairs: 13-19 inliers
among 86-146 matches of a wide-baseline pair are only just beyond chance. The second,
independent test does: under the background hypothesis the consensus is chosen by geometry
alone, so the Lowe ratios of its matches are distributed like those of the other matches,
while real correspondences are more distinctive. The joint figure ``log10 NFA + log10 p``
is +2.95 and above for every chance pair above and at most +2.6 for the real pairs kept
(freiburg, seeds 0 and 1); the pipeline requires it to be at most
:data:`CONFIDENT_LOG10_NFA`. The margins are thin and measured on these sets only.

Both tests still let through chance consensus of 10-20 matches of textured photographs, from
``log10 NFA`` +3.6 down to -0.3, below the weakest real pairs'. A third test looks where the
epipolar consensus does not: it fixes where each image-2 point lies across its epipolar line,
not where along it. A real motion moves the neighbouring points of a surface alike, so matches
that are neighbours in image 1 are neighbours in image 2; a chance consensus places its
image-2 points anywhere along their lines. :func:`local_consistency` ranks each match's nearest
neighbour in image 1 by its distance in image 2 and compares the ranks with placements drawn
under the background hypothesis, uniform along each line's chord; every consensus above
:data:`LOCAL_CHECK_LOG10_NFA` must reach ``p <= MAX_LOCAL_P``. Measured at 640 x 480 (demo
camera for the photographs; ``p`` resolved to 0.001):

=====================================================  ===================================
pairs                                                  local consistency p
=====================================================  ===================================
freiburg: the 9 pairs answered with 13-20 inliers      0.001-0.005
freiburg: 2 pairs refused (``log10 NFA`` +3.9, +4.2)   0.001, 0.094
380 ordered pairs of 20 scikit-image photographs:      0.068-0.99
the 9 answered before (``log10 NFA`` -0.3..+3.6)
126 pairs of a freiburg frame and a pano_dev photo:    0.039-0.88
the 7 answered before (``log10 NFA`` +0.8..+3.9)
the same, 392 consensus below ``log10 NFA`` 8          10 at 0.001-0.01, 382 above
=====================================================  ===================================

Texture makes the background hypothesis a little optimistic (2.5 % of chance consensus at
the 1 % level; one, +4.9 between a freiburg frame and a pano_dev photo, at 0.001, refused by
its distinctiveness); the real pairs lie below the bar by a factor of two at least.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import (
    MAX_WHOLE_NUMBER,
    as_camera_matrix,
    as_finite_array,
    as_finite_rows,
    as_image_size,
    as_matched_rows,
    as_matrix3,
    as_nonnegative,
    as_number,
    as_positive,
    as_rotation,
    as_whole_number,
    shown,
)
from .limits import MAX_MATCHES
from .metrics import direction_error_deg
from .model_selection import nearest_neighbours

__all__ = [
    "CONFIDENT_LOG10_NFA",
    "DEFAULT_MAX_LOG10_NFA",
    "ESSENTIAL_SAMPLE_SIZE",
    "ESSENTIAL_MODELS_PER_SAMPLE",
    "MAX_CONSENSUS_THRESHOLD_PX",
    "MIN_CONSENSUS_BAND",
    "MISSED_CONSENSUS_PROBABILITY",
    "Significance",
    "chord_lengths",
    "distinctiveness",
    "LOCAL_CHECK_LOG10_NFA",
    "LOCAL_CONSISTENCY_DRAWS",
    "LOCAL_CONSISTENCY_MATCHES",
    "local_consistency",
    "MAX_LOCAL_P",
    "MAX_MEDIAN_RAY_ANGLE_DEG",
    "MIN_CHECKED_INLIERS",
    "ray_angles_deg",
    "require_checked_consensus",
    "require_matchable_viewpoints",
    "require_significance",
    "epipolar_lines",
    "log10_binomial",
    "epipolar_significance",
    "smallest_significant_consensus",
]

DEFAULT_MAX_LOG10_NFA = 5.0
"""Default bar on ``log10 NFA``. The textbook bar is 0 (at most one consensus this good expected
by chance), but the bound is loose: wide-baseline freiburg pairs with poses within 10 degrees
score up to +4.4. Between :data:`CONFIDENT_LOG10_NFA` and this bar the consensus must also pass
the distinctiveness test (module docstring)."""

CONFIDENT_LOG10_NFA = 2.8
"""Up to this ``log10 NFA`` the epipolar consensus alone suffices; above it (up to the bar) the
consensus must also be distinctive: ``log10 NFA + log10 p <= CONFIDENT_LOG10_NFA``, ``p`` the
p-value of :func:`distinctiveness`. Chance consensus of unrelated images was measured at
+2.95 and above on that joint figure, real pairs with good poses at +2.6 and below (module
docstring)."""

MAX_MEDIAN_RAY_ANGLE_DEG = 90.0
"""Largest median angle, degrees, between the two rays of a pose's inliers
(:func:`require_matchable_viewpoints`): the change of viewpoint under which the two views see
each point. Beyond 90 degrees a point lies inside the sphere whose diameter is the baseline,
and one of the views sees its surface at least 45 degrees from its normal; descriptors are
matched across changes of viewpoint up to about 60 degrees (Mikolajczyk et al., 2005, "A
comparison of affine region detectors"). A pose that puts half its consensus beyond 90 degrees
is not the geometry its matches were found under. Measured: the 85 freiburg pairs' right
poses at 2-63 degrees (three 32-62 degrees off at 59-77); cropped to a 30 % overlap, 20 poses
32-174 degrees off on 10-15 inliers that pass the significance bar, 13 of them at 90.2-144
degrees, poses within 15 degrees at most 62; ten renders of five presets at 0.02-7.6
(``docs/decision.md``)."""

ESSENTIAL_SAMPLE_SIZE = 5
ESSENTIAL_MODELS_PER_SAMPLE = 10
MIN_CHECKED_INLIERS = ESSENTIAL_SAMPLE_SIZE + 1
"""Fewest inliers of a general pose whose residual the other inliers check
(:func:`require_checked_consensus`): one more than the pose's five parameters. The count of
the NFA assumes a model drawn from ``s`` matches and tested by the ``k - s`` others; the pose
returned is fitted to all ``k``, and a match of leverage above one half
(:data:`ppo_cv.refine.LEVERAGE_MAX`, Huber's bound) sets a direction of it more than the others
together: the fit moved to it, and its residual tests the pose little. With fewer checked
inliers than this the pose's deviations are undetermined
(:func:`ppo_cv.refine.pose_information`: ``rotation_sigma_deg`` inf, ``t_sigma_deg`` at its
cap). Measured (640 x 480, demo camera, 150 random-noise pairs): the 23 chance consensus of
8-9 of 23-42 matches that reach a pose, at ``log10 NFA`` +1.4..+3.9, hold 1-5 checked inliers
(8 were answered before); the nine freiburg pairs answered with 13-20 inliers (``log10 NFA``
-2.3..+4.4) hold 10-18 (``docs/decision.md``). A chance consensus of a dozen or more matches
is not caught here, but by :func:`local_consistency` (``docs/limits.md``, "Significance")."""
MAX_LOCAL_P = 0.01
"""Largest :func:`local_consistency` p-value of a consensus with ``log10 NFA`` above
:data:`LOCAL_CHECK_LOG10_NFA` (module docstring): the 1 % level. Measured: the weak real pairs
at 0.001-0.005, the chance consensus that pass every other test at 0.039 and above."""
LOCAL_CHECK_LOG10_NFA = -10.0
"""``log10 NFA`` above which a consensus must also be locally consistent
(:func:`local_consistency`): chance consensus of unrelated photographs were measured down to
-3.1; below this the epipolar consensus alone suffices, and the test's cost, which grows with
the square of the consensus, is not paid."""
LOCAL_CONSISTENCY_MATCHES = 100
"""Most matches :func:`local_consistency` ranks: those of least residual. A bound on its cost
(about 0.4 s at 100); the consensus measured above :data:`LOCAL_CHECK_LOG10_NFA` held at most 50."""
LOCAL_CONSISTENCY_DRAWS = 999
"""Placements drawn under the background hypothesis for the p-value of
:func:`local_consistency`, whose smallest value is then 0.001."""
MAX_CONSENSUS_THRESHOLD_PX = 16.0
"""Largest ``eps_k`` tried, pixels: a wider band is no epipolar consensus at these thresholds."""
MIN_CONSENSUS_BAND = 0.25
"""Narrowest chance band of a consensus that :func:`smallest_significant_consensus` assumes, as
a share of ``2 tau D / A`` (``tau`` the fit's threshold, ``D`` the diagonal and ``A`` the area
of image 2): the fits of ``ppo-cv pairs`` on freiburg (seed 0) with ``log10 NFA`` below 8
measured ``p(eps_k)`` at 0.39 to 5.9 times that."""
MISSED_CONSENSUS_PROBABILITY = 0.05
"""``eta``: a uniform fit may stop once a consensus that could still change its answer (at least
as large as the best so far and :func:`smallest_significant_consensus`) would have given an
all-inlier sample with probability ``1 - eta`` (:mod:`ppo_cv.robust`)."""


@dataclass(frozen=True)
class Significance:
    """Outcome of the a-contrario test.

    Attributes
    ----------
    log10_nfa : float
        ``log10`` of the smallest number of false alarms over ``k``; ``+inf`` with too few
        matches to test.
    num_consistent : int
        The ``k`` achieving it: the size of the most meaningful consensus.
    threshold : float
        ``eps_k``, pixels: the residual of the ``k``-th best match.
    probability : float
        ``p(eps_k)`` of the geometric-mean chord: chance that a random match falls within
        ``eps_k`` of its epipolar line.
    num_matches : int
        ``n``.
    consistent : ndarray of bool, shape (n,)
        The ``k`` matches within ``eps_k``.
    """

    log10_nfa: float
    num_consistent: int
    threshold: float
    probability: float
    num_matches: int
    consistent: np.ndarray


def log10_binomial(n: np.ndarray | int, k: np.ndarray | int) -> np.ndarray:
    """``log10 C(n, k)`` for integers ``0 <= k <= n <=`` :data:`ppo_cv.limits.MAX_MATCHES`
    (broadcast), exact sums of logarithms."""
    n, k = np.asarray(n), np.asarray(k)
    if n.dtype.kind not in "iu" or k.dtype.kind not in "iu":
        raise TypeError(f"n and k must be integers, got dtypes {n.dtype} and {k.dtype}")
    try:
        shape = np.broadcast_shapes(n.shape, k.shape)
    except ValueError:
        raise ValueError(
            f"n and k must broadcast together, got shapes {n.shape} and {k.shape}"
        ) from None
    if not np.all((0 <= k) & (k <= n)):
        raise ValueError(f"log10_binomial needs 0 <= k <= n, got n={shown(n)} and k={shown(k)}")
    if n.size and n.max() > MAX_MATCHES:
        raise ValueError(f"log10_binomial takes n up to {MAX_MATCHES}, got {shown(n.max())}")
    if not n.size or not k.size:
        return np.zeros(shape)
    n, k = n.astype(np.int64), k.astype(np.int64)
    log_factorial = np.concatenate([[0.0], np.cumsum(np.log10(np.arange(1, int(n.max()) + 1)))])
    return log_factorial[n] - log_factorial[k] - log_factorial[n - k]


def _log10_nfa(n: int, k: np.ndarray, log_p: np.ndarray, sample_size, models_per_sample):
    """``log10 NFA`` of consensuses of ``k`` of ``n`` matches, each within a band of chance
    ``10^log_p``: ``N_out (n - s) C(n, k) C(k, s) p^(k - s)``, ``log_p`` already counting its
    ``k - s`` factors."""
    return (
        np.log10(models_per_sample * (n - sample_size))
        + log10_binomial(n, k)
        + log10_binomial(k, sample_size)
        + log_p
    )


def _as_solver(sample_size: Any, models_per_sample: Any) -> tuple[int, int]:
    """``(s, N_out)`` of a minimal solver as ints, whole numbers in 1..
    :data:`~ppo_cv.checks.MAX_WHOLE_NUMBER`; ValueError or TypeError naming the one at fault."""
    return (
        as_whole_number(sample_size, "sample_size", 1, MAX_WHOLE_NUMBER),
        as_whole_number(models_per_sample, "models_per_sample", 1, MAX_WHOLE_NUMBER),
    )


def epipolar_lines(E: np.ndarray, x1: np.ndarray, K2: np.ndarray) -> np.ndarray:
    """Epipolar lines ``l2 = K2^-T E x1`` in pixels of image 2, scaled to unit normals, (N, 3).

    ``l2 . (u, v, 1)`` is then the signed pixel distance of ``(u, v)`` to the line; a line of
    zero normal (``x1`` at the epipole) is returned as ``(0, 0, 1)``: no point lies on it.
    ``E`` (3, 3), ``x1`` (N, 3) normalized, ``K2`` (3, 3) a camera matrix; ValueError or
    TypeError naming the argument at fault.
    """
    E, x1 = as_matrix3(E, "E"), as_finite_rows(x1, "x1", 3)
    return _epipolar_lines(E, x1, as_camera_matrix(K2, "K2"))


def _epipolar_lines(E: np.ndarray, x1: np.ndarray, K2: np.ndarray) -> np.ndarray:
    """:func:`epipolar_lines`, unchecked."""
    lines = x1 @ (np.linalg.inv(K2).T @ E).T
    norm = np.hypot(lines[:, 0], lines[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = lines / norm[:, None]
    return np.where((norm > 0)[:, None] & np.isfinite(unit), unit, [0.0, 0.0, 1.0])


def chord_lengths(lines: np.ndarray, image_size: tuple[int, int], margin: float) -> np.ndarray:
    """Length, pixels, of each line inside the image grown by ``margin`` on every side, (N,).

    The image covers ``[-0.5, w - 0.5] x [-0.5, h - 0.5]``; ``lines`` have unit normals
    ``(a, b)``. The line is ``p0 + s d`` with ``p0 = -c (a, b)``, ``d = (-b, a)``; each axis
    bounds ``s`` to an interval (all of R when ``d`` is parallel to it and ``p0`` inside), and
    the chord is the length of the intersection of the two intervals. ValueError or TypeError
    naming the argument at fault.
    """
    lines = as_finite_rows(lines, "lines", 3)
    size = as_image_size(image_size, "image_size")
    _, _, first, last = _chords(lines, size, as_nonnegative(margin, "margin"))
    return np.maximum(last - first, 0.0)


def _chords(lines: np.ndarray, image_size: tuple[int, int], margin: float):
    """The chords of :func:`chord_lengths` as ``p0 + s d``, ``s`` from ``first`` to ``last``:
    ``p0``, ``d`` (N, 2) and ``first``, ``last`` (N,) (``first > last`` for a line outside)."""
    width, height = image_size
    low = np.array([-0.5 - margin, -0.5 - margin])
    high = np.array([width - 0.5 + margin, height - 0.5 + margin])
    p0 = -lines[:, 2:3] * lines[:, :2]
    d = np.column_stack([-lines[:, 1], lines[:, 0]])
    with np.errstate(divide="ignore", invalid="ignore"):
        s_low, s_high = (low - p0) / d, (high - p0) / d
    parallel = np.abs(d) < 1e-12
    inside = (p0 >= low) & (p0 <= high)
    first = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(s_low, s_high))
    last = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(s_low, s_high))
    return p0, d, first.max(axis=1), last.min(axis=1)


def epipolar_significance(
    E: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    K2: np.ndarray,
    image_size2: tuple[int, int],
    *,
    sample_size: int = ESSENTIAL_SAMPLE_SIZE,
    models_per_sample: int = ESSENTIAL_MODELS_PER_SAMPLE,
    max_threshold: float = MAX_CONSENSUS_THRESHOLD_PX,
) -> Significance:
    """Number of false alarms of the epipolar consensus of ``E`` (module docstring).

    Parameters
    ----------
    E : ndarray, shape (3, 3)
        Essential matrix in normalized coordinates, ``x2^T E x1 = 0``, any scale.
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalized coordinates of all putative matches, not only the inliers.
    K2 : ndarray, shape (3, 3)
        Camera matrix of image 2: residuals and epipolar chords are measured in its pixels.
    image_size2 : (int, int)
        ``(width, height)`` of image 2, pixels.
    sample_size, models_per_sample : int
        ``s`` and ``N_out`` of the minimal solver, whole numbers from 1.
    max_threshold : float
        Largest ``eps_k`` tried, pixels: a number > 0, ``inf`` for no bound.

    Returns
    -------
    Significance

    Raises
    ------
    ValueError, TypeError
        An argument of another shape or kind, named.
    """
    E, (x1, x2), K2 = as_matrix3(E, "E"), as_matched_rows(x1, x2), as_camera_matrix(K2, "K2")
    n = int(x1.shape[0])
    width, height = as_image_size(image_size2, "image_size2")
    sample_size, models_per_sample = _as_solver(sample_size, models_per_sample)
    max_threshold = as_number(max_threshold, "max_threshold")
    if not max_threshold > 0:
        raise ValueError(f"max_threshold must be a number > 0 (inf: no bound), got {max_threshold}")
    lines = _epipolar_lines(E, x1, K2)
    residuals = np.abs(np.einsum("ij,ij->i", lines, x2 @ np.asarray(K2, float).T))
    order = np.argsort(residuals)
    eps = residuals[order]
    k = np.arange(sample_size + 1, n + 1)
    k = k[eps[k - 1] <= max_threshold]
    if k.size == 0:
        return Significance(np.inf, 0, np.nan, np.nan, n, np.zeros(n, dtype=bool))
    eps = eps[k - 1]
    _, _, first, last = _chords(lines[order], (width, height), eps[-1])
    log_chord = np.log10(np.maximum(np.maximum(last - first, 0.0), 1.0))
    prefix = np.cumsum(log_chord)[k - 1]
    # the k - s largest chords of the k best: all k minus at least s times the smallest
    log_chords = prefix - sample_size * np.minimum.accumulate(log_chord)[k - 1]
    log_band = np.log10(np.maximum(2.0 * eps / (width * height), 1e-300))
    log_p = np.minimum((k - sample_size) * log_band + log_chords, 0.0)
    log10_nfa = _log10_nfa(n, k, log_p, sample_size, models_per_sample)
    best = int(np.argmin(log10_nfa))
    log_mean_chord = min(log_chords[best] / (k[best] - sample_size), 6.0)
    return Significance(
        log10_nfa=float(log10_nfa[best]),
        num_consistent=int(k[best]),
        threshold=float(eps[best]),
        probability=float(min(2.0 * eps[best] * 10.0**log_mean_chord / (width * height), 1.0)),
        num_matches=n,
        consistent=residuals <= eps[best],
    )


def distinctiveness(ratios: np.ndarray, consistent: np.ndarray) -> float:
    """One-sided p-value that the consistent matches have lower Lowe ratios than the others.

    Wilcoxon-Mann-Whitney rank-sum test, normal approximation with continuity correction:
    ``U = R - k (k + 1) / 2`` from the rank sum ``R`` of the ``k`` consistent ratios among all
    ``n``, ``p = Phi((U - k m / 2 + 1/2) / sqrt(k m (n + 1) / 12))``, ``m = n - k``. Under the
    background hypothesis the consensus is chosen by geometry alone, so its ratios are drawn
    like the others' and ``p`` is uniform; real correspondences are more distinctive.

    Parameters
    ----------
    ratios : ndarray, shape (n,)
    consistent : ndarray of bool, shape (n,)

    Returns
    -------
    float
        ``p`` in [0, 1]; 1 when either group is empty.
    """
    from math import erfc, sqrt

    ratios = as_finite_array(ratios, "ratios")
    if ratios.ndim != 1 or np.shape(consistent) != ratios.shape:
        raise ValueError(
            f"ratios and consistent must be (n,) of one length, got shapes {ratios.shape} and "
            f"{np.shape(consistent)}"
        )
    if np.asarray(consistent).dtype != bool:
        kind = np.asarray(consistent).dtype
        raise TypeError(f"consistent must be a mask of bool, got dtype {kind}")
    k = int(np.count_nonzero(consistent))
    n = int(ratios.shape[0])
    m = n - k
    if k == 0 or m == 0:
        return 1.0
    ranks = np.empty(n)
    ranks[np.argsort(ratios, kind="stable")] = np.arange(1, n + 1)
    u = float(ranks[consistent].sum()) - k * (k + 1) / 2
    z = (u - k * m / 2 + 0.5) / sqrt(k * m * (n + 1) / 12)
    return 0.5 * erfc(-z / sqrt(2.0))


def _log_rank_sums(points2: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """``sum_i log r_i`` for each set of image-2 points (B, k, 2): ``r_i`` the rank, 1 to
    ``k - 1``, of the distance from point ``i`` to point ``neighbours[i]`` among its distances
    to the others (ties to the favour of the neighbour), (B,)."""
    k = points2.shape[1]
    u, v = points2[..., 0], points2[..., 1]
    gaps = np.square(u[:, :, None] - u[:, None]) + np.square(v[:, :, None] - v[:, None])
    to_neighbour = gaps[:, np.arange(k), neighbours]
    ranks = np.maximum(np.count_nonzero(gaps < to_neighbour[..., None], axis=-1), 1)
    return np.log(ranks).sum(axis=1)


def local_consistency(
    x1: np.ndarray,
    points2: np.ndarray,
    lines: np.ndarray,
    image_size2: tuple[int, int],
    margin: float,
    draws: int = LOCAL_CONSISTENCY_DRAWS,
) -> float:
    """One-sided p-value that the neighbours in image 1 of a consensus are neighbours in image 2
    by chance.

    Each match's nearest neighbour in image 1 (:func:`ppo_cv.model_selection.nearest_neighbours`)
    is ranked among the others by its distance in image 2 to the match's point; the statistic
    is the sum of the ranks' logarithms. Under the background hypothesis each image-2 point is
    uniform over the chord of its epipolar line inside the image grown by ``margin``
    (:func:`chord_lengths`), independently of the others: the epipolar consensus fixes where a
    point lies across its line, not where along it. ``p`` is the share of ``draws`` such
    placements (a generator of seed 0) whose statistic is at most the observed one, counting the
    observed: ``(1 + count) / (1 + draws)``, at least ``1 / (1 + draws)``; a point whose line
    misses the image, or has no normal (``(0, 0, 1)``, a point at the epipole), stays where it
    is. A real motion moves neighbouring points of a surface
    alike, and ranks small.

    Parameters
    ----------
    x1 : ndarray, shape (k, 3)
        Homogeneous normalized coordinates in image 1 of the consensus's matches.
    points2 : ndarray, shape (k, 2)
        Their points in image 2, pixels.
    lines : ndarray, shape (k, 3)
        Their epipolar lines in image 2 with unit normals, or ``(0, 0, 1)``
        (:func:`epipolar_lines`).
    image_size2 : (int, int)
        ``(width, height)`` of image 2, pixels.
    margin : float
        Pixels the image is grown by: the consensus's threshold ``eps_k``.
    draws : int
        Placements drawn under the background hypothesis.

    Returns
    -------
    float
        ``p`` in (0, 1]; 1 for fewer than three matches.
    """
    x1, points2, lines = _local_consistency_inputs(x1, points2, lines)
    size2 = as_image_size(image_size2, "image_size2")
    margin = as_nonnegative(margin, "margin")
    draws = as_whole_number(draws, "draws", 1, 100_000)
    k = int(x1.shape[0])
    if k < 3:
        return 1.0
    neighbours = nearest_neighbours(x1[:, :2] / x1[:, 2:])
    observed = _log_rank_sums(points2[None], neighbours)[0]
    p0, d, first, last = _chords(lines, size2, margin)
    outside = ~((first <= last) & (last - first < np.inf))  # outside, or of no normal
    first, last = np.where(outside, 0.0, first), np.where(outside, 0.0, last)
    rng, chunk = np.random.default_rng(0), max(1, 2**22 // (k * k))
    sums = []
    for start in range(0, draws, chunk):
        along = first + rng.random((min(chunk, draws - start), k)) * (last - first)
        placed = np.where(outside[:, None], points2, p0 + along[..., None] * d)
        sums.append(_log_rank_sums(placed, neighbours))
    return float((1 + np.count_nonzero(np.concatenate(sums) <= observed)) / (1 + draws))


def _local_consistency_inputs(x1, points2, lines):
    """``x1`` (k, 3) with a nonzero last coordinate, ``points2`` (k, 2) and ``lines`` (k, 3)
    with unit or zero normals, finite, as float; ValueError or TypeError naming the one at fault."""
    x1 = as_finite_array(x1, "x1")
    points2 = as_finite_array(points2, "points2")
    lines = as_finite_array(lines, "lines")
    k = x1.shape[0] if x1.ndim == 2 else -1
    for name, array, width in (("x1", x1, 3), ("points2", points2, 2), ("lines", lines, 3)):
        if array.shape != (k, width):
            raise ValueError(
                f"x1, points2 and lines must be (k, 3), (k, 2) and (k, 3) of one k, got shapes "
                f"{x1.shape}, {points2.shape} and {lines.shape} ({name} at fault)"
            )
    if np.any(x1[:, 2] == 0):
        raise ValueError("x1 must have a nonzero last coordinate (points at infinity given)")
    normal = np.hypot(lines[:, 0], lines[:, 1])
    if not np.all((np.abs(normal - 1.0) < 1e-6) | (normal == 0)):
        raise ValueError("lines must have unit normals (a, b) (ppo_cv.significance.epipolar_lines)")
    return x1, points2, lines


def smallest_significant_consensus(
    num_matches: int,
    image_size2: tuple[int, int],
    threshold: float,
    max_log10_nfa: float,
    *,
    sample_size: int = ESSENTIAL_SAMPLE_SIZE,
    models_per_sample: int = ESSENTIAL_MODELS_PER_SAMPLE,
) -> int:
    """Fewest matches whose consensus can reach ``log10 NFA <= max_log10_nfa``.

    ``NFA(k)`` of :func:`epipolar_significance` for ``k`` of ``num_matches`` matches within a
    band of chance ``p = MIN_CONSENSUS_BAND * 2 threshold D / A`` (``D`` the diagonal and ``A``
    the area of image 2), the narrowest measured (:data:`MIN_CONSENSUS_BAND`): a smaller
    consensus is not significant unless its band is narrower still.

    Parameters
    ----------
    num_matches : int
        ``n``, the putative matches.
    image_size2 : (int, int)
        ``(width, height)`` of image 2, pixels.
    threshold : float
        Inlier threshold of the fit, pixels.
    max_log10_nfa : float
        The significance bar.
    sample_size, models_per_sample : int
        ``s`` and ``N_out`` of the minimal solver, whole numbers from 1.

    Returns
    -------
    int
        The smallest such ``k``; ``num_matches + 1`` when no consensus can be significant.
    """
    width, height = as_image_size(image_size2, "image_size2")
    n = as_whole_number(num_matches, "num_matches", 0, MAX_MATCHES)
    threshold = as_positive(threshold, "threshold")
    if as_number(max_log10_nfa, "max_log10_nfa") != max_log10_nfa:
        raise ValueError("max_log10_nfa must be a number (inf: every consensus), got nan")
    sample_size, models_per_sample = _as_solver(sample_size, models_per_sample)
    k = np.arange(sample_size + 1, n + 1)
    if k.size == 0:
        return n + 1
    band = MIN_CONSENSUS_BAND * 2.0 * threshold * np.hypot(width, height) / (width * height)
    log_p = np.minimum((k - sample_size) * np.log10(min(band, 1.0)), 0.0)
    log10_nfa = _log10_nfa(n, k, log_p, sample_size, models_per_sample)
    passing = k[log10_nfa <= max_log10_nfa]
    return int(passing[0]) if passing.size else n + 1


def require_significance(
    E: np.ndarray, x1: np.ndarray, x2: np.ndarray, K2: np.ndarray, size2: tuple[int, int],
    max_log10_nfa: float, ratios: np.ndarray,
) -> Significance:  # fmt: skip
    """The a-contrario test of an essential matrix ``E`` over all matches ``x1``, ``x2`` (N, 3)
    (:func:`epipolar_significance`, image 2 of ``size2`` = (width, height) pixels seen by
    ``K2``), for a weak consensus (``log10 NFA`` above :data:`CONFIDENT_LOG10_NFA`) the
    distinctiveness of its matches by their Lowe ``ratios`` (N,) (:func:`distinctiveness`):
    ``log10 NFA + log10 p <= CONFIDENT_LOG10_NFA``, and above :data:`LOCAL_CHECK_LOG10_NFA`
    its :func:`local_consistency` at most :data:`MAX_LOCAL_P`; ``max_log10_nfa`` inf turns
    all three off. Returns the :class:`Significance`; ValueError "no reliable two-view
    geometry" with the figures when the consensus may be chance (``log10 NFA`` above
    ``max_log10_nfa``, not distinctive enough, or not locally consistent); ValueError or
    TypeError naming an argument of another shape or kind."""
    E, (x1, x2), K2 = as_matrix3(E, "E"), as_matched_rows(x1, x2), as_camera_matrix(K2, "K2")
    size2, ratios = as_image_size(size2, "size2"), as_finite_array(ratios, "ratios")
    max_log10_nfa = as_number(max_log10_nfa, "max_log10_nfa")
    if np.isnan(max_log10_nfa):
        raise ValueError("max_log10_nfa must be a number or inf, got nan")
    if ratios.shape != (len(x1),):
        raise ValueError(f"ratios must be (N,) of the {len(x1)} matches, got {ratios.shape}")
    significance = epipolar_significance(E, x1, x2, K2, size2)
    refused = not significance.log10_nfa <= max_log10_nfa
    detail = f"log10 NFA {significance.log10_nfa:.1f} > {max_log10_nfa:g}"
    if not refused and CONFIDENT_LOG10_NFA < significance.log10_nfa and max_log10_nfa < np.inf:
        p_value = distinctiveness(ratios, significance.consistent)
        joint = significance.log10_nfa + np.log10(max(p_value, 1e-300))
        refused = not joint <= CONFIDENT_LOG10_NFA
        detail = (
            f"log10 NFA {significance.log10_nfa:.1f} and distinctiveness p = {p_value:.2f} of its "
            f"matches: {joint:.1f} > {CONFIDENT_LOG10_NFA:g}"
        )
    local = LOCAL_CHECK_LOG10_NFA < significance.log10_nfa and max_log10_nfa < np.inf
    if not refused and local:
        p_local = _consensus_local_consistency(E, x1, x2, K2, size2, significance)
        refused = not p_local <= MAX_LOCAL_P
        detail = (
            f"log10 NFA {significance.log10_nfa:.1f}, but its matches' neighbours in image 1 are "
            "no nearer in image 2 than points placed at random along their epipolar lines: "
            f"local consistency p = {p_local:.3f} > {MAX_LOCAL_P:g}"
        )
    if refused:
        raise ValueError(
            f"no reliable two-view geometry: the consensus may be chance ({detail}; best "
            f"{significance.num_consistent} of {significance.num_matches} matches within "
            f"{significance.threshold:.2f} px)"
        )
    return significance


def _consensus_local_consistency(E, x1, x2, K2, size2, significance: Significance) -> float:
    """:func:`local_consistency` of the consistent matches of ``significance`` (at most
    :data:`LOCAL_CONSISTENCY_MATCHES`, those of least residual) under ``E`` (3, 3), ``x1``,
    ``x2`` (N, 3) normalized, image 2 of ``size2`` pixels seen by ``K2`` (3, 3)."""
    K2 = np.asarray(K2, float)
    lines = _epipolar_lines(E, x1, K2)
    points2 = x2 @ K2.T
    points2 = points2[:, :2] / points2[:, 2:]
    residuals = np.abs(np.einsum("ij,ij->i", lines[:, :2], points2) + lines[:, 2])
    chosen = np.flatnonzero(significance.consistent)
    chosen = chosen[np.argsort(residuals[chosen], kind="stable")][:LOCAL_CONSISTENCY_MATCHES]
    return local_consistency(
        x1[chosen], points2[chosen], lines[chosen], size2, significance.threshold
    )


def require_checked_consensus(inliers: np.ndarray, checked: np.ndarray) -> int:
    """ValueError "no reliable two-view geometry" when fewer than :data:`MIN_CHECKED_INLIERS` of
    a general pose's ``inliers`` (N,) bool are ``checked`` (N,) bool, the subset whose residual
    the other inliers check (:func:`ppo_cv.refine.checked_inliers`): the pose rests on the
    matches it was fitted to and is tested by too few, as a chance consensus of a few matches.
    Returns the number checked."""
    for name, mask in (("inliers", inliers), ("checked", checked)):
        if np.asarray(mask).dtype != bool or np.ndim(mask) != 1:
            raise TypeError(f"{name} must be a mask of bool, shape (N,), got {shown(mask)}")
    if np.shape(inliers) != np.shape(checked):
        raise ValueError(
            f"inliers and checked must be of one length, got {np.size(inliers)} and "
            f"{np.size(checked)}"
        )
    count, total = int(np.count_nonzero(checked)), int(np.count_nonzero(inliers))
    if count < MIN_CHECKED_INLIERS:
        raise ValueError(
            f"no reliable two-view geometry: {count} of the pose's {total} inliers are checked "
            f"by the others (at least {MIN_CHECKED_INLIERS}; the rest hold it at leverage above "
            "one half): the pose is fitted to its matches, not tested by them, as a chance "
            "consensus may be"
        )
    return count


def ray_angles_deg(x1: np.ndarray, x2: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Angle, degrees, between the ray of each match in image 1 and its ray in image 2 carried
    into camera 1 by ``R`` (``X2 = R X1 + t``), (N,).

    Where the rays meet in front of both cameras it is the angle under which the point sees the
    two camera centres, whatever ``t``: 0 for a pure rotation.

    Parameters
    ----------
    x1, x2 : ndarray, shape (N, 3)
        Homogeneous normalized coordinates of the matches.
    R : ndarray, shape (3, 3)
        Rotation from camera 1 to camera 2.

    Raises
    ------
    ValueError, TypeError
        An argument of another shape or kind, named.
    """
    (x1, x2), R = as_matched_rows(x1, x2), as_rotation(R, "R")
    return np.atleast_1d(direction_error_deg(x1, x2 @ R))


def require_matchable_viewpoints(x1: np.ndarray, x2: np.ndarray, R: np.ndarray) -> float:
    """ValueError "no reliable two-view geometry" when the median of :func:`ray_angles_deg` of
    the inliers ``x1``, ``x2`` (N, 3) through ``R`` exceeds :data:`MAX_MEDIAN_RAY_ANGLE_DEG`:
    the pose has most of its consensus seen from directions no descriptor matches across, as a
    chance consensus of a few matches may. Returns that median, degrees (0 for no inliers);
    ValueError or TypeError naming an argument of another shape or kind."""
    (x1, x2), R = as_matched_rows(x1, x2), as_rotation(R, "R")
    if x1.shape[0] == 0:
        return 0.0
    median = float(np.median(ray_angles_deg(x1, x2, R)))
    if not median <= MAX_MEDIAN_RAY_ANGLE_DEG:
        raise ValueError(
            f"no reliable two-view geometry: the pose has its {x1.shape[0]} inliers seen from "
            f"directions a median {median:.0f} deg apart (at most {MAX_MEDIAN_RAY_ANGLE_DEG:g}: "
            "beyond it no descriptor matches a surface), as a chance consensus may"
        )
    return median
