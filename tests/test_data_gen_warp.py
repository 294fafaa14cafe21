"""Real photos warped by a pure rotation: geometry, coverage, imperfections and bad input."""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
import pytest
from test_data_gen_imperfect import rotation_residuals, sift_matches

from ppo_cv.data_gen import (
    REAL_PHOTO,
    Imperfections,
    intrinsics,
    make_warped_pair,
    source_photos,
    warp_pair,
)

BUNDLED = [Path(str(resources.files("ppo_cv") / "data" / n)) for n in ("demo1.png", "demo2.png")]


def photo() -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(BUNDLED[0])), cv2.COLOR_BGR2RGB)


@pytest.fixture(scope="module")
def warped():
    return make_warped_pair(seed=0, index=3, source=BUNDLED)


def test_identity_warp_with_the_photo_camera_returns_the_photo():
    image = photo()
    K = intrinsics((640, 480), 60.0)
    pair = warp_pair(image, K, np.eye(3), K_source=K)
    np.testing.assert_array_equal(pair.image1, image)
    np.testing.assert_array_equal(pair.image2, image)
    assert np.all(pair.t == 0) and np.isnan(pair.depth1).all()


def test_warped_pair_is_the_rotation_homography_after_true_undistortion(warped):
    pair = warped
    assert np.all(pair.t == 0.0) and pair.image1.shape == (312, 416, 3)
    params = pair.params
    assert params["photo"] in {"demo1.png", "demo2.png"}
    assert 25.0 <= params["hfov_deg"] <= 35.0
    assert 0.35 <= abs(params["yaw_deg"]) / params["hfov_deg"] <= 0.7
    assert 0.02 <= abs(params["k1"]) <= 0.1 and 70 <= params["jpeg_quality"] <= 95
    assert params["upsampling"] >= 1.0
    factor = params["focal_factor"]
    np.testing.assert_allclose(pair.K1_given[:2, :2], pair.K1[:2, :2] * factor, rtol=1e-15)
    p1, p2 = sift_matches(pair.image1, pair.image2)
    assert len(p1) > 40
    residual = rotation_residuals(pair, p1, p2)
    assert np.median(residual) < 1.0 and np.mean(residual < 1.0) > 0.6
    wrong = dataclasses.replace(pair, R=cv2.Rodrigues(np.radians([0.5, 0.0, 0.0]))[0] @ pair.R)
    assert np.median(rotation_residuals(wrong, p1, p2)) > 3.0


def test_views_stay_inside_the_photo():
    """No black border: no output pixel samples the outermost ring of a white photo (black)."""
    white = np.zeros((480, 640, 3), np.uint8)
    white[1:-1, 1:-1] = 255
    exact = dataclasses.replace(REAL_PHOTO, noise_std=0.0, blur_sigma=0.0, jpeg_quality=None)
    for index in range(8):
        pair = make_warped_pair(seed=1, index=index, imperfections=exact, source=BUNDLED)
        K, R = pair.K1, pair.R
        again = warp_pair(white, K, R, pair.dist1, pair.image1.shape[1::-1])
        assert again.image1.min() >= 240 and again.image2.min() >= 240
        np.testing.assert_array_equal(again.params["K_source"], pair.params["K_source"])


def test_given_source_camera_that_does_not_cover_is_refused():
    K = intrinsics((640, 480), 60.0)
    R = cv2.Rodrigues(np.radians([0.0, 10.0, 0.0]))[0]
    with pytest.raises(ValueError, match="leaves the photo"):
        warp_pair(photo(), K, R, K_source=K)
    fitted = warp_pair(photo(), K, R)
    assert fitted.params["upsampling"] > 1.0
    with pytest.raises(ValueError, match="behind the photo"):
        warp_pair(photo(), K, cv2.Rodrigues(np.radians([0.0, 170.0, 0.0]))[0])


def test_warps_are_deterministic_and_perfect_ones_share_the_geometry():
    a = make_warped_pair(seed=4, index=1, source=BUNDLED)
    b = make_warped_pair(seed=4, index=1, source=BUNDLED)
    np.testing.assert_array_equal(a.image1, b.image1)
    np.testing.assert_array_equal(a.image2, b.image2)
    assert a.params == b.params
    perfect = make_warped_pair(seed=4, index=1, imperfections=None, source=BUNDLED)
    np.testing.assert_array_equal(perfect.R, a.R)
    np.testing.assert_array_equal(perfect.K1, a.K1)
    assert perfect.dist1.size == 0 and perfect.params["imperfect"] is False
    np.testing.assert_array_equal(perfect.K1_given, perfect.K1)
    other = make_warped_pair(seed=5, index=1, source=BUNDLED)
    assert not np.array_equal(other.R, a.R)


def test_default_source_is_the_freiburg_frames(freiburg):
    photos = source_photos()
    assert [p.name for p in photos] == sorted(p.name for p in (freiburg / "images").iterdir())
    pair = make_warped_pair(seed=0, index=0)
    assert pair.params["photo"] in {p.name for p in photos}


def test_bad_warp_arguments_are_rejected(tmp_path):
    K = intrinsics((64, 48), 30.0)
    with pytest.raises(TypeError, match="uint8"):
        warp_pair(photo().astype(np.float32), K, np.eye(3))
    with pytest.raises(ValueError, match="shape"):
        warp_pair(np.zeros((48, 64, 4), np.uint8), K, np.eye(3))
    with pytest.raises(ValueError, match="R must be a rotation"):
        warp_pair(photo(), K, 2 * np.eye(3))
    with pytest.raises(ValueError, match="jpeg_quality"):
        warp_pair(photo(), K, np.eye(3), jpeg_quality=0)
    with pytest.raises(ValueError, match="focal_factor"):
        warp_pair(photo(), K, np.eye(3), focal_factor=0.0)
    with pytest.raises(ValueError, match="does not exist"):
        make_warped_pair(source=tmp_path / "missing.png")
    with pytest.raises(ValueError, match="no photos"):
        make_warped_pair(source=tmp_path)
    (tmp_path / "broken.png").write_bytes(b"not a png")
    with pytest.raises(ValueError, match="not a readable image: .*broken.png"):
        make_warped_pair(source=tmp_path)
    with pytest.raises(TypeError, match="imperfections"):
        make_warped_pair(imperfections="real", source=BUNDLED)
    with pytest.raises(ValueError, match="index"):
        make_warped_pair(index=-1, source=BUNDLED)
    assert isinstance(REAL_PHOTO, Imperfections)
