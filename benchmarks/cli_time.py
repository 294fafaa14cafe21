"""Wall time of ``ppo-cv pair``, process start included, on three pairs in one run.

- the built-in 640x480 demo pair (a general motion);
- a 640x480 render of a pure rotation (``ppo_cv.data_gen`` ``pure-rotation``, seed 0, index 0),
  which runs the photometric refit;
- a real tripod pair of ``../shared/data/pano_dev`` (its first pair, a pure rotation that runs
  the refit, 611x918: 1.83 times the demo pair's pixels), skipped with a note when the shared
  data is absent; with ``--every-sequence`` the first pair of each of its three sequences
  (``book`` 611x918, ``bookshelf`` 382x574, ``csie`` 720x540), each labelled with its pixels
  against the demo pair's, since detection and the refit's windows grow with them.

With ``--phone-size`` that first pair also enlarged to a phone photo's 12 megapixels (a longer
side of 4032 px, JPEG): detected on a copy reduced to ``--max-size`` (2000 px) and refitted on
it, at the threshold times that reduction.

Run ``python benchmarks/cli_time.py [--runs 7] [--floor] [--every-sequence] [--phone-size]``:
prints the machine, the median wall time of the whole command per pair with its ratio to the
demo pair's, and the median of each pipeline stage as reported in the ``--json`` output. The
pairs take turns within each run, so a change of load on the machine touches them alike.
``--floor`` adds each rotation pair once more with ``--no-photometric``: what the pair costs
without its refit, the part of its time that the refit cannot explain. ``--refit N`` adds where
the refit's time goes: the photometric refit of each rotation pair, its inputs taken from one
run of ``estimate_pair``, replayed N times in this process with one BLAS thread (the command's)
and its threads run one after the other, the process CPU time of each part (median over the
calls).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PANO_DEV = (
    Path(os.environ.get("PPO_CV_SHARED", Path(__file__).resolve().parents[1] / ".." / "shared"))
    / "data"
    / "pano_dev"
)


def installed_command() -> list[str]:
    """The console script of this interpreter's environment (what a user of it runs)."""
    beside = Path(sys.executable).with_name("ppo-cv")
    exe = str(beside) if beside.is_file() else shutil.which("ppo-cv")
    if exe is None:
        raise SystemExit("ppo-cv is not installed: pip install .")
    return [exe]


def _intrinsics(K) -> str:
    return f"{K[0][0]},{K[1][1]},{K[0][2]},{K[1][2]}"


def _rendered_rotation(folder: Path) -> list[str]:
    """Arguments of ``ppo-cv pair`` for a 640x480 pure-rotation render written to ``folder``."""
    import cv2

    from ppo_cv import data_gen

    pair = data_gen.make_pair("pure-rotation", seed=0, index=0)
    paths = [folder / "rotation_1.png", folder / "rotation_2.png"]
    for path, image in zip(paths, (pair.image1, pair.image2), strict=True):
        cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    cameras = ["--K", _intrinsics(pair.K1), "--K2", _intrinsics(pair.K2)]
    return [str(paths[0]), str(paths[1]), *cameras]


def _tripod_pairs(every_sequence: bool) -> list[tuple[str, list[str]]]:
    """Labels and arguments of ``ppo-cv pair`` for the first pano_dev pair, or with
    ``every_sequence`` for the first pair of each of its sequences (the image names' prefix
    before ``_``); none without the data."""
    pairs = PANO_DEV / "pairs_with_gt.txt"
    if not pairs.is_file():
        return []
    lines = [line.split() for line in pairs.read_text().splitlines() if line.strip()]
    firsts = {fields[0].split("_", 1)[0]: fields for fields in reversed(lines)}
    chosen = list(reversed(firsts.values())) if every_sequence else lines[:1]
    return [_tripod_arguments(fields) for fields in chosen]


def _tripod_arguments(fields: list[str]) -> tuple[str, list[str]]:
    """Label (name, size, pixels against the demo pair's) and ``ppo-cv pair`` arguments of
    one line of the pano_dev pairs file."""
    import cv2

    K1 = [[float(v) for v in fields[4 + 3 * r : 7 + 3 * r]] for r in range(3)]
    K2 = [[float(v) for v in fields[13 + 3 * r : 16 + 3 * r]] for r in range(3)]
    images = [str(PANO_DEV / "images" / name) for name in fields[:2]]
    height, width = cv2.imread(images[0], cv2.IMREAD_GRAYSCALE).shape
    pixels = width * height / (640 * 480)
    label = f"real tripod pair, pano_dev {fields[0]} ({width}x{height}, {pixels:.2f}x the pixels)"
    return label, [*images, "--K", _intrinsics(K1), "--K2", _intrinsics(K2)]


PHONE_SIDE = 4032
"""Longer side, pixels, of ``--phone-size``'s pair: a 12-megapixel phone photo."""


def _phone_size_pair(folder: Path) -> list[tuple[str, list[str]]]:
    """Label and ``ppo-cv pair`` arguments of the first pano_dev pair enlarged to a longer side
    of :data:`PHONE_SIDE` (bicubic, written as JPEG at quality 95 as a phone does, the camera
    matrices scaled by the pixel-centre map); none without the data."""
    import cv2
    import numpy as np

    pairs = PANO_DEV / "pairs_with_gt.txt"
    if not pairs.is_file():
        return []
    fields = next(line.split() for line in pairs.read_text().splitlines() if line.strip())
    images = [cv2.imread(str(PANO_DEV / "images" / name)) for name in fields[:2]]
    scale = PHONE_SIDE / max(images[0].shape[:2])
    S = np.array([[scale, 0, (scale - 1) / 2], [0, scale, (scale - 1) / 2], [0, 0, 1]])
    paths = [folder / f"phone_{i}.jpg" for i in (1, 2)]
    for path, image in zip(paths, images, strict=True):
        enlarged = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
        cv2.imwrite(str(path), enlarged, [cv2.IMWRITE_JPEG_QUALITY, 95])
    height, width = cv2.imread(str(paths[0]), cv2.IMREAD_GRAYSCALE).shape
    cameras = [
        S @ np.array([float(v) for v in fields[start : start + 9]]).reshape(3, 3)
        for start in (4, 13)
    ]
    pixels = width * height / (640 * 480)
    label = (
        f"real tripod pair, pano_dev {fields[0]} enlarged to {width}x{height} "
        f"({pixels:.1f}x the pixels)"
    )
    arguments = [*map(str, paths), "--K", _intrinsics(cameras[0]), "--K2", _intrinsics(cameras[1])]
    return [(label, arguments)]


def run(pairs: dict[str, list[str]], runs: int) -> dict[str, tuple[list, dict, list]]:
    """Per pair: wall times, stage times and the verdicts, the pairs taking turns."""
    measured = {label: ([], {}, []) for label in pairs}
    for _ in range(runs):
        for label, arguments in pairs.items():
            walls, stages, verdicts = measured[label]
            start = time.perf_counter()
            out = subprocess.run(
                [*installed_command(), "pair", *arguments, "--json"], capture_output=True, text=True
            )
            walls.append(time.perf_counter() - start)
            if out.returncode != 0:
                raise SystemExit(f"ppo-cv pair failed on the {label}: {out.stderr.strip()}")
            data = json.loads(out.stdout)
            for stage, seconds in data["timings"].items():
                stages.setdefault(stage, []).append(seconds)
            verdicts.append("pure rotation" if data["pure_rotation"] else data["model"])
    return measured


def _machine() -> str:
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"{platform.system()} {platform.release()}, Python {platform.python_version()}; "
        f"load average {load} at the end"
    )


def report(measured: dict[str, tuple[list, dict, list]], runs: int, notes: list[str]) -> str:
    labels = list(measured)
    demo = statistics.median(measured[labels[0]][0])
    lines = [f"ppo-cv pair, {runs} runs per pair, taking turns", "", f"Machine: {_machine()}", ""]
    lines += ["| pair | verdict | whole command, median | / demo pair |", "|---|---|---:|---:|"]
    for label, (walls, _, verdicts) in measured.items():
        wall = statistics.median(walls)
        verdict = max(set(verdicts), key=verdicts.count)
        lines.append(f"| {label} | {verdict} | {wall:.2f} s | {wall / demo:.2f} |")
    lines += ["", "Median of each stage (ms):", ""]
    lines += ["| stage | " + " | ".join(labels) + " |", "|---|" + "---:|" * len(labels)]
    stages = list(dict.fromkeys(s for _, found, _ in measured.values() for s in found))
    for stage in stages:
        cells = [
            f"{statistics.median(found[stage]) * 1e3:.1f}" if stage in found else "-"
            for _, found, _ in measured.values()
        ]
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    return "\n".join([*lines, *(["", *notes] if notes else [])])


REFIT_PARTS = {
    "_align": "polish: window alignment",
    "_fit_windows": "refits of the tracks",
    "_seen_through": "warps of image 2",
    "_prepare": "preparing the images",
    "_search": "Lucas-Kanade searches",
    "_corner_candidates": "corner response (both sides)",
    "_corners": "corners",
    "_plane_parallax": "the tracks' parallax",
}
"""Functions of ``ppo_cv.photometric`` timed by ``--refit``, each without the others it calls."""


def _refit_inputs(arguments: list[str]) -> tuple[tuple, dict] | None:
    """The arguments of the first ``refine_rotation_photometric`` call of ``estimate_pair`` on
    the pair of ``ppo-cv pair`` ``arguments`` (two images, ``--K``, ``--K2``); None when the
    pair runs no refit."""
    import cv2

    from ppo_cv import estimate_pair, pipeline

    def camera(text: str) -> list[list[float]]:
        fx, fy, cx, cy = (float(v) for v in text.split(","))
        return [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]

    images = [cv2.imread(path) for path in arguments[:2]]
    K1, K2 = camera(arguments[3]), camera(arguments[5])
    calls = []
    refine = pipeline.refine_rotation_photometric

    def recorded(*args, **kwargs):
        calls.append((args, kwargs))
        return refine(*args, **kwargs)

    pipeline.refine_rotation_photometric = recorded
    try:
        estimate_pair(*images, K1, K2)
    finally:
        pipeline.refine_rotation_photometric = refine
    return calls[0] if calls else None


def refit_profile(arguments: list[str], calls: int) -> dict[str, float] | None:
    """Median process CPU time (s) of each part of the pair's photometric refit over ``calls``
    replays, its threads one after the other; ``"lens fits"`` the lens rotation fits per call.
    None when the pair runs no refit."""
    from ppo_cv import photometric

    recorded = _refit_inputs(arguments)
    if recorded is None:
        return None
    args, kwargs = recorded
    spent, stack, fits = {}, [], [0]
    originals = {name: getattr(photometric, name) for name in [*REFIT_PARTS, "_threaded_map"]}
    originals["fit_rotation_lens"] = photometric.fit_rotation_lens

    def timed(name, function):
        def call(*a, **k):
            stack.append(0.0)
            start = time.process_time()
            try:
                return function(*a, **k)
            finally:
                elapsed = time.process_time() - start
                spent[name] = spent.get(name, 0.0) + elapsed - stack.pop()
                if stack:
                    stack[-1] += elapsed

        return call

    def counted(*a, **k):
        fits[0] += 1
        return originals["fit_rotation_lens"](*a, **k)

    for name in REFIT_PARTS:
        setattr(photometric, name, timed(name, originals[name]))
    photometric._threaded_map = lambda function, items: [function(item) for item in items]
    photometric.fit_rotation_lens = counted
    samples = []
    try:
        for _ in range(calls):
            spent.clear()
            fits[0] = 0
            start = time.process_time()
            photometric.refine_rotation_photometric(*args, **kwargs)
            total = time.process_time() - start
            samples.append({**spent, "rest": total - sum(spent.values()), "total": total,
                            "lens fits": fits[0]})  # fmt: skip
    finally:
        for name, function in originals.items():
            setattr(photometric, name, function)
    return {key: statistics.median(s.get(key, 0.0) for s in samples) for key in samples[0]}


def refit_report(profiles: dict[str, dict[str, float]], calls: int) -> str:
    """Markdown table of :func:`refit_profile` per pair."""
    labels = list(profiles)
    lines = [
        f"Photometric refit replayed in process, {calls} calls per pair, one BLAS thread, its"
        " threads one after the other: median process CPU time (ms)",
        "",
        "| part | " + " | ".join(labels) + " |",
        "|---|" + "---:|" * len(labels),
    ]
    for key, name in [*REFIT_PARTS.items(), ("rest", "the rest"), ("total", "total")]:
        cells = [f"{profile.get(key, 0.0) * 1e3:.1f}" for profile in profiles.values()]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    counts = [f"{profile['lens fits']:.0f}" for profile in profiles.values()]
    lines.append("| lens rotation fits (count) | " + " | ".join(counts) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument(
        "--floor", action="store_true", help="the rotation pairs also with --no-photometric"
    )
    parser.add_argument(
        "--refit", type=int, default=0, metavar="N",
        help="also replay each rotation pair's photometric refit N times and time its parts",
    )  # fmt: skip
    parser.add_argument(
        "--every-sequence", action="store_true",
        help="the first pair of each pano_dev sequence, not only of the first",
    )  # fmt: skip
    parser.add_argument(
        "--phone-size", action="store_true",
        help=f"also the first pano_dev pair enlarged to a longer side of {PHONE_SIDE} px",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.refit:
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads, as the command
    notes = []
    with tempfile.TemporaryDirectory() as folder:
        pairs = {
            "demo pair (640x480)": [],
            "pure-rotation render (640x480)": _rendered_rotation(Path(folder)),
        }
        tripods = _tripod_pairs(args.every_sequence)
        if not tripods:
            notes.append(f"Note: no real tripod pair measured ({PANO_DEV} is absent).")
        pairs |= dict(tripods)
        if args.phone_size:
            pairs |= dict(_phone_size_pair(Path(folder)))
        rotations = list(pairs.items())[1:]
        if args.floor:
            pairs |= {
                f"{label}, --no-photometric": [*arguments, "--no-photometric"]
                for label, arguments in rotations
            }
        measured = run(pairs, args.runs)
        profiles = {
            label: refit_profile(arguments, args.refit)
            for label, arguments in rotations
            if args.refit
        }
    skipped = [label for label, profile in profiles.items() if profile is None]
    notes += [f"Note: the {label} runs no photometric refit." for label in skipped]
    profiles = {label: profile for label, profile in profiles.items() if profile is not None}
    print(report(measured, args.runs, notes))
    if profiles:
        print("\n" + refit_report(profiles, args.refit))


if __name__ == "__main__":
    main()
