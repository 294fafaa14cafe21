"""ppo_cv.colmap: conventions of every transform, checked against pycolmap itself."""

from __future__ import annotations

import re

import numpy as np
import pycolmap
import pytest
from twoview import pycolmap_relative_pose

import ppo_cv
from ppo_cv import colmap
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

Config = pycolmap.TwoViewGeometryConfiguration
K = np.array([[500.0, 0.0, 320.0], [0.0, 480.0, 240.0], [0.0, 0.0, 1.0]])


def rotation(axis, degrees: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return pycolmap.Rotation3d(axis / np.linalg.norm(axis) * np.deg2rad(degrees)).matrix()


def scene(seed: int, R: np.ndarray, t: np.ndarray, n: int = 300, noise: float = 0.5):
    """Pixel matches of random points 4-10 m in front of camera 1, seen by ``X2 = R X1 + t``."""
    rng = np.random.default_rng(seed)
    X1 = rng.uniform([-3.0, -2.0, 4.0], [3.0, 2.0, 10.0], (n, 3))
    X2 = X1 @ R.T + t
    p1 = (X1 @ K.T)[:, :2] / X1[:, 2:] + rng.normal(0.0, noise, (n, 2))
    p2 = (X2 @ K.T)[:, :2] / X2[:, 2:] + rng.normal(0.0, noise, (n, 2))
    return p1, p2


@pytest.fixture(scope="module")
def camera() -> pycolmap.Camera:
    return colmap.camera_from_K(K, 640, 480)


def test_camera_round_trip(camera):
    assert camera.model_name == "PINHOLE"
    assert (camera.width, camera.height) == (640, 480)
    np.testing.assert_array_equal(colmap.K_from_camera(camera), K)
    # pycolmap projects camera-frame points with the same K.
    X = np.array([[0.3, -0.2, 2.0]])
    np.testing.assert_allclose(camera.img_from_cam(X), (X @ K.T)[:, :2] / X[:, 2:])


def test_camera_rejects_what_pinhole_cannot_hold():
    with pytest.raises(ValueError, match="skew"):
        colmap.camera_from_K([[500, 1, 320], [0, 500, 240], [0, 0, 1]], 640, 480)
    with pytest.raises(ValueError, match="image width must be a whole number in 1"):
        colmap.camera_from_K(K, 0, 480)
    with pytest.raises(ValueError, match="3x3"):
        colmap.camera_from_K(np.eye(2), 640, 480)
    radial = pycolmap.Camera(
        model="SIMPLE_RADIAL", width=640, height=480, params=[500, 320, 240, 0.1]
    )
    with pytest.raises(ValueError, match="distortion"):
        colmap.K_from_camera(radial)


def test_rigid3d_is_cam2_from_cam1():
    R, t = rotation([0.2, 1.0, -0.3], 25.0), np.array([0.4, -1.0, 0.3])
    rigid = colmap.rigid3d_from_pose(R, t)
    X1 = np.array([0.5, -0.7, 3.0])
    np.testing.assert_allclose(rigid * X1, R @ X1 + t)
    R_back, t_back = colmap.pose_from_rigid3d(rigid)
    np.testing.assert_allclose(R_back, R, atol=1e-12)
    np.testing.assert_allclose(t_back, t, atol=1e-12)
    R_inv, t_inv = colmap.pose_from_rigid3d(rigid.inverse())
    np.testing.assert_allclose(R_inv, R.T, atol=1e-12)
    np.testing.assert_allclose(t_inv, -R.T @ t, atol=1e-12)
    with pytest.raises(ValueError, match="rotation"):
        colmap.rigid3d_from_pose(-R, t)


def test_relative_pose_of_reconstruction_maps_camera1_points_to_camera2():
    pycolmap.set_random_seed(0)
    options = pycolmap.SyntheticDatasetOptions()
    options.num_rigs, options.num_cameras_per_rig, options.num_frames_per_rig = 1, 1, 3
    options.num_points3D = 60
    reconstruction = pycolmap.synthesize_dataset(options)
    id1, id2 = sorted(reconstruction.reg_image_ids())[:2]
    R, t = colmap.relative_pose(reconstruction, id1, id2)
    image1, image2 = reconstruction.image(id1), reconstruction.image(id2)
    shared = [
        p.xyz
        for p in reconstruction.points3D.values()
        if {e.image_id for e in p.track.elements} >= {id1, id2}
    ]
    assert len(shared) > 10
    X_world = np.array(shared)
    X1 = X_world @ image1.cam_from_world().matrix()[:, :3].T + image1.cam_from_world().translation
    X2 = X_world @ image2.cam_from_world().matrix()[:, :3].T + image2.cam_from_world().translation
    np.testing.assert_allclose(X1 @ R.T + t, X2, atol=1e-9)


def test_pycolmap_relative_pose_and_ppo_pick_the_same_pose(camera):
    R_gt = rotation([0.1, 1.0, 0.2], 12.0)
    t_gt = np.array([1.0, 0.15, 0.2]) / np.linalg.norm([1.0, 0.15, 0.2])
    p1, p2 = scene(1, R_gt, t_gt)
    R_c, t_c, found = pycolmap_relative_pose(camera, p1, camera, p2)
    assert rotation_error_deg(R_c, R_gt) < 0.5 and direction_error_deg(t_c, t_gt) < 2.0
    E = np.cross(np.eye(3), t_c) @ R_c  # [t]_x R, pycolmap's x2^T E x1 = 0
    result = ppo_cv.recover_pose(E, p1, p2, K, mask=found["inlier_mask"])
    assert rotation_error_deg(result.R, R_c) < 1e-4
    assert direction_error_deg(result.t, t_c) < 1e-4
    assert not result.pure_rotation


def test_two_view_geometry_from_pose(camera):
    R_gt, t_gt = rotation([0.0, 1.0, 0.0], 10.0), np.array([1.0, 0.0, 0.0])
    p1, p2 = scene(2, R_gt, t_gt, noise=0.0)
    E = np.cross(np.eye(3), t_gt) @ R_gt
    result = ppo_cv.recover_pose(E, p1, p2, K)
    matches = np.stack([np.arange(300), np.arange(300)[::-1]], axis=1)
    geometry = colmap.two_view_geometry_from_pose(result, E, matches)
    assert geometry.config == Config.CALIBRATED
    R, t = colmap.pose_from_rigid3d(geometry.cam2_from_cam1)
    np.testing.assert_allclose(R, R_gt, atol=1e-9)
    np.testing.assert_allclose(t, t_gt, atol=1e-9)
    np.testing.assert_array_equal(geometry.inlier_matches, matches[result.inliers])
    np.testing.assert_allclose(geometry.E, E)
    # The analytic points are exact: their median triangulation angle is the true one.
    X1 = result.points3d
    true = colmap.triangulation_angles(X1, R_gt, t_gt)
    assert geometry.tri_angle == pytest.approx(np.median(true), rel=1e-9)
    assert 0.05 < geometry.tri_angle < 0.3
    geometry.invert()
    R_inv, t_inv = colmap.pose_from_rigid3d(geometry.cam2_from_cam1)
    np.testing.assert_allclose(R_inv, R_gt.T, atol=1e-9)
    np.testing.assert_allclose(t_inv, -R_gt.T @ t_gt, atol=1e-9)
    with pytest.raises(ValueError, match="matches"):
        colmap.two_view_geometry_from_pose(result, E, matches[:10])


def test_pure_rotation_where_relative_pose_reports_a_translation(camera):
    R_gt = rotation([0.3, 1.0, 0.1], 8.0)
    p1, p2 = scene(3, R_gt, np.zeros(3), noise=0.5)
    R_c, t_c, found = pycolmap_relative_pose(camera, p1, camera, p2)
    # pycolmap's five-point solver returns a unit baseline with nothing to tell it is noise.
    assert np.linalg.norm(t_c) == pytest.approx(1.0)
    assert found["num_inliers"] > 250
    E = np.cross(np.eye(3), t_c) @ R_c
    result = ppo_cv.recover_pose(E, p1, p2, K, mask=found["inlier_mask"])
    assert result.pure_rotation
    assert rotation_error_deg(result.R, R_gt) < 1.0
    geometry = colmap.two_view_geometry_from_pose(result, E)
    assert geometry.config == Config.PANORAMIC
    assert geometry.tri_angle == 0.0
    np.testing.assert_array_equal(geometry.cam2_from_cam1.translation, np.zeros(3))


@pytest.mark.parametrize("pure", [False, True], ids=["general", "pure-rotation"])
def test_estimate_two_view_geometry_against_pycolmap(camera, pure):
    R_gt = rotation([0.2, 1.0, 0.1], 10.0)
    t_gt = np.zeros(3) if pure else np.array([0.8, 0.1, -0.3])
    p1, p2 = scene(4, R_gt, t_gt, noise=0.4)
    ours = colmap.estimate_two_view_geometry(camera, p1, camera, p2)
    matches = np.stack([np.arange(len(p1)), np.arange(len(p1))], 1).astype(np.uint32)
    theirs = pycolmap.estimate_calibrated_two_view_geometry(camera, p1, camera, p2, matches)
    assert pycolmap.estimate_two_view_geometry_pose(camera, p1, camera, p2, theirs)
    assert ours.success
    np.testing.assert_array_equal(ours.geometry.inlier_matches.shape[1], 2)
    R, t = colmap.pose_from_rigid3d(ours.geometry.cam2_from_cam1)
    R_c, t_c = colmap.pose_from_rigid3d(theirs.cam2_from_cam1)
    assert rotation_error_deg(R, R_gt) < 1.0 and rotation_error_deg(R, R_c) < 1.0
    if pure:
        assert ours.pose.pure_rotation
        assert ours.geometry.config == Config.PANORAMIC
        assert not np.any(t)
    else:
        assert not ours.pose.pure_rotation
        assert ours.geometry.config == Config.CALIBRATED == theirs.config
        assert direction_error_deg(t, t_gt) < 2.0 and direction_error_deg(t, t_c) < 2.0
        assert ours.geometry.tri_angle == pytest.approx(theirs.tri_angle, rel=0.1)


def test_recover_pose_from_geometry_undistorts_by_the_camera_model():
    camera = pycolmap.Camera(
        model="SIMPLE_RADIAL", width=640, height=480, params=[500.0, 320.0, 240.0, -0.08]
    )
    R_gt = rotation([0.0, 1.0, 0.2], 9.0)
    t_gt = np.array([1.0, 0.0, 0.1]) / np.linalg.norm([1.0, 0.0, 0.1])
    rng = np.random.default_rng(5)
    X1 = rng.uniform([-3.0, -2.0, 4.0], [3.0, 2.0, 10.0], (200, 3))
    p1 = camera.img_from_cam(X1)
    p2 = camera.img_from_cam(X1 @ R_gt.T + t_gt)
    geometry = pycolmap.TwoViewGeometry()
    geometry.E = np.cross(np.eye(3), t_gt) @ R_gt
    geometry.inlier_matches = np.stack([np.arange(200), np.arange(200)], 1).astype(np.uint32)
    result = colmap.recover_pose_from_geometry(geometry, camera, p1, camera, p2)
    np.testing.assert_allclose(result.R, R_gt, atol=1e-9)
    np.testing.assert_allclose(result.t, t_gt, atol=1e-9)
    assert result.num_inliers == 200
    # Without E (an uncalibrated verification) the five-point solver supplies one.
    geometry.E = np.zeros((3, 3))
    result = colmap.recover_pose_from_geometry(geometry, camera, p1, camera, p2)
    assert rotation_error_deg(result.R, R_gt) < 1e-3 and direction_error_deg(result.t, t_gt) < 1e-2


def test_estimate_two_view_geometry_without_enough_matches(camera):
    p1, p2 = scene(6, np.eye(3), np.array([1.0, 0.0, 0.0]), n=8)
    estimate = colmap.estimate_two_view_geometry(camera, p1, camera, p2)
    assert not estimate.success and estimate.pose is None
    with pytest.raises(ValueError, match="equal shapes"):
        colmap.estimate_two_view_geometry(camera, p1, camera, p2[:5])


def test_a_degenerate_geometry_is_named_for_its_matches_not_for_a_given_E(camera):
    # every match reusing keypoint 0 of image 1: pycolmap's E of them was refused as if the
    # caller had given it ("E is not an essential matrix ... pass E = K2^T F K1")
    p1, p2 = scene(6, rotation([0.0, 1.0, 0.0], 5.0), np.array([1.0, 0.0, 0.0]), n=60)
    matches = np.stack([np.zeros(60, int), np.arange(60)], 1)
    with pytest.raises(ValueError) as info:
        colmap.estimate_two_view_geometry(camera, p1, camera, p2, matches)
    message = str(info.value)
    assert message.startswith("the geometry's E, from its ") and "is degenerate" in message
    assert "keypoint 0 of image 1 is in " in message and "pass E =" not in message


def test_two_view_reconstruction_from_analytic_points():
    R_gt = rotation([0.1, 1.0, 0.0], 8.0)
    t_gt = np.array([1.0, 0.1, 0.0]) / np.linalg.norm([1.0, 0.1, 0.0])
    p1, p2 = scene(7, R_gt, t_gt, n=120, noise=0.0)
    E = np.cross(np.eye(3), t_gt) @ R_gt
    result = ppo_cv.recover_pose(E, p1, p2, K)
    # Keypoint lists in a different order than the matches, as in a database.
    order2 = np.random.default_rng(0).permutation(120)
    keypoints2 = np.empty_like(p2)
    keypoints2[order2] = p2
    matches = np.stack([np.arange(120), order2], axis=1)
    camera = colmap.camera_from_K(K, 640, 480)
    camera.camera_id = 1
    image1 = pycolmap.Image(name="a.png", camera_id=1, image_id=3)
    image2 = pycolmap.Image(name="b.png", camera_id=1, image_id=5)
    reconstruction = colmap.two_view_reconstruction(
        camera, camera, image1, image2, p1, keypoints2, matches, result, min_tri_angle=0.0
    )
    assert reconstruction.num_reg_images() == 2 and reconstruction.num_cameras() == 1
    assert reconstruction.num_points3D() == 120
    R, t = colmap.relative_pose(reconstruction, 3, 5)
    np.testing.assert_allclose(R, R_gt, atol=1e-9)
    np.testing.assert_allclose(t, t_gt, atol=1e-9)
    reconstruction.update_point_3d_errors()
    assert reconstruction.compute_mean_reprojection_error() < 1e-6
    # Every point projects onto its own keypoints in both images.
    image = reconstruction.image(5)
    for point in list(reconstruction.points3D.values())[:10]:
        element = next(e for e in point.track.elements if e.image_id == 5)
        np.testing.assert_allclose(
            image.project_point(point.xyz), keypoints2[element.point2D_idx], atol=1e-6
        )
    # The angle filter drops the points seen under a small parallax.
    angles = np.degrees(colmap.triangulation_angles(result.points3d, R_gt, t_gt))
    threshold = float(np.median(angles))
    fewer = colmap.two_view_reconstruction(
        camera, camera, image1, image2, p1, keypoints2, matches, result, min_tri_angle=threshold
    )
    assert fewer.num_points3D() == np.count_nonzero(angles >= threshold)


def test_two_view_reconstruction_rejects_pure_rotation(camera):
    R_gt = rotation([0.0, 1.0, 0.0], 8.0)
    p1, p2 = scene(8, R_gt, np.zeros(3), n=50, noise=0.0)
    E = np.cross(np.eye(3), [1.0, 0.0, 0.0]) @ R_gt
    result = ppo_cv.recover_pose(E, p1, p2, K)
    assert result.pure_rotation
    image1 = pycolmap.Image(name="a.png", camera_id=1, image_id=1)
    image2 = pycolmap.Image(name="b.png", camera_id=1, image_id=2)
    matches = np.stack([np.arange(50), np.arange(50)], axis=1)
    with pytest.raises(ValueError, match="pure rotation"):
        colmap.two_view_reconstruction(camera, camera, image1, image2, p1, p2, matches, result)


def _two_view_inputs():
    R_gt = rotation([0.1, 1.0, 0.0], 8.0)
    t_gt = np.array([1.0, 0.0, 0.0])
    p1, p2 = scene(7, R_gt, t_gt, n=60, noise=0.0)
    result = ppo_cv.recover_pose(np.cross(np.eye(3), t_gt) @ R_gt, p1, p2, K)
    camera = colmap.camera_from_K(K, 640, 480)
    camera.camera_id = 1
    return camera, p1, p2, np.stack([np.arange(60), np.arange(60)], axis=1), result


def _other_camera(camera_id: int) -> pycolmap.Camera:
    other = colmap.camera_from_K(K * [[1.1], [1.1], [1.0]], 640, 480)
    other.camera_id = camera_id
    return other


@pytest.mark.parametrize(
    "change, message",
    [
        ({"camera1": "unset"}, "camera1 has no camera_id; set camera1.camera_id"),
        ({"image2": {"image_id": None}}, "image2 has no image_id"),
        ({"image1": {"camera_id": 5}}, "image1 has camera_id 5, but camera1 has 1"),
        ({"camera2": "other"}, "camera1 and camera2 differ but share camera_id 1"),
        ({"image2": {"image_id": 1}}, "distinct image_id and name, got 1 'a.png' and 1 'b.png'"),
        ({"image2": {"name": "a.png"}}, "distinct image_id and name"),
        ({"min_tri_angle": float("nan")}, "min_tri_angle must be a finite number >= 0"),
        ({"min_tri_angle": -1.0}, "min_tri_angle must be a finite number >= 0"),
    ],
)
def test_two_view_reconstruction_names_inputs_pycolmap_would_fail_on(change, message):
    # These failed inside pycolmap ("Rig 1 that contains Camera 1 does not exist", for a camera
    # of camera_from_K), or, for a NaN angle or two cameras of one id, gave another model.
    camera, p1, p2, matches, result = _two_view_inputs()
    cameras = {"camera1": camera, "camera2": camera}
    if change.get("camera1") == "unset":
        cameras["camera1"] = colmap.camera_from_K(K, 640, 480)
    if change.get("camera2") == "other":
        cameras["camera2"] = _other_camera(1)
    fields = {"image1": {"name": "a.png", "camera_id": 1, "image_id": 1},
              "image2": {"name": "b.png", "camera_id": 1, "image_id": 2}}  # fmt: skip
    for key in ("image1", "image2"):
        fields[key].update(change.get(key, {}))
    images = [pycolmap.Image(**{k: v for k, v in fields[key].items() if v is not None})
              for key in ("image1", "image2")]  # fmt: skip
    angle = {"min_tri_angle": change["min_tri_angle"]} if "min_tri_angle" in change else {}
    with pytest.raises(ValueError, match=re.escape(message)):
        colmap.two_view_reconstruction(cameras["camera1"], cameras["camera2"], *images, p1, p2,
                                       matches, result, **angle)  # fmt: skip


def test_two_view_reconstruction_keeps_the_first_match_of_a_keypoint_matched_twice():
    # A matcher without cross-check matches one keypoint twice; pycolmap failed on the second
    # point it observed ("point2D.point3D_id == point3D_id").
    camera, p1, p2, matches, result = _two_view_inputs()
    matches[5, 1] = matches[4, 1]
    second = _other_camera(2)
    image1 = pycolmap.Image(name="a.png", camera_id=1, image_id=1)
    image2 = pycolmap.Image(name="b.png", camera_id=2, image_id=2)
    reconstruction = colmap.two_view_reconstruction(
        camera, second, image1, image2, p1, p2, matches, result, min_tri_angle=0.0
    )
    assert reconstruction.num_points3D() == 59 and reconstruction.num_cameras() == 2
    observed = {e.point2D_idx for p in reconstruction.points3D.values() for e in p.track.elements
                if e.image_id == 1}  # fmt: skip
    assert 4 in observed and 5 not in observed


def _exact_pose_inputs():
    """(E, x1, x2, K) of 30 exact matches of a translating camera, pixels."""
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-1, 1, (30, 2)), rng.uniform(4, 8, 30)])
    R, t = np.eye(3), np.array([1.0, 0.0, 0.0])
    E = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]]) @ R
    project = lambda P: (P @ K.T)[:, :2] / P[:, 2:]  # noqa: E731
    return E, project(X), project(X @ R.T + t), K


def _geometry(matches) -> pycolmap.TwoViewGeometry:
    geometry = pycolmap.TwoViewGeometry()
    geometry.inlier_matches = np.asarray(matches, dtype=np.uint32)
    return geometry


_KEYPOINTS = np.random.default_rng(0).uniform(0, 480, (10, 2))
_SIX = [[i, i] for i in range(6)]


@pytest.mark.parametrize(
    "call, error, words",
    [
        (lambda cam: colmap.camera_from_K(K, "640", 480), TypeError, r"width must be a whole"),
        (lambda cam: colmap.camera_from_K(K, 640.5, 480), ValueError, r"width must be a whole"),
        (lambda cam: colmap.camera_from_K(K, 640, np.nan), ValueError, r"height must be a whole"),
        (lambda cam: colmap.rigid3d_from_pose(np.eye(3), [np.nan, 0, 1]), ValueError,
         r"t has 1 NaN or infinite"),
        (lambda cam: colmap.rigid3d_from_pose(np.eye(3), "abc"), TypeError,
         r"t must be three numbers, got str 'abc'"),
        (lambda cam: colmap.recover_pose_from_geometry(
            _geometry([*_SIX, [2, 50]]), cam, _KEYPOINTS, cam, _KEYPOINTS), ValueError,
         r"inlier_matches index keypoint 50 of image 2, which has 10 keypoints"),
        (lambda cam: colmap.recover_pose_from_geometry(
            _geometry([*_SIX, [10, 2]]), cam, _KEYPOINTS, cam, _KEYPOINTS), ValueError,
         r"inlier_matches index keypoint 10 of image 1, which has 10 keypoints"),
        (lambda cam: colmap.recover_pose_from_geometry(
            _geometry(_SIX), cam, _KEYPOINTS[:, 0], cam, _KEYPOINTS), ValueError,
         r"keypoints1 must have shape \(M, >=2\), got \(10,\)"),
        # not pycolmap's objects, or none: named (they were AttributeErrors, or pycolmap's
        # list of overloads)
        (lambda cam: colmap.K_from_camera(K), TypeError,
         r"^camera must be a pycolmap.Camera, got ndarray: make one with "
         r"ppo_cv.colmap.camera_from_K\(K, width, height\)$"),
        (lambda cam: colmap.rays_from_camera(None, _KEYPOINTS), TypeError,
         r"^camera must be a pycolmap.Camera, got NoneType"),
        (lambda cam: colmap.estimate_two_view_geometry(K, _KEYPOINTS, cam, _KEYPOINTS), TypeError,
         r"^camera1 must be a pycolmap.Camera, got ndarray"),
        (lambda cam: colmap.pose_from_rigid3d(None), TypeError,
         r"^rigid must be a pycolmap.Rigid3d, got NoneType$"),
        (lambda cam: colmap.relative_pose(None, 1, 2), TypeError,
         r"^reconstruction must be a pycolmap.Reconstruction, got NoneType$"),
        (lambda cam: colmap.relative_pose(pycolmap.Reconstruction(), 1, 2), ValueError,
         r"^the reconstruction has no image of id 1$"),
        (lambda cam: colmap.median_tri_angle(None), TypeError,
         r"^pose must be a ppo_cv.pose.PoseResult or ppo_cv.result.PairResult, got NoneType"),
        (lambda cam: colmap.two_view_geometry_from_pose(None), TypeError, r"^pose must be a"),
        (lambda cam: colmap.recover_pose_from_geometry(None, cam, _KEYPOINTS, cam, _KEYPOINTS),
         TypeError, r"^geometry must be a pycolmap.TwoViewGeometry, got NoneType$"),
        # points and matches pycolmap took: NaN gave a geometry of uninitialised memory, a
        # match beyond the keypoints was read, a NaN pri_threshold passed
        (lambda cam: colmap.rays_from_camera(cam, np.full((3, 2), np.nan)), ValueError,
         r"^points has 6 NaN or infinite value\(s\)$"),
        (lambda cam: colmap.estimate_two_view_geometry(
            cam, np.full((20, 2), np.nan), cam, _KEYPOINTS), ValueError,
         r"^points1 has 40 NaN or infinite value\(s\)$"),
        (lambda cam: colmap.estimate_two_view_geometry(
            cam, _KEYPOINTS, cam, _KEYPOINTS, matches=[*_SIX, [0, 99]]), ValueError,
         r"^matches index keypoint 99 of image 2, which has 10 keypoints$"),
        (lambda cam: colmap.estimate_two_view_geometry(
            cam, _KEYPOINTS, cam, _KEYPOINTS, matches=[*_SIX, [-1, 0]]), ValueError,
         r"^matches must be keypoint indices >= 0, got -1$"),
        (lambda cam: colmap.estimate_two_view_geometry(
            cam, _KEYPOINTS, cam, _KEYPOINTS, matches=np.ones((6, 2))), TypeError,
         r"^matches must be whole numbers \(keypoint indices\), got float64$"),
        (lambda cam: colmap.estimate_two_view_geometry(
            cam, _KEYPOINTS, cam, _KEYPOINTS, pri_threshold=np.nan), ValueError,
         r"^pri_threshold must be a number in \[0, 1\]"),
        (lambda cam: colmap.triangulation_angles(np.zeros((3, 2)), np.eye(3), [1, 0, 0]),
         ValueError, r"^points3d must have shape \(N, 3\), got \(3, 2\)$"),
        (lambda cam: colmap.two_view_geometry_from_pose(
            ppo_cv.recover_pose(*_exact_pose_inputs()), E=np.full((3, 3), np.nan)), ValueError,
         r"^E has 9 NaN or infinite value\(s\)$"),
    ],
    ids=["width text", "width fraction", "height NaN", "t NaN", "t text",
         "match beyond keypoints 2", "match beyond keypoints 1", "keypoints of one column",
         "K_from_camera K", "rays no camera", "estimate K as camera", "rigid None",
         "relative_pose None", "relative_pose no image", "tri angle None", "geometry None pose",
         "geometry None", "rays NaN", "estimate NaN points", "estimate match beyond",
         "estimate negative match", "estimate float matches", "estimate NaN pri",
         "tri angles shape", "E NaN"],
)
def test_hostile_arguments_are_errors_naming_them(camera, call, error, words):
    with pytest.raises(error, match=words):
        call(camera)
