"""The paper's math (ppo_cv.ppo) against exact synthetic geometry."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from twoview import make_scene, project, random_rotation, skew

from ppo_cv import ppo

K = np.array([[800.0, 0.0, 512.0], [0.0, 800.0, 512.0], [0.0, 0.0, 1.0]])
W1T = ppo.W1.T


def _random_pose(rng):
    t = rng.normal(size=3)
    return random_rotation(rng, 40.0), t * rng.uniform(0.2, 3.0) / np.linalg.norm(t)


def _normalized_scene(rng, n=80, noise_px=0.0, R=None, t=None):
    if R is None:
        R, t = _random_pose(rng)
    X, p1, p2 = make_scene(rng, n, R, t, K, noise_px=noise_px)
    return X, ppo.normalize(p1, K), ppo.normalize(p2, K), R, t


def test_noise_free_random_poses_are_recovered_exactly():
    rng = np.random.default_rng(0)
    for _ in range(300):
        X, x1, x2, R, t = _normalized_scene(rng)
        E = skew(t) @ R * rng.choice([-1.0, 1.0]) * rng.uniform(1e-3, 1e3)
        sel = ppo.select_pose(E, x1, x2)
        np.testing.assert_allclose(sel.R, R, atol=1e-9)
        np.testing.assert_allclose(sel.t, t / np.linalg.norm(t), atol=1e-9)
        assert (sel.support_R, sel.support_R_rejected) == (len(X), 0)
        assert (sel.support_t, sel.support_t_rejected) == (len(X), 0)
        points = ppo.analytic_points(x1, x2, sel.R, sel.t)
        np.testing.assert_allclose(points, X / np.linalg.norm(t), rtol=1e-7, atol=1e-9)


def test_analytic_depths_match_both_cameras():
    rng = np.random.default_rng(1)
    X, x1, x2, R, t = _normalized_scene(rng)
    z1, z2 = ppo.analytic_depths(x1, x2, R, t)
    scale = np.linalg.norm(t)
    np.testing.assert_allclose(z1 * scale, X[:, 2], rtol=1e-9)
    np.testing.assert_allclose(z2 * scale, (X @ R.T + t)[:, 2], rtol=1e-9)


def test_decomposition_is_independent_of_scale_and_sign():
    rng = np.random.default_rng(2)
    R, t = _random_pose(rng)
    E = skew(t) @ R
    ref = ppo.decompose_essential(E)
    for factor in (-1.0, 1e-6, 1e6, -37.0):
        cand = ppo.decompose_essential(factor * E)
        for Rc in (ref.R1, ref.R2):
            assert min(np.abs(Rc - Ri).max() for Ri in (cand.R1, cand.R2)) < 1e-9
        assert min(np.abs(cand.t - ref.t).max(), np.abs(cand.t + ref.t).max()) < 1e-9


@pytest.mark.parametrize("noise", [0.0, 1e-3, 1e-1])
def test_candidates_are_rotations_and_explain_the_essential_matrix(noise):
    rng = np.random.default_rng(3)
    R, t = _random_pose(rng)
    E = skew(t) @ R + noise * rng.normal(size=(3, 3))
    cand = ppo.decompose_essential(E)
    for Rc in (cand.R1, cand.R2):
        np.testing.assert_allclose(Rc @ Rc.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rc) == pytest.approx(1.0)
    assert np.linalg.norm(cand.t) == pytest.approx(1.0)
    if noise == 0.0:
        for Rc in (cand.R1, cand.R2):
            Ec = skew(cand.t) @ Rc
            cos = np.sum(Ec * E) / (np.linalg.norm(Ec) * np.linalg.norm(E))
            assert abs(cos) == pytest.approx(1.0)
        np.testing.assert_allclose(cand.singular_values, [2**-0.5, 2**-0.5, 0.0], atol=1e-12)


def test_rank_one_essential_matrix_still_gives_rotations():
    E = np.outer([1.0, 2.0, 3.0], [0.5, -1.0, 2.0])
    cand = ppo.decompose_essential(E)
    for Rc in (cand.R1, cand.R2):
        np.testing.assert_allclose(Rc @ Rc.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rc) == pytest.approx(1.0)


def test_same_side_scores_flip_between_rotations_and_intersection_ignores_rotation():
    rng = np.random.default_rng(4)
    _, x1, x2, R, t = _normalized_scene(rng, noise_px=1.0)
    cand = ppo.decompose_essential(skew(t) @ R)
    m1_a = ppo.same_side_scores(x1, x2, cand.R1, cand.t)
    m1_b = ppo.same_side_scores(x1, x2, cand.R2, cand.t)
    np.testing.assert_allclose(m1_a, -m1_b, atol=1e-12)  # eq. 68
    m2_a = ppo.intersection_scores(x1, x2, cand.R1, cand.t)
    m2_b = ppo.intersection_scores(x1, x2, cand.R2, cand.t)
    np.testing.assert_allclose(m2_a, m2_b, atol=1e-12)  # eq. 74-75
    np.testing.assert_allclose(ppo.intersection_scores(x1, x2, cand.R1, -cand.t), -m2_a)


def test_scores_match_their_geometric_definitions():
    rng = np.random.default_rng(5)
    _, x1, x2, R, t = _normalized_scene(rng, noise_px=2.0)
    X1 = np.c_[x1, np.ones(len(x1))]
    X2 = np.c_[x2, np.ones(len(x2))]
    e = t / np.linalg.norm(t)
    m1 = np.einsum("ij,ij->i", np.cross(e, X1 @ R.T), np.cross(e, X2))  # eq. 65
    np.testing.assert_allclose(ppo.same_side_scores(x1, x2, R, t), m1, atol=1e-12)
    n1, n2 = np.linalg.norm(X1, axis=1), np.linalg.norm(X2, axis=1)
    cos1 = X2 @ e / n2
    cos2 = (X1 @ R.T) @ e / n1
    np.testing.assert_allclose(ppo.intersection_scores(x1, x2, R, t), n1 * n2 * (cos1 - cos2))
    sin3 = np.linalg.norm(np.cross(X2, X1 @ R.T), axis=1) / (n1 * n2)
    assert ppo.m3_indicator(x1, x2, R) == pytest.approx(np.mean(sin3))
    np.testing.assert_allclose(ppo.same_side_scores(X1, X2, R, t), m1, atol=1e-12)


@pytest.mark.parametrize("n", [7, 8192, 20001])  # one block, exactly one, several
def test_frame_scores_equal_the_scores_of_r1_and_u3(n):
    rng = np.random.default_rng(12)
    R, t = _random_pose(rng)
    _, p1, p2 = make_scene(rng, n, R, t, K, noise_px=1.0)
    E = (skew(t) @ R + rng.normal(scale=1e-3, size=(3, 3))) * -3.0  # noisy, any scale and sign
    cand = ppo.decompose_essential(E)
    x1, x2 = ppo.normalize(p1, K), ppo.normalize(p2, K)
    m1 = ppo.same_side_scores(x1, x2, cand.R1, cand.t)
    m2 = ppo.intersection_scores(x1, x2, cand.R1, cand.t)
    maps = np.array((W1T @ cand.Vt, cand.U.T))
    rays = np.array((np.c_[x1, np.ones(n)].T, np.c_[x2, np.ones(n)].T))
    pixels = np.array((np.c_[p1, np.ones(n)].T, np.c_[p2, np.ones(n)].T))
    for F, points in ((maps, rays), (maps @ np.linalg.inv(K), pixels)):
        f1, f2 = ppo.frame_scores(F, points)
        np.testing.assert_allclose(f1, m1, atol=1e-12)
        np.testing.assert_allclose(f2, m2, atol=1e-12)


def test_pure_rotation_rotation_is_a_candidate_and_is_chosen():
    """Proposition 7: for t = 0 any Q = R [a]x solves the essential equation (eq. 52)."""
    rng = np.random.default_rng(6)
    for _ in range(50):
        R = random_rotation(rng, 40.0)
        X, x1, x2, _, _ = _normalized_scene(rng, R=R, t=np.zeros(3))
        Q = R @ skew(rng.normal(size=3))
        sel = ppo.select_pose(Q, x1, x2)
        np.testing.assert_allclose(sel.R, R, atol=1e-9)
        assert sel.support_R == len(X)
        assert ppo.pure_rotation_indicator(sel.m2) < 1e-12  # Proposition 8
        assert ppo.m3_indicator(x1, x2, sel.R) < 1e-12
        np.testing.assert_allclose(ppo.rotation_from_rays(x1, x2), R, atol=1e-12)


def test_pri_separates_parallax_from_pure_rotation():
    rng = np.random.default_rng(7)
    R = random_rotation(rng, 10.0)
    _, x1, x2, _, t = _normalized_scene(rng, R=R, t=np.array([1.0, 0.2, 0.0]), noise_px=0.5)
    sel = ppo.select_pose(skew(t) @ R, x1, x2)
    assert ppo.pure_rotation_indicator(sel.m2) > 5 * ppo.DEFAULT_PRI_THRESHOLD
    assert np.isnan(ppo.pure_rotation_indicator(np.empty(0)))


@pytest.mark.filterwarnings("error")
def test_points_at_infinity_get_infinite_depth_and_nan_points_without_warnings():
    rng = np.random.default_rng(8)
    X, x1, x2, R, t = _normalized_scene(rng, n=20)
    x2 = x2.copy()
    far = ppo.normalize(project(K, (np.c_[x1[:5], np.ones(5)] * 1e30) @ R.T), K)
    x2[:5] = far
    z1, z2 = ppo.analytic_depths(x1, x2, R, t)
    assert np.all(np.isinf(z1[:5])) and np.all(np.isinf(z2[:5]))
    assert np.all(np.isfinite(z1[5:]))
    points = ppo.analytic_points(x1, x2, R, t)
    assert np.isnan(points[:5]).all() and np.isfinite(points[5:]).all()


@pytest.mark.parametrize("alpha, max_ratio", [(0.01, 0.5), (1.0, 1.05)])
def test_analytic_points_beat_dlt_at_small_parallax(alpha, max_ratio):
    """Fig. 7: the analytic reconstruction is much better than DLT at small parallax."""
    rng = np.random.default_rng(9)
    errors_analytic, errors_dlt = [], []
    for _ in range(30):
        R = random_rotation(rng, 10.0)
        direction = np.r_[rng.normal(size=2), 0.0]
        t = direction / np.linalg.norm(direction) * 4.2 * alpha
        X = rng.uniform([-15, -15, 15], [15, 15, 45], (100, 3))
        p1 = project(K, X) + rng.normal(0, 1.0, (100, 2))
        p2 = project(K, X @ R.T + t) + rng.normal(0, 1.0, (100, 2))
        x1, x2 = ppo.normalize(p1, K), ppo.normalize(p2, K)
        scale = np.linalg.norm(t)
        analytic = ppo.analytic_points(x1, x2, R, t) * scale
        H = cv2.triangulatePoints(np.eye(3, 4), np.c_[R, t], x1.T, x2.T)
        dlt = (H[:3] / H[3]).T
        errors_analytic.append(np.sqrt(np.nanmean(np.sum((analytic - X) ** 2, axis=1))))
        errors_dlt.append(np.sqrt(np.mean(np.sum((dlt - X) ** 2, axis=1))))
    assert np.median(errors_analytic) < max_ratio * np.median(errors_dlt)


def test_normalize_inverts_the_camera_matrix_with_skew():
    Ks = np.array([[700.0, 3.0, 300.0], [0.0, 650.0, 200.0], [0.0, 0.0, 1.0]])
    rng = np.random.default_rng(10)
    x = rng.normal(size=(10, 2))
    pixels = (np.c_[x, np.ones(10)] @ Ks.T)[:, :2]
    np.testing.assert_allclose(ppo.normalize(pixels, Ks), x, atol=1e-12)


_X = np.column_stack([np.linspace(-0.3, 0.3, 8), np.linspace(0.2, -0.2, 8)])
_E = skew([1.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "call, error, words",
    [(lambda: ppo.decompose_essential(None), TypeError, "E is required"),
     (lambda: ppo.decompose_essential(np.full((3, 3), np.nan)), ValueError, "E has 9 NaN"),
     (lambda: ppo.decompose_essential(np.zeros(9)), ValueError, "E must be a 3x3 matrix"),
     (lambda: ppo.decompose_essential(np.zeros((3, 3))), ValueError, "E is all zeros"),
     (lambda: ppo.select_pose(_E, None, _X), TypeError, "x1 is required"),
     (lambda: ppo.select_pose(_E, _X, _X.tolist()[:5]), ValueError,
      "x1 and x2 must have the same length, got 8 and 5"),
     (lambda: ppo.select_pose(_E, _X, _X.T), ValueError, "x2 must have shape (N, 3)"),
     (lambda: ppo.select_pose(_E, _X, _X, used=np.ones(8)), TypeError,
      "used must be a bool array of shape (8,), got float64"),
     (lambda: ppo.normalize(None, K), TypeError, "points is required"),
     (lambda: ppo.normalize(_X.tolist(), None), TypeError, "K is required"),
     (lambda: ppo.normalize(_X, K.ravel()), ValueError, "K must be a 3x3 matrix"),
     (lambda: ppo.same_side_scores(_X, _X, np.eye(3), np.zeros(3)), ValueError,
      "t is zero: it has no direction"),
     (lambda: ppo.intersection_scores(_X, _X[:3], np.eye(3), [1, 0, 0]), ValueError,
      "x1 and x2 must have the same length, got 8 and 3"),
     (lambda: ppo.analytic_points(_X, _X, np.eye(2), [1, 0, 0]), ValueError,
      "R must be a 3x3 matrix, got shape (2, 2)"),
     (lambda: ppo.analytic_depths(_X, None, np.eye(3), [1, 0, 0]), TypeError,
      "x2 is required"),
     (lambda: ppo.m3_indicator(_X.tolist(), _X, np.full((3, 3), np.nan)), ValueError,
      "R has 9 NaN"),
     (lambda: ppo.pure_rotation_indicator(None), ValueError,
      "m2 must be scores of shape (N,), got shape ()"),
     (lambda: ppo.pure_rotation_indicator([0.1, np.nan]), ValueError, "m2 has 1 NaN"),
     (lambda: ppo.rotation_from_rays(_X, None), TypeError, "x2 is required"),
     (lambda: ppo.rotation_from_rays(_X, _X[:4]), ValueError, "x1 and x2 must have the same")],
    ids=["E None", "E NaN", "E flat", "E zeros", "x1 None", "lengths", "x2 transposed",
         "used floats", "points None", "K None", "K flat", "zero t", "score lengths",
         "R 2x2", "depths None", "m3 NaN R", "PRI None", "PRI NaN", "rays None",
         "rays lengths"],
)  # fmt: skip
def test_the_paper_s_functions_name_a_bad_argument(call, error, words):
    # numpy's LinAlgError ("0-dimensional array given", "SVD did not converge"), an
    # AttributeError ("'NoneType' object has no attribute 'shape'") or a RuntimeWarning and
    # candidates of NaN for a zero E
    with pytest.raises(error) as info:
        call()
    assert words in str(info.value)


def test_the_paper_s_functions_take_lists_and_homogeneous_points():
    homogeneous = np.column_stack([_X, np.ones(8)])
    chosen = ppo.select_pose(_E.tolist(), _X.tolist(), homogeneous)
    expected = ppo.select_pose(_E, _X, _X)
    assert np.array_equal(chosen.R, expected.R) and np.array_equal(chosen.m1, expected.m1)
    np.testing.assert_allclose(ppo.normalize(_X.tolist(), K.tolist()), (_X - 512.0) / 800.0)
    assert ppo.pure_rotation_indicator([0.1, -0.3]) == pytest.approx(0.2)
    depths = ppo.analytic_depths(_X.tolist(), homogeneous, np.eye(3).tolist(), [[1], [0], [0]])
    assert np.all(np.isinf(depths[0]))  # identical rays: parallel, no depth
