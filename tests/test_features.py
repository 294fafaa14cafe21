"""Descriptor matching: the dense nearest-neighbour search against a brute-force sort."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import features
from ppo_cv.features import _two_nearest_dense


@pytest.mark.parametrize("block", [7, 256, 2048])
def test_two_nearest_equal_a_full_sort(block):
    rng = np.random.default_rng(3)
    d1 = rng.random((50, 16)).astype(np.float32)
    d2 = rng.random((40, 16)).astype(np.float32)
    index12, dist12, mutual12 = _two_nearest_dense(d1, d2, block=block)
    full = np.linalg.norm(d1[:, None, :].astype(float) - d2[None, :, :], axis=2)
    order = np.argsort(full, axis=1)[:, :2]
    np.testing.assert_array_equal(index12, order)
    np.testing.assert_allclose(dist12, np.take_along_axis(full, order, axis=1), atol=1e-5)
    mutual = np.argmin(full, axis=0)[order[:, 0]] == np.arange(len(d1))
    assert 0 < np.count_nonzero(mutual) < len(d1)
    np.testing.assert_array_equal(mutual12, mutual)


@pytest.mark.parametrize("block", [3, 2048])
def test_a_repeated_descriptor_is_the_mutual_match_of_its_first_row_only(block):
    rng = np.random.default_rng(4)  # small integers: every distance exact, the tie exact
    d2 = rng.integers(0, 16, (12, 8)).astype(np.float32)
    d1 = np.vstack([d2[[5, 2]], rng.integers(0, 16, (4, 8)).astype(np.float32), d2[[5]]])
    index12, _, mutual12 = _two_nearest_dense(d1, d2, block=block)
    assert index12[0, 0] == index12[6, 0] == 5
    assert mutual12[0] and mutual12[1] and not mutual12[6]


_GREY = np.random.default_rng(1).integers(0, 256, (48, 64), dtype=np.uint8)


def _sift(count: int = 4):
    from ppo_cv.features import Features

    rng = np.random.default_rng(0)
    return Features(rng.uniform(0, 100, (count, 2)).astype(np.float32),
                    rng.uniform(0, 1, (count, 128)).astype(np.float32), "sift",
                    np.full(count, 0.05, np.float32))  # fmt: skip


@pytest.mark.parametrize(
    "call, error, words",
    [(lambda f: features.match_features(None, f), TypeError,
      "features1 must be a ppo_cv.features.Features, got NoneType"),
     (lambda f: features.match_features(f, f, ratio="0.8"), TypeError,
      "ratio must be a number, got str"),
     (lambda f: features.match_features(f, f, ratio=True), TypeError,
      "ratio must be a number, got True"),
     (lambda f: features.match_features(f, f, mutual="no"), TypeError,
      "mutual must be True or False, got str 'no'"),
     (lambda f: features.match_features(f, f, unique=0), TypeError,
      "unique must be True or False, got int 0"),
     (lambda f: features.at_threshold(f, None), TypeError,
      "threshold_scale must be a number, got NoneType"),
     (lambda f: features.at_threshold((f,), 2.0), TypeError,
      "features must be a ppo_cv.features.Features, got tuple"),
     # max_features=1.5 ran as 1, a text failed in int(); max_image_size=0 was called a size
     # that makes the image too small, "or 0 for the full size"
     (lambda f: features.detect_features(_GREY, max_features=1.5), ValueError,
      "max_features must be a whole number in 1.."),
     (lambda f: features.detect_features(_GREY, max_features="800"), TypeError,
      "max_features must be a whole number, got str"),
     # ORB failed in OpenCV with std::bad_alloc
     (lambda f: features.detect_features(_GREY, "orb", max_features=2**31 - 1), ValueError,
      "max_features must be a whole number in 1..1000000, got 2147483647"),
     (lambda f: features.detect_features(_GREY, max_image_size=0), ValueError,
      "max_image_size must be a whole number in 32.."),
     (lambda f: features.detect_features(_GREY, threshold_scale="2"), TypeError,
      "threshold_scale must be a number, got str"),
     # "image must hold numbers, got dtype object": no word that no image was given
     (lambda f: features.detect_features(None, name="image2"), TypeError,
      "image2 is required: an image array (H, W) or (H, W, 3), got None"),
     (lambda f: features.detect_features("a.png"), TypeError,
      "image must be an image array (H, W) or (H, W, 3), got a path 'a.png': read it with "
      "ppo_cv.images.load_image")],
    ids=["features None", "ratio text", "ratio True", "mutual text", "unique 0",
         "threshold None", "features tuple", "max_features 1.5", "max_features text",
         "max_features beyond ORB",
         "max_image_size 0", "threshold_scale text", "image None", "image path"],
)  # fmt: skip
def test_detection_and_matching_name_a_bad_argument(call, error, words):
    # an AttributeError ("'NoneType' object has no attribute 'kind'"), Python's "'<' not
    # supported", ratio=True read as 1 and mutual="no" as true
    with pytest.raises(error) as info:
        call(_sift())
    assert words in str(info.value)


def _fields(**changed):
    f = _sift(6)
    fields = {"keypoints": f.keypoints, "descriptors": f.descriptors, "kind": f.kind,
              "responses": f.responses, "threshold_scale": 1.0}  # fmt: skip
    return {**fields, **changed}


_NAN_KEYPOINT = np.where(np.arange(12).reshape(6, 2) == 3, np.nan, 1.0)


@pytest.mark.parametrize(
    "changed, error, words",
    [({"keypoints": _NAN_KEYPOINT}, ValueError, "Features.keypoints has 1 NaN"),
     ({"keypoints": np.ones((6, 3))}, ValueError, "Features.keypoints must have shape (N, 2)"),
     ({"keypoints": np.ones((4, 2))}, ValueError,
      "Features.descriptors must have one row per keypoint (4, D), got (6, 128)"),
     ({"descriptors": np.zeros((6, 128), np.uint8)}, TypeError,
      "Features.descriptors of sift must be floats, got dtype uint8"),
     ({"descriptors": np.full((6, 128), np.nan, np.float32)}, ValueError,
      "Features.descriptors has 768 NaN"),
     ({"responses": np.ones(3)}, ValueError, "Features.responses must have one per keypoint"),
     ({"kind": "surf"}, ValueError, "Features.kind must be one of sift, orb, akaze"),
     ({"threshold_scale": float("nan")}, ValueError, "Features.threshold_scale must be a finite"),
     ({"keypoints": None}, TypeError, "Features.keypoints is required, got None")],
    ids=["NaN keypoint", "keypoints of 3", "fewer keypoints", "uint8 SIFT", "NaN descriptors",
         "responses short", "unknown kind", "NaN threshold scale", "no keypoints"],
)  # fmt: skip
def test_features_are_checked_when_made(changed, error, words):
    # given to estimate_pair, they ran: NaN keypoints and (N, 3) rows without a word, fewer
    # keypoints than descriptors failed with an IndexError deep inside the pipeline
    from ppo_cv.features import Features

    with pytest.raises(error) as info:
        Features(**_fields(**changed))
    assert words in str(info.value)


def test_features_take_their_keypoints_as_a_list():
    # "'list' object has no attribute 'shape'"
    from ppo_cv.features import Features

    given = Features(**_fields(keypoints=_sift(6).keypoints.tolist()))
    assert isinstance(given.keypoints, np.ndarray) and len(given) == 6


def test_given_features_of_another_size_or_detector_are_named():
    # they failed their first consensus and a detection on the images replaced them silently
    from ppo_cv.consensus import require_features_of
    from ppo_cv.features import Features

    f = _sift(6)
    with pytest.raises(ValueError, match=r"features2 has keypoints outside its 64x48 image"):
        require_features_of(f, f, (480, 640), (48, 64))
    shorter = Features(**_fields(descriptors=np.ones((6, 64), np.float32)))
    with pytest.raises(ValueError, match="descriptors of 128 and 64 values"):
        require_features_of(f, shorter, (480, 640), (480, 640))
    with pytest.raises(ValueError, match="descriptors of 128 and 64 values"):
        features.match_features(f, shorter)
