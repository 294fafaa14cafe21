"""Output folders named through ``..`` or a symbolic link: replaced as a whole, or refused
before any work, never set aside and lost."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ppo_cv.atomic import atomic_directory, check_target

COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]
SMALL_SYNTH = ["-n", "1", "--width", "32", "--height", "32", "--supersample", "1", "-q"]

THROUGH_ITSELF = {  # the spelling of folder out that passes through out itself
    "down_and_up": "out/sub/../../out",
    "into_itself": "out/sub/../",
    "twice": "out/sub/../../out/sub/..",
}


def _old_output(root: Path) -> Path:
    (root / "out" / "sub").mkdir(parents=True)
    (root / "out" / "old.txt").write_text("old")
    return root / "out"


@pytest.mark.parametrize("spelling", list(THROUGH_ITSELF.values()), ids=list(THROUGH_ITSELF))
def test_a_folder_named_through_itself_is_replaced_as_a_whole(tmp_path, spelling):
    out = _old_output(tmp_path)
    with atomic_directory(tmp_path / spelling, overwrite=True) as staging:
        (staging / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_folder_named_through_a_symbolic_link_is_replaced_as_a_whole(tmp_path):
    out = _old_output(tmp_path)
    (tmp_path / "link").symlink_to(out / "sub")
    with atomic_directory(tmp_path / "link" / ".." / ".." / "out", overwrite=True) as staging:
        (staging / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "out"]


def test_synth_replaces_an_output_named_through_itself(tmp_path):
    out = _old_output(tmp_path)
    done = subprocess.run(
        [*COMMAND, "synth", "out/sub/../../out", "--overwrite", *SMALL_SYNTH],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PPO_CV_SHARED": str(tmp_path / "none")},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["gt", "images", "pairs_with_gt.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("path", ["/dev/stdout", "/dev/fd/1", "/proc/self/fd/1", "/dev/out"])
@pytest.mark.parametrize("kind", ["file", "folder"])
def test_an_output_among_devices_and_streams_is_refused_even_with_overwrite(path, kind):
    # with standard output redirected to a regular file, /dev/stdout passed as an existing file
    # and --overwrite renamed the new output onto the /dev/stdout link itself
    with pytest.raises(ValueError, match="holds devices and streams .*; give another path$"):
        check_target(path, kind, overwrite=True)
    assert os.readlink("/dev/stdout") == "/proc/self/fd/1"


def test_an_output_that_is_a_fifo_is_not_offered_overwrite(tmp_path):
    # it said "already exists; pass --overwrite to replace it", which then refused it
    os.mkfifo(tmp_path / "fifo.jsonl")
    with pytest.raises(ValueError, match=r"fifo\.jsonl is not a regular file .*give a file name$"):
        check_target(tmp_path / "fifo.jsonl", "file")


def _pairs_of_the_demo_pair(folder: Path, output: str) -> subprocess.CompletedProcess:
    """``ppo-cv pairs`` on the demo pair listed in ``folder``, run there, ``-o output``."""
    demo = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
    (folder / "pairs.txt").write_text("demo1.png demo2.png\n")
    return subprocess.run(
        [*COMMAND, "pairs", "pairs.txt", str(demo), "--K", "535.4,539.2,320.1,247.6",
         "-o", output, "-q"],
        cwd=folder, capture_output=True, text=True, timeout=300,
    )  # fmt: skip


def test_pairs_to_dev_stdout_names_the_dash(tmp_path):
    done = _pairs_of_the_demo_pair(tmp_path, "/dev/stdout")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == (
        "ppo-cv pairs: -o /dev/stdout is a device or a stream; -o - writes to standard output\n"
    )


@pytest.mark.parametrize("kind", ["folder", "file"])
def test_a_symbolic_link_to_nothing_is_refused_before_any_work_unless_replaced(tmp_path, kind):
    # It is no file nor folder, so it passed the checks, and the output, complete, was refused
    # at its final rename ("already exists; pass --overwrite"), after the whole run.
    from ppo_cv.atomic import atomic_file, check_target

    link = tmp_path / "out"
    link.symlink_to("gone")
    with pytest.raises(ValueError, match=r"out is a symbolic link to gone, which leads "
                       r"nowhere; pass --overwrite to replace it$"):  # fmt: skip
        check_target(link, kind)
    assert link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    if kind == "folder":
        with atomic_directory(link, overwrite=True) as staging:
            (staging / "new.txt").write_text("new")
        assert [p.name for p in link.iterdir()] == ["new.txt"]
    else:
        with atomic_file(link, overwrite=True) as handle:
            handle.write("new")
        assert link.read_text() == "new"
    assert not link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("old", [[], ["old.txt"]], ids=["empty", "replaced"])
def test_an_output_folder_that_is_a_link_keeps_the_link_and_fills_its_folder(tmp_path, old):
    # the link was set aside with the old output and a real folder put in its place
    real = tmp_path / "disk" / "out"
    real.mkdir(parents=True)
    for name in old:
        (real / name).write_text("old")
    (tmp_path / "out").symlink_to(real)
    with atomic_directory(tmp_path / "out", overwrite=bool(old)) as staging:
        (staging / "new.txt").write_text("new")
    assert (tmp_path / "out").is_symlink() and os.readlink(tmp_path / "out") == str(real)
    assert [p.name for p in real.iterdir()] == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk", "out"]
    assert [p.name for p in real.parent.iterdir()] == ["out"]


def test_a_link_to_a_folder_that_is_not_empty_is_refused_by_the_folder_it_leads_to(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "old.txt").write_text("old")
    (tmp_path / "out").symlink_to("real")
    with pytest.raises(ValueError, match=r"real exists and is not an empty directory; pass"):
        check_target(tmp_path / "out", "folder")


def test_pair_out_through_a_link_writes_the_linked_folder(tmp_path):
    demo = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
    (tmp_path / "real").mkdir()
    (tmp_path / "out").symlink_to("real")
    done = subprocess.run(
        [*COMMAND, "pair", str(demo / "demo1.png"), str(demo / "demo2.png"),
         "--K", "535.4,539.2,320.1,247.6", "--out", "out", "-q"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out").is_symlink()
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == [
        "colmap", "matches.png", "points.ply", "result.json"
    ]  # fmt: skip


def test_make_dataset_into_a_link_to_an_empty_folder(tmp_path):
    # os.rmdir of the link failed with NotADirectoryError after the pairs were rendered
    from ppo_cv.data_gen.io import PAIRS_FILE, make_dataset

    (tmp_path / "real").mkdir()
    (tmp_path / "out").symlink_to("real")
    assert make_dataset(tmp_path / "out", 1, size=(32, 32), supersample=1, workers=1) == (
        tmp_path / "out"
    )
    assert (tmp_path / "out").is_symlink() and (tmp_path / "real" / PAIRS_FILE).is_file()


def test_an_output_file_that_is_a_link_keeps_the_link_and_replaces_its_file(tmp_path):
    # the link was replaced by a regular file, and the file it led to kept its old content
    from ppo_cv.atomic import atomic_file

    real = tmp_path / "disk" / "poses.jsonl"
    real.parent.mkdir()
    real.write_text("old\n")
    link = tmp_path / "poses.jsonl"
    link.symlink_to(real)
    with pytest.raises(ValueError, match=r"disk/poses\.jsonl already exists; pass --overwrite"):
        check_target(link, "file")
    with atomic_file(link, overwrite=True) as handle:
        handle.write("new\n")
    assert link.is_symlink() and os.readlink(link) == str(real) and real.read_text() == "new\n"
    assert sorted(p.name for p in real.parent.iterdir()) == ["poses.jsonl"]


@pytest.mark.parametrize(
    ("name", "format_"),
    [("poses.csv", "CSV"), ("poses.json", "one JSON document"), ("poses.YAML", "YAML")],
)
def test_pairs_refuses_an_output_named_for_another_format(tmp_path, name, format_):
    # poses.csv was written, exit 0, holding JSON lines that a CSV reader cannot read
    done = _pairs_of_the_demo_pair(tmp_path, name)
    stem = name.rsplit(".", 1)[0]
    assert done.returncode == 2 and not (tmp_path / name).exists()
    assert done.stderr == (
        f"ppo-cv pairs: -o {name}: pairs writes JSON lines (one JSON object per pair and line), "
        f"not {format_}; name the file {stem}.jsonl\n"
    )


@pytest.mark.parametrize(
    ("name", "compression", "wanted"),
    [("poses.jsonl.gz", "gzip", "poses.jsonl"), ("poses.csv.bz2", "bzip2", "poses.jsonl"),
     ("poses.xz", "xz", "poses.jsonl"), ("poses.jsonl.ZIP", "zip", "poses.jsonl")],
)
def test_pairs_refuses_an_output_named_compressed(tmp_path, name, compression, wanted):
    # poses.jsonl.gz was written as plain text, exit 0: gzip.open and pandas, which take the
    # compression from the name, then failed on it
    done = _pairs_of_the_demo_pair(tmp_path, name)
    assert done.returncode == 2 and not (tmp_path / name).exists()
    assert done.stderr == (
        f"ppo-cv pairs: -o {name}: pairs writes JSON lines (one JSON object per pair and line), "
        f"not {compression}-compressed data (compress the file after the run); name the file "
        f"{wanted}\n"
    )


def test_pairs_writes_json_lines_to_a_plain_name(tmp_path):
    done = _pairs_of_the_demo_pair(tmp_path, "poses.txt")
    assert done.returncode == 0, done.stderr
    (line,) = (tmp_path / "poses.txt").read_text().splitlines()
    assert json.loads(line)["model"] == "general"
