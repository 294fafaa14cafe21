"""Shared fixtures: the real-pair data set beside the repository, when it is there.

The test data folder is ``$PPO_CV_SHARED``, by default ``../shared`` beside the clone; every
test reaches it through :func:`shared_path` or the ``freiburg`` fixture and skips without it.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# The tests exercise the installed package, as CI installs it, also under ``python -m pytest``,
# which puts the checkout first on sys.path (tests/test_source_tree.py covers the checkout).
sys.path[:] = [entry for entry in sys.path if Path(entry or os.curdir).resolve() != ROOT]


def shared_path(*parts: str) -> Path:
    """A path inside the test data folder: ``$PPO_CV_SHARED``, default ``../shared``."""
    return Path(os.environ.get("PPO_CV_SHARED") or ROOT.parent / "shared").joinpath(*parts)


@pytest.fixture(scope="session")
def freiburg() -> Path:
    """The freiburg real pairs (images/ and pairs_with_gt.txt); skips when absent."""
    folder = shared_path("data", "freiburg")
    if not (folder / "pairs_with_gt.txt").is_file():
        pytest.skip(f"real-pair data not found at {folder} (set PPO_CV_SHARED)")
    return folder


@pytest.fixture(scope="session")
def freiburg_photos() -> Path:
    """The freiburg frames, as ``data_gen`` warps them by default; skips when absent.

    Tests whose figures hold for pairs warped from these frames pass them as ``source``: without
    them ``data_gen`` falls back to the two frames in ``ppo_cv/data``, other pairs entirely.
    """
    folder = shared_path("data", "freiburg", "images")
    if not folder.is_dir():
        pytest.skip(f"freiburg frames to warp not found at {folder} (set PPO_CV_SHARED)")
    return folder


@pytest.fixture
def K():
    """A pinhole camera with unequal focal lengths."""
    return np.array([[800.0, 0.0, 320.0], [0.0, 780.0, 240.0], [0.0, 0.0, 1.0]])


@pytest.fixture(scope="session")
def pano_dev() -> Path:
    """The real tripod panoramas (images/ and pairs_with_gt.txt); skips when absent."""
    folder = shared_path("data", "pano_dev")
    if not (folder / "pairs_with_gt.txt").is_file():
        pytest.skip(f"real panoramas not found at {folder} (set PPO_CV_SHARED)")
    return folder
