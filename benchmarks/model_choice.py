"""The model estimate_pair chooses per rendered preset, beside pycolmap's, and every anchor's AUC.

Usage (from the repository root)::

    python benchmarks/model_choice.py --seeds 0 1 --pairs 5 --jobs 2 [--motions planar ...]

For every preset of ``ppo_cv.data_gen.MOTIONS`` (640x480), clean and with the imperfections of
real photos (``data_gen.REAL_PHOTO``, every method given the slightly wrong ``K1_given``,
``K2_given``), ``make_pair(motion, seed, index)`` is estimated by

``estimate_pair``
    the pipeline, with the homography and the three-model decision (:mod:`ppo_cv.motion_model`);
``estimate_pair (no plane)``
    the same with ``PairOptions(plane=False)``: rotation or general only, the pipeline before
    the plane was wired in;

and by every anchor of ``anchors.py`` on shared SIFT matches. Printed: the confusion table
(rows: presets, columns: how many pairs ``estimate_pair`` called rotation / plane / general,
and pycolmap's TwoViewGeometry configurations of the same pairs), then the AUC@5/10/20 of the
pose error (the larger of the rotation and translation-direction errors, degrees; rotation error
alone for a pure rotation) per preset and method. Nothing is written.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402

from ppo_cv import estimate_pair  # noqa: E402
from ppo_cv.pipeline import PairOptions  # noqa: E402

PIPELINES = ("estimate_pair", "estimate_pair (no plane)")
METHODS = (*PIPELINES, *anchors.ANCHORS)
MODELS = ("rotation", "plane", "general", "failed")


def evaluate(task: tuple[str, int, int, bool]) -> dict:
    """Pose errors of every method and the models chosen, for one rendered pair."""
    from ppo_cv.data_gen import REAL_PHOTO, make_pair

    motion, seed, index, imperfect = task
    cv2.setNumThreads(1)
    pair = make_pair(
        motion, seed=seed, index=index, imperfections=REAL_PHOTO if imperfect else None
    )
    K1 = pair.K1 if pair.K1_given is None else pair.K1_given
    K2 = pair.K2 if pair.K2_given is None else pair.K2_given
    bgr1 = cv2.cvtColor(pair.image1, cv2.COLOR_RGB2BGR)
    bgr2 = cv2.cvtColor(pair.image2, cv2.COLOR_RGB2BGR)
    errors, model = {}, "failed"
    for name, plane in zip(PIPELINES, (True, False), strict=True):
        try:
            result = estimate_pair(bgr1, bgr2, K1, K2, options=PairOptions(plane=plane))
            R, t = result.R, result.t
            if plane:
                model = result.model
        except ValueError:
            R, t = None, None
        errors[name] = anchors.pose_error_deg(R, t, pair.R, pair.t)[2]
    shared = anchors.sift_matches(bgr1, bgr2)
    config = None
    for name in anchors.ANCHORS:
        anchor = anchors.run_anchor(name, shared, K1, K2)
        errors[name] = anchors.pose_error_deg(anchor.R, anchor.t, pair.R, pair.t)[2]
        if name == "pycolmap":
            config = anchor.extra.get("config")
    preset = f"{motion} (imperfect)" if imperfect else motion
    return {"preset": preset, "model": model, "config": str(config), "errors": errors}


def main(argv: list[str] | None = None) -> None:
    from ppo_cv.data_gen import MOTIONS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motions", nargs="+", default=list(MOTIONS), choices=list(MOTIONS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--pairs", type=int, default=5, help="pairs per seed and preset")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--clean-only", action="store_true", help="skip the imperfect renders")
    args = parser.parse_args(argv)
    variants = (False,) if args.clean_only else (False, True)
    tasks = [
        (m, s, i, imperfect)
        for m in args.motions
        for imperfect in variants
        for s in args.seeds
        for i in range(args.pairs)
    ]
    rows = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for row in pool.map(evaluate, tasks):
            rows.append(row)
            print(f"{row['preset']}: {row['model']}, pycolmap {row['config']}", flush=True)
    presets = list(dict.fromkeys(row["preset"] for row in rows))
    print(f"\n{len(rows)} rendered pairs, 640x480, seeds {args.seeds}, {args.pairs} per seed")
    print(f"{platform.node()}, {platform.machine()}, {os.cpu_count()} cores\n")
    print("| preset | rotation | plane | general | failed | pycolmap configurations |")
    print("|---|---:|---:|---:|---:|---|")
    for preset in presets:
        chosen = Counter(row["model"] for row in rows if row["preset"] == preset)
        configs = Counter(row["config"] for row in rows if row["preset"] == preset)
        counts = " | ".join(str(chosen[m]) for m in MODELS)
        listed = ", ".join(f"{c} {n}" for c, n in sorted(configs.items()))
        print(f"| {preset} | {counts} | {listed} |")
    print("\nAUC@5 / AUC@10 / AUC@20 (pose error, degrees)\n")
    print("| preset | " + " | ".join(METHODS) + " |")
    print("|---|" + "---:|" * len(METHODS))
    for preset in presets:
        cells = []
        for method in METHODS:
            errors = [row["errors"][method] for row in rows if row["preset"] == preset]
            cells.append(" / ".join(f"{100 * anchors.auc(errors, th):.1f}" for th in (5, 10, 20)))
        print(f"| {preset} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
