"""ppo-cv: relative pose of two calibrated views by the pose-only (PPO) inequalities.

* :func:`recoverPose` is a drop-in for ``cv2.recoverPose``; :func:`install` swaps it in.
* :func:`recover_pose` returns a :class:`PoseResult` with the pure-rotation decision and
  analytic 3D points.
* :func:`estimate_pair` goes from two photos to a :class:`PairResult`.
* :mod:`ppo_cv.ppo` holds the paper's mathematics; :mod:`ppo_cv.colmap` and :mod:`ppo_cv.sfm`
  connect to pycolmap and load on first use.

``R`` and ``t`` map camera-1 coordinates to camera-2 coordinates, ``X2 = R X1 + t``, with
``|t| = 1``; for a pure rotation (``result.pure_rotation``) ``t`` means nothing.

>>> import ppo_cv
>>> K = [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]
>>> result = ppo_cv.estimate_pair("img1.png", "img2.png", K)  # doctest: +SKIP
>>> result.R, result.t, result.pure_rotation, result.model  # doctest: +SKIP

The same from a shell: ``ppo-cv pair img1.png img2.png --K 535.4,539.2,320.1,247.6``
(``ppo-cv --help`` lists the commands). The README and ``docs/python.md`` of the source
repository describe every argument, result field and decision.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .calib import Camera, camera_from_exif, load_calibration, parse_intrinsics
    from .export import write_outputs
    from .opencv_compat import (
        RecoverPoseError,
        RecoverPoseTypeError,
        install,
        installed,
        is_installed,
        recoverPose,
        uninstall,
    )
    from .pipeline import PairOptions, PairResult, estimate_pair
    from .pose import PoseResult, recover_pose
    from .ppo import DEFAULT_PRI_THRESHOLD

__all__ = [
    "DEFAULT_PRI_THRESHOLD",
    "Camera",
    "PairOptions",
    "PairResult",
    "PoseResult",
    "RecoverPoseError",
    "RecoverPoseTypeError",
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
_EXPORTED_FROM = {
    "DEFAULT_PRI_THRESHOLD": "ppo",
    "Camera": "calib",
    "PairOptions": "pipeline",
    "PairResult": "pipeline",
    "PoseResult": "pose",
    "RecoverPoseError": "opencv_compat",
    "RecoverPoseTypeError": "opencv_compat",
    "camera_from_exif": "calib",
    "estimate_pair": "pipeline",
    "install": "opencv_compat",
    "installed": "opencv_compat",
    "is_installed": "opencv_compat",
    "load_calibration": "calib",
    "parse_intrinsics": "calib",
    "recoverPose": "opencv_compat",
    "recover_pose": "pose",
    "uninstall": "opencv_compat",
    "write_outputs": "export",
}
"""The module of each name of ``__all__``, imported on first use: the command line sets its
signal handlers before numpy, OpenCV and pycolmap load."""


def __getattr__(name: str):
    if name in _LAZY_SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    if name in _EXPORTED_FROM:
        value = getattr(importlib.import_module(f".{_EXPORTED_FROM[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}" + _opencv_hint(name))


def _opencv_hint(name: str) -> str:
    """Where code that swapped ``cv2`` for ``ppo_cv`` wholesale finds ``name``: in OpenCV."""
    if name.startswith("_") or importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return ""  # a submodule being imported (``from ppo_cv import cli``): OpenCV not loaded
    import cv2

    if not hasattr(cv2, name):
        return ""
    return f" (ppo_cv stands in for cv2.recoverPose only: use cv2.{name} as before)"


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__, *_LAZY_SUBMODULES})


class _SourceTreeFinder:
    """Meta path finder of ``ppo_cv.cli`` and ``ppo_cv.data_gen`` in a source tree.

    The two subpackages live in the top-level folders ``cli/`` and ``data_gen/`` of the source
    tree, which installation maps into the package. Imported from a source tree (no
    ``ppo_cv/cli`` beside this file, but ``../cli`` and a ``pyproject.toml``), this finder maps
    the two folders in the same way, so that ``import ppo_cv.cli.main`` and
    ``python -m ppo_cv`` work from the root of a clone.
    """

    def __init__(self, folders: dict[str, str]) -> None:
        self.folders = folders

    def find_spec(self, fullname: str, path=None, target=None):
        folder = self.folders.get(fullname)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(
            fullname, os.path.join(folder, "__init__.py"), submodule_search_locations=[folder]
        )


def _map_source_tree(package: str, here: str, names: tuple[str, ...]) -> None:
    root = os.path.dirname(here)
    if not os.path.isfile(os.path.join(root, "pyproject.toml")):
        return
    folders = {
        f"{package}.{name}": os.path.join(root, name)
        for name in names
        if not os.path.exists(os.path.join(here, name))
        and os.path.isfile(os.path.join(root, name, "__init__.py"))
    }
    if folders and not any(isinstance(f, _SourceTreeFinder) for f in sys.meta_path):
        # first: the subpackages belong to this tree, even if another one is installed
        sys.meta_path.insert(0, _SourceTreeFinder(folders))


_map_source_tree(__name__, os.path.dirname(os.path.abspath(__file__)), ("cli", "data_gen"))
