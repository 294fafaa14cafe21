"""Standard output full (``> /dev/full``) or closed (``>&-``): exit code 2 and one line on stderr,
never a traceback or a result silently lost (issue 44, defect 13). A closed standard output is
refused before any work; a full one is found when the result is printed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
NAMES = [DEMO["image1"], DEMO["image2"]]
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]
PAIR = ["pair", *(f"images/{n}" for n in NAMES), "--K", K_TEXT, "--max-features", "600"]
COMMANDS = {
    "pair": PAIR,
    "pair --json": [*PAIR, "--json"],
    "pairs": ["pairs", "two.txt", "images", "--K", K_TEXT, "--max-features", "600", "-q"],
    "sfm": ["sfm", "images", "model", "--K", K_TEXT, "--threads", "1", "-q"],
    "synth": ["synth", "render", "--pairs", "1", "--width", "96", "--height", "72",
              "--supersample", "1", "-q"],
}  # fmt: skip
FULL = "cannot write to standard output: No space left on device"
CLOSED = f"standard output is closed; redirect it to a file or {os.devnull}"


def _close_stdout() -> None:
    os.close(1)


@pytest.mark.parametrize("stdout", ["full", "closed"])
@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_full_or_closed_stdout_is_one_line_and_exit_2(tmp_path, name, stdout):
    (tmp_path / "images").mkdir()
    for image in NAMES:
        shutil.copy(DATA / image, tmp_path / "images" / image)
    (tmp_path / "two.txt").write_text(f"{NAMES[0]} {NAMES[1]}\n{NAMES[1]} {NAMES[0]}\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    with open(os.devnull if stdout == "closed" else "/dev/full", "w") as sink:
        done = subprocess.run([*COMMAND, *COMMANDS[name]], cwd=tmp_path, stdout=sink,
                              stderr=subprocess.PIPE, text=True, timeout=600,
                              preexec_fn=_close_stdout if stdout == "closed" else None)  # fmt: skip
    command = name.split()[0]
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"ppo-cv {command}: {FULL if stdout == 'full' else CLOSED}"
    ], done.stderr
    if stdout == "closed":  # refused before any work
        assert sorted(p.name for p in tmp_path.iterdir()) == before


def _close_stderr() -> None:
    os.close(2)


@pytest.mark.parametrize("output", [[], ["--out", "result"]], ids=["summary", "--out"])
def test_a_closed_stderr_does_not_stop_a_run_or_reach_its_files(tmp_path, output):
    """``2>&-``: the run ends as with stderr open; nothing meant for stderr lands in a file the
    command opened (the first file opened would take descriptor 2)."""
    (tmp_path / "images").mkdir()
    for image in NAMES:
        shutil.copy(DATA / image, tmp_path / "images" / image)
    done = subprocess.run([*COMMAND, *PAIR, *output], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, preexec_fn=_close_stderr)  # fmt: skip
    assert done.returncode == 0
    assert done.stdout.splitlines()[1].startswith("  verdict      general motion")
    if output:
        result = json.loads((tmp_path / "result" / "result.json").read_text())
        assert result["model"] == "general"


@pytest.mark.parametrize(
    "argv, command",
    [(["--version"], "ppo-cv"), (["--help"], "ppo-cv"), (["pair", "--help"], "ppo-cv pair"),
     (["synth", "--help"], "ppo-cv synth")],
)  # fmt: skip
def test_help_and_version_into_a_closed_pipe_are_one_line_and_exit_2(argv, command):
    """``ppo-cv --help | true`` when the reader left first: as every command's result, one line
    and exit code 2 (it was a silent exit code 1)."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = subprocess.run([*COMMAND, *argv], stdout=write_end, stderr=subprocess.PIPE,
                              text=True, timeout=120)  # fmt: skip
    finally:
        os.close(write_end)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [f"{command}: cannot write to standard output: Broken pipe"]
