"""Homography branch: robust fit, decomposition into (R, t, n) and the choice by PPO, with truth."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ppo_cv.data_gen import euler_to_matrix
from ppo_cv.homography import (
    estimate_homography,
    homography_sampson_errors,
    symmetric_transfer_errors,
)
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.plane import (
    decompose_homography,
    frontality,
    homography_from_pose,
    normalize_homography,
    planar_pose,
    refine_planar_pose,
    select_plane_pose,
    undistort_division,
)

FOCAL = 800.0


def random_plane_pose(rng: np.random.Generator):
    """A random pose and a plane facing camera 1: ``(R, t, n, d)``, ``n^T X1 = d``."""
    R = euler_to_matrix(rng.normal(0.0, [5.0, 5.0, 20.0]))
    t = rng.normal(size=3)
    n = euler_to_matrix(np.r_[rng.uniform(-40, 40, 2), 0.0])[:, 2]
    return R, t, n, rng.uniform(3.0, 8.0)


def plane_points(rng, n, d, count, half_width=0.5):
    """Normalized points of view 1 (N, 3) and the 3D points of the plane they see (N, 3)."""
    rays = np.column_stack([rng.uniform(-half_width, half_width, (count, 2)), np.ones(count)])
    return rays, rays * (d / (rays @ n))[:, None]


def views(X1, R, t, rng=None, noise_px=0.0):
    """Normalized homogeneous points of both views, Gaussian pixel noise of ``noise_px``."""
    X2 = X1 @ R.T + t
    x1, x2 = X1 / X1[:, 2:], X2 / X2[:, 2:]
    if noise_px:
        for x in (x1, x2):
            x[:, :2] += rng.normal(0.0, noise_px / FOCAL, (len(x), 2))
    return x1, x2


def true_candidate(cand, R, t, n) -> int:
    """Index of the candidate nearest to the truth."""
    gaps = [
        np.linalg.norm(cand.R[k] - R) + np.linalg.norm(cand.t[k] - t / np.linalg.norm(t))
        + np.linalg.norm(cand.n[k] - n)
        for k in range(4)
    ]  # fmt: skip
    return int(np.argmin(gaps))


# ------------------------------------------------------------------ decomposition


@pytest.mark.parametrize("seed", range(6))
def test_one_candidate_is_the_truth_and_every_candidate_rebuilds_h(seed):
    rng = np.random.default_rng(seed)
    R, t, n, d = random_plane_pose(rng)
    H = homography_from_pose(R, t, n, d) * rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 10.0)
    x1, X1 = plane_points(rng, n, d, 20)
    x2 = views(X1, R, t)[1]
    cand = decompose_homography(normalize_homography(H, x1, x2))
    k = true_candidate(cand, R, t, n)
    np.testing.assert_allclose(cand.R[k], R, atol=1e-9)
    np.testing.assert_allclose(cand.T[k], t / d, atol=1e-9)
    np.testing.assert_allclose(cand.n[k], n, atol=1e-9)
    for j in range(4):
        np.testing.assert_allclose(cand.R[j] @ cand.R[j].T, np.eye(3), atol=1e-12)
        assert np.linalg.det(cand.R[j]) == pytest.approx(1.0)
        assert np.linalg.norm(cand.n[j]) == pytest.approx(1.0)
        np.testing.assert_allclose(cand.R[j] + np.outer(cand.T[j], cand.n[j]), cand.H, atol=1e-9)
    np.testing.assert_allclose(cand.R[0], cand.R[1])
    np.testing.assert_allclose(cand.T[1], -cand.T[0])
    np.testing.assert_allclose(cand.n[3], -cand.n[2])
    assert not np.allclose(cand.R[0], cand.R[2], atol=1e-6)


@pytest.mark.parametrize("seed", range(6))
def test_decomposition_equals_opencv(seed):
    rng = np.random.default_rng(100 + seed)
    R, t, n, d = random_plane_pose(rng)
    H = normalize_homography(homography_from_pose(R, t, n, d) * 3.0)
    cand = decompose_homography(H)
    count, Rs, Ts, Ns = cv2.decomposeHomographyMat(H, np.eye(3))
    assert count == 4
    ours = [np.concatenate([cand.R[k].ravel(), cand.T[k], cand.n[k]]) for k in range(4)]
    theirs = [np.concatenate([Rs[k].ravel(), Ts[k].ravel(), Ns[k].ravel()]) for k in range(4)]
    for row in ours:
        assert min(np.abs(row - other).max() for other in theirs) < 1e-9


def test_pure_rotation_decomposes_to_zero_translation():
    R = euler_to_matrix([3.0, -4.0, 10.0])
    cand = decompose_homography(2.0 * R)
    for k in range(4):
        np.testing.assert_allclose(cand.R[k], R, atol=1e-9)
        np.testing.assert_allclose(cand.T[k], 0.0, atol=1e-9)


def test_planar_pose_of_a_rotation_has_no_translation():
    R = euler_to_matrix([3.0, -4.0, 10.0])
    x1 = np.column_stack([np.random.default_rng(1).uniform(-0.5, 0.5, (20, 2)), np.ones(20)])
    x2 = x1 @ R.T
    pose = planar_pose(-3.0 * R, x1, x2 / x2[:, 2:])
    np.testing.assert_allclose(pose.R, R, atol=1e-9)
    assert not pose.t.any() and pose.distance == np.inf
    assert not pose.supports.any() and not pose.ambiguous


def test_normalize_fixes_scale_and_sign():
    rng = np.random.default_rng(7)
    R, t, n, d = random_plane_pose(rng)
    H = homography_from_pose(R, t, n, d)
    x1, X1 = plane_points(rng, n, d, 15)
    x2 = views(X1, R, t)[1]
    np.testing.assert_allclose(normalize_homography(-4.0 * H, x1, x2), H, atol=1e-12)
    np.testing.assert_allclose(np.linalg.svd(normalize_homography(H))[1][1], 1.0)
    with pytest.raises(ValueError, match="rank"):
        normalize_homography(np.outer([1.0, 2, 3], [1.0, 0, 0]))
    with pytest.raises(ValueError, match="shape"):
        normalize_homography(np.eye(2))


# ------------------------------------------------------------------ choice by PPO


def protocol_planar_problems(count, noise_px, seed=0):
    """Planes at 30 m, tilted up to 35 degrees, seen under the paper's motion (Section 5)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        R = euler_to_matrix(rng.normal(0.0, [5.0, 5.0, 20.0]))
        phi = rng.uniform(0, 2 * np.pi)
        t = -R @ (0.5 * 4.2 * np.array([np.cos(phi), np.sin(phi), 0.0]))
        n = euler_to_matrix(np.r_[rng.uniform(-35, 35, 2), 0.0])[:, 2]
        _, X1 = plane_points(rng, n, 30.0 * n[2], 50, half_width=0.6)
        yield R, t, n, views(X1, R, t, rng, noise_px)


@pytest.mark.parametrize("seed", range(3))
def test_ppo_picks_the_true_candidate_noise_free(seed):
    for R, t, n, (x1, x2) in protocol_planar_problems(10, noise_px=0.0, seed=seed):
        d = 30.0 * n[2]
        pose = planar_pose(homography_from_pose(R, t, n, d) * -2.0, x1, x2)
        assert not pose.ambiguous
        np.testing.assert_allclose(pose.R, R, atol=1e-9)
        np.testing.assert_allclose(pose.t, t / np.linalg.norm(t), atol=1e-9)
        np.testing.assert_allclose(pose.n, n, atol=1e-9)
        assert pose.distance == pytest.approx(d / np.linalg.norm(t))
        assert pose.support == 50 and pose.inliers.all()
        assert np.all(pose.m1 > 0) and np.all(pose.m2 > 0)
        # the flipped (-T, -n) of the same rotation puts every point behind camera 1
        assert pose.supports[pose.candidate ^ 1] == 0
        # the other rotation loses points to one of the two inequalities
        assert pose.supports[pose.candidate ^ 2] < 50


def test_ppo_choice_on_noisy_planes_matches_truth_and_beats_visibility_filter():
    right_ppo = right_cv = 0
    problems = list(protocol_planar_problems(60, noise_px=2.0, seed=5))
    for R, t, n, (x1, x2) in problems:
        H, _ = cv2.findHomography(x1[:, :2], x2[:, :2], 0)
        pose = planar_pose(H, x1, x2)
        truth = true_candidate(pose.candidates, R, t, n)
        right_ppo += pose.candidate == truth
        c = pose.candidates
        kept = cv2.filterHomographyDecompByVisibleRefpoints(
            list(c.R), list(c.n.reshape(4, 3, 1)),
            x1[:, None, :2].astype(np.float32), x2[:, None, :2].astype(np.float32),
        )  # fmt: skip
        right_cv += kept is not None and kept.ravel().tolist() == [truth]
        if pose.candidate == truth:
            assert rotation_error_deg(pose.R, R) < 2.0
    assert right_ppo >= 0.95 * len(problems)
    assert right_ppo >= right_cv


def test_off_plane_matches_break_the_two_fold_ambiguity():
    # a small patch of a tilted plane seen under a large motion: both rotations keep every
    # plane point in front of both cameras; points off the plane tell them apart
    rng = np.random.default_rng(3)
    for _ in range(2):
        n = euler_to_matrix(np.r_[rng.uniform(-60, 60, 2), 0])[:, 2]
        xy = rng.uniform(-0.3, 0.3, (40, 2))
        R, t = euler_to_matrix(rng.normal(0, 10, 3)), rng.normal(size=3) * 1.5
    rays = np.column_stack([xy, np.ones(40)])
    X1 = rays * (4.0 / (rays @ n))[:, None]
    off = np.column_stack([rng.uniform(-1, 1, (15, 2)), rng.uniform(3, 6, 15)])
    x1, x2 = views(np.vstack([X1, off]), R, t)
    on_plane = np.arange(55) < 40
    H = homography_from_pose(R, t, n, 4.0)
    alone = planar_pose(H, x1[on_plane], x2[on_plane])
    assert alone.ambiguous and sorted(alone.supports.tolist()) == [0, 0, 40, 40]
    pose = planar_pose(H, x1, x2, on_plane, threshold=1e-6)
    np.testing.assert_allclose(pose.R, R, atol=1e-9)
    np.testing.assert_allclose(pose.t, t / np.linalg.norm(t), atol=1e-9)
    assert pose.ambiguous and pose.inliers.sum() == 40
    # two matches off the plane are too few to overrule the prior
    few = np.arange(55) < 42
    assert planar_pose(H, x1[few], x2[few], on_plane[few], 1e-6).candidate == alone.candidate


def test_two_fold_ambiguity_goes_to_the_plane_facing_both_cameras():
    # a narrow view of a nearly frontal plane under a sideways motion: both rotations keep
    # every point in front of both cameras; the false one sees the plane obliquely
    rng = np.random.default_rng(0)
    n = euler_to_matrix([10.0, -15.0, 0.0])[:, 2]
    R = euler_to_matrix([2.0, -8.0, 1.0])
    t = -R @ np.array([1.0, 0.2, 0.3])
    _, X1 = plane_points(rng, n, 4.0, 40, half_width=0.1)
    x1, x2 = views(X1, R, t)
    pose = planar_pose(homography_from_pose(R, t, n, 4.0), x1, x2)
    assert pose.ambiguous and sorted(pose.supports.tolist()) == [0, 0, 40, 40]
    np.testing.assert_allclose(pose.R, R, atol=1e-9)
    np.testing.assert_allclose(pose.n, n, atol=1e-9)
    scores = frontality(pose.candidates)
    assert scores[pose.candidate] == pytest.approx(n[2] + (R @ n)[2])
    assert scores[pose.candidate] > scores[pose.candidate ^ 2] + 0.5


def test_docstring_examples_run():
    import doctest

    import ppo_cv.plane

    result = doctest.testmod(ppo_cv.plane, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


def test_select_rejects_mismatched_shapes():
    cand = decompose_homography(homography_from_pose(np.eye(3), [1.0, 0, 0], [0, 0, 1.0], 4.0))
    with pytest.raises(ValueError, match="same shape"):
        select_plane_pose(cand, np.zeros((5, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="used"):
        select_plane_pose(cand, np.zeros((5, 2)), np.zeros((5, 2)), np.ones(4, bool))
    with pytest.raises(ValueError, match="inliers"):
        planar_pose(np.eye(3), np.zeros((5, 2)), np.zeros((5, 2)), np.ones(3, bool))


# ------------------------------------------------------------------ residuals and robust fit


def test_sampson_error_is_exact_for_an_affine_homography():
    rng = np.random.default_rng(11)
    x1 = np.column_stack([rng.uniform(-0.5, 0.5, (30, 2)), np.ones(30)])
    shift = rng.normal(0, 1e-3, (30, 2))
    x2 = x1.copy()
    x2[:, :2] += shift
    # for H = I the nearest consistent match is the midpoint: distance |shift| / sqrt(2)
    np.testing.assert_allclose(
        homography_sampson_errors(np.eye(3), x1, x2),
        np.linalg.norm(shift, axis=1) / np.sqrt(2),
        rtol=1e-9,
    )
    np.testing.assert_allclose(
        symmetric_transfer_errors(np.eye(3), x1, x2), np.sqrt(2) * np.linalg.norm(shift, axis=1)
    )


def test_sampson_error_matches_the_geometric_error_of_a_projective_homography():
    from scipy.optimize import least_squares

    rng = np.random.default_rng(12)
    R, t, n, d = random_plane_pose(rng)
    H = homography_from_pose(R, t, n, d)
    _, X1 = plane_points(rng, n, d, 8)
    x1, x2 = views(X1, R, t, rng, noise_px=2.0)
    sampson = homography_sampson_errors(H, x1, x2)
    for i in range(len(x1)):
        # gold standard: the nearest (x1', H x1') to the measured match
        def residual(p, i=i):
            q = H @ np.r_[p, 1.0]
            return np.r_[p - x1[i, :2], q[:2] / q[2] - x2[i, :2]]

        best = least_squares(residual, x1[i, :2], xtol=1e-15, ftol=1e-15, gtol=1e-15)
        assert sampson[i] == pytest.approx(np.linalg.norm(best.fun), rel=1e-3)


def planar_matches(seed, n_inliers=150, n_outliers=50, noise_px=0.5):
    rng = np.random.default_rng(seed)
    R, t, n, d = random_plane_pose(rng)
    t = 0.5 * t / np.linalg.norm(t)
    _, X1 = plane_points(rng, n, d, n_inliers)
    x1, x2 = views(X1, R, t, rng, noise_px)
    junk = np.column_stack([rng.uniform(-0.5, 0.5, (n_outliers, 2)), np.ones(n_outliers)])
    x2o = junk.copy()
    x2o[:, :2] += rng.uniform(-0.2, 0.2, (n_outliers, 2))
    truth = np.r_[np.ones(n_inliers, bool), np.zeros(n_outliers, bool)]
    return np.vstack([x1, junk]), np.vstack([x2, x2o]), truth, (R, t, n, d)


@pytest.mark.parametrize("backend", ["pycolmap", "opencv"])
def test_robust_fit_finds_the_plane_and_its_pose(backend):
    x1, x2, truth, (R, t, n, d) = planar_matches(21)
    fit = estimate_homography(x1, x2, FOCAL, backend=backend, threshold=2.0)
    assert fit is not None and fit.backend == backend
    assert np.count_nonzero(fit.inliers & truth) >= 0.97 * truth.sum()
    assert np.count_nonzero(fit.inliers & ~truth) <= 2
    assert np.median(fit.residuals[truth]) < 1.0
    assert np.median(fit.residuals[~truth]) > 10.0
    H_true = homography_from_pose(R, t, n, d)
    assert np.abs(fit.H - H_true).max() < 0.02
    pose = planar_pose(fit.H, x1, x2, fit.inliers, threshold=2.0 / FOCAL)
    assert rotation_error_deg(pose.R, R) < 0.5
    assert direction_error_deg(pose.t, t) < 3.0


@pytest.mark.parametrize("backend", ["pycolmap", "opencv"])
def test_fit_on_a_subset_finds_the_plane_among_all_matches(backend):
    x1, x2, truth, (R, t, n, d) = planar_matches(22, n_inliers=150, n_outliers=300)
    fit_on = truth.copy()
    fit_on[np.flatnonzero(truth)[::2]] = False  # half the plane and 10 outliers to fit on
    fit_on[np.flatnonzero(~truth)[:10]] = True
    fit = estimate_homography(x1, x2, FOCAL, backend=backend, threshold=2.0, fit_on=fit_on)
    assert fit is not None
    assert np.count_nonzero(fit.inliers & truth) >= 0.95 * truth.sum()
    assert np.count_nonzero(fit.inliers & ~truth) <= 3
    assert fit.residuals.shape == (len(x1),)
    assert np.abs(fit.H - homography_from_pose(R, t, n, d)).max() < 0.02
    with pytest.raises(ValueError, match="fit_on must be a boolean mask"):
        estimate_homography(x1, x2, FOCAL, fit_on=np.flatnonzero(truth))
    with pytest.raises(ValueError, match="at least 4"):
        estimate_homography(x1, x2, FOCAL, fit_on=np.arange(len(x1)) < 3)


def test_robust_fit_rejects_bad_input():
    x = np.column_stack([np.zeros((3, 2)), np.ones(3)])
    with pytest.raises(ValueError, match="at least 4"):
        estimate_homography(x, x, FOCAL)
    with pytest.raises(ValueError, match="backend"):
        estimate_homography(x, x, FOCAL, backend="ransac")
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        estimate_homography(np.zeros((10, 2)), np.zeros((10, 2)), FOCAL)
    with pytest.raises(ValueError, match="same length"):
        estimate_homography(np.ones((10, 3)), np.ones((9, 3)), FOCAL)
    with pytest.raises(ValueError, match="NaN"):
        estimate_homography(np.full((10, 3), np.nan), np.ones((10, 3)), FOCAL)
    with pytest.raises(ValueError, match="> 0"):
        estimate_homography(np.ones((10, 3)), np.ones((10, 3)), 0.0)


def _distort(x: np.ndarray, k1: float) -> np.ndarray:
    """OpenCV's radial model ``x (1 + k1 r^2)`` on normalized homogeneous points."""
    out = x.copy()
    out[:, :2] *= (1.0 + k1 * np.sum(x[:, :2] ** 2, axis=1))[:, None]
    return out


def _pose_errors(R, t, R_true, t_true) -> tuple[float, float]:
    return rotation_error_deg(R, R_true), direction_error_deg(t, t_true)


def _distorted_plane(seed: int, k1: float, noise_px: float = 0.5, count: int = 400):
    rng = np.random.default_rng(seed)
    R, t, n, d = random_plane_pose(rng)
    t = 0.3 * d * t / np.linalg.norm(t)
    x1, X = plane_points(rng, n, d, count, half_width=0.35)
    X2 = X @ R.T + t
    x2 = X2 / X2[:, 2:]
    keep = (X2[:, 2] > 0) & np.all(np.abs(x2[:, :2]) < 0.35, axis=1)
    y1, y2 = _distort(x1[keep], k1), _distort(x2[keep], k1)
    y1[:, :2] += rng.normal(0, noise_px / FOCAL, (len(y1), 2))
    y2[:, :2] += rng.normal(0, noise_px / FOCAL, (len(y2), 2))
    return (R, t, n, d), y1, y2


@pytest.mark.parametrize("seed", range(4))
def test_refinement_with_k1_recovers_the_pose_under_unmodelled_distortion(seed):
    k1 = 0.08 if seed % 2 else -0.06
    (R, t, _, _), y1, y2 = _distorted_plane(seed, k1)
    fit = estimate_homography(y1, y2, FOCAL, threshold=2.0)
    pose = planar_pose(fit.H, y1, y2, fit.inliers, threshold=1.0 / FOCAL)
    start = max(_pose_errors(pose.R, pose.t, R, t))
    T = pose.candidates.T[pose.candidate]
    refined = refine_planar_pose(
        pose.R, T, pose.n, y1, y2, fit.inliers, scale=2.0 / FOCAL, fit_k1=True
    )
    error = max(_pose_errors(refined.R, refined.t, R, t))
    assert error < 0.5 * start and error < 2.0
    assert refined.k1 == pytest.approx(k1, abs=0.03)
    assert refined.cost < refined.cost_start
    assert np.median(refined.residuals[fit.inliers]) < np.median(
        symmetric_transfer_errors(pose.candidates.H, y1, y2)[fit.inliers]
    )


@pytest.mark.parametrize("seed", range(3))
def test_refinement_without_distortion_keeps_k1_zero_and_does_not_lose_accuracy(seed):
    (R, t, n, d), y1, y2 = _distorted_plane(seed, 0.0, noise_px=0.5)
    fit = estimate_homography(y1, y2, FOCAL, threshold=2.0)
    pose = planar_pose(fit.H, y1, y2, fit.inliers, threshold=1.0 / FOCAL)
    # start from a perturbed candidate: the refinement must bring it back to the data
    R0 = euler_to_matrix(np.array([2.0, -2.0, 2.0])) @ pose.R
    T0 = pose.candidates.T[pose.candidate] * 1.2
    start = max(_pose_errors(R0, T0, R, t))
    refined = refine_planar_pose(R0, T0, pose.n, y1, y2, fit.inliers, scale=2.0 / FOCAL,
                                 fit_k1=True)  # fmt: skip
    error = max(_pose_errors(refined.R, refined.t, R, t))
    unrefined = max(_pose_errors(pose.R, pose.t, R, t))
    assert refined.k1 == 0.0 and np.isfinite(refined.k1_sigma)
    assert error < 0.5 * start and error < 1.1 * unrefined + 0.05
    assert refined.n @ n > np.cos(np.radians(2.0))
    assert refined.distance == pytest.approx(d / np.linalg.norm(t), rel=0.05)


def test_division_model_undoes_radial_distortion_to_first_order():
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(-0.3, 0.3, (50, 2)), np.ones(50)])
    back = undistort_division(_distort(x, 0.05), 0.05)
    assert np.max(np.abs(back - x)) < 2e-4  # second order: k1^2 r^5
    assert np.array_equal(undistort_division(x[:, :2], 0.0), x)


def test_refinement_rejects_mismatched_used_mask():
    (R, t, n, d), y1, y2 = _distorted_plane(0, 0.0)
    with pytest.raises(ValueError, match="used must have shape"):
        refine_planar_pose(R, t / d, n, y1, y2, np.ones(3, bool))


@pytest.mark.parametrize("seed", range(4))
def test_bounded_plane_search_finds_a_plane_holding_a_quarter_of_the_matches(seed):
    from ppo_cv.motion_model import plane_ransac_trials

    rng = np.random.default_rng(40 + seed)
    R, t, n, d = random_plane_pose(rng)
    clean1, X1 = plane_points(rng, n, d, 100)
    x1, x2 = views(X1, R, t, rng, noise_px=0.3)
    other1, other2 = (
        np.column_stack([rng.uniform(-0.5, 0.5, (300, 2)), np.ones(300)]) for _ in range(2)
    )
    x1, x2 = np.vstack([x1, other1]), np.vstack([x2, other2])
    fits = [
        estimate_homography(x1, x2, FOCAL, min_trials=1, max_trials=trials)
        for trials in (plane_ransac_trials(0.9999), 100_000)
    ]
    on_plane = [fit.inliers[:100].mean() for fit in fits]
    assert on_plane[0] > 0.7 and on_plane[0] >= on_plane[1] - 0.03
    assert fits[0].inliers[100:].mean() < 0.02


def test_plane_ransac_trials_refuses_a_confidence_outside_the_unit_interval():
    from ppo_cv.motion_model import plane_ransac_trials

    assert plane_ransac_trials(0.99) < plane_ransac_trials(0.9999) < 10_000
    for bad in (0.0, 1.0, 1.5):
        with pytest.raises(ValueError, match="confidence"):
            plane_ransac_trials(bad)
