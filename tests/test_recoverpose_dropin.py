"""ppo_cv.recoverPose mirrors every call form of cv2.recoverPose."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from twoview import make_scene, random_rotation

import ppo_cv
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

OPENCV_RECOVER_POSE = cv2.recoverPose


@pytest.fixture(scope="module")
def scene():
    """A noisy general-motion pair with an E and RANSAC mask from OpenCV."""
    rng = np.random.default_rng(3)
    K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
    R = random_rotation(rng, 15.0)
    t = np.array([0.8, -0.2, 0.3])
    t /= np.linalg.norm(t)
    X, p1, p2 = make_scene(rng, 150, R, t, K, noise_px=0.3)
    p2[:10] = rng.uniform(0, 640, (10, 2))
    E, mask = cv2.findEssentialMat(p1, p2, K, cv2.RANSAC, 0.999, 1.0)
    return {"K": K, "R": R, "t": t, "X": X, "p1": p1, "p2": p2, "E": E[:3], "mask": mask}


def _check_pose(out, scene, reference):
    retval, R, t, mask = out[:4]
    assert isinstance(retval, int)
    assert R.shape == (3, 3) and R.dtype == np.float64
    assert t.shape == (3, 1) and t.dtype == np.float64
    assert mask.shape == (len(scene["p1"]), 1) and mask.dtype == np.uint8
    assert np.linalg.norm(t) == pytest.approx(1.0)
    assert rotation_error_deg(R, reference[1]) < 1e-4
    assert direction_error_deg(t, reference[2]) < 1e-4
    assert abs(retval - reference[0]) <= 3
    assert retval == np.count_nonzero(mask)


def test_form_camera_matrix(scene):
    args = (scene["E"], scene["p1"], scene["p2"], scene["K"])
    _check_pose(ppo_cv.recoverPose(*args), scene, OPENCV_RECOVER_POSE(*args))
    kwargs = {
        "E": scene["E"],
        "points1": scene["p1"],
        "points2": scene["p2"],
        "cameraMatrix": scene["K"],
    }
    _check_pose(ppo_cv.recoverPose(**kwargs), scene, OPENCV_RECOVER_POSE(**kwargs))


def test_a_camera_matrix_changed_in_place_is_used_and_a_bad_one_always_rejected(scene):
    K = scene["K"].copy()
    args = (scene["E"], scene["p1"], scene["p2"])
    first = ppo_cv.recoverPose(*args, K, distanceThresh=50.0)[4]
    K[0, 2] += 40.0  # same array object, new principal point
    moved = ppo_cv.recoverPose(*args, K, distanceThresh=50.0)[4]
    np.testing.assert_array_equal(
        moved, ppo_cv.recoverPose(*args, K.copy(), distanceThresh=50.0)[4]
    )
    assert np.abs(moved - first).max() > 1e-3
    K[0, 0] = 0.0
    for _ in range(2):
        with pytest.raises(ValueError, match="cameraMatrix has a zero focal length"):
            ppo_cv.recoverPose(*args, K)


def test_form_focal_and_principal_point(scene):
    focal, pp = 800.0, (320.0, 240.0)
    reference = OPENCV_RECOVER_POSE(scene["E"], scene["p1"], scene["p2"], focal=focal, pp=pp)
    out = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], focal=focal, pp=pp)
    _check_pose(out, scene, reference)
    positional = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], None, None, focal, pp)
    _check_pose(positional, scene, reference)


@pytest.mark.parametrize("extra", [(), (None,)], ids=["K None", "K None, R None"])
def test_a_camera_matrix_of_none_is_refused_as_opencv_refuses_it(scene, extra):
    # read as the focal, pp form with its R output None: pixels were taken for normalized
    # points (focal 1, principal point 0) without a word; OpenCV fails on the camera matrix
    args = (scene["E"], scene["p1"], scene["p2"], None, *extra)
    with pytest.raises(cv2.error):
        OPENCV_RECOVER_POSE(*args)
    with pytest.raises(ppo_cv.RecoverPoseTypeError, match=r"^cameraMatrix is required, got None"):
        ppo_cv.recoverPose(*args)


def test_form_focal_defaults_to_normalized_points(scene):
    x1 = cv2.undistortPoints(scene["p1"].reshape(-1, 1, 2), scene["K"], None)
    x2 = cv2.undistortPoints(scene["p2"].reshape(-1, 1, 2), scene["K"], None)
    reference = OPENCV_RECOVER_POSE(scene["E"], x1, x2)
    _check_pose(ppo_cv.recoverPose(scene["E"], x1, x2), scene, reference)


def test_form_distance_threshold_returns_analytic_points(scene):
    ours = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], scene["K"], distanceThresh=50.0)
    reference = OPENCV_RECOVER_POSE(
        scene["E"], scene["p1"], scene["p2"], scene["K"], distanceThresh=50.0
    )
    assert len(ours) == 5
    _check_pose(ours, scene, reference)
    points = ours[4]
    assert points.shape == (4, len(scene["p1"])) and points.dtype == np.float64
    inliers = ours[3].ravel() > 0
    inliers[:10] = False  # the outliers of the fixture may pass any pose test by chance
    euclidean = (points[:3] / points[3]).T[inliers]
    theirs = reference[4]
    checks = ((scene["X"][inliers], 0.15), ((theirs[:3] / theirs[3]).T[inliers], 0.01))
    for expected, tolerance in checks:
        relative = np.linalg.norm(euclidean - expected, axis=1) / np.linalg.norm(expected, axis=1)
        assert np.median(relative) < tolerance
    keyword = ppo_cv.recoverPose(
        E=scene["E"],
        points1=scene["p1"],
        points2=scene["p2"],
        cameraMatrix=scene["K"],
        distanceThresh=5.0,
    )
    assert keyword[0] < ours[0]


def test_a_positional_distance_with_a_triangulated_points_buffer_is_the_third_form(scene):
    # OpenCV tries each form in turn: a number after cameraMatrix is the R buffer of the first,
    # but with triangulatedPoints=, which only the third has, the distance; this was a TypeError
    args = (scene["E"], scene["p1"], scene["p2"], scene["K"], 50.0)
    buffer, theirs = np.zeros((4, len(scene["p1"]))), np.zeros((4, len(scene["p1"])))
    ours = ppo_cv.recoverPose(*args, triangulatedPoints=buffer)
    reference = OPENCV_RECOVER_POSE(*args, triangulatedPoints=theirs)
    assert len(ours) == len(reference) == 5 and ours[4] is buffer and reference[4] is theirs
    _check_pose(ours, scene, reference)
    keyword = ppo_cv.recoverPose(*args[:4], distanceThresh=50.0)
    assert ours[0] == keyword[0] and np.array_equal(ours[4], keyword[4])


def test_form_two_cameras_with_distortion():
    rng = np.random.default_rng(4)
    K1 = np.array([[700.0, 0.0, 330.0], [0.0, 710.0, 250.0], [0.0, 0.0, 1.0]])
    K2 = np.array([[900.0, 0.0, 310.0], [0.0, 905.0, 235.0], [0.0, 0.0, 1.0]])
    d1, d2 = np.array([-0.2, 0.05, 0.001, -0.001, 0.0]), np.array([0.1, -0.02, 0.0, 0.0, 0.0])
    R = random_rotation(rng, 10.0)
    t = np.array([1.0, 0.1, 0.05])
    X = rng.uniform([-3, -2, 5], [3, 2, 10], (200, 3))
    p1 = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K1, d1)[0].reshape(-1, 2)
    p2 = cv2.projectPoints(X, cv2.Rodrigues(R)[0], t, K2, d2)[0].reshape(-1, 2)
    out = ppo_cv.recoverPose(p1, p2, K1, d1, K2, d2)
    retval, E, R_out, t_out, mask = out
    assert E.shape == (3, 3) and mask.shape == (200, 1)
    assert rotation_error_deg(R_out, R) < 0.05
    assert direction_error_deg(t_out, t) < 0.5
    assert retval >= 190
    reference = OPENCV_RECOVER_POSE(p1, p2, K1, d1, K2, d2)
    assert rotation_error_deg(R_out, reference[2]) < 0.1
    keyword = ppo_cv.recoverPose(
        points1=p1,
        points2=p2,
        cameraMatrix1=K1,
        distCoeffs1=d1,
        cameraMatrix2=K2,
        distCoeffs2=d2,
        method=cv2.USAC_MAGSAC,
        prob=0.999,
        threshold=1.0,
    )
    assert rotation_error_deg(keyword[2], R) < 0.05


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", ["N2", "N12", "1N2", "N21"])
def test_accepted_shapes_and_dtypes(scene, dtype, shape):
    # (N, 2, 1), column vectors, which cv2.recoverPose reads too, was refused
    def reshape(p):
        p = p.astype(dtype)
        return {"N2": p, "N12": p.reshape(-1, 1, 2), "1N2": p.reshape(1, -1, 2),
                "N21": p.reshape(-1, 2, 1)}[shape]  # fmt: skip

    p1, p2 = reshape(scene["p1"]), reshape(scene["p2"])
    reference = OPENCV_RECOVER_POSE(scene["E"], p1, p2, scene["K"])
    _check_pose(ppo_cv.recoverPose(scene["E"], p1, p2, scene["K"]), scene, reference)


def test_mask_semantics_follow_opencv(scene):
    no_mask = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], scene["K"])
    assert set(np.unique(no_mask[3])) <= {0, 255}
    ours = ppo_cv.recoverPose(  # a copy: the (N, 1) uint8 mask receives the output, as in OpenCV
        scene["E"], scene["p1"], scene["p2"], scene["K"], mask=scene["mask"].copy()
    )
    assert set(np.unique(ours[3])) <= {0, 1}
    assert not np.any(ours[3].ravel()[scene["mask"].ravel() == 0])
    reference = OPENCV_RECOVER_POSE(
        scene["E"], scene["p1"], scene["p2"], scene["K"], mask=scene["mask"].copy()
    )
    assert abs(ours[0] - reference[0]) <= 3
    assert ours[0] <= np.count_nonzero(scene["mask"])
    ones = np.ones(len(scene["p1"]), dtype=bool)
    ones[:75] = False
    subset = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], scene["K"], mask=ones)
    assert not subset[3][:75].any() and subset[0] <= 75


def test_output_buffers_are_filled_in_place(scene):
    R_buffer, t_buffer = np.zeros((3, 3)), np.zeros((3, 1))
    out = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], scene["K"], R_buffer, t_buffer)
    assert out[1] is R_buffer and out[2] is t_buffer
    assert rotation_error_deg(R_buffer, scene["R"]) < 1.0


def test_install_uninstall_and_context_manager(scene):
    args = (scene["E"], scene["p1"], scene["p2"], scene["K"])
    try:
        ppo_cv.install()
        assert cv2.recoverPose is ppo_cv.recoverPose and ppo_cv.is_installed()
        _check_pose(cv2.recoverPose(*args), scene, OPENCV_RECOVER_POSE(*args))
        ppo_cv.uninstall()
        assert cv2.recoverPose is OPENCV_RECOVER_POSE and not ppo_cv.is_installed()
        with ppo_cv.installed():
            assert cv2.recoverPose is ppo_cv.recoverPose
        assert cv2.recoverPose is OPENCV_RECOVER_POSE
        with pytest.raises(RuntimeError), ppo_cv.installed():
            raise RuntimeError("inside")
        assert cv2.recoverPose is OPENCV_RECOVER_POSE
    finally:
        ppo_cv.uninstall()


def test_installed_form_with_points_does_not_recurse(scene):
    with ppo_cv.installed():
        out = cv2.recoverPose(scene["p1"], scene["p2"], scene["K"], None, scene["K"], None)
    assert rotation_error_deg(out[2], scene["R"]) < 1.0
    assert direction_error_deg(out[3], scene["t"]) < 5.0


def test_many_points_and_normalized_equivalence():
    rng = np.random.default_rng(5)
    K = np.eye(3)
    R = random_rotation(rng, 10.0)
    t = np.array([0.0, 0.0, 1.0])
    _, p1, p2 = make_scene(rng, 20000, R, t, K)
    E = np.cross(np.eye(3), t).T @ R  # [t]x R
    out = ppo_cv.recoverPose(E, p1, p2)
    assert out[0] >= 0.99 * 20000
    assert rotation_error_deg(out[1], R) < 1e-6 and direction_error_deg(out[2], t) < 1e-6


def test_form_with_points_keeps_the_rotation_and_the_mask_contract_for_pure_rotation():
    rng = np.random.default_rng(6)
    K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
    R = random_rotation(rng, 15.0)
    _, p1, p2 = make_scene(rng, 200, R, np.zeros(3), K, noise_px=0.5)
    retval, E, R_out, t_out, mask = ppo_cv.recoverPose(p1, p2, K, None, K, None)
    assert rotation_error_deg(R_out, R) < 1.0
    x1 = cv2.undistortPoints(p1.reshape(-1, 1, 2), K, None).reshape(-1, 2)
    x2 = cv2.undistortPoints(p2.reshape(-1, 1, 2), K, None).reshape(-1, 2)
    m1 = ppo_cv.ppo.same_side_scores(x1, x2, R_out, t_out.ravel())
    m2 = ppo_cv.ppo.intersection_scores(x1, x2, R_out, t_out.ravel())
    both = (m1 > 0) & (m2 > 0)
    assert np.all(both[mask.ravel() > 0]) and retval == np.count_nonzero(mask)


def test_an_infinite_distance_threshold_keeps_every_point_as_in_opencv(scene):
    # "no cut of far points" was refused: distanceThresh must be a finite number > 0
    args = (scene["E"], scene["p1"], scene["p2"], scene["K"])
    ours = ppo_cv.recoverPose(*args, distanceThresh=np.inf)
    reference = OPENCV_RECOVER_POSE(*args, distanceThresh=np.inf)
    _check_pose(ours, scene, reference)
    assert ours[0] == ppo_cv.recoverPose(*args)[0]
    for bad in (0.0, -1.0, -np.inf, np.nan):
        with pytest.raises(ValueError, match="distanceThresh must be a finite number > 0"):
            ppo_cv.recoverPose(*args, distanceThresh=bad)


def test_a_camera_matrix_given_with_focal_is_refused_not_overwritten(scene):
    # the focal, pp form takes the fourth argument as its R output: OpenCV, and this function,
    # wrote the rotation over the caller's camera matrix
    K = scene["K"].copy()
    args = (scene["E"], scene["p1"], scene["p2"], K)
    for keywords in ({"focal": 800.0}, {"pp": (320.0, 240.0)}, {"focal": 800.0, "pp": (320, 240)}):
        with pytest.raises(ppo_cv.RecoverPoseTypeError, match="a camera matrix in the place of"):
            ppo_cv.recoverPose(*args, **keywords)
        np.testing.assert_array_equal(K, scene["K"])
    rotation = cv2.Rodrigues(np.array([0.0, 0.0, 0.3]))[0]  # a previous answer, reused as buffer
    for buffer in (np.zeros((3, 3)), np.eye(3), rotation):
        out = ppo_cv.recoverPose(scene["E"], scene["p1"], scene["p2"], buffer, focal=800.0,
                                 pp=(320.0, 240.0))  # fmt: skip
        assert out[1] is buffer
        _check_pose(out, scene, OPENCV_RECOVER_POSE(*args[:3], scene["K"]))


@pytest.mark.parametrize("name", ["findEssentialMat", "RANSAC", "SIFT_create"])
def test_a_wholesale_swap_of_cv2_is_told_what_ppo_cv_stands_in_for(name):
    """Code that replaced ``cv2`` by ``ppo_cv`` everywhere, not only in its ``recoverPose``
    calls, met a bare ``has no attribute 'findEssentialMat'``."""
    with pytest.raises(AttributeError, match=rf"has no attribute '{name}' \(ppo_cv stands in "
                       rf"for cv2.recoverPose only: use cv2.{name} as before\)$"):  # fmt: skip
        getattr(ppo_cv, name)
    assert not hasattr(ppo_cv, name)


def test_names_opencv_lacks_and_private_names_get_no_hint():
    for name in ("no_such_function", "_private", "__wrapped__"):
        with pytest.raises(AttributeError) as error:
            getattr(ppo_cv, name)
        assert str(error.value) == f"module 'ppo_cv' has no attribute {name!r}"
