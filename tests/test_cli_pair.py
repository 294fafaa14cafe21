"""``ppo-cv pair``, ``demo`` and ``pairs`` through typer's runner and as a subprocess."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from ppo_cv.cli.main import app
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
DEMO1, DEMO2 = str(DATA / DEMO["image1"]), str(DATA / DEMO["image2"])
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
FX, FY, CX, CY = DEMO["intrinsics"]
COLMAP_CAMERA = f"1 PINHOLE 640 480 {FX} {FY} {CX + 0.5} {CY + 0.5}\n"  # COLMAP's pixels
REQUIRED_KEYS = {
    "R",
    "t",
    "pure_rotation",
    "pri",
    "num_matches",
    "num_inliers",
    "num_points",
    "model",
    "cameras",
    "uncertainty",
    "lens",
    "evidence",
    "plane",
    "timings",
    "translation_determined",
}

runner = CliRunner()


def check_demo_pose(data):
    R, t = np.array(data["R"]), np.array(data["t"])
    assert rotation_error_deg(R, np.array(DEMO["reference_R"])) < 1.0
    assert direction_error_deg(t, np.array(DEMO["reference_t"]), signed=False) < 3.0


def read_ply(path):
    raw = Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    header = raw[:end].decode("ascii").splitlines()
    assert header[0] == "ply" and header[1] == "format binary_little_endian 1.0"
    count = int(next(line for line in header if line.startswith("element vertex")).split()[-1])
    dtype = np.dtype(
        [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")]
    )
    return np.frombuffer(raw[end:], dtype=dtype, count=count)


@pytest.fixture(scope="module")
def demo_json():
    result = runner.invoke(app, ["pair", "--json"])
    assert result.exit_code == 0, result.output
    return result


def test_no_arguments_runs_the_demo_pair(demo_json):
    data = json.loads(demo_json.stdout)
    assert REQUIRED_KEYS <= set(data)
    check_demo_pose(data)
    assert not data["pure_rotation"] and data["translation_determined"]
    # the demo pair translates: its rotation is the essential matrix's, with its deviation;
    # a 60 degree field holds it within a tenth of a degree wherever its radial term goes
    assert data["rotation_source"] == "essential"
    assert 0.0 < data["uncertainty"]["rotation_bias_deg"] < 0.1
    assert 0.0 < data["uncertainty"]["rotation_sigma_deg"] < 1.0
    assert data["num_inliers"] >= 100 and data["num_points"] > 0
    assert np.allclose(data["cameras"]["K1"], [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]])


def test_human_summary(tmp_path):
    result = runner.invoke(app, ["pair", DEMO1, DEMO2, "--K", K_TEXT])
    assert result.exit_code == 0, result.output
    for word in ("rotation", "euler", "translation", "PRI", "general motion", "inliers", "ransac"):
        assert word in result.stdout
    assert "R source     the essential matrix's refined pose" in result.stdout
    sigma_line = r"R sigma      \d+\.\d{3} deg \(rotation angle error, root mean square\)"
    assert re.search(sigma_line, result.stdout)


def test_demo_command_matches_pair_without_arguments(demo_json):
    result = runner.invoke(app, ["demo", "--json"])
    assert result.exit_code == 0, result.output
    assert np.allclose(json.loads(result.stdout)["R"], json.loads(demo_json.stdout)["R"])


def test_subprocess_json_is_the_only_stdout():
    exe = shutil.which("ppo-cv")
    command = [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]
    out = subprocess.run(
        [*command, "pair", DEMO1, DEMO2, "--K", K_TEXT, "--K2", K_TEXT, "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert REQUIRED_KEYS <= set(data)
    check_demo_pose(data)


def _pair_with_stderr_on_a_terminal(*options: str) -> tuple[int, str]:
    """``ppo-cv pair`` on the demo images, stderr a pseudo-terminal: exit code and its text."""
    import pty

    exe = shutil.which("ppo-cv")
    command = [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]
    reader, writer = pty.openpty()
    process = subprocess.Popen(
        [*command, "pair", DEMO1, DEMO2, "--K", K_TEXT, "--json", *options],
        stdout=subprocess.DEVNULL,
        stderr=writer,
        env={**os.environ, "TERM": "xterm", "COLUMNS": "100"},
    )
    os.close(writer)
    chunks = []
    while True:
        try:
            chunk = os.read(reader, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(reader)
    return process.wait(timeout=120), b"".join(chunks).decode("utf-8", "replace")


def test_a_single_pair_shows_its_stage_on_a_terminal_only():
    code, shown = _pair_with_stderr_on_a_terminal()
    assert code == 0
    assert "ppo-cv pair:" in shown and " done" in shown
    code, shown = _pair_with_stderr_on_a_terminal("--quiet")
    assert code == 0 and shown == ""


def test_a_single_pair_prints_nothing_on_stderr_read_by_a_script():
    exe = shutil.which("ppo-cv")
    command = [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]
    out = subprocess.run(
        [*command, "pair", DEMO1, DEMO2, "--K", K_TEXT, "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0 and out.stderr == ""


def test_out_directory_files_open(tmp_path):
    import pycolmap

    out = tmp_path / "result"
    result = runner.invoke(app, ["pair", DEMO1, DEMO2, "--K", K_TEXT, "--out", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads((out / "result.json").read_text())
    check_demo_pose(data)
    points = read_ply(out / "points.ply")
    assert len(points) == data["num_points"] > 0
    assert np.all(points["z"] > 0) and points["red"].std() > 0
    matches = cv2.imread(str(out / "matches.png"))
    assert matches.shape[1:] == (1280, 3) and matches.shape[0] > 480  # legend underneath
    model = pycolmap.Reconstruction(str(out / "colmap"))
    assert model.num_images() == 2 and model.num_points3D() == data["num_points"]
    image2 = model.find_image_with_name(Path(DEMO2).name)
    pose = image2.cam_from_world()
    pose = pose() if callable(pose) else pose
    np.testing.assert_allclose(pose.rotation.matrix(), np.array(data["R"]), atol=1e-9)
    assert model.compute_mean_reprojection_error() < 1.0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_calibration_file_and_distortion_options(tmp_path):
    calib = tmp_path / "cameras.txt"
    calib.write_text(COLMAP_CAMERA)
    result = runner.invoke(app, ["pair", DEMO1, DEMO2, "--calib", str(calib), "--json"])
    assert result.exit_code == 0, result.output
    check_demo_pose(json.loads(result.stdout))
    result = runner.invoke(
        app, ["pair", DEMO1, DEMO2, "--K", K_TEXT, "--dist", "0,0,0,0", "--json"]
    )
    assert result.exit_code == 0, result.output


def test_missing_intrinsics_fall_back_to_exif_with_a_warning():
    result = runner.invoke(app, ["pair", DEMO1, DEMO2, "--json"])
    assert result.exit_code == 0, result.output
    assert "warning:" in result.stderr and "no intrinsics" in result.stderr
    assert np.allclose(json.loads(result.stdout)["cameras"]["K1"][0][0], 768.0)


def _phone_jpeg(source, path, orientation: int) -> None:
    """The demo frame as a phone stores it: pixels turned a quarter when ``orientation`` is 6
    (shown upright by turning them back), a 28 mm equivalent focal length."""
    from PIL import Image

    image = Image.open(source).convert("RGB")
    if orientation == 6:
        image = image.transpose(Image.Transpose.ROTATE_90)
    exif = Image.Exif()
    exif[0x010F], exif[0x0110], exif[0x0112] = "Maker", "Model", orientation
    exif.get_ifd(0x8769)[0xA405] = 28
    image.save(path, quality=95, exif=exif.tobytes())


def test_exif_orientation_gives_the_camera_of_the_upright_image(tmp_path):
    runs = {}
    for orientation in (1, 6):
        paths = [tmp_path / f"{orientation}_{k}.jpg" for k in (1, 2)]
        for source, path in zip((DEMO1, DEMO2), paths, strict=True):
            _phone_jpeg(source, path, orientation)
        result = runner.invoke(app, ["pair", *map(str, paths), "--json"])
        assert result.exit_code == 0, result.output
        runs[orientation] = json.loads(result.stdout)
    assert cv2.imread(str(tmp_path / "6_1.jpg")).shape == (480, 640, 3)
    upright, turned = runs[1], runs[6]
    np.testing.assert_allclose(turned["cameras"]["K1"], upright["cameras"]["K1"])
    np.testing.assert_allclose(np.array(turned["cameras"]["K1"])[:2, 2], [320.0, 240.0])
    check_demo_pose(turned)
    assert rotation_error_deg(turned["R"], upright["R"]) < 0.3


def test_a_calibration_of_the_pixels_as_stored_names_the_exif_orientation(tmp_path):
    """A phone calibrated in landscape and a photo taken upright: its pixels are stored as the
    calibration describes them (480x640) and shown turned (640x480). The refusal names the
    EXIF orientation and the way out, which poses the pair in the stored pixels' frame."""
    paths = [tmp_path / f"{k}.jpg" for k in (1, 2)]
    for source, path in zip((DEMO1, DEMO2), paths, strict=True):
        _phone_jpeg(source, path, 6)
    fx, fy, cx, cy = DEMO["intrinsics"]
    calib = tmp_path / "phone.yml"
    storage = cv2.FileStorage(str(calib), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 480)
    storage.write("image_height", 640)
    storage.write("camera_matrix", np.array([[fy, 0, cy], [0, fx, 639 - cx], [0, 0, 1]]))
    storage.write("distortion_coefficients", np.zeros(5))
    storage.release()
    args = ["pair", *map(str, paths), "--calib", str(calib), "--json"]
    refused = runner.invoke(app, args)
    assert refused.exit_code == 2 and refused.stdout == ""
    assert refused.stderr.strip() == (
        f"ppo-cv pair: --calib {calib} describes a camera of 480x640 images, the pixels of "
        f"{paths[0]} as stored (480x640), but its EXIF orientation turns them upright to "
        "640x480: --no-exif-orientation (or exif_orientation=False) reads them as stored, as "
        "the calibration describes them"
    )
    stored = runner.invoke(app, [*args, "--no-exif-orientation"])
    assert stored.exit_code == 0, stored.output
    data = json.loads(stored.stdout)
    assert data["cameras"]["image_size1"] == [480, 640]
    upright = runner.invoke(app, ["pair", DEMO1, DEMO2, "--K", K_TEXT, "--json"])
    turn = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # upright to stored axes
    R_upright = np.array(json.loads(upright.stdout)["R"])
    assert rotation_error_deg(data["R"], turn @ R_upright @ turn.T) < 0.3


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    text = root / "notes.png"
    text.write_text("this is not an image\n")
    blank = root / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640, 3), 127, np.uint8))
    noise = root / "noise.png"
    rng = np.random.default_rng(0)
    cv2.imwrite(
        str(noise), cv2.GaussianBlur(rng.integers(0, 256, (480, 640, 3), np.uint8), (0, 0), 2)
    )
    copy = root / "copy.png"
    shutil.copy(DEMO1, copy)
    return {
        "text": str(text),
        "blank": str(blank),
        "noise": str(noise),
        "copy": str(copy),
        "missing": str(root / "absent.png"),
    }


@pytest.mark.parametrize(
    "args, message",
    [
        (["{missing}", DEMO2, "--K", K_TEXT], "image not found"),
        (["{text}", DEMO2, "--K", K_TEXT], "not a readable image"),
        ([DEMO1, "{copy}", "--K", K_TEXT], "identical"),
        ([DEMO1, DEMO2, "--K", "535.4,539.2,320.1"], "--K must be 4 numbers"),
        ([DEMO1, DEMO2, "--K", "a,b,c,d"], "--K must be numbers separated by commas, spaces or "
         "semicolons: field 1 of 4 is 'a'"),
        ([DEMO1, DEMO2, "--K", K_TEXT, "--dist", "0.1,0.2,0.3"], "--dist must be"),
        ([DEMO1, DEMO2, "--calib", "{missing}"], "calibration file not found"),
        ([DEMO1, DEMO2, "--K", K_TEXT, "--features", "surf"], "unknown features"),
        ([DEMO1], "give two images"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, bad_files, args, message):
    import re

    out = tmp_path / "out"
    args = [a.format(**bad_files) for a in args]
    result = runner.invoke(app, ["pair", *args, "--out", str(out)])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ppo-cv pair: ")
    assert re.search(message, lines[0])
    assert "Traceback" not in result.output and result.stdout == ""
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_bad_input_as_subprocess_has_no_traceback(bad_files):
    exe = shutil.which("ppo-cv")
    command = [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]
    out = subprocess.run(
        [*command, "pair", bad_files["text"], DEMO2, "--K", K_TEXT],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "not a readable image" in out.stderr
    assert out.stdout == ""


def test_pairs_with_ground_truth_prints_auc(tmp_path, freiburg):
    lines = (freiburg / "pairs_with_gt.txt").read_text().splitlines()[:3]
    pairs_file = tmp_path / "pairs.txt"
    pairs_file.write_text("\n".join(lines) + "\n")
    output = tmp_path / "poses.jsonl"
    result = runner.invoke(
        app,
        [
            "pairs",
            str(pairs_file),
            str(freiburg / "images"),
            "--output",
            str(output),
            "--workers",
            "2",
        ],
    )
    assert result.exit_code == 0, result.output
    rows = [json.loads(line) for line in output.read_text().splitlines()]
    assert [r["image1"] for r in rows] == [line.split()[0] for line in lines]
    errors = [max(r["R_err_deg"], r["t_err_deg"]) for r in rows]
    assert max(errors) < 5.0
    assert "AUC@5" in result.stdout and "| 3 | 0 |" in result.stdout


def test_pairs_without_intrinsics_guesses_them_as_pair_does(tmp_path):
    pairs_file = tmp_path / "pairs.txt"
    pairs_file.write_text(f"{Path(DEMO1).name} {Path(DEMO2).name}\n")
    result = runner.invoke(app, ["pairs", str(pairs_file), str(DATA), "--workers", "1"])
    assert result.exit_code == 0, result.output
    (row,) = [json.loads(line) for line in result.stdout.splitlines()]
    # no EXIF in the PNGs: 1.2 x the larger side
    assert np.allclose(row["cameras"]["K1"][0][0], 768.0)
    assert "warning: no intrinsics given" in result.stderr and "pass --K" in result.stderr
    result = runner.invoke(
        app, ["pairs", str(pairs_file), str(DATA), "--K", K_TEXT, "--workers", "1"]
    )
    assert result.exit_code == 0, result.output
    (row,) = [json.loads(line) for line in result.stdout.splitlines()]
    check_demo_pose(row)
    assert "AUC" not in result.output


def test_pairs_reports_failures_per_line(tmp_path):
    pairs_file = tmp_path / "pairs.txt"
    pairs_file.write_text(f"{Path(DEMO1).name} missing.png\n")
    result = runner.invoke(
        app, ["pairs", str(pairs_file), str(DATA), "--K", K_TEXT, "--workers", "1"]
    )
    assert result.exit_code == 1  # no pair has a pose
    (row,) = [json.loads(line) for line in result.stdout.splitlines()]
    assert "image not found" in row["error"]


def test_demo_data_is_attributed():
    text = (DATA / "DEMO.md").read_text()
    assert "TUM RGB-D" in text and "CC BY 4.0" in text
    assert os.path.getsize(DEMO1) > 0 and cv2.imread(DEMO1).shape == (480, 640, 3)


@pytest.mark.parametrize("name", ["result.json", "points.PLY", "pose.txt"])
def test_an_out_named_as_a_file_is_refused_before_the_run(tmp_path, name):
    # --out result.json wrote a folder named result.json holding result.json
    result = runner.invoke(app, ["pair", DEMO1, DEMO2, "--K", K_TEXT, "--out",
                                 str(tmp_path / name)])  # fmt: skip
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == (
        f"ppo-cv pair: --out takes a folder, and {tmp_path / name} names a file: the folder "
        "receives result.json, points.ply, matches.png and a COLMAP model; --json > "
        "result.json writes the JSON object alone\n"
    )
    assert list(tmp_path.iterdir()) == []
    (tmp_path / name).mkdir()  # a folder so named is one
    replaced = runner.invoke(app, ["pair", DEMO1, DEMO2, "--K", K_TEXT, "--out",
                                   str(tmp_path / name), "--quiet"])  # fmt: skip
    assert replaced.exit_code == 0 and (tmp_path / name / "result.json").is_file()
