"""ppo-cv: relative pose of two calibrated views by the pose-only (PPO) inequalities.

* :func:`recoverPose` is a drop-in for ``cv2.recoverPose``; :func:`install` swaps it in.
* :func:`recover_pose` returns a :class:`PoseResult` with the pure-rotation decision and
  analytic 3D points.
* :func:`estimate_pair` goes from two photos to a :class:`PairResult`.
* :mod:`ppo_cv.ppo` holds the paper's mathematics; :mod:`ppo_cv.colmap` and :mod:`ppo_cv.sfm`
  connect to pycolmap and load on first use.
"""

from __future__ import annotations

import importlib

from .calib import Camera, camera_from_exif, load_calibration, parse_intrinsics
from .export import write_outputs
from .opencv_compat import install, installed, is_installed, recoverPose, uninstall
from .pipeline import PairOptions, PairResult, estimate_pair
from .pose import PoseResult, recover_pose
from .ppo import DEFAULT_PRI_THRESHOLD

__all__ = [
    "DEFAULT_PRI_THRESHOLD",
    "Camera",
    "PairOptions",
    "PairResult",
    "PoseResult",
    "camera_from_exif",
    "estimate_pair",
    "install",
    "installed",
    "is_installed",
    "load_calibration",
    "parse_intrinsics",
    "recoverPose",
    "recover_pose",
    "uninstall",
    "write_outputs",
]

__version__ = "0.1.0"

_LAZY_SUBMODULES = ("colmap", "sfm", "data_gen")


def __getattr__(name: str):
    if name in _LAZY_SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
