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
   pipelines (features and matching included), one process, one pair at a time: median wall
   and CPU time (``time.process_time``, summed over threads), the OpenCV pipeline's SIFT
   alone, the median wall and CPU time of each stage of ``estimate_pair`` (CPU read through
   its ``progress`` callback) and the stages of the pair of median CPU time, the processor and
   its load. ``--only-pipeline`` runs this section alone
   and rewrites the report with the other sections' stored results; ``--baseline DIR`` adds
   the same timing of an earlier version's ``estimate_pair`` (``git worktree add DIR <commit>``
   or ``git archive``).
5. Peak memory of identification up to N = 1e6 (``memory.py``).

The freiburg pairs are read from ``../shared/data/freiburg`` beside the repository (or
``--freiburg DIR``); the section is skipped with a note when they are absent.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import inspect  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import shlex  # noqa: E402
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
FREIBURG = Path(os.environ.get("PPO_CV_SHARED", ROOT.parent / "shared")) / "data" / "freiburg"
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


def run_ppo_cv(image1, image2, K1, K2, progress=None) -> anchors.AnchorResult:
    """Pose, pure-rotation flag, PRI and M3 (of its inliers) of ``ppo_cv.estimate_pair``;
    ``progress`` is passed on when this version's ``estimate_pair`` takes it."""
    fn = _estimate_pair()
    if fn is None:
        return anchors.AnchorResult(None, None, float("nan"), {"missing": True})
    reports = progress is not None and "progress" in inspect.signature(fn).parameters
    start = time.perf_counter()
    try:
        result = fn(image1, image2, K1, K2, **({"progress": progress} if reports else {}))
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


def _machine() -> dict:
    """Processor, logical cores and the 1-minute load average now."""
    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        names = [line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines()
                 if line.startswith("model name")]  # fmt: skip
        model = names[0] if names else model
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"cpu": model, "cores": os.cpu_count(), "load": round(load, 2)}


def _pipeline_images(freiburg: Path | None, n_pairs: int, seed: int) -> list[tuple]:
    """(BGR image 1, BGR image 2, K1, K2) of the first ``n_pairs`` freiburg pairs, or of as
    many rendered general pairs without them."""
    if freiburg is not None:
        load = lambda name: cv2.imread(str(freiburg / "images" / name))  # noqa: E731
        return [
            (load(pair["name1"]), load(pair["name2"]), pair["K1"], pair["K2"])
            for pair in anchors.read_pairs_file(freiburg / "pairs_with_gt.txt")[:n_pairs]
        ]
    from ppo_cv.data_gen.io import make_pair

    pairs = [make_pair("general", seed=seed, index=i) for i in range(n_pairs)]
    bgr = lambda image: cv2.cvtColor(image, cv2.COLOR_RGB2BGR)  # noqa: E731
    return [(bgr(p.image1), bgr(p.image2), p.K1, p.K2) for p in pairs]


def _timed(fn) -> tuple[float, float, object]:
    """Wall and CPU seconds of ``fn()`` (CPU summed over the process's threads), its value."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, value


def _opencv_pipeline(anchor: str, image1, image2, K1, K2):
    return anchors.run_anchor(anchor, anchors.sift_matches(image1, image2), K1, K2)


def _opencv_sift(image1, image2, K1, K2) -> anchors.AnchorResult:
    """The detection of the OpenCV pipeline alone (SIFT of both images, as
    ``anchors.sift_matches`` runs it): the floor of every pipeline here."""
    sift = cv2.SIFT_create(4000)
    for image in (image1, image2):
        sift.detectAndCompute(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), None)
    return anchors.AnchorResult(None, None, 0.0)


class StageCPU:
    """Process CPU seconds (all threads) of each stage of ``estimate_pair``, read as its
    ``progress`` reports a stage's end; a stage that runs twice is summed and counted."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.runs: dict[str, int] = {}
        self.clock = time.process_time()

    def __call__(self, stage: str) -> None:
        now = time.process_time()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self.clock
        self.runs[stage] = self.runs.get(stage, 0) + 1
        self.clock = now


def per_pair_table(wall: dict, cpu: dict, stage_cpu: list[dict], detections: list[int]) -> str:
    """Markdown table of each pair: ``estimate_pair`` against OpenCV's pipeline (wall and CPU
    seconds), its detections and its three costliest stages in CPU ms: which pairs sit above
    OpenCV's time, and where."""
    ours, opencv = "ppo_cv estimate_pair", "OpenCV pipeline"
    rows = [
        "| pair | estimate_pair wall / CPU s | OpenCV wall / CPU s | detections "
        "| costliest stages, CPU ms |",
        "|---:|---:|---:|---:|---|",
    ]
    for i, stages in enumerate(stage_cpu):
        top = sorted(stages.items(), key=lambda item: -item[1])[:3]
        rows.append(
            f"| {i} | {wall[ours][i]:.3f} / {cpu[ours][i]:.3f} | "
            f"{wall[opencv][i]:.3f} / {cpu[opencv][i]:.3f} | {detections[i]} | "
            + ", ".join(f"{stage} {1000 * seconds:.0f}" for stage, seconds in top)
            + " |"
        )
    return "\n".join(rows)


def per_pair_times(wall: dict, cpu: dict, detections: list[int]) -> list[dict]:
    """Wall and CPU seconds of ``estimate_pair`` and of the OpenCV pipeline on each pair, and
    the detections ``estimate_pair`` ran: the record behind the count of pairs at or below
    OpenCV's time in the report."""
    ours, opencv = "ppo_cv estimate_pair", "OpenCV pipeline"
    return [
        {"wall": w, "cpu": c, "opencv_wall": ow, "opencv_cpu": oc, "detections": d}
        for w, c, ow, oc, d in zip(
            wall[ours], cpu[ours], wall[opencv], cpu[opencv], detections, strict=True
        )
    ]


def pipeline_speed(freiburg: Path | None, n_pairs: int, seed: int, ours_only: bool = False) -> dict:
    """Median wall and CPU time per pair of the three pipelines, features and matching
    included, one pair at a time in this process; the median time of each stage of
    ``estimate_pair`` (``PairResult.timings``, wall) and the machine."""
    images = _pipeline_images(freiburg, n_pairs, seed)
    cv2.setNumThreads(1)
    machine = _machine()
    ours = "ppo_cv estimate_pair"
    calls = {ours: run_ppo_cv}
    if not ours_only:
        calls["OpenCV pipeline"] = partial(_opencv_pipeline, "opencv")
        calls["pycolmap pipeline"] = partial(_opencv_pipeline, "pycolmap")
        calls["OpenCV SIFT alone"] = _opencv_sift
    if _estimate_pair() is None:
        del calls[ours]
    wall = {label: [] for label in calls}
    cpu = {label: [] for label in calls}
    stages: dict[str, list[float]] = {}
    stage_cpu: list[dict[str, float]] = []
    detections: list[int] = []
    for image1, image2, K1, K2 in images:
        for label, call in calls.items():
            progress = StageCPU() if label == ours else None
            if progress is not None:
                call = partial(call, progress=progress)
            seconds, cpu_seconds, result = _timed(partial(call, image1, image2, K1, K2))
            wall[label].append(seconds)
            cpu[label].append(cpu_seconds)
            for stage, value in result.extra.get("timings", {}).items():
                stages.setdefault(stage, []).append(value)
            if progress is not None and progress.seconds:
                stage_cpu.append(progress.seconds)
                detections.append(progress.runs.get("features", 0))
    out = {label: float(np.median(v)) for label, v in wall.items()}
    out["cpu"] = {label: float(np.median(v)) for label, v in cpu.items()}
    out["stages"] = {stage: float(np.median(v)) for stage, v in stages.items()}
    if len(stage_cpu) == len(images) and images:
        out["stage_cpu"] = {
            stage: float(np.median([one.get(stage, 0.0) for one in stage_cpu]))
            for stage in out["stages"]
        }
        middle = int(np.argsort(cpu[ours])[(len(images) - 1) // 2])
        out["median_pair"] = {"index": middle, "cpu": float(cpu[ours][middle]),
                              "stage_cpu": stage_cpu[middle]}  # fmt: skip
    if ours in wall and "OpenCV pipeline" in wall and len(detections) == len(images):
        out["per_pair"] = per_pair_times(wall, cpu, detections)
    out["pairs"] = len(images)
    out["source"] = "freiburg" if freiburg is not None else "rendered general"
    out["machine"] = {**machine, "load_after": _machine()["load"]}
    print(
        "pipeline time (wall, CPU): "
        + ", ".join(f"{k} {out[k]:.3f} s, {out['cpu'][k]:.3f} s" for k in calls),
        flush=True,
    )
    if not ours_only and len(stage_cpu) == len(images):
        print(per_pair_table(wall, cpu, stage_cpu, detections), flush=True)
    return out


def baseline_speed(tree: Path, label: str, args) -> dict:
    """``pipeline_speed`` of ``estimate_pair`` from the ppo_cv package under ``tree`` (an
    earlier version's source), in a child process with the same settings."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as scratch:
        target = Path(scratch) / "baseline.json"
        command = [
            sys.executable, __file__, "--pipeline-json", str(target),
            "--pipeline-pairs", str(args.pipeline_pairs), "--seed", str(args.seed),
            "--freiburg", str(args.freiburg),
        ]  # fmt: skip
        env = {**os.environ, "PYTHONPATH": str(tree)}
        subprocess.run(command, env=env, check=True)
        timed = json.loads(target.read_text())
    timed["label"] = label
    return timed


def only_pipeline(args, freiburg: Path | None) -> None:
    """Time the whole pairs again and rewrite the report from the stored results with them."""
    res = json.loads((args.out / "results.json").read_text())
    if args.baseline is not None:
        baseline = baseline_speed(args.baseline, args.baseline_label, args)
    res["pipeline_speed"] = pipeline_speed(freiburg, args.pipeline_pairs, args.seed)
    if args.baseline is not None:
        res["pipeline_speed"]["baseline"] = baseline
    res["pipeline_speed"]["command"] = "python benchmarks/compare.py " + shlex.join(sys.argv[1:])
    _write(res, args, figures=("pipeline",))


def _write(res: dict, args, figures: tuple[str, ...] | None = None) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(res, indent=1, default=float))
    summary = compare_report.summarise(res)
    compare_report.draw(res, summary, args.out, figures)
    args.report.parent.mkdir(parents=True, exist_ok=True)
    kept = compare_report.kept_sections(args.report)
    args.report.write_text(
        compare_report.render(res, summary, os.path.relpath(args.out, args.report.parent)) + kept
    )
    print(compare_report.headline(summary))
    print(f"wrote {args.report} and {args.out}/")


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
    parser.add_argument(
        "--only-pipeline",
        action="store_true",
        help="time the whole pairs (section 4) only; the other sections come from the stored "
        "OUT/results.json of a full run",
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="with --only-pipeline: a folder holding an earlier ppo_cv package, whose "
        "estimate_pair is timed on the same pairs in a child process (the 'before' row)",
    )
    parser.add_argument("--baseline-label", default="before", help="name of the --baseline row")
    parser.add_argument("--pipeline-json", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.baseline is not None and not (args.baseline / "ppo_cv" / "__init__.py").is_file():
        parser.error(f"--baseline {args.baseline} holds no ppo_cv package")
    if args.baseline is not None and not args.only_pipeline:
        parser.error("--baseline needs --only-pipeline")
    if args.only_pipeline and not (args.out / "results.json").is_file():
        parser.error(f"--only-pipeline needs the results of a full run in {args.out}/results.json")
    cv2.setNumThreads(1)
    start = time.perf_counter()
    freiburg = args.freiburg if (args.freiburg / "pairs_with_gt.txt").is_file() else None
    if args.pipeline_json is not None:
        timed = pipeline_speed(freiburg, args.pipeline_pairs, args.seed, ours_only=True)
        timed["ppo_cv"] = str(Path(ppo_cv.__file__).resolve().parent)
        args.pipeline_json.write_text(json.dumps(timed, indent=1))
        return
    if args.only_pipeline:
        only_pipeline(args, freiburg)
        return

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
    _write(res, args)
    print(f"in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
