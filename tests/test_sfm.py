"""ppo_cv.sfm and ``ppo-cv sfm``: initial-pair ranking and PPO-seeded incremental mapping."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pycolmap
import pytest
from typer.testing import CliRunner

import ppo_cv
from ppo_cv import colmap, sfm
from ppo_cv.cli.main import app
from ppo_cv.data_gen import read_pairs, relative_gt_from_poses, render_tripod_then_move
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

ROOT = Path(__file__).resolve().parents[1]
FREIBURG_K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


# --- score_pose on exact poses --------------------------------------------------------------


def synthetic_pose(t: np.ndarray, n: int = 200, seed: int = 0, noise: float = 0.0):
    rng = np.random.default_rng(seed)
    K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])
    a = np.deg2rad(5.0)
    R = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    X1 = rng.uniform([-2.0, -1.5, 4.0], [2.0, 1.5, 6.0], (n, 3))
    X2 = X1 @ R.T + t
    p1 = (X1 @ K.T)[:, :2] / X1[:, 2:] + rng.normal(0.0, noise, (n, 2))
    p2 = (X2 @ K.T)[:, :2] / X2[:, 2:] + rng.normal(0.0, noise, (n, 2))
    axis = t if np.any(t) else np.array([1.0, 0.0, 0.0])
    E = np.cross(np.eye(3), axis) @ R
    return ppo_cv.recover_pose(E, p1, p2, K), X1, R


def test_score_pose_accepts_parallax_and_scores_by_inliers_and_angle():
    t = np.array([1.0, 0.0, 0.0])
    pose, X1, R = synthetic_pose(t)
    score, tri_angle, rejection = sfm.score_pose(pose, target_tri_angle=30.0)
    true_angle = np.degrees(np.median(colmap.triangulation_angles(X1, R, t)))
    assert rejection == ""
    assert tri_angle == pytest.approx(true_angle, rel=1e-9)
    assert score == pytest.approx(200 * true_angle / 30.0)
    assert sfm.score_pose(pose, target_tri_angle=1.0)[0] == pytest.approx(200.0)


@pytest.mark.parametrize(
    "t, kwargs, reason",
    [
        (np.zeros(3), {}, "pure rotation"),
        (np.array([0.3, 0.0, 0.0]), {"min_tri_angle": 10.0}, "small parallax"),
        (np.array([1.0, 0.0, 0.0]), {"min_inliers": 201}, "too few inliers"),
        (np.array([0.3, 0.0, 3.0]), {"min_tri_angle": 0.0}, "forward motion"),
    ],
)
def test_score_pose_rejections(t, kwargs, reason):
    pose, _, _ = synthetic_pose(t, noise=0.3)
    score, _, rejection = sfm.score_pose(pose, **kwargs)
    assert rejection.startswith(reason) and score == 0.0


def test_score_pairs_on_a_synthesized_database(tmp_path):
    """pycolmap's synthetic scene: exact matches, distorted SIMPLE_RADIAL camera, known poses.
    The scene is drawn from pycolmap's global generator, seeded here so that it does not depend
    on the tests run before (seed 10 draws a pair with PRI 0.095)."""
    pycolmap.set_random_seed(0)
    options = pycolmap.SyntheticDatasetOptions()
    options.num_rigs, options.num_cameras_per_rig, options.num_frames_per_rig = 1, 1, 5
    options.num_points3D = 200
    options.camera_has_prior_focal_length = True
    path = tmp_path / "synthetic.db"
    with pycolmap.Database.open(path) as database:
        reconstruction = pycolmap.synthesize_dataset(options, database)
        ids, geometries = database.read_two_view_geometries()
        id1, id2 = pycolmap.pair_id_to_image_pair(ids[0])
        degenerate = geometries[0]
        degenerate.config = pycolmap.TwoViewGeometryConfiguration.DEGENERATE
        database.update_two_view_geometry(id1, id2, degenerate)
    pairs = sfm.score_pairs(path)
    assert len(pairs) == 10
    for pair in pairs:
        if (pair.image_id1, pair.image_id2) == (id1, id2):
            assert pair.rejection.startswith("no pose (DEGENERATE") and pair.score == 0.0
            continue
        R, t = colmap.relative_pose(reconstruction, pair.image_id1, pair.image_id2)
        assert rotation_error_deg(pair.R, R) < 1e-4 and direction_error_deg(pair.t, t) < 1e-4
        assert pair.num_inliers == pair.num_matches
        assert not pair.pure_rotation and pair.pri > 0.1


# --- a camera that pans on a tripod, then walks -------------------------------------------


@pytest.fixture(scope="module")
def tripod(tmp_path_factory):
    """8 rendered views (4 pan, 4 move) and their COLMAP database with known intrinsics."""
    folder = tmp_path_factory.mktemp("tripod")
    images = folder / "images"
    names, K, poses = render_tripod_then_move(images, n_pan=4, n_move=4)
    database = folder / "db.db"
    sfm.prepare_database(images, database, K=K)
    pan = {n for n in names if "pan" in n}
    return images, database, K, relative_gt_from_poses(names, poses), pan


@pytest.fixture(scope="module")
def tripod_pairs(tripod):
    return sfm.score_pairs(tripod[1])


def test_pure_rotation_pairs_look_easiest_and_are_rejected(tripod, tripod_pairs):
    _, _, _, gt, pan = tripod
    by_matches = sorted(tripod_pairs, key=lambda p: -p.num_matches)
    assert {by_matches[0].name1, by_matches[0].name2} <= pan
    for pair in tripod_pairs:
        if {pair.name1, pair.name2} <= pan:
            assert pair.pure_rotation and pair.rejection.startswith("pure rotation")
            assert pair.score == 0.0
        else:
            assert pair.accepted, pair
    accepted = [p for p in tripod_pairs if p.accepted]
    assert len(accepted) == len(tripod_pairs) - 6
    assert [p.score for p in accepted] == sorted((p.score for p in accepted), reverse=True)


def gt_pose(gt: dict, name1: str, name2: str) -> tuple[np.ndarray, np.ndarray]:
    """``cam2_from_cam1`` of two views, whichever order the ground truth stores them in."""
    if (name1, name2) in gt:
        return gt[(name1, name2)]
    R, t = gt[(name2, name1)]
    return R.T, -R.T @ t


def test_pair_poses_match_ground_truth(tripod, tripod_pairs):
    # The database's essential matrices come from pycolmap's verification (4 px threshold), so
    # these are rough two-view poses; what matters is the right candidate.
    gt = tripod[3]
    rotation_errors, translation_errors = [], []
    for pair in tripod_pairs:
        R_gt, t_gt = gt_pose(gt, pair.name1, pair.name2)
        rotation_errors.append(rotation_error_deg(pair.R, R_gt))
        if pair.accepted:
            translation_errors.append(direction_error_deg(pair.t, t_gt))
    assert max(rotation_errors) < 3.0 and np.median(rotation_errors) < 0.3
    assert max(translation_errors) < 10.0 and np.median(translation_errors) < 2.0


@pytest.mark.parametrize("seeding", sfm.SEEDINGS)
def test_ppo_seeded_reconstruction_registers_every_view(tripod, seeding):
    images, database, _, gt, pan = tripod
    messages = []
    result = sfm.reconstruct(
        database, images, seeding=seeding, fix_intrinsics=True, progress=messages.append
    )
    assert result.initialization == "ppo"
    assert not set(result.initial_pair) <= pan
    best = result.pairs[0]
    assert set(result.initial_pair) == {best.name1, best.name2}
    assert result.all_registered and result.num_registered == 8
    assert result.mean_reprojection_error < 0.5
    rotation_errors, translation_errors = sfm.pose_errors(result.reconstruction, gt)
    assert len(rotation_errors) == 28
    assert max(rotation_errors) < 0.3
    assert np.median(translation_errors) < 1.0
    assert any("initial pair" in m for m in messages)
    assert any("registered 8 images" in m for m in messages)


def _database_named_against_id_order(tripod, folder: Path) -> tuple[Path, Path]:
    """A copy of the tripod database whose image names sort opposite to their ids, as the
    extraction threads can number them."""
    images, database = tripod[0], tripod[1]
    copy, renamed = folder / "db.db", folder / "images"
    renamed.mkdir()
    shutil.copy(database, copy)
    with pycolmap.Database.open(copy) as opened:
        for rank, image in enumerate(sorted(opened.read_all_images(), key=lambda i: i.image_id)):
            new_name = f"{99 - rank:02d}_{image.name}"
            shutil.copy(images / image.name, renamed / new_name)
            image.name = new_name
            opened.update_image(image)
    return copy, renamed


@pytest.mark.parametrize("seeding", sfm.SEEDINGS)
def test_progress_names_the_initial_pair_in_the_order_of_the_result(tripod, tmp_path, seeding):
    database, images = _database_named_against_id_order(tripod, tmp_path)
    messages = []
    result = sfm.reconstruct(
        database, images, seeding=seeding, fix_intrinsics=True, progress=messages.append
    )
    best = result.pairs[0]
    assert best.name1 < best.name2 and best.image_id1 > best.image_id2  # names, not ids
    for pair in result.pairs:  # each pose is that of its order: camera 1 is name1
        R_gt, _ = gt_pose(tripod[3], pair.name1[3:], pair.name2[3:])
        assert pair.name1 < pair.name2 and rotation_error_deg(pair.R, R_gt) < 3.0, pair
    seeded = [m for m in messages if m.startswith("seeding with")]
    started = [m for m in messages if m.startswith("initial pair")]
    assert seeded == [f"seeding with {best.name1} {best.name2} ({seeding})"]
    assert started == [f"initial pair {best.name1} {best.name2}"]
    assert result.initial_pair == (best.name1, best.name2)


def test_reconstruct_rejects_bad_arguments(tripod, tmp_path):
    images, database, *_ = tripod
    with pytest.raises(ValueError, match="initialization"):
        sfm.reconstruct(database, images, initialization="random")
    with pytest.raises(ValueError, match="seeding"):
        sfm.reconstruct(database, images, seeding="random")
    with pytest.raises(ValueError, match="does not exist"):
        sfm.reconstruct(tmp_path / "missing.db", images)
    with pytest.raises(ValueError, match="does not exist"):
        sfm.score_pairs(tmp_path / "missing.db")
    with pytest.raises(ValueError, match="no image pair qualifies"):
        sfm.reconstruct(database, images, min_inliers=10**6)


@pytest.mark.parametrize(
    "scoring, words",
    [
        ({"target_tri_angle": 0}, "target_tri_angle must be a finite number > 0, got 0"),
        ({"target_tri_angle": -2.0}, "target_tri_angle must be a finite number > 0, got -2"),
        ({"min_tri_angle": float("nan")}, "min_tri_angle must be a finite number >= 0"),
    ],
)
def test_run_sfm_checks_the_scoring_before_any_feature_is_extracted(tripod, tmp_path, scoring,
                                                                   words):  # fmt: skip
    # A target_tri_angle of 0 passed the early check and was refused by the scoring, after
    # the features were extracted and matched.
    messages: list[str] = []
    with pytest.raises(ValueError, match=words):
        sfm.run_sfm(tripod[0], tmp_path / "model", progress=messages.append, **scoring)
    assert messages == [] and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "trials, error",
    [("a", TypeError), (None, TypeError), (True, TypeError), (0, ValueError), (1.5, ValueError)],
)
def test_reconstruct_names_a_max_init_trials_that_is_no_count(tripod, trials, error):
    # "a" gave int()'s message, naming nothing; 0, -3, 1.5 and True ran as 1.
    images, database, *_ = tripod
    messages: list[str] = []
    with pytest.raises(error, match=r"^max_init_trials must be a whole number"):
        sfm.reconstruct(database, images, max_init_trials=trials, progress=messages.append)
    assert messages == []


def test_prepare_database_rejects_bad_inputs(tripod, tmp_path):
    images, database, *_ = tripod
    with pytest.raises(ValueError, match="already exists"):
        sfm.prepare_database(images, database)
    lonely = tmp_path / "one"
    lonely.mkdir()
    shutil.copy(next(images.iterdir()), lonely)
    with pytest.raises(ValueError, match="at least 2 images"):
        sfm.prepare_database(lonely, tmp_path / "db.db")
    with pytest.raises(ValueError, match="does not exist"):
        sfm.prepare_database(tmp_path / "nowhere", tmp_path / "db.db")
    assert not (tmp_path / "db.db").exists()


def test_a_database_named_by_a_symbolic_link_to_nothing_is_never_replaced(tripod, tmp_path):
    # No --overwrite replaces a database, so the link is refused as a database that exists.
    link = tmp_path / "db.db"
    link.symlink_to("nowhere.db")
    with pytest.raises(ValueError, match="already exists; give a new file name"):
        sfm.prepare_database(tripod[0], link)
    with pytest.raises(ValueError, match="already exists; give a new file name"):
        sfm.run_sfm(tripod[0], tmp_path / "model", database_path=link)
    assert link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["db.db"]


def test_too_few_images_names_the_sub_folders_that_hold_images(tmp_path):
    # A COLMAP-style folder of one folder per camera gave "found 0", naming no cause.
    source = sorted(Path(ppo_cv.__file__).parent.joinpath("data").glob("*.png"))[0]
    for folder in ("cam2", "cam1", "notes"):
        (tmp_path / "images" / folder).mkdir(parents=True)
    for folder in ("cam1", "cam2"):
        shutil.copy(source, tmp_path / "images" / folder / "a.png")
    (tmp_path / "images" / "notes" / "a.txt").write_text("no image")
    with pytest.raises(ValueError) as error:
        sfm.prepare_database(tmp_path / "images", tmp_path / "db.db")
    assert str(error.value) == (
        f"need at least 2 images in {str(tmp_path / 'images')!r}, found 0; sub-folders are not "
        "read, and cam1, cam2 hold images: give the folder of the images, or put them in one"
    )
    assert not (tmp_path / "db.db").exists()


def test_a_given_K_reaches_pycolmap_in_colmap_pixel_coordinates_and_comes_back():
    # COLMAP's features put the first pixel's centre at (0.5, 0.5): the given (OpenCV) principal
    # point went to pycolmap as it was, half a pixel off its keypoints and those of the images
    K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
    reader, *_ = sfm._pycolmap_options(K, 1000, 1, 0)
    params = [float(v) for v in reader.camera_params.split(",")]
    assert params == [535.4, 539.2, 320.6, 248.1]
    camera = pycolmap.Camera(model="PINHOLE", width=640, height=480, params=params)
    K_back, dist = sfm._pipeline_camera(camera, given=True)
    np.testing.assert_allclose(K_back, K, atol=1e-12)
    assert dist is None
    # a camera pycolmap guessed is read as calib.camera_from_exif reads its guess (pair's camera)
    K_guessed, _ = sfm._pipeline_camera(camera, given=False)
    np.testing.assert_array_equal(K_guessed, camera.calibration_matrix())


# --- the command line ----------------------------------------------------------------------


def test_cli_sfm_writes_a_colmap_model(tripod, tmp_path):
    images, _, K, gt, pan = tripod
    subset = tmp_path / "images"
    subset.mkdir()
    for name in ("00_pan.png", "01_pan.png", "04_move.png", "05_move.png", "06_move.png"):
        shutil.copy(images / name, subset)
    out = tmp_path / "model"
    k = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    run = CliRunner().invoke(app, ["sfm", str(subset), str(out), "--K", k, "--json"])
    assert run.exit_code == 0, run.output
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["registered"] == summary["images"] == 5
    started = [line for line in run.stderr.splitlines() if ": initial pair" in line]
    assert started == [f"ppo-cv sfm: initial pair {' '.join(summary['initial_pair'])}"]
    assert not set(summary["initial_pair"]) <= pan
    reconstruction = pycolmap.Reconstruction(out)
    assert reconstruction.num_reg_images() == 5
    camera = next(iter(reconstruction.cameras.values()))
    shift = np.array([[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]])  # COLMAP's pixel coordinates
    np.testing.assert_allclose(camera.calibration_matrix(), K + shift)
    ranking = (out / "initial_pairs.txt").read_text().splitlines()
    assert ranking[0].startswith("#") and len(ranking) == 1 + 10
    assert "pure_rotation" in (out / "initial_pairs.txt").read_text()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--K", "1,2,3"], "--K must be 4 numbers"),
        (["--K", "0,500,320,240"], "zero focal length"),
        (["--K", "a,b,c,d"], "numbers"),
        (["--init", "best"], "--init must be one of"),
        (["--seeding", "best"], "--seeding must be one of"),
    ],
)
def test_cli_sfm_bad_options(tripod, tmp_path, args, message):
    run = CliRunner().invoke(app, ["sfm", str(tripod[0]), str(tmp_path / "out"), *args])
    assert run.exit_code == 2
    assert message in run.stderr and "Traceback" not in run.output
    assert not (tmp_path / "out").exists()


def test_cli_sfm_bad_folders(tripod, tmp_path):
    existing = tmp_path / "exists"
    existing.mkdir()
    (existing / "keep.txt").write_text("keep")
    runner = CliRunner()
    run = runner.invoke(app, ["sfm", str(tripod[0]), str(existing)])
    assert run.exit_code == 2 and "is not an empty directory; pass --overwrite" in run.stderr
    assert [p.name for p in existing.iterdir()] == ["keep.txt"]
    run = runner.invoke(app, ["sfm", str(tmp_path / "nowhere"), str(tmp_path / "out")])
    assert run.exit_code == 2 and "does not exist" in run.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    run = runner.invoke(app, ["sfm", str(empty), str(tmp_path / "out")])
    assert run.exit_code == 2 and "at least 2 images" in run.stderr
    assert not (tmp_path / "out").exists()


def test_a_database_inside_the_output_folder_is_refused_before_any_work(tripod, tmp_path):
    # The model replaces the output folder as a whole at the end: a database kept inside it
    # was deleted and the finished model refused (or, with --overwrite, written with exit 2).
    images, _, K, *_ = tripod
    out = tmp_path / "model"
    out.mkdir()
    with pytest.raises(ValueError, match=r"database_path .*db\.db lies in output_dir .*model"):
        sfm.run_sfm(images, out, K=K, database_path=out / "db.db")
    (out / "keep.txt").write_text("keep")
    k = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    args = ["sfm", str(images), str(out), "--K", k, "--database", str(out / "db.db")]
    run = CliRunner().invoke(app, [*args, "--overwrite"])
    assert run.exit_code == 2, run.output
    assert run.stderr == (
        f"ppo-cv sfm: --database {out / 'db.db'} lies in OUT_DIR {out}, which the model "
        "replaces as a whole; keep the database outside it\n"
    )
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["model"]


def test_cli_sfm_refuses_a_symbolic_link_to_nothing_as_out_dir_before_any_work(tripod, tmp_path):
    images, _, K, *_ = tripod
    (tmp_path / "model").symlink_to("gone")
    k = f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}"
    run = CliRunner().invoke(app, ["sfm", str(images), str(tmp_path / "model"), "--K", k])
    assert run.exit_code == 2, run.output
    assert run.stderr == (
        f"ppo-cv sfm: {tmp_path / 'model'} is a symbolic link to gone, which leads nowhere; "
        "pass --overwrite to replace it\n"
    )
    assert (tmp_path / "model").is_symlink() and len(list(tmp_path.iterdir())) == 1


@pytest.mark.parametrize(
    "entry, error, words",
    [
        (
            (np.eye(3),),
            TypeError,
            r"\('a\.png', 'b\.png'\)\] must be \(R, t\), got tuple of length 1",
        ),
        ((np.eye(3) * 2, np.ones(3)), ValueError, r"R is not a rotation matrix"),
        ((np.full((3, 3), np.nan), np.ones(3)), ValueError, r"R has 9 NaN"),
        ((np.eye(4), np.ones(3)), ValueError, r"R must be a 3x3 rotation matrix"),
        ((np.eye(3), [1.0, np.nan, 0.0]), ValueError, r"t has 1 NaN"),
        ((np.eye(3), "xyz"), TypeError, r"t must hold real numbers"),
    ],
)
def test_pose_errors_names_a_ground_truth_entry_that_is_no_pose(entry, error, words):
    # NaN gave NaN errors and 2 * I a zero error, silently; the others numpy's messages.
    reconstruction = pycolmap.Reconstruction()
    with pytest.raises(error, match=words):
        sfm.pose_errors(reconstruction, {("a.png", "b.png"): entry})
    with pytest.raises(TypeError, match="gt keys must be \\(name1, name2\\) image names"):
        sfm.pose_errors(reconstruction, {"a.png": (np.eye(3), np.ones(3))})


def test_pose_errors_takes_a_translation_as_a_column():
    reconstruction = pycolmap.Reconstruction()
    assert sfm.pose_errors(reconstruction, {("a.png", "b.png"): (np.eye(3), np.ones((3, 1)))}) == (
        [],
        [],
    )


# --- real images -----------------------------------------------------------------------------


def test_freiburg_sfm_matches_pseudo_ground_truth(freiburg, tmp_path):
    out = tmp_path / "model"
    result = sfm.run_sfm(freiburg / "images", out, K=FREIBURG_K)
    assert result.num_images == 17 and result.all_registered
    assert result.mean_reprojection_error < 1.0
    assert not result.pairs[0].pure_rotation
    gt = {
        (r["name1"], r["name2"]): (r["R"], r["t"])
        for r in read_pairs(freiburg / "pairs_with_gt.txt")
    }
    rotation_errors, translation_errors = sfm.pose_errors(pycolmap.Reconstruction(out), gt)
    assert len(rotation_errors) == 85
    assert np.median(rotation_errors) < 1.0
    assert np.median(translation_errors) < 2.0


# --- a planar pair: valid initial pair with its homography's pose ---------------------------


def test_score_pairs_scores_a_planar_pair_with_its_homography_pose(tmp_path):
    import cv2

    from ppo_cv.data_gen import make_pair

    pair = make_pair("planar", seed=0, size=(640, 480))
    images = tmp_path / "images"
    images.mkdir()
    for name, image in (("a.png", pair.image1), ("b.png", pair.image2)):
        cv2.imwrite(str(images / name), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    sfm.prepare_database(images, tmp_path / "db.db", K=pair.K1)
    (score,) = sfm.score_pairs(tmp_path / "db.db")
    assert score.model == "plane" and not score.pure_rotation
    assert score.accepted and score.score > 0 and score.tri_angle > 1.0
    R, t = (pair.R, pair.t) if score.name1 == "a.png" else (pair.R.T, -pair.R.T @ pair.t)
    assert rotation_error_deg(score.R, R) < 0.2
    assert direction_error_deg(score.t, t) < 0.5


def _pair_named(name1: str, name2: str) -> sfm.PairScore:
    return sfm.PairScore(1, 2, name1, name2, 40, 38, 0.1, False, 5.0, 38.0, "", np.eye(3),
                         np.array([1.0, 0.0, 0.0]))  # fmt: skip


@pytest.mark.parametrize(
    "names",
    [
        ("a.png", "b.png"),
        ("frame one.png", "ünï cödé\t2.png"),
        ("été.jpg", "x y z.jpg"),
        ("#1.png", "#2.png"),
        ("a.png", "#b.png"),
    ],
)
def test_initial_pairs_text_keeps_names_with_spaces_as_the_pairs_file_does(tmp_path, names):
    from ppo_cv.cli.batch import _fields

    text = sfm.format_pairs([_pair_named(*names)])
    line = text.splitlines()[1]
    assert _fields(line)[:2] == list(names) and len(_fields(line)) == 8
    model = pycolmap.Reconstruction()
    result = sfm.SfmResult(model, "ppo", names, (_pair_named(*names),), 2, 0, 0, float("nan"), 1,
                           0.0)  # fmt: skip
    sfm.write_model(result, tmp_path / "model")
    assert (tmp_path / "model" / "initial_pairs.txt").read_bytes() == text.encode("utf-8")


def test_a_result_prints_its_counts_not_every_ranked_pair():
    """``print(run_sfm(...))`` listed every ranked pair: 136 of them on the 17 freiburg
    frames, some 35,000 characters."""
    pairs = tuple(_pair_named(f"{i}.png", f"{i + 1}.png") for i in range(136))
    result = sfm.SfmResult(pycolmap.Reconstruction(), "ppo", ("0.png", "1.png"), pairs, 17, 17,
                           2304, 0.48, 1, 4.4)  # fmt: skip
    text = repr(result)
    assert len(text) < 500 and "PairScore(" not in text
    assert "pairs=<136 PairScore, best first>" in text
    assert "initial_pair=('0.png', '1.png')" in text and "num_registered=17" in text
    assert result.pairs == pairs


def _database_cameras(images, database) -> dict:
    """The camera of each image of ``images`` in the database ``prepare_database`` writes."""
    sfm.prepare_database(images, database)
    with pycolmap.Database.open(database) as opened:
        return {image.name: opened.read_camera(image.camera_id)
                for image in opened.read_all_images()}  # fmt: skip


def test_an_exif_focal_length_that_is_none_is_not_the_databases_camera(tmp_path):
    # pycolmap took 65535 mm (a placeholder) for a prior focal length of 1.2 million px
    from PIL import Image

    images = tmp_path / "images"
    images.mkdir()
    texture = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    for name, focal_35mm in (("a.jpg", 65535), ("b.jpg", 36)):
        exif = Image.Exif()
        exif[0x010F], exif[0x0110] = "Maker", "Model"
        exif.get_ifd(0x8769)[0xA405] = focal_35mm  # FocalLengthIn35mmFilm
        Image.fromarray(texture).save(images / name, exif=exif)
    cameras = _database_cameras(images, tmp_path / "db.db")
    assert cameras["a.jpg"].mean_focal_length() == 768.0
    assert not cameras["a.jpg"].has_prior_focal_length
    assert cameras["b.jpg"].has_prior_focal_length
    expected = 36 / np.hypot(36, 24) * 800  # the 35 mm frame's diagonal to the image's
    assert cameras["b.jpg"].mean_focal_length() == pytest.approx(expected, rel=1e-3)


def test_the_databases_camera_of_a_resized_photo_has_the_focal_length_of_its_pixels(tmp_path):
    # pycolmap's FocalLength x FocalPlaneXResolution is in the camera's pixels, 4000 wide: 2500
    # px for a copy of 640, where camera_from_exif gives 400
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    images = tmp_path / "images"
    images.mkdir()
    texture = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    for name, recorded, related in (("a.jpg", (4000, 3000), None), ("b.jpg", (640, 480), None),
                                    ("c.jpg", (640, 480), (4000, 3000))):  # fmt: skip
        exif = Image.Exif()
        sub = exif.get_ifd(0x8769)
        sub[0x920A], sub[0xA20E], sub[0xA210] = IFDRational(4.0), IFDRational(6250.0), 3
        sub[0xA002], sub[0xA003] = recorded  # 4 mm at 625 px/mm, the size the camera wrote
        if related is not None:  # a resizer rewrote PixelXDimension, left RelatedImageWidth
            sub[0xA005] = {0x1001: related[0], 0x1002: related[1]}
        Image.fromarray(texture).save(images / name, exif=exif)
    cameras = _database_cameras(images, tmp_path / "db.db")
    assert cameras["a.jpg"].mean_focal_length() == pytest.approx(400.0, rel=1e-4)
    assert cameras["b.jpg"].mean_focal_length() == pytest.approx(2500.0, rel=1e-4)
    assert cameras["c.jpg"].mean_focal_length() == pytest.approx(400.0, rel=1e-4)
    assert all(camera.has_prior_focal_length for camera in cameras.values())
    assert ppo_cv.camera_from_exif(images / "a.jpg")[0].K[0, 0] == pytest.approx(400.0, rel=1e-4)


def test_sfm_into_a_folder_of_photos_says_the_image_folder_comes_first(tmp_path):
    # `ppo-cv sfm model images` advised "pass --overwrite to replace it" for the photos
    data = Path(ppo_cv.__file__).parent / "data"
    for folder in ("model", "images"):
        (tmp_path / folder).mkdir()
    (tmp_path / "model" / "cameras.bin").write_bytes(b"")
    for image in ("demo1.png", "demo2.png"):
        (tmp_path / "images" / image).write_bytes((data / image).read_bytes())
    args = ["sfm", str(tmp_path / "model"), str(tmp_path / "images"), "--K", "500,500,320,240"]
    for extra in ([], ["--overwrite"]):
        run = CliRunner().invoke(app, [*args, *extra])
        assert run.exit_code == 2 and run.stdout == ""
        assert run.stderr == (
            f"ppo-cv sfm: OUT_DIR {tmp_path / 'images'} holds 2 images (demo1.png, demo2.png), "
            "which a model folder never does: the image folder comes first, ppo-cv sfm "
            "IMAGE_DIR OUT_DIR; give an output folder without images\n"
        )
    assert sorted(p.name for p in (tmp_path / "images").iterdir()) == ["demo1.png", "demo2.png"]
