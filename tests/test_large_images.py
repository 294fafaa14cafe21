"""Photos of phone size: what a 12-megapixel pair costs in memory, and the threshold of keypoints
located on its reduced copy."""

from __future__ import annotations

import threading
import time
import tracemalloc

import cv2
import numpy as np
import pytest

from ppo_cv import consensus, photometric
from ppo_cv.options import PairOptions


class _Overlap:
    """A stand-in for the detector that counts how many detections run at once."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.running = 0
        self.most = 0
        self.calls = 0

    def __call__(self, image, *args):
        with self.lock:
            self.running += 1
            self.calls += 1
            self.most = max(self.most, self.running)
        time.sleep(0.2)
        with self.lock:
            self.running -= 1
        return image.shape


@pytest.mark.parametrize(
    ("shape", "at_once"),
    [((480, 640), 2), ((960, 1280), 2), ((3000, 4000), 1), ((3000, 4000, 3), 1)],
    ids=["640x480", "1280x960", "4000x3000 grey", "4000x3000 colour"],
)
def test_large_pairs_are_detected_one_image_after_the_other(monkeypatch, shape, at_once):
    """Two detection copies of 2000x1500 pixels on two threads held two SIFT scale spaces of
    about 650 MB each; a 640x480 pair keeps its two threads."""
    overlap = _Overlap()
    monkeypatch.setattr(consensus, "detect_features", overlap)
    image = np.zeros(shape, np.uint8)
    f1, f2, _ = consensus.detect_both(image, image.copy(), PairOptions(backend="opencv"))
    assert f1 == f2 == shape
    assert overlap.most == at_once


def test_the_bound_counts_the_copies_detection_runs_on():
    """Full-size detection (``max_image_size=None``) of a pair of 1500x1100 images exceeds the
    bound that their copies reduced to 1000 pixels keep within."""
    shape = (1100, 1500)
    reduced = consensus._detected_pixels(shape, PairOptions(max_image_size=1000))
    full = consensus._detected_pixels(shape, PairOptions(max_image_size=None))
    assert full == 1100 * 1500 and reduced == pytest.approx(1000 * 1100 / 1.5)
    assert 2 * reduced <= consensus._PARALLEL_DETECTION_PIXELS < 2 * full


def _texture(shape: tuple[int, int]) -> np.ndarray:
    rng = np.random.default_rng(0)
    return cv2.GaussianBlur(rng.uniform(0, 255, shape), (0, 0), 2).astype(np.uint8)


@pytest.mark.parametrize(
    ("shape", "large"), [((240, 320), False), ((1500, 2100), True)], ids=["320x240", "2100x1500"]
)
def test_window_sides_of_a_large_image_are_searched_one_after_the_other(monkeypatch, shape, large):
    """Each window side's search warps image 2 at full size: on two threads a 4000x3000 pair's
    refit peaked at 1.22 GB of resident memory, one side after the other at 1.02 GB."""
    overlap = _Overlap()

    def corners(gray1, *args):
        overlap(gray1)
        return np.zeros((0, 2))

    monkeypatch.setattr(photometric, "_corners", corners)
    image = _texture(shape)
    K = np.array([[shape[1], 0, shape[1] / 2 - 0.5], [0, shape[1], shape[0] / 2 - 0.5], [0, 0, 1]])
    refined = photometric.refine_rotation_photometric(
        image, image, K, K, np.eye(3), window=(15, 31)
    )
    assert refined is None and overlap.calls == 2
    assert overlap.most == (1 if large else min(2, max(cv2.getNumThreads(), 1)))


def test_the_refit_prepares_an_image_in_few_bytes_per_pixel():
    """Image 2 read as cells, image 1's contrast and image 2 warped, in numpy bytes per pixel
    of the image (the peak while preparing, what stays, the warp's passing peak): 59, 40 and 33
    when each coefficient had its own array and the contrast was computed last."""
    image = _texture((600, 800))
    pixels = image.size
    tracemalloc.start()
    try:
        prepared = photometric._prepare(image, image.copy())
        kept, peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        photometric._seen_through(prepared, lambda points: points + [3.3, -2.1])
        warp = tracemalloc.get_traced_memory()[1] - tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert peak / pixels < 46 and kept / pixels < 38 and warp / pixels < 24
    np.testing.assert_array_equal(prepared.plane2.intensity, image.ravel())


def test_the_refit_of_a_large_pure_rotation_runs_on_the_reduced_copy(monkeypatch):
    """A 640x480 pure-rotation render enlarged to 2560x1920: the refit aligns its windows on
    copies of at most ``max_image_size`` pixels, as the features were found (at full size it
    prepared and warped 12-megapixel planes, 5-6 s of a phone-size pair), and keeps the
    rotation of the render."""
    from ppo_cv import data_gen, pipeline
    from ppo_cv.metrics import rotation_error_deg

    seen = []
    refit = pipeline.refine_rotation_photometric

    def recording(image1, image2, *args, **kwargs):
        seen.append((image1.shape[:2], image2.shape[:2]))
        return refit(image1, image2, *args, **kwargs)

    monkeypatch.setattr(pipeline, "refine_rotation_photometric", recording)
    pair = data_gen.make_pair("pure-rotation", seed=0, index=0)
    scale = 4.0
    S = np.array([[scale, 0, (scale - 1) / 2], [0, scale, (scale - 1) / 2], [0, 0, 1]])
    images = [
        cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
        for image in (pair.image1, pair.image2)
    ]
    result = pipeline.estimate_pair(*images, S @ pair.K1_given, S @ pair.K2_given)
    assert seen and all(shape == ((1500, 2000), (1500, 2000)) for shape in seen)
    assert result.pure_rotation and result.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(result.R, pair.R) < 0.05


def test_an_enlarged_pair_detected_on_a_reduced_copy_keeps_the_inliers_of_the_original():
    """The demo pair enlarged twice (bicubic, the camera matrix scaled) and detected on a copy
    reduced back to 640 px: its keypoints carry twice the original's noise in full-size
    pixels. With the threshold held at 1 full-size pixel it kept 202 inliers where the
    original keeps 259 of its matches; with the threshold scaled by the reduction, 255."""
    import json
    from pathlib import Path

    from ppo_cv import pipeline
    from ppo_cv.metrics import direction_error_deg, rotation_error_deg

    data = Path(pipeline.__file__).parent / "data"
    demo = json.loads((data / "demo.json").read_text())
    images = [cv2.imread(str(data / demo[name])) for name in ("image1", "image2")]
    fx, fy, cx, cy = demo["intrinsics"]
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
    S = np.array([[2.0, 0, 0.5], [0, 2.0, 0.5], [0, 0, 1]])
    enlarged = [
        cv2.resize(image, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC) for image in images
    ]
    original = pipeline.estimate_pair(*images, K)
    result = pipeline.estimate_pair(*enlarged, S @ K, options=PairOptions(max_image_size=640))
    assert result.num_inliers >= 0.95 * original.num_inliers
    assert result.evidence.significance.ransac_threshold_px == 2.0
    assert original.evidence.significance.ransac_threshold_px == 1.0
    assert rotation_error_deg(result.R, np.array(demo["reference_R"])) < 0.5
    assert direction_error_deg(result.t, np.array(demo["reference_t"])) < 1.5


def test_the_threshold_is_scaled_by_the_larger_reduction_within_the_accepted_range():
    """A 4000x3000 image with a 2000x1500 one: the threshold doubles, as the first image's
    keypoints are located on a copy reduced twice; 80 pixels so doubled are held at
    ``MAX_RANSAC_THRESHOLD`` (the replaced options checked it: "must be in (0, 100]", for a
    threshold the user never gave). A pair no larger than ``max_image_size`` keeps its
    options."""
    from types import SimpleNamespace

    from ppo_cv import pipeline

    large = SimpleNamespace(img1=np.zeros((3000, 4000), np.uint8), img2=np.zeros((1500, 2000)))
    assert pipeline._in_detection_pixels(large, PairOptions()).ransac_threshold == 2.0
    held = pipeline._in_detection_pixels(large, PairOptions(ransac_threshold=80))
    assert held.ransac_threshold == pipeline.MAX_RANSAC_THRESHOLD
    options = PairOptions(ransac_threshold=0.7)
    small = SimpleNamespace(img1=large.img2, img2=large.img2)
    assert pipeline._in_detection_pixels(small, options) is options
    full_size = PairOptions(max_image_size=None)
    assert pipeline._in_detection_pixels(large, full_size) is full_size
