"""Wall time of ``ppo-cv pair`` on the built-in 640x480 demo pair, process start included.

Run ``python benchmarks/cli_time.py [--runs 7]``: prints the median wall time of the whole
command and the median of each pipeline stage as reported in its ``--json`` output.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import time


def _command() -> list[str]:
    exe = shutil.which("ppo-cv")
    return [exe] if exe else [sys.executable, "-m", "ppo_cv.cli.main"]


def run(runs: int) -> tuple[list[float], dict[str, list[float]]]:
    walls, stages = [], {}
    for _ in range(runs):
        start = time.perf_counter()
        out = subprocess.run([*_command(), "pair", "--json"], capture_output=True, text=True)
        walls.append(time.perf_counter() - start)
        if out.returncode != 0:
            raise SystemExit(f"ppo-cv pair failed: {out.stderr.strip()}")
        for stage, seconds in json.loads(out.stdout)["timings"].items():
            stages.setdefault(stage, []).append(seconds)
    return walls, stages


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args(argv)
    walls, stages = run(args.runs)
    print(f"ppo-cv pair on the demo pair, {args.runs} runs")
    print()
    print("| stage | median |")
    print("|---|---:|")
    for stage, values in stages.items():
        print(f"| {stage} | {statistics.median(values) * 1e3:.1f} ms |")
    print(f"| **whole command, process start included** | **{statistics.median(walls):.2f} s** |")


if __name__ == "__main__":
    main()
