"""``rotation_sigma_deg`` against the rotation error on renders (``benchmarks/rotation_sigma.py``,
its renders of ``tests/imperfect.py``, six seeds): the root-mean-square error over the pairs of
each model against the mean deviation. The target is a factor 1.5 either way; measured are 1.05
(general), 1.45 (plane) and 1.04 (rotation); the plane's was 1.68 while a support lead of 2 of
784 matches chose between the homography's two interpretations (``docs/rotation_sigma.md``)"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from imperfect import imperfect_render

from ppo_cv import estimate_pair
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.plane import support_ties

ROOT = Path(__file__).resolve().parents[1]
SEEDS = 6
TARGET = 1.5
MEASURED = 2.0  # the largest ratio measured on these renders, with a margin


@pytest.fixture(scope="module")
def table() -> dict[str, tuple[int, float, float, float]]:
    spec = importlib.util.spec_from_file_location(
        "rotation_sigma_benchmark", ROOT / "benchmarks" / "rotation_sigma.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    rows = script.run(SEEDS)
    return {value: rest for value, *rest in script.calibration_rows(rows, "model")}


MODELS = ["general", "plane", "rotation"]


@pytest.mark.slow
@pytest.mark.parametrize("model", MODELS)
def test_sigma_neither_overstates_nor_understates_beyond_the_measured_factor(table, model):
    pairs, rms, mean_sigma, ratio = table[model]
    assert pairs >= 5
    assert 1.0 / TARGET <= ratio <= MEASURED, f"{model}: RMS {rms:.3f} / sigma {mean_sigma:.3f}"


@pytest.mark.slow
@pytest.mark.parametrize("model", MODELS)
def test_rms_error_within_the_target_factor_of_the_mean_sigma(table, model):
    _, rms, mean_sigma, ratio = table[model]
    assert 1.0 / TARGET <= ratio <= TARGET, f"{model}: RMS {rms:.3f} / sigma {mean_sigma:.3f}"


@pytest.mark.parametrize(
    ("rows", "tied"),
    [
        ([[1] * 40, [1] * 39 + [0], [0] * 40], [True, True, False]),
        ([[1] * 30 + [0] * 10, [0] * 10 + [1] * 30, [0] * 40], [True, True, False]),
        ([[1] * 40, [1] * 20 + [0] * 20, [1] * 40], [True, False, True]),
        ([[0] * 40, [0] * 40], [True, True]),
    ],
    ids=["lead-of-one", "swap-of-ten", "lead-of-twenty", "no-support"],
)
def test_support_ties_count_a_lead_beyond_three_deviations_of_the_sign_test(rows, tied):
    assert support_ties(np.array(rows, dtype=bool)).tolist() == tied


def test_a_support_lead_within_the_noise_leaves_the_plane_to_frontality():
    # a room at a baseline of 0.005 of the depth: the two interpretations of its homography
    # keep 784 and 782 of 811 matches in front of both cameras (29 against 27 kept by one
    # only); the count chose the one 0.37 degree off, frontality the one 0.21 off
    pair = imperfect_render(2, 0.005)
    result = estimate_pair(pair.image1, pair.image2, pair.K_given)
    assert result.model == "plane" and result.plane.ambiguous
    assert rotation_error_deg(result.R, pair.R) < 0.3
