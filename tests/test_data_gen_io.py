"""Datasets on disk and the ``ppo-cv synth`` command."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from ppo_cv.cli.main import app
from ppo_cv.data_gen import PAIRS_FILE, make_dataset, make_pair, read_pairs

SMALL = (160, 120)


def _files(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}  # fmt: skip


def test_same_seed_same_bytes(tmp_path):
    a = make_dataset(tmp_path / "a", pairs=3, motion="general", seed=5, size=SMALL, workers=1)
    b = make_dataset(tmp_path / "b", pairs=3, motion="general", seed=5, size=SMALL, workers=2)
    c = make_dataset(tmp_path / "c", pairs=3, motion="general", seed=6, size=SMALL, workers=1)
    files_a, files_b, files_c = _files(a), _files(b), _files(c)
    assert len(files_a) == 3 * 4 + 1
    assert files_a == files_b
    assert files_a.keys() == files_c.keys() and files_a != files_c
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_dataset_contents_match_the_rendered_pairs(tmp_path):
    out = make_dataset(tmp_path / "set", pairs=2, motion="small-parallax", seed=1, size=SMALL,
                       alpha=0.05, workers=1)  # fmt: skip
    records = read_pairs(out / PAIRS_FILE)
    assert len(records) == 2
    line = (out / PAIRS_FILE).read_text().splitlines()[0].split()
    assert len(line) == 38 and line[2:4] == ["0", "0"]
    assert line[-4:] == ["0.000000000000", "0.000000000000", "0.000000000000", "1.000000000000"]
    for index, record in enumerate(records):
        pair = make_pair("small-parallax", seed=1, index=index, size=SMALL, alpha=0.05)
        gt = json.loads((out / "gt" / f"pair_{index:03d}.json").read_text())
        assert (out / "images" / record["name1"]).is_file()
        assert gt["image2"] == f"images/{record['name2']}"
        np.testing.assert_allclose(record["R"], pair.R, atol=1e-11)
        np.testing.assert_allclose(record["t"], pair.t, atol=1e-11)
        np.testing.assert_allclose(record["K1"], pair.K1, atol=1e-6)
        np.testing.assert_array_equal(np.array(gt["R"]), pair.R)
        np.testing.assert_array_equal(np.array(gt["t"]), pair.t)
        np.testing.assert_array_equal(np.array(gt["K2"]), pair.K2)
        assert gt["params"]["motion"] == "small-parallax" and gt["params"]["alpha"] == 0.05
        np.testing.assert_array_equal(np.load(out / gt["depth1"]), pair.depth1)


def test_pairs_file_reads_like_the_freiburg_one(freiburg):
    record = read_pairs(freiburg / "pairs_with_gt.txt")[0]
    assert record["K1"][0, 0] == pytest.approx(535.4)
    np.testing.assert_allclose(record["R"] @ record["R"].T, np.eye(3), atol=1e-6)


def test_existing_directory_is_refused(tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep")
    with pytest.raises(FileExistsError):
        make_dataset(tmp_path / "full", pairs=1, size=SMALL)
    with pytest.raises(ValueError, match="unknown motion"):
        make_dataset(tmp_path / "new", pairs=1, motion="orbit", size=SMALL)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]


@pytest.mark.parametrize("workers", ["1", "0"], ids=["one worker", "0: one per CPU, as pairs"])
def test_cli_writes_a_dataset(tmp_path, workers):
    out = tmp_path / "synth"
    result = CliRunner().invoke(app, ["synth", str(out), "--pairs", "2", "--motion",
                                      "pure-rotation", "--seed", "4", "--width", "160",
                                      "--height", "120", "--workers", workers])  # fmt: skip
    assert result.exit_code == 0, result.output
    records = read_pairs(out / PAIRS_FILE)
    assert len(records) == 2 and all(np.all(r["t"] == 0) for r in records)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--motion", "orbit"], "unknown motion"),
        (["--pairs", "0"], "--pairs"),
        (["--seed", "-3"], "--seed"),
        (["--alpha", "2"], "--alpha"),
        (["--scene", "garden"], "unknown scene"),
        (["--width", "4"], "--width"),
        (["--workers", "-1"], "--workers must be in 0..256"),
        (["--height", "15"], "--height must be in 16..4096"),  # too thin to detect features on
        (["--alpha", "0.5"], "--alpha applies to --motion small-parallax only"),
        (["--imperfect", "--exposure-ev", "100"], "--exposure-ev must be in [0.0, 3.0]"),
        (["--imperfect", "--noise", "60"], "--noise must be in [0, 50]"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(tmp_path, args, message):
    out = tmp_path / "synth"
    result = CliRunner().invoke(app, ["synth", str(out), *args])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.output
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_cli_smallest_side_is_the_one_features_are_detected_on():
    from ppo_cv.cli.synth import MIN_SIDE
    from ppo_cv.features import MIN_IMAGE_SIDE

    assert MIN_SIDE == MIN_IMAGE_SIDE


def test_cli_refuses_a_non_empty_directory(tmp_path):
    (tmp_path / "x").write_text("keep")
    result = CliRunner().invoke(app, ["synth", str(tmp_path), "--pairs", "1"])
    assert result.exit_code == 2 and "not an empty directory" in result.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["x"]


def test_imperfect_dataset_gives_the_estimator_the_given_intrinsics(tmp_path):
    from ppo_cv.data_gen import REAL_PHOTO

    out = make_dataset(tmp_path / "set", pairs=2, motion="panorama", seed=3, size=SMALL,
                       imperfections=REAL_PHOTO, workers=1)  # fmt: skip
    for index, record in enumerate(read_pairs(out / PAIRS_FILE)):
        pair = make_pair("panorama", seed=3, index=index, size=SMALL, imperfections=REAL_PHOTO)
        gt = json.loads((out / "gt" / f"pair_{index:03d}.json").read_text())
        np.testing.assert_allclose(record["K1"], pair.K1_given, atol=1e-6)
        assert abs(record["K1"][0, 0] / pair.K1[0, 0] - 1) > 1e-4
        np.testing.assert_array_equal(np.array(gt["K1"]), pair.K1)
        np.testing.assert_array_equal(np.array(gt["K1_given"]), pair.K1_given)
        np.testing.assert_array_equal(np.array(gt["dist1"]), pair.dist1)
        assert gt["params"]["k1"] == pair.params["k1"] and gt["params"]["imperfect"] is True
        assert np.all(record["t"] == 0.0)


def test_warped_dataset(tmp_path):
    from importlib import resources

    photo = resources.files("ppo_cv") / "data" / "demo2.png"
    out = make_dataset(tmp_path / "warp", pairs=2, seed=1, source="warp", warp_source=str(photo),
                       workers=1)  # fmt: skip
    records = read_pairs(out / PAIRS_FILE)
    assert len(records) == 2 and all(np.all(r["t"] == 0.0) for r in records)
    gt = json.loads((out / "gt" / "pair_001.json").read_text())
    assert gt["params"]["photo"] == "demo2.png" and gt["params"]["motion"] == "panorama"
    assert gt["dist1"] == [] and (gt["width"], gt["height"]) == (416, 312)
    assert np.isnan(np.load(out / gt["depth1"])).all()
    for bad, message in (
        ({"motion": "general"}, "panorama"),
        ({"alpha": 0.1}, "alpha"),
        ({"noise_std": 1.0}, "imperfections"),
        ({"source": "video"}, "source"),
    ):
        kwargs = {"source": "warp", "warp_source": str(photo), **bad}
        with pytest.raises(ValueError, match=message):
            make_dataset(tmp_path / "bad", pairs=1, **kwargs)
    assert not (tmp_path / "bad").exists()


def test_cli_imperfect_and_warp(tmp_path):
    from importlib import resources

    runner = CliRunner()
    out = tmp_path / "tiny"
    result = runner.invoke(app, ["synth", str(out), "-n", "1", "--motion", "tiny-baseline",
                                 "--baseline-ratio", "0.03", "--imperfect", "--width", "64",
                                 "--height", "48", "--noise", "2", "--workers", "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"wrote 1 pair to {out} (")  # not '1 pairs'
    gt = json.loads((out / "gt" / "pair_000.json").read_text())
    assert gt["params"]["baseline_ratio"] == 0.03 and gt["params"]["noise_std"] == 2.0
    assert gt["params"]["blur_sigma"] == 0.5 and gt["K1"] != gt["K1_given"]
    out = tmp_path / "tripod"
    result = runner.invoke(app, ["synth", str(out), "-n", "1", "--motion", "panorama",
                                 "--pivot-offset", "0.08", "--width", "64", "--height", "48",
                                 "--workers", "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    gt = json.loads((out / "gt" / "pair_000.json").read_text())
    R, t, pivot = np.array(gt["R"]), np.array(gt["t"]), np.array([0.0, 0.0, -0.08])
    assert gt["params"]["pivot_offset"] == 0.08
    np.testing.assert_allclose(R @ pivot + t, pivot, atol=1e-12)
    folder = resources.files("ppo_cv") / "data"
    out = tmp_path / "warp"
    result = runner.invoke(app, ["synth", str(out), "-n", "1", "--warp", "--imperfect",
                                 "--warp-source", str(folder), "--width", "200", "--height",
                                 "150", "--workers", "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    gt = json.loads((out / "gt" / "pair_000.json").read_text())
    assert (gt["width"], gt["height"]) == (200, 150) and gt["params"]["jpeg_quality"] >= 70
    out = tmp_path / "lit"
    result = runner.invoke(app, ["synth", str(out), "-n", "1", "--warp", "--imperfect",
                                 "--warp-source", str(folder), "--width", "200", "--height",
                                 "150", "--exposure-ev", "1", "--vignetting", "0.3",
                                 "--workers", "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    params = json.loads((out / "gt" / "pair_000.json").read_text())["params"]
    assert params["vignetting"] == 0.3 and 0 < abs(params["exposure_ev"]) <= 1.0
    assert params["imperfections"]["exposure_ev"] == 1.0
    lit = cv2.imread(str(out / "images" / "pair_000_1.png"), cv2.IMREAD_GRAYSCALE)
    plain = cv2.imread(str(tmp_path / "warp" / "images" / "pair_000_1.png"), cv2.IMREAD_GRAYSCALE)
    corner, centre = (slice(0, 20), slice(0, 20)), (slice(65, 85), slice(90, 110))
    darkening = [float(np.mean(lit[w])) / float(np.mean(plain[w])) for w in (corner, centre)]
    assert darkening[0] < 0.95 * darkening[1]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--blur", "51"], "--blur"),
        (["--noise", "-1"], "--noise"),
        (["--width", "5000"], "--width"),
        (["--width", "4096", "--height", "4096", "--supersample", "2"], "samples"),
        (["--pairs", "100000"], "--pairs"),
        (["--baseline-ratio", "0.01"], "tiny-baseline and tripod only"),
        (["--motion", "tiny-baseline", "--baseline-ratio", "0.6"], "--baseline-ratio"),
        (["--pivot-offset", "0.08"], "panorama only"),
        (["--motion", "panorama", "--pivot-offset", "1.5"], "--pivot-offset"),
        (["--warp", "--pivot-offset", "0.08"], "panorama only"),
        (["--warp", "--motion", "general"], "panorama"),
        (["--warp", "--width", "300"], "both --width and --height"),
        (["--warp", "--scene", "room"], "--scene"),
        (["--warp-source", "photos"], "needs --warp"),
        (["--warp", "--warp-source", "missing.png"], "does not exist"),
        (["--warp", "--different-k"], "--different-k"),
    ],
)
def test_cli_new_options_bad_input_exits_2_with_one_line(tmp_path, args, message):
    out = tmp_path / "synth"
    result = CliRunner().invoke(app, ["synth", str(out), *args])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.output
    assert not out.exists()


def test_pairs_file_written_by_an_editor_with_a_byte_order_mark_is_read(tmp_path):
    out = make_dataset(tmp_path / "set", pairs=1, motion="general", seed=2, size=SMALL, workers=1)
    text = (out / PAIRS_FILE).read_text(encoding="utf-8")
    marked = tmp_path / "marked.txt"
    marked.write_bytes(b"\xef\xbb\xbf" + text.replace(" ", "  ").encode("utf-8"))
    (record,) = read_pairs(marked)
    (expected,) = read_pairs(out / PAIRS_FILE)
    assert record["name1"] == expected["name1"]
    np.testing.assert_array_equal(record["R"], expected["R"])
