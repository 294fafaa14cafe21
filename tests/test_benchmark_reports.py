"""The committed pure-rotation report is what its script makes of the committed rows."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "pure_rotation.py"
ROWS = ROOT / "benchmarks" / "pure_rotation.json"
REPORT = ROOT / "docs" / "pure_rotation.md"


@pytest.fixture(scope="module")
def script():
    if not (SCRIPT.is_file() and ROWS.is_file() and REPORT.is_file()):
        pytest.skip("the benchmark script, its rows or its report are not in this tree")
    spec = importlib.util.spec_from_file_location("pure_rotation_benchmark", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_report_is_regenerated_from_the_stored_rows(script):
    saved = json.loads(ROWS.read_text())
    seconds = saved.pop("_seconds")
    text = script.report(saved, seconds, "benchmarks/pure_rotation_statistic.png")
    # the paragraph after the title names the versions of the machine that renders it
    title, made_by, made = text.split("\n\n", 2)
    committed_title, committed_by, committed = REPORT.read_text().split("\n\n", 2)
    assert made == committed and title == committed_title
    assert made_by.startswith("Made by") and f"in one run of {seconds:.0f} s" in committed_by


def test_report_counts_flags_as_the_rows_say(script):
    saved = json.loads(ROWS.read_text())
    rows = saved["data_gen warped photo, exposure and vignetting"]["rows"]
    flagged = sum(bool(row["ppo_cv_flag"]) for row in rows)
    line = next(
        line
        for line in REPORT.read_text().splitlines()
        if line.startswith("| data_gen warped photo, exposure and vignetting |")
    )
    cells = [cell.strip() for cell in line.split("|")[1:-1]]
    assert cells[2] == str(len(rows))
    assert cells[3] == f"{100.0 * flagged / len(rows):.0f} %"


def test_benchmarks_page_summarises_the_stored_rows(script, monkeypatch):
    """Section 3 of docs/benchmarks.md is what compare_report makes of the committed rows."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location(
        "compare_report_under_test", ROOT / "benchmarks" / "compare_report.py"
    )
    compare_report = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(compare_report)
    lines = compare_report.pure_rotation_lines("benchmarks", ROWS)
    page = (ROOT / "docs" / "benchmarks.md").read_text()
    assert "\n".join(lines) in page
    saved = json.loads(ROWS.read_text())
    translating = [
        row
        for name, data in saved.items()
        if not name.startswith(("_", "sweep")) and "focal_ratio" not in data
        and data["label"] == 0 and name != "freiburg"
        for row in data["rows"]
        if "error" not in row
    ]  # fmt: skip
    flagged = sum(bool(row["ppo_cv_flag"]) for row in translating)
    line = next(line for line in lines if line.startswith("| translating renders"))
    cells = [cell.strip() for cell in line.split("|")[1:-1]]
    assert cells[1:3] == [str(len(translating)), f"{100.0 * flagged / len(translating):.0f} %"]


def test_a_missing_pano_dev_folder_gives_a_row_that_says_so(script, monkeypatch, tmp_path):
    monkeypatch.setattr(script, "PANO_DEV", tmp_path / "pano_dev")
    results = script.run(quick=True, sets=["pano_dev"])
    assert list(results) == ["pano_dev"]
    skipped = results["pano_dev"]
    assert skipped["rows"] == [] and "pairs_with_gt.txt" in skipped["skipped"]
    line = next(
        line for line in script.report(results, 1.0, None).splitlines()
        if line.startswith("| pano_dev |")
    )  # fmt: skip
    assert "| 0 | skipped: no " in line and str(tmp_path) in line


@pytest.mark.parametrize(
    "args, message",
    [(["--merge"], "--merge needs --sets"), (["--workers", "0"], "--workers must be at least 1")],
)
def test_bad_benchmark_options_exit_2_with_a_message(args, message):
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)
    assert done.returncode == 2 and message in done.stderr
