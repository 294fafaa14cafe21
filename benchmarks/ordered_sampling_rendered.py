"""Pose error of ``estimate_pair`` on rendered pairs with and without ordered sampling.

Run ``python benchmarks/ordered_sampling_rendered.py [--pairs 4] [--real-photo 2]``: for each
motion of ``ppo_cv.data_gen.MOTIONS``, pairs ``make_pair(motion, seed=0, index=i)`` (and a
few with ``imperfections=REAL_PHOTO``) go through ``estimate_pair`` with
``PairOptions(ordered_sampling=False)`` (one fit over all matches, the old default) and with
the default (ordered sampling). Prints the rotation and translation-direction errors
(degrees; the translation error is left out where the true t is zero), the model chosen and
the RANSAC time of each.
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from ppo_cv.data_gen import MOTIONS, REAL_PHOTO, make_pair
from ppo_cv.metrics import direction_error_deg, rotation_error_deg
from ppo_cv.pipeline import PairOptions, estimate_pair


def errors(result, pair) -> tuple[float, float | None]:
    """Rotation error and sign-free translation-direction error (None for a zero t), degrees."""
    rotation_error = rotation_error_deg(result.R, pair.R)
    if np.linalg.norm(pair.t) < 1e-12:
        return rotation_error, None
    return rotation_error, direction_error_deg(result.t, pair.t, signed=False)


def run(pair, ordered: bool) -> tuple[str, float, float]:
    options = PairOptions(ordered_sampling=ordered)
    images = (pair.image1[:, :, ::-1], pair.image2[:, :, ::-1])
    try:
        result = estimate_pair(*images, pair.K1_given, pair.K2_given, options=options)
    except ValueError as exc:
        return f"error: {str(exc)[:40]}", float("nan"), float("nan")
    r_err, t_err = errors(result, pair)
    t_text = "-" if t_err is None else f"{t_err:.2f}"
    return (
        f"{r_err:.2f} / {t_text} ({result.model})",
        result.timings["ransac"],
        max(r_err, t_err or 0.0),
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=4, help="pairs per motion")
    parser.add_argument("--real-photo", type=int, default=2, help="REAL_PHOTO pairs per motion")
    args = parser.parse_args(argv)
    cases = [(m, i, False) for m in MOTIONS for i in range(args.pairs)]
    cases += [(m, i, True) for m in MOTIONS for i in range(args.real_photo)]
    print("| motion | index | REAL_PHOTO | old: R / t error (model) | new: R / t error (model) "
          "| RANSAC s old / new |")  # fmt: skip
    print("|---|---:|---|---|---|---|")
    worst = {False: [], True: []}
    times = {False: [], True: []}
    for motion, index, real in cases:
        pair = make_pair(motion, seed=0, index=index, imperfections=REAL_PHOTO if real else None)
        cells = []
        for ordered in (False, True):
            text, seconds, pose_err = run(pair, ordered)
            cells.append(text)
            times[ordered].append(seconds)
            worst[ordered].append(pose_err)
        print(
            f"| {motion} | {index} | {'yes' if real else 'no'} | {cells[0]} | {cells[1]} "
            f"| {times[False][-1]:.3f} / {times[True][-1]:.3f} |"
        )
    for ordered, label in ((False, "old"), (True, "new")):
        finite = [e for e in worst[ordered] if e == e]
        print(
            f"{label}: median pose error {statistics.median(finite):.2f} deg, max "
            f"{max(finite):.2f} deg, {len(worst[ordered]) - len(finite)} failed, RANSAC "
            f"{np.nansum(times[ordered]):.2f} s in all"
        )


if __name__ == "__main__":
    main()
