"""Side-by-side benchmark of ppo_cv against OpenCV, pycolmap and PoseLib, in one run.

Usage (from the repository root, after ``pip install ".[bench]"``)::

    python benchmarks/compare.py --out docs/benchmarks --report docs/benchmarks.md

Sections (each prints its table as it finishes; the report collects them):

1. Pose identification time from the same E and points, N = 10 ... 1e5: ``ppo_cv.recoverPose``,
   ``cv2.recoverPose`` and pycolmap's pose from E (``estimate_two_view_geometry_pose``).
2. Accuracy: AUC@5/10/20 of the pose error on rendered pairs of every motion preset of
   ``ppo_cv.data_gen`` and on the freiburg real pairs, for ``ppo_cv.estimate_pair`` and the
   anchors of ``anchors.py`` on shared SIFT matches.
3. Pure-rotation detection on rendered pure-rotation, small-parallax, planar and general
   pairs: ppo_cv's flag, pycolmap's configuration and the paper's M3 indicator.
4. Whole-pipeline time per image pair: ``estimate_pair`` against the OpenCV and pycolmap
   pipelines (features and matching included), one process, one pair at a time.
5. Peak memory of identification up to N = 1e6 (``memory.py``).

The freiburg pairs are read from ``../shared/data/freiburg`` beside the repository (or
``--freiburg DIR``); the section is skipped with a note when they are absent.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402
import compare_report  # noqa: E402
import memory  # noqa: E402
from identification import identification_problem, time_call  # noqa: E402

import ppo_cv  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FREIBURG = ROOT.parent / "shared" / "data" / "freiburg"
MOTIONS = ("general", "pure-rotation", "small-parallax", "forward", "planar")
DETECTION_MOTIONS = ("pure-rotation", "small-parallax", "planar", "general")
SPEED_SIZES = (10, 100, 1000, 10_000, 100_000)
METHODS = ("ppo_cv",) + anchors.ANCHORS
M3_THRESHOLD = 0.015


# ---------------------------------------------------------------- identification speed


def _pycolmap_pose_from_E(E, p1, p2, K):
    import pycolmap

    camera = pycolmap.Camera(
        model="PINHOLE", width=1024, height=1024, params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    )
    pairs = np.repeat(np.arange(len(p1), dtype=np.uint32)[:, None], 2, axis=1)

    def call():
        geometry = pycolmap.TwoViewGeometry(
            config=pycolmap.TwoViewGeometryConfiguration.CALIBRATED, E=E, inlier_matches=pairs
        )
        pycolmap.estimate_two_view_geometry_pose(camera, p1, camera, p2, geometry)
        return geometry

    return call


def identification_speed(sizes=SPEED_SIZES, repeats: int = 7) -> list[dict]:
    """Median seconds per call of the three identifications on the same E and points."""
    rows = []
    for n in sizes:
        E, p1, p2, K, R, t = identification_problem(n)
        calls = {
            "ppo_cv.recoverPose": partial(ppo_cv.recoverPose, E, p1, p2, K),
            "cv2.recoverPose": partial(cv2.recoverPose, E, p1, p2, K),
            "pycolmap pose from E": _pycolmap_pose_from_E(E, p1, p2, K),
        }
        samples = {name: [] for name in calls}
        for _ in range(repeats):
            for name, fn in calls.items():
                samples[name].append(time_call(fn, 1)[0])
        row = {"n": n, **{name: float(np.median(v)) for name, v in samples.items()}}
        rows.append(row)
        print(
            f"identification N={n}: "
            + ", ".join(f"{k} {v * 1e3:.3f} ms" for k, v in row.items() if k != "n"),
            flush=True,
        )
    return rows


# ---------------------------------------------------------------- the project's pipeline


def _estimate_pair():
    """``ppo_cv.estimate_pair`` if this version of the library has it, else None."""
    fn = getattr(ppo_cv, "estimate_pair", None)
    if fn is None:
        try:
            from ppo_cv.pipeline import estimate_pair as fn
        except ImportError:
            return None
    return fn


def run_ppo_cv(image1, image2, K1, K2) -> anchors.AnchorResult:
    """Pose, pure-rotation flag, PRI and M3 (of its inliers) of ``ppo_cv.estimate_pair``."""
    fn = _estimate_pair()
    if fn is None:
        return anchors.AnchorResult(None, None, float("nan"), {"missing": True})
    start = time.perf_counter()
    try:
        result = fn(image1, image2, K1, K2)
    except Exception as exc:  # a failure is a benchmark outcome: record it, keep going
        return anchors.AnchorResult(None, None, time.perf_counter() - start, {"error": repr(exc)})
    seconds = time.perf_counter() - start
    inlier1, inlier2 = result.inlier_points
    extra = {
        "pure_rotation": bool(result.pure_rotation),
        "pri": float(result.pri),
        "m3": anchors.m3_of(inlier1, inlier2, result.cameras.K1, result.cameras.K2, result.R),
        "inliers": result.num_inliers,
        "timings": dict(result.timings),
    }
    return anchors.AnchorResult(
        np.asarray(result.R, float), np.asarray(result.t, float).ravel(), seconds, extra
    )


# ---------------------------------------------------------------- accuracy on image pairs


def evaluate_pair(image1, image2, K1, K2, R_gt, t_gt) -> dict:
    """Every method on one pair of BGR images: pose errors, times and detection outputs."""
    matches = anchors.sift_matches(image1, image2)
    out = {"matches": len(matches.points1), "match_seconds": matches.seconds, "methods": {}}
    results = {"ppo_cv": run_ppo_cv(image1, image2, K1, K2)}
    for name in anchors.ANCHORS:
        results[name] = anchors.run_anchor(name, matches, K1, K2)
    for name, res in results.items():
        e_R, e_t, e = anchors.pose_error_deg(res.R, res.t, R_gt, t_gt)
        out["methods"][name] = {
            "err_R": e_R,
            "err_t": e_t,
            "err": e,
            "seconds": res.seconds,
            "failed": res.R is None,
            **res.extra,
        }
    return out


def _rendered_task(args: tuple) -> dict:
    motion, index, seed = args
    from ppo_cv.data_gen.io import make_pair

    cv2.setNumThreads(1)
    pair = make_pair(motion, seed=seed, index=index)
    bgr1 = cv2.cvtColor(pair.image1, cv2.COLOR_RGB2BGR)
    bgr2 = cv2.cvtColor(pair.image2, cv2.COLOR_RGB2BGR)
    row = evaluate_pair(bgr1, bgr2, pair.K1, pair.K2, pair.R, pair.t)
    row.update(
        set="rendered",
        motion=motion,
        index=index,
        alpha=pair.params.get("alpha"),
        t_norm=float(np.linalg.norm(pair.t)),
    )
    return row


def _freiburg_task(args: tuple) -> dict:
    root, pair = args
    cv2.setNumThreads(1)
    image1 = cv2.imread(str(Path(root) / "images" / pair["name1"]))
    image2 = cv2.imread(str(Path(root) / "images" / pair["name2"]))
    row = evaluate_pair(image1, image2, pair["K1"], pair["K2"], pair["R"], pair["t"])
    row.update(set="freiburg", name1=pair["name1"], name2=pair["name2"])
    return row


def accuracy_runs(
    pairs_per_motion: int, seed: int, freiburg: Path | None, jobs: int, freiburg_limit: int | None
) -> list[dict]:
    tasks = [(m, i, seed) for m in MOTIONS for i in range(pairs_per_motion)]
    rows = []
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for row in pool.map(_rendered_task, tasks):
            rows.append(row)
            print(
                f"rendered {row['motion']} #{row['index']}: "
                + ", ".join(f"{k} {v['err']:.2f}" for k, v in row["methods"].items()),
                flush=True,
            )
        if freiburg is not None:
            pairs = anchors.read_pairs_file(freiburg / "pairs_with_gt.txt")
            pairs = pairs[:freiburg_limit] if freiburg_limit else pairs
            for row in pool.map(_freiburg_task, [(str(freiburg), p) for p in pairs]):
                rows.append(row)
        print(f"accuracy: {len(rows)} pairs evaluated", flush=True)
    return rows


# ---------------------------------------------------------------- whole-pipeline time


def pipeline_speed(freiburg: Path | None, n_pairs: int, seed: int) -> dict:
    """Median wall time per pair of the three pipelines, features and matching included."""
    images = []
    if freiburg is not None:
        for pair in anchors.read_pairs_file(freiburg / "pairs_with_gt.txt")[:n_pairs]:
            load = lambda n: cv2.imread(str(freiburg / "images" / n))  # noqa: E731
            images.append((load(pair["name1"]), load(pair["name2"]), pair["K1"], pair["K2"]))
    else:
        from ppo_cv.data_gen.io import make_pair

        for i in range(n_pairs):
            p = make_pair("general", seed=seed, index=i)
            images.append(
                (
                    cv2.cvtColor(p.image1, cv2.COLOR_RGB2BGR),
                    cv2.cvtColor(p.image2, cv2.COLOR_RGB2BGR),
                    p.K1,
                    p.K2,
                )
            )
    cv2.setNumThreads(1)
    times = {"ppo_cv estimate_pair": [], "OpenCV pipeline": [], "pycolmap pipeline": []}
    for image1, image2, K1, K2 in images:
        if _estimate_pair() is not None:
            start = time.perf_counter()
            run_ppo_cv(image1, image2, K1, K2)
            times["ppo_cv estimate_pair"].append(time.perf_counter() - start)
        for label, anchor in (("OpenCV pipeline", "opencv"), ("pycolmap pipeline", "pycolmap")):
            start = time.perf_counter()
            matches = anchors.sift_matches(image1, image2)
            anchors.run_anchor(anchor, matches, K1, K2)
            times[label].append(time.perf_counter() - start)
    out = {k: float(np.median(v)) for k, v in times.items() if v}
    out["pairs"] = len(images)
    out["source"] = "freiburg" if freiburg is not None else "rendered general"
    print("pipeline time: " + ", ".join(f"{k} {v}" for k, v in out.items()), flush=True)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="ppo_cv against OpenCV, pycolmap and PoseLib.")
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks"))
    parser.add_argument("--report", type=Path, default=Path("docs/benchmarks.md"))
    parser.add_argument("--pairs", type=int, default=8, help="rendered pairs per motion preset")
    parser.add_argument("--seed", type=int, default=0, help="seed of the rendered pairs")
    parser.add_argument("--freiburg", type=Path, default=FREIBURG)
    parser.add_argument("--freiburg-limit", type=int, default=None, help="first N pairs only")
    parser.add_argument("--pipeline-pairs", type=int, default=10, help="pairs timed end to end")
    parser.add_argument("--memory-sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    start = time.perf_counter()
    freiburg = args.freiburg if (args.freiburg / "pairs_with_gt.txt").is_file() else None

    res: dict = {"identification": identification_speed()}
    res["pipeline_speed"] = pipeline_speed(freiburg, args.pipeline_pairs, args.seed)
    res["memory"] = memory.run(args.memory_sizes)
    print(memory.markdown_table(res["memory"]), flush=True)
    res["pairs"] = accuracy_runs(args.pairs, args.seed, freiburg, args.jobs, args.freiburg_limit)
    res["settings"] = {
        "command": "python benchmarks/compare.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "pairs_per_motion": args.pairs,
        "seed": args.seed,
        "jobs": args.jobs,
        "freiburg": freiburg is not None,
        "m3_threshold": M3_THRESHOLD,
        "pri_threshold": ppo_cv.DEFAULT_PRI_THRESHOLD,
        "estimate_pair": _estimate_pair() is not None,
        "total_seconds": round(time.perf_counter() - start, 1),
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "opencv": cv2.__version__,
            "pycolmap": __import__("pycolmap").__version__,
            "poselib": getattr(__import__("poselib"), "__version__", "?"),
            "ppo_cv": ppo_cv.__version__,
        },
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(res, indent=1, default=float))
    summary = compare_report.summarise(res)
    compare_report.draw(res, summary, args.out)
    args.report.parent.mkdir(parents=True, exist_ok=True)
    kept = compare_report.kept_sections(args.report)
    args.report.write_text(
        compare_report.render(res, summary, os.path.relpath(args.out, args.report.parent)) + kept
    )
    print(compare_report.headline(summary))
    print(f"wrote {args.report} and {args.out}/ in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
