"""Intrinsics parsing: --K strings, OpenCV YAML/XML, COLMAP cameras.txt, JSON and EXIF."""

from __future__ import annotations

import doctest
import json
import os
import re

import cv2
import numpy as np
import pytest

from ppo_cv import calib
from ppo_cv.calib import (
    Camera,
    camera_from_exif,
    fit_to_image,
    load_calibration,
    parse_distortion,
    parse_intrinsics,
)

K_FREIBURG = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
DIST = np.array([-0.2, 0.05, 0.001, -0.002, 0.01])


def test_docstring_examples():
    result = doctest.testmod(calib, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


@pytest.mark.parametrize(
    "text",
    [
        "535.4,539.2,320.1,247.6",
        "535.4, 539.2, 320.1, 247.6",
        "535.4 539.2 320.1 247.6",
        "535.4,0,320.1,0,539.2,247.6,0,0,1",
        "[535.4, 0, 320.1, 0, 539.2, 247.6, 0, 0, 1]",
        str(K_FREIBURG.tolist()),  # K printed by Python: nested lists
        str(K_FREIBURG),  # and by numpy, over three lines
    ],
)
def test_parse_intrinsics_accepts_four_or_nine_numbers(text):
    np.testing.assert_allclose(parse_intrinsics(text), K_FREIBURG)


@pytest.mark.parametrize(
    "text, message",
    [
        ("535.4,539.2,320.1", "4 numbers"),
        ("1,2,3,4,5", "4 numbers"),
        ("fx,fy,cx,cy", "numbers"),
        ("", "4 numbers"),
        ("0,539.2,320.1,247.6", "focal"),
        ("-535.4,539.2,320.1,247.6", "positive"),
        ("535.4,0,320.1,0,539.2,247.6,0,1,1", "last row"),
        ("nan,539.2,320.1,247.6", "NaN"),
    ],
)
def test_parse_intrinsics_rejects_malformed_text(text, message):
    with pytest.raises(ValueError, match=message):
        parse_intrinsics(text)


def test_parse_distortion():
    np.testing.assert_allclose(parse_distortion("-0.2,0.05,0.001,-0.002"), DIST[:4])
    np.testing.assert_allclose(parse_distortion("-0.2,0.05,0.001,-0.002,0.01"), DIST)
    assert parse_distortion("0,0,0,0") is None
    with pytest.raises(ValueError, match="k1,k2,p1,p2"):
        parse_distortion("0.1,0.2,0.3")
    with pytest.raises(ValueError, match="numbers"):
        parse_distortion("k1")


@pytest.mark.parametrize("extension", ["yml", "yaml", "xml", "json"])
def test_opencv_file_storage(tmp_path, extension):
    # json: cv2.FileStorage's JSON was read as a JSON camera and refused ("camera_matrix must be
    # numbers, got {"type_id": "opencv-matrix", ...")
    path = tmp_path / f"camera.{extension}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 640)
    storage.write("image_height", 480)
    storage.write("camera_matrix", K_FREIBURG)
    storage.write("distortion_coefficients", DIST.reshape(1, 5))
    storage.release()
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K_FREIBURG)
    np.testing.assert_allclose(camera.dist, DIST)
    assert camera.image_size == (640, 480)


def _written_by_opencv(tmp_path, extension: str) -> bytes:
    path = tmp_path / f"written.{extension}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("camera_matrix", K_FREIBURG)
    storage.write("distortion_coefficients", DIST.reshape(1, 5))
    storage.release()
    return path.read_bytes()


BOM_FILES = {  # the text of each format, as an editor on Windows saves it: a UTF-8 BOM first
    "yml": lambda tmp_path: _written_by_opencv(tmp_path, "yml"),
    "xml": lambda tmp_path: _written_by_opencv(tmp_path, "xml"),
    "json": lambda _: json.dumps({"K": K_FREIBURG.tolist(), "dist": DIST.tolist()}).encode(),
    "txt": lambda _: b"# Camera list\n1 OPENCV 640 480 535.4 539.2 320.6 248.1 "
    + " ".join(str(v) for v in DIST[:4]).encode() + b"\n",
}


@pytest.mark.parametrize("extension", list(BOM_FILES))
def test_a_byte_order_mark_before_a_calibration_is_read_past(tmp_path, extension):
    path = tmp_path / f"camera.{extension}"
    path.write_bytes(b"\xef\xbb\xbf" + BOM_FILES[extension](tmp_path))
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K_FREIBURG)
    np.testing.assert_allclose(camera.dist, DIST if extension != "txt" else DIST[:4])


def test_opencv_stereo_file_gives_two_cameras(tmp_path):
    path = tmp_path / "stereo.yml"
    K2 = K_FREIBURG * [[1.1], [1.1], [1.0]]
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("M1", K_FREIBURG)
    storage.write("D1", DIST)
    storage.write("M2", K2)
    storage.release()
    first, second = load_calibration(path)
    np.testing.assert_allclose(first.K, K_FREIBURG)
    np.testing.assert_allclose(second.K, K2)
    assert second.dist is None


def test_opencv_file_with_bad_distortion_names_the_file(tmp_path):
    path = tmp_path / "short.yml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("camera_matrix", K_FREIBURG)
    storage.write("distortion_coefficients", np.array([0.1, 0.0, 0.0]))
    storage.release()
    with pytest.raises(ValueError, match=r"distortion coefficients in .*short\.yml must be"):
        load_calibration(path)


def test_opencv_file_without_camera_matrix(tmp_path):
    path = tmp_path / "empty.yml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("something_else", 3)
    storage.release()
    with pytest.raises(ValueError, match="no camera matrix"):
        load_calibration(path)


def test_colmap_cameras_txt(tmp_path):
    path = tmp_path / "cameras.txt"
    path.write_text(
        "# Camera list with one line of data per camera:\n"
        "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        "1 PINHOLE 640 480 535.4 539.2 320.6 248.1\n"
        "2 SIMPLE_RADIAL 640 480 500 320 240 -0.1\n"
    )
    first, second = load_calibration(path)
    np.testing.assert_allclose(first.K, K_FREIBURG)  # COLMAP's pixel centres are 0.5 further
    assert first.dist is None
    np.testing.assert_allclose(second.K, [[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]])
    np.testing.assert_allclose(second.dist, [-0.1, 0, 0, 0])


@pytest.mark.parametrize(
    "line, K, dist",
    [
        # the principal point in OpenCV's pixel coordinates, COLMAP's less half a pixel
        ("1 SIMPLE_PINHOLE 640 480 500 320 240", [500, 500, 319.5, 239.5], None),
        ("1 RADIAL 640 480 500 320 240 -0.1 0.02", [500, 500, 319.5, 239.5], [-0.1, 0.02, 0, 0]),
        (
            "1 OPENCV 640 480 510 500 320 240 -0.1 0.02 0.001 0.002",
            [510, 500, 319.5, 239.5],
            [-0.1, 0.02, 0.001, 0.002],
        ),
        (
            "1 FULL_OPENCV 640 480 510 500 320 240 -0.1 0.02 0.001 0.002 0.01 0 0 0",
            [510, 500, 319.5, 239.5],
            [-0.1, 0.02, 0.001, 0.002, 0.01, 0, 0, 0],
        ),
    ],
)
def test_colmap_camera_models(tmp_path, line, K, dist):
    path = tmp_path / "cameras.txt"
    path.write_text(line + "\n")
    (camera,) = load_calibration(path)
    fx, fy, cx, cy = K
    np.testing.assert_allclose(camera.K, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
    if dist is None:
        assert camera.dist is None
    else:
        np.testing.assert_allclose(camera.dist, dist)


@pytest.mark.parametrize(
    "text, message",
    [
        ("1 FISHEYE 640 480 1 2 3 4\n", "unsupported COLMAP camera model"),
        ("1 PINHOLE 640 480 535.4 539.2\n", "takes 4 parameters"),
        ("1 PINHOLE\n", "expected CAMERA_ID"),
        ("# only comments\n", "no camera"),
        # one id naming two cameras: the second line was taken as image 2's camera
        ("1 PINHOLE 640 480 500 500 320 240\n1 PINHOLE 640 480 510 500 320 240\n",
         r"cameras.txt:2: camera 1 is described otherwise on line 1; each CAMERA_ID names one"),
        ("x PINHOLE 640 480 500 500 320 240\n", r"CAMERA_ID must be a whole number >= 0, got 'x'"),
    ],
)
def test_colmap_errors(tmp_path, text, message):
    path = tmp_path / "cameras.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


@pytest.mark.parametrize(
    "text",
    [
        "camera_matrix: [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]\n",
        "camera_matrix:\n  - [535.4, 0, 320.1]\n  - [0, 539.2, 247.6]\n  - [0, 0, 1]\n",
        "camera_matrix: [535.4, 0, 320.1, 0, 539.2, 247.6, 0, 0, 1]\n",
    ],
)
def test_a_yaml_camera_matrix_may_be_given_as_rows(tmp_path, text):
    """A 3x3 list of rows was refused as "must be a list of numbers"; JSON takes it."""
    path = tmp_path / "camera.yaml"
    path.write_text(text)
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K_FREIBURG)


def test_a_yaml_row_holding_text_is_named(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_text('camera_matrix: [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, "a"]]\n')
    with pytest.raises(ValueError, match="camera_matrix in .* must be a list of numbers, flat or"):
        load_calibration(path)


@pytest.mark.parametrize(
    "write, K",
    [
        (lambda path: np.savetxt(path, K_FREIBURG), K_FREIBURG),
        (lambda path: np.savetxt(path, K_FREIBURG, delimiter=",", header="K"), K_FREIBURG),
        (lambda path: path.write_text("535.4 539.2 320.1 247.6\n"), K_FREIBURG),
        (lambda path: path.write_text(str(K_FREIBURG) + "\n"), K_FREIBURG),
    ],
)
def test_a_text_file_of_numbers_only_is_the_camera_matrix(tmp_path, write, K):
    """``K.txt`` as numpy writes it was read as a COLMAP ``cameras.txt`` and refused with
    ``expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...``."""
    path = tmp_path / "K.txt"
    write(path)
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K)
    assert camera.dist is None and camera.image_size is None


@pytest.mark.parametrize(
    "text, message",
    [
        ("1 2 3 4 5\n", r"camera matrix in .*K.txt must be 4 numbers fx,fy,cx,cy or the 9 "),
        ("535 0 320\n0 535 240\n0 0 1\nnan\n", "camera matrix in .*K.txt has NaN"),
        ("1 PINHOLE\n", "expected CAMERA_ID"),
    ],
)
def test_a_text_file_of_numbers_that_are_no_camera_matrix_says_so(tmp_path, text, message):
    path = tmp_path / "K.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


@pytest.mark.parametrize("text", ["-0.1", "-0.1,0.01", "-0.1,0.01,0"])
def test_a_radial_term_alone_is_told_how_to_give_the_four_coefficients(text):
    with pytest.raises(ValueError, match=r"got \d \(k1 alone, or k1,k2: give k1,0,0,0 or k1,k2,"):
        parse_distortion(text, "--dist")


@pytest.mark.parametrize("text", ["535", "535,539", "535,320,240"])
def test_a_focal_length_alone_is_told_how_to_give_the_principal_point(text):
    with pytest.raises(ValueError, match=r"got \d \(a focal length alone, or f,cx,cy: give "
                       r"f,f,cx,cy, the principal point at the image centre"):  # fmt: skip
        parse_intrinsics(text, "--K")


@pytest.mark.parametrize(
    "lines, cameras",
    [
        (["1 PINHOLE 640 480 500 500 320 240"] * 3, 1),  # one camera per image, all alike
        (["1 PINHOLE 640 480 500 500 320 240", "2 SIMPLE_RADIAL 640 480 500 320 240 0.1"], 2),
    ],
)
def test_a_colmap_file_of_cameras_all_alike_is_one_camera(tmp_path, lines, cameras):
    path = tmp_path / "cameras.txt"
    path.write_text("\n".join(lines) + "\n")
    assert len(load_calibration(path)) == cameras


def test_a_colmap_file_gives_its_cameras_in_the_order_of_their_ids(tmp_path):
    # COLMAP writes cameras.txt in any order; the second line's camera 1 was image 2's camera
    path = tmp_path / "cameras.txt"
    path.write_text("2 PINHOLE 640 480 510 500 320 240\n1 PINHOLE 640 480 500 500 320 240\n")
    assert [camera.K[0, 0] for camera in load_calibration(path)] == [500.0, 510.0]


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("dup.json", '{"K": [500, 500, 320, 240], "K": [900, 900, 320, 240]}',
         r"dup.json is not a calibration file: the key 'K' is given twice in one object"),
        ("dup2.json", '{"cameras": [{"fx": 5, "fx": 500, "fy": 500, "cx": 320, "cy": 240}]}',
         r"the key 'fx' is given twice"),
    ],
)  # fmt: skip
def test_a_json_key_given_twice_is_refused(tmp_path, name, text, message):
    # JSON readers keep the last value: the file said two things and one was dropped silently
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


def test_utf16_text_is_named_so(tmp_path):
    path = tmp_path / "camera.json"
    path.write_text('{"K": [500, 500, 320, 240]}', encoding="utf-16")
    with pytest.raises(ValueError, match=r"camera.json is UTF-16 text, not UTF-8 .*: save it as "
                       r"UTF-8$"):  # fmt: skip  (it said 'a binary file, such as an image?')
        load_calibration(path)


@pytest.mark.parametrize(
    "name, text",
    [
        ("cameras.txt", "1 PINHOLE 640 480 500 500 320 240\n2 PINHOLE 640 480 510 500 320 240\n"
         "3 PINHOLE 640 480 500 500 320 240\n"),
        ("cameras.json", '{"cameras": [[500, 500, 320, 240], [510, 500, 320, 240], '
         '[520, 500, 320, 240]]}'),
    ],
)  # fmt: skip
def test_a_file_of_more_than_two_cameras_is_refused(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match="describes 3 different cameras; give a file of one"):
        load_calibration(path)


@pytest.mark.parametrize(
    "data",
    [
        {"K": K_FREIBURG.tolist(), "dist": DIST.tolist()},
        {"K": K_FREIBURG.ravel().tolist(), "dist": DIST.tolist()},
        {"fx": 535.4, "fy": 539.2, "cx": 320.1, "cy": 247.6, "distortion": DIST.tolist()},
        {"cameras": [{"K": [535.4, 539.2, 320.1, 247.6], "dist": DIST.tolist()}]},
    ],
)
def test_json_single_camera(tmp_path, data):
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K_FREIBURG)
    np.testing.assert_allclose(camera.dist, DIST)


@pytest.mark.parametrize(
    "data",
    [
        {"K1": [535.4, 539.2, 320.1, 247.6], "K2": [600, 600, 300, 200]},
        [{"K": K_FREIBURG.tolist()}, {"fx": 600, "fy": 600, "cx": 300, "cy": 200}],
        {"cameras": [[535.4, 539.2, 320.1, 247.6], [600, 600, 300, 200]]},
    ],
    ids=["K1 K2", "list of objects", "cameras of numbers"],
)
def test_json_two_cameras(tmp_path, data):
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(data))
    first, second = load_calibration(path)
    np.testing.assert_allclose(first.K, K_FREIBURG)
    np.testing.assert_allclose(second.K, [[600, 0, 300], [0, 600, 200], [0, 0, 1]])


@pytest.mark.parametrize(
    "text, message",
    [
        ("{not json", "not valid JSON"),
        ('{"focal": 500}', "expected K"),
        ('{"K": [1, 2, 3]}', "4 numbers"),
        ('{"K": [500, 500, 320, 240], "dist": [1, 2, 3]}', "k1,k2,p1,p2"),
        ('{"fx": true, "fy": 500, "cx": 320, "cy": 240}', "fx must be numbers, got true"),
        ('{"K": [500, 500, 320, 240], "dist": [false, 0, 0, 0]}', "dist must be numbers"),
        ('{"K": "500,500,320,240"}', r'K must be numbers, got "500,500,320,240"'),
        ('{"fx": "a", "fy": 500, "cx": 320, "cy": 240}', 'fx must be numbers, got "a"'),
        ('{"K": [500, 500, 320, 240], "dist": [0.1, "a", 0, 0]}', r"dist must be numbers, got "
         r'\[0.1, "a", 0, 0\]'),
        ('{"cameras": [{"K": [500, 500, 320, 240], "dist": [1, 2]}]}', "camera 1: dist must be "
         "OpenCV distortion"),
        ('{"cameras": {"K": [500, 500, 320, 240]}}', "cameras must be a list of cameras"),
        ('{"cameras": []}', "no camera in"),
        # the file named, not Python's limit on the digits of an integer alone
        ('{"fx": ' + "9" * 5000 + ', "fy": 500, "cx": 320, "cy": 240}',
         r"camera\.json is not a calibration file: Exceeds the limit \(4300 digits\) for "
         "integer string conversion: value has 5000 digits$"),
    ],
)
def test_json_errors(tmp_path, text, message):
    path = tmp_path / "camera.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


@pytest.mark.parametrize(
    "data, key",
    [
        ({"K": [535.4, 539.2, 320.1, 247.6], "distortion_coefficients": DIST.tolist()},
         "distortion_coefficients"),
        ({"fx": 535.4, "fy": 539.2, "cx": 320.1, "cy": 247.6, "k1": -0.2, "k2": 0.05}, "k1"),
        ({"K": [535.4, 539.2, 320.1, 247.6], "image_size": [640, 480]}, "image_size"),
        ({"K": [535.4, 539.2, 320.1, 247.6], "K2": [600, 600, 300, 200]}, "K2"),
        ({"K1": [535.4, 539.2, 320.1, 247.6], "D1": DIST.tolist()}, "D1"),
        ({"cameras": [{"K": [535.4, 539.2, 320.1, 247.6]}], "dist": DIST.tolist()}, "dist"),
    ],
    ids=["OpenCV's name", "k1 k2", "image_size", "K with K2", "D1", "dist beside cameras"],
)  # fmt: skip
def test_a_json_key_that_would_be_ignored_is_refused_by_name(tmp_path, data, key):
    # each was dropped without a word: a camera read without its distortion, size or second K
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=f"camera.json: unknown key '{key}', which would be "):
        load_calibration(path)


def test_a_json_camera_may_carry_text_beside_its_numbers(tmp_path):
    path = tmp_path / "camera.json"
    path.write_text(json.dumps({"name": "cam0", "model": "pinhole", "K": K_FREIBURG.tolist()}))
    np.testing.assert_array_equal(load_calibration(path)[0].K, K_FREIBURG)


def test_the_image_size_of_a_json_rig_is_read(tmp_path):
    # {"K1", "K2", "width", "height"} dropped the size: a calibration of larger images was not
    # scaled to the photos
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"K1": [535.4, 539.2, 320.1, 247.6], "K2": [600, 600, 300, 200],
                                "width": 640, "height": 480}))  # fmt: skip
    assert [camera.image_size for camera in load_calibration(path)] == [(640, 480)] * 2


@pytest.mark.parametrize("key", ["distortion", "dist", "Distortion_Coeffs"])
@pytest.mark.parametrize("extension", ["yml", "xml"])
def test_an_opencv_distortion_under_a_name_not_read_is_refused(tmp_path, extension, key):
    # its coefficients were dropped: the camera was read without distortion
    path = tmp_path / f"camera.{extension}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("camera_matrix", K_FREIBURG)
    storage.write(key, DIST.reshape(1, 5))
    storage.write("distortion_model", "plumb_bob")  # text: read past
    storage.release()
    with pytest.raises(ValueError, match=f"^{key} in .*camera.{extension} is no distortion key"):
        load_calibration(path)


ROS_CAMERA_INFO = """image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [535.4, 0, 320.1, 0, 539.2, 247.6, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.2, 0.05, 0.001, -0.002, 0.01]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


def test_a_ros_camera_info_file_is_read(tmp_path):
    # its matrices, maps without OpenCV's dt, were "malformed ...: !dt.empty() in function 'read'"
    path = tmp_path / "camera.yaml"
    path.write_text(ROS_CAMERA_INFO)
    (camera,) = load_calibration(path)
    np.testing.assert_allclose(camera.K, K_FREIBURG)
    np.testing.assert_allclose(camera.dist, DIST)
    assert camera.image_size == (640, 480)


def test_a_ros_fisheye_is_refused(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_text(ROS_CAMERA_INFO.replace("plumb_bob", "equidistant"))
    with pytest.raises(ValueError, match="distortion_model 'equidistant' in .* is not OpenCV's"):
        load_calibration(path)


def test_missing_calibration_file(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_calibration(tmp_path / "absent.yml")


def test_exif_absent_gives_default_guess(tmp_path):
    path = tmp_path / "plain.png"
    cv2.imwrite(str(path), np.zeros((480, 640, 3), np.uint8))
    camera, from_exif = camera_from_exif(path)
    assert not from_exif
    np.testing.assert_allclose(camera.K, [[768, 0, 320], [0, 768, 240], [0, 0, 1]])


def test_exif_camera_of_a_photo_stored_sideways_is_that_of_the_upright_image(tmp_path):
    from PIL import Image

    path = tmp_path / "portrait.jpg"
    exif = Image.Exif()
    exif[0x010F], exif[0x0110], exif[0x0112] = "Maker", "Model", 8  # turn 90 deg to show
    exif.get_ifd(0x8769)[0xA405] = 36
    Image.fromarray(np.zeros((480, 640, 3), np.uint8)).save(path, exif=exif)
    assert cv2.imread(str(path)).shape[:2] == (640, 480)
    camera, from_exif = camera_from_exif(path)
    assert from_exif
    np.testing.assert_allclose(camera.K[:2, 2], [240.0, 320.0])
    expected = 36.0 / np.hypot(36.0, 24.0) * np.hypot(640.0, 480.0)
    np.testing.assert_allclose(np.diag(camera.K)[:2], expected, rtol=1e-3)


def test_exif_focal_length_is_used(tmp_path):
    from PIL import Image

    path = tmp_path / "photo.jpg"
    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Maker", "Model"  # Make, Model
    ifd = exif.get_ifd(0x8769)
    ifd[0xA405] = 36  # FocalLengthIn35mmFilm, mm, relative to the 36x24 mm frame diagonal
    Image.fromarray(np.zeros((480, 640, 3), np.uint8)).save(path, exif=exif)
    camera, from_exif = camera_from_exif(path)
    assert from_exif
    expected = 36.0 / np.hypot(36.0, 24.0) * np.hypot(640.0, 480.0)
    np.testing.assert_allclose(camera.K[0, 0], expected, rtol=1e-3)
    np.testing.assert_allclose(camera.K[:2, 2], [320.0, 240.0])


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("bad.yml", "%YAML:1.0\n---\ncamera_matrix: [1, 2, 3\n", "malformed OpenCV calibration"),
        ("empty.yml", "", "is empty"),
        ("scalar.yml", "%YAML:1.0\n---\ncamera_matrix: 5\n", "is a scalar, not a matrix"),
        ("top.yml", "%YAML:1.0\n---\n5\n", "malformed OpenCV calibration"),
        ("bad.xml", '<?xml version="1.0"?>\n<opencv_storage><camera_matrix>1 2', "malformed"),
        ("deep.json", "[" * 100_000 + "]" * 100_000, "nested too deeply"),
        ("deep_object.json", '{"K":' * 50_000 + "1" + "}" * 50_000, "nested too deeply"),
        (
            "square.yml",
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n"
            "  data: [535.4, 539.2, 320.1, 247.6]\n",
            r"camera matrix in .*square\.yml must be a 3x3 matrix, got shape \(2, 2\)",
        ),
        (
            "square.json",
            '{"K": [[535.4, 539.2], [320.1, 247.6]]}',
            r"3x3 matrix, got shape \(2, 2\)",
        ),
        (
            "size.yml",
            "%YAML:1.0\n---\nimage_width: 640.5\nimage_height: 480\ncamera_matrix: [1, 1, 0, 0]\n",
            "image width and height must be whole numbers",
        ),
        ("cameras.txt", "1 PINHOLE 0 480 500 500 320 240\n", "whole numbers from 1 to 1e6"),
        (
            "cameras.txt",
            "1 PINHOLE w h 500 500 320 240\n",
            "image width and height must be numbers",
        ),
    ],
)
def test_unparseable_calibration_files_are_value_errors(tmp_path, name, text, message):
    (tmp_path / name).write_text(text)
    with pytest.raises(ValueError, match=message):
        load_calibration(tmp_path / name)


_HUGE = "1" + "0" * 400  # an integer JSON reads whole, beyond float64


@pytest.mark.parametrize(
    "entry, message",
    [(f'"fx": {_HUGE}, "fy": 500, "cx": 320, "cy": 240', "fx holds a number beyond the range"),
     (f'"K": [[{_HUGE}, 0, 320], [0, 500, 240], [0, 0, 1]]', "K holds a number beyond the range"),
     (f'"fx": 500, "fy": 500, "cx": 320, "cy": 240, "dist": [{_HUGE}, 0, 0, 0]',
      "dist holds a number beyond the range"),
     (f'"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": {_HUGE}, "height": 480',
      "whole numbers from 1 to 1e6, got <401-digit integer> and 480")],
    ids=["fx", "K", "dist", "width"],
)  # fmt: skip
def test_a_json_integer_beyond_a_float_is_named(tmp_path, entry, message):
    # Python's OverflowError escaped load_calibration, and ppo-cv pair --calib ended in it
    path = tmp_path / "camera.json"
    path.write_text("{" + entry + "}")
    with pytest.raises(ValueError, match=re.escape(message)):
        load_calibration(path)


def test_a_plain_list_of_nine_numbers_reads_as_K(tmp_path):
    path = tmp_path / "list.yml"
    path.write_text("%YAML:1.0\n---\ncamera_matrix: [500, 0, 320, 0, 510, 240, 0, 0, 1]\n")
    np.testing.assert_array_equal(
        load_calibration(path)[0].K, [[500, 0, 320], [0, 510, 240], [0, 0, 1]]
    )


@pytest.mark.parametrize(
    "name, text",
    [
        ("cameras.txt", "1 PINHOLE 320 240 267.7 269.6 159.8 123.55\n"),
        ("camera.json", '{"fx": 267.7, "fy": 269.6, "cx": 159.8, "cy": 123.55, "width": 320, '
                        '"height": 240}'),
        ("camera.yml", "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\n"
                       "camera_matrix: [267.7, 0, 159.8, 0, 269.6, 123.55, 0, 0, 1]\n"),
    ],
)  # fmt: skip
def test_a_calibration_states_the_size_of_its_images(tmp_path, name, text):
    (tmp_path / name).write_text(text)
    (camera,) = load_calibration(tmp_path / name)
    assert camera.image_size == (320, 240)


def test_a_camera_is_scaled_to_a_resized_image_about_the_pixel_centres():
    camera = Camera(
        np.array([[267.7, 0.5, 159.8], [0, 269.6, 123.55], [0, 0, 1]]), None, (320, 240)
    )
    scaled, note = fit_to_image(camera, (640, 480), "--calib c.txt", "a.png")
    np.testing.assert_allclose(
        scaled.K, [[535.4, 1.0, 320.1], [0, 539.2, 247.6], [0, 0, 1]], rtol=0, atol=1e-12
    )
    assert scaled.image_size == (640, 480)
    assert note == (
        "--calib c.txt describes a camera of 320x240 images: its camera matrix scaled by 2 to "
        "a.png, 640x480 pixels"
    )
    # a pixel centre of the small image lands on the same point of the large one
    u_small = camera.K[0, 0] * 0.1 + camera.K[0, 2]
    assert scaled.K[0, 0] * 0.1 + scaled.K[0, 2] == pytest.approx((u_small + 0.5) * 2 - 0.5)
    same, note = fit_to_image(camera, (320, 240), "c")
    assert same is camera and note is None
    unsized = Camera(camera.K)
    same, note = fit_to_image(unsized, (640, 480), "c")
    assert same is unsized and note is None
    with pytest.raises(ValueError, match="320x240 images but a.png is 640x400 pixels, another"):
        fit_to_image(camera, (640, 400), "c", "a.png")


def test_a_calibration_of_an_image_turned_by_exif_names_the_turn():
    """The camera of 320x240 images and an image stored so (a resized copy too) but shown
    upright as 240x320 or 480x640: the EXIF orientation is named with the way out; an image
    not turned by EXIF keeps the general refusal."""
    camera = Camera(np.array([[267.7, 0, 159.8], [0, 269.6, 123.55], [0, 0, 1]]), None, (320, 240))
    for size in ((240, 320), (480, 640)):
        message = (
            rf"the pixels of a.jpg as stored \({size[1]}x{size[0]}\), but its EXIF orientation "
            "turns them upright to .*--no-exif-orientation"
        )
        with pytest.raises(ValueError, match=message):
            fit_to_image(camera, size, "c", "a.jpg", turned=True)
        with pytest.raises(ValueError, match="another aspect ratio"):
            fit_to_image(camera, size, "c", "a.jpg")
    with pytest.raises(ValueError, match="another aspect ratio"):
        fit_to_image(camera, (640, 400), "c", "a.jpg", turned=True)
    with pytest.raises(TypeError, match="turned"):
        fit_to_image(camera, (640, 480), "c", "a.jpg", turned="yes")


@pytest.mark.parametrize("value", [None, 535.4, b"535.4,539.2,320.1,247.6"], ids=repr)
@pytest.mark.parametrize("parse", [parse_intrinsics, parse_distortion], ids=lambda f: f.__name__)
def test_parsing_something_other_than_text_is_a_type_error(parse, value):
    """None and a number were a ValueError about comma-separated numbers (None "got 1" number)."""
    with pytest.raises(TypeError, match=f"must be a text of numbers, got {type(value).__name__}"):
        parse(value)


def _exif_target(tmp_path, kind):
    path = tmp_path / f"{kind}.png"
    if kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "truncated":
        cv2.imwrite(str(tmp_path / "whole.png"), np.full((480, 640, 3), 90, np.uint8))
        path.write_bytes((tmp_path / "whole.png").read_bytes()[:300])
    return path


@pytest.mark.parametrize(
    "kind, words",
    [("missing", "image not found: "), ("folder", "expected an image file, got a directory: "),
     ("fifo", "not a regular file: "), ("truncated", "not a readable image: ")],
)  # fmt: skip
def test_camera_from_exif_names_a_file_that_is_no_image(tmp_path, capfd, kind, words):
    """pycolmap said an existing folder did not exist, and guessed a camera for a damaged image
    after libpng's errors on stderr."""
    path = _exif_target(tmp_path, kind)
    with pytest.raises(ValueError, match=re.escape(f"{words}{path}")):
        camera_from_exif(path)
    assert capfd.readouterr().err == ""


def test_camera_from_exif_of_something_other_than_a_path_is_a_type_error():
    with pytest.raises(TypeError, match="path must be a path .*, got NoneType"):
        camera_from_exif(None)


PNG_BYTES = cv2.imencode(".png", np.zeros((8, 8), np.uint8))[1].tobytes()


@pytest.mark.parametrize(
    "data, words",
    [(PNG_BYTES, "(byte 0x89): a binary file, such as an image?"),
     ("1 PINHOLE 640 480 500 500 320 240 # café\n".encode("latin-1"),
      "(byte 0xe9): save it as UTF-8")],
    ids=["an image", "Latin-1 text"],
)  # fmt: skip
@pytest.mark.parametrize("what", ["calibration file", "pairs file"])
def test_a_file_that_is_no_utf8_text_is_named_with_what_it_is(tmp_path, data, words, what):
    """Python's decoding error alone ("'utf-8' codec can't decode byte 0x89 in position 0")."""
    from ppo_cv.cli.batch import read_pairs

    path = tmp_path / "given.txt"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=re.escape(f"{what} {path} is not UTF-8 text {words}")):
        load_calibration(path) if what == "calibration file" else read_pairs(path)


FISHEYE = [-0.01, 0.002, -0.001, 0.0003]  # equidistant k1..k4, no OpenCV pinhole coefficients


@pytest.mark.parametrize(
    "data, where",
    [
        ({"K": K_FREIBURG.tolist(), "dist": FISHEYE, "distortion_model": "equidistant"},
         "camera.json"),
        ({"cameras": [{"K": K_FREIBURG.tolist(), "dist": FISHEYE, "distortion_model": "fov"}]},
         "camera.json camera 1"),
        ({"K1": K_FREIBURG.tolist(), "dist1": FISHEYE, "distortion_model": "Equidistant"},
         "camera.json"),
    ],
    ids=["camera", "cameras", "rig"],
)  # fmt: skip
def test_a_json_fisheye_is_refused_by_name(tmp_path, data, where):
    # its coefficients were read as OpenCV's pinhole k1, k2, p1, p2: a silent wrong camera
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    model = (data.get("cameras") or [data])[0]["distortion_model"]
    with pytest.raises(ValueError, match=f"^distortion_model '{model}' in .*{where} is not "
                                         "OpenCV's pinhole distortion"):  # fmt: skip
        load_calibration(path)


@pytest.mark.parametrize(
    "model, dist",
    [("radtan", DIST[:4]), ("plumb_bob", DIST), ("rational_polynomial", np.r_[DIST, 0.1, 0, 0])],
)
@pytest.mark.parametrize("extension", ["json", "yml"])
def test_opencv_distortion_models_are_read(tmp_path, model, dist, extension):
    path = tmp_path / f"camera.{extension}"
    if extension == "json":
        path.write_text(json.dumps({"distortion_model": model, "K": K_FREIBURG.tolist(),
                                    "dist": dist.tolist()}))  # fmt: skip
    else:
        path.write_text(ROS_CAMERA_INFO.replace("plumb_bob", model).replace(
            "cols: 5\n  data: [-0.2, 0.05, 0.001, -0.002, 0.01]",
            f"cols: {dist.size}\n  data: {dist.tolist()}"))  # fmt: skip
    (camera,) = load_calibration(path)
    np.testing.assert_array_equal(camera.dist, dist)
    np.testing.assert_array_equal(camera.K, K_FREIBURG)


KALIBR_NONE = {
    "json": {"K": K_FREIBURG.tolist(), "distortion_model": "none", "distortion_coeffs": []},
    "json rig": {"K1": K_FREIBURG.tolist(), "distortion_model": "none", "dist1": [0, 0, 0, 0]},
    "yml": ROS_CAMERA_INFO.replace("plumb_bob", "none").replace(
        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.2, 0.05, 0.001, -0.002, 0.01]",
        "distortion_coeffs: []"),
    "yml no coefficients": ROS_CAMERA_INFO.replace("plumb_bob", '""').replace(
        "  data: [-0.2, 0.05, 0.001, -0.002, 0.01]", "  data: [0, 0, 0, 0, 0]"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(KALIBR_NONE))
def test_a_distortion_model_of_none_is_read_as_no_distortion(tmp_path, case):
    # Kalibr's "distortion_model: none" was refused as no OpenCV pinhole distortion
    data = KALIBR_NONE[case]
    path = tmp_path / f"camera.{case.split()[0]}"
    path.write_text(json.dumps(data) if isinstance(data, dict) else data)
    (camera,) = load_calibration(path)
    assert camera.dist is None
    np.testing.assert_array_equal(camera.K, K_FREIBURG)


@pytest.mark.parametrize("extension", ["json", "yml"])
def test_a_distortion_model_of_none_with_coefficients_is_refused(tmp_path, extension):
    path = tmp_path / f"camera.{extension}"
    if extension == "json":
        path.write_text(json.dumps({"K": K_FREIBURG.tolist(), "distortion_model": "none",
                                    "distortion_coeffs": DIST[:4].tolist()}))  # fmt: skip
    else:
        path.write_text(ROS_CAMERA_INFO.replace("plumb_bob", "none"))
    words = r"distortion_model 'none' in .*camera\.(json|yml) says no distortion, but the "
    with pytest.raises(ValueError, match=words + r"coefficients \[-0\.2, .*remove one of the"):
        load_calibration(path)


KALIBR_CAMCHAIN = """cam0:
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
cam1:
  T_cn_cnm1:
  - [0.9999972564779, 0.002312067192424, 0.0003760081024, -0.110073808127187]
  - [-0.002317135723275, 0.999898048507103, 0.014089835846691, 0.000399121547014]
  - [-0.000343393120620, -0.014090668452714, 0.999900662638082, -0.000853702503357]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: pinhole
  distortion_coeffs: [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05]
  distortion_model: radtan
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
"""


@pytest.mark.parametrize("newline", ["\n", "\r\n"], ids=["LF", "CRLF"])
def test_a_kalibr_camchain_is_read_camera_by_camera(tmp_path, newline):
    # OpenCV's YAML parser failed on its T_cn_cnm1 lists: "malformed OpenCV calibration file
    # camchain.yaml: skipSpaces ... Incorrect indentation"
    path = tmp_path / "camchain.yaml"
    path.write_bytes(KALIBR_CAMCHAIN.replace("\n", newline).encode())
    first, second = load_calibration(path)
    K = [[458.654, 0, 367.215], [0, 457.296, 248.375], [0, 0, 1]]
    np.testing.assert_array_equal(first.K, K)
    np.testing.assert_array_equal(first.dist, [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-5])
    np.testing.assert_array_equal(second.K[:2, 2], [379.999, 255.238])
    assert first.image_size == second.image_size == (752, 480)
    one = KALIBR_CAMCHAIN.split("cam1:")[0].replace("radtan", "none")
    path.write_text(one.replace("[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]", "[]"))
    (camera,) = load_calibration(path)
    assert camera.dist is None and camera.K[0, 0] == 458.654


@pytest.mark.parametrize(
    "change, words",
    [(("pinhole", "omni"), "camera_model 'omni' in .*camchain.yaml cam0 is not a pinhole camera"),
     (("radtan", "equidistant"), "distortion_model 'equidistant' in .*cam0 is not OpenCV's"),
     (("[752, 480]", "[752]"), r"cam0: resolution must be \[width, height\], got \[752.0\]"),
     (("[458.654, 457.296,", "[458.654, x,"), "cam0: intrinsics must be numbers"),
     (("intrinsics: [458.654, 457.296, 367.215, 248.375]",
       "intrinsics:\n  - 458.654\n  - 457.296\n  - 367.215\n  - 248.375"),
      r"cam0: intrinsics must be a list of numbers on its line, \[a, b, ...\], got ''")],
    ids=["omnidirectional", "fisheye", "resolution", "intrinsics", "block list"],
)  # fmt: skip
def test_a_kalibr_camera_this_reader_cannot_take_is_refused_by_name(tmp_path, change, words):
    path = tmp_path / "camchain.yaml"
    path.write_text(KALIBR_CAMCHAIN.replace(*change, 1))
    with pytest.raises(ValueError, match=words):
        load_calibration(path)


def _photo_of_35mm_focal(path, focal_35mm: int) -> None:
    from PIL import Image

    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Maker", "Model"
    exif.get_ifd(0x8769)[0xA405] = focal_35mm  # FocalLengthIn35mmFilm
    texture = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    Image.fromarray(texture).save(path, exif=exif)


@pytest.mark.parametrize("focal_35mm, field", [(65535, "0.0303"), (1, "173")])
def test_an_exif_focal_length_that_is_none_is_not_used(tmp_path, focal_35mm, field):
    # 65535 mm (a placeholder) gave f = 1.2 million px, used with a warning of the field only
    from ppo_cv.cli.common import exif_camera

    path = tmp_path / "photo.jpg"
    _photo_of_35mm_focal(path, focal_35mm)
    with pytest.warns(calib.ImplausibleCameraWarning) as caught:
        camera, from_exif = camera_from_exif(path)
    assert not from_exif
    np.testing.assert_array_equal(camera.K, [[768, 0, 320], [0, 768, 240], [0, 0, 1]])
    (message,) = [str(w.message) for w in caught]
    assert message.startswith(f"{path}: the EXIF focal length f=")
    assert f"gives a {field} deg field of view across 640 px, outside 0.5..150 deg" in message
    assert "not used, guessing f=768.0 px (1.2 x image size)" in message
    K, found, doubts = exif_camera(path)
    assert not found and doubts == [message]
    np.testing.assert_array_equal(K, camera.K)


def test_the_exif_field_bounds_and_both_exif_checks_share_one_field_of_view(tmp_path):
    # the CLI's warning and calib's refusal each computed the field of view themselves
    from ppo_cv.cli.common import exif_camera

    low, high = calib.EXIF_PLAUSIBLE_FIELD_DEG
    assert calib.EXIF_FIELD_RANGE_DEG[0] < low < high < calib.EXIF_FIELD_RANGE_DEG[1]
    assert calib.field_of_view_deg(18.0, 36.0) == pytest.approx(90.0)
    assert calib.field_of_view_deg(50.0, 36.0) == pytest.approx(39.5978, abs=1e-4)  # 50 mm
    path = tmp_path / "photo.jpg"
    _photo_of_35mm_focal(path, 200)  # a 200 mm equivalent: about 10 deg across
    K, found, doubts = exif_camera(path)
    field = calib.field_of_view_deg(K[0, 0], 640)
    assert found and 5 < field < low
    assert doubts == [
        f"{path}: the EXIF focal length f={K[0, 0]:.1f} px gives a {field:.1f} deg horizontal "
        f"field of view at 640 px wide, outside {low:g}..{high:g} deg; pass --K or --calib"
    ]
    assert calib.unusable_exif_focal(K[0, 0], 640) is None
    assert f"a {calib.field_of_view_deg(65535 / 36 * 640, 640):.3g} deg field" in (
        calib.unusable_exif_focal(65535 / 36 * 640, 640)
    )


def test_the_focal_length_put_in_place_of_an_unusable_one_is_colmaps_guess(tmp_path):
    from PIL import Image

    path = tmp_path / "plain.png"  # no EXIF: pycolmap guesses the focal length itself
    Image.fromarray(np.zeros((480, 640, 3), np.uint8)).save(path)
    camera, from_exif = camera_from_exif(path)
    assert not from_exif and camera.K[0, 0] == calib.GUESSED_FOCAL_FACTOR * 640


@pytest.mark.parametrize("focal_35mm", [10, 3000])
def test_an_exif_focal_length_of_a_real_lens_is_used(tmp_path, focal_35mm):
    path = tmp_path / "photo.jpg"
    _photo_of_35mm_focal(path, focal_35mm)
    camera, from_exif = camera_from_exif(path)
    assert from_exif
    expected = focal_35mm / np.hypot(36.0, 24.0) * np.hypot(640.0, 480.0)
    np.testing.assert_allclose(camera.K[0, 0], expected, rtol=1e-3)


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("camera.yml", "%YAML:1.0\n---\nimage_width: 640\n"
                       "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n",
         "image_width without image_height"),
        ("camera.xml", '<?xml version="1.0"?>\n<opencv_storage><image_height>480</image_height>'
                       "<camera_matrix>500 0 320 0 500 240 0 0 1</camera_matrix>"
                       "</opencv_storage>\n", "image_height without image_width"),
        ("camera.json", '{"K": [500, 500, 320, 240], "width": 640}', "width without height"),
        ("camera.json", '{"K1": [500, 500, 320, 240], "height": 480}', "height without width"),
    ],
)  # fmt: skip
def test_an_image_width_without_its_height_is_refused(tmp_path, name, text, message):
    # YAML dropped the size silently, and a camera of other images was not fitted to the image
    (tmp_path / name).write_text(text)
    with pytest.raises(ValueError, match=f"{name}: {message}; give both .* or neither$"):
        load_calibration(tmp_path / name)


@pytest.mark.parametrize(
    "text, field",
    [("535.4 539.2; x, 247.6", "field 3 of 4 is 'x'"), ("535,4,539,2,320,1,247,6o", "field 8 of 8 "
     "is '6o'"), ("[[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, one]]", "field 9 of 9 is 'one'")],
)  # fmt: skip
def test_intrinsics_that_are_no_numbers_name_the_field_and_the_separators(text, field):
    # "--K must be comma-separated numbers", though spaces and semicolons are read too
    with pytest.raises(ValueError, match=f"^--K must be numbers separated by commas, spaces or "
                                         f"semicolons: {field}$"):  # fmt: skip
        parse_intrinsics(text, "--K")


def test_colmap_parameters_that_are_no_numbers_name_the_field(tmp_path):
    path = tmp_path / "cameras.txt"
    path.write_text("1 PINHOLE 640 480 500 x 320 240\n")
    message = r"cameras.txt:1: PARAMS must be numbers separated by .*: field 2 of 4 is 'x'$"
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


@pytest.mark.parametrize("name", ["camera.json", "cameras.txt"])
@pytest.mark.parametrize("text", ["", "\n \n", "\ufeff"])
def test_an_empty_calibration_file_is_called_empty(tmp_path, name, text):
    # an empty .json said "is not valid JSON: Expecting value (line 1)"
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=f"^calibration file .*{name} is empty$"):
        load_calibration(path)


@pytest.mark.parametrize("text", ["535,4,539,2", "4,535,320,240", "535.4,100,320.1,247.6"])
def test_focal_lengths_no_camera_has_are_refused_with_the_likely_typo(text):
    # "535,4,539,2" (decimal commas) was read as fx 535, fy 4 and posed behind a warning
    with pytest.raises(ValueError, match=r"^--K gives fx=.* which no camera has \(a decimal comma"):
        parse_intrinsics(text, "--K")


def test_an_anamorphic_pixel_is_still_a_camera():
    K = parse_intrinsics("1070.8,535.4,640,360", "--K")
    assert K[0, 0] / K[1, 1] == pytest.approx(2.0)


# A phone's photo: 4000x3000 pixels on a 6.4 mm wide sensor (625 px/mm), a 4 mm lens: f = 2500
# px at the camera's size, 400 px in a copy of 640x480 (0.16 of it), a 77 deg field across.
PHONE_FOCAL_MM, PHONE_PX_PER_MM, PHONE_SIZE = 4.0, 625.0, (4000, 3000)
PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0}  # FocalPlaneResolutionUnit: inch, cm, mm


def _phone_photo(path, size=(640, 480), *, recorded=PHONE_SIZE, unit=3, focal_35mm=None,
                 orientation=None, focal_plane=True) -> None:  # fmt: skip
    """A black JPEG of ``size`` (width, height) with the EXIF of :data:`PHONE_FOCAL_MM`."""
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Maker", "Model"
    if orientation is not None:
        exif[0x0112] = orientation
    sub = exif.get_ifd(0x8769)
    if focal_plane:
        sub[0x920A] = IFDRational(PHONE_FOCAL_MM)  # FocalLength, mm
        resolution = IFDRational(PHONE_PX_PER_MM * PER_UNIT[unit])
        sub[0xA20E], sub[0xA20F], sub[0xA210] = resolution, resolution, unit
    if recorded is not None:
        sub[0xA002], sub[0xA003] = recorded  # PixelXDimension, PixelYDimension
    if focal_35mm is not None:
        sub[0xA405] = focal_35mm
    Image.fromarray(np.zeros((size[1], size[0], 3), np.uint8)).save(path, exif=exif)


@pytest.mark.parametrize("unit", [2, 3, 4], ids=["inch", "cm", "mm"])
def test_the_sensor_focal_length_of_a_resized_photo_is_scaled_to_its_pixels(tmp_path, unit):
    # pycolmap's FocalLength x FocalPlaneXResolution is in the camera's pixels: 2500 px for a
    # copy of 640 px, a 14.6 deg field for a 77 deg one
    from ppo_cv.cli.common import exif_camera

    path = tmp_path / "resized.jpg"
    _phone_photo(path, unit=unit)
    camera, from_exif = camera_from_exif(path)
    assert from_exif
    np.testing.assert_allclose(np.diag(camera.K)[:2], 400.0, rtol=1e-4)
    np.testing.assert_allclose(camera.K[:2, 2], [320.0, 240.0])
    K, found, doubts = exif_camera(path)
    low, high = calib.EXIF_PLAUSIBLE_FIELD_DEG
    assert found and low < calib.field_of_view_deg(K[0, 0], 640) < high
    assert doubts == [
        f"{path}: the EXIF says the photo was 4000x3000 pixels, the image is 640x480, a resized "
        "copy: its EXIF focal length, in the original's pixels, is scaled by 0.16 to f=400.0 px "
        "(not right if it was cropped too; pass --K or --calib)"
    ]


@pytest.mark.parametrize("orientation, stored", [(6, (640, 480)), (None, (480, 640))],
                         ids=["turned by its orientation", "turned pixels"])  # fmt: skip
def test_a_resized_photo_turned_upright_is_scaled_by_its_own_sides(tmp_path, orientation, stored):
    path = tmp_path / "resized.jpg"
    _phone_photo(path, stored, orientation=orientation)
    camera, _ = camera_from_exif(path)
    np.testing.assert_allclose(np.diag(camera.K)[:2], 400.0, rtol=1e-4)
    np.testing.assert_allclose(camera.K[:2, 2], [240.0, 320.0])


@pytest.mark.parametrize("recorded", [PHONE_SIZE, None, (640, 480)],
                         ids=["resized", "no recorded size", "the camera's size"])  # fmt: skip
def test_a_35mm_equivalent_is_read_on_the_image_and_never_scaled(tmp_path, recorded):
    # pycolmap reads it before the sensor's tags, on the image's own diagonal: a resized copy
    # keeps it true, and a warning that its focal length may not fit said what was not so
    from ppo_cv.cli.common import exif_camera

    path = tmp_path / "photo.jpg"
    _phone_photo(path, recorded=recorded, focal_35mm=28)
    camera, _ = camera_from_exif(path)
    np.testing.assert_allclose(camera.K[0, 0], 28 / np.hypot(36, 24) * 800, rtol=1e-4)
    assert exif_camera(path)[2] == []


def test_the_sensor_focal_length_is_kept_at_the_cameras_size_or_without_a_recorded_one(
    tmp_path,
):
    for recorded in ((640, 480), None):
        path = tmp_path / f"{recorded}.jpg"
        _phone_photo(path, recorded=recorded)
        np.testing.assert_allclose(camera_from_exif(path)[0].K[0, 0], 2500.0, rtol=1e-4)


@pytest.mark.parametrize("focal_35mm", [None, 28], ids=["sensor focal", "35 mm equivalent"])
def test_a_cropped_photos_focal_length_is_not_scaled_but_doubted(tmp_path, focal_35mm):
    from ppo_cv.cli.common import exif_camera

    path = tmp_path / "square.jpg"
    _phone_photo(path, (480, 480), focal_35mm=focal_35mm)
    expected = 2500.0 if focal_35mm is None else 28 / np.hypot(36, 24) * np.hypot(480, 480)
    np.testing.assert_allclose(camera_from_exif(path)[0].K[0, 0], expected, rtol=1e-4)
    assert exif_camera(path)[2][0] == (
        f"{path}: the EXIF says the photo was 4000x3000 pixels, the image is 480x480, another "
        "aspect ratio (cropped?), so its EXIF focal length may not fit; pass --K or --calib"
    )


def test_exif_focal_scale_and_resize_scale():
    from ppo_cv.images import ExifLayout

    assert calib.resize_scale((4000, 3000), (1600, 1200)) == 0.4
    assert calib.resize_scale((3000, 4000), (1600, 1200)) == 0.4
    assert calib.resize_scale((4000, 3000), (1600, 1600)) is None
    scale = calib.exif_focal_scale
    assert scale(ExifLayout(None, (4000, 3000), None, True), (1600, 1200)) == 0.4
    assert scale(ExifLayout(None, (4000, 3000), 28.0, True), (1600, 1200)) == 1.0
    assert scale(ExifLayout(None, (4000, 3000), None, False), (1600, 1200)) == 1.0
    assert scale(ExifLayout(None, None, None, True), (1600, 1200)) == 1.0
    assert scale(ExifLayout(None, (4000, 3000), None, True), (1600, 1600)) == 1.0
    assert scale(ExifLayout(None, (720, 540), None, True, (2272, 1704)), (540, 720)) == 720 / 2272
    assert scale(ExifLayout(None, None, None, True, (2272, 1704)), (720, 540)) == 720 / 2272
    assert scale(ExifLayout(None, (4000, 3000), None, True, (640, 480)), (1600, 1200)) == 0.4


def test_a_focal_length_from_pycolmaps_table_of_sensors_is_never_scaled(tmp_path):
    # without FocalPlaneXResolution pycolmap takes the sensor's width from its table (a Canon
    # PowerShot S45: 7.18 mm) and multiplies by the image's own size: right for a resized copy
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    from ppo_cv.cli.common import exif_camera
    from ppo_cv.images import exif_layout

    path = tmp_path / "s45.jpg"
    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Canon", "Canon PowerShot S45"
    sub = exif.get_ifd(0x8769)
    sub[0x920A], sub[0xA002], sub[0xA003] = IFDRational(12.28125), 2272, 1704
    Image.fromarray(np.zeros((540, 720, 3), np.uint8)).save(path, exif=exif)
    layout = exif_layout(path)
    assert layout.pixel_size == (2272, 1704) and not layout.sensor_resolution
    camera, from_exif = camera_from_exif(path)
    assert from_exif and 1200 < camera.K[0, 0] < 1290  # 12.28 / 7.18 x 720 = 1231.5
    assert exif_camera(path)[2] == []


@pytest.mark.parametrize(
    "call, error, words",
    [(lambda: calib.resize_scale((0, 0), (1600, 1200)), ValueError,
      "original width must be a whole number in 1.."),
     (lambda: calib.resize_scale((4000, 3000), None), TypeError,
      "size must be (width, height), got None"),
     (lambda: calib.warn_implausible(np.diag([500.0, 500.0, 1.0]), "480x640", "K"), TypeError,
      "image_shape must be an image's shape (rows, columns[, channels]), got '480x640'"),
     (lambda: calib.warn_implausible(np.diag([500.0, 500.0, 1.0]), (480,), "K"), TypeError,
      "image_shape must be an image's shape")],
    ids=["resize from zero", "resize to None", "shape text", "shape of one side"],
)  # fmt: skip
def test_the_size_helpers_name_a_size_that_is_none(call, error, words):
    # a ZeroDivisionError, "'NoneType' object is not iterable", "string index out of range",
    # "tuple index out of range"
    with pytest.raises(error) as info:
        call()
    assert words in str(info.value)


# A Canon PowerShot S45's photo (2272x1704, 12.28 mm at 8114.29 px per inch of its sensor: f =
# 3923 px) resized to 720x540 by a resizer that wrote the copy's own size in PixelXDimension and
# PixelYDimension and left the interoperability tags' RelatedImageWidth and RelatedImageLength.
S45_FOCAL_MM, S45_PX_PER_INCH, S45_SIZE = 12.28125, 8114.285714, (2272, 1704)
S45_FOCAL_PX = S45_FOCAL_MM * S45_PX_PER_INCH / 25.4


def _s45_photo(path, size=(720, 540), *, recorded=(720, 540), related=S45_SIZE,
               focal_35mm=None) -> None:  # fmt: skip
    """A black JPEG of ``size`` (width, height) with the EXIF of a resized S45 photo."""
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Canon", "Canon PowerShot S45"
    sub = exif.get_ifd(0x8769)
    resolution = IFDRational(S45_PX_PER_INCH)
    sub[0x920A], sub[0xA20E], sub[0xA20F], sub[0xA210] = (IFDRational(S45_FOCAL_MM),
                                                          resolution, resolution, 2)  # fmt: skip
    if recorded is not None:
        sub[0xA002], sub[0xA003] = recorded  # PixelXDimension, PixelYDimension
    if focal_35mm is not None:
        sub[0xA405] = focal_35mm
    if related is not None:
        sub[0xA005] = {0x1001: related[0], 0x1002: related[1]}  # RelatedImageWidth, Length
    Image.fromarray(np.zeros((size[1], size[0], 3), np.uint8)).save(path, exif=exif)


@pytest.mark.parametrize("recorded", [(720, 540), (540, 720), None],
                         ids=["rewritten", "rewritten turned", "dropped"])  # fmt: skip
def test_a_resized_photo_whose_pixel_dimensions_were_rewritten_is_scaled_by_its_related_size(
    tmp_path, recorded
):
    # the copy's own size in PixelXDimension left the original's 3923 px, a 10.5 deg field for a
    # 32 deg one; the interoperability tags keep the 2272 px the camera wrote
    from ppo_cv.cli.common import exif_camera
    from ppo_cv.images import exif_layout

    path = tmp_path / "csie.jpg"
    _s45_photo(path, recorded=recorded)
    camera, from_exif = camera_from_exif(path)
    assert from_exif
    np.testing.assert_allclose(camera.K[0, 0], S45_FOCAL_PX * 720 / 2272, rtol=1e-4)  # 1243.3
    layout = exif_layout(path)
    assert layout.related_size == S45_SIZE and layout.camera_size == S45_SIZE
    K, found, doubts = exif_camera(path)
    written = "say 720x540, rewritten by a resizer" if recorded == (720, 540) else (
        "say 540x720, rewritten by a resizer" if recorded else "are missing")  # fmt: skip
    assert found and doubts == [
        f"{path}: the EXIF's RelatedImageWidth and RelatedImageLength say the camera wrote "
        f"2272x1704 pixels (PixelXDimension and PixelYDimension {written}), the image is "
        f"720x540, a resized copy: its EXIF focal length, in the original's pixels, is scaled by "
        f"0.3169 to f={K[0, 0]:.1f} px (not right if it was cropped too; pass --K or --calib)"
    ]


@pytest.mark.parametrize(
    "size, recorded, related, focal_35mm, expected",
    [(S45_SIZE, S45_SIZE, S45_SIZE, None, S45_FOCAL_PX),
     (S45_SIZE, S45_SIZE, None, None, S45_FOCAL_PX),
     ((720, 540), S45_SIZE, (720, 540), None, S45_FOCAL_PX * 720 / 2272),
     ((720, 540), (720, 540), S45_SIZE, 38, 38 / np.hypot(36, 24) * 900)],
    ids=["the camera's file", "no related size", "a smaller related size", "35 mm equivalent"],
)  # fmt: skip
def test_a_related_size_that_tells_no_resize_leaves_the_focal_length(
    tmp_path, size, recorded, related, focal_35mm, expected
):
    from ppo_cv.cli.common import exif_camera

    path = tmp_path / "photo.jpg"
    _s45_photo(path, size, recorded=recorded, related=related, focal_35mm=focal_35mm)
    np.testing.assert_allclose(camera_from_exif(path)[0].K[0, 0], expected, rtol=1e-4)
    doubts = exif_camera(path)[2]
    assert not any("RelatedImageWidth" in doubt for doubt in doubts)
