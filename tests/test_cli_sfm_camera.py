"""``ppo-cv sfm --K`` with a camera that does not fit the images warns as ``ppo-cv pair`` does:
after the run, beside the summary, and on the one line of a failure."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

from ppo_cv import sfm
from ppo_cv.cli.main import app

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
FAR_OFF = "525,525,1920,240"  # cx three times the 640 px width
DOUBT = (
    "warning: --K looks implausible for a 640x480 image: principal point (1920, 240) is "
    "outside the 640x480 image"
)


def _model(image_dir, output_dir, progress, **settings):
    progress("mapping")
    return SimpleNamespace(
        initial_pair=(DEMO["image1"], DEMO["image2"]), mean_reprojection_error=0.5,
        initialization="ppo", num_registered=2, num_images=2, num_points3D=40, num_models=1,
        elapsed=1.0,
    )  # fmt: skip


def _no_model(image_dir, output_dir, progress, **settings):
    progress("mapping")
    raise sfm.ReconstructionFailed("no image pair qualifies as an initial pair")


def _run(tmp_path, monkeypatch, run_sfm, K, *options):
    monkeypatch.setattr(sfm, "run_sfm", run_sfm)
    images = tmp_path / "images"
    if not images.exists():
        images.mkdir()
        for name in (DEMO["image1"], DEMO["image2"]):
            (images / name).write_bytes((DATA / name).read_bytes())
    return CliRunner().invoke(app, ["sfm", str(images), str(tmp_path / "model"), "--K", K,
                                    *options])  # fmt: skip


def test_a_far_off_principal_point_is_warned_of_beside_the_model(tmp_path, monkeypatch):
    run = _run(tmp_path, monkeypatch, _model, FAR_OFF)
    lines = run.stderr.splitlines()
    assert run.exit_code == 0 and "registered 2/2 images" in run.stdout
    assert lines.count(f"ppo-cv sfm: {DOUBT}") == 1
    assert lines.index("ppo-cv sfm: mapping") < lines.index(f"ppo-cv sfm: {DOUBT}")


def test_a_far_off_principal_point_is_named_on_the_line_of_a_failure(tmp_path, monkeypatch):
    run = _run(tmp_path, monkeypatch, _no_model, FAR_OFF, "--quiet")
    assert run.exit_code == 1 and run.stdout == ""
    assert run.stderr.splitlines() == [
        f"ppo-cv sfm: no image pair qualifies as an initial pair; {DOUBT}"
    ]


@pytest.mark.parametrize("run_sfm", [_model, _no_model])
def test_a_camera_that_fits_is_no_warning(tmp_path, monkeypatch, run_sfm):
    run = _run(tmp_path, monkeypatch, run_sfm, "525,525,319.5,239.5", "--quiet")
    assert "warning" not in run.stderr and run.exit_code == (0 if run_sfm is _model else 1)


def test_a_camera_of_the_pixels_as_stored_names_the_exif_orientation(tmp_path, monkeypatch):
    """Photos stored turned a quarter (EXIF orientation 6) are read upright, 640x480; a camera
    of their stored pixels (principal point at the centre of 480x640) is named as such."""
    from PIL import Image

    (tmp_path / "images").mkdir()
    for name in (DEMO["image1"], DEMO["image2"]):
        exif = Image.Exif()
        exif[0x0112] = 6
        stored = Image.open(DATA / name).convert("RGB").transpose(Image.Transpose.ROTATE_90)
        stored.save(tmp_path / "images" / f"{Path(name).stem}.jpg", exif=exif.tobytes())
    run = _run(tmp_path, monkeypatch, _no_model, "525,525,239.5,319.5", "--quiet")
    assert run.exit_code == 1
    assert run.stderr.strip().endswith(
        "warning: --K looks implausible for a 640x480 image: principal point (239.5, 319.5) is "
        "the centre of a 480x640 image: a camera for the pixels as stored, where the EXIF "
        "orientation turns the image upright (--no-exif-orientation reads them as stored)?"
    )
