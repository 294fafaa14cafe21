"""Installing the project adds one top-level package, ``ppo_cv``, and the ``ppo-cv`` command."""

from __future__ import annotations

from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def _config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_installed_package_lives_under_ppo_cv():
    setuptools = _config()["tool"]["setuptools"]
    assert all(name.split(".")[0] == "ppo_cv" for name in setuptools["packages"])
    mapping = setuptools["package-dir"]
    assert mapping["ppo_cv.cli"] == "cli" and mapping["ppo_cv.data_gen"] == "data_gen"


def test_every_source_package_is_listed():
    listed = set(_config()["tool"]["setuptools"]["packages"])
    mapping = {v: k for k, v in _config()["tool"]["setuptools"]["package-dir"].items()}
    for init in ROOT.glob("*/**/__init__.py"):
        folder = init.parent.relative_to(ROOT).as_posix()
        if folder.split("/")[0] in {"tests", "benchmarks", "docs", "build"}:
            continue
        top, _, rest = folder.partition("/")
        package = mapping.get(top, top) + ("." + rest.replace("/", ".") if rest else "")
        assert package in listed, f"{folder} is not installed by pyproject.toml"


def test_command_line_entry_point():
    assert _config()["project"]["scripts"]["ppo-cv"] == "ppo_cv.cli.main:main"
