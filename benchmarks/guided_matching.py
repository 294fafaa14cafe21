"""Guided matching in place of a weak pair's second detection, measured on the freiburg pairs.

Run ``python benchmarks/guided_matching.py [--freiburg DIR] [--variants 3:0.9 1:0.8 3:0.8]
[--json FILE]`` from the repository root. About 8 minutes on 2 cores.

A pair is weak when its first consensus has fewer than ``PairOptions.redetect_below`` inliers;
``estimate_pair`` then detects SIFT again at ``consensus.REDETECT_THRESHOLD_SCALE`` (about
2 x 90 ms of CPU on a freiburg pair). The variant measured here matches the first features
again, guided by the weak consensus's essential matrix ``E``: each keypoint of image 1 may
match only the keypoints of image 2 within ``BAND`` RANSAC thresholds (Sampson distance) of its
epipolar line, mutual nearest neighbours among those, with the ratio test ``RATIO`` among them
(a keypoint with one candidate is tested against its second nearest over the whole image). The
guided matches are refitted as the pipeline fits matches (ordered sampling); where that holds
at least ``redetect_below`` inliers and its ``E`` is confidently significant over the unguided
matches (``log10 NFA`` at most ``significance.CONFIDENT_LOG10_NFA``), the pair keeps it and is
not detected again; otherwise it goes on as without the variant. A first consensus that
ordered sampling could not settle has no ``E`` to guide by and is detected again as before.

The default pipeline runs once on every pair; each variant then runs again on the pairs whose
first consensus was weak and would be detected again (the others take the same path either
way). Prints, per variant: the pairs that skip the detection, AUC@5/10/20 of the larger of the
rotation and translation-direction errors over all pairs, the pairs refused, the poses changed
(and how many got worse, by how much), the CPU time summed over the pairs and its median per
pair; then the changed pairs one by one.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import anchors  # noqa: E402
import compare  # noqa: E402

from ppo_cv import consensus, pipeline  # noqa: E402
from ppo_cv.features import Features, unique_pixel_pairs  # noqa: E402
from ppo_cv.significance import CONFIDENT_LOG10_NFA, epipolar_significance  # noqa: E402

CHANGED = 1e-9
"""A pose whose rotation matrix or unit translation moved by more than this in any entry
counts as changed."""


@dataclass(frozen=True)
class Variant:
    """The epipolar band, in RANSAC thresholds, and the ratio test of the guided matching."""

    band: float
    ratio: float

    @property
    def label(self) -> str:
        return f"band {self.band:g} x threshold, ratio {self.ratio:g}"


def epipolar_band(E: np.ndarray, points1: np.ndarray, points2: np.ndarray, band: float):
    """(N1, N2) bool: the pairs of normalized points within Sampson distance ``band`` of ``E``."""
    Ex1, Etx2 = points1 @ E.T, points2 @ E
    residual = Ex1 @ points2.T
    denominator = (Ex1[:, 0] ** 2 + Ex1[:, 1] ** 2)[:, None] + (Etx2[:, 0] ** 2 + Etx2[:, 1] ** 2)
    return residual * residual < band * band * denominator


def guided_matches(f1: Features, f2: Features, allowed: np.ndarray, ratio: float):
    """Mutual nearest neighbours among the ``allowed`` pairs, ratio-tested among them; one
    match per pixel pair. Returns the (M, 2) index pairs and their distance ratios."""
    d1, d2 = f1.descriptors, f2.descriptors
    squared = np.einsum("ij,ij->i", d1, d1)[:, None] + np.einsum("ij,ij->i", d2, d2)[None, :]
    squared -= 2 * (d1 @ d2.T)
    np.maximum(squared, 0, out=squared)
    rows = np.arange(len(d1))
    unguided_second = np.partition(squared, 1, axis=1)[:, 1]
    squared[~allowed] = np.inf
    first = np.argmin(squared, axis=1)
    nearest = squared[rows, first]
    column_best = squared.min(axis=0)
    squared[rows, first] = np.inf
    second = np.where(allowed.sum(axis=1) > 1, squared.min(axis=1), unguided_second)
    keep = np.isfinite(nearest) & (nearest < ratio**2 * second) & (nearest == column_best[first])
    kept = np.flatnonzero(keep)
    _, first_row = np.unique(first[kept], return_index=True)
    kept = kept[np.sort(first_row)]
    matches = np.stack([kept, first[kept]], axis=1).astype(np.int64)
    ratios = np.sqrt(nearest[kept] / np.maximum(second[kept], 1e-300))
    unique = unique_pixel_pairs(
        np.column_stack([np.arange(len(kept)), np.arange(len(kept))]),
        f1.keypoints[kept], f2.keypoints[first[kept]], nearest[kept],
    )[:, 0]  # fmt: skip
    return matches[unique], ratios[unique]


class GuidedConsensus:
    """``consensus._consensus`` that, for a weak first consensus of features a second
    detection would follow, tries the guided matching of ``variant`` first (module
    docstring); ``record`` says what it found for the last pair."""

    def __init__(self, original, variant: Variant | None) -> None:
        self.original, self.variant, self.record = original, variant, {}

    def __call__(self, f1, f2, scale, K1, K2, dist1, dist2, focal, shape2, options, lap, *settle):
        camera = (K1, K2, dist1, dist2, focal, shape2, options, lap)
        found = self.original(f1, f2, scale, *camera, *settle)
        low = consensus.REDETECT_THRESHOLD_SCALE
        if (
            found is None
            or settle != (False,)
            or found.fit.num_inliers >= options.redetect_below
            or f1.kind != "sift"
            or all(consensus._thins_to(f, low) for f in (f1, f2))
        ):
            return found
        self.record.update(first_inliers=found.fit.num_inliers, first_matches=len(found.matches))
        if self.variant is None:
            return found
        guided = self._guided(found, K1, K2, dist1, dist2, focal, shape2, options, lap)
        return found if guided is None else guided

    def _guided(self, found, K1, K2, dist1, dist2, focal, shape2, options, lap):
        f1, f2 = found.features1, found.features2
        points1 = consensus._normalize(f1.keypoints, K1, dist1)
        points2 = consensus._normalize(f2.keypoints, K2, dist2)
        band = self.variant.band * options.ransac_threshold / focal
        allowed = epipolar_band(found.fit.E, points1, points2, band)
        matches, ratios = guided_matches(f1, f2, allowed, self.variant.ratio)
        lap("matching")
        self.record.update(guided_matches=len(matches))
        if len(matches) < options.redetect_below:
            return None
        x1, x2 = points1[matches[:, 0]], points2[matches[:, 1]]
        try:
            fit = consensus._robust_essential(x1, x2, focal, ratios, K2, shape2, options)
        except ValueError:
            return None
        finally:
            lap("ransac")
        size2 = (int(shape2[1]), int(shape2[0]))
        significance = epipolar_significance(fit.E, found.x1, found.x2, K2, size2)
        self.record.update(guided_inliers=fit.num_inliers, log10_nfa=significance.log10_nfa)
        if fit.num_inliers < options.redetect_below or not (
            significance.log10_nfa <= min(options.max_log10_nfa, CONFIDENT_LOG10_NFA)
        ):
            return None
        self.record.update(skipped_detection=True)
        return replace(found, matches=matches, x1=x1, x2=x2, fit=fit, significance=significance)


def run_pair(pair: dict, images: list, hook: GuidedConsensus) -> dict:
    """``estimate_pair`` with default options on one pair through ``hook``: pose error, CPU."""
    hook.record = {}
    start = time.process_time()
    try:
        result = pipeline.estimate_pair(*images, pair["K1"], pair["K2"])
        R, t = np.asarray(result.R, float), np.asarray(result.t, float).ravel()
    except ValueError:
        R = t = None
    cpu = time.process_time() - start
    error = anchors.pose_error_deg(R, t, pair["R"], pair["t"])[2]
    return {"error": error, "refused": R is None, "R": R, "t": t, "cpu": cpu, **hook.record}


def changed(a: dict, b: dict) -> bool:
    if a["refused"] or b["refused"]:
        return a["refused"] != b["refused"]
    same_t = np.allclose(a["t"], b["t"], rtol=0, atol=CHANGED)
    return not (np.allclose(a["R"], b["R"], rtol=0, atol=CHANGED) and same_t)


def summary_row(label: str, rows: list[dict], base: list[dict]) -> str:
    errors = [r["error"] for r in rows]
    moved = [(r, b) for r, b in zip(rows, base, strict=True) if changed(r, b)]
    worse = sorted(r["error"] - b["error"] for r, b in moved if r["error"] > b["error"])
    cpu = [r["cpu"] for r in rows]
    aucs = " / ".join(f"{100 * anchors.auc(errors, th):.1f}" for th in (5, 10, 20))
    worse_text = str(len(worse))
    if worse:
        worse_text += f" (median {np.median(worse):.2f}, max {worse[-1]:.2f})"
    skipped = sum(bool(r.get("skipped_detection")) for r in rows)
    return (
        f"| {label} | {skipped} | {aucs} | {sum(r['refused'] for r in rows)} | {len(moved)} | "
        f"{worse_text} | {sum(cpu):.1f} | {np.median(cpu):.3f} |"
    )


def _plain(row: dict) -> dict:
    return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in row.items()}


def _variant(parser: argparse.ArgumentParser, text: str) -> Variant:
    """A ``BAND:RATIO`` of ``--variants``; the parser's error (exit 2) for any other text."""
    try:
        band, ratio = (float(value) for value in text.split(":"))
    except ValueError:
        parser.error(f"--variants takes BAND:RATIO pairs such as 3:0.9, got {text!r}")
    return Variant(band, ratio)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--freiburg", type=Path, default=compare.FREIBURG)
    parser.add_argument("--variants", nargs="+", default=["3:0.9", "1:0.8", "3:0.8"],
                        help="BAND:RATIO of each variant")  # fmt: skip
    parser.add_argument("--limit", type=int, default=None, help="first N pairs only")
    parser.add_argument("--json", type=Path, help="also write the per-pair rows here")
    args = parser.parse_args(argv)
    variants = [_variant(parser, text) for text in args.variants]
    if args.limit is not None and args.limit < 1:
        parser.error(f"--limit must be at least 1, got {args.limit}")
    if not (args.freiburg / "pairs_with_gt.txt").is_file():
        parser.error(f"no freiburg pairs in {args.freiburg} (pairs_with_gt.txt and images/): "
                     "give --freiburg DIR or set PPO_CV_SHARED")  # fmt: skip
    pairs = anchors.read_pairs_file(args.freiburg / "pairs_with_gt.txt")[: args.limit]
    load = lambda name: cv2.imread(str(args.freiburg / "images" / name))  # noqa: E731
    original = consensus._consensus
    hook = GuidedConsensus(original, None)
    consensus._consensus = hook
    try:
        base = [run_pair(p, [load(p["name1"]), load(p["name2"])], hook) for p in pairs]
        weak = [i for i, row in enumerate(base) if "first_inliers" in row]
        results = {}
        for variant in variants:
            hook.variant = variant
            rows = list(base)
            for i in weak:
                pair = pairs[i]
                rows[i] = run_pair(pair, [load(pair["name1"]), load(pair["name2"])], hook)
            results[variant.label] = rows
    finally:
        consensus._consensus = original
    print(f"{len(pairs)} freiburg pairs, {len(weak)} weak ones detected again;", compare._machine())
    print("| second detection of a weak pair | pairs that skip it | AUC@5/10/20 | refused | "
          "poses changed | worse (deg) | CPU summed s | median CPU per pair s |")  # fmt: skip
    print("|---|---:|---|---:|---:|---|---:|---:|")
    print(summary_row("detected again (default)", base, base))
    for label, rows in results.items():
        print(summary_row(f"guided matching, {label}", rows, base))
    for label, rows in results.items():
        print(f"\n{label}: pair, first inliers / matches, guided inliers / matches, error deg")
        for i in weak:
            r = rows[i]
            if changed(r, base[i]):
                print(f"  {i}: {r['first_inliers']} / {r['first_matches']}, "
                      f"{r.get('guided_inliers')} / {r.get('guided_matches')}, "
                      f"{base[i]['error']:.2f} -> {r['error']:.2f}")  # fmt: skip
    if args.json:
        every = {"default": base, **results}
        args.json.write_text(json.dumps({k: [_plain(r) for r in v] for k, v in every.items()}))


if __name__ == "__main__":
    main()
