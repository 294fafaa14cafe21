"""Conventions stated where results are shown: Euler labels, ``X2 = R X1 + t``, intrinsics,
distortion, undetermined translations and the stage timings."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import types

import cv2
import numpy as np
import pytest

from ppo_cv import consensus, pipeline
from ppo_cv.data_gen import make_pair
from ppo_cv.export import (
    CAMERA_AXES,
    POSE_CONVENTION,
    camera_euler_degrees,
    euler_zyx_degrees,
    result_to_dict,
)
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.result import (
    ConsensusSignificance,
    DecisionEvidence,
    LensTerms,
    ModelComparison,
    PairCameras,
    PairResult,
    PoseUncertainty,
    TrackParallax,
)

DEMO_K = "535.4,539.2,320.1,247.6"


def rodrigues(*rotation_vector):
    return cv2.Rodrigues(np.asarray(rotation_vector, dtype=np.float64))[0]


AXES = {"yaw": (0, 1, 0), "pitch": (1, 0, 0), "roll": (0, 0, 1)}


@pytest.mark.parametrize(
    "field, degrees",
    [(f, d) for f in AXES for d in (10.0, -35.0, 80.0)] + [("yaw", 170.0), ("roll", -170.0)],
)
def test_each_camera_axis_has_its_label(field, degrees):
    # y is the camera's down axis (pan), x its right axis (tilt), z its optical axis (roll).
    euler = camera_euler_degrees(rodrigues(*np.radians(degrees) * np.array(AXES[field])))
    expected = {"yaw": 0.0, "pitch": 0.0, "roll": 0.0, field: degrees}
    assert euler._asdict() == pytest.approx(expected, abs=1e-9)


def test_composition_order_is_yaw_then_pitch_then_roll():
    rng = np.random.default_rng(0)
    for yaw, pitch, roll in rng.uniform([-180, -89, -180], [180, 89, 180], (50, 3)):
        R = (
            rodrigues(0, np.radians(yaw), 0)
            @ rodrigues(np.radians(pitch), 0, 0)
            @ rodrigues(0, 0, np.radians(roll))
        )
        assert camera_euler_degrees(R) == pytest.approx((yaw, pitch, roll), abs=1e-8)


def test_gimbal_lock_still_rebuilds_the_rotation():
    R = rodrigues(0, np.radians(30), 0) @ rodrigues(np.radians(90), 0, 0)
    yaw, pitch, roll = camera_euler_degrees(R)
    assert pitch == pytest.approx(90.0) and roll == 0.0
    rebuilt = rodrigues(0, np.radians(yaw), 0) @ rodrigues(np.radians(pitch), 0, 0)
    np.testing.assert_allclose(rebuilt, R, atol=1e-9)


def test_old_aerospace_angles_still_work():
    assert euler_zyx_degrees(rodrigues(0, 0, np.radians(20))) == pytest.approx((20.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def demo_json_with_distortion():
    done = subprocess.run(
        [sys.executable, "-m", "ppo_cv", "pair", "--json", "--dist", "0.01,-0.002,0,0"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_json_states_the_conventions_and_the_distortion(demo_json_with_distortion):
    data = demo_json_with_distortion
    assert data["convention"] == POSE_CONVENTION and "X2 = R X1 + t" in data["convention"]
    assert data["camera_axes"] == CAMERA_AXES == "x right, y down, z forward"
    assert (
        data["cameras"]["dist1"]
        == data["cameras"]["dist2"]
        == pytest.approx([0.01, -0.002, 0.0, 0.0])
    )
    np.testing.assert_allclose(
        data["cameras"]["K1"], [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]
    )
    assert np.linalg.norm(data["t"]) == pytest.approx(1.0) and "t_guess" not in data
    euler = camera_euler_degrees(np.array(data["R"]))
    assert data["rotation_euler_deg"] == pytest.approx(euler._asdict())
    assert "euler_zyx_deg" not in data


def test_summary_and_help_state_the_conventions():
    summary = subprocess.run(
        [sys.executable, "-m", "ppo_cv", "pair", "--dist", "0.01,-0.002,0,0"],
        capture_output=True,
        text=True,
    )
    assert summary.returncode == 0, summary.stderr
    text = summary.stdout
    assert "X2 = R X1 + t" in text and "x right, y down, z forward" in text
    assert "(about y)" in text and "(about x)" in text and "(about z)" in text
    assert "fx 535.40  fy 539.20  cx 320.10  cy 247.60  distortion 0.01,-0.002,0,0" in text
    helped = subprocess.run(
        [sys.executable, "-m", "ppo_cv", "pair", "--help"],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "120"},
    )
    assert "X2 = R X1 + t" in helped.stdout and "t_guess" in helped.stdout


@pytest.fixture(scope="module")
def pure_rotation_files(tmp_path_factory):
    pair = make_pair("pure-rotation", seed=0, index=0, size=(480, 360))
    folder = tmp_path_factory.mktemp("rotation")
    for name, image in (("a.png", pair.image1), ("b.png", pair.image2)):
        cv2.imwrite(str(folder / name), image[..., ::-1])
    K = pair.K1
    return folder, f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}", pair


def test_pure_rotation_json_has_no_usable_t(pure_rotation_files):
    folder, K, pair = pure_rotation_files
    args = [sys.executable, "-m", "ppo_cv", "pair", str(folder / "a.png"), str(folder / "b.png")]
    done = subprocess.run([*args, "--K", K, "--json"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    data = json.loads(done.stdout)
    assert data["pure_rotation"] and not data["translation_determined"]
    assert data["t"] is None and np.linalg.norm(data["t_guess"]) == pytest.approx(1.0)
    R_error = rotation_error_deg(data["R"], pair.R)
    assert R_error < 0.5
    # the stated rotation uncertainty covers the actual error within a few sigma
    assert 0.0 < data["uncertainty"]["rotation_sigma_deg"] < 1.0
    assert R_error < 4.0 * data["uncertainty"]["rotation_sigma_deg"]
    summary = subprocess.run([*args, "--K", K], capture_output=True, text=True).stdout
    assert "translation  undetermined (pure rotation); best unit guess" in summary
    assert f"R sigma      {data['uncertainty']['rotation_sigma_deg']:.3f} deg" in summary


def test_result_to_dict_keeps_t_for_a_general_motion():
    nan = float("nan")
    result = PairResult(
        R=np.eye(3), t=np.array([1.0, 0, 0]), pure_rotation=False, model="general",
        rotation_source="essential", pri=0.1,
        keypoints1=np.zeros((3, 2)), keypoints2=np.zeros((3, 2)),
        matches=np.repeat(np.arange(3), 2).reshape(3, 2), inliers=np.ones(3, dtype=bool),
        points3d=np.ones((3, 3)), point_matches=np.arange(3), colours=np.zeros((3, 3), np.uint8),
        cameras=PairCameras(np.eye(3), np.eye(3), None, np.array([0.1, 0, 0, 0]), (4, 3), (4, 3)),
        uncertainty=PoseUncertainty(1.0, nan, 0),
        lens=LensTerms(1.0, 1.0, np.zeros(2), 3.0, nan, 0.0),
        evidence=DecisionEvidence(
            ModelComparison(0.015, *[nan] * 10), TrackParallax(nan, nan),
            ConsensusSignificance(-50.0, 1.0, 1.0),
        ),
        plane=None, timings={},
    )  # fmt: skip
    data = result_to_dict(result)
    assert data["t"] == [1.0, 0.0, 0.0] and "t_guess" not in data
    assert data["cameras"]["dist1"] is None and data["cameras"]["dist2"] == [0.1, 0.0, 0.0, 0.0]
    json.dumps(data)


def test_features_time_excludes_the_overlapped_pycolmap_import(monkeypatch):
    pair = make_pair("general", seed=0, index=0, size=(240, 180))
    import importlib

    def slow_import(name):
        time.sleep(1.5)  # an import far slower than detection on a 240x180 image
        return importlib.import_module(name)

    monkeypatch.setattr(consensus, "sys", types.SimpleNamespace(modules={}))
    monkeypatch.setattr(consensus, "importlib", types.SimpleNamespace(import_module=slow_import))
    result = pipeline.estimate_pair(pair.image1[..., ::-1], pair.image2[..., ::-1], pair.K1)
    stages = list(result.timings)
    assert stages[stages.index("features") + 1] == "pycolmap_import"
    assert result.timings["features"] < 1.0 < result.timings["pycolmap_import"]
