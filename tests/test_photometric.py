"""Intensity-aligned tracks of a pure rotation (ppo_cv.photometric) against ground truth."""

from __future__ import annotations

import json
from importlib import resources

import cv2
import numpy as np
import pytest
from imperfect import imperfect_render, warped_rotation_pair

from ppo_cv import PairOptions, estimate_pair, photometric
from ppo_cv.export import result_to_dict
from ppo_cv.metrics import rotation_error_deg
from ppo_cv.photometric import MIN_NCC, align_windows, refine_rotation_photometric
from ppo_cv.rotation import fit_rotation_lens

K_DEMO = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


def _demo_photo() -> np.ndarray:
    data = resources.files("ppo_cv.data").joinpath("demo1.png").read_bytes()
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)


def _vignetted(image: np.ndarray, gain: float, strength: float) -> np.ndarray:
    """Exposure ``gain`` and a radial fall-off to ``1 - strength`` in the corners."""
    h, w = image.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    shade = gain * (1.0 - strength * r2)
    return np.clip(image * shade[..., None], 0, 255).astype(np.uint8)


def _matches_fit(pair, result):
    """The lens rotation of the feature matches of a pipeline result, as the pipeline fits it."""
    K_inv = np.linalg.inv(pair.K_given)
    m = result.matches
    x1 = np.column_stack([result.keypoints1[m[:, 0]], np.ones(len(m))]) @ K_inv.T
    x2 = np.column_stack([result.keypoints2[m[:, 1]], np.ones(len(m))]) @ K_inv.T
    noise = 0.5 / pair.K_given[0, 0]
    return fit_rotation_lens(x1, x2, result.inliers, result.R, noise=noise)


H_DEMO = np.array([[1.02, 0.01, 6.0], [-0.01, 0.99, -4.0], [2e-5, 1e-5, 1.0]])
"""A homography between the demo frame and its warped copy in the window tests."""


def _through_demo_homography(points: np.ndarray) -> np.ndarray:
    p = np.column_stack([points, np.ones(len(points))]) @ H_DEMO.T
    return p[:, :2] / p[:, 2:]


def test_windows_find_a_homography_the_transfer_misses_by_pixels():
    photo = cv2.cvtColor(_demo_photo(), cv2.COLOR_BGR2GRAY)
    H, truth_of = H_DEMO, _through_demo_homography

    def transfer(points):
        return truth_of(points) + np.array([2.3, -1.7])

    found = cv2.goodFeaturesToTrack(photo, 400, 0.01, 8).reshape(-1, 2)
    points = np.round(found[(found[:, 0] > 40) & (found[:, 0] < 600)]).astype(np.float64)
    points = points[(points[:, 1] > 40) & (points[:, 1] < 440)]
    truth = truth_of(points)
    image2 = cv2.warpPerspective(photo, H, photo.shape[::-1], flags=cv2.INTER_CUBIC)
    image2 = np.clip(image2 * 0.7 + 20, 0, 255).astype(np.uint8)  # exposure and black level
    u, v = np.round(truth[0]).astype(int)
    image2[v - 30 : v + 30, u - 30 : u + 30] = 128  # an occluder over the strongest corner
    occluded = np.all(np.abs(truth - truth[0]) < 20, axis=1)

    tracks = align_windows(photo, image2, points, transfer, levels=1)
    error = np.linalg.norm(tracks.points2 - truth, axis=1)
    assert np.count_nonzero(tracks.valid) > 0.8 * len(points)
    assert np.median(error[tracks.valid]) < 0.05
    assert np.percentile(error[tracks.valid], 90) < 0.1
    assert not np.any(tracks.valid & occluded)
    assert np.all(tracks.ncc[tracks.valid] >= MIN_NCC)


def test_windows_next_to_highlights_clipped_in_one_shot_keep_their_accuracy():
    from ppo_cv.data_gen import expose

    photo = cv2.cvtColor(_demo_photo(), cv2.COLOR_BGR2GRAY)
    truth_of = _through_demo_homography
    image2 = cv2.warpPerspective(photo, H_DEMO, photo.shape[::-1], flags=cv2.INTER_CUBIC)
    image2 = expose(image2, gain=2.0)  # one stop brighter: 5 % of the pixels clip at white
    found = cv2.goodFeaturesToTrack(photo, 600, 0.01, 8).reshape(-1, 2).astype(np.float64)
    points = found[np.all((found > 40) & (found < (600, 440)), axis=1)]
    truth = truth_of(points)
    tracks = align_windows(
        photo, image2, points, lambda p: truth_of(p) + np.array([0.8, -0.6]), levels=1
    )
    near = cv2.dilate((image2 >= 250).astype(np.uint8), np.ones((21, 21), np.uint8))
    u, v = np.round(truth).astype(int).T
    clipped = tracks.valid & (near[v.clip(0, 479), u.clip(0, 639)] > 0)
    error = np.linalg.norm(tracks.points2 - truth, axis=1)
    # with the clipped pixels in the fit, a tenth of these windows were off by over 0.4 px
    assert np.count_nonzero(clipped) >= 50
    assert np.percentile(error[clipped], 90) < 0.2
    assert np.percentile(error[tracks.valid], 90) < 0.08


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_refit_on_windows_recovers_rotation_and_focal_of_a_warped_photo(seed):
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, seed, angle_range=(10.0, 15.0))
    result = estimate_pair(
        pair.image1, pair.image2, pair.K_given, options=PairOptions(photometric=False)
    )
    start = _matches_fit(pair, result)
    refined = refine_rotation_photometric(
        pair.image1, pair.image2, pair.K_given, pair.K_given, start.R,
        focal_scale=start.focal_scale, k1=start.k1, rotation_sigma_deg=start.rotation_sigma_deg,
    )  # fmt: skip
    assert refined is not None and refined.num_tracks > 100
    assert rotation_error_deg(refined.fit.R, pair.R) < 0.05
    assert abs(refined.fit.focal_scale - (1.0 + pair.focal_error)) < 0.004
    assert abs(refined.fit.k1 - pair.k1) < 0.01
    assert refined.noise_px < 0.15


def test_refit_survives_exposure_and_vignetting():
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, 4, angle_range=(10.0, 15.0))
    image1 = _vignetted(pair.image1, 1.0, 0.3)
    image2 = _vignetted(pair.image2, 0.75, 0.3)
    result = estimate_pair(image1, image2, pair.K_given)
    assert result.pure_rotation and result.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(result.R, pair.R) < 0.06


def test_refit_with_the_distortion_given_leaves_no_radial_term():
    """The pipeline's ``dist`` reaches the windows: told the lens, the fit finds k1 = 0."""
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, 1, angle_range=(10.0, 15.0))
    dist = np.array([pair.k1, 0.0, 0.0, 0.0, 0.0])
    K_true = pair.K_given.copy()
    K_true[:2, :2] /= 1.0 + pair.focal_error
    result = estimate_pair(pair.image1, pair.image2, K_true, dist1=dist)
    assert result.pure_rotation and result.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(result.R, pair.R) < 0.03
    assert abs(result.lens.focal_scale - 1.0) < 0.003


def test_refit_is_refused_on_unrelated_images_and_on_a_rotation_far_from_its_bound():
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, 0, angle_range=(10.0, 15.0))
    noise = np.random.default_rng(0).integers(0, 255, pair.image2.shape, dtype=np.uint8)
    unrelated = cv2.GaussianBlur(noise, (0, 0), 1.5)
    assert (
        refine_rotation_photometric(pair.image1, unrelated, pair.K_given, pair.K_given, pair.R)
        is None
    )
    c, s = np.cos(np.radians(1.5)), np.sin(np.radians(1.5))
    off = np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]]) @ pair.R
    refined = refine_rotation_photometric(
        pair.image1, pair.image2, pair.K_given, pair.K_given, off, rotation_sigma_deg=0.05
    )
    assert refined is None


@pytest.mark.slow
def test_pipeline_rotation_of_imperfect_renders_beats_the_feature_matches():
    errors, matches_errors = [], []
    for seed in range(4):
        pair = imperfect_render(seed)
        # the render's principal point is exactly the centre it is given: keep it
        given = PairOptions(principal_point="given")
        result = estimate_pair(pair.image1, pair.image2, pair.K_given, options=given)
        matches = estimate_pair(
            pair.image1, pair.image2, pair.K_given,
            options=PairOptions(photometric=False, principal_point="given"),
        )  # fmt: skip
        assert result.pure_rotation and result.uncertainty.rotation_tracks > 100
        assert matches.uncertainty.rotation_tracks == 0
        errors.append(rotation_error_deg(result.R, pair.R))
        matches_errors.append(rotation_error_deg(matches.R, pair.R))
        # each sigma also counts the rotation a focal length given 2-3 % off may hide
        # (rotation_choice.focal_trade_deg), which tracks do not resolve: compare the errors
        assert errors[-1] < matches_errors[-1]
        assert errors[-1] < 5.0 * result.uncertainty.rotation_sigma_deg
        assert result.uncertainty.t_sigma_deg > 30.0 and result.num_points == 0
    assert max(errors) < 0.04
    assert np.mean(errors) < 0.5 * np.mean(matches_errors)


def test_json_and_summary_name_the_tracks():
    from ppo_cv.cli.pair import _rotation_sigma_lines

    pair = imperfect_render(0)
    result = estimate_pair(pair.image1, pair.image2, pair.K_given)
    record = json.loads(json.dumps(result_to_dict(result)))
    assert record["uncertainty"]["rotation_tracks"] == result.uncertainty.rotation_tracks > 100
    assert (
        f"{result.uncertainty.rotation_tracks} intensity-aligned windows"
        in _rotation_sigma_lines(result)[0]
    )
    moving = imperfect_render(1, 0.15)
    general = estimate_pair(moving.image1, moving.image2, moving.K_given)
    assert result_to_dict(general)["uncertainty"]["rotation_tracks"] == 0


@pytest.mark.slow
def test_rotation_sigma_of_the_tracks_covers_the_actual_errors():
    """Overlapping windows share pixels: the bound is inflated by their overlap, not below it."""
    ratios = []
    for seed in range(4):
        for pair in (
            imperfect_render(seed),
            warped_rotation_pair(_demo_photo(), K_DEMO, seed, angle_range=(10.0, 15.0)),
        ):
            result = estimate_pair(pair.image1, pair.image2, pair.K_given)
            if result.uncertainty.rotation_tracks:
                ratios.append(
                    rotation_error_deg(result.R, pair.R) / result.uncertainty.rotation_sigma_deg
                )
    assert len(ratios) >= 6
    rms = float(np.sqrt(np.mean(np.square(ratios))))
    assert 0.3 < rms < 1.5


def test_command_line_switches_the_refit(tmp_path):
    from typer.testing import CliRunner

    from ppo_cv.cli.main import app

    pair = imperfect_render(0)
    paths = [str(tmp_path / "a.png"), str(tmp_path / "b.png")]
    for path, image in zip(paths, (pair.image1, pair.image2), strict=True):
        cv2.imwrite(path, image)
    K = pair.K_given
    k_text = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    records = {}
    for flag in ("--photometric", "--no-photometric"):
        exact = ["--principal-point", "given"]  # the render's centre is its principal point
        run = CliRunner().invoke(app, ["pair", *paths, "--K", k_text, "--json", flag, *exact])
        assert run.exit_code == 0, run.output
        records[flag] = json.loads(run.stdout)
    assert records["--photometric"]["uncertainty"]["rotation_tracks"] > 100
    assert records["--no-photometric"]["uncertainty"]["rotation_tracks"] == 0
    errors = {flag: rotation_error_deg(np.array(r["R"]), pair.R) for flag, r in records.items()}
    assert errors["--photometric"] < errors["--no-photometric"]


def test_windows_on_an_object_that_moved_are_dropped():
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, 2, angle_range=(10.0, 15.0))
    image2 = pair.image2.copy()
    h, w = image2.shape[:2]
    top, left = h // 3, w // 3
    block = (slice(top, top + h // 3), slice(left, left + w // 4))
    image2[block] = np.roll(pair.image2, (0, 7), axis=(0, 1))[block]  # moved 7 px sideways
    result = estimate_pair(
        pair.image1, image2, pair.K_given, options=PairOptions(photometric=False)
    )
    start = _matches_fit(pair, result)
    refined = refine_rotation_photometric(
        pair.image1, image2, pair.K_given, pair.K_given, start.R,
        focal_scale=start.focal_scale, k1=start.k1, rotation_sigma_deg=start.rotation_sigma_deg,
    )  # fmt: skip
    assert refined is not None
    p2 = refined.tracks.points2
    inside = (p2[:, 1] > top + 12) & (p2[:, 1] < top + h // 3 - 12)
    inside &= (p2[:, 0] > left + 12) & (p2[:, 0] < left + w // 4 - 12)
    assert np.count_nonzero(inside) >= 10
    assert not np.any(refined.inliers & inside)
    error = rotation_error_deg(refined.fit.R, pair.R)
    assert error < 0.1 and error < 3.0 * refined.fit.rotation_sigma_deg


def test_bad_arguments_are_named():
    image = _demo_photo()
    K = K_DEMO
    with pytest.raises(ValueError, match="window"):
        align_windows(image, image, np.zeros((3, 2)), lambda p: p, window=20)
    with pytest.raises(ValueError, match="levels"):
        align_windows(image, image, np.zeros((3, 2)), lambda p: p, levels=-1)
    with pytest.raises(TypeError, match="transfer"):
        align_windows(image, image, np.zeros((3, 2)), None)
    with pytest.raises(ValueError, match="points1"):
        align_windows(image, image, np.full((3, 2), np.nan), lambda p: p)
    assert len(align_windows(image, image, np.zeros((0, 2)), lambda p: p).valid) == 0
    with pytest.raises(ValueError, match="rotation"):
        refine_rotation_photometric(image, image, K, K, np.ones((3, 3)))
    with pytest.raises(ValueError, match="not a rotation"):
        refine_rotation_photometric(image, image, K, K, np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="rotation_sigma_deg"):
        refine_rotation_photometric(image, image, K, K, np.eye(3), rotation_sigma_deg=0.0)
    with pytest.raises(ValueError, match="K2"):
        refine_rotation_photometric(image, image, K, np.eye(2), np.eye(3))
    for count in (0, -1, 2.5, 2**40):  # 0 and 2.5 gave None, -1 and 2**40 an OpenCV error
        with pytest.raises(ValueError, match="max_corners"):
            refine_rotation_photometric(image, image, K, K, np.eye(3), max_corners=count)
    for count in ("600", True):
        with pytest.raises(TypeError, match="max_corners"):
            refine_rotation_photometric(image, image, K, K, np.eye(3), max_corners=count)
    for name, value, error in [("focal_scale", "1.0", TypeError), ("focal_scale", 0.0, ValueError),
                               ("k1", "0", TypeError), ("k1", np.nan, ValueError)]:  # fmt: skip
        # a text failed in Python's float() with a message naming neither
        with pytest.raises(error, match=name):
            refine_rotation_photometric(image, image, K, K, np.eye(3), **{name: value})


def test_a_settled_search_is_returned_without_its_polish(monkeypatch):
    """``settled`` sees each window side's searched refit with its parallax; where it holds for
    every side, the refit of least deviation is returned as searched, no window polished;
    where it does not, the refit is the one without ``settled``."""
    pair = warped_rotation_pair(_demo_photo(), K_DEMO, 0, angle_range=(10.0, 15.0))
    args = (pair.image1, pair.image2, pair.K_given, pair.K_given, pair.R)
    polished, seen = [], []
    polish = photometric._polish
    monkeypatch.setattr(photometric, "_polish", lambda *a: polished.append(1) or polish(*a))
    full = refine_rotation_photometric(*args, rotation_sigma_deg=0.2)
    assert full is not None and polished
    polished.clear()
    unsettled = refine_rotation_photometric(
        *args, rotation_sigma_deg=0.2, settled=lambda refined: seen.append(refined) or False
    )
    assert polished and len(seen) == 1 and seen[0].parallax is not None
    assert np.array_equal(unsettled.fit.R, full.fit.R)
    assert np.array_equal(unsettled.parallax.H, full.parallax.H)
    polished.clear()
    seen.clear()
    searched = refine_rotation_photometric(
        *args, rotation_sigma_deg=0.2, settled=lambda refined: seen.append(refined) or True
    )
    assert not polished and len(seen) == len(photometric.WINDOWS)
    least = min(seen, key=lambda refined: refined.fit.rotation_sigma_deg)
    assert searched is least and searched.parallax is not None
    assert not np.array_equal(searched.fit.R, full.fit.R)
    assert rotation_error_deg(searched.fit.R, pair.R) < 0.1
    with pytest.raises(TypeError, match="settled must be a callable"):
        refine_rotation_photometric(*args, settled=True)


def _good_features_corners(gray, count, window, transfer):
    """The corners of a window side as ``cv2.goodFeaturesToTrack`` selects them."""
    found = cv2.goodFeaturesToTrack(gray, 4 * count, 0.003, max(window // 4, 3))
    corners = np.zeros((0, 2)) if found is None else found.reshape(-1, 2).astype(np.float64)
    h, w = gray.shape
    half = window // 2
    inside = (corners >= half).all(axis=1) & (corners <= [w - 1 - half, h - 1 - half]).all(axis=1)
    corners = corners[inside]
    moved = transfer(corners)
    inside = (moved >= window).all(axis=1) & (moved <= [w - 1 - window, h - 1 - window]).all(axis=1)
    return corners[inside][:count]


def test_corners_of_every_window_side_are_those_of_good_features_to_track():
    """The window sides share one corner response of image 1 and space its candidates each
    by their own distance: the same corners in the same order as ``cv2.goodFeaturesToTrack``
    (equal responses included: a checkerboard of single pixels is made of ties)."""
    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.uniform(0, 255, (240, 320)), (0, 0), 2).astype(np.uint8)
    pixels = (np.indices((90, 120)).sum(axis=0) % 2 * 255).astype(np.uint8)
    squares = ((np.indices((240, 320)) // 8).sum(axis=0) % 2 * 255).astype(np.uint8)
    flat = np.full((60, 80), 90, np.uint8)
    photo = cv2.cvtColor(_demo_photo(), cv2.COLOR_BGR2GRAY)
    for gray in (photo, texture, pixels, squares, flat):
        candidates = photometric._corner_candidates(gray)
        for shift in ((0.0, 0.0), (0.7 * gray.shape[1], 3.0)):
            transfer = lambda points, shift=shift: points + np.array(shift)  # noqa: E731
            for window, count in ((5, 600), (21, 600), (31, 600), (31, 40), (41, 1)):
                expected = _good_features_corners(gray, count, window, transfer)
                found = photometric._corners(
                    candidates, count, window, transfer, gray.shape, gray.shape
                )
                np.testing.assert_array_equal(found, expected)
    assert len(photometric._corners(photometric._corner_candidates(flat), 9, 21, transfer,
                                    flat.shape, flat.shape)) == 0  # fmt: skip


def test_the_window_sides_share_one_corner_response(monkeypatch):
    calls = {"cornerMinEigenVal": 0, "goodFeaturesToTrack": 0}
    for name in calls:
        function = getattr(cv2, name)

        def counted(*args, name=name, function=function, **kwargs):
            calls[name] += 1
            return function(*args, **kwargs)

        monkeypatch.setattr(cv2, name, counted)
    image1 = cv2.GaussianBlur(
        np.random.default_rng(0).uniform(0, 255, (240, 320)), (0, 0), 2
    ).astype(np.uint8)
    K = np.array([[400.0, 0, 159.5], [0, 400.0, 119.5], [0, 0, 1]])
    c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    image2 = cv2.warpPerspective(image1, K @ R @ np.linalg.inv(K), (320, 240))
    refined = refine_rotation_photometric(image1, image2, K, K, np.eye(3), window=(21, 31))
    assert refined is not None and rotation_error_deg(refined.fit.R, R) < 0.02
    assert calls == {"cornerMinEigenVal": 1, "goodFeaturesToTrack": 0}


@pytest.mark.parametrize("index", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_a_second_radial_term_nobody_models_does_not_break_the_refit(index):
    """Real lenses have k2 too; the lens model has k1 only (k2 = 2 k1 here, |k1| 0.05-0.1)."""
    from ppo_cv import data_gen

    imperfections = data_gen.Imperfections(k1_range=(0.05, 0.1), k2_fraction=2.0)
    pair = data_gen.make_pair("panorama", seed=0, index=index, imperfections=imperfections)
    image1 = np.ascontiguousarray(pair.image1[..., ::-1])
    image2 = np.ascontiguousarray(pair.image2[..., ::-1])
    result = estimate_pair(image1, image2, pair.K1_given, pair.K2_given)
    assert result.pure_rotation and result.uncertainty.rotation_tracks > 100
    assert rotation_error_deg(result.R, pair.R) < 0.06


def test_the_polish_steps_a_chunk_whole_or_only_its_moving_windows_alike(monkeypatch):
    """While most of a chunk's windows still move, the polish steps all of them and keeps the
    steps of the moving ones; the windows that stopped stay where they stopped."""
    photo = cv2.cvtColor(_demo_photo(), cv2.COLOR_BGR2GRAY)
    image2 = cv2.warpPerspective(photo, H_DEMO, photo.shape[::-1], flags=cv2.INTER_CUBIC)
    found = cv2.goodFeaturesToTrack(photo, 300, 0.01, 8).reshape(-1, 2)
    points = np.round(found[np.all((found > 40) & (found < (600, 440)), axis=1)])
    tracks = []
    for share in (0.0, 2.0):  # every step over the whole chunk, or over the moving windows
        monkeypatch.setattr(photometric, "_DENSE_STEPS", share)
        transfer = lambda p: _through_demo_homography(p) + np.array([0.4, -0.3])  # noqa: E731
        tracks.append(align_windows(photo, image2, points, transfer, window=31, levels=1))
    assert np.count_nonzero(tracks[0].valid) > 100
    for name in ("points2", "valid", "ncc"):
        np.testing.assert_array_equal(getattr(tracks[0], name), getattr(tracks[1], name))
