"""A :class:`~ppo_cv.PairResult` prints as one readable line, its large arrays by their shape."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

import ppo_cv
from ppo_cv.result import compact_repr


@pytest.fixture(scope="module")
def demo_result():
    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    fx, fy, cx, cy = info["intrinsics"]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return ppo_cv.estimate_pair(str(data / info["image1"]), str(data / info["image2"]), K)


def test_pair_result_repr_shows_the_answer_and_the_arrays_by_shape(demo_result):
    """``print(result)`` on the demo pair wrote 14,000 characters over hundreds of lines of
    keypoints and matches, with the answer lost among them."""
    text = repr(demo_result)
    assert "\n" not in text and len(text) < 3000 and str(demo_result) == text
    assert text.startswith("PairResult(R=array([[") and "model='general'" in text
    for name in ("keypoints1", "keypoints2", "matches", "inliers", "points3d", "colours"):
        array = getattr(demo_result, name)
        assert f"{name}=<ndarray {array.dtype}, shape {array.shape}>" in text
    assert "cameras=PairCameras(K1=array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6]," in text
    assert "plane=None" in text and "timings={'load': " in text


@pytest.mark.parametrize(
    "value, expected",
    [
        (np.arange(16.0).reshape(4, 4)[:1], "array([[0.0, 1.0, 2.0, 3.0]])"),
        (np.zeros((17,), np.uint8), "<ndarray uint8, shape (17,)>"),
        (np.float64(0.25), "0.25"),
        ((640, 480), "(640, 480)"),
        ((np.int64(3),), "(3,)"),
        ({"a": np.ones(2)}, "{'a': array([1.0, 1.0])}"),
        (np.array([1 / 3]), "array([0.333333])"),
    ],
)
def test_compact_repr_of_each_kind(value, expected):
    assert compact_repr(value) == expected


def test_rendered_pairs_and_protocol_samples_print_their_arrays_by_shape():
    """A rendered pair printed 118 lines of numpy's summaries of its images and depth map, a
    protocol sample 14,000 characters."""
    from ppo_cv.data_gen import RenderedPair, paper_protocol

    image = np.zeros((120, 160, 3), np.uint8)
    pair = RenderedPair(image, image, np.eye(3), np.eye(3), np.eye(3), np.zeros(3),
                        np.ones((120, 160), np.float32), params={"scene": "room"})  # fmt: skip
    text = repr(pair)
    assert "\n" not in text and len(text) < 800
    assert "image1=<ndarray uint8, shape (120, 160, 3)>" in text
    assert "depth1=<ndarray float32, shape (120, 160)>" in text and "'scene': 'room'" in text
    sample = paper_protocol(n_poses=20, n_points=50, alpha=0.2, noise_px=1.0, seed=0)
    text = repr(sample)
    assert "\n" not in text and len(text) < 800
    assert "points1=<ndarray float64, shape (20, 50, 2)>" in text and "seed=0, mc_run=0)" in text
