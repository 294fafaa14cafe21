"""Rendered planar pairs: the homography branch against estimate_pair and pycolmap, in one run.

Usage (from the repository root)::

    python benchmarks/planar_pairs.py --seeds 0 1 2 --pairs 10 --jobs 2 [--imperfect]

For every pair ``make_pair("planar", seed, index)`` (640x480; with ``--imperfect`` the
imperfections of real photos, ``data_gen.REAL_PHOTO``, and every method given the slightly
wrong ``K1_given``, ``K2_given``) the pose error (the larger of the
rotation and translation-direction errors, degrees, as in ``docs/benchmarks.md``) of

``H + PPO``
    :func:`ppo_cv.homography.estimate_homography` (pycolmap LO-RANSAC, 1 px) and
    :func:`ppo_cv.plane.planar_pose` on the shared SIFT matches of ``anchors.py``;
``H + PPO + refine``
    the same pose refined over the homography inliers (:func:`ppo_cv.refine.refine_pose`), what
    the pipeline does for the general case;
``H + PPO (ppo_cv features)``
    the refined branch on the matches of :mod:`ppo_cv.features` (RootSIFT, mutual, ratio 0.9),
    the matches ``estimate_pair`` uses;
``estimate_pair``
    the current pipeline (essential matrix), its own features;
``pycolmap``
    ``estimate_calibrated_two_view_geometry`` on the shared matches (it fits a homography too);

and the AUC@5/10/20 of each column. Measurements are printed, nothing is written.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402

from ppo_cv import estimate_pair  # noqa: E402
from ppo_cv.features import detect_features, match_features  # noqa: E402
from ppo_cv.homography import estimate_homography  # noqa: E402
from ppo_cv.plane import planar_pose  # noqa: E402
from ppo_cv.refine import refine_pose  # noqa: E402

METHODS = (
    "H + PPO",
    "H + PPO + refine",
    "H + PPO (ppo_cv features)",
    "estimate_pair",
    "pycolmap",
)
THRESHOLD_PX = 1.0


def _normalized(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    x = cv2.undistortPoints(points.reshape(-1, 1, 2).astype(np.float64), K, None).reshape(-1, 2)
    return np.column_stack([x, np.ones(len(x))])


def homography_pose(p1, p2, K1, K2, refine: bool):
    """``(R, t, ambiguous)`` of the homography branch on pixel matches, or None."""
    if len(p1) < 8:
        return None
    x1, x2 = _normalized(p1, K1), _normalized(p2, K2)
    focal = float(np.mean([K1[0, 0], K1[1, 1], K2[0, 0], K2[1, 1]]))
    fit = estimate_homography(x1, x2, focal, threshold=THRESHOLD_PX)
    if fit is None or fit.num_inliers < 8:
        return None
    pose = planar_pose(fit.H, x1, x2, fit.inliers, threshold=THRESHOLD_PX / focal)
    R, t = pose.R, pose.t
    if refine:
        R, t = refine_pose(R, t, x1, x2, fit.inliers, focal)
    return R, t, pose.ambiguous


def evaluate(task: tuple[int, int, bool]) -> dict:
    from ppo_cv.data_gen import REAL_PHOTO, make_pair

    seed, index, imperfect = task
    cv2.setNumThreads(1)
    pair = make_pair(
        "planar", seed=seed, index=index, imperfections=REAL_PHOTO if imperfect else None
    )
    K1 = pair.K1 if pair.K1_given is None else pair.K1_given
    K2 = pair.K2 if pair.K2_given is None else pair.K2_given
    bgr1 = cv2.cvtColor(pair.image1, cv2.COLOR_RGB2BGR)
    bgr2 = cv2.cvtColor(pair.image2, cv2.COLOR_RGB2BGR)
    shared = anchors.sift_matches(bgr1, bgr2)
    f1, f2 = detect_features(bgr1), detect_features(bgr2)
    own = match_features(f1, f2)
    q1, q2 = f1.keypoints[own[:, 0]], f2.keypoints[own[:, 1]]
    poses = {
        "H + PPO": homography_pose(shared.points1, shared.points2, K1, K2, False),
        "H + PPO + refine": homography_pose(shared.points1, shared.points2, K1, K2, True),
        "H + PPO (ppo_cv features)": homography_pose(q1, q2, K1, K2, True),
    }
    try:
        result = estimate_pair(bgr1, bgr2, K1, K2)
        poses["estimate_pair"] = (result.R, result.t, False)
    except ValueError:
        poses["estimate_pair"] = None
    colmap = anchors.run_anchor("pycolmap", shared, K1, K2)
    poses["pycolmap"] = None if colmap.R is None else (colmap.R, colmap.t, False)
    errors = {}
    for name, pose in poses.items():
        R, t = (None, None) if pose is None else pose[:2]
        errors[name] = anchors.pose_error_deg(R, t, pair.R, pair.t)[2]
    ambiguous = poses["H + PPO"] is not None and poses["H + PPO"][2]
    return {
        "seed": seed,
        "index": index,
        "errors": errors,
        "ambiguous": ambiguous,
        "config": colmap.extra.get("config"),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--pairs", type=int, default=10, help="pairs per seed")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--imperfect", action="store_true", help="renders with REAL_PHOTO")
    args = parser.parse_args(argv)
    tasks = [(s, i, args.imperfect) for s in args.seeds for i in range(args.pairs)]
    rows = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for row in pool.map(evaluate, tasks):
            rows.append(row)
            errs = ", ".join(f"{k} {v:.2f}" for k, v in row["errors"].items())
            print(f"planar seed {row['seed']} #{row['index']}: {errs}", flush=True)
    kind = "imperfect (REAL_PHOTO) " if args.imperfect else ""
    print(f"\n{len(rows)} {kind}rendered planar pairs, 640x480, seeds {args.seeds}")
    print(f"{platform.node()}, {platform.machine()}, {os.cpu_count()} cores\n")
    print("| method | AUC@5 | AUC@10 | AUC@20 |")
    print("|---|---:|---:|---:|")
    for name in METHODS:
        errors = [row["errors"][name] for row in rows]
        aucs = " | ".join(f"{100 * anchors.auc(errors, th):.1f}" for th in (5, 10, 20))
        print(f"| {name} | {aucs} |")
    ambiguous = sum(row["ambiguous"] for row in rows)
    configs = sorted({str(row["config"]) for row in rows})
    counts = ", ".join(f"{c} {sum(str(r['config']) == c for r in rows)}" for c in configs)
    print(f"\ntwo-fold ambiguity met (tie-break used): {ambiguous} of {len(rows)} pairs")
    print(f"pycolmap configurations: {counts}")


if __name__ == "__main__":
    main()
