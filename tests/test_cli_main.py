"""Usage errors of the ``ppo-cv`` command are one line on stderr with exit code 2."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import ppo_cv
from ppo_cv.cli.main import BLAS_THREAD_VARIABLES, main


def _run(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    out, err = capsys.readouterr()
    return exit_info.value.code, out, err


@pytest.mark.parametrize(
    "argv, prefix, message",
    [
        (["bogus"], "ppo-cv: ", "No such command 'bogus'"),
        (["pair", "--no-such-option"], "ppo-cv pair: ", "No such option: --no-such-option"),
        (["pairs"], "ppo-cv pairs: ", "Missing argument"),
        (["synth", "out", "--pairs", "many"], "ppo-cv synth: ", "Invalid value for '--pairs'"),
        (["pair", "a.png", "b.png", "--features"], "ppo-cv pair: ",
         "Option '--features' requires an argument"),
        (["sfm", "images", "model", "--K"], "ppo-cv sfm: ", "Option '--K' requires an argument"),
    ],
)
def test_usage_errors_are_one_line_with_exit_code_2(argv, prefix, message, capsys):
    code, out, err = _run(argv, capsys)
    assert code == 2 and out == ""
    assert message in err and len(err.strip().splitlines()) == 1
    assert err.startswith(prefix), err


def test_no_arguments_prints_help_and_exits_2(capsys):
    code, out, err = _run([], capsys)
    assert code == 2 and "Usage" in out + err and "pair" in out + err


def test_help_exits_0(capsys):
    code, out, _ = _run(["--help"], capsys)
    assert code == 0 and "synth" in out and "sfm" in out


@pytest.mark.parametrize("command, option", [("pair", "--max-size"), ("pairs", "--max-size"),
                                             ("sfm", "--K")])
def test_an_option_in_pixels_says_so_in_its_help(command, option):
    # --max-size said "at most this" and sfm's --K "Intrinsics fx,fy,cx,cy": no unit
    import typer

    from ppo_cv.cli.main import app

    group = typer.main.get_command(app)
    (param,) = [p for p in group.commands[command].params if option in p.opts]
    assert "pixels" in param.help


def test_help_lists_the_commands_in_the_order_a_newcomer_needs_them(capsys):
    # they were listed in the order the modules registered them: synth, sfm, pair, demo, pairs
    code, out, _ = _run(["--help"], capsys)
    lines = out.split("Commands:")[1].splitlines()
    names = [line.split()[0] for line in lines if line[:2] == "  " and line[2:3] != " "]
    assert code == 0 and names == ["pair", "pairs", "sfm", "synth", "demo"]


def test_version_is_printed_by_the_installed_command():
    done = subprocess.run([sys.executable, "-m", "ppo_cv.cli.main", "--version"],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert (done.returncode, done.stdout, done.stderr) == (0, f"ppo-cv {ppo_cv.__version__}\n", "")


_BLAS_PROBE = """
import os, sys
from ppo_cv.cli.main import main
numpy_before = 'numpy' in sys.modules
try:
    main(['--version'])
except SystemExit:
    pass
print(numpy_before, os.environ.get('OPENBLAS_NUM_THREADS'), os.environ.get('MKL_NUM_THREADS'))
"""


@pytest.mark.parametrize(
    "given, expected", [(None, "False 1 1"), ("2", "False 2 1")], ids=["unset", "user's"]
)
def test_the_command_runs_blas_on_one_thread_unless_told_otherwise(given, expected):
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    done = subprocess.run([sys.executable, "-c", _BLAS_PROBE], capture_output=True, text=True,
                          timeout=60, env=env)  # fmt: skip
    assert done.stdout.split("\n")[-2] == expected, done.stderr


def test_synth_help_lists_every_motion_and_scene_in_an_80_column_terminal():
    from ppo_cv.data_gen import MOTIONS, SCENES

    env = {**os.environ, "COLUMNS": "80", "TERMINAL_WIDTH": "80"}
    done = subprocess.run([sys.executable, "-m", "ppo_cv.cli.main", "synth", "--help"],
                          capture_output=True, text=True, timeout=60, env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr
    for name in (*MOTIONS, *SCENES):
        assert name in done.stdout, name


def _long_names(command: str) -> set[str]:
    import typer

    from ppo_cv.cli.main import app

    group = typer.main.get_command(app)
    params = group.params if command == "" else group.commands[command].params
    return {n for p in params for n in (*p.opts, *p.secondary_opts) if n.startswith("--")}


@pytest.mark.parametrize("command", ["", "pair", "demo", "pairs", "sfm", "synth"])
def test_help_fits_80_columns_with_every_option_name_whole(command):
    env = {**os.environ, "COLUMNS": "80", "TERMINAL_WIDTH": "80"}
    argv = [sys.executable, "-m", "ppo_cv.cli.main", *([command] if command else []), "--help"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    lines = done.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80
    assert "…" not in done.stdout and "..." not in done.stdout.split("Commands:")[-1]
    words = set(done.stdout.replace("/", " ").replace(",", " ").split())
    assert _long_names(command) <= words, _long_names(command) - words
    if command in ("pair", "pairs"):
        assert "Pipeline:" in lines and lines.index("Pipeline:") > lines.index("Options:")


@pytest.mark.parametrize(
    "variable, value, warned",
    [("OMP_NUM_THREADS", "abc", True), ("OMP_NUM_THREADS", "0", True),
     ("OMP_NUM_THREADS", "", True), ("OMP_NUM_THREADS", "4,0", True),
     ("OMP_THREAD_LIMIT", "4,2", True), ("OMP_NUM_THREADS", "2", False),
     ("OMP_NUM_THREADS", "4,2", False), ("OMP_THREAD_LIMIT", " 3", False)],
)  # fmt: skip
def test_an_unreadable_openmp_thread_count_is_one_warning_line(variable, value, warned):
    """The OpenMP runtime pycolmap loads prints two lines of its own for a value it cannot read
    and ignores it; the command drops it first and says so in one line."""
    env = {**os.environ, variable: value}
    done = subprocess.run([sys.executable, "-m", "ppo_cv.cli.main", "pair", "--help"],
                          capture_output=True, text=True, timeout=120, env=env)  # fmt: skip
    assert done.returncode == 0
    assert done.stdout.startswith("Usage: ppo-cv pair")
    expected = [f"ppo-cv pair: warning: {variable}={value!r} is not a positive whole number; "
                "ignored"] if warned else []  # fmt: skip
    assert done.stderr.splitlines() == expected


@pytest.mark.parametrize("value", ["", "  "])
def test_an_empty_pixel_limit_is_unset_with_one_warning_line(value):
    # it failed every image with "PPO_CV_MAX_IMAGE_PIXELS must be a whole number, got ''"
    env = {**os.environ, "PPO_CV_MAX_IMAGE_PIXELS": value}
    done = subprocess.run([sys.executable, "-m", "ppo_cv.cli.main", "demo"],
                          capture_output=True, text=True, timeout=300, env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines()[0] == (
        f"ppo-cv demo: warning: PPO_CV_MAX_IMAGE_PIXELS={value!r} is empty; ignored"
    )
    assert "PPO_CV_MAX_IMAGE_PIXELS" not in "".join(done.stderr.splitlines()[1:])


USAGE = {
    "pair": ("[IMAGE1] [IMAGE2]", ["IMAGE1", "IMAGE2"]),
    "pairs": ("PAIRS_FILE IMAGE_DIR", ["PAIRS_FILE", "IMAGE_DIR"]),
    "sfm": ("IMAGE_DIR OUT_DIR", ["IMAGE_DIR", "OUT_DIR"]),
    "synth": ("OUT_DIR", ["OUT_DIR"]),
}


@pytest.mark.parametrize("command", list(USAGE))
def test_usage_and_arguments_use_the_names_the_help_text_uses(command, capsys):
    """The help text speaks of PAIRS_FILE, IMAGE_DIR and OUT_DIR; the usage line said
    ``{pairs_file} {image_dir}`` and a missing argument was 'pairs_file'."""
    usage, names = USAGE[command]
    code, out, _ = _run([command, "--help"], capsys)
    assert code == 0
    assert out.splitlines()[0] == f"Usage: ppo-cv {command} [OPTIONS] {usage}"
    arguments = out.split("Arguments:\n")[1].split("\n\n")[0]
    assert [line.split()[0] for line in arguments.splitlines() if line[2:3] != " "] == names
    if command != "pair":
        code, _, err = _run([command], capsys)
        assert (code, err) == (2, f"ppo-cv {command}: Missing argument '{names[0]}'.\n")


_SFM_IMPORT_PROBE = """
import sys
import ppo_cv.cli.sfm
print('ppo_cv.sfm' in sys.modules, 'pycolmap' in sys.modules)
"""


def test_the_bounds_in_sfm_and_synth_help_are_the_ones_checked():
    # sfm's help wrote the literal 1..256 beside sfm.MAX_THREADS and the CLI kept its own
    # MAX_FEATURES; synth wrote 0..256 beside WORKERS_MAX
    from ppo_cv import limits, sfm
    from ppo_cv.cli.common import WORKERS_MAX

    assert (sfm.MAX_THREADS, sfm.MAX_FEATURES) == (limits.MAX_THREADS, limits.MAX_FEATURES)
    env = {**os.environ, "COLUMNS": "200", "TERMINAL_WIDTH": "200"}
    helps = {}
    for command in ("sfm", "synth"):
        done = subprocess.run([sys.executable, "-m", "ppo_cv.cli.main", command, "--help"],
                              capture_output=True, text=True, timeout=60, env=env)  # fmt: skip
        assert done.returncode == 0, done.stderr
        helps[command] = " ".join(done.stdout.split())
    assert f"Threads for pycolmap (1..{limits.MAX_THREADS})." in helps["sfm"]
    assert f"SIFT features per image (1..{limits.MAX_FEATURES})." in helps["sfm"]
    assert f"Worker processes (0..{WORKERS_MAX}; 0 or none" in helps["synth"]
    done = subprocess.run([sys.executable, "-c", _SFM_IMPORT_PROBE], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert done.stdout == "False False\n", done.stderr


@pytest.mark.parametrize(
    "argv, line",
    [(["a.png", "b.png", "pair"],
      "ppo-cv: No such command 'a.png'; the command comes first: ppo-cv pair followed by its "
      "arguments"),
     (["pair", "a.png", "b.png", "535.4,539.2,320.1,247.6"],
      "ppo-cv pair: Got unexpected extra argument(s) (535.4,539.2,320.1,247.6); intrinsics go "
      "after --K: --K 535.4,539.2,320.1,247.6"),
     (["pairs", "pairs.txt", "images", "[[500, 0, 320], [0, 500, 240], [0, 0, 1]]"],
      "ppo-cv pairs: Got unexpected extra argument(s) ([[500, 0, 320], [0, 500, 240], [0, 0, "
      "1]]); intrinsics go after --K: --K 500,0,320,0,500,240,0,0,1"),
     (["pair", "a.png", "b.png", "c.png"], "ppo-cv pair: Got unexpected extra argument(s) (c.png)"),
     (["bogus", "pairs"], "ppo-cv: No such command 'bogus'; the command comes first: ppo-cv "
      "pairs followed by its arguments")],
    ids=["command last", "intrinsics without --K", "a matrix without --K", "a third image",
         "a word before the command"],
)  # fmt: skip
def test_a_command_line_in_the_wrong_order_gets_the_remedy(argv, line, capsys):
    # "No such command 'a.png'." and "Got unexpected extra argument(s)" said nothing of the order
    code, out, err = _run(argv, capsys)
    assert (code, out, err) == (2, "", line + "\n")
