#!/usr/bin/env python3
"""PPO-seeded incremental SfM against pycolmap's default initialisation.

Usage: python benchmarks/sfm_compare.py [--freiburg DIR] [--views N_PAN N_MOVE] [--steps S ...]
                                        [--repeat R] [--threads T]

Data sets:

* ``tripod-<step>``: rendered views of one textured room (``ppo_cv.data_gen``) from a camera
  that first pans on a tripod (pure rotations: the pairs with the most matches) and then walks
  sideways with the given stride in metres; exact poses are known.
* ``freiburg``: the 17 real frames of ``../shared/data/freiburg`` with their intrinsics and the
  pseudo ground truth of ``pairs_with_gt.txt`` (skipped when absent).

For each set and each initialisation (the PPO ranking with either seeding, and pycolmap's
default) the script reports the initial pair (and whether it is a pure rotation, for the
rendered sets), registered images, 3D points, mean reprojection error, the median
relative-rotation and translation-direction error of the registered cameras against ground
truth over all image pairs, and the time of pair scoring plus mapping (features and matches are
computed once per set and shared). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from ppo_cv import sfm
from ppo_cv.data_gen import read_pairs, relative_gt_from_poses, render_tripod_then_move

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PPO_CV_SHARED", ROOT.parent / "shared"))
FREIBURG = SHARED / "data" / "freiburg"
CONFIGURATIONS = (
    ("ppo two-view", "ppo", "two-view"),
    ("ppo pair-options", "ppo", "pair-options"),
    ("colmap default", "colmap", "two-view"),
)
"""(label, initialization, seeding) of the runs; seeding is unused by ``colmap``."""
FREIBURG_K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


def load_freiburg_gt(pairs_file: Path) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """``(name1, name2) -> (R, t)`` with ``X2 = R X1 + t`` from a pairs-with-gt file."""
    return {(r["name1"], r["name2"]): (r["R"], r["t"]) for r in read_pairs(pairs_file)}


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def compare(name: str, image_dir: Path, K: np.ndarray, gt, pure_rotation_names=frozenset(),
            num_threads: int = 2, repeat: int = 1) -> list[dict]:  # fmt: skip
    """Run both initialisations on one image folder; one row per initialisation."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="sfm-compare-") as scratch:
        database = Path(scratch) / "db.db"
        sfm.prepare_database(image_dir, database, K=K, num_threads=num_threads)
        if pure_rotation_names:
            print(ranking_note(name, sfm.score_pairs(database), pure_rotation_names))
        for label, initialization, seeding in CONFIGURATIONS:
            runs = [
                sfm.reconstruct(
                    database,
                    image_dir,
                    initialization=initialization,
                    seeding=seeding,
                    fix_intrinsics=True,
                    num_threads=num_threads,
                )
                for _ in range(repeat)
            ]
            result = runs[-1]
            pair = result.initial_pair
            rotation_errors, translation_errors = (
                sfm.pose_errors(result.reconstruction, gt) if result.reconstruction else ([], [])
            )
            rows.append(
                {
                    "set": name,
                    "init": label,
                    "initial pair": " ".join(pair) if pair else "-",
                    "pure rotation pair": bool(pair and set(pair) <= pure_rotation_names),
                    "registered": f"{result.num_registered}/{result.num_images}",
                    "models": result.num_models,
                    "points": result.num_points3D,
                    "reproj px": result.mean_reprojection_error,
                    "rot err med deg": _median(rotation_errors),
                    "t dir err med deg": _median(translation_errors),
                    "time s": statistics.median(r.elapsed for r in runs),
                }
            )
    return rows


def ranking_note(name: str, pairs: list, pure_rotation_names: frozenset) -> str:
    """One line on how the pure-rotation pairs ranked by matches and how PPO scored them."""
    pure = [p for p in pairs if {p.name1, p.name2} <= pure_rotation_names]
    other = [p for p in pairs if p not in pure]
    by_matches = sorted(pairs, key=lambda p: -p.num_matches)
    top = next(i for i, p in enumerate(by_matches) if p not in pure)
    return (
        f"{name}: by match count the first pair with a baseline ranks {top + 1} of {len(pairs)}; "
        f"{len(pure)} pure-rotation pairs, {min(p.num_matches for p in pure)}-"
        f"{max(p.num_matches for p in pure)} matches, PRI {min(p.pri for p in pure):.4f}-"
        f"{max(p.pri for p in pure):.4f}, rejected as pure rotation: "
        f"{sum(p.rejection.startswith('pure rotation') for p in pure)}; "
        f"{len(other)} other pairs, PRI {min(p.pri for p in other):.4f}-"
        f"{max(p.pri for p in other):.4f}, accepted: {sum(p.accepted for p in other)}, "
        f"largest median triangulation angle {max(p.tri_angle for p in other):.1f} deg"
    )


def markdown(rows: list[dict]) -> str:
    header = list(rows[0])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        cells = []
        for value in row.values():
            cells.append(f"{value:.3f}" if isinstance(value, float) else str(value))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--freiburg", type=Path, default=FREIBURG)
    parser.add_argument("--views", type=int, nargs=2, default=(4, 4), metavar=("N_PAN", "N_MOVE"))
    parser.add_argument("--steps", type=float, nargs="+", default=(0.45, 0.08),
                        help="walk strides (m) of the rendered sets")  # fmt: skip
    parser.add_argument("--repeat", type=int, default=1, help="runs per timing (median)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    rows = []
    for step in args.steps:
        with tempfile.TemporaryDirectory(prefix="sfm-tripod-") as scratch:
            names, K, poses = render_tripod_then_move(scratch, *args.views, step=step)
            pan = frozenset(n for n in names if "pan" in n)
            gt = relative_gt_from_poses(names, poses)
            rows += compare(
                f"tripod-{step:g}", Path(scratch), K, gt, pan, args.threads, args.repeat
            )
    if (args.freiburg / "pairs_with_gt.txt").is_file():
        gt = load_freiburg_gt(args.freiburg / "pairs_with_gt.txt")
        rows += compare("freiburg", args.freiburg / "images", FREIBURG_K, gt,
                        num_threads=args.threads, repeat=args.repeat)  # fmt: skip
    else:
        print(f"freiburg data not found at {args.freiburg}; skipped", file=sys.stderr)
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
