"""Pose identification time: ``ppo_cv.recoverPose`` against ``cv2.recoverPose``.

Both functions get the same essential matrix, the same pixel points and the same camera
matrix (OpenCV's first call form), in one process, interleaved so that both see the same
machine state. Points follow the paper's simulation protocol (Section 5: d = 30 m, parallax
factor 0.5, 1 px noise); ``E`` is the exact ``[t]x R`` of the ground truth, so both functions
only choose among the four candidates of ``E`` and no RANSAC is timed.

Run ``python benchmarks/identification.py`` (``--quick`` for fewer repeats); prints a markdown
table of median times and the ratio cv2 / ppo_cv for each N.
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

import cv2
import numpy as np

import ppo_cv
from ppo_cv.data_gen import paper_protocol
from ppo_cv.robust import essential_from_pose

sys.path.insert(0, str(Path(__file__).resolve().parent / "paper"))
from timing import per_call  # noqa: E402

__all__ = ["identification_problem", "time_call", "run", "main"]

SIZES = (50, 1000, 100_000)
GOALS = {50: 5.0, 1000: 30.0, 100_000: 50.0}


def identification_problem(n_points: int, seed: int = 0) -> tuple[np.ndarray, ...]:
    """``(E, points1, points2, K, R, t)`` for one pose of the paper's protocol with N points."""
    sample = paper_protocol(1, n_points, alpha=0.5, noise_px=1.0, seed=seed)
    R, t = sample.R[0], sample.t[0]
    return essential_from_pose(R, t), sample.points1[0], sample.points2[0], sample.K, R, t


def time_call(fn, repeats: int, min_seconds: float = 0.02, best_of: int = 3) -> np.ndarray:
    """Seconds per call of ``fn()``: ``repeats`` samples of :func:`per_call` (the fastest of
    ``best_of`` loops lasting about ``min_seconds``, so that timer resolution and a busy
    machine's interruptions do not dominate microsecond calls)."""
    fn()
    return np.array([per_call(fn, min_seconds, best_of) for _ in range(repeats)])


def run(sizes=SIZES, repeats: int = 15) -> list[dict]:
    """Median identification times of both functions for each N, interleaved."""
    rows = []
    for n in sizes:
        E, p1, p2, K, R, t = identification_problem(n)
        ours = partial(ppo_cv.recoverPose, E, p1, p2, K)
        theirs = partial(cv2.recoverPose, E, p1, p2, K)
        times = {"ppo_cv": [], "cv2": []}
        for _ in range(repeats):
            times["ppo_cv"].append(time_call(ours, 1)[0])
            times["cv2"].append(time_call(theirs, 1)[0])
        _, R_ours, t_ours, _ = ours()
        _, R_cv, t_cv, _ = theirs()
        agree = np.allclose(R_ours, R_cv, atol=1e-9) and np.allclose(t_ours, t_cv, atol=1e-9)
        ppo_med, cv_med = np.median(times["ppo_cv"]), np.median(times["cv2"])
        rows.append(
            {
                "n": n,
                "ppo_cv_s": ppo_med,
                "cv2_s": cv_med,
                "ratio": cv_med / ppo_med,
                "goal": GOALS.get(n),
                "same_pose": bool(agree),
            }
        )
    return rows


def _fmt_time(seconds: float) -> str:
    return f"{seconds * 1e6:.1f} us" if seconds < 1e-3 else f"{seconds * 1e3:.2f} ms"


def markdown_table(rows: list[dict]) -> str:
    lines = [
        "| N | ppo_cv.recoverPose | cv2.recoverPose | speed-up (cv2 / ppo_cv) | goal | same pose |",
        "|---:|---:|---:|---:|---:|:---:|",
    ]
    for r in rows:
        goal = f"{r['goal']:.0f}x" if r["goal"] else "-"
        met = "" if not r["goal"] else (" (met)" if r["ratio"] >= r["goal"] else " (missed)")
        lines.append(
            f"| {r['n']} | {_fmt_time(r['ppo_cv_s'])} | {_fmt_time(r['cv2_s'])} | "
            f"{r['ratio']:.1f}x | {goal}{met} | {'yes' if r['same_pose'] else 'no'} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=15, help="timing samples per function")
    parser.add_argument("--quick", action="store_true", help="5 samples instead of 15")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    rows = run(repeats=5 if args.quick else args.repeats)
    print(
        f"OpenCV {cv2.__version__}, numpy {np.__version__}, one thread for OpenCV; "
        "median of interleaved samples, each the fastest of 3 timing loops"
    )
    print()
    print(markdown_table(rows))


if __name__ == "__main__":
    main()
