"""What a new user meets first, through the installed command: ``pairs`` without intrinsics,
``sfm`` on photos of several sizes and when nothing can be built, the verdict line of the
summary, and photos whose EXIF is stale or belongs to a larger original."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from ppo_cv.metrics import direction_error_deg, rotation_error_deg

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
DEMO1, DEMO2 = DATA / DEMO["image1"], DATA / DEMO["image2"]
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
FX, FY, CX, CY = DEMO["intrinsics"]
K_MATRIX = np.array([[FX, 0.0, CX], [0.0, FY, CY], [0.0, 0.0, 1.0]])
COLMAP_CAMERA = f"1 PINHOLE 640 480 {FX} {FY} {CX + 0.5} {CY + 0.5}\n"  # COLMAP's pixel centres
EXE = shutil.which("ppo-cv")
COMMAND = [EXE] if EXE else [sys.executable, "-m", "ppo_cv.cli.main"]


def ppo_cv(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([*COMMAND, *map(str, args)], capture_output=True, text=True,
                          timeout=300, cwd=cwd)  # fmt: skip


def warnings_of(done: subprocess.CompletedProcess) -> list[str]:
    return [line for line in done.stderr.splitlines() if ": warning: " in line]


def check_demo_pose(data: dict, rotation_deg: float = 1.0, direction_deg: float = 3.0) -> None:
    assert rotation_error_deg(np.array(data["R"]), np.array(DEMO["reference_R"])) < rotation_deg
    t, t_ref = np.array(data["t"]), np.array(DEMO["reference_t"])
    assert direction_error_deg(t, t_ref, signed=False) < direction_deg


def photo(source: Path, path: Path, *, orientation: int = 1, focal_35mm: int | None = 28,
          recorded_size: tuple[int, int] | None = None, exif: bool = True) -> None:  # fmt: skip
    """``source`` saved as a JPEG with the EXIF a camera writes: the orientation (6: pixels
    stored turned a quarter), a 35 mm equivalent focal length and the recorded pixel size."""
    from PIL import Image

    image = Image.open(source).convert("RGB")
    if orientation == 6:
        image = image.transpose(Image.Transpose.ROTATE_90)
    if not exif:
        image.save(path, quality=95)
        return
    tags = Image.Exif()
    tags[0x010F], tags[0x0110], tags[0x0112] = "Maker", "Model", orientation
    sub = tags.get_ifd(0x8769)
    if focal_35mm is not None:
        sub[0xA405] = focal_35mm
    if recorded_size is not None:
        sub[0xA002], sub[0xA003] = recorded_size
    image.save(path, quality=95, exif=tags.tobytes())


# --- 1. pairs: intrinsics from EXIF, --K2, --calib, the file format in --help ----------------


def test_pairs_without_intrinsics_takes_the_cameras_pair_takes(tmp_path):
    for source, name in ((DEMO1, "a.jpg"), (DEMO2, "b.jpg")):
        photo(source, tmp_path / name)
    (tmp_path / "pairs.txt").write_text("a.jpg b.jpg\n")
    pairs = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--workers", "1", "--quiet")
    assert pairs.returncode == 0, pairs.stderr
    (row,) = [json.loads(line) for line in pairs.stdout.splitlines()]
    pair = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--json")
    assert pair.returncode == 0, pair.stderr
    single = json.loads(pair.stdout)
    np.testing.assert_allclose(row["cameras"]["K1"], single["cameras"]["K1"])
    # the EXIF focal, not the size guess
    assert row["cameras"]["K1"][0][0] != pytest.approx(1.2 * 640)
    check_demo_pose(row, 2.0, 6.0)
    (warning,) = warnings_of(pairs)
    assert "no intrinsics given for 1 of 1 pairs" in warning
    assert "EXIF focal lengths of 2 of 2 images" in warning


def test_pairs_takes_a_calibration_file_and_a_second_camera(tmp_path):
    (tmp_path / "pairs.txt").write_text(f"{DEMO1.name} {DEMO2.name}\n")
    calib = tmp_path / "cameras.txt"
    calib.write_text(COLMAP_CAMERA)
    runs = {
        "calib": ("--calib", calib),
        "K2": ("--K", K_TEXT, "--K2", K_TEXT),
    }
    for name, options in runs.items():
        done = ppo_cv("pairs", tmp_path / "pairs.txt", DATA, *options, "--workers", "1", "-q")
        assert done.returncode == 0, done.stderr
        (row,) = [json.loads(line) for line in done.stdout.splitlines()]
        np.testing.assert_allclose(row["cameras"]["K2"], K_MATRIX, err_msg=name)
        check_demo_pose(row)
        assert warnings_of(done) == []
    done = ppo_cv("pairs", tmp_path / "pairs.txt", DATA, "--K2", K_TEXT)
    assert done.returncode == 2 and "--K2 needs --K" in done.stderr


def test_pairs_takes_one_camera_for_a_photo_stored_turned_as_pair_does(tmp_path):
    """A photo stored sideways with an EXIF orientation is read upright, the size of its
    partner: ``pairs --K`` runs it, as ``pair --K`` does, rather than refuse two sizes."""
    photo(DEMO1, tmp_path / "a.jpg")
    photo(DEMO2, tmp_path / "b.jpg", orientation=6)
    (tmp_path / "pairs.txt").write_text("a.jpg b.jpg\n")
    done = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--K", K_TEXT, "--workers", "1",
                  "-q")  # fmt: skip
    assert done.returncode == 0, done.stderr
    (row,) = [json.loads(line) for line in done.stdout.splitlines()]
    check_demo_pose(row)
    stored = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--K", K_TEXT,
                    "--no-exif-orientation")  # fmt: skip
    assert stored.returncode == 2
    assert "b.jpg 480x640 pixels: one camera matrix (--K) cannot fit" in stored.stderr


@pytest.mark.parametrize("suffix", [".jpg", ".png", ".tif"])
def test_the_header_size_is_the_stored_one_whatever_the_format(tmp_path, suffix):
    """Pillow reports a TIFF's size turned by its orientation tag, other formats' as stored:
    turned once more as EXIF says, the TIFF's size came out sideways and ``pairs --K`` refused
    a TIFF stored turned beside a PNG of the same view."""
    from PIL import Image

    from ppo_cv.images import image_size

    tags = Image.Exif()
    tags[0x0112] = 6
    turned = Image.open(DEMO1).convert("RGB").transpose(Image.Transpose.ROTATE_90)
    turned.save(tmp_path / f"a{suffix}", exif=tags.tobytes())
    assert image_size(tmp_path / f"a{suffix}") == (480, 640)
    shutil.copy(DEMO2, tmp_path / "b.png")
    (tmp_path / "pairs.txt").write_text(f"a{suffix} b.png\n")
    done = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--K", K_TEXT, "-q")
    assert done.returncode == 0, done.stderr
    (row,) = [json.loads(line) for line in done.stdout.splitlines()]
    check_demo_pose(row)


def test_pairs_scales_a_calibration_that_states_its_size_as_pair_does(tmp_path):
    """A calibration stating its image size is scaled to each image of its aspect ratio (a
    half-size copy here) in ``pairs`` as in ``pair``; one that states none is refused for two
    sizes, the message naming the file rather than ``--K``."""
    cv2.imwrite(str(tmp_path / "a.png"), cv2.imread(str(DEMO1)))
    half = cv2.resize(cv2.imread(str(DEMO2)), (320, 240), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(tmp_path / "b.png"), half)
    (tmp_path / "pairs.txt").write_text("a.png b.png\n")
    sized = tmp_path / "cameras.txt"
    sized.write_text(COLMAP_CAMERA)
    done = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--calib", sized, "-q")
    assert done.returncode == 0, done.stderr
    (row,) = [json.loads(line) for line in done.stdout.splitlines()]
    single = ppo_cv("pair", tmp_path / "a.png", tmp_path / "b.png", "--calib", sized, "--json")
    assert single.returncode == 0, single.stderr
    np.testing.assert_allclose(row["cameras"]["K2"], json.loads(single.stdout)["cameras"]["K2"])
    np.testing.assert_allclose(np.array(row["cameras"]["K2"])[0, 0], FX / 2)
    unsized = tmp_path / "camera.json"
    unsized.write_text(json.dumps({"K": DEMO["intrinsics"]}))
    refused = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--calib", unsized)
    assert refused.returncode == 2
    assert f"one camera matrix (--calib {unsized}) cannot fit both sizes" in refused.stderr


def test_pairs_help_documents_the_file_format():
    done = ppo_cv("pairs", "--help")
    assert done.returncode == 0
    text = " ".join(done.stdout.split())
    assert "'0 0'" in text and "ground-truth motion T_1to2" in text
    assert "EXIF focal length" in text


# --- 2. sfm: images of several sizes, the cause of a failure, the database kept ---------------


def test_sfm_reconstructs_images_of_two_sizes_with_a_camera_each(tmp_path):
    import pycolmap

    images = tmp_path / "images"
    images.mkdir()
    shutil.copy(DEMO1, images / "a.png")
    shutil.copy(DEMO2, images / "b.png")
    smaller = cv2.resize(cv2.imread(str(DEMO2)), (512, 384), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(images / "c.png"), smaller)
    done = ppo_cv("sfm", images, tmp_path / "model", "--threads", "1", "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("registered 3/3 images")
    model = pycolmap.Reconstruction(tmp_path / "model")
    sizes = {(c.width, c.height) for c in model.cameras.values()}
    assert sizes == {(640, 480), (512, 384)}
    assert len(model.cameras) == 3  # PNGs hold no EXIF focal length: a camera per image
    with_K = ppo_cv("sfm", images, tmp_path / "other", "--K", K_TEXT)
    assert with_K.returncode == 2 and not (tmp_path / "other").exists()
    assert "the images have 2 sizes" in with_K.stderr and "omit --K" in with_K.stderr


def test_sfm_says_why_nothing_was_built_and_keeps_the_database(tmp_path):
    import pycolmap

    images = tmp_path / "images"
    images.mkdir()
    K = K_MATRIX
    angle = np.radians(6.0)
    R = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    first = cv2.imread(str(DEMO1))
    cv2.imwrite(str(images / "a.png"), first)
    turned = cv2.warpPerspective(first, K @ R @ np.linalg.inv(K), (640, 480))
    cv2.imwrite(str(images / "b.png"), turned)  # a pure rotation: no pair can start a model
    done = ppo_cv("sfm", "images", "model", "--K", K_TEXT, "--database", "db.db", "--threads",
                  "1", "--quiet", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 1
    (line,) = done.stderr.splitlines()
    assert line.startswith("ppo-cv sfm: the 2 images look like a panorama (pure rotations ")
    assert "hold no structure to reconstruct: of 1 matched pair, 1 pure rotation" in line
    assert "db.db" in line
    assert "score_pairs" not in done.stderr and "Traceback" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["db.db", "images"]
    with pycolmap.Database.open(tmp_path / "db.db") as database:
        assert database.num_images() == 2


# --- 3. the verdict line names the deciding test ---------------------------------------------


def _lines(summary: str) -> dict[str, str]:
    return {line[:15].strip(): line[15:] for line in summary.splitlines()[1:]}


@pytest.mark.parametrize(
    "options, pri_side, decided_by",
    [
        ((), "(at or above the threshold 0.015)", "decided by GRIC"),
        # PRI alone would call the demo pair a rotation; GRIC overrules it
        (("--pri-threshold", "0.5"), "(below the threshold 0.5; not the deciding test, see "
         "verdict)", "decided by GRIC"),
    ],
)  # fmt: skip
def test_verdict_names_the_test_that_decided(options, pri_side, decided_by):
    done = ppo_cv("pair", DEMO1, DEMO2, "--K", K_TEXT, *options)
    assert done.returncode == 0, done.stderr
    lines = _lines(done.stdout)
    assert lines["verdict"].startswith("general motion (translation determined); " + decided_by)
    assert lines["PRI"].endswith(pri_side)
    assert "general motion" not in lines["PRI"]


def test_a_pure_rotation_summary_says_why_t_and_the_homography_read_as_they_do(tmp_path):
    """A pure rotation's summary showed ``t sigma 90.00 deg`` and a homography that a plane
    "explains better" (negative GRIC difference) without a word: a newcomer read a plane and
    an error of 90 degrees. Both lines now say that this is what a rotation gives."""
    from ppo_cv.data_gen import make_pair

    pair = make_pair("pure-rotation", seed=0, index=0, size=(320, 240))
    names = [tmp_path / "1.png", tmp_path / "2.png"]
    for name, image in zip(names, (pair.image1, pair.image2), strict=True):
        cv2.imwrite(str(name), image[..., ::-1])
    K = pair.K1
    done = ppo_cv("pair", *names, "--K", f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}", "--quiet")
    assert done.returncode == 0, done.stderr
    lines = _lines(done.stdout)
    assert lines["verdict"].startswith("pure rotation (translation undetermined")
    assert lines["t sigma"] == (
        "90.00 deg (direction of t, one standard deviation; undetermined for a pure rotation)"
    )
    assert lines["homography"].endswith(", as for any rotation: its matches fit a homography")
    general = _lines(ppo_cv("pair", DEMO1, DEMO2, "--K", K_TEXT, "--quiet").stdout)
    assert general["t sigma"].endswith("deg (direction of t, one standard deviation)")
    assert general["homography"].endswith(" per match")


def test_the_homography_remark_comes_only_where_the_plane_looks_better():
    """A tripod pair whose homography GRIC rates worse than the essential matrix (positive
    difference) needs no remark: the line is as for a general pair."""
    import dataclasses

    from ppo_cv import estimate_pair
    from ppo_cv.cli.pair import _plane_lines

    result = estimate_pair(str(DEMO1), str(DEMO2), K_MATRIX)
    assert result.evidence.selection.gric_plane_difference > 0
    called_rotation = dataclasses.replace(result, pure_rotation=True)
    assert _plane_lines(called_rotation) == _plane_lines(result)
    assert _plane_lines(result)[0].endswith(" per match")


@pytest.mark.parametrize("order", [("pairs.txt", "images"), ("images", "pairs.txt")])
def test_pair_given_a_pairs_file_and_a_folder_names_the_pairs_command(tmp_path, order):
    """``ppo-cv pair pairs.txt images`` (the arguments of ``pairs``) answered only that
    ``images`` is a directory."""
    (tmp_path / "images").mkdir()
    shutil.copy(DEMO1, tmp_path / "images")
    (tmp_path / "pairs.txt").write_text(f"{DEMO1.name} {DEMO1.name}\n")
    done = ppo_cv("pair", *order, "--K", K_TEXT, cwd=tmp_path)
    assert (done.returncode, done.stdout) == (2, "")
    assert done.stderr == (
        "ppo-cv pair: images is a folder and pairs.txt no image: 'pair' takes two images; a "
        "pairs file and an image folder are run by ppo-cv pairs pairs.txt images\n"
    )


# --- 4. EXIF: orientation on or off, doubtful focal lengths, the wording -----------------------


def test_no_exif_orientation_reads_the_pixels_as_stored(tmp_path):
    """A stale tag: pixels stored upright, the EXIF saying they are turned a quarter."""
    for source, name in ((DEMO1, "a.jpg"), (DEMO2, "b.jpg")):
        photo(source, tmp_path / name, orientation=8)
    shown = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--json")
    stored = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--json",
                    "--no-exif-orientation")  # fmt: skip
    assert stored.returncode == 0, stored.stderr
    data = json.loads(stored.stdout)
    np.testing.assert_allclose(np.array(data["cameras"]["K1"])[:2, 2], [320.0, 240.0])
    check_demo_pose(data, 2.0, 6.0)
    assert shown.returncode != 0 or json.loads(shown.stdout)["cameras"]["K1"][0][
        2
    ] == pytest.approx(240.0)
    (tmp_path / "pairs.txt").write_text("a.jpg b.jpg\n")
    pairs = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--no-exif-orientation",
                   "--workers", "1", "-q")  # fmt: skip
    (row,) = [json.loads(line) for line in pairs.stdout.splitlines()]
    assert rotation_error_deg(np.array(row["R"]), np.array(data["R"])) < 0.5


def test_exif_of_a_cropped_photo_and_an_implausible_field_warn(tmp_path):
    photo(DEMO1, tmp_path / "a.jpg", recorded_size=(4032, 2268))
    photo(DEMO2, tmp_path / "b.jpg", focal_35mm=400)
    photo(DEMO1, tmp_path / "c.jpg", recorded_size=(4032, 3024))  # resized: its 35 mm fits
    done = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--json")
    warnings = warnings_of(done)
    assert any("a.jpg: the EXIF says the photo was 4032x2268 pixels, the image is 640x480, "
               "another aspect ratio (cropped?)" in w for w in warnings)  # fmt: skip
    resized = warnings_of(ppo_cv("pair", tmp_path / "c.jpg", tmp_path / "b.jpg", "--json"))
    assert not any("c.jpg" in w for w in resized) and any("b.jpg" in w for w in resized)
    (field,) = [w for w in warnings if "field of view" in w]
    assert "b.jpg: the EXIF focal length" in field and "outside 15..120 deg" in field
    assert not any("a.jpg" in w and "field of view" in w for w in warnings)


def test_pairs_gives_one_line_for_photos_whose_exif_is_doubtful_alike(tmp_path):
    # a folder of one camera's photos gave one warning line per photo (10 on pano_dev's csie)
    for name in ("a.jpg", "b.jpg", "c.jpg", "d.jpg"):
        photo(DEMO1 if name != "b.jpg" else DEMO2, tmp_path / name, focal_35mm=400)
    photo(DEMO2, tmp_path / "e.jpg", focal_35mm=800)
    (tmp_path / "pairs.txt").write_text("a.jpg b.jpg\nb.jpg c.jpg\nc.jpg d.jpg\nd.jpg e.jpg\n")
    done = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--workers", "1", "-q")
    fields = [w for w in warnings_of(done) if "field of view" in w]
    assert len(fields) == 2, done.stderr
    assert fields[0].startswith(f"ppo-cv pairs: warning: 4 images in {tmp_path} (a.jpg, b.jpg, "
                                "c.jpg, ...): the EXIF focal length f=")  # fmt: skip
    assert fields[1].startswith(f"ppo-cv pairs: warning: {tmp_path / 'e.jpg'}: the EXIF focal")


def test_without_exif_the_wording_is_either_and_no_orientation_is_suggested(tmp_path):
    for source, name in ((DEMO1, "a.jpg"), (DEMO2, "b.jpg")):
        photo(source, tmp_path / name, exif=False)
    done = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--json")
    (warning,) = warnings_of(done)
    assert "no EXIF focal length in either image" in warning
    turned = "525,525,239.5,319.5"  # the camera of the image turned a quarter
    done = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--K", turned, "--json")
    (warning,) = warnings_of(done)
    assert "is the centre of a 480x640 image: a camera of the image turned a quarter?" in warning
    assert "EXIF" not in warning
    photo(DEMO1, tmp_path / "c.jpg", orientation=6)
    photo(DEMO2, tmp_path / "d.jpg", orientation=6)
    stored_camera = "525,525,240,320"  # that of the stored, sideways pixels
    done = ppo_cv("pair", tmp_path / "c.jpg", tmp_path / "d.jpg", "--K", stored_camera, "--json")
    (warning,) = warnings_of(done)
    assert "EXIF orientation turns the image upright" in warning


def test_sfm_reconstructs_photos_upright_unless_told_not_to(tmp_path):
    import pycolmap

    images = tmp_path / "images"
    images.mkdir()
    for source, name in ((DEMO1, "a.jpg"), (DEMO2, "b.jpg")):
        photo(source, images / name, orientation=6)
    sizes, warned = {}, {}
    for flag in ("--exif-orientation", "--no-exif-orientation"):
        out = tmp_path / flag.strip("-")
        done = ppo_cv("sfm", images, out, flag, "--threads", "1", "--quiet")
        assert done.returncode == 0, done.stderr
        warned[flag] = " ".join(warnings_of(done))
        model = pycolmap.Reconstruction(out)
        assert model.num_reg_images() == 2
        sizes[flag] = {(c.width, c.height) for c in model.cameras.values()}
    assert sizes == {"--exif-orientation": {(640, 480)}, "--no-exif-orientation": {(480, 640)}}
    assert sorted(p.name for p in images.iterdir()) == ["a.jpg", "b.jpg"]
    assert "COLMAP reads the pixels as stored" in warned["--exif-orientation"]
    assert "--no-exif-orientation" in warned["--exif-orientation"]
    assert "COLMAP reads" not in warned["--no-exif-orientation"]


def test_sfm_quotes_image_names_holding_spaces_in_its_summary(tmp_path):
    """``initial pair a b.png c.png`` read as three names; quoted as in initial_pairs.txt."""
    images = tmp_path / "images"
    images.mkdir()
    shutil.copy(DEMO1, images / "a b.png")
    shutil.copy(DEMO2, images / "c.png")
    done = ppo_cv("sfm", images, tmp_path / "model", "--K", K_TEXT, "--threads", "1")
    assert done.returncode == 0, done.stderr
    assert 'initial pair "a b.png" c.png (ppo)' in done.stdout
    assert 'ppo-cv sfm: seeding with "a b.png" c.png (two-view)' in done.stderr.splitlines()
    initial = (tmp_path / "model" / "initial_pairs.txt").read_text().splitlines()
    assert initial[1].startswith('"a b.png" c.png ')


def test_pair_out_says_its_colmap_model_is_of_photos_turned_upright(tmp_path):
    """The model's camera is the upright 640x480 one, while COLMAP (``pycolmap.Bitmap``) reads
    the stored 480x640 pixels: the model, read with the photos, was silently inconsistent."""
    import pycolmap

    photo(DEMO1, tmp_path / "a.jpg", orientation=6)
    photo(DEMO2, tmp_path / "b.jpg")
    done = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--K", K_TEXT,
                  "--out", tmp_path / "out", "-q")  # fmt: skip
    assert done.returncode == 0, done.stderr
    model = pycolmap.Reconstruction(tmp_path / "out" / "colmap")
    assert {(c.width, c.height) for c in model.cameras.values()} == {(640, 480)}
    stored = pycolmap.Bitmap.read(str(tmp_path / "a.jpg"), False)
    assert (stored.width, stored.height) == (480, 640)
    (warning,) = warnings_of(done)
    model_name = f"the COLMAP model {tmp_path / 'out'}/colmap"
    assert warning.startswith(f"ppo-cv pair: warning: {model_name} describes a.jpg as its EXIF "
                              "orientation turns it upright")  # fmt: skip
    assert "pass --no-exif-orientation" in warning
    without_out = ppo_cv("pair", tmp_path / "a.jpg", tmp_path / "b.jpg", "--K", K_TEXT, "-q")
    assert without_out.returncode == 0 and warnings_of(without_out) == []


# --- 5. a camera matrix of another image size ------------------------------------------------

K_OF_A_LARGER_COPY = ",".join(str(3 * v) for v in DEMO["intrinsics"])  # a 1920x1440 original


def test_pairs_warns_once_about_a_camera_of_another_image_size(tmp_path):
    (tmp_path / "pairs.txt").write_text(f"{DEMO1.name} {DEMO2.name}\n{DEMO2.name} {DEMO1.name}\n")
    done = ppo_cv("pairs", tmp_path / "pairs.txt", DATA, "--K", K_OF_A_LARGER_COPY,
                  "--workers", "1", "--quiet")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == [
        f"ppo-cv pairs: warning: {tmp_path / 'pairs.txt'}:1: --K looks implausible for a "
        "640x480 image: principal point (960.3, 742.8) is outside the 640x480 image "
        "(and 1 more line)"
    ]
    assert len(done.stdout.splitlines()) == 2


def test_pair_warns_about_such_a_camera_in_one_line_only():
    done = ppo_cv("pair", DEMO1, DEMO2, "--K", K_OF_A_LARGER_COPY, "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == [
        "ppo-cv pair: warning: --K looks implausible for a 640x480 image: principal point "
        "(960.3, 742.8) is outside the 640x480 image"
    ]


# --- 6. --dist with a calibration of one camera ---------------------------------------------


def test_dist_with_a_one_camera_calibration_describes_both_images_as_with_K(tmp_path):
    calibration = tmp_path / "camera.json"
    calibration.write_text(json.dumps({"fx": FX, "fy": FY, "cx": CX, "cy": CY}))
    cameras = {}
    for source in (["--K", K_TEXT], ["--calib", calibration]):
        done = ppo_cv("pair", DEMO1, DEMO2, *source, "--dist", "0.05,0,0,0", "--json")
        assert done.returncode == 0, done.stderr
        used = json.loads(done.stdout)["cameras"]
        cameras[source[0]] = (used["dist1"], used["dist2"])
    assert cameras["--calib"] == cameras["--K"] == ([0.05, 0, 0, 0], [0.05, 0, 0, 0])


def test_synth_names_the_images_folder_and_the_pairs_command_runs_as_printed(tmp_path):
    done = ppo_cv("synth", "render", "--pairs", "1", "--width", "160", "--height", "120",
                  "--supersample", "1", "-q", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    printed = done.stdout.strip().split("run them with: ppo-cv ")[1].split()
    assert printed == ["pairs", "render/pairs_with_gt.txt", "render/images"]
    run = ppo_cv(*printed, "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    (line,) = [json.loads(text) for text in run.stdout.splitlines()]
    assert line["image1"] == "pair_000_1.png" and "error" not in line, line


@pytest.mark.parametrize(
    "options, named",
    [(["--K", "600,600,320,240"], "--K is"),
     (["--K", "600,600,320,240", "--K2", "600,600,320,240"], "--K and --K2 are")],
)  # fmt: skip
def test_pairs_says_when_every_line_carries_the_cameras_given_on_the_command_line(
    tmp_path, options, named
):
    # the lines' own camera matrices stood and --K was dropped without a word
    intrinsics = " ".join(["0 0"] + [" ".join(map(str, K_MATRIX.ravel()))] * 2)
    (tmp_path / "pairs.txt").write_text(f"{DEMO1.name} {DEMO2.name} {intrinsics}\n")
    done = ppo_cv("pairs", "pairs.txt", DATA, "-q", *options, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert warnings_of(done) == [
        f"ppo-cv pairs: warning: {named} not used: every line of pairs.txt carries its own "
        "camera matrices, which stand"
    ]
    check_demo_pose(json.loads(done.stdout))


@pytest.mark.parametrize(
    "args, option, joined",
    [(["pair", DEMO1, DEMO2, "--K", FX, FY, CX, CY], "--K", K_TEXT),
     (["pair", DEMO1, DEMO2, "--K", K_TEXT, "--dist", "-0.1", "0.01", "0", "0"], "--dist",
      "-0.1,0.01,0,0"),
     (["pairs", "pairs.txt", "images", "--K", FX, FY, CX, CY], "--K", K_TEXT)],
    ids=["pair --K", "pair --dist", "pairs --K"],
)  # fmt: skip
def test_numbers_given_as_separate_arguments_get_the_comma_remedy(args, option, joined):
    # "Got unexpected extra argument(s) (539.2 320.1 247.6)" and nothing about --K
    done = ppo_cv(*args)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.endswith(
        f"; {option} takes its numbers as one argument, joined by commas: {option} {joined}\n"
    )
    assert done.stderr.count("\n") == 1


@pytest.mark.parametrize(
    "args, name",
    [
        (["pairs", "pairs.txt", ""], "'IMAGE_DIR'"),
        (["pairs", "", "."], "'PAIRS_FILE'"),
        (["pairs", "pairs.txt", ".", "-o", ""], "'--output' / '-o'"),
        (["pair", "", "b.png"], "'IMAGE1'"),
        (["pair", "a.png", "b.png", "--calib", ""], "'--calib'"),
        (["pair", "a.png", "b.png", "--out", ""], "'--out'"),
        (["sfm", "", "model"], "'IMAGE_DIR'"),
        (["sfm", ".", "model", "--database", ""], "'--database'"),
        (["synth", ""], "'OUT_DIR'"),
    ],
)
def test_an_empty_path_is_refused_not_read_as_the_current_folder(tmp_path, args, name):
    """An unset variable (``ppo-cv pairs "$PAIRS" "$DIR"``) gives an empty path, which Python
    reads as ``.``: run in a folder holding the images, ``pairs`` would run on it."""
    for image in (DEMO1, DEMO2):
        shutil.copy(image, tmp_path / image.name)
    (tmp_path / "pairs.txt").write_text(f"{DEMO1.name} {DEMO2.name}\n")
    done = ppo_cv(*args, "--quiet", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        f"ppo-cv {args[0]}: Invalid value for {name}: the path is empty (an unset variable?); "
        "give a name"
    ]
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([DEMO1.name, DEMO2.name, "pairs.txt"])


def test_the_readme_explains_every_line_of_the_demo_summary():
    """Each line ``ppo-cv pair`` prints on the demo pair is in the README's sample of that
    summary and has a row in the table below it."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = readme.split("### What the summary says", 1)[1].split("\n## ", 1)[0]
    sample, table = section.split("| line | what it means |", 1)
    done = ppo_cv("pair", "--quiet")
    assert done.returncode == 0, done.stderr
    labels = [re.match(r"  (\S+(?: \S+)?) {2,}", line) for line in done.stdout.splitlines()[1:]]
    assert labels and all(labels)
    for label in (found[1] for found in labels):
        assert f"\n  {label} " in sample, label
        assert re.search(rf"^\|[^|]*`{re.escape(label)}`", table, re.M), label


def test_a_name_whose_accents_are_encoded_otherwise_says_so(tmp_path):
    """A file named on macOS (``e`` and a combining accent) and a pairs line typed elsewhere
    (``é``) print alike: "image not found: café.png" beside a listed café.png said nothing."""
    import unicodedata

    stored, typed = (unicodedata.normalize(form, "café.png") for form in ("NFD", "NFC"))
    shutil.copy(DEMO1, tmp_path / stored)
    shutil.copy(DEMO2, tmp_path / "b.png")
    remedy = ("('cafe\\u0301.png' exists: the same name with its accents encoded otherwise "
              "than 'caf\\xe9.png' (Unicode NFD, as macOS writes names, or NFC)")  # fmt: skip
    done = ppo_cv("pair", tmp_path / typed, tmp_path / "b.png", "--K", K_TEXT)
    assert done.returncode == 2
    assert done.stderr.startswith(f"ppo-cv pair: image not found: {tmp_path / typed} {remedy}")
    (tmp_path / "pairs.txt").write_text(f"{typed} b.png\n", encoding="utf-8")
    done = ppo_cv("pairs", tmp_path / "pairs.txt", tmp_path, "--K", K_TEXT, "-q")
    assert done.returncode == 1
    assert remedy in json.loads(done.stdout)["error"]


def test_pairs_whose_names_differ_from_the_files_in_case_say_so(tmp_path):
    """A list naming ``.jpg`` what the camera wrote ``.JPG``: no image of it is found."""
    (tmp_path / "images").mkdir()
    for index, image in enumerate((DEMO1, DEMO2)):
        photo(image, tmp_path / "images" / f"IMG_{index}.JPG")
    (tmp_path / "pairs.txt").write_text("IMG_0.jpg IMG_1.jpg\n")
    done = ppo_cv("pairs", "pairs.txt", "images", "--K", K_TEXT, "-q", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        "ppo-cv pairs: image folder images holds none of the 2 images pairs.txt names (the "
        "first: IMG_0.jpg); IMG_0.JPG exists: names are case-sensitive"
    ]
