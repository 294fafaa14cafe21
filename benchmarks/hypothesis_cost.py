"""What one hypothesis of the uniform essential-matrix fit costs, and what numpy would pay.

Run ``python benchmarks/hypothesis_cost.py [--trials 20000]``. The uniform fit of a weak pair
(``ppo_cv.robust``) runs pycolmap's RANSAC on the five-point solver for a number of hypotheses
that its stop rule fixes; this prints the CPU time per hypothesis at several numbers of matches
(random matches, so that every fit runs to the fixed count and local optimisation is rare),
from which the share of the solver (the cost at no matches) and of scoring (the cost per match)
follow, beside the CPU time per matrix of the two batched LAPACK calls a numpy five-point solver
needs at least (the null space of a 5x9 system, the eigenvalues of a 10x10 action matrix),
and the machine (CPU model, CPU count, load average).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from ppo_cv.atomic import import_pycolmap
from ppo_cv.robust import ransac_options, virtual_camera

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pairs_cache import _cpu_model, _load  # noqa: E402

MATCHES = (30, 150, 600)
FOCAL = 500.0


def pycolmap_cost(num_matches: int, trials: int, rng: np.random.Generator) -> float:
    """CPU seconds per hypothesis of ``pycolmap.estimate_essential_matrix`` on random matches."""
    pycolmap = import_pycolmap()
    points1 = FOCAL * rng.uniform(-0.5, 0.5, (num_matches, 2))
    points2 = FOCAL * rng.uniform(-0.5, 0.5, (num_matches, 2))
    options = ransac_options(1.0, 0.95, trials, trials, 0, 1.0)
    camera = virtual_camera(FOCAL)
    start = time.process_time()
    pycolmap.estimate_essential_matrix(points1, points2, camera, camera, options)
    return (time.process_time() - start) / trials


def lapack_cost(batch: int, rng: np.random.Generator) -> dict[str, float]:
    """CPU seconds per matrix of numpy's batched SVD (5x9) and eigenvalues (10x10)."""
    systems, actions = rng.normal(size=(batch, 5, 9)), rng.normal(size=(batch, 10, 10))
    costs = {}
    for name, call in (
        ("SVD of 5x9 (null space of the sample)", lambda: np.linalg.svd(systems)),
        ("eigenvalues of 10x10 (action matrix)", lambda: np.linalg.eigvals(actions)),
    ):
        start = time.process_time()
        call()
        costs[name] = (time.process_time() - start) / batch
    return costs


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=20_000, help="hypotheses per fit")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    load_before = _load()
    per_match = {n: pycolmap_cost(n, args.trials, rng) for n in MATCHES}
    lapack = lapack_cost(args.trials, rng)
    slope = (per_match[MATCHES[-1]] - per_match[MATCHES[0]]) / (MATCHES[-1] - MATCHES[0])
    solver = per_match[MATCHES[0]] - slope * MATCHES[0]
    print(
        f"{_cpu_model()}, {os.cpu_count()} CPUs, load average (1/5/15 min) {load_before} before "
        f"and {_load()} after; {args.trials} hypotheses per fit, CPU time"
    )
    print()
    print("| pycolmap, random matches | microseconds per hypothesis |")
    print("|---|---:|")
    for n, cost in per_match.items():
        print(f"| {n} matches | {1e6 * cost:.1f} |")
    print(f"| of which solver and sampling (no matches) | {1e6 * solver:.1f} |")
    print(f"| of which scoring, per match | {1e6 * slope:.3f} |")
    print()
    print("| numpy, batched LAPACK | microseconds per matrix |")
    print("|---|---:|")
    for name, cost in lapack.items():
        print(f"| {name} | {1e6 * cost:.1f} |")


if __name__ == "__main__":
    main()
