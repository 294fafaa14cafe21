"""Rendered planar pairs: the homography branch against estimate_pair and pycolmap, in one run.

Usage (from the repository root)::

    python benchmarks/planar_pairs.py --seeds 0 1 2 --pairs 10 --jobs 2 [--imperfect [KIND]]

For every pair ``make_pair("planar", seed, index)`` (640x480; with ``--imperfect`` the
imperfections of real photos, ``data_gen.REAL_PHOTO``, or one of them alone, ``--imperfect
focal`` / ``k1`` / ``fov`` / ``jpeg``, see :data:`IMPERFECTIONS`; every method is given the
``K1_given``, ``K2_given`` of the pair) the pose error (the larger of the rotation and
translation-direction errors, degrees, as in ``docs/benchmarks.md``) of

``oracle ...``
    the error budget: exact correspondences on a 16-pixel grid of view 1 (from the rendered
    depth, the true poses, intrinsics and distortion), normalized with the given intrinsics
    and no distortion as an estimator sees them; the least-squares homography decomposed (the
    candidate closest to the truth: no ambiguity), then refined on the homography without and
    with the division-model ``k1`` (:func:`ppo_cv.plane.refine_planar_pose`). What is left is
    the error the imperfections cause by themselves;
``H + PPO``
    :func:`ppo_cv.homography.estimate_homography` (pycolmap LO-RANSAC, 1 px) and
    :func:`ppo_cv.plane.planar_pose` on the shared SIFT matches of ``anchors.py``;
``H + PPO + refine E``
    the same pose refined on the Sampson error of ``E = [t]x R`` over the homography inliers
    (:func:`ppo_cv.refine.refine_pose`), what the pipeline does for the general case;
``H + PPO + refine H`` / ``H + PPO + refine H, k1``
    the pose refined on the symmetric transfer error of its homography
    (:func:`ppo_cv.plane.refine_planar_pose`), without and with the division-model ``k1``;
``estimate_pair``
    the pipeline with its defaults, its own features;
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
from ppo_cv.homography import estimate_homography  # noqa: E402
from ppo_cv.plane import decompose_homography, planar_pose, refine_planar_pose  # noqa: E402
from ppo_cv.refine import refine_pose  # noqa: E402

ORACLES = ("oracle H", "oracle H refined", "oracle H refined, k1")
BRANCHES = ("H + PPO", "H + PPO + refine E", "H + PPO + refine H", "H + PPO + refine H, k1")
METHODS = (*ORACLES, *BRANCHES, "estimate_pair", "pycolmap")
THRESHOLD_PX = 1.0
GRID_PX = 16


def imperfections(kind: str | None):
    """The ``REAL_PHOTO`` imperfections (``"all"``), one of them alone, or None (clean)."""
    from ppo_cv.data_gen import REAL_PHOTO, Imperfections

    none = {"k1_range": (0.0, 0.0), "focal_error": 0.0, "hfov_range": None,
            "jpeg_quality": None, "noise_std": 0.0, "blur_sigma": 0.0}  # fmt: skip
    keep = {
        "focal": ("focal_error",),
        "k1": ("k1_range",),
        "fov": ("hfov_range",),
        "jpeg": ("jpeg_quality", "noise_std", "blur_sigma"),
    }
    if kind is None:
        return None
    if kind == "all":
        return REAL_PHOTO
    return Imperfections(**{k: v for k, v in none.items() if k not in keep[kind]})


IMPERFECTIONS = ("all", "focal", "k1", "fov", "jpeg")


def _normalized(points: np.ndarray, K: np.ndarray) -> np.ndarray:
    x = cv2.undistortPoints(points.reshape(-1, 1, 2).astype(np.float64), K, None).reshape(-1, 2)
    return np.column_stack([x, np.ones(len(x))])


def exact_matches(pair) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free pixel matches ``(N, 2)`` on a grid of view 1, through the rendered depth."""
    height, width = pair.depth1.shape
    u, v = np.meshgrid(np.arange(8, width, GRID_PX), np.arange(8, height, GRID_PX))
    p1 = np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)
    depth = pair.depth1[p1[:, 1].astype(int), p1[:, 0].astype(int)].astype(np.float64)
    ok = np.isfinite(depth)
    p1, depth = p1[ok], depth[ok]
    dist1 = pair.dist1 if pair.dist1.size else None
    dist2 = pair.dist2 if pair.dist2.size else None
    rays = cv2.undistortPoints(p1.reshape(-1, 1, 2), pair.K1, dist1).reshape(-1, 2)
    X2 = np.column_stack([rays, np.ones(len(rays))]) * depth[:, None] @ pair.R.T + pair.t
    p2 = cv2.projectPoints(X2, np.zeros(3), np.zeros(3), pair.K2, dist2)[0].reshape(-1, 2)
    inside = (X2[:, 2] > 0) & np.all((p2 >= 0) & (p2 <= [width - 1, height - 1]), axis=1)
    return p1[inside], p2[inside]


def oracle_poses(pair, K1, K2) -> dict:
    """Poses of the error budget (see the module docstring), keyed by ``ORACLES``."""
    p1, p2 = exact_matches(pair)
    x1, x2 = _normalized(p1, K1), _normalized(p2, K2)
    H = np.linalg.inv(K2) @ cv2.findHomography(p1, p2, 0)[0] @ K1
    candidates = decompose_homography(planar_pose(H, x1, x2).candidates.H)
    errors = [anchors.pose_error_deg(R, t, pair.R, pair.t)[2]
              for R, t in zip(candidates.R, candidates.t, strict=True)]  # fmt: skip
    best = int(np.argmin(errors))
    R, T, n = candidates.R[best], candidates.T[best], candidates.n[best]
    focal = float(np.mean([K1[0, 0], K1[1, 1], K2[0, 0], K2[1, 1]]))
    scale = THRESHOLD_PX / focal
    plain = refine_planar_pose(R, T, n, x1, x2, scale=scale)
    lens = refine_planar_pose(R, T, n, x1, x2, scale=scale, fit_k1=True)
    return {
        "oracle H": (R, candidates.t[best]),
        "oracle H refined": (plain.R, plain.t),
        "oracle H refined, k1": (lens.R, lens.t),
    }


def homography_poses(p1, p2, K1, K2) -> dict:
    """Poses of the homography branch on pixel matches, keyed by ``BRANCHES`` (None: failed)."""
    poses = dict.fromkeys(BRANCHES)
    if len(p1) < 8:
        return poses
    x1, x2 = _normalized(p1, K1), _normalized(p2, K2)
    focal = float(np.mean([K1[0, 0], K1[1, 1], K2[0, 0], K2[1, 1]]))
    fit = estimate_homography(x1, x2, focal, threshold=THRESHOLD_PX)
    if fit is None or fit.num_inliers < 8:
        return poses
    pose = planar_pose(fit.H, x1, x2, fit.inliers, threshold=THRESHOLD_PX / focal)
    T = pose.candidates.T[pose.candidate]
    poses["H + PPO"] = (pose.R, pose.t)
    poses["H + PPO + refine E"] = refine_pose(pose.R, pose.t, x1, x2, fit.inliers, focal)
    for name, fit_k1 in (("H + PPO + refine H", False), ("H + PPO + refine H, k1", True)):
        refined = refine_planar_pose(pose.R, T, pose.n, x1, x2, fit.inliers,
                                     scale=THRESHOLD_PX / focal, fit_k1=fit_k1)  # fmt: skip
        poses[name] = (refined.R, refined.t)
    poses["ambiguous"] = pose.ambiguous
    return poses


def evaluate(task: tuple[int, int, str | None]) -> dict:
    from ppo_cv.data_gen import make_pair

    seed, index, kind = task
    cv2.setNumThreads(1)
    pair = make_pair("planar", seed=seed, index=index, imperfections=imperfections(kind))
    K1, K2 = pair.K1_given, pair.K2_given
    bgr1 = cv2.cvtColor(pair.image1, cv2.COLOR_RGB2BGR)
    bgr2 = cv2.cvtColor(pair.image2, cv2.COLOR_RGB2BGR)
    shared = anchors.sift_matches(bgr1, bgr2)
    poses = {**oracle_poses(pair, K1, K2), **homography_poses(shared.points1, shared.points2,
                                                              K1, K2)}  # fmt: skip
    ambiguous = bool(poses.pop("ambiguous", False))
    try:
        result = estimate_pair(bgr1, bgr2, K1, K2)
        poses["estimate_pair"] = (result.R, result.t)
        model = result.model
    except ValueError:
        poses["estimate_pair"], model = None, "failed"
    colmap = anchors.run_anchor("pycolmap", shared, K1, K2)
    poses["pycolmap"] = None if colmap.R is None else (colmap.R, colmap.t)
    errors = {}
    for name in METHODS:
        R, t = (None, None) if poses[name] is None else poses[name]
        errors[name] = anchors.pose_error_deg(R, t, pair.R, pair.t)[2]
    return {
        "seed": seed,
        "index": index,
        "errors": errors,
        "ambiguous": ambiguous,
        "model": model,
        "config": colmap.extra.get("config"),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--pairs", type=int, default=10, help="pairs per seed")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--imperfect", nargs="?", const="all", default=None,
                        choices=IMPERFECTIONS,
                        help="REAL_PHOTO (all) or one of its imperfections alone")  # fmt: skip
    args = parser.parse_args(argv)
    tasks = [(s, i, args.imperfect) for s in args.seeds for i in range(args.pairs)]
    rows = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for row in pool.map(evaluate, tasks):
            rows.append(row)
            errs = ", ".join(f"{k} {v:.2f}" for k, v in row["errors"].items())
            print(f"planar seed {row['seed']} #{row['index']}: {errs}", flush=True)
    kind = "" if args.imperfect is None else f"imperfect ({args.imperfect}) "
    print(f"\n{len(rows)} {kind}rendered planar pairs, 640x480, seeds {args.seeds}")
    print(f"{platform.node()}, {platform.machine()}, {os.cpu_count()} cores\n")
    print("| method | AUC@5 | AUC@10 | AUC@20 | median error (deg) |")
    print("|---|---:|---:|---:|---:|")
    for name in METHODS:
        errors = [row["errors"][name] for row in rows]
        aucs = " | ".join(f"{100 * anchors.auc(errors, th):.1f}" for th in (5, 10, 20))
        print(f"| {name} | {aucs} | {np.median(errors):.2f} |")
    ambiguous = sum(row["ambiguous"] for row in rows)
    print(f"\ntwo-fold ambiguity met (tie-break used): {ambiguous} of {len(rows)} pairs")
    for label, key in (("estimate_pair models", "model"), ("pycolmap configurations", "config")):
        values = sorted({str(row[key]) for row in rows})
        counts = ", ".join(f"{c} {sum(str(r[key]) == c for r in rows)}" for c in values)
        print(f"{label}: {counts}")


if __name__ == "__main__":
    main()
