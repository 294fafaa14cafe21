"""A translation GRIC sees but the intensity-aligned tracks measure as negligible: the rotation
candidate of ``ppo_cv.motion_model`` and its revision by ``with_tracks``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ppo_cv import PairOptions, estimate_pair, recover_pose, sfm
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.motion_model import (
    MIN_CANDIDATE_ROTATION_GAP,
    NEGLIGIBLE_PARALLAX,
    NEGLIGIBLE_SIGNIFICANCE,
    PARALLAX_SIGNIFICANCE,
    decide_motion,
    with_tracks,
)
from ppo_cv.parallax import PlaneParallax
from ppo_cv.refine import refine_pose
from ppo_cv.rotation import fit_rotation_lens

FOCAL = 3000.0


def _turn_with_step(rng, baseline: float, k1: float = 0.0, focal_error: float = 0.0):
    """Normalised matches of a 20 degree pan in a 30 degree field whose centre steps
    ``baseline`` sideways before a slanted, curved wall 5-12 away, located to 0.05 px at a focal
    length of :data:`FOCAL` px, seen through radial distortion ``k1`` nobody models and
    normalised with a focal length ``focal_error`` off."""
    n = 600
    q = rng.uniform(-0.27, 0.27, (n, 2))
    depth = 8.0 + 12.0 * q[:, 0] + 20.0 * q[:, 1] ** 2
    X = np.column_stack([q, np.ones(n)]) * depth[:, None]
    a = np.radians(20.0)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def observe(P):
        x = P[:, :2] / P[:, 2:]
        x = x * (1.0 + k1 * np.sum(x**2, axis=1, keepdims=True))
        x = (x + rng.normal(0.0, 0.05 / FOCAL, x.shape)) * (1.0 + focal_error)
        return np.column_stack([x, np.ones(n)])

    x1, x2 = observe(X), observe(X @ R.T + np.array([baseline, 0.0, 0.0]))
    keep = np.all(np.abs(x2[:, :2]) < 0.27, axis=1)
    return R, x1[keep], x2[keep]


def _candidate(k1: float = -0.05, focal_error: float = 0.03):
    """A step of baseline / depth 0.0005 and the decision on its refined essential matrix."""
    R, x1, x2 = _turn_with_step(np.random.default_rng(0), 0.004, k1, focal_error)
    used = np.ones(len(x1), dtype=bool)
    R_essential, t_essential = refine_pose(R, np.array([1.0, 0.0, 0.0]), x1, x2, used, FOCAL)
    motion = decide_motion(x1, x2, R_essential, t_essential, used, FOCAL)
    return R, R_essential, x1, x2, motion


def _tracks(parallax: float, sigma: float) -> PlaneParallax:
    return PlaneParallax(H=np.eye(3), parallax=parallax, sigma=sigma, residuals=np.zeros(1))


def test_a_significant_but_tiny_step_makes_a_rotation_candidate():
    """Through a lens nobody modelled and a focal length 3 % off, the essential matrix of a
    narrow field lets its translation absorb the lens: its rotation is degrees off."""
    R, R_essential, x1, x2, motion = _candidate()
    assert not motion.pure_rotation and motion.gric_difference > 0
    assert motion.rotation_candidate
    assert rotation_error_deg(R_essential, R) > 2.0
    # the step, 0.03 degrees seen from the wall, and the focal scale it moves
    assert rotation_error_deg(motion.R, R) < 0.2
    assert motion.rotation_gap == pytest.approx(
        np.radians(rotation_error_deg(R_essential, motion.R))
    )
    rng = np.random.default_rng(1)
    R, y1, y2 = _turn_with_step(rng, 0.4, -0.05, 0.03)
    wide = decide_motion(y1, y2, R, np.array([1.0, 0, 0]), np.ones(len(y1), bool), FOCAL)
    assert wide.model == "general" and not wide.rotation_candidate


def test_an_essential_matrix_that_agrees_with_the_rotation_keeps_its_translation():
    """Through an exact lens the essential matrix measures the same step consistently: its
    rotation lies within a negligible translation's tilt of the rotation-only fit, and no
    parallax of the tracks can make the pair a rotation."""
    R, R_essential, x1, x2, motion = _candidate(k1=0.0, focal_error=0.0)
    assert not motion.pure_rotation and motion.gric_difference > 0
    assert rotation_error_deg(R_essential, R) < 0.05
    assert motion.rotation_gap < MIN_CANDIDATE_ROTATION_GAP and not motion.rotation_candidate
    lens = fit_rotation_lens(x1, x2, motion.rotation_inliers, motion.R, noise=0.05 / FOCAL)
    assert not with_tracks(motion, lens, _tracks(0.0, 1e-5), x1, x2, FOCAL).pure_rotation


def test_negligible_tracks_parallax_turns_a_candidate_into_a_rotation():
    R, _, x1, x2, motion = _candidate()
    lens = fit_rotation_lens(x1, x2, motion.rotation_inliers, motion.R, noise=0.05 / FOCAL)
    bound = NEGLIGIBLE_PARALLAX - NEGLIGIBLE_SIGNIFICANCE * 1e-4
    decided = with_tracks(motion, lens, _tracks(0.99 * bound, 1e-4), x1, x2, FOCAL)
    assert decided.pure_rotation and decided.model == "rotation"
    assert np.allclose(decided.R, lens.R)
    assert decided.track_parallax == pytest.approx(0.99 * bound)


@pytest.mark.parametrize(
    ("parallax", "sigma"),
    [
        (NEGLIGIBLE_PARALLAX - NEGLIGIBLE_SIGNIFICANCE * 1e-4 + 1e-5, 1e-4),
        (0.0012, 0.001),
        (float("nan"), float("nan")),
    ],
)
def test_a_parallax_not_negligible_with_margin_keeps_the_general_decision(parallax, sigma):
    R, _, x1, x2, motion = _candidate()
    lens = fit_rotation_lens(x1, x2, motion.rotation_inliers, motion.R, noise=0.05 / FOCAL)
    decided = with_tracks(motion, lens, _tracks(parallax, sigma), x1, x2, FOCAL)
    assert not decided.pure_rotation and decided.model == motion.model
    assert np.array_equal(decided.R, motion.R)


def test_only_a_candidate_is_called_a_rotation_by_its_tracks():
    R, _, x1, x2, motion = _candidate()
    lens = fit_rotation_lens(x1, x2, motion.rotation_inliers, motion.R, noise=0.05 / FOCAL)
    plain = dataclasses.replace(motion, rotation_candidate=False)
    decided = with_tracks(plain, lens, _tracks(0.0, 1e-5), x1, x2, FOCAL)
    assert not decided.pure_rotation and decided.model == motion.model


def test_the_sfm_hook_never_starts_from_a_candidate():
    R, _, x1, x2, motion = _candidate()
    rng = np.random.default_rng(2)
    _, y1, y2 = _turn_with_step(rng, 0.4)
    E = np.cross(np.eye(3), np.array([1.0, 0.0, 0.0])) @ R
    pose = recover_pose(E, y1[:, :2], y2[:, :2], np.eye(3))
    assert sfm.score_pose(pose, min_inliers=10)[2] == ""
    score, _, rejection = sfm.score_pose(pose, motion=motion, min_inliers=10)
    assert score == 0.0 and rejection.startswith("rotation not ruled out")


@pytest.mark.slow
def test_a_tripod_pan_whose_pivot_the_matches_see_is_flagged_by_its_tracks():
    """A 21 degree pan in a 34 degree field of 1600 x 1200 px, the camera 15 cm before the
    tripod's axis, focal lengths per photo and the centre as principal point: the feature matches
    fix the step well enough for GRIC to prefer the essential matrix, whose rotation slides with
    the lens term (so the rotation-only fit's is returned, its bias read on the matches' plane);
    the tracks' plane moved less than a thousandth of its distance."""
    from ppo_cv import data_gen
    from ppo_cv.cli.pair import _summary
    from ppo_cv.export import result_to_dict

    stitched = data_gen.Imperfections(
        centred_principal_point=True, view_focal_error=0.01, exposure_ev=1.0, vignetting=0.35
    )
    pair = data_gen.make_pair(
        "panorama", seed=1, index=25, imperfections=stitched, pivot_offset=0.15,
        size=(1600, 1200),
    )  # fmt: skip
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    K1, K2 = pair.K1_given, pair.K2_given
    matches = estimate_pair(image1, image2, K1, K2, options=PairOptions(photometric=False))
    assert matches.model == "general" and matches.evidence.selection.gric_difference > 0
    assert matches.rotation_source == "rotation"  # the essential matrix's slides with its lens
    assert matches.uncertainty.rotation_bias_deg > 0.0
    assert rotation_error_deg(matches.R, pair.R) < 0.6
    result = estimate_pair(image1, image2, K1, K2)
    assert (
        result.pure_rotation
        and result.model == "rotation"
        and result.evidence.selection.gric_difference > 0
    )
    assert (
        result.evidence.tracks.parallax
        + NEGLIGIBLE_SIGNIFICANCE * result.evidence.tracks.parallax_sigma
        < (NEGLIGIBLE_PARALLAX)
    )
    assert rotation_error_deg(result.R, pair.R) < 0.6
    assert result.uncertainty.rotation_tracks > 100 and not result.translation_determined
    assert result.evidence.selection.rotation_gap_deg > np.degrees(MIN_CANDIDATE_ROTATION_GAP)
    record = result_to_dict(result)["evidence"]
    assert record["tracks"]["parallax"] == pytest.approx(result.evidence.tracks.parallax)
    assert record["selection"]["rotation_gap_deg"] == pytest.approx(
        result.evidence.selection.rotation_gap_deg
    )
    assert "negligible" in _summary(result, "a.png", "b.png", None)


def test_a_step_of_two_percent_that_makes_a_candidate_is_measured_and_not_flagged():
    """Baseline / depth 0.02 (``tiny-baseline`` index 8): the rotation passes every test but
    GRIC, so the windows are aligned; their plane moved 1.4 % of its distance."""
    from ppo_cv import data_gen
    from ppo_cv.cli.pair import _summary

    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=8, imperfections=data_gen.REAL_PHOTO, baseline_ratio=0.02
    )
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    result = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    assert not result.pure_rotation and result.translation_determined
    assert result.evidence.selection.gric_difference > 0 and result.uncertainty.rotation_tracks == 0
    assert (
        result.evidence.tracks.parallax
        - PARALLAX_SIGNIFICANCE * result.evidence.tracks.parallax_sigma
        > (NEGLIGIBLE_PARALLAX)
    )
    assert "not called a pure rotation" in _summary(result, "a.png", "b.png", None)
