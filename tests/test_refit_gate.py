"""The photometric refit runs only where it can change the answer
(:func:`ppo_cv.rotation_choice.refit_could_change`)."""

from dataclasses import replace

import numpy as np
import pytest

from ppo_cv import data_gen, pipeline, rotation_choice
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.motion_model import MAX_TRACK_PARALLAX, decide_motion


def _counting_refits(monkeypatch) -> list:
    calls = []
    refit = pipeline.refine_rotation_photometric

    def counted(*args, **kwargs):
        calls.append(True)
        return refit(*args, **kwargs)

    monkeypatch.setattr(pipeline, "refine_rotation_photometric", counted)
    return calls


def test_a_precise_pure_rotation_skips_the_refit_and_keeps_its_rotation(monkeypatch):
    """A clean 640x480 render of a pure rotation: its 1,500 matches fix the rotation to 0.006
    degree, their parallax biases it by 0.012 and is far below the veto bound, so no window is
    aligned; the rotation stays within the tolerance of the refitted one and of the truth, and
    its reported deviation, the matches' bias counted, covers its error (0.009 degree)."""
    pair = data_gen.make_pair("pure-rotation", seed=0, index=0)
    calls = _counting_refits(monkeypatch)
    skipped = pipeline.estimate_pair(pair.image1, pair.image2, pair.K1_given, pair.K2_given)
    assert not calls and skipped.pure_rotation and skipped.uncertainty.rotation_tracks == 0
    tolerance = rotation_choice.REFIT_TOLERANCE_DEG
    error = rotation_error_deg(skipped.R, pair.R)
    assert error < skipped.uncertainty.rotation_sigma_deg <= tolerance

    monkeypatch.setattr(rotation_choice, "REFIT_TOLERANCE_DEG", 0.0)
    refitted = pipeline.estimate_pair(pair.image1, pair.image2, pair.K1_given, pair.K2_given)
    assert calls and refitted.pure_rotation and refitted.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(skipped.R, refitted.R) < tolerance


def test_a_pure_rotation_as_photos_are_taken_is_refitted(monkeypatch):
    """The same render through a real photo's lens (distortion, focal length off): the matches
    leave the rotation 0.08 degree uncertain, the refit runs and lands within 0.01 degree."""
    pair = data_gen.make_pair("pure-rotation", seed=0, index=0, imperfections=data_gen.REAL_PHOTO)
    calls = _counting_refits(monkeypatch)
    result = pipeline.estimate_pair(pair.image1, pair.image2, pair.K1_given, pair.K2_given)
    assert calls and result.pure_rotation and result.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(result.R, pair.R) < 0.01


def _rotation_matches(parallax: float):
    """Exact normalised matches (300, 3) of a 5 degree pan, those of the lower half seen from a
    camera moved sideways by ``parallax`` of their depth (a floor nearer than the rest), and
    the decision on them."""
    rng = np.random.default_rng(0)
    q1 = rng.uniform(-0.4, 0.4, (300, 2))
    c, s = np.cos(np.radians(5.0)), np.sin(np.radians(5.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    ray = np.column_stack([q1, np.ones(300)]) @ R.T
    ray[:, 0] += np.where(q1[:, 1] > 0, parallax, 0.0) * ray[:, 2]
    x1 = np.column_stack([q1, np.ones(300)])
    x2 = np.column_stack([ray[:, :2] / ray[:, 2:] + rng.normal(0, 2e-5, (300, 2)), np.ones(300)])
    t = np.array([1.0, 0.0, 0.0])
    motion = decide_motion(x1, x2, R, t, np.ones(300, bool), 1000.0)
    return motion, x1, x2


def test_matches_whose_parallax_may_reach_the_veto_bound_are_refitted():
    """A pan whose matches fix the rotation well within the tolerance skips the refit; the same
    decision facing matches with a parallax of half the veto bound does not: its tracks could
    refuse it."""
    motion, x1, x2 = _rotation_matches(0.0)
    assert motion.pure_rotation and motion.rotation_sigma_deg < rotation_choice.REFIT_TOLERANCE_DEG
    assert not rotation_choice.refit_could_change(motion, x1, x2)
    _, x1, x2 = _rotation_matches(0.5 * MAX_TRACK_PARALLAX)
    assert rotation_choice.refit_could_change(motion, x1, x2)


@pytest.mark.parametrize(
    "changes",
    [
        {"pure_rotation": False, "rotation_candidate": True},
        {"lens_excess": 0.5},  # clipped to the box
    ],
)
def test_only_an_unclipped_pure_rotation_can_skip(changes):
    """A rotation candidate, or a rotation whose lens was clipped to its box, is always
    refitted, however precise its matches."""
    motion, x1, x2 = _rotation_matches(0.0)
    assert not rotation_choice.refit_could_change(motion, x1, x2)
    assert rotation_choice.refit_could_change(replace(motion, **changes), x1, x2)
