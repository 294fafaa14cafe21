"""Exports that open cleanly and mean what they say: one match per pixel pair, real COLMAP
reprojection errors, a readable ``matches.png`` and one row convention for ``points3d``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from importlib import resources

import numpy as np
import pycolmap
import pytest
from twoview import make_scene, random_rotation, skew

import ppo_cv
from ppo_cv import colmap
from ppo_cv.calib import COLMAP_PIXEL_OFFSET
from ppo_cv.export import (
    MAX_DRAWN_MATCHES,
    check_colmap_camera,
    draw_matches,
    matches_to_draw,
    write_colmap_model,
    write_outputs,
    write_ply,
)
from ppo_cv.features import Features, detect_features, match_features, unique_pixel_pairs
from ppo_cv.pipeline import estimate_pair, load_image

K = np.array([[700.0, 0.0, 320.0], [0.0, 700.0, 240.0], [0.0, 0.0, 1.0]])
CENTRE_SHIFT = np.array([[0, 0, COLMAP_PIXEL_OFFSET], [0, 0, COLMAP_PIXEL_OFFSET], [0, 0, 0]])


@pytest.fixture(scope="module")
def demo():
    """(image1, image2, K) of the built-in demo pair."""
    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    fx, fy, cx, cy = info["intrinsics"]
    K_demo = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return load_image(str(data / info["image1"])), load_image(str(data / info["image2"])), K_demo


@pytest.fixture(scope="module")
def demo_result(demo):
    return estimate_pair(*demo)


def pixel_pairs(matches, keypoints1, keypoints2):
    return np.round(np.hstack([keypoints1[matches[:, 0]], keypoints2[matches[:, 1]]]), 2)


def test_sift_repeats_locations_and_matches_keep_each_pixel_pair_once(demo):
    f1, f2 = detect_features(demo[0]), detect_features(demo[1])
    raw = match_features(f1, f2, ratio=0.9, unique=False)
    matches = match_features(f1, f2, ratio=0.9)
    raw_pairs = pixel_pairs(raw, f1.keypoints, f2.keypoints)
    pairs = pixel_pairs(matches, f1.keypoints, f2.keypoints)
    assert len(np.unique(raw_pairs, axis=0)) < len(raw)  # the duplicates this removes
    assert len(np.unique(pairs, axis=0)) == len(matches) == len(np.unique(raw_pairs, axis=0))
    assert set(map(tuple, matches.tolist())) <= set(map(tuple, raw.tolist()))


def test_estimate_pair_counts_each_correspondence_once(demo_result):
    result = demo_result
    pairs = pixel_pairs(result.matches, result.keypoints1, result.keypoints2)
    assert len(np.unique(pairs, axis=0)) == result.num_matches
    points = result.points3d[result.point_matches]
    assert result.num_points > 100
    assert len(np.unique(np.round(points, 9), axis=0)) == result.num_points


def test_duplicates_keep_the_smallest_descriptor_distance():
    keypoints1 = np.array([[10.0, 20.0], [10.001, 20.0], [30.0, 40.0]])
    keypoints2 = np.array([[11.0, 21.0], [11.0, 21.002], [31.0, 41.0], [11.0, 21.0]])
    matches = np.array([[0, 0], [1, 1], [2, 2], [0, 3]])
    kept = unique_pixel_pairs(matches, keypoints1, keypoints2, np.array([0.5, 0.2, 0.3, 0.1]))
    np.testing.assert_array_equal(kept, [[2, 2], [0, 3]])
    coarse = unique_pixel_pairs(matches, keypoints1, keypoints2, np.zeros(4), resolution=1e-4)
    np.testing.assert_array_equal(coarse, [[0, 0], [1, 1], [2, 2]])


def test_binary_features_are_deduplicated_too():
    rng = np.random.default_rng(0)
    descriptors = rng.integers(0, 256, (40, 32), dtype=np.uint8)
    keypoints = rng.uniform(0, 100, (40, 2))
    keypoints[20:] = keypoints[:20]  # every location twice, with different descriptors
    f = Features(keypoints, descriptors, "orb")
    assert len(match_features(f, f, ratio=1.0, unique=False)) == 40
    assert len(match_features(f, f, ratio=1.0)) == 20


def reprojection_errors(points, pixels1, pixels2, R, t, K1, K2):
    """Mean pixel reprojection error of each point over the two views, by hand."""

    def project(X, K_):
        x = X @ K_.T
        return x[:, :2] / x[:, 2:]

    e1 = np.linalg.norm(project(points, K1) - pixels1, axis=1)
    e2 = np.linalg.norm(project(points @ R.T + t, K2) - pixels2, axis=1)
    return (e1 + e2) / 2


def test_colmap_model_carries_real_reprojection_errors(demo, demo_result, tmp_path):
    result = demo_result
    write_outputs(tmp_path / "out", result, demo[0], demo[1], ("a.png", "b.png"))
    model = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap"))
    assert model.num_points3D() == result.num_points
    errors = {tuple(np.round(p.xyz, 6)): p.error for p in model.points3D.values()}
    rows = result.point_matches
    m = result.matches[rows]
    expected = reprojection_errors(
        result.points3d[rows],
        result.keypoints1[m[:, 0]],
        result.keypoints2[m[:, 1]],
        result.R,
        result.t,
        result.cameras.K1,
        result.cameras.K2,
    )
    ours = np.array([errors[tuple(np.round(p, 6))] for p in result.points3d[rows]])
    np.testing.assert_allclose(ours, expected, rtol=1e-4, atol=1e-6)
    assert np.all(ours >= 0) and 0.05 < model.compute_mean_reprojection_error() < 1.0
    text = (tmp_path / "out" / "colmap" / "points3D.txt").read_text()
    rows_text = [line.split() for line in text.splitlines() if not line.startswith("#")]
    assert all(float(row[7]) >= 0 for row in rows_text)  # ERROR column, -1 meant unknown


def test_exported_pair_reads_back_with_its_pose_names_and_point_counts(demo, demo_result, tmp_path):
    result = demo_result
    write_outputs(tmp_path / "out", result, demo[0], demo[1], ("a.png", "b.png"))
    model = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap"))
    ids = {image.name: image_id for image_id, image in model.images.items()}
    assert sorted(ids) == ["a.png", "b.png"] and model.num_reg_images() == 2
    R, t = colmap.relative_pose(model, ids["a.png"], ids["b.png"])  # cam2_from_world * inv(cam1)
    np.testing.assert_allclose(R, result.R, atol=1e-12)
    np.testing.assert_allclose(t, result.t, atol=1e-12)
    (camera,) = model.cameras.values()
    assert camera.model_name == "PINHOLE"
    np.testing.assert_allclose(colmap.K_from_camera(camera), result.cameras.K1 + CENTRE_SHIFT)
    data = (tmp_path / "out" / "points.ply").read_bytes()
    header, body = data.split(b"end_header\n", 1)
    (count,) = re.findall(rb"element vertex (\d+)", header)
    assert int(count) == model.num_points3D() == result.num_points > 0
    assert len(body) == int(count) * (3 * 4 + 3)


def test_two_view_reconstruction_carries_real_reprojection_errors():
    rng = np.random.default_rng(3)
    R, t = random_rotation(rng, 10.0), np.array([1.0, 0.2, 0.1]) / np.linalg.norm([1, 0.2, 0.1])
    X, p1, p2 = make_scene(rng, 80, R, t, K, noise_px=0.5)
    pose = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K)
    camera = colmap.camera_from_K(K, 640, 480)
    camera.camera_id = 1
    image1 = pycolmap.Image(name="a.png", camera_id=1, image_id=1)
    image2 = pycolmap.Image(name="b.png", camera_id=1, image_id=2)
    matches = np.stack([np.arange(80), np.arange(80)], axis=1)
    model = colmap.two_view_reconstruction(
        camera, camera, image1, image2, p1, p2, matches, pose, min_tri_angle=0.0
    )
    ids = sorted(model.points3D)
    points = np.array([model.points3D[i].xyz for i in ids])
    index = [model.points3D[i].track.elements[0].point2D_idx for i in ids]
    expected = reprojection_errors(points, p1[index], p2[index], R, t, K, K)
    np.testing.assert_allclose([model.points3D[i].error for i in ids], expected, rtol=1e-6)
    assert 0.1 < model.compute_mean_reprojection_error() < 1.0


def test_matches_to_draw_caps_and_puts_inliers_first():
    inliers = np.zeros(500, dtype=bool)
    inliers[::3] = True  # 167 inliers
    drawn = matches_to_draw(inliers, 150)
    assert len(drawn) == 150 == len(np.unique(drawn)) and inliers[drawn].all()
    few = np.r_[np.ones(100, bool), np.zeros(300, bool)]
    drawn = matches_to_draw(few, 150)
    assert len(drawn) == 150 and np.count_nonzero(few[drawn]) == 100
    np.testing.assert_array_equal(matches_to_draw(few[:120], 150), np.arange(120))
    assert len(matches_to_draw(inliers, None)) == 500
    np.testing.assert_array_equal(drawn, matches_to_draw(few, 150))  # deterministic


def test_matches_png_has_a_legend_and_a_readable_number_of_lines(demo, demo_result):
    image1, image2, _ = demo
    result = demo_result
    assert result.num_matches > MAX_DRAWN_MATCHES  # the cap applies on the demo pair
    canvas = draw_matches(image1, image2, result)
    height, width = image1.shape[:2]
    assert canvas.shape[1] == 2 * width and canvas.shape[0] > height + 60
    legend = canvas[height:]
    background = legend[-1, -1]
    text = np.any(legend != background, axis=2)
    assert text.mean() > 0.01  # written on, not an empty band
    green = np.all(legend == (0, 200, 0), axis=2)
    red = np.all(legend == (0, 0, 255), axis=2)
    assert green.any() and red.any()  # the colour keys of inliers and outliers
    # Lines on the images: far fewer drawn pixels than with every match.
    everything = draw_matches(image1, image2, result, max_lines=None)
    lines_capped = np.count_nonzero(np.any(canvas[:height] != _pair_image(image1, image2), axis=2))
    lines_all = np.count_nonzero(np.any(everything[:height] != _pair_image(image1, image2), axis=2))
    assert 0 < lines_capped < 0.8 * lines_all


def _pair_image(image1, image2):
    return np.hstack([image1, image2])


def test_points3d_rows_are_the_same_rule_in_recover_pose_and_estimate_pair(demo_result):
    rng = np.random.default_rng(5)
    R, t = random_rotation(rng, 10.0), np.array([0.0, 0.2, 1.0]) / np.linalg.norm([0, 0.2, 1])
    X, p1, p2 = make_scene(rng, 60, R, t, K)
    p2[:10] = p2[:10][::-1] + 40.0  # outliers
    mask = np.ones(60, dtype=bool)
    mask[50:] = False  # unused points
    pose = ppo_cv.recover_pose(skew(t) @ R, p1, p2, K, mask=mask)
    assert pose.points3d.shape == (60, 3)
    finite = np.isfinite(pose.points3d).all(axis=1)
    np.testing.assert_array_equal(finite, pose.inliers)
    assert not finite[50:].any() and finite[10:50].all() and not pose.inliers[:10].all()
    np.testing.assert_allclose(pose.points3d[10:50], X[10:50], rtol=1e-7)
    result = demo_result
    assert result.points3d.shape == (result.num_matches, 3)
    finite = np.isfinite(result.points3d).all(axis=1)
    np.testing.assert_array_equal(np.flatnonzero(finite), result.point_matches)
    assert result.inliers[finite].all() and result.num_points == finite.sum()


@pytest.mark.parametrize(
    "names, kind",
    [(("a.png", "b.png"), "txt"), (("frame one.png", "été\t2.png"), "bin")],
)
def test_colmap_model_keeps_image_names_with_spaces(demo, demo_result, tmp_path, names, kind):
    write_outputs(tmp_path / "out", demo_result, demo[0], demo[1], names)
    model = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap"))
    assert sorted(image.name for image in model.images.values()) == sorted(names)
    assert (tmp_path / "out" / "colmap" / f"images.{kind}").is_file()
    assert model.num_points3D() == demo_result.num_points


def _coefficients(count, **entries):
    dist = np.zeros(count)
    for index, value in entries.items():
        dist[int(index[1:])] = value
    return dist


SKEWED = np.array([[700.0, 4.0, 320.0], [0.0, 700.0, 240.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    "K_camera, dist, words",
    [
        (SKEWED, None, r"camera 1 has skew 4\.0"),
        (K, _coefficients(12, i8=0.01), r"thin-prism coefficients s1..s4 \[0\.01, 0\.0, 0"),
        (K, _coefficients(14, i12=0.002), r"tilt coefficients tauX, tauY \[0\.002, 0\.0\]"),
    ],
    ids=["skew", "thin prism", "tilt"],
)
def test_a_camera_colmap_cannot_hold_is_refused_and_nothing_written(
    demo, demo_result, tmp_path, K_camera, dist, words
):
    with pytest.raises(ValueError, match=words):
        check_colmap_camera(K_camera, dist, "camera 1")
    if K_camera is K:
        with pytest.raises(ValueError, match=words):
            write_outputs(tmp_path / "out", demo_result, demo[0], demo[1], dists=(dist, None))
        assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "dist, model, params",
    [
        (None, "PINHOLE", []),
        (_coefficients(5, i0=0.1, i4=0.01), "FULL_OPENCV", [0.1, 0, 0, 0, 0.01, 0, 0, 0]),
        (_coefficients(8, i0=0.1, i7=0.02), "FULL_OPENCV", [0.1, 0, 0, 0, 0, 0, 0, 0.02]),
        (_coefficients(14, i0=0.1, i5=0.03), "FULL_OPENCV", [0.1, 0, 0, 0, 0, 0.03, 0, 0]),
    ],
    ids=["none", "5", "8", "14 with zero thin prism and tilt"],
)
def test_the_colmap_camera_is_the_camera_used(demo, demo_result, tmp_path, dist, model, params):
    write_outputs(tmp_path / "out", demo_result, demo[0], demo[1], dists=(dist, None))
    camera = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap")).cameras[1]
    K1 = demo_result.cameras.K1 + CENTRE_SHIFT
    assert camera.model_name == model
    np.testing.assert_allclose(camera.params, [K1[0, 0], K1[1, 1], K1[0, 2], K1[1, 2], *params])


def test_pycolmap_puts_the_centre_of_the_first_pixel_at_half_a_pixel():
    # the convention COLMAP_PIXEL_OFFSET states: blobs centred on OpenCV pixels (100, 80) and
    # (200, 150) are found by pycolmap's SIFT at (100.5, 80.5) and (200.5, 150.5)
    rows, cols = np.mgrid[0:240, 0:320].astype(np.float64)
    image = np.full((240, 320), 0.1)
    for x, y in [(100.0, 80.0), (200.0, 150.0)]:
        image += 0.8 * np.exp(-((cols - x) ** 2 + (rows - y) ** 2) / 18.0)
    options = pycolmap.FeatureExtractionOptions()
    options.use_gpu, options.num_threads = False, 1
    extractor = pycolmap.FeatureExtractor.create(options, pycolmap.Device.cpu)
    keypoints, _ = extractor.extract_from_float32_array(image.astype(np.float32))
    found = np.unique(np.round([[k.x, k.y] for k in keypoints], 3), axis=0)
    expected = np.array([[100.0, 80.0], [200.0, 150.0]]) + COLMAP_PIXEL_OFFSET
    np.testing.assert_allclose(found, expected, atol=0.01)


def test_the_colmap_model_is_in_colmap_pixel_coordinates(demo_result, tmp_path):
    # its principal point and keypoints were OpenCV's, half a pixel off for COLMAP, whose
    # features of the same images sit 0.5 px further right and down
    result = demo_result
    write_colmap_model(tmp_path, result, ("a.png", "b.png"))
    model = pycolmap.Reconstruction(str(tmp_path))
    (camera,) = model.cameras.values()
    points = result.points3d[result.point_matches]
    ours = points @ result.cameras.K1.T
    ours = ours[:, :2] / ours[:, 2:]
    projected = np.asarray(camera.img_from_cam(points))
    np.testing.assert_allclose(projected, ours + COLMAP_PIXEL_OFFSET, atol=1e-9)
    ids = {image.name: image for image in model.images.values()}
    stored = np.array([point.xy for point in ids["a.png"].points2D])
    np.testing.assert_allclose(stored, result.inlier_points[0] + COLMAP_PIXEL_OFFSET, atol=1e-9)
    (read_back,) = ppo_cv.load_calibration(tmp_path / "cameras.txt")
    np.testing.assert_allclose(read_back.K, result.cameras.K1, atol=1e-12)


WRITE_OUTPUTS_CASES = {
    # a model with two images of one name, or of no name, which COLMAP cannot hold
    "names alike": ({"names": ("a.png", "a.png")}, ValueError, "names must differ"),
    "names empty": ({"names": ("", "b.png")}, TypeError, "names must be two non-empty texts"),
    "three names": ({"names": ("a.png", "b.png", "c.png")}, TypeError,
                    "names must be two image names"),
    # an image of another size: matches.png drawn off the image, the model's size not its own
    "image cut": ({"image1": lambda demo: demo[0][:100]}, ValueError,
                  "image1 is 640x100 pixels, but the result's image 1 is 640x480"),
    "image None": ({"image2": lambda demo: None}, TypeError, "image2 is required"),
    # JSON has no NaN: result.json held the bare word NaN
    "extra NaN": ({"extra": {"note": float("nan")}}, ValueError,
                  "extra cannot be written as JSON: Out of range float values"),
    "extra object": ({"extra": {"note": object()}}, TypeError, "extra cannot be written as JSON"),
    "dists of 3": ({"dists": ([0.1, 0, 0], None)}, ValueError,
                   "dists[0] must be OpenCV distortion coefficients"),
    "result None": ({"result": None}, TypeError, "result must be a PairResult"),
    "directory None": ({"directory": None}, TypeError, "directory must be a path"),
    # Python's "keywords must be strings", naming nothing
    "extra int key": ({"extra": {1: "a"}}, TypeError, "extra's keys must be texts, got int 1"),
    # a NUL in a name with a space (a binary model) ended the name: a model no reader could read
    "name NUL": ({"names": ("a\0 1.png", "a\0 2.png")}, ValueError,
                 "image name 'a\\x00 1.png' holds a NUL character"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(WRITE_OUTPUTS_CASES))
def test_write_outputs_names_a_bad_argument_and_writes_nothing(demo, demo_result, tmp_path, case):
    changes, error, words = WRITE_OUTPUTS_CASES[case]
    arguments = {"directory": tmp_path / "out", "result": demo_result, "image1": demo[0],
                 "image2": demo[1]}  # fmt: skip
    for key, value in changes.items():
        arguments[key] = value(demo) if callable(value) else value
    with pytest.raises(error, match=re.escape(words)):
        write_outputs(**arguments)
    assert list(tmp_path.iterdir()) == []


def test_write_outputs_writes_numpy_numbers_in_extra_as_json_numbers(demo, demo_result, tmp_path):
    # np.int64 and np.float32 were refused as "not JSON serializable"
    extra = {"gain": np.float64(1.5), "count": np.int64(3), "scale": np.float32(0.5),
             "kept": np.bool_(True), "sizes": [np.int32(4), np.uint8(2)],
             "K": np.eye(2)}  # fmt: skip
    write_outputs(tmp_path / "out", demo_result, demo[0], demo[1], extra=extra)
    written = json.loads((tmp_path / "out" / "result.json").read_text(encoding="utf-8"))
    assert {key: written[key] for key in extra} == {
        "gain": 1.5, "count": 3, "scale": 0.5, "kept": True, "sizes": [4, 2],
        "K": [[1.0, 0.0], [0.0, 1.0]],
    }  # fmt: skip
    with pytest.raises(TypeError, match="extra cannot be written as JSON: Object of type"):
        write_outputs(tmp_path / "complex", demo_result, demo[0], demo[1],
                      extra={"z": np.complex128(1j)})  # fmt: skip
    assert not (tmp_path / "complex").exists()


def test_write_outputs_reads_images_given_as_paths(demo_result, tmp_path):
    data = resources.files("ppo_cv.data")
    write_outputs(tmp_path / "out", demo_result, data / "demo1.png", data / "demo2.png")
    drawn = load_image(str(tmp_path / "out" / "matches.png"))
    assert drawn.shape[1] == 2 * 640 and drawn.std() > 10


@pytest.mark.parametrize("directory", ["images", ".", "images/demo1.png"])
def test_write_outputs_never_replaces_the_images_it_was_given_as_paths(
    demo, demo_result, tmp_path, monkeypatch, directory
):
    # with overwrite=True it replaced the folder holding them (the images were deleted)
    import cv2

    monkeypatch.chdir(tmp_path)
    (tmp_path / "images").mkdir()
    paths = [f"images/demo{i}.png" for i in (1, 2)]
    for path, image in zip(paths, demo[:2], strict=True):
        cv2.imwrite(path, image)
    before = {path: (tmp_path / path).read_bytes() for path in paths}
    refused = rf"^the output directory {re.escape(directory)} (is|holds) the input"
    with pytest.raises(ValueError, match=refused):
        ppo_cv.write_outputs(directory, demo_result, *paths, overwrite=True)
    assert sorted(p.name for p in (tmp_path / "images").iterdir()) == ["demo1.png", "demo2.png"]
    assert {path: (tmp_path / path).read_bytes() for path in paths} == before


ROWS = np.zeros((3, 3))
COLOURS = np.zeros((3, 3), np.uint8)


@pytest.mark.parametrize(
    "call, exception, words",
    [(lambda p: write_ply(p, np.full((3, 3), np.nan), COLOURS), ValueError,
      "points has 9 NaN or infinite value(s)"),
     (lambda p: write_ply(p, ROWS, COLOURS[:2]), ValueError,
      "colours must have the shape of points (3, 3), got (2, 3)"),
     (lambda p: write_ply(p, ROWS[:, :2], COLOURS), ValueError,
      "points must have shape (N, 3), got (3, 2)"),
     (lambda p: write_ply(p, ROWS, np.full((3, 3), 300)), ValueError,
      "colours must be 0..255 whole numbers"),
     (lambda p: write_ply(p, ROWS + 1e39, COLOURS), ValueError,
      "points must lie within float32's range"),
     (lambda p: write_ply(p.parent, ROWS, COLOURS), ValueError, "is a folder; give a file name"),
     (lambda p: ppo_cv.export.camera_euler_degrees(np.full((3, 3), np.nan)), ValueError,
      "R has 9 NaN or infinite value(s)"),
     (lambda p: ppo_cv.export.rotation_angle_axis(np.zeros((3, 3))), ValueError,
      "R is not a rotation matrix"),
     (lambda p: ppo_cv.export.euler_zyx_degrees(np.diag([1.0, 1.0, -1.0])), ValueError,
      "R is not a rotation matrix"),
     (lambda p: ppo_cv.export.result_to_dict(None), TypeError,
      "result must be a PairResult (estimate_pair), got NoneType"),
     (lambda p: ppo_cv.export.draw_matches(None, None, {}), TypeError,
      "result must be a PairResult (estimate_pair), got dict"),
     # numpy's "expected a sequence of integers", "'<=' not supported", "negative dimensions"
     (lambda p: matches_to_draw(np.ones(200, bool), 1.5), ValueError,
      "max_lines must be a whole number >= 0 or None, got 1.5"),
     (lambda p: matches_to_draw(np.ones(200, bool), "10"), TypeError,
      "max_lines must be a whole number or None, got str '10'"),
     (lambda p: matches_to_draw(np.ones(200, bool), np.nan), ValueError,
      "max_lines must be a whole number >= 0 or None, got nan"),
     (lambda p: matches_to_draw(np.ones(3, bool), True), TypeError,
      "max_lines must be a whole number or None, got bool True"),
     # Python's "expected str, bytes or os.PathLike object, not int"
     (lambda p: write_ply(3, ROWS, COLOURS), TypeError,
      "path must be a path (str or os.PathLike), got int")],
    ids=["NaN points", "colours fewer", "points of two", "colour 300", "beyond float32",
         "folder", "euler NaN", "angle-axis zeros", "zyx mirror", "dict None", "draw dict",
         "max_lines fraction", "max_lines text", "max_lines NaN", "max_lines True", "ply path"],
)  # fmt: skip
def test_the_export_helpers_refuse_what_they_cannot_write(tmp_path, call, exception, words):
    # they wrote NaN vertices, wrapped colour 300 to 44, broke on a numpy broadcast, read a
    # mirror or zeros as some rotation, or failed on an attribute of None
    with pytest.raises(exception, match=re.escape(words)):
        call(tmp_path / "points.ply")
    assert not (tmp_path / "points.ply").exists()


def test_a_colmap_model_into_a_file_is_refused_and_the_file_kept(demo_result, tmp_path):
    # os.makedirs's FileExistsError
    path = tmp_path / "model"
    path.write_text("notes")
    with pytest.raises(ValueError, match="model is a file, not a folder"):
        write_colmap_model(path, demo_result)
    assert path.read_text() == "notes"


def test_extra_of_long_doubles_is_written_and_one_nested_too_deeply_refused(
    demo_result, demo, tmp_path
):
    # a long double's tolist() is itself: json asked for it again until a RecursionError, as
    # it did for a list nested 100000 deep
    out = write_outputs(tmp_path / "out", demo_result, *demo[:2],
                        extra={"scale": np.longdouble(1.5), "scales": np.ones(2, np.longdouble)})
    data = json.loads((out / "result.json").read_text(encoding="utf-8"))
    assert data["scale"] == 1.5 and data["scales"] == [1.0, 1.0]
    deep = []
    for _ in range(100_000):
        deep = [deep]
    with pytest.raises(ValueError, match="extra cannot be written as JSON: it is nested too deep"):
        write_outputs(tmp_path / "deep", demo_result, *demo[:2], extra={"deep": deep})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_max_lines_beyond_a_float_draws_every_match():
    # float(10**400) raised OverflowError
    assert matches_to_draw(np.ones(200, bool), 10**400).tolist() == list(range(200))


def test_write_ply_replaces_a_file_whole(tmp_path):
    path = tmp_path / "points.ply"
    path.write_bytes(b"old")
    write_ply(path, ROWS + 1.0, COLOURS + 7)
    data = path.read_bytes()
    assert data.startswith(b"ply\n") and data.endswith(b"\x07\x07\x07") and b"vertex 3" in data
    assert sorted(p.name for p in tmp_path.iterdir()) == ["points.ply"]


@pytest.mark.parametrize(
    "call, exception, words",
    [(lambda r, i, p: write_colmap_model(p, r, names=("a.png", "a.png")), ValueError,
      "names must differ: a COLMAP model names each image once"),
     (lambda r, i, p: write_colmap_model(p, r, names="ab"), TypeError,
      "names must be two image names, got 'ab'"),
     (lambda r, i, p: write_colmap_model(p, r, names=("a.png",)), TypeError,
      "names must be two image names"),
     (lambda r, i, p: write_colmap_model(p, r, dists=(np.full(4, np.nan), None)), ValueError,
      "dists[0] has 4 NaN or infinite value(s)"),
     (lambda r, i, p: write_colmap_model(p, r, dists="ab"), TypeError,
      "dists must be two distortions (None for none), got 'ab'"),
     (lambda r, i, p: draw_matches(np.full(i[0].shape, np.nan), i[1], r), ValueError,
      "image1 has 921600 NaN or infinite pixel value(s)"),
     (lambda r, i, p: draw_matches(i[0][:100], i[1], r), ValueError,
      "image1 is 640x100 pixels, but the result's image 1 is 640x480"),
     (lambda r, i, p: draw_matches(i[0], None, r), TypeError, "image2"),
     (lambda r, i, p: matches_to_draw(None), TypeError,
      "inliers must be a one-dimensional array of bool, got object of shape ()"),
     (lambda r, i, p: matches_to_draw(np.ones((3, 3), bool)), TypeError,
      "inliers must be a one-dimensional array of bool, got bool of shape (3, 3)"),
     (lambda r, i, p: matches_to_draw(np.ones(9, bool), seed="x"), TypeError,
      "seed must be a whole number, got str 'x'"),
     (lambda r, i, p: ppo_cv.export.result_to_dict(r, R=1), ValueError,
      "extra would replace the result's own field(s) 'R'"),
     (lambda r, i, p: write_outputs(p, r, *i, extra={"t": [0, 0, 1], "model": "x"}), ValueError,
      "extra would replace the result's own field(s) 'model', 't'"),
     # os.makedirs's "expected str, bytes or os.PathLike object, not NoneType" and "No such
     # file or directory: ''"
     (lambda r, i, p: write_colmap_model(None, r), TypeError,
      "directory must be a path (str or os.PathLike), got NoneType"),
     (lambda r, i, p: write_colmap_model("", r), ValueError,
      "directory is an empty path, not a file or folder name")],
    ids=["same names", "names text", "one name", "NaN dist", "dists text", "draw NaN",
         "draw other size", "draw None", "inliers None", "inliers 2-D", "seed text",
         "extra R", "write extra t", "colmap folder None", "colmap folder empty"],
)  # fmt: skip
def test_the_writers_check_what_write_outputs_checks(demo_result, demo, tmp_path, call,
                                                     exception, words):  # fmt: skip
    # a COLMAP model of two images of one name, or with NaN parameters, was written; 'ab' was
    # read as the names 'a' and 'b'; a NaN image was drawn as black, another size's drawn over;
    # None drew one match; an extra 'R' replaced the result's rotation in result.json
    with pytest.raises(exception, match=re.escape(words)):
        call(demo_result, demo[:2], tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def _mean_reprojection_px(model, camera) -> float:
    """Mean distance (pixels) of every track element of ``model`` from its point seen by
    ``camera``."""
    errors = []
    for point in model.points3D.values():
        for element in point.track.elements:
            image = model.images[element.image_id]
            seen = camera.img_from_cam(image.cam_from_world() * point.xyz)
            errors.append(np.linalg.norm(seen - image.points2D[element.point2D_idx].xy))
    return float(np.mean(errors))


@pytest.mark.parametrize(
    "seed, scene, dist, model",
    [(1, None, None, "general"), (1, None, np.array([0.01, -0.002, 0.0, 0.0, 0.001]), "general"),
     (0, "plane", None, "plane")],
    ids=["general", "general with a given distortion", "plane"],
)  # fmt: skip
def test_the_colmap_camera_carries_the_radial_term_the_pose_was_fitted_with(
    tmp_path, seed, scene, dist, model
):
    from imperfect import imperfect_render

    from ppo_cv.export import fitted_radial_k1

    pair = imperfect_render(seed, 0.15 if scene is None else 0.1, scene=scene)
    result = estimate_pair(pair.image1, pair.image2, pair.K_given, dist1=dist, dist2=dist)
    assert result.model == model and abs(fitted_radial_k1(result)) > 0.03  # k1 0.06 or -0.05
    write_outputs(tmp_path / "out", result, pair.image1, pair.image2)
    model = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap"))
    (camera,) = model.cameras.values()
    assert camera.model_name == ("OPENCV" if dist is None else "FULL_OPENCV")
    K, coefficients = result.cameras.K1, np.zeros(8) if dist is None else np.r_[dist, 0, 0, 0]
    given = pycolmap.Camera(
        model="FULL_OPENCV", width=camera.width, height=camera.height,
        params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2], *coefficients],
    )  # fmt: skip
    exported = _mean_reprojection_px(model, camera)
    through_given = _mean_reprojection_px(model, given)
    assert exported < 0.5 * through_given and exported < 0.2
    assert model.compute_mean_reprojection_error() == pytest.approx(exported, rel=1e-6)


@pytest.mark.parametrize(
    "focal, k1, size, worst_px",
    [(900.0, 0.1, 4, 0.05), (500.0, -0.1, 4, 0.05), (500.0, 0.3, 8, 0.1), (350.0, -0.1, 8, 0.05)],
    ids=["narrow", "normal", "strong", "wide"],
)
def test_the_composed_lens_takes_k3_where_four_coefficients_miss_it(focal, k1, size, worst_px):
    # (k1, k2) alone missed a strong radial term in a wide field by up to 10 px at the corners
    from ppo_cv.camera import normalized_to_pixels, pixels_to_normalized
    from ppo_cv.export import composed_distortion
    from ppo_cv.plane import undistort_division

    K_wide = np.array([[focal, 0.0, 320.0], [0.0, focal, 240.0], [0.0, 0.0, 1.0]])
    coefficients = composed_distortion(K_wide, None, (640, 480), k1)
    u, v = np.meshgrid(np.linspace(0, 639, 41), np.linspace(0, 479, 31))
    pixels = np.column_stack([u.ravel(), v.ravel()])
    ideal = undistort_division(pixels_to_normalized(pixels, K_wide, None), k1)[:, :2]
    back = normalized_to_pixels(ideal, K_wide, coefficients)
    assert coefficients.size == size and np.abs(back - pixels).max() < worst_px


_K_NORMAL = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    "k1, error, words",
    [(-5.0, ValueError, "(|x|^2 up to 0.64), got -5.0"),
     (1e300, ValueError, "within +-10 under which"),
     (None, TypeError, "k1 must be a number, got NoneType")],
    ids=["folding the image", "huge", "none"],
)  # fmt: skip
def test_a_division_term_that_is_no_lens_is_refused_by_the_composed_lens(k1, error, words):
    # -5 folds a 640x480 image at 500 px (1 + k1 |x|^2 reaches 0 inside it), 1e300 squeezes it
    # to a point: both gave coefficients of nothing; None failed in numpy
    from ppo_cv.export import composed_distortion

    with pytest.raises(error) as info:
        composed_distortion(_K_NORMAL, None, (640, 480), k1)
    assert words in str(info.value)


@pytest.mark.parametrize(
    "call, error, words",
    [(lambda e: e.check_colmap_names(np.array(["a.png", "b.png"])), TypeError,
      "names must be two image names (texts), got array("),
     (lambda e: e.check_colmap_names("ab"), TypeError, "names must be two image names"),
     (lambda e: e.check_colmap_camera(2 * np.eye(3), None, "camera 1"), ValueError,
      "camera 1 must be upper triangular with last row (0, 0, 1)"),
     (lambda e: e.check_colmap_camera(np.full((3, 3), np.nan), None, "camera 1"), ValueError,
      "camera 1 has 9 NaN"),
     (lambda e: e.check_colmap_camera(_K_NORMAL, [0.1, 0.0, 0.0], "camera 2"), ValueError,
      "camera 2 must be OpenCV distortion coefficients")],
    ids=["names array", "names one text", "K scaled", "K nan", "dist of 3"],
)  # fmt: skip
def test_the_colmap_checks_name_what_is_no_name_or_camera(call, error, words):
    # an AttributeError ("'numpy.ndarray' object has no attribute 'encode'"), "ab" passed as
    # two names, a camera matrix of last row (0, 0, 2) passed and a NaN one "has skew nan"
    from ppo_cv import export

    with pytest.raises(error) as info:
        call(export)
    assert words in str(info.value)


def test_a_nan_division_term_is_refused_by_the_composed_lens():
    # it hung numpy's least squares in LAPACK (holding the interpreter: run apart, with a timeout)
    code = (
        "import numpy as np\n"
        "from ppo_cv.export import composed_distortion\n"
        "K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])\n"
        "try:\n"
        "    composed_distortion(K, None, (640, 480), float('nan'))\n"
        "except ValueError as error:\n"
        "    print(error)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "k1 must be a division term" in run.stdout and "got nan" in run.stdout


def test_a_moving_pair_given_the_rotation_only_fit_exports_points_of_that_rotation(tmp_path):
    # the points were the essential matrix's, whose rotation the choice had set aside: image 2
    # of the COLMAP model saw them tens of pixels from their keypoints on a tripod pair
    from ppo_cv import data_gen

    pair = data_gen.make_pair(
        "tiny-baseline", seed=0, index=9, imperfections=data_gen.REAL_PHOTO, baseline_ratio=0.02
    )
    images = [np.ascontiguousarray(image[..., ::-1]) for image in (pair.image1, pair.image2)]
    result = estimate_pair(*images, pair.K1_given, pair.K2_given)
    assert result.model != "rotation" and result.rotation_source == "rotation"
    assert len(result.point_matches) > 0.9 * np.count_nonzero(result.inliers)
    write_outputs(tmp_path / "out", result, *images)
    model = pycolmap.Reconstruction(str(tmp_path / "out" / "colmap"))
    errors = {
        image_id: np.median([
            np.linalg.norm(
                model.cameras[image.camera_id].img_from_cam(
                    image.cam_from_world() * model.points3D[point.point3D_id].xyz
                ) - point.xy
            )
            for point in image.points2D if point.has_point3D()
        ])
        for image_id, image in model.images.items()
    }  # fmt: skip
    assert errors[2] < 1.0 and errors[2] < 3.0 * errors[1] + 0.1, errors


def test_a_huge_matrix_is_no_rotation_without_a_runtime_warning():
    # R R^T overflowed with a RuntimeWarning before the error
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="R is not a rotation matrix"):
            ppo_cv.export.camera_euler_degrees(np.eye(3) * 1e300)
