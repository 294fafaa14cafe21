"""Pure rotation with something moving in the scene: is it still flagged?

A real tripod panorama rarely holds still: a walker, a car, a branch moves between the shots.
Two views alone cannot tell an object that moved sideways from one that is nearer while the
camera translated: the essential matrix explains the moved object with a translation, the
rotation-only model cannot, and GRIC (``ppo_cv.model_selection``) may then call the pair a
general motion.

Data: the 14 ``ppo_cv.data_gen`` warped photos of ``docs/pure_rotation.md`` (seed 0,
``REAL_PHOTO``: exact pure rotations with real texture). Into both views of each a flat patch
of real texture is pasted (the centre of image 1 of warped pair ``index + 7``, so other photo
content), covering ``area`` of the image, in the overlap of the two views; in view 2 it lands
where the rotation takes it plus ``shift`` pixels to the right: an object that moved.

Run ``python benchmarks/moving_object.py`` (about 30 s on 2 cores); it prints a markdown
table: for each patch size and shift, how many pairs ppo_cv flags, the median rotation error of
the flagged pairs, and the median GRIC difference
(``PairResult.evidence.selection.gric_difference``, below 0 the rotation wins).
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import time
from pathlib import Path

import numpy as np

import ppo_cv
from ppo_cv import PairOptions, data_gen, estimate_pair

sys.path.insert(0, str(Path(__file__).resolve().parent))

from pure_rotation import _as_item, _rotation_error  # noqa: E402

CONFIGS = ((0.0, 0.0), (0.02, 4.0), (0.02, 12.0), (0.04, 4.0), (0.04, 12.0))
"""``(area, shift)``: the patch's share of the image and its sideways move in view 2 (pixels)."""


def _paste(image: np.ndarray, patch: np.ndarray, centre: np.ndarray) -> None:
    """Write ``patch`` into ``image`` centred at ``centre`` (x, y), clipped to the image."""
    (h, w), (ph, pw) = image.shape[:2], patch.shape[:2]
    x0, y0 = (np.round(centre - np.array([pw, ph]) / 2.0)).astype(int)
    xa, ya, xb, yb = max(x0, 0), max(y0, 0), min(x0 + pw, w), min(y0 + ph, h)
    if xb > xa and yb > ya:
        image[ya:yb, xa:xb] = patch[ya - y0 : yb - y0, xa - x0 : xb - x0]


def with_moving_patch(pair, texture: np.ndarray, area: float, shift: float):
    """``pair`` with ``texture``'s centre pasted in both views, moved ``shift`` px in view 2.

    The patch (``area`` of the image, 1.7 times as tall as wide, like a standing person) is
    centred in view 1 halfway between the image centre and the point view 2's centre comes
    from; in view 2 at that point's transfer ``K2 R K1^-1`` (given intrinsics) plus
    ``(shift, 0)``.
    """
    image1, image2 = pair.image1.copy(), pair.image2.copy()
    if area <= 0:
        return dataclasses.replace(pair, image1=image1, image2=image2)
    h, w = image1.shape[:2]
    pw = int(np.sqrt(area * w * h / 1.7))
    ph = int(1.7 * pw)
    th, tw = texture.shape[:2]
    patch = texture[(th - ph) // 2 : (th + ph) // 2, (tw - pw) // 2 : (tw + pw) // 2]
    H = pair.K2_given @ pair.R @ np.linalg.inv(pair.K1_given)
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    source = np.linalg.solve(H, np.r_[centre, 1.0])
    centre1 = (centre + source[:2] / source[2]) / 2.0
    target = H @ np.r_[centre1, 1.0]
    _paste(image1, patch, centre1)
    _paste(image2, patch, target[:2] / target[2] + np.array([shift, 0.0]))
    return dataclasses.replace(pair, image1=image1, image2=image2)


def run(count: int) -> list[dict]:
    """One row per configuration of :data:`CONFIGS` over the first ``count`` warped pairs."""
    pairs = [
        data_gen.make_warped_pair(seed=0, index=i, imperfections=data_gen.REAL_PHOTO)
        for i in range(count + 7)
    ]
    rows = []
    for area, shift in CONFIGS:
        flags, errors, grics = [], [], []
        for index, pair in enumerate(pairs[:count]):
            moved = with_moving_patch(pair, pairs[index + 7].image1, area, shift)
            bgr1, bgr2, K1, K2, _ = _as_item(moved)
            result = estimate_pair(bgr1, bgr2, K1, K2, options=PairOptions())
            flags.append(bool(result.pure_rotation))
            errors.append(_rotation_error(result.R, pair.R))
            grics.append(float(result.evidence.selection.gric_difference))
        flagged = np.array(flags)
        rows.append(
            {
                "area": area,
                "shift": shift,
                "pairs": count,
                "flagged": int(flagged.sum()),
                "flagged_error": float(np.median(np.array(errors)[flagged]))
                if flagged.any()
                else float("nan"),
                "gric": float(np.median(grics)),
            }
        )
    return rows


def table(rows: list[dict]) -> str:
    lines = [
        "| patch area | shift (px) | pairs | ppo_cv flagged | R err of flagged, median (deg) "
        "| median GRIC difference |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {100 * row['area']:.0f} % | {row['shift']:.0f} | {row['pairs']} "
            f"| {row['flagged']} | {row['flagged_error']:.2f} | {row['gric']:+.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=14, help="warped pairs (default 14)")
    args = parser.parse_args(argv)
    if args.pairs < 1:
        parser.error("--pairs must be at least 1")
    start = time.perf_counter()
    rows = run(args.pairs)
    print(table(rows))
    print(
        f"\n{time.perf_counter() - start:.0f} s on {platform.machine()}, "
        f"Python {platform.python_version()}, ppo_cv {ppo_cv.__version__}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
