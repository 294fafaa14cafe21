"""Ordered sampling of the essential-matrix fit: ranked subset first, full fit when weak."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ppo_cv import ppo
from ppo_cv import robust as robust_module
from ppo_cv.consensus import _normalize
from ppo_cv.data_gen import make_pair
from ppo_cv.features import detect_features, match_features, match_features_scored
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.pipeline import PairOptions, estimate_pair
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


@pytest.mark.parametrize("trusted", [0.0, np.inf])
def test_falls_back_when_the_ranked_subset_is_all_outliers(trial_caps, monkeypatch, trusted):
    monkeypatch.setattr(robust_module, "ORDERED_TRUSTED_LOG10_NFA", trusted)
    x1, x2, inlier, R, t = synthetic_matches(120, 180, seed=2)
    scores = np.where(inlier, 0.8, 0.3)  # the best-ranked half: outliers only
    fit = estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, seed=0, max_log10_nfa=np.inf)
    assert fit.sampling == "fallback"
    # a weak subset result (log10 NFA above the trusted bar) gets the full budget, and so does
    # a trusted one whose consensus of chance matches a rival of its size needs it for
    assert trial_caps[2] == 100_000
    assert np.count_nonzero(fit.inliers & inlier) >= 110
    R_est, t_est = pose_of(fit, x1, x2)
    assert rotation_error_deg(R_est, R) < 0.5 and direction_error_deg(t_est, t, signed=False) < 2.0


def test_fallback_respects_a_lower_max_trials(trial_caps):
    x1, x2, inlier, _, _ = synthetic_matches(120, 180, seed=2)
    estimate_essential_ordered(
        x1, x2, FOCAL, np.where(inlier, 0.8, 0.3), SIZE, max_trials=500, min_trials=50
    )
    assert trial_caps and max(trial_caps) == 500


@pytest.mark.parametrize(("inliers", "cap"), [(20, 100_000), (120, 30_000)])
def test_a_trusted_fallback_can_find_a_rival_as_large_as_the_ordered_consensus(
    trial_caps, monkeypatch, inliers, cap
):
    """A significant ordered result (log10 NFA between the fallback bar and the trusted one)
    is checked by a full fit, kept only with more inliers: its budget is what a rival of as
    many inliers needs to give an all-inlier sample with probability ``1 - eta`` (20 of 200:
    about 490,000 hypotheses, capped at ``max_trials``), never below ``FALLBACK_MAX_TRIALS``
    (120 of 300 needs a few dozen)."""
    monkeypatch.setattr(robust_module, "FALLBACK_MAX_LOG10_NFA", -np.inf)
    monkeypatch.setattr(robust_module, "ORDERED_TRUSTED_LOG10_NFA", np.inf)
    x1, x2, inlier, _, _ = synthetic_matches(inliers, 180, seed=3)
    scores = np.where(inlier, 0.4, 0.8) + np.linspace(0, 0.01, len(inlier))
    estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, seed=0, max_log10_nfa=np.inf)
    assert trial_caps[2] == cap


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


@pytest.mark.parametrize(("consensus", "matches"), [(12, 20), (9, 15), (30, 60)])
def test_trials_for_consensus_miss_it_with_probability_eta(consensus, matches):
    """Drawn samples, not the formula again: after the returned count of uniform samples of 5
    distinct matches, runs without an all-inlier sample are about ``eta`` (binomial margin);
    after half of it, clearly more."""
    eta = 0.05
    trials = int(robust_module.trials_for_consensus(consensus, matches, eta))
    rng = np.random.default_rng(7)
    runs = 4000

    def missed(count: int) -> float:
        keys = rng.random((runs, count, matches))
        samples = np.argsort(keys, axis=2)[:, :, :5]
        hit = np.all(samples < consensus, axis=2).any(axis=1)
        return 1.0 - hit.mean()

    margin = 3 * np.sqrt(eta * (1 - eta) / runs)
    assert missed(trials) <= eta + margin
    assert missed(max(trials // 2, 1)) > eta + margin


def test_trials_for_consensus_at_the_edges():
    assert robust_module.trials_for_consensus(4, 100, 0.05) == np.inf
    assert robust_module.trials_for_consensus(100, 100, 0.05) == 1
    assert robust_module.trials_for_consensus(5, 4, 0.05) == np.inf  # no sample of 5 exists


@pytest.mark.parametrize(
    ("arguments", "message"),
    [((10, 100, 0.0), "miss_probability"), ((10, 100, 1.0), "miss_probability")],
)  # fmt: skip
def test_trials_for_consensus_names_bad_arguments(arguments, message):
    with pytest.raises(ValueError, match=message):
        robust_module.trials_for_consensus(*arguments)


@pytest.mark.parametrize("num_inliers", [10, 13, 16, 20, 30])
def test_a_consensus_smaller_than_the_significant_one_is_not_significant(num_inliers):
    """Exact motions at the 0.3 px noise of real matches among uniform outliers: whenever the
    significance test passes the consensus, it holds at least the smallest significant
    consensus; the true consensus of 30 passes."""
    from ppo_cv.robust import essential_from_pose
    from ppo_cv.significance import epipolar_significance, smallest_significant_consensus

    n, bar = 150, 5.0
    smallest = smallest_significant_consensus(n, SIZE, 1.0, bar)
    assert 8 <= smallest <= 20
    K = np.array([[FOCAL, 0.0, SIZE[0] / 2], [0.0, FOCAL, SIZE[1] / 2], [0.0, 0.0, 1.0]])
    for seed in range(5):
        x1, x2, _, R, t = synthetic_matches(num_inliers, n - num_inliers, seed=seed)
        found = epipolar_significance(essential_from_pose(R, t), x1, x2, K, SIZE)
        if found.log10_nfa <= bar:
            assert found.num_consistent >= smallest, (seed, found)
        elif num_inliers == 30:
            raise AssertionError(f"a consensus of 30 of 150 was not significant: {found}")


def test_no_consensus_can_be_significant_among_too_few_matches():
    from ppo_cv.significance import smallest_significant_consensus

    assert smallest_significant_consensus(12, SIZE, 1.0, -50.0) == 13
    assert smallest_significant_consensus(3, SIZE, 1.0, 5.0) == 4
    assert smallest_significant_consensus(40, SIZE, 1.0, np.inf) == 6


def test_a_weak_fit_over_few_chance_matches_stops_at_the_significant_consensus(trial_caps):
    """Uniform matches only (no motion): the ordered result is weak, the full fit stops after
    the hypotheses that would have sampled the smallest significant consensus, well short of
    max_trials, and its consensus stays beyond the bar."""
    from ppo_cv.significance import (
        MISSED_CONSENSUS_PROBABILITY,
        epipolar_significance,
        smallest_significant_consensus,
    )

    x1, x2, _, _, _ = synthetic_matches(0, 40, seed=3)
    scores = np.linspace(0.5, 0.9, 40)
    fit = estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, seed=0)
    smallest = smallest_significant_consensus(40, SIZE, 1.0, 5.0)
    cap = robust_module.trials_for_consensus(smallest, 40, MISSED_CONSENSUS_PROBABILITY)
    assert trial_caps[-1] == int(cap) < 100_000
    K = np.array([[FOCAL, 0.0, SIZE[0] / 2], [0.0, FOCAL, SIZE[1] / 2], [0.0, 0.0, 1.0]])
    assert fit is None or epipolar_significance(fit.E, x1, x2, K, SIZE).log10_nfa > 5.0


def test_a_weak_result_left_to_the_caller_is_none_and_costs_no_full_fit(trial_caps):
    """Chance matches: with ``uniform_when_weak`` False the weak ordered result gives None
    after the ordered fits alone; with it, the full fit runs over all 40 matches."""
    x1, x2, _, _, _ = synthetic_matches(0, 40, seed=3)
    scores = np.linspace(0.5, 0.9, 40)
    assert estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE, uniform_when_weak=False) is None
    assert trial_caps and set(trial_caps) == {robust_module.ORDERED_MAX_TRIALS}
    estimate_essential_ordered(x1, x2, FOCAL, scores, SIZE)
    assert trial_caps[-1] != robust_module.ORDERED_MAX_TRIALS


@pytest.mark.slow
def test_a_weak_freiburg_pair_keeps_the_consensus_of_the_full_budget(freiburg, monkeypatch):
    """A wide-baseline freiburg pair (23 inliers among 155 matches) decided by the uniform fit:
    stopped by evidence, that fit returns the consensus that all 100,000 hypotheses find, and
    the pose stays within 5 degrees of the pseudo ground truth."""
    from ppo_cv.data_gen.io import read_pairs

    weak_fits = []
    real = robust_module._uniform_fit_to_evidence

    def spy(x1, x2, focal, image_size, max_trials, max_log10_nfa, settings):
        found = real(x1, x2, focal, image_size, max_trials, max_log10_nfa, settings)
        weak_fits.append((x1, x2, focal, settings, found))
        return found

    monkeypatch.setattr(robust_module, "_uniform_fit_to_evidence", spy)
    record = read_pairs(freiburg / "pairs_with_gt.txt")[37]
    images = [cv2.imread(str(freiburg / "images" / record[n])) for n in ("name1", "name2")]
    result = estimate_pair(*images, record["K1"], record["K2"])
    assert weak_fits
    for x1, x2, focal, settings, found in weak_fits:
        full = robust_module.estimate_essential(x1, x2, focal, max_trials=100_000, **settings)
        np.testing.assert_array_equal(found.inliers, full.inliers)
        np.testing.assert_allclose(found.E, full.E, atol=1e-12)
    assert rotation_error_deg(result.R, record["R"]) < 5.0
    assert direction_error_deg(result.t, record["t"]) < 5.0


def test_a_weak_freiburg_pair_pays_one_uniform_fit(freiburg, monkeypatch):
    """The same wide-baseline pair: ordered sampling does not settle its first features, the
    denser features' consensus is significant, so the first features are never fitted
    uniformly; one uniform fit, on the denser matches, and the pose within 5 degrees of the
    pseudo ground truth."""
    from ppo_cv.data_gen.io import read_pairs
    from ppo_cv.pipeline import REDETECT_THRESHOLD_SCALE

    ordered, uniform = [], []
    real_ordered = robust_module.estimate_essential_ordered
    real_uniform = robust_module._uniform_fit_to_evidence

    def ordered_spy(x1, *args, **kwargs):
        found = real_ordered(x1, *args, **kwargs)
        ordered.append((len(x1), kwargs.get("uniform_when_weak", True), found))
        return found

    def uniform_spy(x1, *args):
        uniform.append(len(x1))
        return real_uniform(x1, *args)

    monkeypatch.setattr(robust_module, "_uniform_fit_to_evidence", uniform_spy)
    monkeypatch.setattr("ppo_cv.consensus.estimate_essential_ordered", ordered_spy)
    record = read_pairs(freiburg / "pairs_with_gt.txt")[37]
    images = [cv2.imread(str(freiburg / "images" / record[n])) for n in ("name1", "name2")]
    result = estimate_pair(*images, record["K1"], record["K2"])
    (first, settle, unsettled), (denser, _, _) = ordered
    assert not settle and unsettled is None and denser > first
    assert uniform == [denser] == [len(result.matches)]
    assert result.evidence.significance.threshold_scale == REDETECT_THRESHOLD_SCALE
    assert rotation_error_deg(result.R, record["R"]) < 5.0
    assert direction_error_deg(result.t, record["t"]) < 5.0


def test_a_weak_freiburg_pair_is_not_settled_on_the_ordered_consensus(freiburg):
    """freiburg pair 61 at seed 0: ordered sampling gathers 18 of 142 matches at log10 NFA
    -0.3, inside the trusted band; the full fit that checks it was capped at 30,000
    hypotheses, which miss a consensus of 20 about a third of the time, and returned no larger
    one (the pose 39.6 degrees off). With the budget such a rival needs the pair keeps the
    larger, more significant consensus (20 inliers at -4.3; the pose 15.5 degrees off: the
    pair's matches hold rival consensus sets, ``docs/limits.md``)."""
    from ppo_cv.data_gen.io import read_pairs

    record = read_pairs(freiburg / "pairs_with_gt.txt")[61]
    images = [cv2.imread(str(freiburg / "images" / record[n])) for n in ("name1", "name2")]
    result = estimate_pair(*images, record["K1"], record["K2"])
    assert result.num_inliers >= 20
    assert result.evidence.significance.log10_nfa < -4.0
