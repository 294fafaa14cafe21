"""Wall time of ``ppo-cv pair``, process start included, on three pairs in one run.

- the built-in 640x480 demo pair (a general motion);
- a 640x480 render of a pure rotation (``ppo_cv.data_gen`` ``pure-rotation``, seed 0, index 0),
  which runs the photometric refit;
- a real tripod pair of ``../shared/data/pano_dev`` (its first pair, a pure rotation that runs
  the refit), skipped with a note when the shared data is absent.

Run ``python benchmarks/cli_time.py [--runs 7] [--floor]``: prints the machine, the median
wall time of the whole command per pair with its ratio to the demo pair's, and the median of
each pipeline stage as reported in the ``--json`` output. The pairs take turns within each
run, so a change of load on the machine touches them alike. ``--floor`` adds each rotation
pair once more with ``--no-photometric``: what the pair costs without its refit, the part of
its time that the refit cannot explain.
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


def _tripod_pair() -> tuple[str, list[str]] | None:
    """Label and arguments of ``ppo-cv pair`` for the first pano_dev pair; None without it."""
    import cv2

    pairs = PANO_DEV / "pairs_with_gt.txt"
    if not pairs.is_file():
        return None
    fields = pairs.read_text().split("\n", 1)[0].split()
    K1 = [[float(v) for v in fields[4 + 3 * r : 7 + 3 * r]] for r in range(3)]
    K2 = [[float(v) for v in fields[13 + 3 * r : 16 + 3 * r]] for r in range(3)]
    images = [str(PANO_DEV / "images" / name) for name in fields[:2]]
    height, width = cv2.imread(images[0], cv2.IMREAD_GRAYSCALE).shape
    label = f"real tripod pair, pano_dev {fields[0]} ({width}x{height})"
    return label, [*images, "--K", _intrinsics(K1), "--K2", _intrinsics(K2)]


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


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument(
        "--floor", action="store_true", help="the rotation pairs also with --no-photometric"
    )
    args = parser.parse_args(argv)
    notes = []
    with tempfile.TemporaryDirectory() as folder:
        pairs = {
            "demo pair (640x480)": [],
            "pure-rotation render (640x480)": _rendered_rotation(Path(folder)),
        }
        tripod = _tripod_pair()
        if tripod is None:
            notes.append(f"Note: no real tripod pair measured ({PANO_DEV} is absent).")
        else:
            pairs[tripod[0]] = tripod[1]
        if args.floor:
            pairs |= {
                f"{label}, --no-photometric": [*arguments, "--no-photometric"]
                for label, arguments in list(pairs.items())[1:]
            }
        measured = run(pairs, args.runs)
    print(report(measured, args.runs, notes))


if __name__ == "__main__":
    main()
