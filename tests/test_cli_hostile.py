"""Hostile input to every command, each in its own process (issue #11, sections 2, 3 and 5).

Every case must end with exit code 2, exactly one line ``ppo-cv <command>: ...`` on stderr
naming the problem, nothing on stdout, no traceback, and the working folder byte for byte as it
was (nothing written, nothing deleted). Interrupts (SIGINT, SIGTERM) midway through a run must
leave no partial output.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pycolmap
import pytest
from hostile_images import HEADERS

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
DEMO1, DEMO2 = str(DATA / DEMO["image1"]), str(DATA / DEMO["image2"])
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]
PAIR = ["pair", DEMO1, DEMO2, "--K", K_TEXT]
INTRINSICS = " ".join(["0 0"] + ["535.4 0 320.1 0 539.2 247.6 0 0 1"] * 2)
GT = INTRINSICS + " 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"
PARALLEL = 6  # processes at a time
NOT_UTF8 = os.fsdecode(b"bad\xff.png")  # a file name of bytes that are no UTF-8
IMAGES = [f"images/{DEMO['image1']}", f"images/{DEMO['image2']}"]
BAD_GROUND_TRUTH = {  # issue 44, defect 16: what a T_1to2 of a pairs file must not be
    "bottom_row.txt": INTRINSICS + " 1 0 0 0 0 1 0 0 0 0 1 0 1 2 3 4",
    "reflection.txt": INTRINSICS + " 1 0 0 0 0 1 0 0 0 0 -1 0 0 0 0 1",
    "sheared.txt": INTRINSICS + " 1 0.1 0 0 0 1 0 0 0 0 1 0 0 0 0 1",
    "words_in_T.txt": INTRINSICS + " 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 one",
    "words.txt": "foo bar",
    "turned.txt": "1 0",
}


def _images(root: Path) -> None:
    """Images a reader must refuse with one line (issue 44, defects 7, 11, 12, 17 and 19)."""
    demo2 = cv2.imread(DEMO2)
    cv2.imwrite(str(root / "small.png"), cv2.resize(demo2, (320, 240)))
    cv2.imwrite(str(root / "mirror.png"), cv2.imread(DEMO1)[:, ::-1])
    cv2.imwrite(str(root / "const16.png"), np.full((480, 640), 1000, np.uint16))
    cv2.imwrite(str(root / "thin.png"), np.arange(60000, dtype=np.uint8).reshape(1, -1))
    (root / "trunc.png").write_bytes(Path(DEMO1).read_bytes()[:20000])
    tiff = cv2.imencode(".tif", cv2.imread(DEMO1))[1].tobytes()
    (root / "trunc.tif").write_bytes(tiff[: len(tiff) // 2])  # Pillow warns of its EXIF
    shutil.copy(DEMO2, root / NOT_UTF8)
    for extension, header in HEADERS.items():
        (root / f"huge.{extension}").write_bytes(header(30000, 30000))
    (root / "crop.txt").write_text("1 PINHOLE 640 400 535.4 539.2 320.1 247.6\n")
    (root / "one.yml").write_text(
        "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
        "  data: [535.4, 0, 320.1, 0, 539.2, 247.6, 0, 0, 1]\n"
    )
    (root / "two.yml").write_text(
        "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n"
        "  data: [535.4, 539.2, 320.1, 247.6]\n"
    )


def _workspace(root: Path) -> None:
    """The hostile files every case may point at, relative to ``root``."""
    (root / "bad.yml").write_text("%YAML:1.0\n---\ncamera_matrix: [1, 2, 3\n")
    (root / "empty.yml").write_text("")
    (root / "scalar.yml").write_text("%YAML:1.0\n---\ncamera_matrix: 5\n")
    (root / "bad.xml").write_text('<?xml version="1.0"?>\n<opencv_storage><camera_matrix>1 2')
    (root / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    (root / "gt_then_none.txt").write_text(f"a.png b.png {GT}\n#\nc.png d.png {INTRINSICS}\n")
    (root / "no_gt.txt").write_text("a.png b.png\n")
    (root / "negative_focal.txt").write_text(
        f"a.png b.png {INTRINSICS.replace('535.4', '-535.4')}\n"
    )
    (root / "afile").write_text("not a folder\n")
    (root / "images").mkdir()
    for image in (DEMO1, DEMO2):
        shutil.copy(image, root / "images")
    os.mkfifo(root / "fifo.png")
    (root / "nul.txt").write_bytes(b"demo1.png demo2.png\nde\x00mo1.png demo2.png\n")
    (root / "nul_cameras.txt").write_bytes(b"1 PINHOLE 640 480 500 500 320 240\x00\n")
    os.symlink("loop2", root / "loop1")  # a loop of symbolic links
    os.symlink("loop1", root / "loop2")
    (root / "t").mkdir()  # issue 11, section 2: an old file beside where a result would go
    (root / "t" / "points.ply").write_text("OLD\n")
    (root / "t" / "colmap").write_text("x\n")
    (root / "u" / "colmap").mkdir(parents=True)
    (root / "u" / "colmap" / "database.db").write_text("keep\n")
    (root / "taken.jsonl").write_text("mine\n")
    (root / "synth_out").mkdir()
    (root / "synth_out" / "notes.txt").write_text("mine\n")
    (root / "pairs_demo.txt").write_text("demo1.png demo2.png\n")
    os.link(root / "images" / "demo1.png", root / "twin.png")  # a second name of an input
    _images(root)
    shutil.copy(root / "small.png", root / "images")
    (root / "broken").mkdir()  # one readable image beside a truncated one
    shutil.copy(DEMO1, root / "broken")
    shutil.copy(root / "trunc.png", root / "broken")
    (root / "sizes.txt").write_text(
        f"{Path(DEMO1).name} {Path(DEMO2).name}\nsmall.png {Path(DEMO2).name}\n"
    )
    for name, fields in BAD_GROUND_TRUTH.items():
        (root / name).write_text(f"a.png b.png {GT}\nc.png d.png {fields}\n")


def _snapshot(root: Path) -> dict:
    """Every entry under ``root`` with its content (files) or kind (folders, FIFOs)."""
    entries = {}
    for path in sorted(root.rglob("*")):
        key = str(path.relative_to(root))
        if path.is_symlink():
            entries[key] = f"link to {os.readlink(path)}"
        elif path.is_fifo():
            entries[key] = "fifo"
        elif path.is_dir():
            entries[key] = "dir"
        else:
            entries[key] = path.read_bytes()
    return entries


# (arguments, the command named in the message, a pattern the message must match)
CASES = [
    # section 3: calibration files OpenCV or json cannot parse
    ([*PAIR[:3], "--calib", "bad.yml"], "pair", r"malformed OpenCV calibration file.*bad\.yml"),
    ([*PAIR[:3], "--calib", "empty.yml"], "pair", r"empty\.yml is empty"),
    ([*PAIR[:3], "--calib", "scalar.yml"], "pair", r"camera_matrix .* is a scalar"),
    ([*PAIR[:3], "--calib", "bad.xml"], "pair", r"malformed OpenCV calibration file.*bad\.xml"),
    ([*PAIR[:3], "--calib", "deep.json"], "pair", r"deep\.json is nested too deeply"),
    ([*PAIR[:3], "--calib", "fifo.png"], "pair", r"fifo\.png is not a regular file"),
    ([*PAIR[:3], "--K", "535,4,539,2"], "pair", r"fy=4, .* \(a decimal comma\? write 535\.4"),
    # section 3: pairs output paths and inconsistent ground truth
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "-o", "nodir/x.jsonl"],
        "pairs",
        r"folder nodir does not exist",
    ),
    (["pairs", "no_gt.txt", "images", "--K", K_TEXT, "-o", "."], "pairs", r"\. is a folder"),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "-o", "taken.jsonl"],
        "pairs",
        r"taken\.jsonl already exists; pass --overwrite",
    ),
    (
        ["pairs", "gt_then_none.txt", "images"],
        "pairs",
        r"gt_then_none\.txt:3: line 1 carries a ground-truth motion and line 3 does not",
    ),
    (["pairs", "negative_focal.txt", "images"], "pairs", r"negative_focal\.txt:1: K1 .*focal"),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--database", "taken.jsonl"],
        "sfm",
        r"database taken\.jsonl already exists; give a new file name",
    ),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--database", "taken.jsonl", "--overwrite"],
        "sfm",
        r"database taken\.jsonl already exists; give a new file name \(a database is never "
        r"replaced, --overwrite or not\)$",
    ),
    # section 3: numbers out of range, checked before any work
    ([*PAIR, "--seed", "1099511627776"], "pair", r"--seed must be in 0\.\.2147483647"),
    ([*PAIR, "--seed", "-1"], "pair", r"--seed must be in 0\.\."),
    ([*PAIR, "--max-features", "3000000000"], "pair", r"--max-features must be in 8\.\."),
    ([*PAIR, "--max-size", "-5"], "pair", r"--max-size .* must be in 32\.\."),
    ([*PAIR, "--pri-threshold", "-0.1"], "pair", r"--pri-threshold must be in 0\.\.1"),
    ([*PAIR, "--threshold", "inf"], "pair", r"--threshold \(pixels\) must be in"),
    ([*PAIR, "--redetect-below", "-1"], "pair", r"--redetect-below must be in 0\.\."),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "--redetect-below", "-1"],
        "pairs",
        r"--redetect-below must be in 0\.\.",
    ),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "--workers", "-1"],
        "pairs",
        r"--workers must be in 0\.\.256",
    ),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "--seed", "1099511627776"],
        "pairs",
        r"--seed must be in",
    ),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "--max-features", "3000000000"],
        "pairs",
        r"--max-features must be in",
    ),
    (
        ["pairs", "no_gt.txt", "images", "--K", K_TEXT, "--max-size", "-5"],
        "pairs",
        r"--max-size .* must be in",
    ),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--seed", "1099511627776"],
        "sfm",
        r"--seed must be in",
    ),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--max-features", "3000000000"],
        "sfm",
        r"--max-features must be in 1\.\.",
    ),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--threads", "1000000"],
        "sfm",
        r"--threads must be in 1\.\.256",
    ),
    (["sfm", "images", "afile/sub", "--K", K_TEXT], "sfm", r"afile is a file, not a folder"),
    (
        ["sfm", "images", "out", "--K", K_TEXT, "--database", "afile/db.db"],
        "sfm",
        r"afile is a file, not a folder",
    ),
    (["sfm", "images", "t", "--K", K_TEXT], "sfm", r"t exists and is not an empty directory"),
    # section 2: outputs never written over without --overwrite
    ([*PAIR, "--out", "t"], "pair", r"t exists and is not an empty directory"),
    ([*PAIR, "--out", "u"], "pair", r"u exists and is not an empty directory"),
    ([*PAIR, "--out", "afile"], "pair", r"afile is a file, not a folder"),
    (
        ["synth", "synth_out", "--pairs", "1"],
        "synth",
        r"synth_out exists and is not an empty directory",
    ),
    # section 5: bounded resources, non-regular files
    (["synth", "new", "--blur", "1000000"], "synth", r"--blur must be in \[0, 50\]"),
    (
        ["synth", "new", "--view-focal-error", "0.01"],
        "synth",
        r"--centred-principal-point, --view-focal-error, --exposure-ev, --vignetting and "
        r"--narrow-lens need --imperfect",
    ),
    (
        ["synth", "new", "--narrow-lens"],
        "synth",
        r"--vignetting and --narrow-lens need --imperfect",
    ),
    (
        ["synth", "new", "--imperfect", "--vignetting", "1.5"],
        "synth",
        r"--vignetting must be in \[0\.0, 0\.9\]",
    ),
    (
        ["synth", "new", "--imperfect", "--view-focal-error", "0.9"],
        "synth",
        r"--view-focal-error must be in \[0\.0, 0\.5\]",
    ),
    (["pair", "fifo.png", DEMO2, "--K", K_TEXT], "pair", r"not a regular file: fifo\.png"),
    # issue 44, defect 1: an output that is or holds an input, refused even with --overwrite
    *[
        (
            [*args, "--overwrite"],
            args[0],
            rf"the output {re.escape(output)} {relation} the input {re.escape(source)}; give "
            "an output apart from the inputs",
        )
        for args, output, relation, source in [
            (["pair", *IMAGES, "--K", K_TEXT, "--out", "images"], "--out images", "holds",
             IMAGES[0]),
            (["pair", *IMAGES, "--K", K_TEXT, "--out", "."], "--out .", "holds", IMAGES[0]),
            (["pair", *IMAGES, "--K", K_TEXT, "--out", IMAGES[1]], f"--out {IMAGES[1]}", "is",
             IMAGES[1]),
            (["pair", *IMAGES, "--calib", "bad.yml", "--out", "bad.yml"], "--out bad.yml", "is",
             "bad.yml"),
            (["pairs", "pairs_demo.txt", "images", "--K", K_TEXT, "-o", "pairs_demo.txt"],
             "-o pairs_demo.txt", "is", "pairs_demo.txt"),
            (["pairs", "pairs_demo.txt", "images", "--K", K_TEXT, "-o", IMAGES[0]],
             f"-o {IMAGES[0]}", "is", IMAGES[0]),
            (["pairs", "pairs_demo.txt", "images", "--K", K_TEXT, "-o", "twin.png"],
             "-o twin.png", "is", IMAGES[0]),
            (["sfm", "images", "images", "--K", K_TEXT], "OUT_DIR images", "is", "images"),
            (["sfm", "images", ".", "--K", K_TEXT], "OUT_DIR .", "holds", "images"),
            (["sfm", "images", "model", "--K", K_TEXT, "--database", "images"],
             "--database images", "is", "images"),
            (["synth", "images", "--warp", "--warp-source", "images", "--pairs", "1"],
             "OUT_DIR images", "is", "images"),
            (["synth", ".", "--warp", "--warp-source", "twin.png", "--pairs", "1"],
             "OUT_DIR .", "holds", "twin.png"),
        ]
    ],
    # an empty camera option is an error, not the option left out
    ([*PAIR, "--dist", ""], "pair", r"--dist is empty: give k1,k2,p1,p2\[,k3\]"),
    ([*PAIR, "--dist2", ""], "pair", r"--dist2 is empty"),
    ([*PAIR, "--K2", ""], "pair", r"--K2 must be 4 numbers fx,fy,cx,cy .*, got 0"),
    (["pairs", "pairs_demo.txt", "images", "--K", K_TEXT, "--K2", ""], "pairs", r"--K2 must be"),
    # the wrong image folder: one line, not a batch of failed pairs
    (
        ["pairs", "pairs_demo.txt", ".", "--K", K_TEXT],
        "pairs",
        r"image folder \. holds none of the 2 images pairs_demo\.txt names \(the first: demo1",
    ),
    # issue 44: images the readers refuse, each with one line (libpng and OpenCV kept quiet)
    (
        ["pair", "thin.png", DEMO2, "--K", K_TEXT],
        "pair",
        r"thin\.png is 60000x1 pixels: too small or too thin",
    ),
    (["pair", "trunc.png", DEMO2, "--K", K_TEXT], "pair", r"not a readable image: trunc\.png"),
    *[
        (
            ["pair", f"huge.{extension}", DEMO2, "--K", K_TEXT],
            "pair",
            rf"huge\.{extension} declares 30000x30000 pixels, above the limit",
        )
        for extension in HEADERS
    ],
    (
        ["synth", "new", "--warp", "--warp-source", "huge.png"],
        "synth",
        r"huge\.png declares 30000x30000 pixels",
    ),
    (
        ["synth", "new", "--warp", "--warp-source", "fifo.png"],
        "synth",
        r"not a regular file: fifo\.png",
    ),
    (
        ["synth", "new", "--warp", "--warp-source", "nothing.png"],
        "synth",
        r"photo nothing\.png does not exist",
    ),
    # issue 44, defects 8, 9 and 19: one camera for two sizes, a calibration of another shape
    (
        ["pair", DEMO1, "small.png", "--K", K_TEXT],
        "pair",
        r"demo1\.png is 640x480 and small\.png 320x240 pixels: one camera matrix \(--K\) cannot "
        r"fit both sizes; pass --K2",
    ),
    (
        ["pair", DEMO1, "small.png", "--calib", "one.yml"],
        "pair",
        r"one camera matrix \(--calib one\.yml\) cannot fit both sizes",
    ),
    (
        ["pair", DEMO1, DEMO2, "--calib", "crop.txt"],
        "pair",
        r"crop\.txt describes a camera of 640x400 images but .*demo1\.png is 640x480 pixels, "
        r"another aspect ratio",
    ),
    (
        ["pair", DEMO1, DEMO2, "--calib", "two.yml"],
        "pair",
        r"camera matrix in two\.yml must be a 3x3 matrix, got shape \(2, 2\)",
    ),
    (
        ["pair", DEMO1, DEMO2, "--K", "1e308,1e308,320,240"],
        "pair",
        r"--K has an implausible focal length \(fx=1e\+308",
    ),
    (
        ["pairs", "sizes.txt", "images", "--K", K_TEXT],
        "pairs",
        r"sizes\.txt:2: small\.png is 320x240 and demo2\.png 640x480 pixels: one camera matrix "
        r"\(--K\) cannot fit both sizes; give K1 and K2 on the line",
    ),
    # issue 44, defect 16: ground truth that is no rigid motion, fields that are no numbers
    (
        ["pairs", "bottom_row.txt", "images"],
        "pairs",
        r"bottom_row\.txt:2: the ground-truth T_1to2 must end with the row 0 0 0 1, got 1 2 3 4",
    ),
    (
        ["pairs", "reflection.txt", "images"],
        "pairs",
        r"reflection\.txt:2: the ground-truth rotation has determinant -1: a reflection",
    ),
    (
        ["pairs", "sheared.txt", "images"],
        "pairs",
        r"sheared\.txt:2: the ground-truth rotation is not orthonormal",
    ),
    (
        ["pairs", "words_in_T.txt", "images"],
        "pairs",
        r"words_in_T\.txt:2: the ground-truth T_1to2 must be numbers",
    ),
    (
        ["pairs", "words.txt", "images"],
        "pairs",
        r"words\.txt:2: fields 3 and 4 must be 0 0, got foo bar",
    ),
    (
        ["pairs", "turned.txt", "images"],
        "pairs",
        r"turned\.txt:2: fields 3 and 4 \(EXIF rotations\) must be 0 0, got 1 0",
    ),
    # issue 44, defect 17: the right noun for what a path is
    (["pairs", "images", "images", "--K", K_TEXT], "pairs", r"pairs file images is a directory"),
    (
        ["pairs", "fifo.png", "images", "--K", K_TEXT],
        "pairs",
        r"pairs file fifo\.png is not a regular file",
    ),
    (
        ["pairs", "no_gt.txt", "afile", "--K", K_TEXT],
        "pairs",
        r"image folder afile is not a folder",
    ),
    (["sfm", "afile", "out", "--K", K_TEXT], "sfm", r"image folder 'afile' is not a folder"),
    # a camera COLMAP cannot hold is refused before the run, not dropped from the model
    (
        [*PAIR[:3], "--K", "535.4,2,320.1,0,539.2,247.6,0,0,1", "--out", "new"],
        "pair",
        r"--out: camera 1 has skew 2\.0, which no COLMAP camera model holds",
    ),
    (
        [*PAIR, "--dist", "0,0,0,0,0,0,0,0,0.01,0,0,0", "--out", "new"],
        "pair",
        r"--out: camera 1 has thin-prism coefficients s1..s4 \[0\.01, 0\.0, 0\.0, 0\.0\]",
    ),
    (
        ["sfm", "images", "out", "--K", "535.4,2,320.1,0,539.2,247.6,0,0,1"],
        "sfm",
        r"K has skew 2\.0, which pycolmap's PINHOLE camera cannot hold",
    ),
    # too few readable images: one line naming the skipped ones, no warning before it
    *[
        (["sfm", "broken", "out", *k], "sfm",
         r"need at least 2 images in 'broken', found 1 \(1 skipped: not a readable image: "
         r"broken/trunc\.png\)")
        for k in (["--K", K_TEXT], [])
    ],
    (["sfm", "broken", "out", "--K", "1,2"], "sfm", r"--K must be 4 numbers fx,fy,cx,cy"),
    # an output name with no room for the hidden name it is built under: refused before the
    # work, naming the output (it failed after the run, naming the hidden file)
    ([*PAIR, "--out", "o" * 250], "pair", r"cannot write o{250}: its name is 250 bytes; .* at "
     r"most 235$"),
    (["pairs", "pairs_demo.txt", "images", "--K", K_TEXT, "-o", "o" * 246 + ".jsonl"], "pairs",
     r"cannot write o{246}\.jsonl: its name is 252 bytes"),
    (["synth", "s" * 240, "-n", "1"], "synth", r"cannot write s{240}: its name is 240 bytes"),
    (["sfm", "images", "m" * 236, "--K", K_TEXT], "sfm", r"its name is 236 bytes"),
    ([*PAIR, "--out", "d" * 256 + "/new"], "pair",
     r"cannot write d{256}/new: folder name 'd{40}'\.\.\. is 256 bytes, above the 255"),
    # a truncated TIFF: one line, without Pillow's warning about its EXIF block before it
    (["pair", "trunc.tif", DEMO2, "--K", K_TEXT], "pair", r"not a readable image: trunc\.tif$"),
    # a file name that is not UTF-8: the COLMAP model of --out cannot hold it, said before the run
    ([*PAIR[:2], NOT_UTF8, "--K", K_TEXT, "--out", "new"], "pair",
     r"--out: image name 'bad\\xff\.png' is not valid UTF-8, which a COLMAP model cannot hold; "
     r"run without --out$"),
    # a name holding a line break, shown whole (the message named the file "no")
    (["pair", "no\nsuch.png", DEMO2, "--K", K_TEXT], "pair", r"image not found: no\\nsuch\.png$"),
    ([*PAIR[:3], "--calib", "no\nsuch.yml"], "pair",
     r"calibration file not found: no\\nsuch\.yml$"),
    (["pairs", "no\nsuch.txt", "images"], "pairs", r"pairs file not found: no\\nsuch\.txt$"),
    # a name holding a terminal escape is shown by its code (it restyled the terminal)
    (["pair", "no\x1b[31msuch.png", DEMO2, "--K", K_TEXT], "pair",
     r"image not found: no\\x1b\[31msuch\.png$"),
    # '-' is standard output, which cannot hold a folder (no folder named '-' appears)
    ([*PAIR, "--out", "-"], "pair", r"--out takes a folder, not '-' \(standard output\)"),
    # a loop of symbolic links is named so (it was "not found"), as for an image
    ([*PAIR[:3], "--calib", "loop1"], "pair",
     r"cannot read calibration file loop1: Too many levels of symbolic links$"),
    (["pairs", "loop1", "images"], "pairs", r"cannot read pairs file loop1: Too many levels"),
    (["pairs", "pairs_demo.txt", "loop1", "--K", K_TEXT], "pairs",
     r"cannot read image folder loop1: Too many levels"),
    (["sfm", "loop1", "out", "--K", K_TEXT], "sfm",
     r"cannot read image folder loop1: Too many levels of symbolic links$"),
    # the working folder, or one holding it, as an output folder: refused before any work (it
    # was found busy once the pair was done, or the rendering of synth)
    ([*PAIR, "--out", ".", "--overwrite"], "pair",
     r"cannot write \.: it is or holds the current folder, which a new output folder cannot "
     r"replace; give another folder$"),
    (["synth", ".", "-n", "1"], "synth", r"cannot write \.: it is or holds the current folder"),
    # a NUL byte in a text file: named with its line (it was 'embedded null byte' alone)
    (["pairs", "nul.txt", "images"], "pairs", r"pairs file nul\.txt is not text: line 2 holds a "
     r"NUL byte$"),
    ([*PAIR[:3], "--calib", "nul_cameras.txt"], "pair",
     r"calibration file nul_cameras\.txt is not text: line 1 holds a NUL byte$"),
    # a name of 100,000 characters: cut to its first 300 (the line was 100,000 characters)
    (["pair", DEMO1, "x" * 100_000 + ".png", "--K", K_TEXT], "pair",
     r"^ppo-cv pair: cannot read image x{297}\.\.\. File name too long$"),
    # a number of thousands of digits, a text of thousands of characters: named by their start
    ([*PAIR, "--max-features", "1" + "0" * 5000], "pair",
     r"Invalid value for '--max-features': '10{76}\.\.\.' is not a valid int\.$"),
    ([*PAIR, "--max-features", "1" + "0" * 4000], "pair",
     r"--max-features must be in 8\.\.1000000, got <4001-digit integer>$"),
    ([*PAIR, "--" + "x" * 300], "pair", r"No such option: --x{75}\.\.\.$"),
    ([*PAIR[:3], "--K", "x" + "1," * 3000], "pair",
     r"--K must be numbers separated by commas, spaces or semicolons: field 1 of 3000 is 'x1'$"),
    (["synth", "out", "--width", "1" + "0" * 4000], "synth",
     r"--width must be in 16\.\.4096, got <4001-digit integer>$"),
    (["sfm", "images", "model", "--init", "x" * 5000], "sfm",
     r"--init must be one of ppo, colmap, got 'x{36}\.\.\.$"),
]


def _ids():
    return [f"{i:02d}-{' '.join(a[:1] + [x for x in a if x.startswith('-')][:2])}" for i, (a, *_) in
            enumerate(CASES)]  # fmt: skip


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory):
    """Run the cases a few at a time (own process and folder each); collect the outcomes."""
    results = []
    for start in range(0, len(CASES), PARALLEL):
        runs = []
        for number in range(start, min(start + PARALLEL, len(CASES))):
            root = tmp_path_factory.mktemp(f"case{number:02d}")
            _workspace(root)
            before = _snapshot(root)
            process = subprocess.Popen([*COMMAND, *CASES[number][0]], cwd=root, text=True,
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
            runs.append((root, before, process))
        for root, before, process in runs:
            try:
                out, err = process.communicate(timeout=120)
            except subprocess.TimeoutExpired:  # a blocked process is a failure, not a hang
                process.kill()
                out, err = process.communicate()
                err = "TIMEOUT " + err
            results.append((process.returncode, out, err, before, _snapshot(root)))
    return results


@pytest.mark.parametrize("number", range(len(CASES)), ids=_ids())
def test_hostile_input_is_one_line_exit_2_and_touches_nothing(outcomes, number):
    _, command, pattern = CASES[number]
    code, out, err, before, after = outcomes[number]
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith(f"ppo-cv {command}: "), err
    assert re.search(pattern, lines[0]), err
    assert "Traceback" not in err and out == ""
    assert after == before


def _wait_for(process, needle: str) -> str:
    """stderr lines of ``process`` up to the first holding ``needle``."""
    seen = []
    for line in process.stderr:
        seen.append(line)
        if needle in line:
            return "".join(seen)
    raise AssertionError(f"{needle!r} never appeared; stderr: {''.join(seen)}")


def _wait_for_entry(process, root: Path, known: set) -> str:
    """Wait until ``process`` has created something new in ``root``."""
    deadline = time.monotonic() + 120
    while not set(os.listdir(root)) - known:
        assert process.poll() is None and time.monotonic() < deadline, "nothing was started"
        time.sleep(0.05)
    return ""


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(args, root: Path, needle: str | None, signum: int) -> tuple[int, str]:
    """Send ``signum`` midway: SIGINT to the process group (Ctrl-C at a terminal reaches the
    workers too), SIGTERM to the command's process only (as ``kill`` does)."""
    known = set(os.listdir(root))
    # as at a terminal: a runner started in the background passes SIGINT on ignored
    process = subprocess.Popen([*COMMAND, *args], cwd=root, text=True, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               preexec_fn=_default_sigint)  # fmt: skip
    try:
        if needle is None:
            head = _wait_for_entry(process, root, known)
        else:
            head = _wait_for(process, needle)
        if signum == signal.SIGINT:
            os.killpg(process.pid, signum)
        else:
            process.send_signal(signum)
        _, tail = process.communicate(timeout=120)
    finally:
        process.kill()
    return process.returncode, head + tail


@pytest.mark.parametrize(
    "signum, workers",
    [(signal.SIGINT, "2"), (signal.SIGTERM, "2"), (signal.SIGTERM, "1")],
    ids=["SIGINT-group", "SIGTERM-pool", "SIGTERM-in-process"],
)
def test_interrupted_pairs_leave_no_jsonl(tmp_path, signum, workers):
    names = [Path(DEMO1).name, Path(DEMO2).name]
    (tmp_path / "pairs.txt").write_text("".join(f"{names[i % 2]} {names[1 - i % 2]}\n"
                                                for i in range(60)))  # fmt: skip
    args = ["pairs", "pairs.txt", str(DATA), "--K", K_TEXT, "-o", "out.jsonl",
            "--workers", workers, "--max-features", "600"]  # fmt: skip
    code, err = _interrupt(args, tmp_path, " pairs, ", signum)
    assert code == 128 + signum, err
    assert err.strip().splitlines()[-1] == "ppo-cv pairs: interrupted; unfinished output removed"
    assert "Traceback" not in err and "SIGTERM" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pairs.txt"]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_interrupted_synth_leaves_no_staging_folder(tmp_path, signum):
    args = ["synth", "out", "--pairs", "40", "--workers", "2", "--width", "96", "--height", "72",
            "--supersample", "1"]  # fmt: skip
    # SIGTERM as soon as the staging folder exists; Ctrl-C once the workers have started
    code, err = _interrupt(args, tmp_path, None if signum == signal.SIGTERM else " pairs, ", signum)
    assert code == 128 + signum, err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_interrupted_sfm_leaves_no_database_or_model(tmp_path):
    images = tmp_path / "images"
    images.mkdir()
    for image in (DEMO1, DEMO2):
        shutil.copy(image, images)
    args = ["sfm", "images", "model", "--K", K_TEXT, "--database", "db.db", "--threads", "1"]
    code, err = _interrupt(args, tmp_path, "extracting", signal.SIGTERM)
    assert code == 143, err
    assert "Traceback" not in err and "SIGTERM" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["images"]


def test_overwrite_replaces_a_pair_output_as_a_whole(tmp_path):
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "points.ply").write_text("OLD\n")
    (tmp_path / "t" / "stale.txt").write_text("old run\n")
    out = subprocess.run([*COMMAND, *PAIR, "--out", "t", "--overwrite", "--json"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert sorted(p.name for p in (tmp_path / "t").iterdir()) == [
        "colmap", "matches.png", "points.ply", "result.json",
    ]  # fmt: skip
    assert (tmp_path / "t" / "points.ply").read_bytes().startswith(b"ply\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t"]


def test_implausible_intrinsics_warn():
    """A focal length of 1 px gives no pose here (the pose it fits sees its inliers from
    directions 138 degrees apart): the one line of the failure still names the doubtful K."""
    out = subprocess.run([*COMMAND, "pair", DEMO1, DEMO2, "--K", "1,2,-400,247.6", "--json"],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    lines = out.stderr.splitlines()
    assert out.returncode == 1 and len(lines) == 1 and lines[0].startswith("ppo-cv pair: no pose")
    assert "; warning: --K looks implausible" in lines[0]
    assert "focal length fx=1 fy=2 px is outside 0.1..10 x 640 px" in lines[0]
    assert "principal point (-400, 247.6) is outside the 640x480 image" in lines[0]
    assert out.stdout == ""


def test_intrinsics_in_units_of_the_image_size_get_their_pixel_values():
    """A camera given as fractions of the image size, as some datasets store it, gives the demo
    pair a rotation of 0.8 degrees for 10.9, or no pose; the warning gives the pixel values."""
    from ppo_cv.cli.common import implausible_intrinsics

    normalised = [[0.8366, 0, 0.5002], [0, 1.1233, 0.5158], [0, 0, 1]]
    warning = implausible_intrinsics(normalised, (640, 480))
    assert warning is not None
    assert warning.endswith("(in units of the image size? in pixels fx,fy,cx,cy are "
                            "535.424,539.184,320.128,247.584)")  # fmt: skip
    for K in ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[1, 0, 320], [0, 1, 240], [0, 0, 1]]):
        assert "in units of the image size" not in implausible_intrinsics(K, (640, 480))


def test_camera_of_the_image_turned_a_quarter_is_named():
    from ppo_cv.cli.common import implausible_intrinsics

    warning = implausible_intrinsics([[525, 0, 239.5], [0, 525, 319.5], [0, 0, 1]], (640, 480))
    assert warning is not None and "is the centre of a 480x640 image" in warning
    for K in (
        [[525, 0, 319.5], [0, 525, 239.5], [0, 0, 1]],
        [[525, 0, 250], [0, 525, 250], [0, 0, 1]],
    ):
        assert implausible_intrinsics(K, (640, 480)) is None
    assert implausible_intrinsics([[525, 0, 251], [0, 525, 250], [0, 0, 1]], (500, 501)) is None


# --- the helpers behind it, in process ------------------------------------------------------


def test_atomic_file_appears_only_when_complete(tmp_path):
    from ppo_cv.atomic import atomic_file

    target = tmp_path / "out.jsonl"
    with pytest.raises(KeyboardInterrupt), atomic_file(target) as handle:
        handle.write("half\n")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with atomic_file(target) as handle:
        handle.write("whole\n")
        assert not target.exists()
    assert target.read_text() == "whole\n" and list(tmp_path.iterdir()) == [target]
    with pytest.raises(ValueError, match="already exists; pass --overwrite"):
        with atomic_file(target):
            pass
    with atomic_file(target, overwrite=True) as handle:
        handle.write("new\n")
    assert target.read_text() == "new\n" and list(tmp_path.iterdir()) == [target]


def test_atomic_directory_replaces_only_when_asked_and_complete(tmp_path):
    from ppo_cv.atomic import atomic_directory

    target = tmp_path / "out"
    target.mkdir()
    (target / "old.txt").write_text("old")
    with pytest.raises(ValueError, match="not an empty directory; pass --overwrite"):
        with atomic_directory(target):
            pass
    with pytest.raises(RuntimeError), atomic_directory(target, overwrite=True) as staging:
        (staging / "new.txt").write_text("new")
        raise RuntimeError("failed midway")
    assert [p.name for p in target.iterdir()] == ["old.txt"]
    with atomic_directory(target, overwrite=True) as staging:
        (staging / "new.txt").write_text("new")
    assert [p.name for p in target.iterdir()] == ["new.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_deferred_block_holds_a_signal_that_another_thread_receives():
    import threading

    from ppo_cv.atomic import _raise_interrupt, signals_deferred

    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        finished = False
        with pytest.raises(KeyboardInterrupt, match="signal 15"), signals_deferred():
            # the main thread blocks SIGTERM, so the kernel hands it to this thread
            sender = threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGTERM))
            sender.start()
            sender.join()
            time.sleep(0.05)  # bytecode runs: Python's handler is called meanwhile
            finished = True
        assert finished
        with signals_deferred():  # nothing is left over for the next block
            pass
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_worker_pool_is_stopped_on_an_interrupt():
    from ppo_cv.atomic import _raise_interrupt, worker_pool

    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt), worker_pool(2, os.getpid) as pool:
            assert pool.map(abs, [-3, 2, -1, 0]) == [3, 2, 1, 0]
            workers = list(pool.processes)
            assert all(worker.is_alive() for worker in workers)
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1.0)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert len(workers) == 2 and not any(worker.is_alive() for worker in workers)


def test_worker_pool_names_a_worker_that_died():
    from ppo_cv.atomic import worker_pool

    with pytest.raises(ChildProcessError, match=r"a worker process died \(exit 3\)"):
        with worker_pool(2, os.getpid) as pool:
            pool.map(os._exit, [3, 3])
    with worker_pool(2, os.getpid) as pool:  # an exception in a job comes back as itself
        with pytest.raises(ValueError, match="invalid literal"):
            pool.map(int, ["1", "x"])


def test_no_signal_after_the_interrupt_was_handled():
    from ppo_cv.atomic import _raise_interrupt, stop_listening

    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)}
    try:
        signal.signal(signal.SIGTERM, _raise_interrupt)
        signal.signal(signal.SIGALRM, _raise_interrupt)
        signal.setitimer(signal.ITIMER_REAL, 0.02)  # as armed during a worker launch
        stop_listening()
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.1)
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


# --- issue 44: a batch goes on past bad images; folders with bad images; resized calibrations


def _demo_rotation_error(row: dict) -> float:
    from ppo_cv.metrics import rotation_error_deg

    return rotation_error_deg(np.array(row["R"]), np.array(DEMO["reference_R"]))


@pytest.mark.parametrize("cache", [["--workers", "1"], ["--workers", "2"], ["--no-cache"]])
def test_bad_images_in_a_batch_are_failed_lines(tmp_path, cache):
    _images(tmp_path)
    for image in (DEMO1, DEMO2):
        shutil.copy(image, tmp_path)
    demo1, demo2 = Path(DEMO1).name, Path(DEMO2).name
    firsts = [demo1, "const16.png", "thin.png", "trunc.png", "huge.tif", demo1]
    (tmp_path / "pairs.txt").write_text("".join(f"{a} {demo2} {INTRINSICS}\n" for a in firsts))
    out = subprocess.run([*COMMAND, "pairs", "-q", "pairs.txt", ".", *cache], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines() == [
        "ppo-cv pairs: warning: pairs.txt: line 6 (= 1) repeats an earlier line; each runs again "
        "and gives its own JSON line",
        "ppo-cv pairs: warning: 4 of 6 pairs failed",
    ]
    rows = [json.loads(line) for line in out.stdout.splitlines()]
    assert [row["image1"] for row in rows] == firsts
    assert _demo_rotation_error(rows[0]) < 1.0 and rows[5]["R"] == rows[0]["R"]
    errors = [row["error"] for row in rows[1:5]]
    assert "too few features (0)" in errors[0]
    assert "is 60000x1 pixels: too small or too thin" in errors[1]
    assert "not a readable image" in errors[2] and "trunc.png" in errors[2]
    assert "huge.tif declares 30000x30000 pixels" in errors[3]


def test_an_unexpected_error_is_the_pair_s_line_named_by_its_type(monkeypatch):
    from ppo_cv.cli import batch

    def broken(*args, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr("ppo_cv.pipeline.estimate_pair", broken)
    row = {"image1": "a.png", "image2": "b.png", "K1": None, "K2": None, "T": None}
    given = (("error", "not a readable image: a.png"), ("file", ""))
    assert batch._pair_job((row, str(DATA), None, given, True))["error"] == given[0][1]
    fx, fy, cx, cy = DEMO["intrinsics"]
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    row = {**row, "image1": Path(DEMO1).name, "image2": Path(DEMO2).name, "K1": K, "K2": K}
    outcome = batch._pair_job((row, str(DATA), None, None, True))
    assert outcome["error"] == "ZeroDivisionError: float division by zero"


def test_sfm_names_the_images_it_skips(tmp_path):
    from ppo_cv.sfm import screen_images

    (tmp_path / "images").mkdir()
    shutil.copy(DEMO1, tmp_path / "images")
    (tmp_path / "images" / "huge.png").write_bytes(HEADERS["png"](30000, 30000))
    (tmp_path / "images" / "trunc.png").write_bytes(Path(DEMO1).read_bytes()[:20000])
    shutil.copy(DEMO2, tmp_path / "images" / NOT_UTF8)  # pycolmap takes names as UTF-8 only
    kept, skipped = screen_images(tmp_path / "images")
    assert kept == [Path(DEMO1).name] and list(skipped) == [NOT_UTF8, "huge.png", "trunc.png"]
    out = subprocess.run([*COMMAND, "sfm", "images", "model", "--K", K_TEXT], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 2
    assert re.fullmatch(
        r"ppo-cv sfm: need at least 2 images in 'images', found 1 \(3 skipped: the name "
        r"'bad\\xff\.png' is not valid UTF-8, which pycolmap cannot read; image too large: "
        r"images/huge\.png declares 30000x30000 pixels, above the limit [^;]*; not a readable "
        r"image: images/trunc\.png\)\n",
        out.stderr,
    ), out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["images"]


def _half_camera() -> tuple[float, float, float, float]:
    """The demo camera for the images halved (pixel centres kept: c' = (c + 0.5) / 2 - 0.5)."""
    fx, fy, cx, cy = DEMO["intrinsics"]
    return fx / 2, fy / 2, (cx + 0.5) / 2 - 0.5, (cy + 0.5) / 2 - 0.5


def _half_calibration(root: Path, kind: str) -> Path:
    fx, fy, cx, cy = _half_camera()
    if kind == "colmap":
        path = root / "cameras.txt"
        path.write_text(f"1 PINHOLE 320 240 {fx} {fy} {cx + 0.5} {cy + 0.5}\n")  # COLMAP's pixels
    elif kind == "json":
        path = root / "camera.json"
        path.write_text(json.dumps({"fx": fx, "fy": fy, "cx": cx, "cy": cy, "width": 320,
                                    "height": 240}))  # fmt: skip
    else:
        path = root / "camera.yml"
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        storage.write("image_width", 320)
        storage.write("image_height", 240)
        storage.write("camera_matrix", np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]))
        storage.release()
    return path


@pytest.mark.parametrize("kind", ["colmap", "yaml", "json"])
def test_a_calibration_of_resized_images_is_scaled_to_the_truth(tmp_path, kind):
    calib = _half_calibration(tmp_path, kind)
    out = subprocess.run([*COMMAND, *PAIR[:3], "--calib", calib.name, "--json"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines() == [  # one line for the two images, as pairs gives
        f"ppo-cv pair: warning: --calib {calib.name} describes a camera of 320x240 images: its "
        f"camera matrix scaled by 2 to {DEMO1} and {DEMO2}, 640x480 pixels",
    ]
    row = json.loads(out.stdout)
    fx, fy, cx, cy = DEMO["intrinsics"]
    K_row = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    np.testing.assert_allclose(row["cameras"]["K1"], K_row, atol=1e-9)
    assert _demo_rotation_error(row) < 1.0


def test_pairs_scales_a_calibration_of_resized_images_to_the_truth(tmp_path):
    calib = _half_calibration(tmp_path, "yaml")
    (tmp_path / "images").mkdir()
    for image in (DEMO1, DEMO2):
        shutil.copy(image, tmp_path / "images")
    (tmp_path / "pairs.txt").write_text(f"{DEMO['image1']} {DEMO['image2']}\n")
    out = subprocess.run([*COMMAND, "pairs", "pairs.txt", "images", "--calib", calib.name, "-q"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines() == [
        f"ppo-cv pairs: warning: --calib {calib.name} describes a camera of 320x240 images: its "
        f"camera matrix scaled by 2 to {DEMO['image1']}, 640x480 pixels (and 1 more images)"
    ]
    row = json.loads(out.stdout)
    fx, fy, cx, cy = DEMO["intrinsics"]
    K_row = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    np.testing.assert_allclose(row["cameras"]["K1"], K_row, atol=1e-9)
    assert _demo_rotation_error(row) < 1.0


def test_the_unscaled_calibration_of_resized_images_is_wrong():
    """What the scaling above corrects: the camera of 320x240 images applied as it is."""
    half = ",".join(str(v) for v in _half_camera())
    out = subprocess.run([*COMMAND, *PAIR[:3], "--K", half, "--json"], capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert _demo_rotation_error(json.loads(out.stdout)) > 2.0


@pytest.mark.parametrize(
    "error, message",
    [
        (OSError(1, "Operation not permitted", "/sys/.out.4242.ab_c9xyz"),
         "cannot write /sys/out: Operation not permitted"),
        (OSError(28, "No space left on device", "/d/.poses.jsonl.old.k2j4h5g6"),
         "cannot write /d/poses.jsonl: No space left on device"),
        (PermissionError(13, "Permission denied", "/data/a.png"), "Permission denied: /data/a.png"),
        (OSError(28, "No space left on device"), "No space left on device"),
        (ValueError("image not found: a.png"), "image not found: a.png"),
        (ValueError(), "ValueError"),
    ],
)  # fmt: skip
def test_a_failure_names_the_path_given_not_the_hidden_one_it_was_built_under(error, message):
    from ppo_cv.cli.common import error_message

    assert error_message(error) == message


@pytest.mark.parametrize("others", [[], [DEMO2]], ids=["copies alone", "with another view"])
def test_sfm_skips_a_copy_of_an_image_naming_the_original(tmp_path, others):
    """Two copies of one photo read as a pure rotation: the folder was called a panorama
    holding no structure; beside another view, the copy was registered as a view of its own."""
    (tmp_path / "images").mkdir()
    for name, source in [("a.png", DEMO1), ("b.png", DEMO1), *(("c.png", o) for o in others)]:
        shutil.copy(source, tmp_path / "images" / name)
    out = subprocess.run([*COMMAND, "sfm", "images", "model", "--K", K_TEXT, "-q"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    reason = "images/b.png is a copy of a.png: the same bytes"
    if not others:
        assert out.returncode == 2
        assert out.stderr == (
            f"ppo-cv sfm: need at least 2 images in 'images', found 1 (1 skipped: {reason})\n"
        )
        return
    assert out.returncode == 0, out.stderr
    assert out.stderr == f"ppo-cv sfm: warning: skipping an image: {reason}\n"
    assert out.stdout.startswith("registered 2/2 images")
    model = pycolmap.Reconstruction(tmp_path / "model")
    assert sorted(image.name for image in model.images.values()) == ["a.png", "c.png"]


def test_the_summary_names_a_file_holding_a_line_break_on_its_first_line(tmp_path):
    shutil.copy(DEMO1, tmp_path / "one\ntwo.png")
    out = subprocess.run([*COMMAND, "pair", "one\ntwo.png", DEMO2, "--K", K_TEXT, "-q"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == f"one\\ntwo.png -> {DEMO2}"
    assert lines[1].startswith("  verdict      general motion")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_pairs_with_a_calibration_and_a_fifo_among_the_images_does_not_hang(tmp_path):
    # fitting the calibration to each image's size opened the FIFO and waited for a writer
    shutil.copy(DEMO1, tmp_path / "a.png")
    shutil.copy(DEMO2, tmp_path / "b.png")
    os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "pairs.txt").write_text("a.png b.png\na.png fifo.png\n")
    (tmp_path / "cameras.txt").write_text("1 PINHOLE 640 480 " + K_TEXT.replace(",", " ") + "\n")
    out = subprocess.run([*COMMAND, "pairs", "-q", "pairs.txt", ".", "--calib", "cameras.txt"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines() == ["ppo-cv pairs: warning: 1 of 2 pairs failed"]
    rows = [json.loads(line) for line in out.stdout.splitlines()]
    assert "R" in rows[0] and "not a regular file" in rows[1]["error"]
