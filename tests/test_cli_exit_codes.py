"""Exit codes of ``ppo-cv``: 0 with a result, 1 when the input was accepted but gave no pose
(``pair``, every pair of ``pairs``), 2 for bad input; each failure one line on
stderr and no output written; a number beyond the range ``pair --help`` states is bad input.
Run as subprocesses."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
DEMO1, DEMO2 = str(DATA / DEMO["image1"]), str(DATA / DEMO["image2"])
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]


@pytest.fixture(scope="module")
def images(tmp_path_factory) -> Path:
    """A folder with a blank 16-bit image, a blurred noise image, the first demo image mirrored
    and a copy of it, beside which every case runs."""
    root = tmp_path_factory.mktemp("images")
    cv2.imwrite(str(root / "const16.png"), np.full((480, 640), 1000, np.uint16))
    rng = np.random.default_rng(0)
    noise = cv2.GaussianBlur(rng.integers(0, 256, (480, 640, 3), np.uint8), (0, 0), 2)
    cv2.imwrite(str(root / "noise.png"), noise)
    cv2.imwrite(str(root / "mirror.png"), cv2.imread(DEMO1)[:, ::-1])
    (root / "copy.png").write_bytes(Path(DEMO1).read_bytes())
    return root


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*COMMAND, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(
    "args, code, pattern",
    [
        # the input accepted, no pose found: 1
        (["const16.png", DEMO2, "--K", K_TEXT], 1, r"no pose: image1 has too few features \(0\)"),
        # without intrinsics: the EXIF warnings a camera would have had are not printed either
        (["const16.png", DEMO2], 1, r"no pose: image1 has too few features \(0\): blank"),
        (
            [DEMO1, "const16.png", "--K", "1,2,-400,247.6"],
            1,
            r"no pose: image2 has too few features \(0\): blank",
        ),
        (
            [DEMO1, "noise.png", "--K", K_TEXT],
            1,
            r"no pose: (too few matches|no reliable two-view geometry)",
        ),
        (
            [DEMO1, "mirror.png", "--K", K_TEXT],
            1,
            r"no pose: the images are mirror images of each other",
        ),
        # the input refused: 2
        ([DEMO1, "copy.png", "--K", K_TEXT], 2, r"the two images are identical"),
        ([DEMO1, "absent.png", "--K", K_TEXT], 2, r"image not found: absent\.png"),
        ([DEMO1, DEMO2, "--K", "1,2,3"], 2, r"--K must be 4 numbers"),
    ],
)
@pytest.mark.parametrize("output", [["--json"], ["--out", "result"]], ids=["json", "out"])
def test_pair_exit_code_says_no_pose_or_bad_input(images, args, code, pattern, output):
    before = sorted(p.name for p in images.iterdir())
    out = _run(["pair", "-q", *args, *output], images)
    lines = out.stderr.strip().splitlines()
    assert out.returncode == code, out.stderr
    assert len(lines) == 1 and lines[0].startswith("ppo-cv pair: "), out.stderr
    assert re.search(pattern, lines[0]), lines[0]
    assert out.stdout == ""
    assert sorted(p.name for p in images.iterdir()) == before


def test_pairs_exits_1_when_no_pair_has_a_pose(images):
    (images / "pairs_none.txt").write_text("const16.png noise.png\n")
    try:
        out = _run(["pairs", "-q", "pairs_none.txt", ".", "--K", K_TEXT], images)
    finally:
        (images / "pairs_none.txt").unlink()
    assert out.returncode == 1, out.stderr
    assert out.stderr.strip().splitlines() == [
        "ppo-cv pairs: no pose: the pair failed (each JSON line names its error); const16.png "
        "noise.png: image1 has too few features (0): blank or textureless image"
    ]
    assert "too few features" in json.loads(out.stdout)["error"]


@pytest.mark.parametrize(
    "option, stated, beyond",
    [
        ("--ratio", "(1e-06..1)", "1.5"),
        ("--threshold", "(1e-06..100)", "101"),
        ("--pri-threshold", "(0..1;", "1.1"),
        ("--max-log10-nfa", "(-1e+06..1e+06;", "2e6"),
        ("--redetect-below", "(0..1000000;", "1000001"),
        ("--max-features", "(8..1000000)", "7"),
        ("--seed", "(0..2147483647)", "-1"),
    ],
)
def test_pair_help_states_each_range_it_enforces(option, stated, beyond):
    # --ratio, --threshold, --pri-threshold, --max-log10-nfa and --redetect-below said no range
    from typer.testing import CliRunner

    from ppo_cv.cli.main import app

    text = " ".join(CliRunner().invoke(app, ["pair", "--help"], terminal_width=400).stdout.split())
    described = text[text.index(f"{option} <"):][:400]
    assert stated in described.split(" --")[0], described
    out = _run(["pair", DEMO1, DEMO2, "--K", K_TEXT, option, beyond], Path.cwd())
    assert out.returncode == 2 and f"{option}" in out.stderr
    low, high = stated.strip("(;)").split("..")
    assert f"must be in {low}..{high}" in out.stderr, out.stderr


RANGE = re.compile(r"\d\.\.\d|[\[(]-?[\d.]+, [\d.]+[\])]|\d-[\d.]+\)")


@pytest.mark.parametrize("command", ["pair", "pairs", "sfm", "synth"])
def test_every_numeric_option_states_its_range_in_help(command):
    # synth's --pairs, --seed ("(>= 0)" for 0..2^32-1), --width, --height, --supersample,
    # --noise, --blur, --workers, --view-focal-error, --exposure-ev and sfm's --threads
    # enforced a range their help did not state
    from typer.testing import CliRunner

    from ppo_cv.cli.main import app

    text = CliRunner().invoke(app, [command, "--help"], terminal_width=400).stdout
    options = re.findall(r"^\s+(?:-\w, )?(--[\w-]+) <(?:int|float)>\s+(.*)$", text, re.M)
    assert len(options) >= 3, text
    unstated = [name for name, described in options if not RANGE.search(described)]
    assert unstated == [], unstated
