"""Hostile input to the helpers the pipeline calls with checked values: the structure from
motion texts and folder checks, the significance tests, the least-squares tools, the reach of
a photometric refit and a rendered pair's cameras. Each is an error naming the argument (the
unchecked forms the fitting loops call give the same figures); and a pair whose two
consensuses are both refused says why each was."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ppo_cv
from ppo_cv import consensus, lsq, photometric, sfm, significance
from ppo_cv.data_gen import RenderedPair

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
X = np.column_stack([np.linspace(-0.2, 0.2, 6), np.linspace(0.1, -0.1, 6), np.ones(6)])
HUGE = 10**400
T, P5 = np.array([0.6, 0.0, 0.8]), np.array([0.01, -0.02, 0.03, 0.1, -0.2])


def _fit(p):
    return p - 1.0


def _rendered(**changed):
    image = np.zeros((8, 8, 3), np.uint8)
    depth = np.ones((8, 8), np.float32)
    return RenderedPair(**{"image1": image, "image2": image, "K1": K, "K2": K, "R": np.eye(3),
                           "t": np.zeros(3), "depth1": depth, **changed})  # fmt: skip


def _significance(**settings):
    """The consensus of a sideways motion (``E = [t]x``, ``t`` along x) over matches of one row."""
    E = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return significance.epipolar_significance(E, X, X + [0.05, 0.0, 0.0], K, (640, 480),
                                              **settings)  # fmt: skip


CASES = {
    # sfm: AttributeError ('NoneType' object has no attribute 'split'), os.fspath's words
    "pair_text None": (lambda: sfm.pair_text(None, "b.png"), TypeError,
                       "name1 must be a str, got NoneType"),
    "pair_text int": (lambda: sfm.pair_text("a.png", 2), TypeError,
                      "name2 must be a str, got int"),
    "format_pairs None": (lambda: sfm.format_pairs(None), TypeError,
                          "pairs must be a list or tuple, got NoneType"),
    "require_two_images folder None": (lambda: sfm.require_two_images(None, [], {}), TypeError,
                                       "image_dir must be a path (str or os.PathLike)"),
    "require_two_images names None": (lambda: sfm.require_two_images("f", None, {}), TypeError,
                                      "names must be a list or tuple, got NoneType"),
    "require_two_images skipped None": (lambda: sfm.require_two_images("f", [], None),
                                        TypeError, "skipped must be a dict, got NoneType"),
    "require_database_outside None": (
        lambda: sfm.require_database_outside(None, "out"), TypeError,
        "database_path must be a path (str or os.PathLike), got NoneType"),
    "require_database_outside named": (
        lambda: sfm.require_database_outside("db", None, ("--database", "OUT_DIR")), TypeError,
        "OUT_DIR must be a path (str or os.PathLike), got NoneType"),
    "require_no_images None": (lambda: sfm.require_no_images(None, "OUT_DIR ", "usage"),
                               TypeError, "OUT_DIR must be a path (str or os.PathLike)"),
    "require_no_images name None": (lambda: sfm.require_no_images("out", None, "usage"),
                                    TypeError, "name must be a str, got NoneType"),
    # significance: AttributeError, unpacking errors, numpy's matmul and LinAlgError words
    "require_significance E None": (
        lambda: significance.require_significance(None, X, X, K, (640, 480), 5.0, np.ones(6)),
        TypeError, "E is required, got None"),
    "require_significance x2 short": (
        lambda: significance.require_significance(np.eye(3), X, X[:4], K, (640, 480), 5.0,
                                                  np.ones(6)),
        ValueError, "x1 and x2 must have the same length, got 6 and 4"),
    "require_significance max NaN": (
        lambda: significance.require_significance(np.eye(3), X, X, K, (640, 480), np.nan,
                                                  np.ones(6)),
        ValueError, "max_log10_nfa must be a number or inf, got nan"),
    "require_significance ratios short": (
        lambda: significance.require_significance(np.eye(3), X, X, K, (640, 480), 5.0,
                                                  np.ones(5)),
        ValueError, "ratios must be (N,) of the 6 matches, got (5,)"),
    "epipolar_significance size text": (
        lambda: significance.epipolar_significance(np.eye(3), X, X, K, "640x480"), TypeError,
        "image_size2 must be (width, height)"),
    "require_matchable_viewpoints None": (
        lambda: significance.require_matchable_viewpoints(None, X, np.eye(3)), TypeError,
        "x1 is required, got None"),
    "require_matchable_viewpoints R": (
        lambda: significance.require_matchable_viewpoints(X, X, np.ones((3, 3))), ValueError,
        "R is not a rotation matrix"),
    "chord_lengths None": (lambda: significance.chord_lengths(None, (640, 480), 1.0), TypeError,
                           "lines is required, got None"),
    "chord_lengths text": (lambda: significance.chord_lengths("abc", (640, 480), 1.0),
                           TypeError, "lines must be an array of real numbers, got str"),
    "chord_lengths size None": (lambda: significance.chord_lengths(X, None, 1.0), TypeError,
                                "image_size must be (width, height), got None"),
    "chord_lengths margin -1": (lambda: significance.chord_lengths(X, (640, 480), -1.0),
                                ValueError, "margin must be a finite number >= 0"),
    "ray_angles_deg None": (lambda: significance.ray_angles_deg(None, X, np.eye(3)), TypeError,
                            "x1 is required, got None"),
    "ray_angles_deg beyond a float": (
        lambda: significance.ray_angles_deg([[HUGE, 0, 1]], [[0, 0, 1]], np.eye(3)), ValueError,
        "x1 holds a number beyond the range of a float"),
    "epipolar_lines None": (lambda: significance.epipolar_lines(None, X, K), TypeError,
                            "E is required, got None"),
    # the minimal solver's counts and the largest band: NaN gave "arange: cannot compute
    # length", text a str concatenation error, 5.0 an IndexError, True and a NaN or negative
    # max_threshold an answer (no consensus, or a bool read as a count), -1 models a NaN NFA
    "epipolar_significance sample_size NaN": (
        lambda: _significance(sample_size=np.nan), ValueError,
        "sample_size must be a whole number in 1..2147483647, got nan"),
    "epipolar_significance sample_size 0": (
        lambda: _significance(sample_size=0), ValueError,
        "sample_size must be a whole number in 1..2147483647, got 0"),
    "epipolar_significance sample_size text": (
        lambda: _significance(sample_size="5"), TypeError,
        "sample_size must be a whole number, got str '5'"),
    "epipolar_significance sample_size bool": (
        lambda: _significance(sample_size=True), TypeError,
        "sample_size must be a whole number, got bool True"),
    "epipolar_significance sample_size huge": (
        lambda: _significance(sample_size=HUGE), ValueError,
        "sample_size must be a whole number in 1..2147483647, got <401-digit integer>"),
    "epipolar_significance models -1": (
        lambda: _significance(models_per_sample=-1), ValueError,
        "models_per_sample must be a whole number in 1..2147483647, got -1"),
    "epipolar_significance models huge": (
        lambda: _significance(models_per_sample=10**30), ValueError,
        "models_per_sample must be a whole number in 1..2147483647"),
    "epipolar_significance models bool": (
        lambda: _significance(models_per_sample=True), TypeError,
        "models_per_sample must be a whole number, got bool True"),
    "epipolar_significance max_threshold NaN": (
        lambda: _significance(max_threshold=np.nan), ValueError,
        "max_threshold must be a number > 0 (inf: no bound), got nan"),
    "epipolar_significance max_threshold -1": (
        lambda: _significance(max_threshold=-1), ValueError,
        "max_threshold must be a number > 0 (inf: no bound), got -1.0"),
    "epipolar_significance max_threshold 0": (
        lambda: _significance(max_threshold=0.0), ValueError,
        "max_threshold must be a number > 0 (inf: no bound), got 0.0"),
    "epipolar_significance max_threshold text": (
        lambda: _significance(max_threshold="16"), TypeError,
        "max_threshold must be a number, got str '16'"),
    "epipolar_significance max_threshold bool": (
        lambda: _significance(max_threshold=True), TypeError,
        "max_threshold must be a number, got True"),
    "smallest_significant_consensus models NaN": (
        lambda: significance.smallest_significant_consensus(
            100, (640, 480), 1.0, 5.0, models_per_sample=np.nan), ValueError,
        "models_per_sample must be a whole number in 1..2147483647, got nan"),
    "epipolar_lines K2 singular": (
        lambda: significance.epipolar_lines(np.eye(3), X, np.diag([500.0, 500.0, 0.0])),
        ValueError, "K2 must be upper triangular with last row (0, 0, 1)"),
    "local_consistency None": (
        lambda: significance.local_consistency(None, X[:, :2], X, (640, 480), 1.0), TypeError,
        "x1 is required, got None"),
    "local_consistency size": (
        lambda: significance.local_consistency(X, X[:, :2], X / np.hypot(X[:, :1], X[:, 1:2]),
                                               (0, 480), 1.0),
        ValueError, "image_size2 width must be a whole number"),
    # lsq: AttributeError, numpy's reshape, broadcast and LinAlgError words
    "cross_matrix None": (lambda: lsq.cross_matrix(None), TypeError, "v is required, got None"),
    "cross_matrix four": (lambda: lsq.cross_matrix([1, 2, 3, 4]), ValueError,
                          "v must be 3 numbers, got shape (4,)"),
    "cross_matrices None": (lambda: lsq.cross_matrices(None), TypeError,
                            "v is required, got None"),
    "rotation_increment NaN": (lambda: lsq.rotation_increment([np.nan, 0, 0]), ValueError,
                               "w has 1 NaN or infinite value(s)"),
    "rotation_increments rows of two": (lambda: lsq.rotation_increments(np.zeros((4, 2))),
                                        ValueError, "w must have shape (N, 3), got (4, 2)"),
    "huber_weights None": (lambda: lsq.huber_weights(None, 1.0), TypeError,
                           "size is required, got None"),
    "huber_weights scale 0": (lambda: lsq.huber_weights(np.ones(3), 0.0), ValueError,
                              "scale must be a finite number > 0, got 0.0"),
    "huber_weights NaN": (lambda: lsq.huber_weights(np.array([1.0, np.nan]), 1.0), ValueError,
                          "size must be residual sizes (N,) without NaN"),
    "gauss_newton_covariance None": (lambda: lsq.gauss_newton_covariance(None, 1.0), TypeError,
                                     "J is required, got None"),
    "gauss_newton_covariance vector": (lambda: lsq.gauss_newton_covariance(np.ones(4), 1.0),
                                       ValueError, "J must be a Jacobian of shape (M, P)"),
    "gauss_newton_covariance variance": (
        lambda: lsq.gauss_newton_covariance(np.eye(3), -1.0), ValueError,
        "variance must be a finite number >= 0, got -1.0"),
    "levenberg_marquardt f None": (lambda: lsq.levenberg_marquardt(None, np.zeros(2), 5),
                                   TypeError, "f must be a callable, got NoneType"),
    "levenberg_marquardt p None": (lambda: lsq.levenberg_marquardt(_fit, None, 5), TypeError,
                                   "p is required, got None"),
    "levenberg_marquardt iterations": (lambda: lsq.levenberg_marquardt(_fit, np.zeros(2), -1),
                                       ValueError, "iterations must be a whole number"),
    "levenberg_marquardt many": (lambda: lsq.levenberg_marquardt(_fit, np.zeros(2), 5, "x"),
                                 TypeError, "many must be a callable, got str"),
    "levenberg_marquardt_stacked p": (
        lambda: lsq.levenberg_marquardt_stacked(_fit, np.zeros((2, 2)), 5), ValueError,
        "p must be parameters of shape (P,), got (2, 2)"),
    "levenberg_marquardt_batched p": (
        lambda: lsq.levenberg_marquardt_batched(_fit, np.zeros(2), 5), ValueError,
        "p must be parameters of shape (S, P), got (2,)"),
    # pose_increment had no checks: a 0-d p raised an IndexError, a complex one warned
    "pose_increment 0-d p": (lambda: lsq.pose_increment(np.eye(3), T, np.array(0.1)), ValueError,
                             "p must be 5 numbers (rotation increment, step of t), got ()"),
    "pose_increment complex p": (lambda: lsq.pose_increment(np.eye(3), T, P5 + 1j), TypeError,
                                 "p must hold real numbers, got dtype complex128"),
    "pose_increment p 1e300": (lambda: lsq.pose_increment(np.eye(3), T, P5 * 1e300), ValueError,
                               "p has entries up to 2e+299, beyond 1e+15"),
    "pose_increment t of norm 2": (lambda: lsq.pose_increment(np.eye(3), 2 * T, P5), ValueError,
                                   "t must be a unit vector, got [1.2, 0.0, 1.6]"),
    "pose_increment R None": (lambda: lsq.pose_increment(None, T, P5), TypeError,
                              "R is required, got None"),
    "pose_increment basis not tangent": (
        lambda: lsq.pose_increment(np.eye(3), T, P5, np.eye(3)[:2]), ValueError,
        "basis must be two orthonormal rows orthogonal to t"),
    # an angle of 1e300 overflowed its square (RuntimeWarning)
    "rotation_increment 1e300": (lambda: lsq.rotation_increment([1e300, 0, 0]), ValueError,
                                 "w has entries up to 1e+300, beyond 1e+15"),
    "rotation_increments 1e300": (lambda: lsq.rotation_increments([[0, 0, -1e300]]), ValueError,
                                  "w has entries up to 1e+300, beyond 1e+15"),
    "huber_weights negative": (lambda: lsq.huber_weights(np.array([1.0, -2.0]), 1.0), ValueError,
                               "size must be residual sizes >= 0 (|r|), got -2.0"),
    # the Jacobians had no checks: len() of a 0-d p, numpy's broadcast of a wrong r0
    "forward_jacobian 0-d p": (lambda: lsq.forward_jacobian(_fit, np.array(1.0), np.zeros(1)),
                               ValueError, "p must be parameters of shape (P,), got ()"),
    "forward_jacobian r0 None": (lambda: lsq.forward_jacobian(_fit, np.zeros(2), None),
                                 TypeError, "r0 is required, got None"),
    "forward_jacobian_stacked step 0": (
        lambda: lsq.forward_jacobian_stacked(_fit, np.zeros(2), np.zeros(2), 0.0), ValueError,
        "step must be a finite number > 0"),
    "stacked_jacobian f None": (lambda: lsq.stacked_jacobian(None, np.zeros(2)), TypeError,
                                "f must be a callable, got NoneType"),
    "stack_by_chunks count 0": (lambda: lsq.stack_by_chunks(np.zeros, 0, 3), ValueError,
                                "count must be at least 1"),
    "stack_by_chunks evaluate None": (lambda: lsq.stack_by_chunks(None, 4, 3), TypeError,
                                      "evaluate must be a callable, got NoneType"),
    # residuals whose squares overflow at the start: numpy's overflow warnings, then NaN steps
    "levenberg_marquardt residuals overflow": (
        lambda: lsq.levenberg_marquardt(_fit, np.array([1e300, 0.0]), 5), ValueError,
        "f(p) has residuals up to 1e+300 at the start p: their squares overflow"),
    "levenberg_marquardt_stacked residuals overflow": (
        lambda: lsq.levenberg_marquardt_stacked(_fit, np.array([1e300, 0.0]), 5), ValueError,
        "f(p) has residuals up to 1e+300 at the start p"),
    "levenberg_marquardt_batched residuals overflow": (
        lambda: lsq.levenberg_marquardt_batched(lambda P, rows: _fit(P),
                                                np.array([[0.0, 0.0], [1e300, 0.0]]), 5),
        ValueError, "many(p) has residuals up to 1e+300 at the start p"),
    "levenberg_marquardt_batched step": (
        lambda: lsq.levenberg_marquardt_batched(_fit, np.zeros((1, 2)), 5, step=0.0),
        ValueError, "step must be a finite number > 0"),
    # the reach of a refit: NaN and negative deviations gave NaN and a negative reach
    "refit_reach_deg NaN": (lambda: photometric.refit_reach_deg(np.nan), ValueError,
                            "rotation_sigma_deg must be a number >= 0"),
    "refit_reach_deg -1": (lambda: photometric.refit_reach_deg(-1.0), ValueError,
                           "rotation_sigma_deg must be a number >= 0 (inf for none), got -1.0"),
    "refit_reach_deg text": (lambda: photometric.refit_reach_deg("0.5"), TypeError,
                             "rotation_sigma_deg must be a number, got str"),
    # a rendered pair's cameras: Python's OverflowError, a NaN camera taken for None
    "RenderedPair K1 beyond a float": (lambda: _rendered(K1=HUGE), ValueError,
                                       "K1 holds a number beyond the range of a float"),
    "RenderedPair K2_given beyond a float": (
        lambda: _rendered(K2_given=[[HUGE, 0, 0], [0, 1, 0], [0, 0, 1]]), ValueError,
        "K2_given holds a number beyond the range of a float"),
    "RenderedPair K1 None": (lambda: _rendered(K1=None), TypeError, "K1 is required, got None"),
    "RenderedPair K2 text": (lambda: _rendered(K2="abc"), TypeError,
                             "K2 must be an array of real numbers, got str"),
    "RenderedPair K1 of four": (lambda: _rendered(K1=np.eye(4)), ValueError,
                                "K1 must be a 3x3 matrix, got shape (4, 4)"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_hostile_input_to_a_helper_is_an_error_naming_the_argument(case):
    call, exception, words = CASES[case]
    with pytest.raises(exception) as info:
        call()
    assert words in str(info.value)


def test_whole_float_counts_of_the_consensus_test_read_as_their_integers():
    """A float count that is a whole number is read as one: ``sample_size=5.0`` raised numpy's
    IndexError (epipolar_significance) or a TypeError of integers (smallest_significant_consensus);
    ``max_threshold`` inf bounds nothing."""
    expected = _significance(sample_size=1)
    assert expected.num_consistent > 1 and np.isfinite(expected.log10_nfa)
    found = _significance(sample_size=1.0, models_per_sample=10.0, max_threshold=np.inf)
    assert (found.log10_nfa, found.num_consistent) == (expected.log10_nfa, expected.num_consistent)
    smallest = significance.smallest_significant_consensus(200, (640, 480), 1.0, 5.0)
    assert significance.smallest_significant_consensus(
        200, (640, 480), 1.0, 5.0, sample_size=5.0, models_per_sample=10.0) == smallest < 200


def _photo(name: str):
    import cv2
    import skimage.data

    image = np.asarray(getattr(skimage.data, name)())
    if image.ndim == 3:
        image = cv2.cvtColor(image[:, :, :3], cv2.COLOR_RGB2BGR)
    return cv2.resize(image, (640, 480))


def test_a_window_whose_brightness_steps_diverge_is_dropped_without_a_warning():
    # The camera man's windows seen in the astronaut photo: the gain of some grew to 1e18 under
    # the steps of their fixed Jacobian, overflowed the normal matrices (float32) and warned.
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        refined = photometric.refine_rotation_photometric(
            _photo("camera"), _photo("astronaut"), K, K, np.eye(3)
        )
    assert refined is None


def _refusing(first: str, denser: str):
    def fit(f1, f2, threshold_scale, *camera):
        reason = first if threshold_scale == 1.0 else denser
        raise ValueError(f"no reliable two-view geometry: {reason}")

    return fit


def test_both_refused_consensuses_say_why_on_one_line(monkeypatch):
    # Astronaut -> camera (skimage.data): both consensuses were refused (log10 NFA 5.9 and 6.0
    # > 5); the error gave the first reason only.
    images = np.random.default_rng(0).integers(0, 256, (2, 240, 320), dtype=np.uint8)
    monkeypatch.setattr(consensus, "_consensus", _refusing("log10 NFA 5.9 > 5", "local p 0.4"))
    with pytest.raises(ValueError) as info:
        ppo_cv.estimate_pair(*images, K)
    scale = f"{consensus.REDETECT_THRESHOLD_SCALE:g}"
    assert str(info.value) == (
        "no reliable two-view geometry: log10 NFA 5.9 > 5; with denser features (threshold "
        f"scale {scale}): local p 0.4"
    )
    monkeypatch.setattr(consensus, "_consensus", _refusing("same", "same"))
    with pytest.raises(ValueError, match="^no reliable two-view geometry: same$"):
        ppo_cv.estimate_pair(*images, K)


def test_the_checked_least_squares_tools_give_the_figures_of_the_unchecked_ones():
    rng = np.random.default_rng(3)
    w, rows, sizes, J = rng.normal(size=3), rng.normal(size=(5, 3)), rng.random(9), rng.normal(
        size=(9, 4))
    x = np.linspace(0.0, 2.0, 30)
    y = 2.0 * np.exp(-1.5 * x)

    def many(P, problems=None):
        return P[:, :1] * np.exp(-P[:, 1:2] * x) - y

    def one(p):
        return many(p[None])[0]

    pairs = [
        (lsq.cross_matrix(w), lsq._cross_matrix(w)),
        (lsq.cross_matrices(rows), lsq._cross_matrices(rows)),
        (lsq.rotation_increment(w), lsq._rotation_increment(w)),
        (lsq.rotation_increments(rows), lsq._rotation_increments(rows)),
        (lsq.huber_weights(sizes, 0.5), lsq._huber_weights(sizes, 0.5)),
        (lsq.gauss_newton_covariance(J, 2.0), lsq._gauss_newton_covariance(J, 2.0)),
        (lsq.levenberg_marquardt(one, np.array([1.0, 0.5]), 20)[0],
         lsq._levenberg_marquardt(one, np.array([1.0, 0.5]), 20)[0]),
        (lsq.levenberg_marquardt_stacked(many, np.array([1.0, 0.5]), 20)[0],
         lsq._levenberg_marquardt_stacked(many, np.array([1.0, 0.5]), 20)[0]),
        (lsq.levenberg_marquardt_batched(many, np.array([[1.0, 0.5], [3.0, 1.0]]), 20),
         lsq._levenberg_marquardt_batched(many, np.array([[1.0, 0.5], [3.0, 1.0]]), 20)),
        *zip(lsq.pose_increment(lsq.rotation_increment(w), T, P5),
             lsq._pose_increment(lsq.rotation_increment(w), T, P5), strict=True),
        *zip(lsq.pose_increment(np.eye(3), T, P5, lsq.tangent_basis(T)),
             lsq._pose_increment(np.eye(3), T, P5, lsq.tangent_basis(T)), strict=True),
        (lsq.forward_jacobian(one, np.array([1.0, 0.5]), one(np.array([1.0, 0.5]))),
         lsq._forward_jacobian(one, np.array([1.0, 0.5]), one(np.array([1.0, 0.5])))),
        (lsq.stacked_jacobian(many, np.array([1.0, 0.5]))[1],
         lsq._stacked_jacobian(many, np.array([1.0, 0.5]))[1]),
    ]  # fmt: skip
    for checked, unchecked in pairs:
        assert np.array_equal(checked, unchecked)
    assert np.allclose(pairs[6][0], [2.0, 1.5], atol=1e-6)


def test_extreme_least_squares_values_give_their_figures_without_warnings():
    """A Huber scale of 1e300 raised an OverflowError and an infinite size weighed NaN; a
    Jacobian of entries near 1e156 overflowed ``J^T J``; an ``n`` of 1e300 overflowed its norm,
    one of norm 2 gave a second row of norm 2. Each now gives the figures of its scaled-down
    twin, without a warning."""
    sizes = np.array([0.0, 0.5, 2.0, 4.0, np.inf])
    J = np.random.default_rng(5).normal(size=(9, 4))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        far = lsq.huber_weights(sizes * 1e300, 1e300)
        near = lsq.huber_weights(sizes, 1.0)
        huge = lsq.gauss_newton_covariance(J * 2.0**520, 1e300)
        tiny = lsq.gauss_newton_covariance(J * 2.0**-400, 2.0)
        beyond = lsq.gauss_newton_covariance(np.eye(3) * 1e-100, 1e300)
        bases = [lsq.tangent_basis(n) for n in ([1e300, -1e300, 5e299], [3e-300, 0, 0], 2 * T)]
    np.testing.assert_allclose(far, near, rtol=1e-15)
    np.testing.assert_allclose(near, [1.0, 1.0, np.sqrt(3.0) / 2.0, np.sqrt(7.0) / 4.0, 0.0])
    expected = lsq.gauss_newton_covariance(J, 1e300)
    np.testing.assert_allclose(np.ldexp(huge, 1040), expected, rtol=1e-12)
    np.testing.assert_allclose(np.ldexp(tiny, -800), expected * 2e-300, rtol=1e-12)
    assert beyond is None  # 1e500: beyond a float
    for basis, n in zip(bases, ([2, -2, 1], [1, 0, 0], T), strict=True):
        frame = np.vstack([np.divide(n, np.linalg.norm(n)), basis])
        np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
