"""A second, denser detection for pairs whose first consensus is weak (``redetect_below``)."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import PairOptions, data_gen, estimate_pair
from ppo_cv import features as features_module
from ppo_cv.cli.pair import _summary
from ppo_cv.consensus import GivenFeaturesReplacedWarning
from ppo_cv.export import result_to_dict
from ppo_cv.features import at_threshold, detect_features
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.pipeline import REDETECT_THRESHOLD_SCALE

STITCHED_NOISY = data_gen.Imperfections(
    centred_principal_point=True,
    view_focal_error=0.01,
    exposure_ev=1.0,
    vignetting=0.35,
    noise_std=6.0,
    blur_sigma=1.2,
)
"""A stitcher's tripod pan (centre and per-photo focal lengths given, shots a stop apart,
vignetting) with the sensor noise and blur of ``benchmarks/pure_rotation.py``."""


def _bgr(image: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(image[..., ::-1])


@pytest.fixture(scope="module")
def narrow_pair(freiburg_photos):
    """Pair 21 of the warped-photo set 1: a 17 degree pan in a 27 degree field, so the views
    share a third of the image; 29 matches at OpenCV's SIFT threshold, 12 of them inliers."""
    pair = data_gen.make_warped_pair(
        seed=1, index=21, imperfections=STITCHED_NOISY, source=freiburg_photos
    )
    assert abs(pair.params["yaw_deg"]) > 0.6 * pair.params["hfov_deg"]
    return pair


def _estimate(pair, **options):
    return estimate_pair(
        _bgr(pair.image1), _bgr(pair.image2), pair.K1_given, pair.K2_given,
        options=PairOptions(**options),
    )  # fmt: skip


def test_a_lower_threshold_keeps_weaker_keypoints(narrow_pair):
    default = detect_features(narrow_pair.image1)
    denser = detect_features(narrow_pair.image1, threshold_scale=REDETECT_THRESHOLD_SCALE)
    assert len(denser) > 2 * len(default)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="threshold_scale"):
            detect_features(narrow_pair.image1, threshold_scale=bad)


def _demo_images() -> list[np.ndarray]:
    import cv2

    from ppo_cv.cli.pair import _demo_inputs

    image1, image2, _ = _demo_inputs()
    return [cv2.imread(image1), cv2.imread(image2)]


@pytest.mark.parametrize("max_image_size", [None, 320])
def test_denser_sift_features_thinned_are_those_of_the_default_threshold(max_image_size):
    for image in _demo_images():
        detect = {"max_image_size": max_image_size}
        default = detect_features(image, **detect)
        denser = detect_features(image, threshold_scale=REDETECT_THRESHOLD_SCALE, **detect)
        thinned = at_threshold(denser, 1.0)
        assert len(denser) > len(default) > 300
        np.testing.assert_array_equal(thinned.keypoints, default.keypoints)
        np.testing.assert_array_equal(thinned.descriptors, default.descriptors)
        assert thinned.threshold_scale == 1.0


@pytest.mark.parametrize("cap", [900, 1500])
def test_sift_cut_to_max_features_thins_to_the_default_threshold(cap):
    """The demo images hold 1210 and 991 keypoints at the default threshold, 2228 and 1989 at
    the lower one: cut at 1500 the lower detection still holds every default keypoint, cut at
    900 it holds the 900 strongest, as a detection at the default threshold cut there."""
    for image in _demo_images():
        cut = detect_features(image, max_features=cap, threshold_scale=REDETECT_THRESHOLD_SCALE)
        assert len(cut) >= cap and cut.threshold_scale > REDETECT_THRESHOLD_SCALE
        holds_default = cut.threshold_scale <= 1.0
        assert holds_default == (cap == 1500)
        expected = detect_features(image, max_features=8000 if holds_default else cap)
        found = at_threshold(cut, 1.0) if holds_default else cut
        np.testing.assert_array_equal(found.keypoints, expected.keypoints)
        np.testing.assert_array_equal(found.descriptors, expected.descriptors)


def _counted_detections(monkeypatch) -> list[float]:
    """The threshold scale of each detection ``estimate_pair`` runs from now on."""
    scales: list[float] = []

    def counted(image, *args, **kwargs):
        found = detect_features(image, *args, **kwargs)
        scales.append(kwargs.get("threshold_scale", args[3] if len(args) > 3 else 1.0))
        return found

    monkeypatch.setattr("ppo_cv.consensus.detect_features", counted)
    return scales


@pytest.mark.parametrize(
    ("detect_once", "per_megapixel", "detections"),
    [(False, None, [0.25] * 2 + [1.0] * 2), (True, None, [0.25] * 2),
     (True, 100, [0.25] * 4 + [1.0] * 2)],
)  # fmt: skip
def test_one_detection_serves_a_weak_pair_unless_cut(
    narrow_pair, monkeypatch, detect_once, per_megapixel, detections
):
    """The narrow pan, detected twice by default, with ``detect_once`` once at the lower
    threshold: both consensuses from it, the pose of the two detections. With a cap below its
    default keypoints, each image is detected again at the default threshold, and again at the
    lower one for the second consensus: the same pose."""
    image1, image2 = _bgr(narrow_pair.image1), _bgr(narrow_pair.image2)
    given = {"features1": detect_features(image1), "features2": detect_features(image2)}
    with pytest.warns(GivenFeaturesReplacedWarning):
        two_detections = estimate_pair(
            image1, image2, narrow_pair.K1_given, narrow_pair.K2_given, **given
        )
    if per_megapixel is not None:
        monkeypatch.setattr("ppo_cv.consensus.FIRST_DETECTION_PER_MEGAPIXEL", per_megapixel)
    scales = _counted_detections(monkeypatch)
    result = estimate_pair(
        image1, image2, narrow_pair.K1_given, narrow_pair.K2_given,
        options=PairOptions(detect_once=detect_once),
    )  # fmt: skip
    low = REDETECT_THRESHOLD_SCALE
    assert low == 0.25 and sorted(scales) == detections
    assert result.evidence.significance.threshold_scale == low
    np.testing.assert_allclose(result.R, two_detections.R, atol=1e-12)
    np.testing.assert_array_equal(result.inliers, two_detections.inliers)


def test_only_sift_features_detected_lower_are_thinned():
    image = _demo_images()[0]
    with pytest.raises(ValueError, match="only SIFT"):
        at_threshold(detect_features(image, "orb"), 1.0)
    with pytest.raises(ValueError, match="at least the features' 1"):
        at_threshold(detect_features(image), REDETECT_THRESHOLD_SCALE)


def test_given_denser_features_serve_both_consensuses(narrow_pair, monkeypatch):
    image1, image2 = _bgr(narrow_pair.image1), _bgr(narrow_pair.image2)
    denser = {
        name: detect_features(image, threshold_scale=REDETECT_THRESHOLD_SCALE)
        for name, image in (("features1", image1), ("features2", image2))
    }
    detected = _estimate(narrow_pair)
    calls = []

    def counted(image, *args, **kwargs):
        calls.append(args)
        return detect_features(image, *args, **kwargs)

    monkeypatch.setattr(features_module, "detect_features", counted)
    monkeypatch.setattr("ppo_cv.consensus.detect_features", counted)
    result = estimate_pair(image1, image2, narrow_pair.K1_given, narrow_pair.K2_given, **denser)
    assert not calls  # thinned for the first consensus, as they are for the second
    assert result.evidence.significance.threshold_scale == REDETECT_THRESHOLD_SCALE
    assert result.evidence.significance.features == "given"
    np.testing.assert_allclose(result.R, detected.R, atol=1e-9)


def test_a_weak_narrow_pan_is_flagged_on_denser_features(narrow_pair):
    single = _estimate(narrow_pair, redetect_below=0)
    assert single.evidence.significance.threshold_scale == 1.0 and single.num_inliers < 20
    assert not single.pure_rotation

    result = _estimate(narrow_pair)
    assert result.evidence.significance.threshold_scale == REDETECT_THRESHOLD_SCALE
    assert result.num_inliers > 2 * single.num_inliers
    assert result.pure_rotation and result.model == "rotation"
    assert rotation_error_deg(result.R, narrow_pair.R) < 0.3
    assert (
        result_to_dict(result)["evidence"]["significance"]["threshold_scale"]
        == REDETECT_THRESHOLD_SCALE
    )
    text = _summary(result, "a.png", "b.png", None)
    assert f"detected again at {REDETECT_THRESHOLD_SCALE:g} x the threshold" in text


@pytest.mark.slow
def test_given_features_of_a_weak_pair_are_detected_again(narrow_pair):
    image1, image2 = _bgr(narrow_pair.image1), _bgr(narrow_pair.image2)
    given = {"features1": detect_features(image1), "features2": detect_features(image2)}
    with pytest.warns(GivenFeaturesReplacedWarning, match=r"consensus of \d+ inliers \(fewer"):
        result = estimate_pair(image1, image2, narrow_pair.K1_given, narrow_pair.K2_given, **given)
    detected = _estimate(narrow_pair)
    assert result.evidence.significance.threshold_scale == REDETECT_THRESHOLD_SCALE
    assert result.evidence.significance.features == "detected"
    np.testing.assert_allclose(result.R, detected.R, atol=1e-9)


def test_a_strong_pair_keeps_its_first_features():
    from ppo_cv.cli.pair import _demo_inputs

    image1, image2, info = _demo_inputs()
    K = np.array(info["intrinsics"], dtype=float)
    K = np.array([[K[0], 0, K[2]], [0, K[1], K[3]], [0, 0, 1]])
    result = estimate_pair(image1, image2, K)
    assert result.num_inliers > 2 * PairOptions().redetect_below
    assert result.evidence.significance.threshold_scale == 1.0
    assert "detected again" not in _summary(result, "a.png", "b.png", None)


def test_without_a_consensus_the_first_failure_is_reported():
    pair = data_gen.make_warped_pair(seed=0, index=1)
    blank = np.full_like(pair.image1, 128)
    with pytest.raises(ValueError, match="image2 has too few features"):
        estimate_pair(_bgr(pair.image1), blank, pair.K1_given)


@pytest.mark.parametrize("index", [23, 42, 69])
def test_weak_freiburg_pairs_are_posed_from_denser_features(freiburg, index):
    """Three freiburg pairs with 17-28 inliers at the default threshold, posed 3-28 degrees
    off (the larger of the rotation and translation direction errors); the denser features
    bring each within 1.5 degrees of the pseudo ground truth."""
    import cv2

    from ppo_cv.data_gen.io import read_pairs
    from ppo_cv.metrics import direction_error_deg

    record = read_pairs(freiburg / "pairs_with_gt.txt")[index]
    images = [cv2.imread(str(freiburg / "images" / record[n])) for n in ("name1", "name2")]

    def error(options: PairOptions) -> tuple[float, float]:
        result = estimate_pair(*images, record["K1"], record["K2"], options=options)
        pose = max(
            rotation_error_deg(result.R, record["R"]), direction_error_deg(result.t, record["t"])
        )
        return pose, result.evidence.significance.threshold_scale

    single, scale = error(PairOptions(redetect_below=0))
    assert single > 3.0 and scale == 1.0
    denser, scale = error(PairOptions())
    assert denser < 1.5 and scale == REDETECT_THRESHOLD_SCALE
