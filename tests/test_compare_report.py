"""The whole-pair section of the side-by-side benchmark: its options and its table."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "compare.py"


@pytest.fixture(scope="module")
def compare_report():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location(
            "compare_report_under_test", ROOT / "benchmarks" / "compare_report.py"
        )
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return module


@pytest.mark.parametrize(
    "args, message",
    [
        (["--baseline", "{tmp}"], "--baseline"),
        (["--only-pipeline", "--baseline", "{tmp}"], "holds no ppo_cv package"),
        (["--only-pipeline", "--out", "{tmp}"], "needs the results of a full run"),
    ],
)
def test_bad_pipeline_options_exit_2_with_a_message(args, message, tmp_path):
    args = [arg.replace("{tmp}", str(tmp_path)) for arg in args]
    done = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)
    assert done.returncode == 2 and message in done.stderr.splitlines()[-1]
    assert not (tmp_path / "results.json").exists()


def test_whole_pair_section_lists_wall_and_cpu_time_and_the_baseline(compare_report):
    pipe = {
        "ppo_cv estimate_pair": 0.15,
        "OpenCV pipeline": 0.2,
        "cpu": {"ppo_cv estimate_pair": 0.25, "OpenCV pipeline": 0.19},
        "stages": {"features": 0.08, "matching": 0.004},
        "stage_cpu": {"features": 0.07, "matching": 0.003},
        "median_pair": {"index": 4, "cpu": 0.2, "stage_cpu": {"features": 0.06, "matching": 0.005}},
        "pairs": 10,
        "source": "freiburg",
        "machine": {"cpu": "Some CPU", "cores": 2, "load": 1.5, "load_after": 2.25},
        "baseline": {
            "label": "before",
            "ppo_cv estimate_pair": 0.3,
            "cpu": {"ppo_cv estimate_pair": 0.4},
            "stages": {"features": 0.09},
        },
    }
    lines = compare_report.pipeline_lines(pipe, "figs")
    head = lines.index("| pipeline | median wall s / pair | median CPU s / pair |")
    assert lines[head + 2 : head + 5] == [
        "| ppo_cv estimate_pair, before | 0.300 | 0.400 |",
        "| ppo_cv estimate_pair | 0.150 | 0.250 |",
        "| OpenCV pipeline | 0.200 | 0.190 |",
    ]
    stages = lines.index(
        "| stage | median wall ms | median CPU ms | CPU ms of the median pair "
        "| median wall ms, before |"
    )
    assert lines[stages + 2 : stages + 4] == [
        "| features | 80.0 | 70.0 | 60.0 | 90.0 |",
        "| matching | 4.0 | 3.0 | 5.0 |  |",
    ]
    assert any("Some CPU, 2 logical cores" in line and "1.50" in line for line in lines)


def test_whole_pair_section_counts_the_pairs_at_or_below_opencv(compare_report):
    per_pair = [
        {"wall": 0.15, "cpu": 0.25, "opencv_wall": 0.2, "opencv_cpu": 0.19, "detections": 1},
        {"wall": 0.3, "cpu": 0.18, "opencv_wall": 0.2, "opencv_cpu": 0.19, "detections": 2},
        {"wall": 0.2, "cpu": 0.3, "opencv_wall": 0.2, "opencv_cpu": 0.19, "detections": 2},
    ]
    pipe = {"ppo_cv estimate_pair": 0.2, "OpenCV pipeline": 0.2, "pairs": 3,
            "source": "freiburg", "per_pair": per_pair}  # fmt: skip
    lines = compare_report.pipeline_lines(pipe, "figs")
    assert any("2 of 3 by wall time, 1 of 3 by CPU time" in line for line in lines)
    head = lines.index(
        "| pair | estimate_pair wall / CPU s | OpenCV pipeline wall / CPU s | detections |"
    )
    assert lines[head + 2 : head + 5] == [
        "| 0 | 0.150 / 0.250 | 0.200 / 0.190 | 1 |",
        "| 1 | 0.300 / 0.180 | 0.200 / 0.190 | 2 |",
        "| 2 | 0.200 / 0.300 | 0.200 / 0.190 | 2 |",
    ]


def test_stage_cpu_covers_every_stage_of_estimate_pair_within_its_total():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("compare_under_test", SCRIPT)
        compare = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(compare)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    import time

    import cv2

    from ppo_cv.data_gen.io import make_pair

    pair = make_pair("general", seed=0, index=0)
    bgr1, bgr2 = (cv2.cvtColor(image, cv2.COLOR_RGB2BGR) for image in (pair.image1, pair.image2))
    start = time.process_time()
    stage_cpu = compare.StageCPU()
    result = compare.run_ppo_cv(bgr1, bgr2, pair.K1, pair.K2, progress=stage_cpu)
    total = time.process_time() - start
    assert result.R is not None
    assert list(stage_cpu.seconds) == list(result.extra["timings"])
    assert all(seconds >= 0 for seconds in stage_cpu.seconds.values())
    assert 0 < stage_cpu.seconds["features"] <= sum(stage_cpu.seconds.values()) <= total
