"""Is ``rotation_sigma_deg`` calibrated? RMS rotation error against the mean sigma, per model.

``PairResult.uncertainty.rotation_sigma_deg`` is the deviation of the returned rotation: of the
rotation-only fit for a pure rotation or when the rule of :mod:`ppo_cv.rotation_choice` takes
it (root-mean-square angle, its bias's deviation included), otherwise the root-mean-square
angle of the covariance of the essential matrix's or the plane's final refinement
(:func:`ppo_cv.refine.pose_sigmas_deg`, :func:`ppo_cv.plane.rms_rotation_angle_deg`), for the
essential matrix over the matches the others can check and with the spread of the other
minima of its bas-relief valley that are not significantly worse (:mod:`ppo_cv.valley`). A
calibrated deviation has the root-mean-square error over many pairs close to the mean
deviation: this script prints their ratio per model (and per source of the rotation), which
should lie within 1/1.5 and 1.5.

Pairs: the renders of ``tests/imperfect.py`` (480x360, a 25-35 degree field, radial distortion
nobody models, the focal length given up to 3 % off, noise and JPEG): pure rotations and
baselines of 0.005, 0.02 and 0.05 of the median depth, seeds ``0 .. --seeds - 1``. No real
data is needed.

Run ``python benchmarks/rotation_sigma.py [--seeds 8] [--pairs]`` (a few minutes on 2 shared
cores); it prints the machine and markdown tables per model, rotation source and baseline,
with ``--pairs`` every pair's error against its sigma, its share of its model's squared error
(the pairs that carry the model's ratio), the lens and the focal length's error. The tables,
what the deviations count and what is left: ``docs/rotation_sigma.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from ppo_cv import estimate_pair
from ppo_cv.metrics import rotation_error_deg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from imperfect import imperfect_render  # noqa: E402

BASELINES = (0.0, 0.005, 0.02, 0.05)

__all__ = [
    "BASELINES", "calibration_rows", "pair_lines", "pairwise_rms", "squared_error_shares", "run",
    "main",
]


def run(seeds: int) -> list[dict]:
    """One row per rendered pair: model, rotation source, error and sigma (degrees)."""
    rows = []
    for baseline in BASELINES:
        for seed in range(seeds):
            pair = imperfect_render(seed, baseline)
            try:
                result = estimate_pair(pair.image1, pair.image2, pair.K_given)
            except ValueError:
                continue
            rows.append(
                {
                    "baseline": baseline,
                    "seed": seed,
                    "model": result.model,
                    "source": result.rotation_source,
                    "error": rotation_error_deg(result.R, pair.R),
                    "sigma": float(result.uncertainty.rotation_sigma_deg),
                    "k1": pair.k1,
                    "focal_error": pair.focal_error,
                }
            )
    return rows


def calibration_rows(rows: list[dict], key: str) -> list[tuple[str, int, float, float, float]]:
    """Per value of ``key``: (value, pairs, RMS error, mean sigma, their ratio), pairs with a
    finite sigma only."""
    table = []
    for value in sorted({row[key] for row in rows}):
        chosen = [r for r in rows if r[key] == value and np.isfinite(r["sigma"])]
        if not chosen:
            continue
        rms = float(np.sqrt(np.mean([r["error"] ** 2 for r in chosen])))
        mean = float(np.mean([r["sigma"] for r in chosen]))
        table.append((value, len(chosen), rms, mean, rms / mean))
    return table


def pairwise_rms(rows: list[dict], key: str) -> dict[str, float]:
    """Per value of ``key``: the root mean square of each pair's error over its own sigma
    (finite sigmas only), near 1 when every pair's deviation fits its error, whatever their
    spread; RMS error over mean sigma exceeds it when the sigmas differ from pair to pair."""
    finite = [r for r in rows if np.isfinite(r["sigma"])]
    ratios = {}
    for r in finite:
        ratios.setdefault(r[key], []).append(r["error"] / r["sigma"])
    return {value: float(np.sqrt(np.mean(np.square(z)))) for value, z in ratios.items()}


def squared_error_shares(rows: list[dict], key: str = "model") -> np.ndarray:
    """Each pair's share of the squared error summed over the pairs of its ``key`` value: the
    pairs that carry that value's RMS error, and so its ratio to the mean sigma."""
    squared = np.array([r["error"] ** 2 for r in rows])
    totals = {}
    for r, e2 in zip(rows, squared, strict=True):
        totals[r[key]] = totals.get(r[key], 0.0) + e2
    return np.array([e2 / max(totals[r[key]], 1e-300) for r, e2 in zip(rows, squared, strict=True)])


def pair_lines(rows: list[dict]) -> list[str]:
    """A markdown table of every pair: its render, model, source, error against sigma and its
    share of its model's squared error."""
    lines = [
        "| baseline | seed | model | source | error (deg) | sigma (deg) | error / sigma "
        "| share of model's error^2 | k1 | focal error |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r, share in zip(rows, squared_error_shares(rows), strict=True):
        lines.append(
            f"| {r['baseline']} | {r['seed']} | {r['model']} | {r['source']} | {r['error']:.3f} "
            f"| {r['sigma']:.3f} | {r['error'] / r['sigma']:.1f} | {100 * share:.0f} % "
            f"| {r['k1']:+.3f} | {r['focal_error']:+.3f} |"
        )
    return lines + [""]


def report(rows: list[dict], seconds: float, pairs: bool = False) -> str:
    lines = [
        f"Machine: {platform.platform()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; {len(rows)} pairs in {seconds:.0f} s.",
        "",
    ]
    if pairs:
        lines += pair_lines(rows)
    for key, title in (("model", "model"), ("source", "rotation source"), ("baseline", "baseline")):
        pairwise = pairwise_rms(rows, key)
        lines += [
            f"| {title} | pairs | RMS error (deg) | mean sigma (deg) | RMS / sigma "
            "| RMS of error / sigma |",
            "|---|---|---|---|---|---|",
        ]
        lines += [
            f"| {value} | {n} | {rms:.3f} | {mean:.3f} | {ratio:.2f} | {pairwise[value]:.2f} |"
            for value, n, rms, mean, ratio in calibration_rows(rows, key)
        ]
        lines.append("")
    infinite = sum(not np.isfinite(r["sigma"]) for r in rows)
    lines.append(f"Pairs without a finite sigma (left out): {infinite}.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=8, help="renders per baseline")
    parser.add_argument("--pairs", action="store_true", help="also print every pair's row")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = run(args.seeds)
    print(report(rows, time.perf_counter() - start, args.pairs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
