"""Peak memory of pose identification, per point, for growing N.

Each measurement runs in a fresh interpreter: the inputs (an exact essential matrix and N
noisy pixel matches of the paper's protocol, float64) are built first, then the peak is reset
and one call is made. Two peaks are reported:

* ``traced``: the largest amount of memory held at once by Python and numpy allocations during
  the call (``tracemalloc``), which sees ppo_cv's arrays but not OpenCV's C++ buffers;
* ``rss``: the rise of the process' resident-set high-water mark (``VmHWM`` of
  ``/proc/self/status``, reset through ``/proc/self/clear_refs``), which sees both.

Run ``python benchmarks/memory.py`` (``--sizes 10000 100000 1000000``) for a markdown table.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np

__all__ = ["measure", "run", "markdown_table", "METHODS"]

METHODS = ("ppo_cv.recoverPose", "ppo_cv.recover_pose", "cv2.recoverPose")
SIZES = (10_000, 100_000, 1_000_000)


def _status_kib(field: str) -> int | None:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def _reset_high_water_mark() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def _problem(n: int) -> tuple[np.ndarray, ...]:
    """Exact E and N matches of one pose of the paper's protocol (d = 30 m, alpha 0.5, 1 px)."""
    from ppo_cv.data_gen import paper_protocol
    from ppo_cv.lsq import cross_matrix

    s = paper_protocol(1, n, alpha=0.5, noise_px=1.0, seed=0)
    R, t = s.R[0], s.t[0]
    return (
        cross_matrix(t) @ R,
        np.ascontiguousarray(s.points1[0]),
        np.ascontiguousarray(s.points2[0]),
        s.K,
    )


def measure(method: str, n: int) -> dict:
    """Peaks of one call of ``method`` on N points, in this process (see the module doc)."""
    import cv2

    import ppo_cv

    cv2.setNumThreads(1)
    E, p1, p2, K = _problem(n)
    calls = {
        "ppo_cv.recoverPose": lambda: ppo_cv.recoverPose(E, p1, p2, K),
        "ppo_cv.recover_pose": lambda: ppo_cv.recover_pose(E, p1, p2, K),
        "cv2.recoverPose": lambda: cv2.recoverPose(E, p1, p2, K),
    }
    fn = calls[method]
    small = _problem(100)
    calls_small = {  # warm every code path once, so no lazy import lands in the peak
        "ppo_cv.recoverPose": lambda: ppo_cv.recoverPose(*small),
        "ppo_cv.recover_pose": lambda: ppo_cv.recover_pose(*small),
        "cv2.recoverPose": lambda: cv2.recoverPose(*small),
    }
    calls_small[method]()
    gc.collect()
    reset = _reset_high_water_mark()
    rss_before = _status_kib("VmRSS")
    tracemalloc.start()
    result = fn()
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    hwm = _status_kib("VmHWM")
    del result
    rss = (hwm - rss_before) * 1024 if reset and hwm is not None and rss_before else None
    return {"method": method, "n": n, "traced_bytes": traced_peak, "rss_bytes": rss}


def run(sizes=SIZES, methods=METHODS) -> list[dict]:
    """One fresh interpreter per (method, N).

    glibc's dynamic mmap threshold is pinned so that large arrays freed while building the
    inputs are returned to the system instead of being reused unseen by the RSS peak.
    """
    env = {**os.environ, "MALLOC_MMAP_THRESHOLD_": "65536", "MALLOC_TRIM_THRESHOLD_": "0"}
    rows = []
    for method in methods:
        for n in sizes:
            out = subprocess.run(
                [sys.executable, __file__, "--worker", method, str(n)],
                capture_output=True,
                text=True,
                check=True,
                env=env,
            )
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return rows


def _mib(value: float | None) -> str:
    return "n/a" if value is None else f"{value / 2**20:.1f} MiB"


def markdown_table(rows: list[dict]) -> str:
    lines = [
        "| method | N | traced peak | traced bytes / point | RSS peak rise | RSS bytes / point |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        rss = r["rss_bytes"]
        lines.append(
            f"| {r['method']} | {r['n']:,} | {_mib(r['traced_bytes'])} | "
            f"{r['traced_bytes'] / r['n']:.0f} | {_mib(rss)} | "
            f"{'n/a' if rss is None else round(rss / r['n'])} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Peak memory of pose identification.")
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--worker", nargs=2, metavar=("METHOD", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(measure(args.worker[0], int(args.worker[1]))))
        return
    print(markdown_table(run(args.sizes)))


if __name__ == "__main__":
    main()
