"""SIGTERM and SIGINT to the whole process group of a command, at known points of its run.

What ``timeout``, a service manager or Ctrl-C at a terminal do: the signal reaches the command
and its worker processes alike. Whenever it lands the command must end with one line on stderr
(``ppo-cv <command>: interrupted; unfinished output removed``), exit code 143 for SIGTERM and
130 for SIGINT, no traceback or native stack dump, no process of the group left running, and
nothing new in its folder. ``benchmarks/signals.py`` sends the same signals at random times.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
NAMES = [DEMO["image1"], DEMO["image2"]]
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]
WAIT_SECONDS = 120  # a bound on a stuck run, not a measurement
PROGRESS = re.compile(  # progress lines, printed before the signal
    r"ppo-cv \w+: \d+/\d+ |ppo-cv sfm: (extracting|matching|scoring|seeding) "
)

PAIRS = ["pairs", "six.txt", "images", "--K", K_TEXT, "-o", "out.jsonl", "--workers", "2",
         "--max-features", "600"]  # fmt: skip
PAIR = ["pair", *(f"images/{n}" for n in NAMES), "--K", K_TEXT, "--out", "result"]
SFM = ["sfm", "images", "model", "--K", K_TEXT, "--threads", "1"]


def _inputs(folder: Path) -> set[str]:
    (folder / "images").mkdir()
    for name in NAMES:
        shutil.copy(DATA / name, folder / "images" / name)
    (folder / "six.txt").write_text(f"{NAMES[0]} {NAMES[1]}\n{NAMES[1]} {NAMES[0]}\n" * 3)
    return _entries(folder)


def _entries(folder: Path) -> set[str]:
    return {str(path.relative_to(folder)) for path in folder.rglob("*")}


def _mapped(pid: int, library: str) -> bool:
    """Whether the process has loaded a shared library whose path holds ``library``."""
    try:
        return library in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _signal_when(args, folder: Path, ready, signum: int) -> tuple[int, str]:
    """Run ``args`` in ``folder`` in a new process group; once ``ready(process, stderr lines so
    far)`` holds, send ``signum`` to the group; the exit code and the whole stderr."""
    # as at a terminal: a runner started in the background passes SIGINT on ignored
    process = subprocess.Popen([*COMMAND, *args], cwd=folder, start_new_session=True, text=True,
                               stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, preexec_fn=_default_sigint)  # fmt: skip
    try:
        ready(process)
        os.killpg(process.pid, signum)
        _, err = process.communicate(timeout=WAIT_SECONDS)
        deadline = time.monotonic() + WAIT_SECONDS
        while _group_alive(process.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _group_alive(process.pid), "a process of the group is still running"
    finally:
        if _group_alive(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
        process.kill()
    return process.returncode, err


def _loading(library: str):
    """Ready once the command has mapped ``library`` (it is being imported)."""

    def ready(process) -> None:
        deadline = time.monotonic() + WAIT_SECONDS
        while not _mapped(process.pid, library):
            assert process.poll() is None and time.monotonic() < deadline, "never loaded"
            time.sleep(0.002)

    return ready


def _printed(needle: str):
    """Ready once the command has printed a stderr line holding ``needle``."""

    def ready(process) -> None:
        for line in process.stderr:
            if needle in line:
                return
        raise AssertionError(f"{needle!r} never appeared")

    return ready


# (arguments, when the signal is sent, signal)
CASES = {
    "pair-startup-SIGINT": (PAIR, _loading("_multiarray_umath"), signal.SIGINT),
    "pair-startup-SIGTERM": (PAIR, _loading("_multiarray_umath"), signal.SIGTERM),
    "pair-pycolmap-import-SIGTERM": (PAIR, _loading("pycolmap"), signal.SIGTERM),
    "pair-pycolmap-import-SIGINT": (PAIR, _loading("pycolmap"), signal.SIGINT),
    "sfm-pycolmap-import-SIGTERM": (SFM, _loading("pycolmap"), signal.SIGTERM),
    "pairs-pycolmap-import-SIGTERM": (PAIRS, _loading("pycolmap"), signal.SIGTERM),
    "pairs-features-SIGTERM": (PAIRS, _printed("images (features), "), signal.SIGTERM),
    "pairs-pairs-SIGTERM": (PAIRS, _printed(" pairs, "), signal.SIGTERM),
    "pairs-pairs-SIGINT": (PAIRS, _printed(" pairs, "), signal.SIGINT),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_signal_to_the_process_group_is_one_line_and_leaves_nothing(tmp_path, case):
    args, ready, signum = CASES[case]
    before = _inputs(tmp_path)
    code, err = _signal_when(args, tmp_path, ready, signum)
    lines = [line for line in err.strip().splitlines() if not PROGRESS.match(line)]
    assert code == 128 + signum, err
    assert lines == [f"ppo-cv {args[0]}: interrupted; unfinished output removed"], err
    assert _entries(tmp_path) == before


def test_a_signal_inside_pycolmap_s_feature_extraction_is_one_line(tmp_path):
    # pycolmap logs "Stopping thread..." when an interrupt stops its threaded extraction
    before = _inputs(tmp_path)
    for copy in range(12):
        for name in NAMES:  # one pixel changed: sfm skips byte-for-byte copies
            image = cv2.imread(str(DATA / name))
            image[0, 0, 0] ^= copy + 1
            assert cv2.imwrite(str(tmp_path / "images" / f"{copy}_{name}"), image)
    printed = _printed("extracting SIFT features")

    def ready(process) -> None:
        printed(process)
        time.sleep(1.0)  # into the extraction of 26 images, which takes several seconds

    code, err = _signal_when(SFM, tmp_path, ready, signal.SIGTERM)
    lines = [line for line in err.strip().splitlines() if not PROGRESS.match(line)]
    assert code == 128 + signal.SIGTERM, err
    assert lines == ["ppo-cv sfm: interrupted; unfinished output removed"], err
    assert _entries(tmp_path) - before == {f"images/{c}_{n}" for c in range(12) for n in NAMES}


def test_sigkill_leaves_no_temporary_file(tmp_path):
    # the JSON lines have no name until they are complete: a killed run leaves nothing
    before = _inputs(tmp_path)
    args = [*PAIRS[:-4], "--workers", "1", "--max-features", "600"]
    code, _ = _signal_when(args, tmp_path, _printed(" pairs, "), signal.SIGKILL)
    assert code == -signal.SIGKILL
    assert _entries(tmp_path) == before


def test_the_next_run_removes_what_a_killed_run_left(tmp_path):
    # a folder output cannot be unnamed as a file can: its staging folder, named after the
    # killed process, goes at the next run for the same output
    synth = ["synth", "out", "--width", "96", "--height", "72", "--supersample", "1", "-q"]

    def staging_exists(process) -> None:
        deadline = time.monotonic() + WAIT_SECONDS
        while not any(tmp_path.iterdir()):
            assert process.poll() is None and time.monotonic() < deadline, "nothing was started"
            time.sleep(0.01)

    code, _ = _signal_when([*synth, "--pairs", "200", "--workers", "1"], tmp_path,
                           staging_exists, signal.SIGKILL)  # fmt: skip
    assert code == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and re.fullmatch(r"\.out\.\d+\.[a-z0-9_]{8}", left[0]), left
    done = subprocess.run([*COMMAND, *synth, "--pairs", "1"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=WAIT_SECONDS)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
