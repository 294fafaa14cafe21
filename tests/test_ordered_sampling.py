"""Ordered sampling of the essential-matrix fit: ranked subset first, full fit when weak."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ppo_cv import ppo
from ppo_cv import robust as robust_module
from ppo_cv.data_gen import make_pair
from ppo_cv.features import detect_features, match_features, match_features_scored
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.pipeline import PairOptions, _normalize, estimate_pair
from ppo_cv.robust import estimate_essential_ordered, sampson_errors

FOCAL = 500.0
SIZE = (640, 480)


def synthetic_matches(num_inliers, num_outliers, seed=0):
    """Normalized matches of a known motion (0.3 px noise) plus uniform outliers."""
    rng = np.random.default_rng(seed)
    R = cv2.Rodrigues(np.array([0.05, -0.2, 0.03]))[0]
    t = np.array([1.0, 0.1, 0.2]) / np.linalg.norm([1.0, 0.1, 0.2])
    X = np.column_stack([rng.uniform(-3, 3, (num_inliers, 2)), rng.uniform(4, 10, num_inliers)])
    X2 = X @ R.T + t
    half = np.array(SIZE) / 2 / FOCAL
    x1 = X[:, :2] / X[:, 2:] + rng.normal(0, 0.3 / FOCAL, (num_inliers, 2))
    x2 = X2[:, :2] / X2[:, 2:] + rng.normal(0, 0.3 / FOCAL, (num_inliers, 2))
    o1 = rng.uniform(-half, half, (num_outliers, 2))
    o2 = rng.uniform(-half, half, (num_outliers, 2))
    ones = np.ones((num_inliers + num_outliers, 1))
    x1 = np.hstack([np.vstack([x1, o1]), ones])
    x2 = np.hstack([np.vstack([x2, o2]), ones])
    inlier = np.r_[np.ones(num_inliers, bool), np.zeros(num_outliers, bool)]
    return x1, x2, inlier, R, t


def pose_of(fit, x1, x2):
    chosen = ppo.select_pose(fit.E, x1[fit.inliers], x2[fit.inliers])
    return chosen.R, chosen.t


@pytest.fixture
def trial_caps(monkeypatch) -> list:
    """The ``max_trials`` of every robust fit, in order."""
    caps = []
    real = robust_module.estimate_essential

    def spy(*args, **kwargs):
        caps.append(kwargs["max_trials"])
        return real(*args, **kwargs)

    monkeypatch.setattr(robust_module, "estimate_essential", spy)
    return caps


def test_ranked_subset_suffices_when_the_best_matches_are_inliers(trial_caps):
    x1, x2, inlier, R, t = synthetic_matches(60, 240)
    scores = np.where(inlier, 0.4, 0.8) + np.linspace(0, 0.01, len(inlier))
    fit = estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, seed=1)
    assert fit.sampling == "ordered"
    assert trial_caps == [robust_module.ORDERED_MAX_TRIALS] * 2  # no full fit
    assert np.count_nonzero(fit.inliers & inlier) >= 55
    assert np.count_nonzero(fit.inliers & ~inlier) <= 5
    R_est, t_est = pose_of(fit, x1, x2)
    assert rotation_error_deg(R_est, R) < 0.5 and direction_error_deg(t_est, t, signed=False) < 2.0


@pytest.mark.parametrize(("trusted", "cap"), [(0.0, 100_000), (np.inf, 30_000)])
def test_falls_back_when_the_ranked_subset_is_all_outliers(trial_caps, monkeypatch, trusted, cap):
    monkeypatch.setattr(robust_module, "ORDERED_TRUSTED_LOG10_NFA", trusted)
    x1, x2, inlier, R, t = synthetic_matches(120, 180, seed=2)
    scores = np.where(inlier, 0.8, 0.3)  # the best-ranked half: outliers only
    fit = estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, seed=0, max_log10_nfa=np.inf)
    assert fit.sampling == "fallback"
    # a weak subset result (log10 NFA above the trusted bar) gets the full budget
    assert trial_caps[2] == cap
    assert np.count_nonzero(fit.inliers & inlier) >= 110
    R_est, t_est = pose_of(fit, x1, x2)
    assert rotation_error_deg(R_est, R) < 0.5 and direction_error_deg(t_est, t, signed=False) < 2.0


def test_fallback_respects_a_lower_max_trials(trial_caps):
    x1, x2, inlier, _, _ = synthetic_matches(120, 180, seed=2)
    estimate_essential_ordered(
        x1, x2, FOCAL, np.where(inlier, 0.8, 0.3), SIZE, max_trials=500, min_trials=50
    )
    assert trial_caps and max(trial_caps) == 500


@pytest.mark.parametrize(
    ("scores", "message"),
    [(np.zeros(3), "one score per match"), (np.full(300, np.nan), "finite")],
)
def test_bad_scores_are_named(scores, message):
    x1, x2, _, _, _ = synthetic_matches(100, 200)
    with pytest.raises(ValueError, match=message):
        estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE)


@pytest.fixture(scope="module")
def rendered():
    pair = make_pair("general", seed=0, index=1)
    f1 = detect_features(pair.image1[:, :, ::-1], "sift", 4000)
    f2 = detect_features(pair.image2[:, :, ::-1], "sift", 4000)
    return pair, f1, f2


def test_match_scores_are_the_ratio_and_rank_inliers_first(rendered):
    pair, f1, f2 = rendered
    matches, ratios = match_features_scored(f1, f2, ratio=0.9)
    np.testing.assert_array_equal(matches, match_features(f1, f2, ratio=0.9))
    assert ratios.shape == (len(matches),) and np.all((ratios >= 0) & (ratios < 0.9))
    x1 = _normalize(f1.keypoints[matches[:, 0]], pair.K1, None)
    x2 = _normalize(f2.keypoints[matches[:, 1]], pair.K2, None)
    E_true = robust_module.essential_from_pose(pair.R, pair.t)
    true_inlier = sampson_errors(E_true, x1, x2) * pair.K1[0, 0] < 2.0
    order = np.argsort(ratios)
    best, worst = order[: len(order) // 2], order[len(order) // 2 :]
    assert true_inlier[best].mean() > true_inlier[worst].mean()


def test_ordered_fit_on_a_rendered_pair_matches_ground_truth(rendered):
    pair, f1, f2 = rendered
    matches, ratios = match_features_scored(f1, f2, ratio=0.9)
    x1 = _normalize(f1.keypoints[matches[:, 0]], pair.K1, None)
    x2 = _normalize(f2.keypoints[matches[:, 1]], pair.K2, None)
    fit = estimate_essential_ordered(x1, x2, pair.K1[0, 0], ratios, SIZE)
    assert fit.sampling == "ordered"
    R, t = pose_of(fit, x1, x2)
    assert rotation_error_deg(R, pair.R) < 1.0
    assert direction_error_deg(t, pair.t, signed=False) < 3.0


@pytest.mark.parametrize("motion", ["general", "forward"])
def test_estimate_pair_with_and_without_ordered_sampling(motion):
    pair = make_pair(motion, seed=0, index=0)
    images = (pair.image1[:, :, ::-1], pair.image2[:, :, ::-1])
    for ordered in (True, False):
        options = PairOptions(ordered_sampling=ordered, max_trials=20_000)
        result = estimate_pair(*images, pair.K1_given, pair.K2_given, options=options)
        assert rotation_error_deg(result.R, pair.R) < 1.0, ordered
        assert direction_error_deg(result.t, pair.t, signed=False) < 3.0, ordered


@pytest.mark.parametrize("flag", ["--ordered-sampling", "--no-ordered-sampling"])
def test_pairs_command_passes_the_sampling_choice_on(monkeypatch, tmp_path, flag):
    from typer.testing import CliRunner

    from ppo_cv.cli import batch
    from ppo_cv.cli.main import app

    seen = []
    monkeypatch.setattr(batch, "run_pairs", lambda *args, **kwargs: seen.append(args[5]) or 0)
    pairs = tmp_path / "pairs.txt"
    pairs.write_text("a.png b.png\n")
    out = CliRunner().invoke(
        app, ["pairs", str(pairs), str(tmp_path), "--K", "500,500,320,240", flag]
    )
    assert out.exit_code == 0, out.output
    assert seen[0].ordered_sampling is (flag == "--ordered-sampling")
