"""``ppo-cv pairs`` as a batch tool: features once per image, AUC of pure rotations, progress."""

from __future__ import annotations

import codecs
import io
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

import ppo_cv.consensus
import ppo_cv.features
import ppo_cv.pipeline
from ppo_cv.cli import batch
from ppo_cv.cli.common import ProgressReport, pipeline_options
from ppo_cv.cli.main import app

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
NAME1, NAME2 = DEMO["image1"], DEMO["image2"]
fx, fy, cx, cy = DEMO["intrinsics"]
K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]


def _counting(monkeypatch) -> list:
    """Count every feature detection, whichever path (cache or per pair) calls it."""
    calls = []
    original = ppo_cv.features.detect_features

    def counted(image, *args, **kwargs):
        calls.append(image.shape)
        return original(image, *args, **kwargs)

    monkeypatch.setattr(ppo_cv.features, "detect_features", counted)
    monkeypatch.setattr(ppo_cv.consensus, "detect_features", counted)
    return calls


def _without_timings(path: Path) -> list[dict]:
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    for row in rows:
        row.pop("timings", None)
    return rows


def _with_and_without_cache(tmp_path, options, monkeypatch) -> dict:
    """``{cache: (detections, JSON lines without timings)}`` of ``pairs.txt`` in ``tmp_path``."""
    calls = _counting(monkeypatch)
    runs = {}
    for cache in (True, False):
        calls.clear()
        output = tmp_path / f"cache_{cache}.jsonl"
        code = batch.run_pairs(tmp_path / "pairs.txt", DATA, K_TEXT, output, 1, options,
                               cache=cache, quiet=True)  # fmt: skip
        assert code == 0
        runs[cache] = (len(calls), _without_timings(output))
    return runs


def test_features_are_computed_once_per_image_and_change_nothing(tmp_path, monkeypatch):
    lines = [f"{NAME1} {NAME2}", f"{NAME2} {NAME1}", f"{NAME1} {NAME2}", f"{NAME1} missing.png"]
    (tmp_path / "pairs.txt").write_text("\n".join(lines) + "\n")
    runs = _with_and_without_cache(tmp_path, pipeline_options(max_features=2000), monkeypatch)
    # two readable images detected once for four pairs, at the second detection's threshold;
    # there the first reaches max_features (2000 of its 2228 keypoints), so it is detected
    # again at the first threshold, the second (1989) is not
    assert runs[True][0] == 3
    assert runs[False][0] == 6  # two per pair that reaches detection
    assert runs[True][1] == runs[False][1]  # same poses, inliers, counts: the cache is exact
    assert "image not found" in runs[True][1][3]["error"]
    assert all("error" not in row for row in runs[True][1][:3])


def test_a_weak_pair_reuses_the_cached_denser_features(tmp_path, monkeypatch):
    (tmp_path / "pairs.txt").write_text(f"{NAME1} {NAME2}\n{NAME2} {NAME1}\n")
    options = pipeline_options(redetect_below=5000)  # every pair weak: both consensuses fitted
    runs = _with_and_without_cache(tmp_path, options, monkeypatch)
    assert runs[True][0] == 2  # each image once, at the second detection's threshold
    assert runs[False][0] == 8  # each image twice per pair: at the first threshold and lower
    assert runs[True][1] == runs[False][1]


def test_each_process_decodes_an_image_once_for_all_its_pairs(tmp_path, monkeypatch):
    decoded = []
    original = ppo_cv.pipeline.load_image

    def counted(path, *args, **kwargs):
        decoded.append(Path(path).name)
        return original(path, *args, **kwargs)

    monkeypatch.setattr(ppo_cv.pipeline, "load_image", counted)
    lines = [f"{NAME1} {NAME2}", f"{NAME2} {NAME1}", f"{NAME1} {NAME2}"]
    (tmp_path / "pairs.txt").write_text("\n".join(lines) + "\n")
    output = tmp_path / "out.jsonl"
    options = pipeline_options(max_features=2000)
    code = batch.run_pairs(tmp_path / "pairs.txt", DATA, K_TEXT, output, 1, options, quiet=True)
    assert code == 0
    # once to detect the features, once for the three pairs
    assert sorted(decoded) == sorted([NAME1, NAME2] * 2)
    assert not batch._recent.entries  # nothing is held after the run
    rows = _without_timings(output)
    assert rows[0] == rows[2] and all("error" not in row for row in rows)


def test_recent_arrays_are_read_only_within_budget_and_reread_when_the_file_changes(tmp_path):
    path = tmp_path / "image.png"
    cv2.imwrite(str(path), np.zeros((40, 60, 3), np.uint8))
    first = batch._recent_image(path, True)
    assert batch._recent_image(path, True) is first and not first.flags.writeable
    cv2.imwrite(str(path), np.full((40, 80, 3), 255, np.uint8))
    again = batch._recent_image(path, True)
    assert again.shape == (40, 80, 3) and again.max() == 255  # the new file, decoded
    batch._recent.clear()
    recent = batch._Recent(budget=2500)
    arrays = {name: np.zeros(1000, np.uint8) for name in "abc"}
    for name in "abc":
        recent.get((name,), lambda name=name: arrays[name], batch._one)
    assert list(recent.entries) == [("b",), ("c",)]  # the least recently used went first
    assert recent.get(("d",), lambda: np.zeros(5000, np.uint8), batch._one).size == 5000
    assert list(recent.entries) == [("b",), ("c",)]  # above the budget: returned, not kept
    recent.get(("b",), lambda: None, batch._one)
    recent.get(("e",), lambda: np.zeros(1000, np.uint8), batch._one)
    assert list(recent.entries) == [("b",), ("e",)]  # b, used again, outlived c


def test_feature_cache_is_keyed_by_path_and_options(tmp_path):
    options = pipeline_options()
    cache = batch.FeatureCache(tmp_path, options)
    jobs = cache.jobs([DATA / NAME1, DATA / "." / NAME1, DATA / NAME2])
    assert len(jobs) == 2  # the same file under two spellings is one entry
    other = batch.FeatureCache(tmp_path, pipeline_options(max_features=1000))
    assert cache.key(DATA / NAME1) != other.key(DATA / NAME1)


def test_precomputed_features_are_checked():
    options = pipeline_options()
    image1, image2 = (str(DATA / n) for n in (NAME1, NAME2))
    with pytest.raises(TypeError, match="features1 must be ppo_cv.features.Features"):
        ppo_cv.pipeline.estimate_pair(image1, image2, K, features1="x", features2="y")
    orb = ppo_cv.features.Features(np.zeros((10, 2)), np.zeros((10, 32), np.uint8), "orb")
    with pytest.raises(ValueError, match="features1 are orb features but options.features is"):
        ppo_cv.pipeline.estimate_pair(image1, image2, K, options=options, features1=orb,
                                      features2=orb)  # fmt: skip


def _rotation(axis, degrees) -> np.ndarray:
    return cv2.Rodrigues(np.radians(degrees) * np.asarray(axis, float))[0]


def test_pose_error_of_a_pure_rotation_is_the_rotation_error():
    R_true = _rotation([0, 1, 0], 5.0)
    T = np.eye(4)
    T[:3, :3] = R_true
    R = _rotation([0, 1, 0], 5.5)
    errors = batch.pose_errors(R, np.array([0.0, 0.0, 1.0]), T)
    assert errors["t_err_deg"] is None
    assert errors["pose_err_deg"] == pytest.approx(errors["R_err_deg"]) == pytest.approx(0.5)
    T[:3, 3] = [1.0, 0.0, 0.0]
    moved = batch.pose_errors(R, np.array([0.0, 0.0, 1.0]), T)
    assert moved["t_err_deg"] == pytest.approx(90.0) == moved["pose_err_deg"]


_T_MOVING = np.r_[np.c_[np.eye(3), [1.0, 0.0, 0.0]], [[0.0, 0.0, 0.0, 1.0]]]


@pytest.mark.parametrize(
    "call, exception, words",
    [(lambda: batch.pose_errors(np.eye(3), [0.0, 0.0, 0.0], _T_MOVING), ValueError,
      "t is zero: it has no direction to compare"),
     (lambda: batch.pose_errors(np.eye(3), [1.0, 0.0, 0.0], _T_MOVING * np.nan), ValueError,
      "T has 16 NaN or infinite value(s)"),
     (lambda: batch.pose_errors(np.eye(3), [1.0, 0.0, 0.0], _T_MOVING.tolist()[:2]), ValueError,
      "T must be a 4x4 (or 3x4) motion [R | t], got shape (2, 4)"),
     (lambda: batch.pose_auc([np.nan, 1.0]), ValueError, "errors has 1 NaN or infinite value(s)"),
     (lambda: batch.pose_auc([-5.0, 1.0]), ValueError, "errors must be angles >= 0, got -5"),
     (lambda: batch.pose_auc([[1.0, 2.0]]), ValueError,
      "errors must be a sequence of numbers, got shape (1, 2)"),
     (lambda: batch.pose_auc([1.0], thresholds=(0.0,)), ValueError,
      "thresholds must be a finite number > 0, got 0.0")],
    ids=["zero t", "NaN T", "T of two rows", "NaN error", "negative error", "errors 2-D",
         "zero threshold"],
)  # fmt: skip
def test_pose_errors_and_auc_refuse_what_has_no_error(call, exception, words):
    # a zero t scored as a perfect pose (max(0, NaN) is 0), a NaN T as NaN, a list T failed on
    # its indexing; a NaN or negative error gave an AUC of 0.45 or 1.45, a zero threshold a
    # RuntimeWarning and NaN, 2-D errors numpy's message
    with pytest.raises(exception) as info:
        call()
    assert words in str(info.value)


def test_pose_errors_take_a_list_T():
    errors = batch.pose_errors(np.eye(3), [2.0, 0.0, 0.0], _T_MOVING.tolist())
    assert errors == {"R_err_deg": 0.0, "t_err_deg": 0.0, "pose_err_deg": 0.0}


@pytest.fixture(scope="module")
def rotation_pairs(tmp_path_factory):
    """Two exact pure rotations of the demo images (warped by K R K^-1), with ground truth."""
    root = tmp_path_factory.mktemp("rotations")
    lines = []
    for index, (name, axis) in enumerate(((NAME1, [0, 1, 0]), (NAME2, [1, 0, 0.3]))):
        R = _rotation(axis, 4.0)
        image = cv2.imread(str(DATA / name))
        warped = cv2.warpPerspective(image, K @ R @ np.linalg.inv(K), image.shape[1::-1])
        cv2.imwrite(str(root / f"r{index}_1.png"), image)
        cv2.imwrite(str(root / f"r{index}_2.png"), warped)
        T = np.eye(4)
        T[:3, :3] = R
        numbers = [0, 0, *K.ravel(), *K.ravel(), *T.ravel()]
        lines.append(f"r{index}_1.png r{index}_2.png " + " ".join(f"{v:.12g}" for v in numbers))
    (root / "pairs.txt").write_text("\n".join(lines) + "\n")
    return root


def test_pure_rotations_get_an_auc_and_progress_goes_to_stderr(rotation_pairs, tmp_path):
    pairs = str(rotation_pairs / "pairs.txt")
    args = [*COMMAND, "pairs", pairs, str(rotation_pairs), "--workers", "1",
            "--pri-threshold", "0.02", "-o", str(tmp_path / "out.jsonl")]  # fmt: skip
    out = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    progress = out.stderr.strip().splitlines()
    assert progress[-1].startswith("ppo-cv pairs: 2/2 pairs, ")
    assert any(line.startswith("ppo-cv pairs: 1/2 pairs, ") for line in progress)
    assert "rotation error alone for the 2 pairs whose true t is zero" in out.stdout
    row = out.stdout.strip().splitlines()[-1]
    auc = [float(v) for v in row.strip("|").split("|")[2:]]
    assert min(auc) > 90.0, out.stdout  # the rotations are recovered to a fraction of a degree
    results = [json.loads(line) for line in (tmp_path / "out.jsonl").read_text().splitlines()]
    assert [r["evidence"]["selection"]["pri_threshold"] for r in results] == [0.02, 0.02]
    assert all(r["t_err_deg"] is None and r["R_err_deg"] < 0.5 for r in results)
    quiet = subprocess.run([*args[:-2], "-o", str(tmp_path / "quiet.jsonl"), "--quiet"],
                           capture_output=True, text=True, timeout=120)  # fmt: skip
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_pri_threshold_reaches_the_pipeline(rotation_pairs):
    """A pure rotation is flagged only when its PRI is under the threshold as well (the model
    comparison alone cannot flag it), so a threshold of almost zero turns the flag off."""
    runner = CliRunner()
    intrinsics = ",".join(str(v) for v in (K[0, 0], K[1, 1], K[0, 2], K[1, 2]))
    images = [str(rotation_pairs / "r0_1.png"), str(rotation_pairs / "r0_2.png")]
    pair = ["pair", *images, "--K", intrinsics, "--json"]
    plain = runner.invoke(app, pair)
    strict = runner.invoke(app, [*pair, "--pri-threshold", "1e-9"])
    assert plain.exit_code == 0 and strict.exit_code == 0, plain.output + strict.output
    plain, strict = json.loads(plain.stdout), json.loads(strict.stdout)
    assert (plain["pure_rotation"], strict["pure_rotation"]) == (True, False)
    assert strict["evidence"]["selection"]["pri_threshold"] == 1e-9 and strict["pri"] > 1e-9


def test_sfm_passes_its_options_on(monkeypatch, tmp_path):
    from ppo_cv import sfm

    seen = {}

    def fake_run_sfm(image_dir, output_dir, **kwargs):
        seen.update(kwargs)
        raise ValueError("stopped here")

    monkeypatch.setattr(sfm, "run_sfm", fake_run_sfm)
    images = tmp_path / "images"
    images.mkdir()
    for name in (NAME1, NAME2):
        (images / name).write_bytes((DATA / name).read_bytes())
    args = ["sfm", str(images), str(tmp_path / "model"), "--pri-threshold", "0.03", "--seed", "7"]
    run = CliRunner().invoke(app, [*args, "--quiet"])
    assert run.exit_code == 2 and "ppo-cv sfm: stopped here" in run.stderr
    assert "warning: no intrinsics given" in run.stderr  # sfm warns without --K, as pair does
    assert seen["pri_threshold"] == 0.03 and seen["seed"] == 7


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("terminal", [False, True])
def test_progress_report_plain_lines_or_a_bar(monkeypatch, terminal):
    stream = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    with ProgressReport("pairs", "pairs", 3) as report:
        for _ in range(3):
            report.advance()
    text = stream.getvalue()
    plain = [line for line in text.splitlines() if line.startswith("ppo-cv pairs: ")]
    if terminal:
        assert plain == [] and "3/3" in text  # rich's bar, not the plain lines
    else:
        assert plain[0].startswith("ppo-cv pairs: 1/3 pairs, ")
        assert plain[-1].startswith("ppo-cv pairs: 3/3 pairs, ")
    quiet = io.StringIO()
    monkeypatch.setattr(sys, "stderr", quiet)
    with ProgressReport("pairs", "pairs", 3, quiet=True) as report:
        report.advance(3)
    assert quiet.getvalue() == ""


def test_max_trials_reaches_ransac_and_is_bounded(monkeypatch, tmp_path):
    seen = []
    real = batch.run_pairs

    def spy(*args, **kwargs):
        seen.append(args[5])
        return real(*args, **kwargs)

    monkeypatch.setattr(batch, "run_pairs", spy)
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"{NAME1} {NAME2}\n")
    runner = CliRunner()
    ok = runner.invoke(
        app,
        ["pairs", str(pairs), str(DATA), "--K", K_TEXT, "--workers", "1", "--quiet",
         "--max-trials", "50", "-o", str(tmp_path / "out.jsonl")],
    )  # fmt: skip
    assert ok.exit_code == 0, ok.output
    assert (seen[0].max_trials, seen[0].min_trials) == (50, 50)
    line = json.loads((tmp_path / "out.jsonl").read_text())
    assert "error" not in line and len(line["R"]) == 3, line
    bad = runner.invoke(app, ["pairs", str(pairs), str(DATA), "--K", K_TEXT, "--max-trials", "0"])
    assert bad.exit_code == 2 and "--max-trials" in bad.output


@pytest.mark.parametrize(
    "line, names",
    [
        ('"my photo 1.png" photo2.png', ["my photo 1.png", "photo2.png"]),
        ("a.png b.png   # the first pair", ["a.png", "b.png"]),
        ("a.png b.png\t#comment", ["a.png", "b.png"]),
        ('"été 1.jpg" "b b.jpg" # both quoted', ["été 1.jpg", "b b.jpg"]),
        ("a#1.png b.png", ["a#1.png", "b.png"]),
    ],
)
def test_pairs_file_fields_quotes_and_trailing_comments(tmp_path, line, names):
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"# header\n{line}\n", encoding="utf-8")
    (row,) = batch.read_pairs(pairs, K=K_TEXT)
    assert [row["image1"], row["image2"]] == names and row["line"] == 2


def test_a_pairs_file_as_windows_editors_save_it_is_read(tmp_path):
    """UTF-8 byte-order mark, CRLF line ends, names with spaces and accents, comments."""
    images = tmp_path / "photos"
    images.mkdir()
    (images / "frame one.png").write_bytes((DATA / NAME1).read_bytes())
    (images / "cadre deux é.png").write_bytes((DATA / NAME2).read_bytes())
    text = '# office, two frames\r\n"frame one.png" "cadre deux é.png"  # 1 s apart\r\n'
    (tmp_path / "pairs.txt").write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    args = [*COMMAND, "pairs", str(tmp_path / "pairs.txt"), str(images), "--K", K_TEXT,
            "--workers", "1", "--quiet"]  # fmt: skip
    out = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    (result,) = [json.loads(line) for line in out.stdout.splitlines()]
    assert (result["image1"], result["image2"]) == ("frame one.png", "cadre deux é.png")
    error = np.degrees(np.arccos((np.trace(np.array(result["R"]).T @ DEMO["reference_R"]) - 1) / 2))
    assert error < 1.0


def test_a_name_with_unquoted_spaces_is_refused_with_the_remedy(tmp_path):
    pairs = tmp_path / "pairs.txt"
    pairs.write_text("my photo.png other.png\n")
    with pytest.raises(ValueError, match=r"pairs\.txt:1: .*got 3 fields \(put a name with spaces"):
        batch.read_pairs(pairs, K=K_TEXT)


@pytest.mark.parametrize(
    "line",
    ['"a.png b.png', 'a.png "b.png', '"a b".png c.png', 'a.png b"c.png', '"a.png" "b.png'],
)
def test_a_double_quote_that_does_not_enclose_a_whole_name_is_refused(tmp_path, line):
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"a.png b.png\n{line}\n")
    with pytest.raises(ValueError, match=r"pairs\.txt:2: a double quote .* whole name"):
        batch.read_pairs(pairs, K=K_TEXT)


_K_FIELDS = "535.4 0 320.1 0 539.2 247.6 0 0 1"


@pytest.mark.parametrize(
    "line, remedy",
    [
        ("my photo.png other.png", r"got 3 fields \(put a name with spaces in double quotes\)"),
        ("a.png b.png 0 0 1", r"got 5 fields \(after the names: 0 0, then 9 numbers for K1"),
        (f"a.png b.png 0 0 {_K_FIELDS} {_K_FIELDS[:-2]}",
         r"got 21 fields \(after the names: 0 0, then 9 numbers for K1, 9 for K2 and "
         r"optionally 16 for T_1to2\)"),
        (f"a.png b.png 0 0 {_K_FIELDS} {_K_FIELDS} 1 0 0", r"got 25 fields \(after the names"),
        ("a b.png c.png 0 0", r"got 5 fields \(put a name with spaces in double quotes\)"),
        ("a.png", r"got 1 field \(a pair needs two image names\)"),
        ("a.png,b.png", r"got 1 field \(a pair needs two image names, separated by spaces, not "
                        r"','\)"),
        ("a.png;b.png", r"got 1 field \(a pair needs two image names, separated by spaces, not "
                        r"';'\)"),
    ],
    ids=["space in a name", "one number", "K2 short", "T short", "space and numbers", "one name",
         "comma-separated", "semicolon-separated"],
)
def test_a_line_of_the_wrong_length_gets_the_remedy_that_fits(tmp_path, line, remedy):
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"{line}\n")
    with pytest.raises(ValueError, match=r"pairs\.txt:1: expected .*" + remedy):
        batch.read_pairs(pairs, K=K_TEXT)


@pytest.mark.parametrize(
    "line",
    ["my photo.png\tyour photo.png", "'my photo.png' 'your photo.png'"],
    ids=["tab-separated", "single quotes"],
)
def test_two_names_with_spaces_that_make_four_fields_get_the_quoting_remedy(tmp_path, line):
    # four fields read as 'name1 name2 0 0': "fields 3 and 4 must be 0 0, got your photo.png"
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"{line}\n")
    with pytest.raises(ValueError, match=r"pairs\.txt:1: fields 3 and 4 must be 0 0, got .*"
                                         r"photo\.png'? \(two names with spaces\? put each in "
                                         r"double quotes\)$"):  # fmt: skip
        batch.read_pairs(pairs, K=K_TEXT)


def test_output_dash_is_standard_output(tmp_path):
    (tmp_path / "pairs.txt").write_text(f"{NAME1} absent2.png\n")
    (tmp_path / "images").mkdir()
    (tmp_path / "images" / NAME1).write_bytes((DATA / NAME1).read_bytes())
    args = [*COMMAND, "pairs", "pairs.txt", "images", "--K", K_TEXT, "-o", "-", "--quiet"]
    out = subprocess.run(args, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 1, out.stderr
    (line,) = [json.loads(text) for text in out.stdout.splitlines()]
    assert line["image2"] == "absent2.png" and "image not found" in line["error"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["images", "pairs.txt"]


K_FIELDS = " ".join(str(v) for v in K.ravel())
TRUTH = " ".join(str(v) for v in np.eye(4).ravel())


@pytest.mark.parametrize(
    "truth, output, first_stderr",
    [
        ("", [], None),
        ("", ["-o", "out.jsonl"], None),
        (f" 0 0 {K_FIELDS} {K_FIELDS} {TRUTH}", [], "pose error = max("),
        (f" 0 0 {K_FIELDS} {K_FIELDS} {TRUTH}", ["-o", "out.jsonl"], None),
    ],
    ids=["stdout", "file", "truth-stdout", "truth-file"],
)
def test_a_batch_in_which_every_pair_fails_exits_1_after_its_lines(
    tmp_path, truth, output, first_stderr
):
    (tmp_path / "images").mkdir()
    (tmp_path / "images" / NAME1).write_bytes((DATA / NAME1).read_bytes())
    lines = [f"{NAME1} absent2.png{truth}", f"absent3.png {NAME1}{truth}"]
    (tmp_path / "pairs.txt").write_text("\n".join(lines) + "\n")
    K_option = [] if truth else ["--K", K_TEXT]  # lines with their own K take no --K
    args = [*COMMAND, "pairs", "pairs.txt", "images", *K_option, "--quiet", *output]
    out = subprocess.run(args, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 1, out.stderr
    stderr = out.stderr.splitlines()
    assert stderr[-1].startswith(
        f"ppo-cv pairs: no pose: all 2 pairs failed (each JSON line names its error); "
        f"{NAME1} absent2.png: image not found"
    )
    assert (stderr[0].startswith(first_stderr) if first_stderr else len(stderr) == 1), stderr
    text = (tmp_path / "out.jsonl").read_text() if output else out.stdout
    rows = [json.loads(line) for line in text.splitlines() if line.startswith("{")]
    assert [row["image2"] for row in rows] == ["absent2.png", NAME1]
    assert all("image not found" in row["error"] for row in rows)


def test_a_batch_with_one_pose_exits_0_and_counts_the_failures(tmp_path):
    (tmp_path / "pairs.txt").write_text(f"{NAME1} {NAME2}\n{NAME1} absent2.png\n")
    args = [*COMMAND, "pairs", str(tmp_path / "pairs.txt"), str(DATA), "--K", K_TEXT,
            "--workers", "1", "--quiet", "--max-features", "1000"]  # fmt: skip
    out = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr.splitlines() == ["ppo-cv pairs: warning: 1 of 2 pairs failed"]
    rows = [json.loads(line) for line in out.stdout.splitlines()]
    assert "error" not in rows[0] and "image not found" in rows[1]["error"]


def test_repeated_pairs_file_lines_run_again_under_one_warning(tmp_path):
    lines = [f"{NAME1} {NAME2}", "# again, quoted and commented", f"{NAME2} {NAME1}",
             f'"{NAME1}"  {NAME2}  # the first pair', f"{NAME2} {NAME1}"]  # fmt: skip
    (tmp_path / "pairs.txt").write_text("\n".join(lines) + "\n")
    args = [*COMMAND, "pairs", str(tmp_path / "pairs.txt"), str(DATA), "--K", K_TEXT,
            "--workers", "1", "--quiet", "--max-features", "1000"]  # fmt: skip
    out = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr.splitlines() == [
        f"ppo-cv pairs: warning: {tmp_path / 'pairs.txt'}: lines 4 (= 1), 5 (= 3) repeat an "
        "earlier line; each runs again and gives its own JSON line"
    ]
    results = [json.loads(line) for line in out.stdout.splitlines()]
    assert [(r["image1"], r["image2"]) for r in results] == [
        (NAME1, NAME2), (NAME2, NAME1), (NAME1, NAME2), (NAME2, NAME1)
    ]
    assert results[0]["R"] == results[2]["R"] and "error" not in results[0]


@pytest.mark.parametrize(
    "lines, named",
    [
        (["a.png b.png", "a.png b.png"], "line 2 (= 1) repeats"),
        (["a.png b.png", "b.png a.png"] * 2, "lines 3 (= 1), 4 (= 2) repeat"),
        (["a.png b.png"] * 1000,
         "lines 2 (= 1), 3 (= 1), 4 (= 1), 5 (= 1), 6 (= 1) and 994 more repeat"),
    ],
    ids=["one", "two", "a thousand"],
)
def test_the_repeated_lines_warning_is_one_short_line(tmp_path, capsys, lines, named):
    pairs = tmp_path / "pairs.txt"
    pairs.write_text("\n".join(lines) + "\n")
    batch._warn_repeated_lines(batch.read_pairs(pairs, K=K_TEXT), pairs)
    assert capsys.readouterr().err == (
        f"ppo-cv pairs: warning: {pairs}: {named} an earlier line; each runs again and gives "
        "its own JSON line\n"
    )


ROUNDED = "0.969 -0.158 -0.190 0.138 0.984 -0.114 0.205 0.084 0.975"  # a rotation, 3 decimals
SHEARED = "1 0.05 0 0 1 0 0 0 1"  # no rotation, however rounded


@pytest.mark.parametrize(
    "R, ending",
    [
        (ROUNDED, r"above 0.0001\): its entries, written to 3 decimals, are rounded too far; "
                  "write 6 or more$"),
        (SHEARED, r"\(\|R\^T R - I\| up to 0.05, above 0.0001\)$"),
    ],
    ids=["rounded", "sheared"],
)  # fmt: skip
def test_a_ground_truth_rotation_rounded_too_far_is_refused_with_the_way_out(
    tmp_path, R, ending
):
    # 3 decimals were refused as "not orthonormal", with no word of the decimals
    rows = R.split()
    T = " ".join(rows[0:3] + ["0.5"] + rows[3:6] + ["0"] + rows[6:9] + ["0", "0 0 0 1"])
    K = "535.4 0 320.1 0 539.2 247.6 0 0 1"
    path = tmp_path / "pairs.txt"
    path.write_text(f"a.png b.png 0 0 {K} {K} {T}\n")
    with pytest.raises(ValueError, match="pairs.txt:1: the ground-truth rotation is not "
                                         "orthonormal .*" + ending):  # fmt: skip
        batch.read_pairs(path)


def _calibration(path: Path, size: tuple[int, int], matrix) -> Path:
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", size[0])
    storage.write("image_height", size[1])
    storage.write("camera_matrix", np.array(matrix, float))
    storage.write("distortion_coefficients", np.zeros(5))
    storage.release()
    return path


def test_a_calibration_is_fitted_to_the_images_as_read_upright(tmp_path):
    """Photos stored sideways (480x640) and shown upright (640x480) by their EXIF orientation,
    as ``pair`` reads them: the calibration of the upright images serves them (it was refused
    by the stored size in the header, "another aspect ratio"), one of the stored pixels is
    refused naming the orientation, and serves them read as stored."""
    from PIL import Image

    for name in (NAME1, NAME2):
        image = Image.open(DATA / name).convert("RGB").transpose(Image.Transpose.ROTATE_90)
        exif = Image.Exif()
        exif[0x0112] = 6
        image.save(tmp_path / f"{Path(name).stem}.jpg", quality=95, exif=exif.tobytes())
    pairs = tmp_path / "pairs.txt"
    pairs.write_text(f"{Path(NAME1).stem}.jpg {Path(NAME2).stem}.jpg\n")
    upright = _calibration(tmp_path / "upright.yml", (640, 480), K)
    stored = _calibration(
        tmp_path / "stored.yml", (480, 640), [[fy, 0, cy], [0, fx, 639 - cx], [0, 0, 1]]
    )

    def run(calib: Path, *more: str):
        out = tmp_path / f"{calib.stem}{len(more)}.jsonl"
        args = ["pairs", str(pairs), str(tmp_path), "--calib", str(calib), "-o", str(out)]
        result = CliRunner().invoke(app, [*args, "--workers", "1", "--quiet", *more])
        lines = out.read_text().splitlines() if out.exists() else []
        return result, [json.loads(line) for line in lines]

    result, (line,) = run(upright)
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(line["cameras"]["K1"], K)
    assert abs(line["rotation_angle_deg"] - 10.9) < 0.5
    result, lines = run(stored)
    assert result.exit_code == 2 and lines == []
    assert "as stored (480x640), but its EXIF orientation turns them upright to 640x480" in (
        result.stderr
    )
    result, (line,) = run(stored, "--no-exif-orientation")
    assert result.exit_code == 0, result.output
    assert line["cameras"]["image_size1"] == [480, 640]


def test_a_pairs_file_given_as_a_dash_is_named_as_standard_input(tmp_path, monkeypatch):
    # "pairs file not found: -", as if a file named '-' were missing
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"^pairs file '-': standard input is not read; give "
                                         r"the pairs file's path$"):  # fmt: skip
        batch.read_pairs(Path("-"), K=K_TEXT)
    Path("-").write_text("a.png b.png\n")  # a file of that name is read
    assert [row["image2"] for row in batch.read_pairs(Path("-"), K=K_TEXT)] == ["b.png"]


def test_a_byte_order_mark_at_the_start_of_a_later_line_is_read_past(tmp_path):
    # two pairs files saved with a BOM and concatenated: the comment read as a pair of names
    # '\ufeff#' and 'c', the quoted names as an unclosed double quote
    pairs = tmp_path / "pairs.txt"
    parts = ("a.png b.png\r\n", "# c\r\n", '"my a.png" "my b.png"\r\n')
    pairs.write_bytes(b"".join(codecs.BOM_UTF8 + part.encode() for part in parts))
    rows = batch.read_pairs(pairs, K=K_TEXT)
    assert [(row["image1"], row["image2"], row["line"]) for row in rows] == [
        ("a.png", "b.png", 1), ("my a.png", "my b.png", 3)
    ]  # fmt: skip


@pytest.mark.parametrize("cache", [[], ["--no-cache"]], ids=["cached", "per pair"])
def test_a_name_with_windows_separators_gets_the_forward_slash_remedy(tmp_path, cache):
    # "image not found: images/sub\\demo2.png", where images/sub/demo2.png was the file meant
    (tmp_path / "images" / "sub").mkdir(parents=True)
    (tmp_path / "images" / NAME1).write_bytes((DATA / NAME1).read_bytes())
    (tmp_path / "images" / "sub" / NAME2).write_bytes((DATA / NAME2).read_bytes())
    (tmp_path / "pairs.txt").write_text(f"{NAME1} sub\\{NAME2}\n")
    args = [*COMMAND, "pairs", "pairs.txt", "images", "--K", K_TEXT, "-q", "--workers", "1"]
    done = subprocess.run([*args, *cache], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)  # fmt: skip
    assert done.returncode == 1, done.stderr
    error = json.loads(done.stdout)["error"]
    assert error.startswith("image not found: ") and error.endswith(
        f"sub\\{NAME2} (images/sub/{NAME2} exists: separate folders in names with /, not \\)"
    )


def test_pairs_with_its_two_arguments_the_other_way_round_says_which_comes_first(tmp_path):
    # it said only "pairs file images is a directory"
    (tmp_path / "images").mkdir()
    (tmp_path / "pairs.txt").write_text("a.png b.png\n")
    run = CliRunner().invoke(app, ["pairs", str(tmp_path / "images"), str(tmp_path / "pairs.txt"),
                                   "--quiet"])  # fmt: skip
    assert run.exit_code == 2 and run.stdout == ""
    assert run.stderr == (
        f"ppo-cv pairs: pairs file {tmp_path / 'images'} is a directory and image folder "
        f"{tmp_path / 'pairs.txt'} a file: the pairs file comes first, ppo-cv pairs PAIRS_FILE "
        "IMAGE_DIR\n"
    )


def test_a_run_without_ground_truth_ends_by_saying_what_it_wrote(tmp_path):
    """With ``-o`` and no ground truth ``pairs`` ended without a word on stdout, where ``pair
    --out``, ``sfm`` and ``synth`` say what they wrote and a run with ground truth prints its
    AUC: a newcomer could not tell whether the file held poses or errors."""
    (tmp_path / "images").mkdir()
    for name in (NAME1, NAME2):
        (tmp_path / "images" / name).write_bytes((DATA / name).read_bytes())
    lines = [f"{NAME1} {NAME2}", f"{NAME2} {NAME1}", f"{NAME1} absent.png"]
    (tmp_path / "pairs.txt").write_text("\n".join(lines) + "\n")
    args = [*COMMAND, "pairs", "pairs.txt", "images", "--K", K_TEXT, "--quiet", "--workers", "1"]
    out = subprocess.run([*args, "-o", "out.jsonl"], capture_output=True, text=True,
                         timeout=120, cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stdout == "wrote 3 lines to out.jsonl: 2 general motion, 1 failed\n"
    assert out.stderr == "ppo-cv pairs: warning: 1 of 3 pairs failed\n"
    assert len((tmp_path / "out.jsonl").read_text().splitlines()) == 3
    to_stdout = subprocess.run(args, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert [line[0] for line in to_stdout.stdout.splitlines()] == ["{"] * 3  # JSON lines only
