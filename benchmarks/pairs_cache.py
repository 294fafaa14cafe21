"""``ppo-cv pairs`` on the freiburg pairs: the old behaviour against the new defaults, one run.

Run ``python benchmarks/pairs_cache.py [--workers 2] [--seeds 0 1 2]``: runs the command as a
user does (a subprocess, JSON lines to a file, process start included), alternating the old
behaviour (``--no-cache``, features detected for every pair, with the old defaults written out on
the command line in ``OLD_DEFAULTS``) and today's defaults (each image's features detected once),
once per RANSAC seed so that an AUC change is not one lucky draw. Prints each run's wall time,
CPU time (user + system of the command and its workers: what the run cost on a shared host)
and AUC, the median wall-time and CPU-time ratios, where the worker time goes (pipeline stages
summed over the pairs) and the machine (CPU model, CPU count, load average before and after).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FREIBURG = (
    Path(os.environ.get("PPO_CV_SHARED", Path(__file__).resolve().parents[1] / ".." / "shared"))
    / "data"
    / "freiburg"
)


def _command() -> list[str]:
    """The console script of this interpreter's environment (what a user of it runs)."""
    beside = Path(sys.executable).with_name("ppo-cv")
    exe = str(beside) if beside.is_file() else shutil.which("ppo-cv")
    return [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]


OLD_DEFAULTS = [
    "--no-cache", "--no-ordered-sampling",
    "--max-features", "8000", "--ratio", "0.9", "--max-trials", "100000",
]  # fmt: skip


def run_once(old: bool, workers: int, seed: int, scratch: Path) -> dict:
    """Wall time, AUC row and summed stage times of one ``ppo-cv pairs`` run."""
    output = scratch / f"pairs_{'old' if old else 'new'}_{time.monotonic_ns()}.jsonl"
    command = [
        *_command(), "pairs", str(FREIBURG / "pairs_with_gt.txt"), str(FREIBURG / "images"),
        "--workers", str(workers), "--seed", str(seed), "-o", str(output), "--quiet",
    ]  # fmt: skip
    if old:
        command += OLD_DEFAULTS
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if out.returncode != 0:
        raise SystemExit(f"ppo-cv pairs failed: {out.stderr.strip()}")
    row = re.search(r"^\| (\d+) \| (\d+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \|$", out.stdout, re.M)
    if row is None:
        raise SystemExit(f"no AUC table in the output:\n{out.stdout}")
    stages: dict[str, float] = {}
    for line in output.read_text().splitlines():
        for stage, seconds in json.loads(line).get("timings", {}).items():
            stages[stage] = stages.get(stage, 0.0) + seconds
    return {
        "wall": wall,
        "cpu": cpu,
        "pairs": int(row.group(1)),
        "failed": int(row.group(2)),
        "auc": tuple(float(row.group(i)) for i in (3, 4, 5)),
        "stages": stages,
    }


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _load() -> str:
    return ", ".join(f"{v:.1f}" for v in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="RANSAC seeds")
    args = parser.parse_args(argv)
    if not (FREIBURG / "pairs_with_gt.txt").is_file():
        raise SystemExit(f"freiburg pairs not found in {FREIBURG}; set PPO_CV_SHARED")
    load_before = _load()
    results: dict[bool, list[dict]] = {True: [], False: []}
    with tempfile.TemporaryDirectory(prefix="ppo-cv-bench-") as scratch:
        for seed in args.seeds:
            for old in (True, False):
                results[old].append(run_once(old, args.workers, seed, Path(scratch)))
                r = results[old][-1]
                label = "old" if old else "new"
                line = f"{label} seed {seed}: {r['wall']:.1f} s wall, {r['cpu']:.1f} s CPU"
                print(f"{line}, AUC {r['auc']}", file=sys.stderr, flush=True)
    walls = {old: statistics.median(r["wall"] for r in rs) for old, rs in results.items()}
    cpus = {old: statistics.median(r["cpu"] for r in rs) for old, rs in results.items()}
    print(
        f"ppo-cv pairs on the {results[False][0]['pairs']} freiburg pairs, --workers "
        f"{args.workers}, seeds {' '.join(map(str, args.seeds))}; {_cpu_model()}, "
        f"{os.cpu_count()} CPUs, load average (1/5/15 min) {load_before} before and {_load()} "
        f"after, Python {platform.python_version()}"
    )
    print(f"old: {' '.join(OLD_DEFAULTS)}; new: the defaults (features once per image)")
    print("pose error = max(rotation error, translation-direction error); failures count as 180")
    print()
    print("| run | seed | wall time | CPU time | AUC@5 / 10 / 20 | failed |")
    print("|---|---:|---:|---:|---|---:|")
    for old, label in ((True, "old"), (False, "new")):
        for seed, r in zip(args.seeds, results[old], strict=True):
            auc = " / ".join(f"{v:.1f}" for v in r["auc"])
            times = f"{r['wall']:.1f} s | {r['cpu']:.1f} s"
            print(f"| {label} | {seed} | {times} | {auc} | {r['failed']} |")
    for old, label in ((True, "old"), (False, "new")):
        mean = [statistics.mean(r["auc"][i] for r in results[old]) for i in range(3)]
        print(
            f"| {label}, mean | | {walls[old]:.1f} s (median) | {cpus[old]:.1f} s (median) | "
            + " / ".join(f"{v:.1f}" for v in mean)
            + " | |"
        )
    print()
    print(f"speed-up (median wall time old / new): {walls[True] / walls[False]:.2f}x")
    print(f"CPU time (median old / new): {cpus[True] / cpus[False]:.2f}x")
    print()
    print(
        "Pipeline stages summed over the pairs (seconds of worker time, first seed; with the "
        "cache, detection runs once per image before the pairs and is not in this table):"
    )
    print()
    stages = list(results[True][0]["stages"])
    print("| run | " + " | ".join(stages) + " |")
    print("|---|" + "---:|" * len(stages))
    for old, label in ((True, "old"), (False, "new")):
        s = results[old][0]["stages"]
        print(f"| {label} | " + " | ".join(f"{s.get(k, 0.0):.1f}" for k in stages) + " |")


if __name__ == "__main__":
    main()
