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
from pathlib import Path


def _command() -> list[str]:
    """The console script of this interpreter's environment (what a user of it runs)."""
    beside = Path(sys.executable).with_name("ppo-cv")
    exe = str(beside) if beside.is_file() else shutil.which("ppo-cv")
    if exe is None:
        raise SystemExit("ppo-cv is not installed: pip install .")
    return [exe]


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
