"""``ppo-cv pairs`` on the freiburg pairs with the per-run feature cache and without it.

Run ``python benchmarks/pairs_cache.py [--workers 2] [--runs 1]``: runs the command as a user
does (a subprocess, JSON lines to a file, process start included), alternating
``--no-cache`` (features detected for every pair, as before the cache) and the default (each
image's features detected once), and prints the wall times, their ratio, the AUC of each and
where the time goes (the pipeline stages summed over the pairs), with the machine stated.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
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


def run_once(cache: bool, workers: int, scratch: Path) -> dict:
    """Wall time, AUC row and summed stage times of one ``ppo-cv pairs`` run."""
    output = scratch / f"pairs_{'cache' if cache else 'nocache'}_{time.monotonic_ns()}.jsonl"
    command = [
        *_command(), "pairs", str(FREIBURG / "pairs_with_gt.txt"), str(FREIBURG / "images"),
        "--workers", str(workers), "-o", str(output), "--quiet",
    ]  # fmt: skip
    if not cache:
        command.append("--no-cache")
    start = time.perf_counter()
    out = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - start
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
        "pairs": int(row.group(1)),
        "failed": int(row.group(2)),
        "auc": tuple(float(row.group(i)) for i in (3, 4, 5)),
        "stages": stages,
    }


def _machine() -> str:
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"load average {load} at the end, Python {platform.python_version()}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--runs", type=int, default=1, help="runs of each, alternating")
    args = parser.parse_args(argv)
    if not (FREIBURG / "pairs_with_gt.txt").is_file():
        raise SystemExit(f"freiburg pairs not found in {FREIBURG}; set PPO_CV_SHARED")
    results: dict[bool, list[dict]] = {False: [], True: []}
    with tempfile.TemporaryDirectory(prefix="ppo-cv-bench-") as scratch:
        for _ in range(args.runs):
            for cache in (False, True):
                results[cache].append(run_once(cache, args.workers, Path(scratch)))
    walls = {cache: statistics.median(r["wall"] for r in rs) for cache, rs in results.items()}
    print(
        f"ppo-cv pairs on the {results[True][0]['pairs']} freiburg pairs, --workers "
        f"{args.workers}, median of {args.runs} run(s) each; {_machine()}"
    )
    print("pose error = max(rotation error, translation-direction error)")
    print()
    print("| features | wall time | AUC@5 / 10 / 20 | failed | speed-up |")
    print("|---|---:|---|---:|---:|")
    for cache, label in ((False, "per pair (--no-cache)"), (True, "once per image (default)")):
        r = results[cache][0]
        auc = " / ".join(f"{v:.1f}" for v in r["auc"])
        ratio = walls[False] / walls[cache]
        print(f"| {label} | {walls[cache]:.1f} s | {auc} | {r['failed']} | {ratio:.2f}x |")
    print()
    print(
        "Pipeline stages summed over the pairs (seconds of worker time, first run; with the "
        "cache, detection runs once per image before the pairs and is not in this table):"
    )
    print()
    stages = list(results[False][0]["stages"])
    print("| features | " + " | ".join(stages) + " |")
    print("|---|" + "---:|" * len(stages))
    for cache, label in ((False, "per pair"), (True, "once per image")):
        s = results[cache][0]["stages"]
        print(f"| {label} | " + " | ".join(f"{s.get(k, 0.0):.1f}" for k in stages) + " |")


if __name__ == "__main__":
    main()
