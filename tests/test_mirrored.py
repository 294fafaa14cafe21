"""A mirrored image against an unmirrored one is refused (issue 44, defect 10).

No camera motion mirrors an image, but a reflection still fits an essential matrix: without the
orientation test of the homography (``homography.require_unmirrored``) an image against its own
mirror image read as a confident general motion of 80-84 deg.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import ppo_cv
from ppo_cv.metrics import rotation_error_deg

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
FX, FY, CX, CY = DEMO["intrinsics"]
K = np.array([[FX, 0.0, CX], [0.0, FY, CY], [0.0, 0.0, 1.0]])
FLIPS = {"left-right": np.s_[:, ::-1], "up-down": np.s_[::-1, :]}
REFUSAL = "the images are mirror images of each other"


def _demo(index: int) -> np.ndarray:
    return cv2.imread(str(DATA / DEMO[f"image{index}"]))


def _flipped(image: np.ndarray, flip: str) -> np.ndarray:
    return np.ascontiguousarray(image[FLIPS[flip]])


@pytest.mark.parametrize("flip", list(FLIPS))
@pytest.mark.parametrize("index", [1, 2])
def test_a_demo_image_against_its_mirror_image_is_refused(index, flip):
    image = _demo(index)
    with pytest.raises(ValueError, match=rf"{REFUSAL}: the homography of \d+ matches reverses"):
        ppo_cv.estimate_pair(image, _flipped(image, flip), K)


def test_both_images_mirrored_is_a_rigid_scene_with_the_mirrored_pose():
    """Not refused, and rightly so: the pose is the mirror image of the true one."""
    mirror = np.diag([-1.0, 1.0, 1.0])
    K_mirrored = K.copy()
    K_mirrored[0, 2] = 640 - 1 - CX  # the principal point of the mirrored 640-pixel rows
    result = ppo_cv.estimate_pair(
        _flipped(_demo(1), "left-right"), _flipped(_demo(2), "left-right"), K_mirrored
    )
    reference = mirror @ np.array(DEMO["reference_R"]) @ mirror
    assert rotation_error_deg(result.R, reference) < 1.0


def test_ordinary_pairs_pass_the_orientation_test():
    result = ppo_cv.estimate_pair(_demo(1), _demo(2), K)
    assert rotation_error_deg(result.R, np.array(DEMO["reference_R"])) < 1.0


@pytest.mark.parametrize("line", [0, 40, 84])
def test_freiburg_frames_against_their_mirror_images_are_refused(freiburg, line):
    fields = (freiburg / "pairs_with_gt.txt").read_text().splitlines()[line].split()
    K_line = np.array(fields[4:13], dtype=float).reshape(3, 3)
    first, second = (cv2.imread(str(freiburg / "images" / name)) for name in fields[:2])
    result = ppo_cv.estimate_pair(first, second, K_line)
    T = np.array(fields[22:38], dtype=float).reshape(4, 4)
    assert rotation_error_deg(result.R, T[:3, :3]) < 5.0
    with pytest.raises(ValueError, match=REFUSAL):
        ppo_cv.estimate_pair(first, _flipped(first, "left-right"), K_line)
