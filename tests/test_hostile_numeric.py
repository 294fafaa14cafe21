"""Hostile input to the numeric helpers: the epipolar residuals of :mod:`ppo_cv.robust`, the
pose functions of :mod:`ppo_cv.refine` given no translation, the choice of rotation, the window
overlap of the tracks, the bounds of the consensus test and of the paper's protocol.

Each case is (call, exception type, words naming the argument); after them the behaviours that
are not errors: any scale of ``E`` and ``t``, the same figures from the checked and unchecked
forms, and a pipeline that never pays the checks in its loops.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ppo_cv
from ppo_cv import photometric, refine, robust, rotation_choice, significance, valley
from ppo_cv.data_gen import given_intrinsics, paper_protocol
from ppo_cv.data_gen.protocol import MAX_ALPHA
from ppo_cv.limits import MAX_MATCHES
from ppo_cv.parallax import PlaneParallax
from ppo_cv.rotation import fit_rotation_lens

K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])


def _turn(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _matches():
    """60 rays of a 0.1 radian pan, 1e-3 of noise: (x1, x2) (60, 3)."""
    rng = np.random.default_rng(0)
    x1 = np.column_stack([rng.uniform(-0.4, 0.4, (60, 2)), np.ones(60)])
    seen = x1 @ _turn(0.1).T
    x2 = seen / seen[:, 2:]
    x2[:, :2] += rng.normal(0.0, 1e-3, (60, 2))
    return x1, x2


X1, X2 = _matches()
USED = np.ones(60, bool)
E = robust.essential_from_pose(_turn(0.1), [1.0, 0.2, 0.1])
LENS = fit_rotation_lens(X1, X2, USED, _turn(0.1))
PARALLAX = PlaneParallax(np.eye(3), 0.01, 0.001, np.zeros(3))
ESTIMATE = rotation_choice.RotationEstimate("rotation", np.eye(3), 0.1, 0.2)


def _with(array: np.ndarray, value: float) -> np.ndarray:
    changed = array.copy()
    changed[3, 0] = value
    return changed


def _zero_t(name: str, *extra, **keywords):
    return lambda: getattr(refine, name)(np.eye(3), np.zeros(3), X1, X2, *extra, **keywords)


CASES = {
    # robust: numpy's AxisError for None, a silent NaN error, a broadcast error, a NaN E
    "sampson_errors E None": (lambda: robust.sampson_errors(None, X1, X2), TypeError,
                              "E is required, got None"),
    "sampson_errors NaN match": (lambda: robust.sampson_errors(E, _with(X1, np.nan), X2),
                                 ValueError, "x1 has 1 NaN or infinite value(s)"),
    "sampson_errors lengths": (lambda: robust.sampson_errors(E, X1, X2[:50]), ValueError,
                               "x1 and x2 must hold as many matches, got 60 and 50"),
    "sampson_errors points (N, 2)": (lambda: robust.sampson_errors(E, X1[:, :2], X2), ValueError,
                                     "x1 must have shape (N, 3) or (..., N, 3), got (60, 2)"),
    "sampson_errors E 2x2": (lambda: robust.sampson_errors(np.eye(2), X1, X2), ValueError,
                             "E must be a 3x3 matrix or a stack (..., 3, 3), got shape (2, 2)"),
    "sampson_errors E zero": (lambda: robust.sampson_errors(np.zeros((3, 3)), X1, X2),
                              ValueError, "E is all zeros"),
    "sampson_errors points 1e300": (
        lambda: robust.sampson_errors(E, X1, np.vstack([[1e300, 0.0, 1.0], X2[1:]])), ValueError,
        "x2 has coordinates up to 1e+300, beyond 1e+08"),
    "sampson_errors E text": (lambda: robust.sampson_errors("E", X1, X2), TypeError,
                              "E must be an array of real numbers, got str"),
    "sampson_signed stacks": (lambda: robust.sampson_signed(np.stack([E] * 3),
                                                            np.stack([X1] * 2), X2),
                              ValueError, "the leading axes of E (3, 3, 3), x1 (2, 60, 3)"),
    "sampson_signed_rows lengths": (lambda: robust.sampson_signed_rows(E, X1.T, X2.T[:, :5]),
                                    ValueError, "X1 and X2 must hold as many matches"),
    "sampson_signed_rows rows given": (lambda: robust.sampson_signed_rows(E, X1, X2), ValueError,
                                       "X1 must have shape (..., 3, N), got (60, 3)"),
    "essential_from_pose NaN t": (lambda: robust.essential_from_pose(np.eye(3), [np.nan, 0, 0]),
                                  ValueError, "t has 1 NaN or infinite value(s)"),
    "essential_from_pose zero t": (lambda: robust.essential_from_pose(np.eye(3), [0, 0, 0]),
                                   ValueError, "t is zero: a pure rotation has no essential"),
    "essential_from_pose R ones": (lambda: robust.essential_from_pose(np.ones((3, 3)), [1, 0, 0]),
                                   ValueError, "R is not a rotation matrix"),
    # refine: a zero t answered NaN
    "refine_pose zero t": (_zero_t("refine_pose", USED, 500.0), ValueError, "t is zero"),
    "refine_pose_radial zero t": (_zero_t("refine_pose_radial", USED, scale=1e-3), ValueError,
                                  "t is zero"),
    "k1_noise_bias zero t": (_zero_t("k1_noise_bias", scale=1e-3), ValueError, "t is zero"),
    "refine_pose_huber zero t": (_zero_t("refine_pose_huber", USED, scale=1e-3), ValueError,
                                 "t is zero"),
    "refine_pose_huber NaN scale": (
        lambda: refine.refine_pose_huber(np.eye(3), [1.0, 0, 0], X1, X2, USED, scale=np.nan),
        ValueError, "scale must be a finite number > 0, got nan"),
    "refine_pose_huber no iterations": (
        lambda: refine.refine_pose_huber(np.eye(3), [1.0, 0, 0], X1, X2, USED, scale=1e-3,
                                         iterations=0),
        ValueError, "iterations"),
    "released_lens_shift_deg zero t": (
        lambda: refine.released_lens_shift_deg(np.eye(3), np.zeros(3), 0.0, X1, X2, USED, 1e-3),
        ValueError, "t is zero"),
    "pose_information zero t": (_zero_t("pose_information", USED), ValueError, "t is zero"),
    "pose_sigmas_deg zero t": (_zero_t("pose_sigmas_deg", USED), ValueError, "t is zero"),
    "translation_sigma_deg zero t": (_zero_t("translation_sigma_deg", USED), ValueError,
                                     "t is zero"),
    "checked_inliers zero t": (_zero_t("checked_inliers", USED), ValueError, "t is zero"),
    "valley_minima zero t": (lambda: valley.valley_minima(np.eye(3), np.zeros(3), X1, X2, 1e-3),
                             ValueError, "t is zero"),
    # photometric: a flood of RuntimeWarnings, numpy's errors, a petabyte asked for
    "window_overlap None": (lambda: photometric.window_overlap(None, None), TypeError,
                            "points is required, got None"),
    "window_overlap NaN": (lambda: photometric.window_overlap([[1.0, 2.0], [np.nan, 3.0]]),
                           ValueError, "points has 1 NaN or infinite value(s)"),
    "window_overlap window 0": (lambda: photometric.window_overlap([[0, 0]], 0), ValueError,
                                "window must be a whole number in 1.."),
    "window_overlap window text": (lambda: photometric.window_overlap([[0, 0]], "21"), TypeError,
                                   "window must be a whole number, got str"),
    "window_overlap far apart": (lambda: photometric.window_overlap([[0, 0], [1e7, 1e7]]),
                                 ValueError, "points and their windows span 10000021x10000021"),
    "window_overlap huge window": (lambda: photometric.window_overlap([[0, 0]], 10**6),
                                   ValueError, "span 1000000x1000000 pixels, beyond 100000000"),
    # rotation_choice: AttributeErrors of None, IndexErrors, LinAlgErrors, silent NaN
    "rotation_fit_sigma_deg lens None": (
        lambda: rotation_choice.rotation_fit_sigma_deg(None, X1, X2, USED), TypeError,
        "lens must be a ppo_cv.rotation.LensRotationFit, got NoneType"),
    "rotation_fit_sigma_deg NaN match": (
        lambda: rotation_choice.rotation_fit_sigma_deg(LENS, _with(X1, np.nan), X2, USED),
        ValueError, "x1 has 1 NaN"),
    "focal_bias_deg lengths": (lambda: rotation_choice.focal_bias_deg(LENS, X1, X2[:50], USED),
                               ValueError, "x1 and x2 must have the same length, got 60 and 50"),
    "focal_trade_deg index mask": (
        lambda: rotation_choice.focal_trade_deg(LENS, X1, X2, np.arange(10)), TypeError,
        "used must be a boolean mask of the matches, got dtype int64"),
    "focal_trade_deg step NaN": (
        lambda: rotation_choice.focal_trade_deg(LENS, X1, X2, USED, np.nan), ValueError,
        "step must be a finite number > 0, got nan"),
    "focal_bias_deg step 1e300": (
        lambda: rotation_choice.focal_bias_deg(LENS, X1, X2, USED, 1e300), ValueError,
        "step must be in (0, 0.01] (a finite difference)"),
    "given_focal_fit x2 text": (lambda: rotation_choice.given_focal_fit(LENS, X1, "x2", USED),
                                TypeError, "x2 must be an array of real numbers, got str"),
    "matches_parallax points 1e300": (
        lambda: rotation_choice.matches_parallax(LENS, X1 * 1e300, X2, USED), ValueError,
        "x1 has coordinates up to 1e+300"),
    "wanted_focal_fit scale 0": (
        lambda: rotation_choice.wanted_focal_fit(LENS, X1, X2, USED, 0.0), ValueError,
        "scale must be a finite number > 0"),
    "across_normal_parallax NaN": (
        lambda: rotation_choice.across_normal_parallax(np.full((3, 3), np.nan)), ValueError,
        "H has 9 NaN or infinite value(s)"),
    "across_normal_parallax 2x2": (lambda: rotation_choice.across_normal_parallax(np.eye(2)),
                                   ValueError, "H must be a 3x3 homography, got shape (2, 2)"),
    "translation_bias text": (lambda: rotation_choice.translation_bias("p"), TypeError,
                              "parallax must be a ppo_cv.parallax.PlaneParallax, got str"),
    "focal_free_parallax NaN H": (
        lambda: rotation_choice.focal_free_parallax(
            PlaneParallax(np.full((3, 3), np.nan), 0.1, 0.1, np.zeros(0))),
        ValueError, "H has 9 NaN"),
    "freed_parallax_refused NaN bound": (
        lambda: rotation_choice.freed_parallax_refused(PARALLAX, np.nan), ValueError,
        "bound must be a finite number >= 0, got nan"),
    "unbiased_bias_deg NaN deviation": (
        lambda: rotation_choice.unbiased_bias_deg(1.0, np.nan), ValueError,
        "bias_sigma_deg must be a number >= 0 or inf, got nan"),
    "unbiased_bias_deg None": (lambda: rotation_choice.unbiased_bias_deg(None, 1.0), TypeError,
                               "bias_deg must be a number, got NoneType"),
    "choose_rotation None": (lambda: rotation_choice.choose_rotation(None), TypeError,
                             "estimates must be a sequence of RotationEstimate, got NoneType"),
    "choose_rotation texts": (lambda: rotation_choice.choose_rotation(["a"]), TypeError,
                              "estimates[0] must be a ppo_cv.rotation_choice.RotationEstimate"),
    "RotationEstimate R None": (
        lambda: rotation_choice.RotationEstimate("rotation", None, 0.1, 0.2), TypeError,
        "R is required, got None"),
    "RotationEstimate sigma text": (
        lambda: rotation_choice.RotationEstimate("rotation", np.eye(3), 0.1, "0.2"), TypeError,
        "sigma_deg must be a number, got str"),
    "tracks_could_win None": (lambda: rotation_choice.tracks_could_win(None, ESTIMATE),
                              TypeError, "moving must be a ppo_cv.rotation_choice."),
    "settled_before_polish text": (
        lambda: rotation_choice.settled_before_polish(ESTIMATE, "tracks"), TypeError,
        "searched must be a ppo_cv.photometric.PhotometricRotation, got str"),
    "rotation_only_fit None": (lambda: rotation_choice.rotation_only_fit(None, None), TypeError,
                               "motion must be a ppo_cv.motion_model.MotionDecision"),
    "rotation_only_estimate None": (
        lambda: rotation_choice.rotation_only_estimate(None, None, X1, X2, USED), TypeError,
        "motion must be a ppo_cv.motion_model.MotionDecision, got NoneType"),
    "feature_parallax text": (lambda: rotation_choice.feature_parallax("m", X1, X2), TypeError,
                              "motion must be a ppo_cv.motion_model.MotionDecision, got str"),
    # significance: a count of 2**31 asked for 17 GB
    "log10_binomial n beyond the bound": (
        lambda: significance.log10_binomial(2**40, 3), ValueError,
        "log10_binomial takes n up to 10000000, got 1099511627776"),
    "smallest_significant_consensus 2**31 - 1": (
        lambda: significance.smallest_significant_consensus(2**31 - 1, (640, 480), 1.0, 5.0),
        ValueError, "num_matches must be a whole number in 0..10000000"),
    # data_gen: a camera of focal length 1e302, overflows, terabytes
    "given_intrinsics 1e300": (lambda: given_intrinsics(K, 1e300), ValueError,
                               "focal_factor 1e+300 takes the focal lengths to (5e+302, 5e+302)"),
    "given_intrinsics 1e-300": (lambda: given_intrinsics(K, 1e-300), ValueError,
                                "outside [1e-06, 1e+08] pixels"),
    "paper_protocol alpha 1e300": (lambda: paper_protocol(1, 10, alpha=1e300, noise_px=1.0),
                                   ValueError, "alpha must be at most 100, got 1e+300"),
    "paper_protocol noise 1e300": (lambda: paper_protocol(1, 10, alpha=0.5, noise_px=1e300),
                                   ValueError, "noise_px must be at most 1024"),
    "paper_protocol depth 1e-300": (
        lambda: paper_protocol(1, 10, alpha=0.5, noise_px=1.0, depth=1e-300), ValueError,
        "depth must be finite and >= 1, got 1e-300"),
    "paper_protocol 10**12 points": (lambda: paper_protocol(1, 10**12, alpha=0.5, noise_px=1.0),
                                     ValueError, "n_poses * n_points must be at most 10000000"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_hostile_input_is_an_error_naming_the_argument(case):
    call, exception, words = CASES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the refusal comes before any arithmetic
        with pytest.raises(exception) as info:
            call()
    assert words in str(info.value)


@pytest.mark.parametrize("scale", [1e-310, 1e-200, 3.7, 1e200, 1e300])
def test_any_finite_scale_of_E_gives_the_same_residuals(scale):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scaled = robust.sampson_signed(E * scale, X1, X2)
        by_coordinate = robust.sampson_signed_rows(E * scale, X1.T, X2.T)
    atol = 1e-9 if scale < 1e-300 else 1e-15  # a subnormal E keeps fewer digits
    np.testing.assert_allclose(scaled, robust.sampson_signed(E, X1, X2), rtol=0, atol=atol)
    np.testing.assert_array_equal(by_coordinate, scaled)


@pytest.mark.parametrize("length", [1e-310, 1e-150, 1e150, 1e300])
def test_any_nonzero_length_of_t_gives_the_same_essential_matrix(length):
    t = np.array([0.6, -0.8, 0.3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = robust.essential_from_pose(_turn(0.1), t * length)
    np.testing.assert_allclose(found, robust.essential_from_pose(_turn(0.1), t), atol=1e-8)
    assert np.linalg.norm(found) == pytest.approx(1.0)


def test_the_checked_forms_give_the_figures_of_the_unchecked_ones():
    rng = np.random.default_rng(3)
    stack = rng.normal(size=(4, 3, 3)) * 7.3
    assert np.array_equal(robust.sampson_signed(stack, X1, X2),
                          robust._sampson_signed(stack, X1, X2))  # fmt: skip
    assert np.array_equal(robust.sampson_errors(E.tolist(), X1.tolist(), X2.tolist()),
                          robust._sampson_errors(E, X1, X2))  # fmt: skip
    assert np.array_equal(robust.sampson_signed_rows(stack, X1.T, X2.T),
                          robust._sampson_signed_rows(stack, X1.T, X2.T))  # fmt: skip
    t = np.array([0.3, -1.7, 2.2])
    assert np.array_equal(robust.essential_from_pose(_turn(0.2), t),
                          robust._essential_from_pose(_turn(0.2), t))  # fmt: skip


def test_the_pipeline_never_pays_the_checks_of_the_residuals(monkeypatch):
    """The residuals are computed on every match in the robust fits' refits, the refine rounds
    and the decision: their checks are for callers, the pipeline's data is checked once."""
    import importlib.resources

    def refuse(*args, **kwargs):
        raise AssertionError("the pipeline called a checked residual")

    monkeypatch.setattr(robust, "_checked_sampson", refuse)
    monkeypatch.setattr(robust, "essential_from_pose", refuse)
    data = importlib.resources.files("ppo_cv") / "data"
    camera = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
    result = ppo_cv.estimate_pair(str(data / "demo1.png"), str(data / "demo2.png"), camera)
    assert result.model == "general" and result.inliers.sum() > 100


def test_a_huge_bias_is_measured_without_overflow():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        value = rotation_choice.unbiased_bias_deg(1e300, 6e299)
    assert value == pytest.approx(8e299)
    assert rotation_choice.unbiased_bias_deg(0.5, 0.3) == pytest.approx(0.4)
    assert rotation_choice.unbiased_bias_deg(np.inf, np.inf) == 0.0


def test_the_consensus_test_takes_empty_counts():
    assert significance.log10_binomial(np.array([], int), np.array([], int)).shape == (0,)
    bound = MAX_MATCHES
    assert significance.log10_binomial(np.array([10, 20]), 3).shape == (2,)
    with pytest.raises(ValueError, match=f"takes n up to {bound}"):
        significance.log10_binomial(np.array([10, bound + 1]), 3)


def test_the_protocol_at_its_largest_parallax_stays_finite():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sample = paper_protocol(3, 20, alpha=MAX_ALPHA, noise_px=1024.0, depth=1.0)
    assert np.all(np.isfinite(sample.points2)) and np.abs(sample.points2).max() < 1e8


def test_a_camera_scaled_within_the_bounds_is_kept():
    np.testing.assert_array_equal(given_intrinsics(K, 2.0)[:2, :2], 2.0 * K[:2, :2])
