"""``ppo-cv sfm`` and ``ppo-cv pair`` decide a pair alike: a panorama seeds no reconstruction."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import cv2
import numpy as np
import pycolmap
import pytest
from scipy.spatial.transform import Rotation

from ppo_cv import sfm
from ppo_cv.data_gen import read_pairs, render_tripod_then_move
from ppo_cv.pipeline import estimate_pair

COMMAND = [sys.executable, "-m", "ppo_cv.cli.main"]


@pytest.fixture(scope="module")
def tripod(tmp_path_factory):
    """6 rendered views (3 pan about one centre, 3 walking) and their database with known K."""
    folder = tmp_path_factory.mktemp("tripod")
    images = folder / "images"
    names, K, _ = render_tripod_then_move(images, n_pan=3, n_move=3)
    database = folder / "db.db"
    sfm.prepare_database(images, database, K=K)
    return images, database, K, {n for n in names if "pan" in n}


@pytest.mark.parametrize(
    ("with_K", "counts"),
    [
        (True, "of 10 matched pairs, 10 pure rotation"),
        (False, "of 10 matched pairs, 5 not checked on the images, 5 pure rotation on the images"),
    ],
    ids=["K", "guessed camera"],
)
def test_pan_folder_exits_1_as_a_panorama_and_keeps_the_database(tmp_path, with_K, counts):
    """Without --K pycolmap guesses 1.2 x 480 = 576 px for a 408 px lens: the focal length
    fitted to each checked pair's homography finds the rotation."""
    images = tmp_path / "pan"
    _, K, _ = render_tripod_then_move(images, n_pan=5, n_move=0)
    k = ["--K", f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"] if with_K else []
    run = subprocess.run(
        [*COMMAND, "sfm", str(images), "model", *k, "--database", "db.db", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    line = run.stderr.strip().splitlines()[-1]
    assert line.startswith("ppo-cv sfm: the 5 images look like a panorama (pure rotations")
    assert f"hold no structure to reconstruct: {counts}" in line
    assert line.endswith("the matched features are in db.db")
    assert run.stdout == "" and not (tmp_path / "model").exists()
    with pycolmap.Database.open(tmp_path / "db.db") as database:
        assert database.num_images() == 5


def test_translating_folder_reconstructs_with_a_guessed_camera(tmp_path):
    images = tmp_path / "walk"
    render_tripod_then_move(images, n_pan=1, n_move=4)
    run = subprocess.run(
        [*COMMAND, "sfm", str(images), "model", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("registered 5/5 images"), run.stdout
    model = pycolmap.Reconstruction(tmp_path / "model")
    assert model.num_reg_images() == 5 and model.num_points3D() > 500


def _conjugate_rotation(rotvec, focal_scale: float) -> np.ndarray:
    S = np.diag([focal_scale, focal_scale, 1.0])
    return S @ Rotation.from_rotvec(rotvec).as_matrix() @ np.linalg.inv(S)


@pytest.mark.parametrize(
    ("rotvec", "focal_scale"),
    [
        ([0.0, 0.28, 0.0], 408 / 576),  # the rendered pan's lens against pycolmap's guess
        ([0.02, 0.15, 0.01], 997 / 917.5),  # pano_dev book against its EXIF focal length
        ([0.1, -0.05, 0.2], 1.5),
        ([0.0, 0.05, 0.0], 0.8),
    ],
)
def test_rotation_focal_scale_recovers_the_focal_length_of_a_rotation(rotvec, focal_scale):
    H = 3.7 * _conjugate_rotation(rotvec, focal_scale)
    assert sfm.rotation_focal_scale(H, 600.0, 640) == pytest.approx(focal_scale, rel=1e-4)


@pytest.mark.parametrize(
    "H",
    [
        Rotation.from_rotvec([0.0, 0.0, 0.3]).as_matrix(),  # about the optical axis only
        _conjugate_rotation([0.0, 0.2, 0.0], 20.0),  # a focal length far outside the range
        np.full((3, 3), np.nan),
        np.zeros((3, 3)),
        np.diag([1.0, 1.0, 0.0]),
    ],
    ids=["roll", "out of range", "not finite", "zero", "singular"],
)
def test_rotation_focal_scale_is_none_without_a_focal_length_in_range(H):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a zero H divided 0 by 0 with a RuntimeWarning
        assert sfm.rotation_focal_scale(H, 600.0, 640) is None


@pytest.mark.parametrize(
    "H, error, words",
    [
        (np.eye(2), ValueError, r"^H must have shape \(3, 3\), got \(2, 2\)$"),  # was None
        ("abc", TypeError, r"^H must be a 3x3 array of numbers, got 'abc'$"),
    ],
)
def test_rotation_focal_scale_names_an_H_that_is_no_homography(H, error, words):
    with pytest.raises(error, match=words):
        sfm.rotation_focal_scale(H, 600.0, 640)


def test_image_check_agrees_with_estimate_pair(tripod):
    images, database, K, pan = tripod
    pairs = sfm.score_pairs(database)
    by_names = {(p.name1, p.name2): p for p in pairs}
    rotation = by_names[("00_pan.png", "02_pan.png")]
    walk = by_names[("03_move.png", "05_move.png")]
    assert estimate_pair(images / "00_pan.png", images / "02_pan.png", K).pure_rotation
    assert not estimate_pair(images / "03_move.png", images / "05_move.png", K).pure_rotation
    refusal = sfm._image_rejection(database, images, rotation, 0.01)
    assert refusal.startswith("pure rotation on the images (ppo-cv pair: PRI")
    assert sfm._image_rejection(database, images, walk, 0.01) == ""


def _refusing(pairs_to_refuse, calls):
    """``_image_rejection`` that refuses the given pairs as rotations and checks the others."""
    real = sfm._image_rejection

    def check(database_path, image_dir, pair, pri_threshold, **options):
        calls.append((pair.name1, pair.name2))
        if (pair.name1, pair.name2) in pairs_to_refuse:
            return "pure rotation on the images (ppo-cv pair: PRI 0.0001, rotation)"
        return real(database_path, image_dir, pair, pri_threshold, **options)

    return check


def test_a_pair_the_images_call_a_rotation_is_skipped_for_the_next(tripod, monkeypatch):
    images, database, _, pan = tripod
    ranked = [p for p in sfm.score_pairs(database) if p.accepted]
    best, second = ranked[0], ranked[1]
    calls: list = []
    monkeypatch.setattr(sfm, "_image_rejection", _refusing({(best.name1, best.name2)}, calls))
    messages: list = []
    result = sfm.reconstruct(database, images, fix_intrinsics=True, progress=messages.append)
    assert calls == [(best.name1, best.name2), (second.name1, second.name2)]
    assert result.initial_pair == (second.name1, second.name2)
    assert result.all_registered and result.num_registered == 6
    assert (result.pairs[0].name1, result.pairs[0].name2) == (second.name1, second.name2)
    refused = next(p for p in result.pairs if (p.name1, p.name2) == (best.name1, best.name2))
    assert refused.rejection.startswith("pure rotation on the images") and refused.score == 0
    assert refused.pure_rotation and not refused.accepted
    assert f"refused {best.name1} {best.name2}: pure rotation on the images" in "\n".join(messages)
    assert "pure_rotation_on_the_images" in sfm.format_pairs(result.pairs)


def test_every_checked_pair_a_rotation_fails_as_a_panorama(tripod, monkeypatch):
    images, database, _, _ = tripod
    ranked = [(p.name1, p.name2) for p in sfm.score_pairs(database) if p.accepted]
    assert len(ranked) > sfm.MAX_IMAGE_CHECKS
    calls: list = []
    monkeypatch.setattr(sfm, "_image_rejection", _refusing(set(ranked), calls))
    with pytest.raises(sfm.ReconstructionFailed) as failure:
        sfm.reconstruct(database, images, fix_intrinsics=True)
    assert calls == ranked[: sfm.MAX_IMAGE_CHECKS]
    message = str(failure.value)
    assert message.startswith("the 6 images look like a panorama (pure rotations about one")
    assert f"{sfm.MAX_IMAGE_CHECKS} pure rotation on the images" in message
    assert f"{len(ranked) - sfm.MAX_IMAGE_CHECKS} not checked on the images" in message


def test_pan_folder_with_colmap_initialization_says_why_nothing_was_built(tmp_path):
    # It said "nothing was reconstructed; no model written", which names no cause.
    images = tmp_path / "pan"
    _, K, _ = render_tripod_then_move(images, n_pan=4, n_move=0)
    k = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    run = subprocess.run(
        [*COMMAND, "sfm", str(images), "model", "--K", k, "--init", "colmap", "--quiet",
         "--threads", "1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    assert run.stderr == (
        "ppo-cv sfm: pycolmap's own initialisation found no pair of the 4 images to start a "
        "model from (a panorama, or too little parallax) and no model was written; the PPO "
        "initialisation names why each pair is refused\n"
    )
    assert run.stdout == "" and not (tmp_path / "model").exists()


def test_colmap_initialization_checks_no_pair(tripod, monkeypatch):
    images, database, _, _ = tripod
    calls: list = []
    monkeypatch.setattr(sfm, "_image_rejection", _refusing(set(), calls))
    result = sfm.reconstruct(database, images, initialization="colmap", fix_intrinsics=True)
    assert calls == [] and result.num_registered >= 2


@pytest.mark.slow
def test_real_tripod_panorama_exits_1_where_it_seeded_a_two_image_model(pano_dev, tmp_path):
    """The first 10 frames of pano_dev's ``book`` sequence, with its focal length: the ranking
    accepts a pair that ``ppo-cv pair`` calls a pure rotation (it registered 2 of 10 images)."""
    source = pano_dev / "images"
    images = tmp_path / "book"
    images.mkdir()
    for path in sorted(source.glob("book_*.JPG"))[:10]:
        (images / path.name).symlink_to(path)
    run = subprocess.run(
        [*COMMAND, "sfm", str(images), "model", "--K", "996.9,996.9,305,458.5", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    (line,) = run.stderr.strip().splitlines()
    assert "the 10 images look like a panorama (pure rotations about one point)" in line
    assert "pure rotation on the images" in line
    assert not (tmp_path / "model").exists()


def test_real_tripod_panorama_exits_1_without_K(pano_dev, tmp_path):
    """Four ``book`` frames of pano_dev: pycolmap takes their EXIF focal length (917.5 px,
    997 px in the reference), with which ``ppo-cv pair`` calls them general motion; the focal
    length fitted to each pair's homography calls them rotations (they registered 4 of 4)."""
    images = tmp_path / "book"
    images.mkdir()
    for index in range(4214, 4218):
        name = f"book_DSC0{index}.JPG"
        (images / name).symlink_to(pano_dev / "images" / name)
    run = subprocess.run(
        [*COMMAND, "sfm", str(images), "model", "--database", "db.db"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    line = run.stderr.strip().splitlines()[-1]
    assert "the 4 images look like a panorama (pure rotations about one point)" in line
    assert "pure rotation on the images" in line
    assert "px fitted to the homography" in run.stderr
    assert not (tmp_path / "model").exists()


@pytest.fixture(scope="module")
def real_photo_views(tmp_path_factory):
    """Folders of two views, a tripod pan and a translation as a real camera renders them
    (``REAL_PHOTO``: radial distortion, a 25-35 degree field, JPEG), PNGs without EXIF."""
    from ppo_cv.data_gen import REAL_PHOTO, make_pair

    root = tmp_path_factory.mktemp("real_photo_views")
    for motion, index in (("panorama", 11), ("general", 0)):
        pair = make_pair(motion, 0, index, imperfections=REAL_PHOTO)
        (root / motion).mkdir()
        for view, image in enumerate((pair.image1, pair.image2), 1):
            pixels = np.clip(np.rint(image * 255), 0, 255).astype(np.uint8)
            cv2.imwrite(str(root / motion / f"view{view}.png"), pixels[..., ::-1])
    return root


@pytest.mark.parametrize("motion, pure_rotation", [("panorama", True), ("general", False)])
def test_sfm_refuses_the_pairs_pair_calls_rotations_with_a_guessed_camera(
    real_photo_views, tmp_path, motion, pure_rotation
):
    """The pan's homography, without the lens's radial term, gives a focal length with which
    ``ppo-cv pair`` still calls it general motion; the fit with that term calls it a pure
    rotation. ``sfm`` checked the pair with the homography's focal length only, and seeded a
    two-image model from it; it now decides it as ``pair`` does, with the same focal length."""
    folder = real_photo_views / motion
    done = subprocess.run(
        [*COMMAND, "pair", folder / "view1.png", folder / "view2.png", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    decided = json.loads(done.stdout)
    assert decided["pure_rotation"] is pure_rotation
    run = subprocess.run(
        [*COMMAND, "sfm", str(folder), "model", "--threads", "1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    if not pure_rotation:
        assert run.returncode == 0, run.stderr
        assert run.stdout.startswith("registered 2/2 images"), run.stdout
        assert "refused" not in run.stderr
        return
    assert run.returncode == 1, run.stdout
    (refusal,) = [line for line in run.stderr.splitlines() if " refused " in line]
    assert refusal.startswith(
        "ppo-cv sfm: refused view1.png view2.png: pure rotation on the images (ppo-cv pair: PRI "
    )
    focal = decided["cameras"]["K1"][0][0]
    assert refusal.endswith(
        f"focal length {focal:.1f} px fitted to the homography of its matches and then with "
        "its lens's radial term)"
    )
    line = run.stderr.strip().splitlines()[-1]
    assert "the 2 images look like a panorama" in line
    assert "1 pure rotation on the images" in line
    assert not (tmp_path / "model").exists()


def test_freiburg_reconstructs_without_K(freiburg, tmp_path):
    run = subprocess.run(
        [*COMMAND, "sfm", str(freiburg / "images"), "model", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("registered 17/17 images"), run.stdout
    ranking = (tmp_path / "model" / "initial_pairs.txt").read_text().splitlines()
    assert ranking[1].endswith(" ok")
    gt = {
        (r["name1"], r["name2"]): (r["R"], r["t"])
        for r in read_pairs(freiburg / "pairs_with_gt.txt")
    }
    model = pycolmap.Reconstruction(tmp_path / "model")
    rotation_errors, translation_errors = sfm.pose_errors(model, gt)
    assert len(rotation_errors) == 85
    assert np.median(rotation_errors) < 1.0 and np.median(translation_errors) < 2.0


class _CountingDatabase:
    """A pycolmap database whose reads are counted by method name."""

    def __init__(self, database, reads: dict) -> None:
        self._database, self._reads = database, reads

    def __getattr__(self, name):
        method = getattr(self._database, name)
        if not name.startswith("read_"):
            return method

        def counted(*args):
            self._reads[name] = self._reads.get(name, 0) + 1
            return method(*args)

        return counted


def test_the_focal_fit_and_the_ranking_read_the_pair_once(tripod, monkeypatch):
    images, database, K, pan = tripod
    rotation = {(p.name1, p.name2): p for p in sfm.score_pairs(database)}[
        ("00_pan.png", "02_pan.png")
    ]
    reads: dict = {}
    opened = pycolmap.Database.open

    class Opening:
        def __init__(self, path) -> None:
            self._context = opened(path)

        def __enter__(self):
            return _CountingDatabase(self._context.__enter__(), reads)

        def __exit__(self, *exc):
            return self._context.__exit__(*exc)

    class Pycolmap:
        Database = type("Database", (), {"open": staticmethod(Opening)})

        def __getattr__(self, name):
            return getattr(pycolmap, name)

    monkeypatch.setattr(sfm, "pycolmap", Pycolmap())
    refusal = sfm._image_rejection(database, images, rotation, 0.01, fit_focal=True)
    assert refusal.startswith("pure rotation on the images")
    assert reads["read_two_view_geometry"] == 1 and reads["read_keypoints"] == 2, reads
