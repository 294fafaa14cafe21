"""Shared fixtures: the real-pair data set beside the repository, when it is there."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PPO_CV_SHARED", ROOT.parent / "shared"))
FREIBURG = SHARED / "data" / "freiburg"


@pytest.fixture(scope="session")
def freiburg() -> Path:
    """The freiburg real pairs (images/ and pairs_with_gt.txt); skips when absent."""
    if not (FREIBURG / "pairs_with_gt.txt").is_file():
        pytest.skip(f"real-pair data not found at {FREIBURG}")
    return FREIBURG
