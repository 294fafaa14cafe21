"""An output folder that exists, empty, but cannot be written: refused before any work, one line
and exit code 2, nothing left behind (issue 44, defect 15: the raw ``[Errno 13]`` came after
the whole run and a ``.ro.old.*`` folder stayed).

Permission bits do not stop root, so the folder is made immutable (``chattr +i``), which stops
everyone; without ``chattr`` a non-root user's ``chmod 555`` is used instead.
"""

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
CASES = {
    "pair": ["pair", *(f"images/{n}" for n in NAMES), "--K", K_TEXT, "--out", "ro"],
    "sfm": ["sfm", "images", "ro", "--K", K_TEXT],
    "synth": ["synth", "ro", "--pairs", "1", "--width", "96", "--height", "72"],
}


def _read_only(folder: Path) -> None:
    """Make ``folder`` unwritable for this process, or skip saying why that is impossible."""
    chattr = shutil.which("chattr")
    if chattr and subprocess.run([chattr, "+i", str(folder)], capture_output=True).returncode == 0:
        return
    if os.geteuid() == 0:
        pytest.skip("running as root without a working chattr: no folder is unwritable")
    folder.chmod(0o555)


def _writable_again(folder: Path) -> None:
    chattr = shutil.which("chattr")
    if chattr:
        subprocess.run([chattr, "-i", str(folder)], capture_output=True)
    folder.chmod(0o755)


@pytest.mark.parametrize("overwrite", [False, True], ids=["new", "overwrite"])
@pytest.mark.parametrize("name", list(CASES))
def test_an_unwritable_empty_output_folder_is_refused_before_the_work(tmp_path, name, overwrite):
    (tmp_path / "images").mkdir()
    for image in NAMES:
        shutil.copy(DATA / image, tmp_path / "images" / image)
    folder = tmp_path / "ro"
    folder.mkdir()
    _read_only(folder)
    try:
        assert not os.access(folder, os.W_OK)
        args = [*CASES[name], *(["--overwrite"] if overwrite else [])]
        done = subprocess.run([*COMMAND, *args], cwd=tmp_path, capture_output=True, text=True,
                              timeout=300)  # fmt: skip
    finally:
        _writable_again(folder)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"ppo-cv {name}: cannot replace ro: the folder is not writable"
    ]
    assert done.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["images", "ro"]
    assert list(folder.iterdir()) == []
