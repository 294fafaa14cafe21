"""``ppo_cv.cli`` and ``ppo_cv.data_gen`` import, and ``python -m ppo_cv`` runs, in every layout.

The source tree keeps ``cli/`` and ``data_gen/`` beside ``ppo_cv/``; installation maps them into
the package. Each test runs a fresh interpreter: from the root of the checkout with nothing
installed, with the package installed from a wheel (from elsewhere and from a checkout root,
which shadows the installed package) and with the editable install of the development
environment. Also here: every test reaches the test data through ``PPO_CV_SHARED``.
"""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Prints where the three packages were imported from, then the help of ``python -m ppo_cv``.
PROBE = (
    "import ppo_cv, ppo_cv.cli.main\n"
    "from ppo_cv import data_gen\n"
    "print(ppo_cv.__file__, ppo_cv.cli.main.__file__, data_gen.__file__, sep='\\n')\n"
)


def run(args: list[str], cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    environment.update(env or {})
    return subprocess.run(
        [sys.executable, *args], cwd=cwd, env=environment, capture_output=True, text=True
    )


def probe(cwd: Path, *flags: str, env: dict | None = None) -> list[Path]:
    """Files of ppo_cv, ppo_cv.cli.main and ppo_cv.data_gen in a new interpreter."""
    done = run([*flags, "-c", PROBE], cwd, env)
    assert done.returncode == 0, done.stderr
    return [Path(line).resolve() for line in done.stdout.split()]


def check_module_entry(cwd: Path, *flags: str, env: dict | None = None) -> None:
    done = run([*flags, "-m", "ppo_cv", "--help"], cwd, env)
    assert done.returncode == 0, done.stderr
    assert "Usage: ppo-cv" in done.stdout and "pair" in done.stdout


def copy_tree(target: Path) -> Path:
    """The files a clone holds that building and importing need."""
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info")
    for folder in ("ppo_cv", "cli", "data_gen"):
        shutil.copytree(ROOT / folder, target / folder, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, target / name)
    return target


def site_dirs_without_ppo_cv(scratch: Path) -> list[str]:
    """The site directories, with any installed or editable ppo_cv left out.

    A directory that holds ppo_cv is replaced by a folder in ``scratch`` of links to its other
    entries.
    """
    dirs = list(dict.fromkeys([*site.getsitepackages(), site.getusersitepackages()]))
    paths = []
    for number, d in enumerate(Path(d) for d in dirs if Path(d).is_dir()):
        entries = list(d.iterdir())
        ours = [e for e in entries if e.name.startswith(("ppo_cv", "__editable__", "ppo-cv"))]
        if not ours:
            paths.append(str(d))
            continue
        filtered = scratch / f"site{number}"
        filtered.mkdir()
        for entry in entries:
            if entry not in ours:
                (filtered / entry.name).symlink_to(entry)
        paths.append(str(filtered))
    return paths


def test_clone_root_without_installation(tmp_path):
    env = {"PYTHONPATH": os.pathsep.join(site_dirs_without_ppo_cv(tmp_path))}
    # -S: no site processing, so neither an installed nor an editable ppo_cv can be found
    assert run(["-S", "-c", "import numpy, cv2, typer"], ROOT, env).returncode == 0
    assert run(["-S", "-c", "import ppo_cv.pose"], ROOT / "tests", env).returncode != 0
    package, cli, data_gen = probe(ROOT, "-S", env=env)
    assert package == ROOT / "ppo_cv" / "__init__.py"
    assert cli == ROOT / "cli" / "main.py" and data_gen == ROOT / "data_gen" / "__init__.py"
    check_module_entry(ROOT, "-S", env=env)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path]:
    """(site folder holding the package as a wheel installs it, the checkout it came from)."""
    base = tmp_path_factory.mktemp("wheel")
    clone = copy_tree(base / "clone")
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(base), str(clone)],
        capture_output=True,
        text=True,
    )
    wheels = list(base.glob("ppo_cv-*.whl"))
    if built.returncode != 0 or not wheels:
        pytest.skip(f"could not build a wheel here: {built.stderr.strip()[-200:]}")
    target = base / "site"
    with zipfile.ZipFile(wheels[0]) as wheel:
        wheel.extractall(target)
    return target, clone


def test_wheel_installs_one_top_level_package(installed):
    target, _ = installed
    top = {p.name for p in target.iterdir() if not p.name.endswith(".dist-info")}
    assert top == {"ppo_cv"}
    assert (target / "ppo_cv" / "cli" / "main.py").is_file()
    assert (target / "ppo_cv" / "data_gen" / "render.py").is_file()
    assert (target / "ppo_cv" / "__main__.py").is_file()


def test_installed_package_imports_from_elsewhere(installed, tmp_path):
    target, _ = installed
    env = {"PYTHONPATH": str(target)}
    package, cli, data_gen = probe(tmp_path, env=env)
    assert package == target.resolve() / "ppo_cv" / "__init__.py"
    assert cli.parent == target.resolve() / "ppo_cv" / "cli"
    assert data_gen.parent == target.resolve() / "ppo_cv" / "data_gen"
    check_module_entry(tmp_path, env=env)


def test_clone_root_shadowing_an_installed_package(installed):
    target, clone = installed
    env = {"PYTHONPATH": str(target)}
    package, cli, data_gen = probe(clone, env=env)
    # The checkout's ppo_cv/ comes first on sys.path; its subpackages come from the checkout too.
    assert package == clone.resolve() / "ppo_cv" / "__init__.py"
    assert cli == clone.resolve() / "cli" / "main.py"
    assert data_gen == clone.resolve() / "data_gen" / "__init__.py"
    check_module_entry(clone, env=env)


def test_editable_install(tmp_path):
    package, cli, data_gen = probe(tmp_path)
    if package != ROOT / "ppo_cv" / "__init__.py":
        pytest.skip(f"ppo_cv is not installed in editable mode from {ROOT}")
    assert cli == ROOT / "cli" / "main.py" and data_gen == ROOT / "data_gen" / "__init__.py"
    assert probe(ROOT) == [package, cli, data_gen]
    check_module_entry(tmp_path)


def test_every_test_reaches_the_data_through_ppo_cv_shared():
    # Only conftest.py names the folder; the other tests use shared_path or the fixture.
    for test_file in sorted((ROOT / "tests").glob("*.py")):
        if test_file.name in ("conftest.py", Path(__file__).name):
            continue
        text = test_file.read_text(encoding="utf-8")
        assert '"shared' not in text and "/shared" not in text, test_file.name


def test_tests_skip_when_ppo_cv_shared_has_no_data(tmp_path):
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-rs",
            str(ROOT / "tests" / "test_data_gen_io.py"),
            "-k",
            "freiburg",
        ],
        cwd=ROOT,
        env={**os.environ, "PPO_CV_SHARED": str(tmp_path)},
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 skipped" in done.stdout and str(tmp_path / "data" / "freiburg") in done.stdout


@pytest.mark.parametrize("module", ["ppo_cv", "ppo_cv.cli"])
def test_both_module_entries_run_the_command_line(module):
    done = run(["-m", module, "--version"], ROOT)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("ppo-cv ")


def test_no_gallery_output_is_tracked_and_git_ignores_it():
    """Run from the root, docs/gallery/sfm_init.py and analytic_points.py write their outputs
    there: a 6 MB ``sfm_example/`` of rendered views, database and model was once committed
    with a change. The checkout tracks none of them and git ignores them."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    outputs = ["sfm_example/model/images.bin", "sfm_example/database.db", "analytic_points.ply"]
    tracked = subprocess.run(
        ["git", "ls-files", "--", "sfm_example", "analytic_points.ply"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    assert tracked == ""
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *outputs], cwd=ROOT, capture_output=True, text=True
    ).stdout.split()
    assert ignored == outputs
