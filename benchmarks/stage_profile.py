"""Where a whole pair's time goes: the CPU time of each stage of ``estimate_pair`` against
OpenCV's pipeline on the same images.

Run ``python benchmarks/stage_profile.py [--freiburg DIR] [--renders 4] [--detect-once]
[--json FILE] [--sift-parts PAIRS]`` from the repository root (``--detect-once``:
``PairOptions(detect_once=True)``).
For every freiburg pair (``../shared/data/freiburg`` beside the repository) and ``--renders``
pairs of each motion preset of ``ppo_cv.data_gen`` (640x480), one pair after the other in
this process: ``estimate_pair`` with its default options, its
stages timed in process CPU (all threads) through its ``progress`` callback
(``compare.StageCPU``), then OpenCV's pipeline of ``compare.py`` section 4 on the same images
in three parts: its SIFT of both images, SIFT with the 2-NN ratio-test matching
(``anchors.sift_matches``; matching is the difference) and the pose (``findEssentialMat``
USAC_MAGSAC + ``recoverPose``). Prints markdown tables: the median CPU per pair of each group of
freiburg pairs (one consensus or a second on denser features, with or without the tracks the
rotation choice aligns)
and of the renders, with the median stages; each stage's share of the CPU summed over the
freiburg pairs; the stages of the freiburg pair of median CPU. About 10 minutes on 2 cores.

``--sift-parts PAIRS`` instead splits OpenCV's SIFT on the images of the first PAIRS freiburg
pairs (detection with and without descriptors, at both thresholds; descriptors of given
keypoints; a halved image, whose scale space lacks the upsampled first octave) and times the
two threads of the pipeline's detection of each pair.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402
import compare  # noqa: E402

from ppo_cv.pipeline import PairOptions, estimate_pair  # noqa: E402

STAGES = ("features", "matching", "ransac", "model", "photometric", "decision")
TRACKS_CPU = 0.15
"""Decision-plus-photometric CPU (s) above which a pair counts as aligning tracks: without
them those stages take 10-70 ms, with them 0.25 s and more."""


def _cpu(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


def profile_pair(image1, image2, K1, K2, options: PairOptions | None = None) -> dict:
    """CPU per stage of ``estimate_pair`` and of OpenCV's pipeline on one pair of BGR images."""
    stage_cpu = compare.StageCPU()
    reported: list[str] = []

    def progress(stage: str) -> None:
        stage_cpu(stage)
        reported.append(stage)

    start = time.process_time()
    stage_cpu.clock = start
    try:
        result = estimate_pair(image1, image2, K1, K2, options=options, progress=progress)
        model = result.model
    except ValueError:
        model = None
    row = {"cpu": time.process_time() - start, "stages": stage_cpu.seconds, "model": model}
    row["second_consensus"] = reported.count("features") > 1
    row["tracks"] = (
        stage_cpu.seconds.get("decision", 0.0) + stage_cpu.seconds.get("photometric", 0.0)
        > TRACKS_CPU
    )
    sift = _cpu(lambda: compare._opencv_sift(image1, image2, K1, K2))
    holder = {}
    with_matching = _cpu(lambda: holder.setdefault("m", anchors.sift_matches(image1, image2)))
    pose = _cpu(lambda: anchors.run_anchor("opencv", holder["m"], K1, K2))
    row["opencv"] = {
        "features": sift, "matching": max(with_matching - sift, 0.0), "pose": pose,
        "cpu": with_matching + pose,
    }  # fmt: skip
    return row


def _best_cpu_ms(fn, repeats: int = 3):
    """Least CPU milliseconds of ``repeats`` calls of ``fn`` and its last value."""
    times, value = [], None
    for _ in range(repeats):
        start = time.process_time()
        value = fn()
        times.append(time.process_time() - start)
    return 1e3 * min(times), value


def sift_parts(gray: np.ndarray) -> dict:
    """CPU ms of the parts of OpenCV's SIFT on one grey image at the default contrast threshold
    and at ``REDETECT_THRESHOLD_SCALE`` of it: detection with descriptors, detection alone,
    descriptors of given keypoints (``compute``, which builds the Gaussian pyramid again), the
    same image halved (its scale space lacks the full image's upsampled first octave) and the
    share of keypoints found in that octave."""
    from ppo_cv.pipeline import REDETECT_THRESHOLD_SCALE

    default, lower = (
        cv2.SIFT_create(8000, 3, 0.04 * scale) for scale in (1.0, REDETECT_THRESHOLD_SCALE)
    )
    row = {}
    row["detect+describe"], (keys, _) = _best_cpu_ms(lambda: default.detectAndCompute(gray, None))
    row["detect+describe lower"], _ = _best_cpu_ms(lambda: lower.detectAndCompute(gray, None))
    row["detect"], _ = _best_cpu_ms(lambda: default.detect(gray, None))
    row["detect lower"], found = _best_cpu_ms(lambda: lower.detect(gray, None))
    new = [k for k in found if k.response * 3 < 0.04]
    row["describe the lower's new"], _ = _best_cpu_ms(lambda: default.compute(gray, new))
    row["describe default's"], _ = _best_cpu_ms(lambda: default.compute(gray, list(keys)))
    half = cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2), interpolation=cv2.INTER_AREA)
    row["detect+describe halved"], _ = _best_cpu_ms(lambda: default.detectAndCompute(half, None))
    row["keypoints"], row["keypoints lower"] = len(keys), len(found)
    row["upsampled octave %"] = 100 * np.mean([(k.octave & 255) == 255 for k in keys])
    return row


def thread_overlap(image1, image2) -> dict:
    """Wall and per-thread CPU ms of the default detection of two images on two threads, as
    ``estimate_pair`` runs it."""
    from concurrent.futures import ThreadPoolExecutor

    from ppo_cv.features import detect_features

    def timed(image):
        start = time.thread_time()
        detect_features(image)
        return 1e3 * (time.thread_time() - start)

    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=2) as pool:
        cpu1, cpu2 = pool.map(timed, (image1, image2))
    wall = 1e3 * (time.perf_counter() - start)
    return {"wall": wall, "thread 1": cpu1, "thread 2": cpu2,
            "idle %": 100 * (1 - (cpu1 + cpu2) / (2 * wall))}  # fmt: skip


def parts_report(folder: Path, pairs: int) -> list[str]:
    """Markdown: median SIFT parts over the images of the first ``pairs`` freiburg pairs and
    the thread overlap of their detection."""
    listed = anchors.read_pairs_file(folder / "pairs_with_gt.txt")[:pairs]
    read = lambda name: cv2.imread(str(folder / "images" / name))  # noqa: E731
    names = sorted({pair[key] for pair in listed for key in ("name1", "name2")})
    parts = [sift_parts(cv2.cvtColor(read(name), cv2.COLOR_BGR2GRAY)) for name in names]
    overlap = [thread_overlap(read(p["name1"]), read(p["name2"])) for p in listed]
    lines = [f"OpenCV SIFT on {len(names)} freiburg images, one thread, median of the least "
             "CPU of three runs:", "", "| part | median |", "|---|---:|"]  # fmt: skip
    lines += [f"| {key} | {np.median([r[key] for r in parts]):.1f} |" for key in parts[0]]
    lines += ["", f"The default detection of both images of {len(listed)} pairs on two threads "
              "(ms; idle: the share of the two threads' wall time without CPU):", "",
              "| | median | max |", "|---|---:|---:|"]  # fmt: skip
    lines += [
        f"| {key} | {np.median([r[key] for r in overlap]):.1f} | "
        f"{np.max([r[key] for r in overlap]):.1f} |"
        for key in overlap[0]
    ]
    return lines


def _freiburg(folder: Path):
    for pair in anchors.read_pairs_file(folder / "pairs_with_gt.txt"):
        read = (cv2.imread(str(folder / "images" / pair[key])) for key in ("name1", "name2"))
        yield f"{pair['name1']} {pair['name2']}", (*read, pair["K1"], pair["K2"])


def _renders(per_preset: int):
    from ppo_cv.data_gen.io import make_pair

    for motion in compare.MOTIONS:
        for index in range(per_preset):
            pair = make_pair(motion, seed=0, index=index)
            bgr = (cv2.cvtColor(image, cv2.COLOR_RGB2BGR) for image in (pair.image1, pair.image2))
            yield f"{motion} {index}", (*bgr, pair.K1, pair.K2)


def _group(row: dict) -> str:
    again = "second consensus" if row["second_consensus"] else "one consensus"
    return again + (", tracks" if row["tracks"] else "")


def _summary_row(label: str, rows: list[dict]) -> str:
    ours = np.median([r["cpu"] for r in rows])
    opencv = np.median([r["opencv"]["cpu"] for r in rows])
    stages = [np.median([r["stages"].get(s, 0.0) for r in rows]) * 1e3 for s in STAGES]
    cells = " | ".join(f"{v:.0f}" for v in stages)
    return f"| {label} ({len(rows)}) | {ours:.3f} | {opencv:.3f} | {cells} |"


def report(freiburg_rows: list[dict], render_rows: list[dict]) -> list[str]:
    """Markdown tables of the profiled pairs."""
    lines = [
        "| pairs | estimate_pair CPU s | OpenCV pipeline CPU s | "
        + " | ".join(f"{s} ms" for s in STAGES)
        + " |",
        "|---|" + "---:|" * (2 + len(STAGES)),
    ]
    groups: dict[str, list[dict]] = {}
    for row in freiburg_rows:
        groups.setdefault(_group(row), []).append(row)
    for label in sorted(groups):
        lines.append(_summary_row(f"freiburg, {label}", groups[label]))
    if freiburg_rows:
        lines.append(_summary_row("freiburg, all", freiburg_rows))
    if render_rows:
        lines.append(_summary_row("renders, all", render_rows))
    for name, rows in (("freiburg", freiburg_rows), ("renders", render_rows)):
        if not rows:
            continue
        opencv = {
            part: np.median([r["opencv"][part] for r in rows]) * 1e3
            for part in ("features", "matching", "pose")
        }
        lines += ["", f"OpenCV's pipeline on the {name} pairs, median ms: "
                  + ", ".join(f"{k} {v:.0f}" for k, v in opencv.items())]  # fmt: skip
    if freiburg_rows:
        total = sum(sum(r["stages"].values()) for r in freiburg_rows)
        shares = {
            s: sum(r["stages"].get(s, 0.0) for r in freiburg_rows) / total for s in STAGES
        }
        lines += ["", "Share of the CPU summed over the freiburg pairs: "
                  + ", ".join(f"{s} {100 * v:.0f} %" for s, v in shares.items())]  # fmt: skip
        order = np.argsort([r["cpu"] for r in freiburg_rows])
        middle = freiburg_rows[int(order[(len(order) - 1) // 2])]
        lines += [
            "",
            f"The freiburg pair of median CPU, {middle['name']} ({middle['cpu']:.3f} s, "
            f"{_group(middle)}): "
            + ", ".join(f"{s} {v * 1e3:.0f} ms" for s, v in middle["stages"].items() if v > 5e-4)
            + "; OpenCV's pipeline "
            + ", ".join(f"{k} {middle['opencv'][k] * 1e3:.0f} ms"
                        for k in ("features", "matching", "pose")),  # fmt: skip
        ]
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--freiburg", type=Path, default=compare.FREIBURG)
    parser.add_argument("--renders", type=int, default=4, help="pairs per motion preset")
    parser.add_argument("--json", type=Path, help="also write the rows here")
    parser.add_argument(
        "--detect-once", action="store_true", help="estimate_pair with detect_once=True"
    )
    parser.add_argument(
        "--sift-parts",
        type=int,
        metavar="PAIRS",
        help="only the parts of SIFT on the images of the first PAIRS freiburg pairs",
    )
    args = parser.parse_args(argv)
    options = PairOptions(detect_once=args.detect_once)
    cv2.setNumThreads(1)
    machine = compare._machine()
    if args.sift_parts and not (args.freiburg / "pairs_with_gt.txt").is_file():
        parser.error(f"--sift-parts needs the freiburg pairs; none in {args.freiburg} (give "
                     "--freiburg DIR or set PPO_CV_SHARED)")  # fmt: skip
    if args.sift_parts:
        lines = parts_report(args.freiburg, args.sift_parts)
        print(f"{machine['cpu']}, {machine['cores']} logical cores, 1-minute load average "
              f"{machine['load']:.2f} at the start and {compare._machine()['load']:.2f} at the "
              "end\n")  # fmt: skip
        print("\n".join(lines))
        return
    sources = []
    if (args.freiburg / "pairs_with_gt.txt").is_file():
        sources.append(("freiburg", _freiburg(args.freiburg)))
    else:
        print(f"no freiburg pairs in {args.freiburg}: rendered pairs only", file=sys.stderr)
    sources.append(("renders", _renders(args.renders)))
    rows: dict[str, list[dict]] = {"freiburg": [], "renders": []}
    for source, pairs in sources:
        for name, images in pairs:
            row = {"name": name, **profile_pair(*images, options)}
            rows[source].append(row)
            print(f"{name}: {row['cpu']:.3f} s, OpenCV {row['opencv']['cpu']:.3f} s",
                  file=sys.stderr, flush=True)  # fmt: skip
    machine["load_after"] = compare._machine()["load"]
    print(
        f"{machine['cpu']}, {machine['cores']} logical cores, 1-minute load average "
        f"{machine['load']:.2f} at the start and {machine['load_after']:.2f} at the end; "
        f"detect_once={options.detect_once}\n"
    )
    print("\n".join(report(rows["freiburg"], rows["renders"])))
    if args.json is not None:
        args.json.write_text(json.dumps({"machine": machine, **rows}, indent=1))


if __name__ == "__main__":
    main()
