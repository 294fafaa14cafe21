"""Every field of a :class:`~ppo_cv.pipeline.PairResult`, flat, for pairs that need no data set.

``python tests/result_layout.py OUT.npz`` records the demo pair and three small renders;
``tests/test_result_layout.py`` compares the fields of a fresh run against such a record,
each read through its current path (:data:`ppo_cv.pipeline.RENAMED_FIELDS`). The record
holds the names of the flat layout of 0.1.0, so one file serves before and after a
change of layout.
"""

from __future__ import annotations

import json
import sys
import warnings
from importlib import resources
from operator import attrgetter
from pathlib import Path

import numpy as np

FLAT_FIELDS = (
    "R", "t", "pure_rotation", "pri", "keypoints1", "keypoints2", "matches", "inliers",
    "points3d", "point_matches", "colours", "K1", "K2", "image_size1", "image_size2",
    "pri_threshold", "model", "t_sigma_deg", "rotation_sigma_deg", "rotation_tracks",
    "rotation_residual_px", "general_residual_px", "gric_difference", "lens_excess",
    "noise_sigma_px", "rotation_noise_px", "coherent_share", "track_parallax",
    "track_parallax_sigma", "rotation_gap_deg", "focal_scale", "focal_ratio",
    "principal_offset_px", "principal_bound", "threshold_scale", "dist1", "dist2",
    "log10_nfa", "plane_residual_px", "gric_plane_difference", "plane_epipolar_ratio",
    "plane_normal", "plane_distance", "plane_ambiguous", "plane_k1", "radial_k1",
    "rotation_source", "rotation_bias_deg", "wanted_focal_scale", "ransac_threshold_px",
    "features_source",
)  # fmt: skip
"""Every field of the flat ``PairResult`` but ``timings`` (seconds differ run to run), and
those added since (:data:`ADDED_FIELDS`)."""

ADDED_FIELDS = {
    "rotation_source": "rotation_source",
    "rotation_bias_deg": "uncertainty.rotation_bias_deg",
    "wanted_focal_scale": "lens.wanted_focal_scale",
    "ransac_threshold_px": "evidence.significance.ransac_threshold_px",
    "features_source": "evidence.significance.features",
}
"""Fields added after 0.1.0 -> their path: the record names them as the flat layout would."""

RENDERS = {
    "general": ("general", 0, 0),
    "planar": ("planar", 0, 0),
    "rotation": ("pure-rotation", 0, 0),
}
"""Case name -> ``make_pair(motion, seed, index)`` at :data:`RENDER_SIZE`."""
RENDER_SIZE = (320, 240)


def demo_inputs() -> tuple[str, str, np.ndarray]:
    """The bundled demo pair's image paths and camera matrix."""
    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    fx, fy, cx, cy = info["intrinsics"]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return str(data / info["image1"]), str(data / info["image2"]), K


def run_case(name: str):
    """The :class:`PairResult` of case ``name`` ("demo" or a key of :data:`RENDERS`)."""
    from ppo_cv.data_gen import make_pair
    from ppo_cv.pipeline import estimate_pair

    if name == "demo":
        image1, image2, K = demo_inputs()
        return estimate_pair(image1, image2, K)
    motion, seed, index = RENDERS[name]
    pair = make_pair(motion, seed=seed, index=index, size=RENDER_SIZE)
    return estimate_pair(pair.image1, pair.image2, pair.K1, pair.K2)


NO_PLANE = {"normal": None, "distance": float("nan"), "ambiguous": False, "k1": float("nan")}
"""The flat ``plane_*`` fields of a pair whose model is not a plane."""


def read_renamed(result, name: str):
    """Flat field ``name`` of ``result`` read through its path in
    :data:`ppo_cv.result.RENAMED_FIELDS`, without the deprecated name."""
    from ppo_cv.result import RENAMED_FIELDS

    path = RENAMED_FIELDS.get(name) or ADDED_FIELDS.get(name, name)
    head, _, rest = path.partition(".")
    if head == "plane" and result.plane is None:
        return NO_PLANE[rest]
    return attrgetter(path)(result)


def flat_fields(result, read=getattr) -> dict[str, object]:
    """``{flat name: value}`` of :data:`FLAT_FIELDS`, each read by ``read(result, name)``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return {name: read(result, name) for name in FLAT_FIELDS}


def to_arrays(case: str, fields: dict[str, object]) -> dict[str, np.ndarray]:
    """npz entries ``case/name``; a None value is listed in ``case/:none`` instead."""
    arrays = {f"{case}/{k}": np.asarray(v) for k, v in fields.items() if v is not None}
    none = [k for k, v in fields.items() if v is None]
    arrays[f"{case}/:none"] = np.array(none, dtype=str)
    return arrays


def main(out: str) -> None:
    arrays: dict[str, np.ndarray] = {}
    for case in ("demo", *RENDERS):
        arrays.update(to_arrays(case, flat_fields(run_case(case), read_renamed)))
    np.savez_compressed(Path(out), **arrays)


if __name__ == "__main__":
    main(sys.argv[1])
