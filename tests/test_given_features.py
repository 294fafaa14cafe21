"""Features given to ``estimate_pair``: used as given, refused when unusable, and a pose that
comes from a detection on the images instead said so in the result and by a warning."""

from __future__ import annotations

import json
import warnings
from importlib import resources

import cv2
import numpy as np
import pytest

from ppo_cv import PairOptions, estimate_pair
from ppo_cv.consensus import GivenFeaturesReplacedWarning
from ppo_cv.features import Features, at_threshold, detect_features, match_features


@pytest.fixture(scope="module")
def demo():
    """The demo pair: two images, their camera and their default SIFT features."""
    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    images = [cv2.imread(str(data / info[name])) for name in ("image1", "image2")]
    fx, fy, cx, cy = info["intrinsics"]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return images, K, [detect_features(image) for image in images]


def _sift(keypoints, descriptors) -> Features:
    return Features(np.asarray(keypoints, float), np.asarray(descriptors, np.float32), "sift")


def _unusable(f: Features) -> dict[str, Features]:
    n = len(f)
    return {
        "all-zero descriptors": _sift(f.keypoints, np.zeros((n, 128))),
        "one-value descriptors": _sift(f.keypoints, np.full((n, 128), 0.25)),
        "no keypoints": _sift(np.zeros((0, 2)), np.zeros((0, 128))),
        "one keypoint": _sift(f.keypoints[:1], f.descriptors[:1]),
        "keypoints at one place": _sift(np.full((n, 2), -0.9), f.descriptors),
    }


_REASONS = {
    "all-zero descriptors": "1 distinct descriptor",
    "one-value descriptors": "1 distinct descriptor",
    "no keypoints": r"too few keypoints \(0, need 8\)",
    "one keypoint": r"too few keypoints \(1, need 8\)",
    "keypoints at one place": "at 1 distinct place",
}


@pytest.mark.parametrize("case", sorted(_REASONS))
@pytest.mark.parametrize("which", ["features1", "features2"])
def test_unusable_given_features_are_refused_by_name(demo, case, which):
    """Each was replaced by a detection on the images, a pose given without a word."""
    images, K, (f1, f2) = demo
    given = {"features1": f1, "features2": f2}
    given[which] = _unusable(given[which])[case]
    with pytest.raises(ValueError, match=rf"^{which} has .*{_REASONS[case]}"):
        estimate_pair(*images, K, **given)


def test_unusable_features_fail_before_any_detection(demo, monkeypatch):
    images, K, (f1, f2) = demo

    def refused(*args, **kwargs):
        raise AssertionError("detected on the images")

    monkeypatch.setattr("ppo_cv.consensus.detect_features", refused)
    zeros = _unusable(f1)["all-zero descriptors"]
    with pytest.raises(ValueError, match="features1 has 1 distinct descriptor"):
        estimate_pair(*images, K, features1=zeros, features2=f2)


def test_usable_given_features_are_the_features_used(demo):
    images, K, (f1, f2) = demo
    with warnings.catch_warnings():
        warnings.simplefilter("error", GivenFeaturesReplacedWarning)
        result = estimate_pair(*images, K, features1=f1, features2=f2)
    detected = estimate_pair(*images, K)
    assert result.evidence.significance.features == "given"
    assert detected.evidence.significance.features == "detected"
    np.testing.assert_array_equal(result.keypoints1, f1.keypoints)
    np.testing.assert_allclose(result.R, detected.R, atol=1e-12)


def _scrambled(f: Features) -> Features:
    """``f`` with its descriptors dealt to other keypoints: well formed, matching nothing."""
    order = np.random.default_rng(0).permutation(len(f))
    return Features(f.keypoints, f.descriptors[order], f.kind)


def test_a_pose_from_a_detection_on_the_images_says_so(demo):
    """Given features without a consensus gave way to a detection on the images, and the
    result read as theirs."""
    images, K, (f1, f2) = demo
    given = {"features1": _scrambled(f1), "features2": f2}
    with pytest.warns(GivenFeaturesReplacedWarning, match="features1 and features2 gave no cons"):
        result = estimate_pair(*images, K, **given)
    assert result.evidence.significance.features == "detected"
    assert result.evidence.significance.threshold_scale == 0.25
    assert not np.array_equal(result.keypoints1, f1.keypoints)
    with pytest.raises(ValueError, match="no reliable two-view geometry|too few matches"):
        estimate_pair(*images, K, options=PairOptions(redetect_below=0), **given)


def test_given_denser_features_stay_given_on_a_second_consensus(demo, monkeypatch):
    """SIFT features detected at the lower threshold serve the second consensus themselves."""
    images, K, _ = demo
    denser = [detect_features(image, threshold_scale=0.25) for image in images]
    monkeypatch.setattr("ppo_cv.consensus.detect_features", None)  # no detection may run
    options = PairOptions(redetect_below=10**5)  # every consensus is weak
    with warnings.catch_warnings():
        warnings.simplefilter("error", GivenFeaturesReplacedWarning)
        result = estimate_pair(*images, K, options=options, features1=denser[0],
                               features2=denser[1])  # fmt: skip
    assert result.evidence.significance.features == "given"
    assert len(at_threshold(denser[0], 1.0)) < len(denser[0])


def _options_repr_cut(call) -> str:
    with pytest.raises((TypeError, ValueError)) as caught:
        call()
    return str(caught.value)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda image: detect_features(image, PairOptions()), "kind must be a detector name"),
        (lambda image: detect_features(image, "surf" * 10**5), "unknown feature type 'surf"),
        (lambda image: detect_features(image, np.zeros(10**6)), "kind must be a detector name"),
    ],
    ids=["options", "long name", "array"],
)
def test_errors_quote_a_users_value_cut(demo, call, message):
    """``detect_features(image, PairOptions())`` printed the whole options' repr; an array of
    a million values failed on its truth value, naming nothing."""
    with pytest.raises((TypeError, ValueError)) as caught:
        call(demo[0][0])
    text = str(caught.value)
    assert text.startswith(message) and len(text) < 160, text
    assert "max_features=8000" not in text and "surf" * 20 not in text


def test_options_in_place_of_the_detector_name_is_a_type_error(demo):
    with pytest.raises(TypeError, match=r"^kind must be a detector name \(sift, orb, akaze\), got "
                       r"PairOptions PairOptions\(features="):  # fmt: skip
        detect_features(demo[0][0], PairOptions())


@pytest.mark.parametrize("dtype", [np.float64, np.float16])
def test_float_descriptors_of_any_width_are_matched_by_flann(dtype):
    """Above 12000 features FLANN matches them: it takes float32 only, and other floats failed
    with an OpenCV error. Their values in float32 match alike."""
    rng = np.random.default_rng(0)
    keypoints = rng.uniform(0, 1000, (12100, 2))
    descriptors = rng.random((12100, 8)).astype(dtype)
    shuffled = descriptors[rng.permutation(12100)]

    def matches(kind):
        f1, f2 = (Features(keypoints, d.astype(kind), "sift") for d in (descriptors, shuffled))
        return match_features(f1, f2, flann=True)

    expected = matches(np.float32)
    assert len(expected) > 1000
    np.testing.assert_array_equal(matches(dtype), expected)
