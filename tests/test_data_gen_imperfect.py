"""Imperfect renders (distortion, focal error, narrow field of view, JPEG) and the new presets."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from ppo_cv.data_gen import (
    REAL_PHOTO,
    Imperfections,
    make_pair,
    make_scene,
    project_points,
    sample_motion,
)
from ppo_cv.metrics import rotation_error_deg

SIZE = (320, 240)
EXACT = Imperfections(jpeg_quality=None, noise_std=0.0, blur_sigma=0.0)


def sift_matches(image1, image2, ratio=0.75):
    """Ratio-test SIFT matches between two RGB images: pixels (m, 2) in each."""
    sift = cv2.SIFT_create(nfeatures=3000)
    k1, d1 = sift.detectAndCompute(cv2.cvtColor(image1, cv2.COLOR_RGB2GRAY), None)
    k2, d2 = sift.detectAndCompute(cv2.cvtColor(image2, cv2.COLOR_RGB2GRAY), None)
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m for m, n in knn if m.distance < ratio * n.distance]
    p1 = np.array([k1[m.queryIdx].pt for m in good], np.float64)
    p2 = np.array([k2[m.trainIdx].pt for m in good], np.float64)
    return p1, p2


def rotation_residuals(pair, p1, p2, dist1=None, dist2=None):
    """Distance (px) between ``K2 R K1^-1`` applied to undistorted ``p1`` and undistorted ``p2``."""
    dist1 = pair.dist1 if dist1 is None else dist1
    dist2 = pair.dist2 if dist2 is None else dist2
    x1 = cv2.undistortPoints(p1.reshape(-1, 1, 2), pair.K1, dist1).reshape(-1, 2)
    x2 = cv2.undistortPoints(p2.reshape(-1, 1, 2), pair.K2, dist2).reshape(-1, 2)
    mapped = project_points(np.column_stack([x1, np.ones(len(x1))]), pair.K2, pair.R)
    return np.linalg.norm(mapped - (x2 * np.diag(pair.K2)[:2] + pair.K2[:2, 2]), axis=1)


@pytest.fixture(scope="module")
def panorama():
    return make_pair("panorama", seed=3, index=1, size=SIZE, imperfections=REAL_PHOTO)


def test_imperfections_are_drawn_within_their_ranges():
    for index in range(6):
        pair = make_pair("pure-rotation", seed=2, index=index, size=(48, 36), supersample=1,
                         imperfections=REAL_PHOTO)  # fmt: skip
        params = pair.params
        assert 0.02 <= abs(params["k1"]) <= 0.1 and params["k2"] == 0.0
        np.testing.assert_array_equal(pair.dist1, [params["k1"], 0, 0, 0, 0])
        np.testing.assert_array_equal(pair.dist2, pair.dist1)
        factor = params["focal_factor"]
        assert 0.97 <= factor <= 1.03 and factor != 1.0
        np.testing.assert_allclose(pair.K1_given[:2, :2], pair.K1[:2, :2] * factor, rtol=1e-15)
        np.testing.assert_array_equal(pair.K1_given[:, 2], pair.K1[:, 2])
        np.testing.assert_array_equal(pair.K2_given, pair.K1_given)
        assert 25.0 <= params["hfov_deg"] <= 35.0
        focal = 48 / (2 * np.tan(np.radians(params["hfov_deg"]) / 2))
        assert pair.K1[0, 0] == pytest.approx(focal, rel=1e-12)
        assert 70 <= params["jpeg_quality"] <= 95 and isinstance(params["jpeg_quality"], int)
        assert params["noise_std"] == 1.0 and params["blur_sigma"] == 0.5
    drawn = [REAL_PHOTO.draw(np.random.default_rng(i)).k1 for i in range(12)]
    assert set(np.sign(drawn)) == {-1.0, 1.0}


def test_without_imperfections_the_given_intrinsics_are_the_true_ones():
    pair = make_pair("general", seed=1, size=(48, 36), supersample=1)
    np.testing.assert_array_equal(pair.K1_given, pair.K1)
    np.testing.assert_array_equal(pair.K2_given, pair.K2)
    assert "k1" not in pair.params and pair.dist1.size == 0
    assert 55.0 <= pair.params["hfov1_deg"] <= 70.0


def test_the_unmodelled_distortion_is_in_the_images():
    """Matches obey the true camera model with the drawn distortion, not the pinhole one."""
    strong = Imperfections(k1_range=(0.1, 0.1), hfov_range=None, jpeg_quality=None,
                           noise_std=0.0, blur_sigma=0.0)  # fmt: skip
    pair = make_pair("general", seed=4, size=SIZE, imperfections=strong)
    assert abs(pair.params["k1"]) == 0.1
    p1, p2 = sift_matches(pair.image1, pair.image2)
    assert len(p1) > 150
    u, v = np.rint(p1).astype(int).T
    depth = pair.depth1[v, u].astype(np.float64)

    def transfer(dist):
        x1 = cv2.undistortPoints(p1.reshape(-1, 1, 2), pair.K1, dist).reshape(-1, 2)
        X = np.column_stack([x1, np.ones(len(x1))]) * depth[:, None]
        return np.linalg.norm(project_points(X, pair.K2, pair.R, pair.t, dist) - p2, axis=1)

    with_distortion, pinhole = np.median(transfer(pair.dist1)), np.median(transfer(None))
    assert with_distortion < 0.3
    assert pinhole > 5 * with_distortion and pinhole > 0.5


def test_jpeg_noise_and_blur_are_applied_on_the_same_geometry():
    exact = make_pair("pure-rotation", seed=6, size=(96, 72), imperfections=EXACT)
    real = make_pair("pure-rotation", seed=6, size=(96, 72), imperfections=REAL_PHOTO)
    np.testing.assert_array_equal(exact.R, real.R)
    np.testing.assert_array_equal(exact.K1, real.K1)
    assert exact.params["k1"] == real.params["k1"]
    difference = np.abs(exact.image1.astype(float) - real.image1)
    assert 0.5 < difference.mean() < 10.0
    quality = real.params["jpeg_quality"]
    encoded = cv2.imencode(".jpg", cv2.cvtColor(real.image1, cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_JPEG_QUALITY, quality])[1]  # fmt: skip
    again = cv2.cvtColor(cv2.imdecode(encoded, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    # a JPEG-decoded image re-encoded at its quality barely changes; a raw render does not
    raw = cv2.cvtColor(cv2.imdecode(cv2.imencode(".jpg", cv2.cvtColor(
        exact.image1, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality])[1],
        cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)  # fmt: skip
    assert np.abs(again.astype(float) - real.image1).mean() < np.abs(
        raw.astype(float) - exact.image1).mean()  # fmt: skip


def test_panorama_is_a_pure_rotation_mapped_by_the_infinite_homography(panorama):
    pair = panorama
    assert np.all(pair.t == 0.0)
    params = pair.params
    assert 0.35 <= abs(params["yaw_deg"]) / params["hfov1_deg"] <= 0.7
    assert abs(params["pitch_deg"]) < 6 and abs(params["roll_deg"]) < 6
    assert params["scene"] == "room" and np.isfinite(pair.depth1).all()
    p1, p2 = sift_matches(pair.image1, pair.image2)
    assert len(p1) > 100
    residual = rotation_residuals(pair, p1, p2)
    assert np.median(residual) < 1.0 and np.mean(residual < 1.0) > 0.6
    wrong = dataclasses.replace(pair, R=cv2.Rodrigues(np.radians([0.0, 0.5, 0.0]))[0] @ pair.R)
    assert np.median(rotation_residuals(wrong, p1, p2)) > 3.0


def test_panorama_views_are_filled_with_texture(panorama):
    for image in (panorama.image1, panorama.image2):
        gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
        local = cv2.blur(np.abs(cv2.Laplacian(gray, cv2.CV_32F)), (32, 32))
        assert np.percentile(local, 5) > 1.0


def test_tiny_baseline_records_the_ratio_to_the_median_depth_seen():
    for index in range(3):
        pair = make_pair("tiny-baseline", seed=7, index=index, size=(64, 48), supersample=1)
        params = pair.params
        assert 1e-3 <= params["baseline_ratio"] <= 0.05
        seen = np.median(pair.depth1[np.isfinite(pair.depth1)])
        assert params["median_depth"] == pytest.approx(seen, rel=1e-6)
        centre = -pair.R.T @ pair.t
        np.testing.assert_allclose(centre, params["centre"], atol=1e-12)
        assert np.linalg.norm(centre) / seen == pytest.approx(params["baseline_ratio"], rel=1e-6)
    fixed = make_pair("tiny-baseline", seed=7, size=(64, 48), supersample=3, baseline_ratio=0.02,
                      imperfections=REAL_PHOTO)  # fmt: skip
    seen = np.median(fixed.depth1[np.isfinite(fixed.depth1)])
    assert fixed.params["baseline_ratio"] == 0.02
    assert np.linalg.norm(fixed.t) / seen == pytest.approx(0.02, rel=1e-5)
    zero = make_pair("tiny-baseline", seed=7, size=(64, 48), supersample=1, baseline_ratio=0.0,
                     imperfections=REAL_PHOTO)  # fmt: skip
    rotation = make_pair("pure-rotation", seed=7, size=(64, 48), supersample=1,
                         imperfections=REAL_PHOTO)  # fmt: skip
    assert np.all(zero.t == 0.0)
    np.testing.assert_array_equal(zero.R, rotation.R)
    np.testing.assert_array_equal(zero.image2, rotation.image2)


def test_panorama_turns_about_a_pivot_behind_the_camera():
    scene = make_scene("room", 0)
    still = sample_motion("panorama", scene, np.random.default_rng(4))
    moved = sample_motion("panorama", scene, np.random.default_rng(4), pivot_offset=0.1)
    np.testing.assert_array_equal(still.R, moved.R)
    pivot = np.array([0.0, 0.0, -0.1])
    np.testing.assert_allclose(moved.R @ pivot + moved.t, pivot, atol=1e-15)  # the pivot stays
    angle = np.radians(rotation_error_deg(moved.R, np.eye(3)))
    assert np.linalg.norm(moved.t) == pytest.approx(2 * 0.1 * np.sin(angle / 2), rel=0.01)
    assert moved.params["pivot_offset"] == 0.1 and "pivot_offset" not in still.params
    assert np.all(still.t == 0)
    pair = make_pair("panorama", seed=2, size=(64, 48), supersample=1, pivot_offset=0.1)
    np.testing.assert_allclose(pair.R @ pivot + pair.t, pivot, atol=1e-15)
    with pytest.raises(ValueError, match="panorama only"):
        make_pair("pure-rotation", size=(32, 24), pivot_offset=0.05)
    for bad in (-0.01, 1.5, float("nan")):
        with pytest.raises(ValueError, match="pivot_offset"):
            make_pair("panorama", size=(32, 24), pivot_offset=bad)
    with pytest.raises(TypeError, match="pivot_offset"):
        make_pair("panorama", size=(32, 24), pivot_offset="8 cm")


def test_same_seed_same_bytes_and_other_seeds_differ():
    def digest(seed):
        pair = make_pair("tiny-baseline", seed=seed, size=(64, 48), supersample=1,
                         imperfections=REAL_PHOTO)  # fmt: skip
        return pair.image1.tobytes() + pair.image2.tobytes(), pair.params

    assert digest(5) == digest(5)
    assert digest(5)[0] != digest(6)[0]


def test_sample_motion_new_presets_without_rendering():
    scene = make_scene("room", 0)
    rng = np.random.default_rng(0)
    motion = sample_motion("panorama", scene, rng, hfov_range=(30.0, 30.0))
    assert motion.params["hfov1_deg"] == 30.0 and np.all(motion.t == 0)
    yaw = np.degrees(np.arctan2(motion.R[0, 2], motion.R[2, 2]))
    assert yaw == pytest.approx(motion.params["yaw_deg"], abs=0.2)
    with pytest.raises(ValueError, match="baseline_ratio"):
        sample_motion("tiny-baseline", scene, rng, baseline_ratio=0.7)
    sky = make_scene("backdrop", 0)
    sky = dataclasses.replace(sky, quads=tuple(q for q in sky.quads if q.at_infinity))
    with pytest.raises(ValueError, match="finite distance"):
        sample_motion("tiny-baseline", sky, rng, size=(32, 24))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"k1_range": (0.2, 0.1)}, "k1_range"),
        ({"k1_range": (-0.1, 0.1)}, "k1_range"),
        ({"k1_range": 0.1}, "k1_range"),
        ({"focal_error": 0.6}, "focal_error"),
        ({"focal_error": float("nan")}, "focal_error"),
        ({"hfov_range": (0.5, 30.0)}, "hfov_range"),
        ({"hfov_range": (30.0, 179.0)}, "hfov_range"),
        ({"jpeg_quality": (0, 50)}, "jpeg_quality"),
        ({"jpeg_quality": (50.5, 60)}, "jpeg_quality"),
        ({"noise_std": -1.0}, "noise_std"),
        ({"blur_sigma": 60.0}, "blur_sigma"),
        ({"k2_fraction": "big"}, "k2_fraction"),
        ({"view_focal_error": -0.01}, "view_focal_error"),
        ({"view_focal_error": True}, "view_focal_error"),
        ({"exposure_ev": 3.5}, "exposure_ev"),
        ({"exposure_ev": -0.5}, "exposure_ev"),
        ({"vignetting": 1.0}, "vignetting"),
        ({"vignetting": "strong"}, "vignetting"),
    ],
)
def test_bad_imperfections_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Imperfections(**kwargs)


def test_focal_lengths_given_per_photo_tell_the_same_pair_differently():
    one = make_pair("tiny-baseline", seed=0, index=3, size=SIZE, baseline_ratio=0.02,
                    imperfections=EXACT)  # fmt: skip
    told = dataclasses.replace(EXACT, view_focal_error=0.01)
    per_photo = make_pair("tiny-baseline", seed=0, index=3, size=SIZE, baseline_ratio=0.02,
                          imperfections=told)  # fmt: skip
    assert np.array_equal(one.image1, per_photo.image1)
    assert np.array_equal(one.image2, per_photo.image2)
    assert np.array_equal(one.K1, per_photo.K1) and np.array_equal(one.R, per_photo.R)
    factors = per_photo.params["view_factors"]
    assert all(0.99 <= f <= 1.01 for f in factors) and factors[0] != factors[1]
    for given, base, factor in ((per_photo.K1_given, one.K1_given, factors[0]),
                                (per_photo.K2_given, one.K2_given, factors[1])):  # fmt: skip
        assert np.allclose(given[:2, :2], base[:2, :2] * factor)
        assert np.array_equal(given[:2, 2], base[:2, 2])
    assert one.params["view_factors"] == [1.0, 1.0]


def test_exposure_and_vignetting_act_in_linear_light_on_the_same_pair():
    plain = make_pair("panorama", seed=1, index=2, size=SIZE, imperfections=EXACT)
    lit = dataclasses.replace(EXACT, exposure_ev=1.0, vignetting=0.4)
    pair = make_pair("panorama", seed=1, index=2, size=SIZE, imperfections=lit)
    ev = pair.params["exposure_ev"]
    assert 0.0 < abs(ev) <= 1.0 and pair.params["vignetting"] == 0.4
    assert np.array_equal(pair.K1_given, plain.K1_given) and np.array_equal(pair.R, plain.R)
    h, w = SIZE[1], SIZE[0]
    centre = (slice(h // 2 - 8, h // 2 + 8), slice(w // 2 - 8, w // 2 + 8))
    corner = (slice(0, 16), slice(0, 16))

    def linear(image, where):
        return np.mean((image[where].astype(float) / 255.0) ** 2.2)

    for view, sign in ((0, -1), (1, 1)):
        before, after = (p.image1 if view == 0 else p.image2 for p in (plain, pair))
        gain = 2.0 ** (sign * ev / 2)
        # the centre keeps the gain (little clips there), the corner loses the vignetting too
        assert linear(after, centre) / linear(before, centre) == pytest.approx(gain, rel=0.05)
        corner_ratio = linear(after, corner) / linear(before, corner)
        assert corner_ratio == pytest.approx(gain * (1 - 0.4 * 0.9), rel=0.1)
    redrawn = make_pair("panorama", seed=1, index=2, size=SIZE, imperfections=lit)
    assert np.array_equal(redrawn.image2, pair.image2)


def test_expose_clips_at_white_and_keeps_the_image_without_change():
    from ppo_cv.data_gen import expose

    image = np.full((4, 6, 3), 200, np.uint8)
    assert expose(image) is image
    assert np.all(expose(image, gain=4.0) == 255)
    darker = expose(image, gain=0.5)
    assert np.all(np.abs(darker.astype(float) - 255 * (200 / 255) * 0.5 ** (1 / 2.2)) <= 0.5)
    grey = expose(image[..., 0], vignetting=0.5)
    assert grey.shape == (4, 6) and grey[0, 0] < grey[1, 2] <= 200
    for kwargs, message in (({"gain": 0.0}, "gain"), ({"gain": float("nan")}, "gain"),
                            ({"vignetting": 0.95}, "vignetting")):  # fmt: skip
        with pytest.raises(ValueError, match=message):
            expose(image, **kwargs)
    with pytest.raises(ValueError, match="uint8"):
        expose(image.astype(np.float32))


def test_bad_make_pair_arguments_are_rejected():
    with pytest.raises(ValueError, match="through imperfections"):
        make_pair("general", size=(32, 24), noise_std=1.0, imperfections=REAL_PHOTO)
    with pytest.raises(TypeError, match="imperfections"):
        make_pair("general", size=(32, 24), imperfections={"k1": 0.1})
    with pytest.raises(ValueError, match="tiny-baseline and tripod only"):
        make_pair("general", size=(32, 24), baseline_ratio=0.01)
    with pytest.raises(ValueError, match="baseline_ratio"):
        make_pair("tiny-baseline", size=(32, 24), baseline_ratio=-0.01)
    with pytest.raises(dataclasses.FrozenInstanceError):
        REAL_PHOTO.focal_error = 0.0
    assert REAL_PHOTO == Imperfections() and REAL_PHOTO.hfov_range == (25.0, 35.0)
