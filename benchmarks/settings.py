"""Speed against accuracy: what the two costly stages of ``estimate_pair`` buy, on real pairs.

Run ``python benchmarks/settings.py [--freiburg DIR] [--pano DIR] [--json FILE]`` from the
repository root (about 4-5 minutes on 2 cores).

Two stages cost more than the rest of a pair and can be turned off:

- the second detection of a weak pair (``PairOptions.redetect_below``, ``--redetect-below 0``
  turns it off), which detects SIFT again at a lower threshold where the first consensus has
  fewer than 100 inliers;
- the photometric refit of a pure rotation or rotation candidate (``PairOptions.photometric``,
  ``--no-photometric``), which aligns windows of the images by intensity.

Each setting runs on every freiburg pair (translating, pseudo ground truth) and, when
``../shared/data/pano_dev`` is there, every pano_dev pair (real tripod panoramas), one pair
at a time in this process (OpenCV on one thread, one BLAS thread), beside the OpenCV pipeline
of ``compare.py`` section 4 (SIFT, ratio test, ``findEssentialMat`` USAC_MAGSAC,
``recoverPose``) on the same images in the same run. Prints one markdown table per set: per
setting the median wall and CPU seconds per pair (CPU summed over threads), AUC@5/10/20 of the
pose error (the larger of the rotation and translation-direction errors; 180 degrees for a
pair with no pose) or, on the panoramas, the rotation error (median, share within 1 degree)
and the share flagged as pure rotations.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402
import compare  # noqa: E402

from ppo_cv import PairOptions, estimate_pair  # noqa: E402

SHARED = Path(os.environ.get("PPO_CV_SHARED", compare.ROOT.parent / "shared")) / "data"
SETTINGS = {
    "default": PairOptions(),
    "--redetect-below 0": PairOptions(redetect_below=0),
    "--no-photometric": PairOptions(photometric=False),
    "--redetect-below 0 --no-photometric": PairOptions(redetect_below=0, photometric=False),
}
OPENCV = "OpenCV pipeline"


@dataclass(frozen=True)
class Outcome:
    """One pipeline on one pair: wall and CPU seconds, rotation and pose errors (degrees, 180
    without a pose) and whether it called the pair a pure rotation."""

    wall: float
    cpu: float
    err_R: float
    err: float
    pure_rotation: bool


def _ours(options: PairOptions, image1, image2, K1, K2, R_gt, t_gt) -> Outcome:
    def run():
        try:
            return estimate_pair(image1, image2, K1, K2, options=options)
        except ValueError:
            return None

    wall, cpu, result = compare._timed(run)
    R, t = (None, None) if result is None else (result.R, result.t)
    e_R, _, e = anchors.pose_error_deg(R, t, R_gt, t_gt)
    return Outcome(wall, cpu, e_R, e, bool(result is not None and result.pure_rotation))


def _opencv(image1, image2, K1, K2, R_gt, t_gt) -> Outcome:
    wall, cpu, res = compare._timed(lambda: compare._opencv_pipeline("opencv", image1, image2,
                                                                       K1, K2))  # fmt: skip
    e_R, _, e = anchors.pose_error_deg(res.R, res.t, R_gt, t_gt)
    return Outcome(wall, cpu, e_R, e, False)


def run_set(folder: Path) -> dict[str, list[Outcome]]:
    """Every setting and the OpenCV pipeline on every pair of ``folder``'s pairs file."""
    outcomes: dict[str, list[Outcome]] = {name: [] for name in [*SETTINGS, OPENCV]}
    for pair in anchors.read_pairs_file(folder / "pairs_with_gt.txt"):
        images = [cv2.imread(str(folder / "images" / pair[key])) for key in ("name1", "name2")]
        args = (*images, pair["K1"], pair["K2"], pair["R"], pair["t"])
        for name, options in SETTINGS.items():
            outcomes[name].append(_ours(options, *args))
        outcomes[OPENCV].append(_opencv(*args))
    return outcomes


def summary(outcomes: list[Outcome]) -> dict[str, float]:
    """Median wall and CPU seconds, AUC@5/10/20 (percent), the rotation error's median and
    share within 1 degree, the share flagged and the pairs without a pose."""
    err = [o.err for o in outcomes]
    err_R = np.array([o.err_R for o in outcomes])
    return {
        "wall": float(np.median([o.wall for o in outcomes])),
        "cpu": float(np.median([o.cpu for o in outcomes])),
        **{f"auc{t}": 100 * anchors.auc(err, t) for t in (5, 10, 20)},
        "median_R": float(np.median(err_R)),
        "within_1deg": 100 * float(np.mean(err_R < 1.0)),
        "flagged": 100 * float(np.mean([o.pure_rotation for o in outcomes])),
        "no_pose": int(sum(o.err == 180.0 for o in outcomes)),
    }


def _cells(s: dict[str, float], rotations: bool) -> str:
    """The accuracy cells of one row: rotation error and flags, or AUC and pairs without a pose."""
    if rotations:
        return f"{s['median_R']:.2f} deg | {s['within_1deg']:.0f} % | {s['flagged']:.0f} %"
    return f"{s['auc5']:.1f} / {s['auc10']:.1f} / {s['auc20']:.1f} | {s['no_pose']}"


def table(label: str, summaries: dict[str, dict], rotations: bool) -> str:
    """Markdown table of one set: a row per setting and the OpenCV pipeline."""
    accuracy = ("R error, median | within 1 deg | flagged" if rotations
                else "AUC@5/10/20 | no pose")  # fmt: skip
    head = f"| setting | wall, median | CPU, median | {accuracy} |"
    rule = "|---|" + "---:|" * (head.count("|") - 2)
    rows = [f"| {name} | {s['wall']:.3f} s | {s['cpu']:.3f} s | {_cells(s, rotations)} |"
            for name, s in summaries.items()]  # fmt: skip
    return "\n".join([f"{label}:", "", head, rule, *rows])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--freiburg", type=Path, default=SHARED / "freiburg")
    parser.add_argument("--pano", type=Path, default=SHARED / "pano_dev")
    parser.add_argument("--json", type=Path, help="also write the summaries here")
    args = parser.parse_args(argv)
    sets = {"freiburg": (args.freiburg, False), "pano_dev": (args.pano, True)}
    present = {k: v for k, v in sets.items() if (v[0] / "pairs_with_gt.txt").is_file()}
    if not present:
        parser.error(f"no pairs file in {args.freiburg} or {args.pano}: pass --freiburg or --pano")
    cv2.setNumThreads(1)
    machine = compare._machine()
    results = {}
    for label, (folder, rotations) in present.items():
        summaries = {name: summary(o) for name, o in run_set(folder).items()}
        results[label] = summaries
        print(table(f"{label} ({folder})", summaries, rotations) + "\n", flush=True)
    after = compare._machine()["load"]
    print(f"Machine: {machine['cpu']}, {machine['cores']} cores; load average {machine['load']} "
          f"before, {after} after")  # fmt: skip
    if args.json is not None:
        args.json.write_text(json.dumps({"machine": machine, "sets": results}, indent=1))


if __name__ == "__main__":
    main()
