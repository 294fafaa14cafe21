"""The rule that picks the returned rotation: expected error = |bias| + deviation."""

import numpy as np
import pytest

from ppo_cv.metrics import rotation_error_deg
from ppo_cv.motion_model import MAX_TRACK_PARALLAX
from ppo_cv.parallax import PlaneParallax, fit_plane_parallax, homography_parallax
from ppo_cv.rotation import MAX_K1, correct_points, fit_rotation_lens
from ppo_cv.rotation_choice import (
    RotationEstimate,
    across_normal_parallax,
    choose_rotation,
    focal_bias_deg,
    focal_trade_deg,
    given_focal_fit,
    released_lens_shift_deg,
    rotation_fit_sigma_deg,
    settled_before_polish,
    translation_bias,
)


def _turn(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@pytest.mark.parametrize(
    ("essential", "rotation", "winner"),
    [
        ((0.0, 1.2), (0.3, 0.2), "rotation"),  # tiny parallax, essential poorly determined
        ((0.0, 0.1), (5.0, 0.1), "essential"),  # a real translation: large bias
        ((0.0, 0.3), (0.1, 0.2), "essential"),  # a tie goes to the first (moving) estimate
        ((0.0, float("inf")), (0.5, 0.2), "rotation"),  # moving model undetermined
        ((0.0, 0.4), (float("inf"), 0.05), "essential"),  # bias not measured
        ((0.0, float("nan")), (0.2, 0.1), "rotation"),  # NaN counts as unknown
    ],
)
def test_choose_rotation_takes_the_smallest_expected_error(essential, rotation, winner):
    estimates = [
        RotationEstimate("essential", np.eye(3), *essential),
        RotationEstimate("rotation", _turn(1.0), *rotation),
    ]
    assert choose_rotation(estimates).source == winner


def test_both_unknown_keep_the_moving_model():
    estimates = [
        RotationEstimate("plane", np.eye(3), 0.0, float("inf")),
        RotationEstimate("rotation", np.eye(3), float("inf"), 0.1),
    ]
    assert choose_rotation(estimates).source == "plane"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: choose_rotation([]), "at least one"),
        (lambda: RotationEstimate("homography", np.eye(3), 0.0, 1.0), "unknown rotation source"),
    ],
)
def test_bad_input_is_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize(
    ("parallax", "expected"),
    [
        (None, (float("inf"), 0.0)),
        (PlaneParallax(np.eye(3), 0.01, 0.002, np.zeros(3)), (0.5730, 0.1146)),
        (PlaneParallax(np.eye(3), float("nan"), 0.002, np.zeros(3)), (float("inf"), 0.0)),
    ],
)
def test_translation_bias_is_the_parallax_in_degrees(parallax, expected):
    assert translation_bias(parallax) == pytest.approx(expected, abs=1e-4)


@pytest.mark.parametrize(
    ("u", "n", "expected"),
    [
        ((0.05, 0.0, 0.0), (0.0, 0.0, 1.0), 0.05),  # sideways before a wall
        ((0.05, 0.0, 0.025), (0.0, 0.0, 1.0), 0.05),  # with a forward part: still 0.05
        ((0.03, 0.0, 0.04), (0.3, 0.0, 0.95), None),  # oblique wall: |u x n|
        ((0.0, 0.0, 0.05), (0.0, 0.0, 1.0), 0.0),  # toward the wall: a zoom
        ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0),  # a rotation
    ],
)
def test_across_normal_parallax_is_the_sideways_part_of_the_motion(u, n, expected):
    u, n = np.array(u), np.array(n) / np.linalg.norm(n)
    H = 3.0 * _turn(11.0) @ (np.eye(3) + np.outer(u, n))
    truth = np.linalg.norm(np.cross(u, n)) if expected is None else expected
    assert across_normal_parallax(H) == pytest.approx(truth, abs=1e-6)
    assert across_normal_parallax(np.diag([1.04, 1.04, 1.0])) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("baseline", [0.002, 0.005, 0.01])
def test_a_sideways_translation_biases_the_rotation_fit_by_its_parallax(baseline):
    """The module's derivation: a wall at distance 1 seen by a 20 degree field, the camera
    moved sideways by ``baseline``; the rotation-only fit (lens terms under their priors) is
    off by about ``baseline`` radians, which is the homography's parallax. (Turned, the views'
    centres part and the focal scale takes a share of the shift: the parallax bounds the
    bias.)"""
    rng = np.random.default_rng(3)
    q1 = rng.uniform(-0.17, 0.17, (400, 2))
    X = np.column_stack([q1, np.ones(len(q1))])  # depth 1
    R, t = np.eye(3), np.array([baseline, 0.0, 0.0])
    Y = X @ R.T + t
    x2 = Y[:, :2] / Y[:, 2:] + rng.normal(0.0, 2e-5, (len(q1), 2))
    fit = fit_rotation_lens(q1, x2, np.ones(len(q1), bool), R, noise=3e-5)
    H = R + np.outer(t, [0.0, 0.0, 1.0])
    bias = np.degrees(homography_parallax(H))
    assert bias == pytest.approx(np.degrees(baseline), rel=0.02)
    assert rotation_error_deg(fit.R, R) == pytest.approx(bias, rel=0.1)


def _tilt(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _distort(q: np.ndarray, k1: float) -> np.ndarray:
    return q * (1.0 + k1 * np.sum(q * q, axis=1, keepdims=True))


@pytest.mark.parametrize(("true_k1", "corrected_k1", "reads_parallax"), [
    (0.4, 0.4, False),  # the lens fitted: the rotation's parallax is noise
    (0.4, MAX_K1, True),  # the lens held at the box: degrees of parallax
    (0.3, MAX_K1, True),
])  # fmt: skip
def test_in_a_thin_overlap_a_lens_error_reads_as_parallax(true_k1, corrected_k1, reads_parallax):
    """The module's "lens behind the bias": a pure rotation (parallax 0) seen in the strip an
    11 degree tilt leaves of a 20 x 15 degree field, its points corrected by a lens: the
    homography's parallax lies within three of its deviations of 0 only with the true lens."""
    rng = np.random.default_rng(7)
    q1 = np.column_stack([rng.uniform(-0.17, 0.17, 400), rng.uniform(0.062, 0.129, 400)])
    ray = np.column_stack([q1, np.ones(len(q1))]) @ _tilt(-11.0).T
    q2 = ray[:, :2] / ray[:, 2:]
    noise = 0.3 / 2095.0
    x1 = _distort(q1, true_k1) + rng.normal(0.0, noise, q1.shape)
    x2 = _distort(q2, true_k1) + rng.normal(0.0, noise, q2.shape)
    found = fit_plane_parallax(
        correct_points(x1, 1.0, corrected_k1), correct_points(x2, 1.0, corrected_k1)
    )
    assert (found.parallax > 3.0 * found.sigma) == reads_parallax
    assert (np.degrees(found.parallax) > 1.0) == reads_parallax


def test_fit_sigma_agrees_with_the_lens_fit_covariance():
    rng = np.random.default_rng(5)
    q1 = rng.uniform(-0.3, 0.3, (300, 2))
    R = _turn(12.0)
    ray = np.column_stack([q1, np.ones(len(q1))]) @ R.T
    x2 = ray[:, :2] / ray[:, 2:] + rng.normal(0.0, 3e-4, (len(q1), 2))
    used = np.ones(len(q1), bool)
    fit = fit_rotation_lens(q1, x2, used, R, noise=3e-4 * np.sqrt(2.0))
    sigma = rotation_fit_sigma_deg(fit, q1, x2, used)
    assert np.isfinite(fit.rotation_sigma_deg)
    assert sigma == pytest.approx(fit.rotation_sigma_deg, rel=0.3)
    assert rotation_fit_sigma_deg(fit, q1[:3], x2[:3], used[:3]) == float("inf")


@pytest.mark.parametrize("true_k1", [0.3, 0.5])
def test_the_given_focal_fit_frees_the_lens_term_the_box_clipped(true_k1):
    # a 10 degree pan in a 20 degree field through a lens beyond the box MAX_K1, the focal
    # length given right: the box clips k1 and the rotation pays for it
    rng = np.random.default_rng(0)
    R = _turn(10.0)
    q1 = rng.uniform([-0.17, -0.13], [0.0, 0.13], (300, 2))
    ray = np.column_stack([q1, np.ones(len(q1))]) @ R.T
    q2 = ray[:, :2] / ray[:, 2:]
    seen = [q * (1.0 + true_k1 * np.sum(q * q, axis=1, keepdims=True)) for q in (q1, q2)]
    x1, x2 = (x + rng.normal(0.0, 1e-4, x.shape) for x in seen)
    used = np.ones(len(q1), bool)
    clipped = fit_rotation_lens(x1, x2, used, np.eye(3), noise=1e-4)
    held = given_focal_fit(clipped, x1, x2, used)
    assert true_k1 > MAX_K1 and clipped.lens_excess > 0
    assert held.focal_scale == 1.0 and held.k1 == pytest.approx(true_k1, abs=0.02)
    assert rotation_error_deg(held.R, R) < 0.01 < rotation_error_deg(clipped.R, R)


@pytest.mark.parametrize(
    ("turn_deg", "step", "focal_error"),
    [
        (8.0, 0.01, 0.0),  # a sideways step the focal scale half absorbs
        (4.0, 0.005, 0.0),
        (12.0, 0.008, -0.01),  # the given focal length 1 % off besides
        (8.0, 0.03, 0.0),  # beyond MAX_TRACK_PARALLAX: counted up to it
        (8.0, 0.0, 0.015),  # a pure rotation, focal length off within its prior
    ],
)
def test_focal_bias_is_the_rotation_a_sideways_step_put_into_the_focal_scale(
    turn_deg, step, focal_error
):
    rng = np.random.default_rng(3)
    q1 = rng.uniform(-0.25, 0.25, (300, 2))
    R = _turn(turn_deg)
    ray = np.column_stack([q1, np.ones(len(q1))]) @ R.T + [step, 0.0, 0.0]  # depth 1
    x2 = ray[:, :2] / ray[:, 2:] + rng.normal(0.0, 2e-5, (len(q1), 2))
    given1, given2 = q1 / (1.0 + focal_error), x2 / (1.0 + focal_error)
    used = np.ones(len(q1), bool)
    fit = fit_rotation_lens(given1, given2, used, np.eye(3), noise=3e-5, max_focal_change=0.2)
    error = rotation_error_deg(fit.R, R)
    bias = focal_bias_deg(fit, given1, given2, used)
    if step == 0.0:
        assert error < 0.01 and bias == 0.0
        return
    share = min(1.0, MAX_TRACK_PARALLAX / step)
    assert error > 0.05
    assert 0.6 * share * error <= bias <= 1.2 * share * error


@pytest.mark.parametrize(
    ("turn_deg", "step", "focal_error"),
    [
        (20.0, 0.005, 0.0),
        (40.0, 0.005, 0.0),
        (40.0, 0.004, -0.01),  # the given focal length 1 % short besides
        (40.0, 0.0, 0.015),  # a pure rotation, focal length off within its prior
    ],
)
def test_focal_trade_is_the_rotation_a_step_before_a_floor_and_ceiling_put_into_the_focal_scale(
    turn_deg, step, focal_error
):
    rng = np.random.default_rng(5)
    q1 = rng.uniform(-0.7, 0.7, (400, 2)) * [1.0, 0.75]
    R = _turn(turn_deg)
    pivot = np.array([0.0, 0.0, -1.0])
    t = (pivot - R @ pivot) / np.linalg.norm(pivot - R @ pivot) * step
    inverse_depth = 1.0 + 2.0 * np.abs(q1[:, 1:])  # a floor and a ceiling
    ray = np.column_stack([q1, np.ones(len(q1))]) @ R.T + inverse_depth * t
    x2 = ray[:, :2] / ray[:, 2:] + rng.normal(0.0, 1e-4, (len(q1), 2))
    given1, given2 = q1 / (1.0 + focal_error), x2 / (1.0 + focal_error)
    used = np.all(np.abs(x2) < 0.7, axis=1)
    fit = fit_rotation_lens(given1, given2, used, R, noise=1.4e-4, max_focal_change=0.2)
    error = rotation_error_deg(fit.R, R)
    trade = focal_trade_deg(fit, given1, given2, used)
    if step == 0.0:
        assert error < 0.02 and trade == 0.0
        return
    assert error > 0.5
    assert 0.7 * error <= trade <= 2.0 * error
    assert focal_bias_deg(fit, given1, given2, used) < 0.5 * error  # one depth: a step's share


def _distorted(x: np.ndarray, k1: float) -> np.ndarray:
    """Points (N, 2) that the division model ``q = x / (1 + k1 |x|^2)`` takes to ``x``."""
    d = x.copy()
    for _ in range(50):
        d = x * (1.0 + k1 * np.sum(d**2, axis=1, keepdims=True))
    return d


@pytest.mark.parametrize(
    ("half_width", "step", "k1", "slides"),
    [
        (0.18, 0.005, 0.15, True),  # a 20 degree tripod pan: held at 0, the lens moves R 3 deg
        (0.18, 0.005, 0.0, False),  # the same pan, no lens: nothing to slide along
        (0.6, 0.1, 0.05, True),  # a 62 degree field moved by 0.1: a smaller move, still read
        (0.6, 0.1, 0.0, False),
    ],
)
def test_the_essential_matrix_slide_is_the_error_its_held_lens_term_made(
    half_width, step, k1, slides
):
    """The pose refined on the Sampson error with the lens held at 0 (as the essential matrix's
    is when its radial term is not kept) is off by degrees in a narrow field; its rotation
    moves by a good part of that when ``k1`` is fitted anew under its prior (which holds a
    ``k1`` of 0.15 short of the truth), and stays put without a lens: less the move the noise
    makes on replicates of the matches, what remains is within its deviation."""
    from ppo_cv.refine import refine_pose

    rng = np.random.default_rng(0)
    R, noise = _turn(10.0), 5e-5
    xy = rng.uniform([-half_width, -0.75 * half_width], [half_width, 0.75 * half_width], (400, 2))
    X = np.column_stack([xy, np.ones(400)]) * rng.uniform(4.0, 8.0, (400, 1))
    centre2 = np.array([6.0 * step, 0.0, 0.0])  # baseline / depth about step
    X2 = (X - centre2) @ R.T
    x2 = X2[:, :2] / X2[:, 2:]
    seen = np.all(np.abs(x2) < [half_width, 0.75 * half_width], axis=1)
    h1, h2 = (
        np.column_stack([_distorted(x[seen], k1) + rng.normal(0.0, noise, (seen.sum(), 2)),
                         np.ones(seen.sum())])
        for x in (xy, x2)
    )  # fmt: skip
    used = np.ones(len(h1), bool)
    t = -R @ centre2
    R_held, t_held = refine_pose(R, t / np.linalg.norm(t), h1, h2, used, focal=2000.0)
    error = rotation_error_deg(R_held, R)
    shift, sigma = released_lens_shift_deg(R_held, t_held, 0.0, h1, h2, used, 5 * noise)
    corrected, corrected_sigma = released_lens_shift_deg(
        R_held, t_held, 0.0, h1, h2, used, 5 * noise, replicates=16
    )
    assert sigma == 0.0
    if slides:  # the noise's own move taken out, the lens's stays
        assert error > 0.3 and 0.3 * error < shift < 1.4 * error and corrected > 0.25 * error
    else:  # in the narrow field a k1 within the noise still moves R by a tenth of a degree,
        # a move within the deviation of the noise's own
        assert error < 0.1 and shift < 0.2 and corrected < 2.0 * corrected_sigma


def _estimates_of(pair, monkeypatch):
    """The pair's result and the estimates the rule compared."""
    import ppo_cv.pipeline as pipeline
    from ppo_cv import estimate_pair

    seen = {}

    def recording(estimates):
        seen["estimates"] = list(estimates)
        return choose_rotation(estimates)

    monkeypatch.setattr(pipeline, "choose_rotation", recording)
    result = estimate_pair(pair.image1, pair.image2, pair.K_given)
    return result, {e.source: e for e in seen["estimates"]}


@pytest.mark.parametrize(
    ("seed", "baseline", "chosen"),
    [
        (13, 0.01, "essential"),  # 32 deg field, the translation measured well
        (6, 0.05, "plane"),  # 29 deg field: the tracks' plane reads less than the bias
    ],
)
def test_translating_renders_keep_the_moving_model(seed, baseline, chosen, monkeypatch):
    from imperfect import imperfect_render

    pair = imperfect_render(seed, baseline)
    result, estimates = _estimates_of(pair, monkeypatch)
    assert not result.pure_rotation and result.rotation_source == chosen
    assert np.allclose(result.R, estimates[chosen].R)
    # a translation measured well holds the rotation wherever the lens term goes
    assert result.uncertainty.rotation_bias_deg == estimates[chosen].bias_deg < 0.05
    # weighed with the deviation it reports, the given intrinsics' errors counted
    assert estimates[chosen].rms_error_deg == result.uncertainty.rotation_sigma_deg
    assert estimates[chosen].sigma_deg <= result.uncertainty.rotation_sigma_deg
    error = rotation_error_deg(result.R, pair.R)
    assert error < 0.1 and error < rotation_error_deg(estimates["rotation"].R, pair.R)


def _pairs_file_line(folder, names):
    """``K1, K2`` and the reference rotation of the pair ``names`` in ``folder``'s
    ``pairs_with_gt.txt``."""
    line = next(
        row.split()
        for row in (folder / "pairs_with_gt.txt").read_text().splitlines()
        if row.split()[:2] == list(names)
    )
    K1, K2 = (np.array(line[i : i + 9], float).reshape(3, 3) for i in (4, 13))
    return K1, K2, np.array(line[22:38], float).reshape(4, 4)[:3, :3]


def test_real_tripod_pair_called_general_returns_the_rotation_only_fit(pano_dev, monkeypatch):
    """bookshelf DSC04143 -> DSC04144 (382x574, a 37 degree field): GRIC sees a translation,
    the essential matrix's rotation slides with its radial term; its tracks' plane moved
    about 0.005 of its distance, and the rotation-only fit is returned, closer to the
    reference."""
    from ppo_cv import estimate_pair

    names = ("bookshelf_DSC04143.JPG", "bookshelf_DSC04144.JPG")
    K1, K2, R_ref = _pairs_file_line(pano_dev, names)
    images = [str(pano_dev / "images" / name) for name in names]
    import ppo_cv.pipeline as pipeline

    seen = {}

    def recording(estimates):
        seen.update({e.source: e for e in estimates})
        return choose_rotation(estimates)

    monkeypatch.setattr(pipeline, "choose_rotation", recording)
    result = estimate_pair(*images, K1, K2)
    assert not result.pure_rotation and result.rotation_source == "rotation"
    error = rotation_error_deg(result.R, R_ref)
    assert error < 1.0 and error < rotation_error_deg(seen["essential"].R, R_ref)
    assert 0.0 < result.uncertainty.rotation_bias_deg < 1.0


@pytest.mark.parametrize(
    "names",
    [
        ("csie_IMG_8716.JPG", "csie_IMG_8717.JPG"),  # matches wanting a focal length 0.72x
        ("book_DSC04232.JPG", "book_DSC04233.JPG"),  # and 1.05x the given one
    ],
)
def test_a_tripod_pair_whose_lens_was_clipped_returns_its_rotation_through_the_given_focal(
    names, pano_dev, monkeypatch
):
    """Called general, the lens of its rotation-only fit clipped to the box: the rotation
    returned is fitted through the given focal length, as the reference's is, not through
    the edge of the box."""
    import ppo_cv.pipeline as pipeline
    from ppo_cv import estimate_pair

    K1, K2, R_ref = _pairs_file_line(pano_dev, names)
    seen = {}

    def recording(estimates):
        seen.update({e.source: e for e in estimates})
        return choose_rotation(estimates)

    monkeypatch.setattr(pipeline, "choose_rotation", recording)
    result = estimate_pair(*(str(pano_dev / "images" / name) for name in names), K1, K2)
    assert not result.pure_rotation and result.rotation_source == "rotation"
    assert np.isfinite(result.lens.wanted_focal_scale)  # the lens was clipped
    error = rotation_error_deg(result.R, R_ref)
    assert error < 0.15 and error + 0.2 < rotation_error_deg(seen["rotation"].R, R_ref)


@pytest.mark.parametrize(
    ("data", "names", "aligned", "chosen"),
    [
        # freiburg desk, a hand-held step: the rotation-only fit 2 degrees from an essential
        # matrix of expected error 0.06 took a bias no tracks could read away
        ("freiburg", ("1341847980.722988.png", "1341847981.726650.png"), False, "essential"),
        # a tripod pan called general: the essential matrix slid 8 degrees (its budget 8.6),
        # the tracks' plane reads a bias of about 3 degrees, the matches' 9
        ("pano_dev", ("csie_IMG_8715.JPG", "csie_IMG_8716.JPG"), True, "rotation"),
    ],
)
def test_decision_aligns_windows_only_where_the_rotation_only_fit_could_win(
    data, names, aligned, chosen, request, monkeypatch
):
    import ppo_cv.pipeline as pipeline
    from ppo_cv import estimate_pair

    folder = request.getfixturevalue(data)
    K1, K2, R_ref = _pairs_file_line(folder, names)
    seen, align = {"aligned": False}, pipeline._align_tracks

    def recording_align(*args, keep_clipped=False, **keywords):
        seen["aligned"] |= keep_clipped
        return align(*args, keep_clipped=keep_clipped, **keywords)

    def recording_choice(estimates):
        seen.update({e.source: e for e in estimates})
        return choose_rotation(estimates)

    monkeypatch.setattr(pipeline, "_align_tracks", recording_align)
    monkeypatch.setattr(pipeline, "choose_rotation", recording_choice)
    result = estimate_pair(*(str(folder / "images" / name) for name in names), K1, K2)
    other = "rotation" if chosen == "essential" else "essential"
    assert seen["aligned"] is aligned
    assert not result.pure_rotation and result.rotation_source == chosen
    error = rotation_error_deg(result.R, R_ref)
    assert error < 1.0 and error + 1.0 < rotation_error_deg(seen[other].R, R_ref)


@pytest.mark.parametrize(
    ("apart_deg", "moving", "fit_sigma_deg", "could_win"),
    [
        (2.0, (0.2, 0.8), 0.1, True),  # 2 - 0.5 reach < 2 x 1.0
        (2.6, (0.2, 0.8), 0.1, False),  # 2.1 beyond the budgets of both
        (2.6, (0.2, 0.8), 0.2, True),  # a wider search reaches 0.9 degree
        (30.0, (0.0, 0.5), 10.0, False),  # the search is capped at MAX_SEARCH_SIGMA_DEG
        (30.0, (0.0, float("inf")), 0.1, True),  # a moving model of unknown error
    ],
)
def test_tracks_are_aligned_while_the_refit_could_come_within_both_budgets(
    apart_deg, moving, fit_sigma_deg, could_win
):
    from ppo_cv.rotation_choice import tracks_could_win

    essential = RotationEstimate("essential", np.eye(3), *moving)
    rotation = RotationEstimate("rotation", _turn(apart_deg), 5.0, fit_sigma_deg)
    assert rotation_error_deg(rotation.R, essential.R) == pytest.approx(apart_deg)
    assert tracks_could_win(essential, rotation) is could_win


def test_a_clipped_lens_measures_the_feature_matches_parallax_once(monkeypatch):
    from result_layout import demo_inputs

    import ppo_cv.pipeline as pipeline
    import ppo_cv.rotation_choice as rotation_choice
    from ppo_cv import PairOptions, estimate_pair

    measured, clipped = [], []
    measure, wanted = rotation_choice.matches_parallax, pipeline.wanted_focal_scale
    monkeypatch.setattr(
        rotation_choice, "matches_parallax", lambda *a: measured.append(1) or measure(*a)
    )
    monkeypatch.setattr(
        pipeline,
        "wanted_focal_scale",
        lambda motion, *a: clipped.append(motion.lens_clipped) or wanted(motion, *a),
    )
    image1, image2, K = demo_inputs()
    result = estimate_pair(image1, image2, K, options=PairOptions(photometric=False))
    assert result.model == "general" and result.rotation_source == "essential"
    assert clipped == [True] and len(measured) == 1


def _searched(H, sigma: float, fit_sigma_deg: float, parallax: float | None = None):
    """Searched tracks whose plane has the homography ``H`` with deviation ``sigma`` (radians)
    and whose fit has the deviation ``fit_sigma_deg``."""
    from ppo_cv.photometric import PhotometricRotation, WindowTracks
    from ppo_cv.rotation import LensRotationFit

    fit = LensRotationFit(np.eye(3), 1.0, 0.0, float("inf"), np.empty(0),
                          rotation_sigma_deg=fit_sigma_deg)  # fmt: skip
    tracks = WindowTracks(np.empty((0, 2)), np.empty((0, 2)), np.empty(0, bool), np.empty(0))
    read = homography_parallax(H) if parallax is None else parallax
    plane = PlaneParallax(np.asarray(H, float), read, sigma, np.empty(0))
    return PhotometricRotation(fit, tracks, np.empty(0, bool), 0.1, parallax=plane)


_SIDEWAYS = np.eye(3) + np.outer([0.02, 0.0, 0.0], [0.0, 0.0, 1.0])  # 1.146 degrees of bias
_FOCAL_OFF = np.diag([0.8, 0.8, 1.0]) @ _turn(8.0) @ np.diag([1.25, 1.25, 1.0])


@pytest.mark.parametrize(
    ("H", "sigma", "fit_sigma_deg", "focal_free", "moving", "settled"),
    [
        (_SIDEWAYS, 0.001, 0.1, False, (0.0, 0.5), True),  # 1.146 - 0.172 + 0.1 > 0.5
        (_SIDEWAYS, 0.004, 0.1, False, (0.0, 0.5), True),  # 1.146 - 0.688 + 0.1 = 0.558
        (_SIDEWAYS, 0.004, 0.02, False, (0.0, 0.5), False),  # 0.478: the fit's deviation counts
        (_SIDEWAYS, 0.001, float("inf"), False, (0.0, 0.5), False),  # a lens clipped to its box
        (_SIDEWAYS, 0.008, 0.1, False, (0.0, 0.5), False),  # the bias may read 0
        (_SIDEWAYS, 0.001, 0.1, False, (0.5, 0.6), False),  # 1.07 < 1.1 of a biased moving model
        (_SIDEWAYS, 0.001, 0.1, False, (0.0, float("inf")), False),  # moving model unknown
        (_FOCAL_OFF, 0.001, 0.1, False, (0.0, 0.5), True),  # 3.6 degrees read as parallax
        (_FOCAL_OFF, 0.001, 0.1, True, (0.0, 0.5), False),  # a focal length given off: none
    ],
)
def test_the_choice_is_settled_before_the_polish_where_the_tracks_cannot_win(
    H, sigma, fit_sigma_deg, focal_free, moving, settled
):
    """The rotation-only estimate at its most favourable reading (the bias less
    SETTLED_DEVIATIONS of its deviations, at least 0, plus the fit's deviation; with the focal
    length freed where the decision's lens was clipped) against the moving model's expected
    error; a fit whose lens was clipped (no deviation) settles nothing."""
    essential = RotationEstimate("essential", np.eye(3), *moving)
    searched = _searched(H, sigma, fit_sigma_deg)
    assert settled_before_polish(essential, searched, focal_free=focal_free) is settled


def test_tracks_without_a_measured_plane_never_settle_the_choice():
    from dataclasses import replace

    essential = RotationEstimate("essential", np.eye(3), 0.0, 0.01)
    searched = _searched(_SIDEWAYS, 0.001, 0.1)
    assert settled_before_polish(essential, searched)
    assert not settled_before_polish(essential, replace(searched, parallax=None))
    for unread in (_searched(_SIDEWAYS, 0.001, 0.1, parallax=np.nan),
                   _searched(_SIDEWAYS, float("inf"), 0.1),
                   _searched(np.full((3, 3), np.nan), 0.001, 0.1, parallax=0.02)):  # fmt: skip
        assert not settled_before_polish(essential, unread, focal_free=True)


def _decision_run(pair_or_images, monkeypatch, stop: bool = True):
    """The result of a pair and the polishes run by the rotation choice's alignment (that of
    ``keep_clipped``), ``settled_before_polish`` as it is or (``stop`` False) never holding;
    with what it answered."""
    import ppo_cv.photometric as photometric
    import ppo_cv.pipeline as pipeline
    from ppo_cv import estimate_pair

    polished, answers, choosing = [], [], [False]
    polish, settled, align = photometric._polish, settled_before_polish, pipeline._align_tracks

    def aligning(*args, keep_clipped=False, **keywords):
        choosing[0] = keep_clipped
        return align(*args, keep_clipped=keep_clipped, **keywords)

    monkeypatch.setattr(pipeline, "_align_tracks", aligning)
    monkeypatch.setattr(
        photometric, "_polish", lambda *a: polished.append(choosing[0]) or polish(*a)
    )

    def answering(*args, **keywords):
        answers.append(stop and settled(*args, **keywords))
        return answers[-1]

    monkeypatch.setattr(pipeline, "settled_before_polish", answering)
    return estimate_pair(*pair_or_images), sum(polished), answers


def test_a_translating_pair_whose_tracks_cannot_win_skips_their_polish(monkeypatch):
    """tiny-baseline seed 0 index 4 (480 x 360): the rotation-only fit could win until its
    windows are searched; their plane then reads a bias that loses to the essential matrix
    whatever the polish does. The polish is not run and the answer is the one with it."""
    from ppo_cv.data_gen import make_pair

    pair = make_pair("tiny-baseline", seed=0, index=4, size=(480, 360))
    inputs = (pair.image1, pair.image2, pair.K1_given, pair.K2_given)
    result, polishes, answers = _decision_run(inputs, monkeypatch)
    assert polishes == 0 and answers and all(answers)
    full, polishes, answers = _decision_run(inputs, monkeypatch, stop=False)
    assert polishes >= 1 and answers == [False]
    assert result.model == full.model == "general"
    assert result.rotation_source == full.rotation_source == "essential"
    assert np.array_equal(result.R, full.R) and np.array_equal(result.t, full.t)
    assert result.uncertainty == full.uncertainty
    assert rotation_error_deg(result.R, pair.R) < 0.1


def test_a_tripod_pair_whose_tracks_may_win_is_polished(pano_dev, monkeypatch):
    """bookshelf DSC04166 -> DSC04167, called general: the searched tracks' bias, less three
    of its deviations, leaves the rotation-only fit a chance, so the windows are polished, and
    the rotation-only fit wins."""
    names = ("bookshelf_DSC04166.JPG", "bookshelf_DSC04167.JPG")
    K1, K2, R_ref = _pairs_file_line(pano_dev, names)
    images = [str(pano_dev / "images" / name) for name in names]
    result, polishes, answers = _decision_run((*images, K1, K2), monkeypatch)
    assert polishes >= 1 and answers == [False]
    assert not result.pure_rotation and result.rotation_source == "rotation"
    assert rotation_error_deg(result.R, R_ref) < 1.0
