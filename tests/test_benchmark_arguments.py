"""Benchmark scripts run from a clone without the shared data: a module says which script to
run, and a script that needs the freiburg pairs says so in its usage error (exit 2), never a
traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"

MODULES = {"anchors.py": "compare.py", "rotation_rows.py": "pure_rotation.py",
           "compare_report.py": "compare.py"}  # fmt: skip
NEEDS_FREIBURG = {
    "guided_matching": (["guided_matching.py", "--limit", "1"], "no freiburg pairs in"),
    "guided_matching_variant": (["guided_matching.py", "--variants", "3"], "BAND:RATIO"),
    "guided_matching_limit": (["guided_matching.py", "--limit", "0"], "--limit must be"),
    "stage_profile_sift_parts": (["stage_profile.py", "--sift-parts", "1"], "needs the freiburg"),
    "settings": (["settings.py"], "no pairs file in"),
}


def _run(args: list[str], shared: Path) -> subprocess.CompletedProcess:
    if not (BENCHMARKS / args[0]).is_file():
        pytest.skip(f"benchmarks/{args[0]} is not in this tree")
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / args[0]), *args[1:]], capture_output=True, text=True,
        timeout=300, env={**os.environ, "PPO_CV_SHARED": str(shared)},
    )  # fmt: skip


@pytest.mark.parametrize("module", list(MODULES))
def test_a_benchmark_module_run_as_a_script_names_the_script_to_run(module, tmp_path):
    done = _run([module, "--help"], tmp_path / "none")
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.strip().endswith(f"run python benchmarks/{MODULES[module]} --help")
    assert len(done.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("case", list(NEEDS_FREIBURG), ids=list(NEEDS_FREIBURG))
def test_a_script_without_its_data_or_with_a_bad_option_is_a_usage_error(case, tmp_path):
    args, words = NEEDS_FREIBURG[case]
    done = _run(args, tmp_path / "none")
    assert done.returncode == 2 and words in done.stderr and "Traceback" not in done.stderr
    if "no freiburg" in words:
        assert str(tmp_path / "none" / "data" / "freiburg") in done.stderr
