"""The examples in the docstrings run and print what they claim: every module of the package
holding one (``>>>``) is found and run, so that a new example cannot go unchecked."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"ppo_cv": "ppo_cv", "cli": "ppo_cv.cli", "data_gen": "ppo_cv.data_gen"}
MODULES = sorted(
    f"{package}.{path.stem}"
    for folder, package in PACKAGES.items()
    for path in (ROOT / folder).glob("*.py")
    if ">>> " in path.read_text(encoding="utf-8")
)


def test_the_modules_with_examples_are_found():
    assert {"ppo_cv.ppo", "ppo_cv.pose", "ppo_cv.opencv_compat", "ppo_cv.sfm"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
