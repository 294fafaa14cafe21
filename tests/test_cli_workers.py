"""``--workers`` is capped at the work and at the CPUs this process may use (issue 44, defect 5):
``pairs --workers 48`` on two pairs started 48 interpreters, 5.6 GB, for two pairs."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ppo_cv import atomic

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])


@pytest.mark.parametrize(
    "requested, jobs, cpus, expected",
    [(48, 2, 8, 2), (48, 100, 3, 3), (0, 100, 3, 3), (None, 100, 3, 3), (0, 1, 8, 1),
     (2, 100, 8, 2), (1, 100, 8, 1), (5, 0, 8, 1)],
)  # fmt: skip
def test_workers_are_capped_at_the_jobs_and_the_cpus(monkeypatch, requested, jobs, cpus, expected):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cpus)))
    assert atomic.available_cpus() == cpus
    assert atomic.worker_count(requested, jobs) == expected


def _children(pid: int) -> set[int]:
    """The processes ``pid`` started and that are running (all its threads' children)."""
    found = set()
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            found |= {int(c) for c in Path(f"/proc/{pid}/task/{task}/children").read_text().split()}
    except OSError:
        pass
    return found


def test_pairs_starts_no_more_workers_than_pairs(tmp_path):
    names = [DEMO["image1"], DEMO["image2"]]
    (tmp_path / "images").mkdir()
    for name in names:
        shutil.copy(DATA / name, tmp_path / "images" / name)
    (tmp_path / "two.txt").write_text(f"{names[0]} {names[1]}\n{names[1]} {names[0]}\n")
    command = [sys.executable, "-m", "ppo_cv.cli.main", "pairs", "two.txt", "images", "--K",
               K_TEXT, "--workers", "48", "--max-features", "600", "-o", "out.jsonl",
               "-q"]  # fmt: skip
    process = subprocess.Popen(command, cwd=tmp_path, stderr=subprocess.PIPE, text=True)
    seen = set()
    while process.poll() is None:
        seen |= _children(process.pid)
        time.sleep(0.01)
    assert process.wait(timeout=300) == 0, process.stderr.read()
    # at most two workers and multiprocessing's resource tracker, however often they were seen
    assert 0 < len(seen) <= 3
    assert len((tmp_path / "out.jsonl").read_text().splitlines()) == 2
