"""Is ``t_sigma_deg`` a number a user can threshold? Its calibration on translating pairs.

``PairResult.uncertainty.t_sigma_deg`` is one standard deviation of the direction of ``t``
(:func:`ppo_cv.refine.translation_sigma_deg`). For each translating set this script compares
it with the actual angle between the returned ``t`` and the true one, over the pairs called a
general motion or a plane. For a calibrated deviation of a direction on the sphere (two
components, the larger deviation reported) the error lies below ``1.18 t_sigma`` on at least
half of the pairs (the median of a Rayleigh distribution; more when one axis dominates) and
below ``3 t_sigma`` on nearly all of them. Beside it, the same deviation with the focal length
held exact (``focal_prior=None``), recomputed from each result: what the noise alone allows.

Sets: the 85 freiburg pairs (real, pseudo ground truth; read errors below 0.5 degree as its
noise), ``ppo_cv.data_gen``'s ``tiny-baseline`` at baseline / median depth 0.02 and 0.05 and
``general`` (``REAL_PHOTO``: focal given up to 3 % off, radial distortion nobody models, a
25-35 degree field, JPEG), and the renders of ``tests/imperfect.py`` at baseline / median depth
0.02 and 0.05 (480x360, the same imperfections).

Run ``python benchmarks/translation_sigma.py --report docs/translation_sigma.md`` (about 2 min
on 2 cores); it prints a markdown table and the machine, and with ``--report`` writes them with
this description.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

import ppo_cv
from ppo_cv import PairOptions, data_gen, estimate_pair
from ppo_cv.camera import pixels_to_normalized
from ppo_cv.metrics import direction_error_deg
from ppo_cv.plane import undistort_division
from ppo_cv.refine import T_SIGMA_CAP_DEG, translation_sigma_deg
from ppo_cv.rotation import K1_PRIOR

sys.path.insert(0, str(Path(__file__).resolve().parent))

from pure_rotation import FREIBURG, imperfect_render  # noqa: E402


def _focal_exact_sigma(result, K1: np.ndarray, K2: np.ndarray) -> float:
    """``t_sigma_deg`` of ``result`` recomputed with the focal length held exact."""
    k1 = result.plane.k1 if result.plane is not None else result.lens.radial_k1
    k1 = k1 if np.isfinite(k1) else None
    x1 = pixels_to_normalized(result.keypoints1[result.matches[:, 0]], K1, None)
    x2 = pixels_to_normalized(result.keypoints2[result.matches[:, 1]], K2, None)
    c1, c2 = (np.column_stack([x, np.ones(len(x))]) for x in (x1, x2))
    if k1 is not None:
        c1, c2 = undistort_division(c1, k1), undistort_division(c2, k1)
    prior = K1_PRIOR if k1 is not None else None
    return translation_sigma_deg(
        result.R, result.t, c1, c2, result.inliers, focal_prior=None, k1_prior=prior
    )


def _sets(count: int):
    """``(name, pairs)``, each pair ``(image1, image2, K1, K2, t_true)`` with BGR images."""

    def freiburg():
        for pair in data_gen.read_pairs(FREIBURG / "pairs_with_gt.txt"):
            i1, i2 = (cv2.imread(str(FREIBURG / "images" / pair[k])) for k in ("name1", "name2"))
            yield i1, i2, pair["K1"], pair["K2"], pair["t"]

    def rendered(motion, ratio):
        for index in range(count):
            pair = data_gen.make_pair(
                motion, seed=0, index=index, imperfections=data_gen.REAL_PHOTO,
                baseline_ratio=ratio,
            )  # fmt: skip
            bgr1, bgr2 = (np.ascontiguousarray(v[..., ::-1]) for v in (pair.image1, pair.image2))
            yield bgr1, bgr2, pair.K1_given, pair.K2_given, pair.t

    def harness(ratio):
        for seed in range(100, 100 + count):
            pair = imperfect_render(seed, ratio)
            yield pair.image1, pair.image2, pair.K_given, pair.K_given, pair.t

    if (FREIBURG / "pairs_with_gt.txt").is_file():
        yield "freiburg (real)", freiburg()
    yield "data_gen tiny-baseline 0.02", rendered("tiny-baseline", 0.02)
    yield "data_gen tiny-baseline 0.05", rendered("tiny-baseline", 0.05)
    yield "data_gen general", rendered("general", None)
    yield "harness render 0.02", harness(0.02)
    yield "harness render 0.05", harness(0.05)


def run(count: int) -> list[dict]:
    """One row per set: counts and the calibration of ``t_sigma_deg``."""
    options = PairOptions(photometric=False)
    rows = []
    for name, pairs in _sets(count):
        errors, sigmas, exact, flagged, failed = [], [], [], 0, 0
        for image1, image2, K1, K2, t_true in pairs:
            try:
                result = estimate_pair(image1, image2, K1, K2, options=options)
            except ValueError:
                failed += 1
                continue
            if result.pure_rotation:
                flagged += 1
                continue
            errors.append(float(direction_error_deg(result.t, t_true, signed=False)))
            sigmas.append(result.uncertainty.t_sigma_deg)
            exact.append(_focal_exact_sigma(result, K1, K2))
        arrays = (np.array(errors), np.array(sigmas), np.array(exact))
        rows.append(_row(name, *arrays, flagged, failed))
    return rows


def _row(name, errors, sigmas, exact, flagged, failed) -> dict:
    def ratios(s):
        finite = s < T_SIGMA_CAP_DEG
        z = errors[finite] / s[finite]
        return {
            "capped": int(np.count_nonzero(~finite)),
            "median_ratio": float(np.median(z)) if z.size else float("nan"),
            "within_1_18": float(np.mean(z < 1.18)) if z.size else float("nan"),
            "within_3": float(np.mean(z < 3.0)) if z.size else float("nan"),
            "median_sigma": float(np.median(s)) if s.size else float("nan"),
        }

    return {
        "set": name,
        "pairs": int(errors.size + flagged + failed),
        "scored": int(errors.size),
        "median_error": float(np.median(errors)) if errors.size else float("nan"),
        "t_sigma": ratios(sigmas),
        "focal_exact": ratios(exact),
    }


def table(rows: list[dict]) -> str:
    lines = [
        "| set | pairs | scored | median t error (deg) | median t_sigma_deg | capped "
        "| median error / t_sigma | error < 1.18 t_sigma | error < 3 t_sigma "
        "| focal held exact: median error / sigma | error < 3 sigma |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        s, e = r["t_sigma"], r["focal_exact"]
        lines.append(
            f"| {r['set']} | {r['pairs']} | {r['scored']} | {r['median_error']:.2f} "
            f"| {s['median_sigma']:.2f} | {s['capped']} | {s['median_ratio']:.2f} "
            f"| {100 * s['within_1_18']:.0f} % | {100 * s['within_3']:.0f} % "
            f"| {e['median_ratio']:.2f} | {100 * e['within_3']:.0f} % |"
        )
    return "\n".join(lines)


FINDINGS = """\
On the renders the median of error / `t_sigma_deg` is 0.64-1.48, and 1.40-2.29 with the focal
length held exact: the given focal, up to 3 % off, moves `t` by 0.8 degree per percent in a
28 degree field, which the noise alone does not account for. On freiburg it is 2.54 (3.04
held exact) against a median `t_sigma_deg` of 0.39 degree, of the size of the pseudo ground
truth's own error. The tails are heavier than a Gaussian's (error below 3 `t_sigma_deg` on
64-93 % of the pairs of a set): a deviation describes the spread around the solution found,
not the choice of a wrong one, such as a harness render at 0.02 whose `t` is 73 degrees off
with its rotation 1.6 degrees off. Capped (90) are pairs whose translation the matches do not
determine beyond their noise: 2 of the 14 harness renders at 0.02 and at 0.05, one
`tiny-baseline` pair at 0.02."""


def report(rows: list[dict], machine: str) -> str:
    """The markdown page: what is measured (this module's description), the machine, the table."""
    lines = __doc__.split("\n\n")
    description = "\n\n".join(lines[1:-1])
    return (
        "# t_sigma_deg against the actual error of t\n\n"
        f"Made by `python benchmarks/translation_sigma.py --report docs/translation_sigma.md`"
        f" {machine}.\n\n{description}\n\n{table(rows)}\n\n{FINDINGS}\n"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=14, help="pairs per rendered set (14)")
    parser.add_argument("--report", type=Path, help="write the markdown page here")
    args = parser.parse_args(argv)
    if args.pairs < 1:
        parser.error("--pairs must be at least 1")
    start = time.perf_counter()
    rows = run(args.pairs)
    machine = (
        f"in {time.perf_counter() - start:.0f} s on 2 cores ({platform.machine()}, "
        f"Python {platform.python_version()}, ppo_cv {ppo_cv.__version__})"
    )
    print(table(rows))
    print(f"\n{machine}")
    if args.report is not None:
        args.report.write_text(report(rows, machine))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
