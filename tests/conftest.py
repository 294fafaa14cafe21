"""Shared fixtures: the real-pair data set beside the repository, when it is there."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# The tests exercise the installed package. ``python -m pytest`` puts the checkout first on
# sys.path, where ppo_cv/ lacks the cli and data_gen subpackages that installation maps into it.
sys.path[:] = [entry for entry in sys.path if Path(entry or os.curdir).resolve() != ROOT]
SHARED = Path(os.environ.get("PPO_CV_SHARED", ROOT.parent / "shared"))
FREIBURG = SHARED / "data" / "freiburg"


@pytest.fixture(scope="session")
def freiburg() -> Path:
    """The freiburg real pairs (images/ and pairs_with_gt.txt); skips when absent."""
    if not (FREIBURG / "pairs_with_gt.txt").is_file():
        pytest.skip(f"real-pair data not found at {FREIBURG}")
    return FREIBURG


@pytest.fixture
def K():
    """A pinhole camera with unequal focal lengths."""
    return np.array([[800.0, 0.0, 320.0], [0.0, 780.0, 240.0], [0.0, 0.0, 1.0]])
