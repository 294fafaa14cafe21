"""Hostile input to the library: each case is (call, exception type, words naming the argument).

Followed by the behaviours that are not errors: any scale of E, OpenCV's accepted shapes and
UMats, the positional call OpenCV reads as the first form, and images of any depth.
"""

from __future__ import annotations

import os
import re
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from pathlib import Path

import cv2
import numpy as np
import pytest
from hostile_images import HEADERS, png_header
from twoview import make_scene, random_rotation, skew

import ppo_cv
from ppo_cv.calib import ImplausibleCameraWarning
from ppo_cv.camera import principal_point_is_centre
from ppo_cv.images import load_image
from ppo_cv.pipeline import PairOptions

K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
OPENCV_RECOVER_POSE = cv2.recoverPose


def _scene():
    rng = np.random.default_rng(11)
    R = random_rotation(rng, 10.0)
    t = np.array([1.0, 0.1, 0.3])
    _, p1, p2 = make_scene(rng, 40, R, t, K)
    return skew(t) @ R, p1, p2, R, t / np.linalg.norm(t)


E, P1, P2, R_TRUE, T_TRUE = _scene()
GREY = np.random.default_rng(0).integers(0, 256, (48, 64), dtype=np.uint8)


def _K(**entries):
    K_bad = K.copy()
    for key, value in entries.items():
        K_bad[{"fx": (0, 0), "fy": (1, 1), "cx": (0, 2)}[key]] = value
    return K_bad


def _mask(value, selected=40):
    mask = np.zeros(40)
    mask[:selected] = value
    return mask


_ALL = np.ones(40, bool)


def _significance():
    from ppo_cv import significance

    return significance


def _refine():
    from ppo_cv import refine

    return refine


def _rays(nan_entry=None):
    """Image 1's matches as normalized homogeneous rows (40, 3), one entry NaN if asked."""
    rays = np.column_stack([P1, np.ones(40)]) @ np.linalg.inv(K).T
    if nan_entry is not None:
        rays[3, 0] = nan_entry
    return rays


def _points(index, value):
    points = P2.copy()
    points[index] = value
    return points


def _image_with_nan():
    image = GREY.astype(np.float32)
    image[3, 4] = np.nan
    return image


def _pair(**kwargs):
    args = {"image1": GREY, "image2": GREY[::-1].copy(), "K1": K, **kwargs}
    return lambda: ppo_cv.estimate_pair(**args)


def _sfm_module():
    from ppo_cv import sfm

    return sfm


def _sfm(**kwargs):
    return _sfm_module().run_sfm("no such folder", None, K=K, **kwargs)


def _fundamental():
    K_inverse = np.linalg.inv(K)
    return K_inverse.T @ E @ K_inverse


def _form4(**kwargs):
    args = {"distCoeffs1": None, "distCoeffs2": None, **kwargs}
    return lambda: ppo_cv.recoverPose(P1, P2, cameraMatrix1=K, cameraMatrix2=K, **args)


RAYS = np.column_stack([(P1 - K[:2, 2]) / K[0, 0], np.ones(len(P1))])
RAYS2 = np.column_stack([(P2 - K[:2, 2]) / K[0, 0], np.ones(len(P2))])


def _robust_fit(model, **changes):
    from ppo_cv import homography, robust

    fit = robust.estimate_essential if model == "essential" else homography.estimate_homography
    arguments = {"x1": RAYS, "x2": RAYS2, "focal": 800.0, **changes}
    return fit(arguments.pop("x1"), arguments.pop("x2"), arguments.pop("focal"), **arguments)


def _rotation():
    from ppo_cv import rotation

    return rotation


def _turned_bearings():
    """The bearings of RAYS and those of view 2 turned 90 degrees about y: (40, 3) each."""
    b1 = RAYS / np.linalg.norm(RAYS, axis=1, keepdims=True)
    return b1, b1 @ np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]).T


def _nan_row(rays):
    rays = rays.copy()
    rays[7, 0] = np.nan
    return rays


def _lens_fit(**changes):
    arguments = {"x1": RAYS, "x2": RAYS2, "used": np.ones(40, bool), "R": np.eye(3), **changes}
    fixed = [arguments.pop(name) for name in ("x1", "x2", "used", "R")]
    return _rotation().fit_rotation_lens(*fixed, **arguments)


CASES = {
    # negative, zero, tiny, huge, non-finite focal lengths (issue section 4)
    "recoverPose negative fx": (lambda: ppo_cv.recoverPose(E, P1, P2, _K(fx=-800)), ValueError,
                                "cameraMatrix has a negative focal length"),
    "recoverPose tiny focal": (lambda: ppo_cv.recoverPose(E, P1, P2, _K(fx=1e-200, fy=1e-200)),
                               ValueError, "cameraMatrix has an implausible focal"),
    "recoverPose nan focal": (lambda: ppo_cv.recoverPose(E, P1, P2, _K(fy=np.nan)), ValueError,
                              "cameraMatrix has 1 NaN"),
    "recoverPose focal form negative": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=-800.0),
                                        ValueError, "focal must be a finite number > 0"),
    "recoverPose focal form inf": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=np.inf),
                                   ValueError, "focal"),
    "recoverPose focal form text": (lambda: ppo_cv.recoverPose(E, P1, P2, focal="800"),
                                    TypeError, "focal must be a number"),
    "recoverPose pp nan": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=(np.nan, 1.0)),
                           ValueError, "pp must be two finite numbers"),
    "recoverPose pp wrong size": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=(1, 2, 3)),
                                  TypeError, "pp must be two numbers"),
    # (True, False) was the principal point (1, 0), texts were read as numbers: OpenCV refuses
    "recoverPose pp flags": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=(True, False)),
                             TypeError, "pp must be two numbers"),
    "recoverPose pp texts": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=("320", "240")),
                             TypeError, "pp must be two numbers"),
    "recover_pose negative K1": (lambda: ppo_cv.recover_pose(E, P1, P2, _K(fy=-800)), ValueError,
                                 "K1 has a negative focal length"),
    "recover_pose zero K2": (lambda: ppo_cv.recover_pose(E, P1, P2, K, _K(fx=0)), ValueError,
                             "K2 has a zero focal length"),
    "recover_pose principal point 1e300": (lambda: ppo_cv.recover_pose(E, P1, P2, _K(cx=1e300)),
                                           ValueError, "K1 has a skew or principal point"),
    "estimate_pair negative K1": (_pair(K1=_K(fx=-800)), ValueError, "K1 has a negative"),
    "estimate_pair tiny K2": (_pair(K2=_K(fx=1e-200)), ValueError, "K2 has an implausible"),
    # matrices that are not essential: a fundamental matrix in pixels, rank 3, rank 1
    "recoverPose F for E": (lambda: ppo_cv.recoverPose(_fundamental(), P1, P2, K), ValueError,
                            "E is not an essential matrix"),
    "recover_pose F for E": (lambda: ppo_cv.recover_pose(_fundamental(), P1, P2, K), ValueError,
                             "two largest differ by a factor"),
    "recoverPose identity E": (lambda: ppo_cv.recoverPose(np.eye(3), P1, P2, K), ValueError,
                               "it has rank 3"),
    "recover_pose rank-1 E": (lambda: ppo_cv.recover_pose(np.outer([1, 2, 3], [1, 0, 1]), P1, P2,
                                                          K), ValueError, "it has rank 1"),
    # points that overflow
    "recoverPose points 1e300": (lambda: ppo_cv.recoverPose(E, P1, _points(3, 1e300), K),
                                 ValueError, "points2 has coordinates up to 1e+300"),
    "recover_pose points 1e9": (lambda: ppo_cv.recover_pose(E, _points(0, -1e9), P2, K),
                                ValueError, "points1 has coordinates up to 1e+09"),
    # masks: values OpenCV does not read as 8-bit, too few selected points
    "recoverPose mask 0.5": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(0.5)),
                             ValueError, "mask values must be 0..255 whole numbers"),
    "recoverPose mask 256": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(256)),
                             ValueError, "mask values"),
    "recoverPose mask nan": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(np.nan)),
                             ValueError, "mask values"),
    "recoverPose mask -1": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(-1)),
                            ValueError, "mask values"),
    "recoverPose mask all zero": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(1, 0)),
                                  ValueError, "mask selects 0 of 40 points"),
    "recover_pose mask all zero": (lambda: ppo_cv.recover_pose(E, P1, P2, K, mask=_mask(1, 0)),
                                   ValueError, "mask selects 0 of 40 points"),
    "recover_pose mask 4 points": (lambda: ppo_cv.recover_pose(E, P1, P2, K, mask=_mask(1, 4)),
                                   ValueError, "mask selects 4 of 40 points; at least 5"),
    "recoverPose mask 1 point": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=_mask(255, 1)),
                                 ValueError, "mask selects 1 of 40"),
    "recoverPose mask text": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=np.array(["a"] * 40)),
                              TypeError, "mask must be numeric"),
    # other arguments of the drop-in and the rich API
    "form 4 prob 1.5": (_form4(prob=1.5), ValueError, "prob must be in (0, 1)"),
    "form 4 prob 0": (_form4(prob=0.0), ValueError, "prob must be a finite number > 0"),
    "form 4 method unknown": (_form4(method=12345), ValueError, "method must be one of"),
    "form 4 method text": (_form4(method="ransac"), TypeError, "method must be an int flag"),
    "form 4 threshold inf": (_form4(threshold=np.inf), ValueError, "threshold must be a finite"),
    "form 4 threshold 1000": (_form4(threshold=1000.0), ValueError,
                              "threshold must be in (0, 100]"),
    "form 4 distortion 1e10": (_form4(distCoeffs1=[1e10, 0, 0, 0]), ValueError,
                               "distCoeffs1: radial k1, k2"),
    "form 4 tangential 5": (_form4(distCoeffs2=[0, 0, 5.0, 0]), ValueError,
                            "distCoeffs2: tangential p1, p2"),
    "recoverPose distanceThresh nan": (
        lambda: ppo_cv.recoverPose(E, P1, P2, K, distanceThresh=np.nan), ValueError,
        "distanceThresh"),
    "recover_pose pri_threshold -1": (
        lambda: ppo_cv.recover_pose(E, P1, P2, K, pri_threshold=-1), ValueError,
        "pri_threshold must be a number in [0, 1]"),
    "recover_pose pri_threshold 2": (
        lambda: ppo_cv.recover_pose(E, P1, P2, K, pri_threshold=2.0), ValueError,
        "pri_threshold must be a number in [0, 1] (the paper's is 0.015), got 2.0"),
    "recover_pose pri_threshold nan": (
        lambda: ppo_cv.recover_pose(E, P1, P2, K, pri_threshold=np.nan), ValueError,
        "pri_threshold"),
    # True is no number: it read as 1 (every pair a pure rotation, a focal length of 1 px)
    "recover_pose pri_threshold True": (
        lambda: ppo_cv.recover_pose(E, P1, P2, K, pri_threshold=True), TypeError,
        "pri_threshold must be a number, got True"),
    "recoverPose focal True": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=True), TypeError,
                               "focal must be a number, got True"),
    "recoverPose distanceThresh True": (
        lambda: ppo_cv.recoverPose(E, P1, P2, K, distanceThresh=np.True_), TypeError,
        "distanceThresh must be a number, got np.True_"),
    "form 4 threshold True": (_form4(threshold=True), TypeError, "threshold must be a number"),
    "run_sfm target_tri_angle True": (lambda: _sfm(target_tri_angle=True), TypeError,
                                      "target_tri_angle must be a number, got True"),
    "recover_pose pri_threshold text": (
        lambda: ppo_cv.recover_pose(E, P1, P2, K, pri_threshold="x"), TypeError,
        "pri_threshold must be a number"),
    # estimate_pair: options, thresholds, distortion, images
    "estimate_pair options not PairOptions": (_pair(options={"features": "sift"}), TypeError,
                                              "options must be a PairOptions"),
    "run_sfm K flat 4": (lambda: _sfm_module().run_sfm(".", None, K=[535.4, 539.2, 320.1, 247.6]),
                         ValueError, "K must be a 3x3 matrix, got shape (4,) (fx, fy, cx, "
                         "cy? give [[fx, 0, cx], [0, fy, cy], [0, 0, 1]])"),
    "estimate_pair K1 flat 9": (_pair(K1=K.ravel()), ValueError,
                                "K1 must be a 3x3 matrix, got shape (9,) (the 9 entries of K? "
                                "reshape them to (3, 3), row by row)"),
    "PairOptions max_image_size 0": (lambda: PairOptions(max_image_size=0), ValueError,
                                     "max_image_size must be a whole number in 32..2147483647, "
                                     "got 0 (None: full size)"),
    # ORB failed on it in OpenCV with std::bad_alloc, mid-run
    "PairOptions max_features beyond ORB": (
        lambda: PairOptions(features="orb", max_features=2**31 - 1), ValueError,
        "max_features must be a whole number in 8..1000000, got 2147483647"),
    "PairOptions threshold inf": (lambda: PairOptions(ransac_threshold=np.inf), ValueError,
                                  "ransac_threshold must be in (0, 100]"),
    "PairOptions threshold nan": (lambda: PairOptions(ransac_threshold=np.nan), ValueError,
                                  "ransac_threshold"),
    "PairOptions threshold 101": (lambda: PairOptions(ransac_threshold=101.0), ValueError,
                                  "ransac_threshold"),
    "PairOptions pri_threshold -1": (lambda: PairOptions(pri_threshold=-1.0), ValueError,
                                     "pri_threshold must be a number in [0, 1]"),
    "PairOptions pri_threshold 1.5": (lambda: PairOptions(pri_threshold=1.5), ValueError,
                                      "pri_threshold must be a number in [0, 1]"),
    "PairOptions pri_threshold inf": (lambda: PairOptions(pri_threshold=np.inf), ValueError,
                                      "pri_threshold must be a number in [0, 1]"),
    "PairOptions max_log10_nfa nan": (lambda: PairOptions(max_log10_nfa=np.nan), ValueError,
                                      "max_log10_nfa"),
    # options under which every pair is refused: no consensus is below -inf, and a pair has
    # no more matches than keypoints
    "PairOptions max_log10_nfa -inf": (lambda: PairOptions(max_log10_nfa=-np.inf), ValueError,
                                       "max_log10_nfa is -inf: no consensus is below it"),
    "PairOptions min_inliers beyond max_features": (
        lambda: PairOptions(max_features=100, min_inliers=101), ValueError,
        "min_inliers (101) exceeds max_features (100)"),
    "PairOptions ratio complex": (lambda: PairOptions(ratio=np.complex128(0.8)), TypeError,
                                  "ratio must be a real number, got complex128"),
    "estimate_pair dist 1e10": (_pair(dist1=[1e10, 0, 0, 0]), ValueError,
                                "dist1: radial k1, k2 [10000000000.0, 0.0]"),
    "estimate_pair dist k3 50": (_pair(dist1=[0, 0, 0, 0, 50.0]), ValueError, "dist1: radial k3"),
    "estimate_pair dist2 tangential": (_pair(K2=K, dist2=[0, 0, 0, 2.0]), ValueError,
                                       "dist2: tangential"),
    "estimate_pair NaN pixel": (_pair(image1=_image_with_nan()), ValueError,
                                "image1 has 1 NaN or infinite pixel"),
    "estimate_pair image None": (_pair(image2=None), TypeError, "image2 is required"),
    # no calibration: the message names the EXIF camera ppo-cv itself would guess
    "estimate_pair K1 None": (_pair(K1=None), TypeError,
                              "K1 is required, got None (no calibration? "
                              "ppo_cv.camera_from_exif(image)[0].K is the camera"),
    "estimate_pair image bytes": (_pair(image1=b"img1.png"), TypeError,
                                  "image1 must be an image array or a path (str or "),
    "estimate_pair sizes differ without K2": (_pair(image2=GREY[:40]), ValueError,
                                              "pass K2 for image2"),
    "estimate_pair image text dtype": (_pair(image1=np.full((8, 8), "a")), TypeError,
                                       "image1 must hold numbers"),
    "estimate_pair constant 16-bit image": (_pair(image1=np.full((48, 64), 1000, np.uint16)),
                                            ValueError, "image1 has too few features (0)"),
    "estimate_pair 60000x1 image": (_pair(image1=np.zeros((1, 60000), np.uint8), K2=K),
                                    ValueError, "image1 is 60000x1 pixels: too small or too thin"),
    "estimate_pair 40x12 image": (_pair(image2=GREY[:12, :40], K2=K), ValueError,
                                  "image2 is 40x12 pixels"),
    # thin only once reduced to max_image_size: the message did not say how to keep it
    "estimate_pair 4000x30 image": (
        _pair(image1=np.zeros((30, 4000), np.uint8), K2=K), ValueError,
        "reduced to 2000: a larger max_image_size (--max-size), or 0 for the full size, keeps it"),
    # options that reached pycolmap or numpy unchecked, or read "no" as true
    "PairOptions seed -1": (lambda: PairOptions(seed=-1), ValueError,
                            "seed must be a whole number in 0..2147483647, got -1"),
    "PairOptions seed 2**40": (lambda: PairOptions(seed=2**40), ValueError, "seed must be"),
    "PairOptions seed text": (lambda: PairOptions(seed="1"), TypeError,
                              "seed must be a whole number, got str"),
    "PairOptions max_features 100.5": (lambda: PairOptions(max_features=100.5), ValueError,
                                       "max_features must be a whole number in 8.."),
    "PairOptions max_features text": (lambda: PairOptions(max_features="a"), TypeError,
                                      "max_features must be a whole number"),
    "PairOptions ratio text": (lambda: PairOptions(ratio="0.8"), TypeError,
                               "ratio must be a number"),
    "PairOptions plane 'no'": (lambda: PairOptions(plane="no"), TypeError,
                               "plane must be True or False, got str 'no'"),
    # structure from motion: numbers and keywords checked before the features are extracted
    "run_sfm max_num_features 0": (lambda: _sfm(max_num_features=0), ValueError,
                                   "max_num_features must be a whole number in 1..100000"),
    "run_sfm num_threads text": (lambda: _sfm(num_threads="2"), TypeError,
                                 "num_threads must be a whole number"),
    "run_sfm seed 2**40": (lambda: _sfm(seed=2**40), ValueError, "seed must be a whole number"),
    "run_sfm scoring typo": (lambda: _sfm(min_inlier=3), TypeError,
                             "unexpected keyword argument 'min_inlier'; the scoring takes"),
    "run_sfm scoring text": (lambda: _sfm(pri_threshold="x"), TypeError,
                             "pri_threshold must be a number"),
    "score_pairs not a database": (lambda: _sfm_module().score_pairs(__file__), ValueError,
                                   "is not a COLMAP database (no SQLite header)"),
    "recoverPose 14 positional": (lambda: ppo_cv.recoverPose(E, P1, P2, K, *[None] * 10), TypeError,
                                  "recoverPose(E, points1, points2, cameraMatrix, ...) takes at "
                                  "most 7 positional arguments, got 14"),
    # paths that are not paths, or no folder: named before anything is read
    "estimate_pair image1 5": (_pair(image1=5), TypeError,
                               "image1 must be an image array or a path (str or os.PathLike), got "
                               "int 5"),
    "run_sfm image_dir None": (lambda: _sfm_module().run_sfm(None, None, K=K), TypeError,
                               "image_dir must be a path (str or os.PathLike), got NoneType"),
    "run_sfm output_dir 5": (lambda: _sfm_module().run_sfm(".", 5, K=K), TypeError,
                             "output_dir must be a path"),
    "score_pairs None": (lambda: _sfm_module().score_pairs(None), TypeError,
                         "database_path must be a path"),
    # an empty path (an unset variable) is no name: Path("") would be the current folder
    "estimate_pair image1 empty": (_pair(image1=""), ValueError,
                                   "image1 is an empty path, not a file or folder name"),
    "run_sfm image_dir empty": (lambda: _sfm_module().run_sfm("", "model", K=K), ValueError,
                                "image_dir is an empty path"),
    "run_sfm output_dir empty": (lambda: _sfm_module().run_sfm(".", "", K=K), ValueError,
                                 "output_dir is an empty path"),
    "score_pairs empty": (lambda: _sfm_module().score_pairs(""), ValueError,
                          "database_path is an empty path"),
    "load_calibration empty": (lambda: ppo_cv.load_calibration(""), ValueError,
                               "path is an empty path"),
    "write_outputs directory empty": (
        lambda: ppo_cv.write_outputs("", None, GREY, GREY), ValueError,
        "directory is an empty path"),
    "estimate_pair K text": (_pair(K1="535.4,539.2,320.1,247.6"), TypeError,
                             "K1 must be an array of real numbers, got str: parse a text with "
                             "ppo_cv.parse_intrinsics"),
    "estimate_pair K a Camera": (_pair(K1=ppo_cv.Camera(K)), TypeError,
                                 "K1 must be an array of real numbers, got Camera: pass its .K "
                                 "(and its .dist as the distortion)"),
    # hooks: given features that were ignored, a progress that failed as 'not callable'
    "estimate_pair features1 text": (_pair(features1="x", features2="y"), TypeError,
                                     "features1 must be ppo_cv.features.Features, got str"),
    "estimate_pair features2 alone": (
        lambda: ppo_cv.estimate_pair(GREY, GREY[::-1].copy(), K,
                                     features2=ppo_cv.features.detect_features(GREY)),
        ValueError, "give both features1 and features2, or neither"),
    "estimate_pair progress 5": (_pair(progress=5), TypeError,
                                 "progress must be a callable taking a stage name, got int"),
    "run_sfm verbose 'no'": (lambda: _sfm(verbose="no"), TypeError,
                             "verbose must be True or False, got str 'no'"),
    "run_sfm exif_orientation 'no'": (lambda: _sfm(exif_orientation="no"), TypeError,
                                      "exif_orientation must be True or False, got str 'no'"),
    "run_sfm overwrite 'yes'": (lambda: _sfm(overwrite="yes"), TypeError,
                                "overwrite must be True or False, got str 'yes'"),
    "run_sfm progress 5": (lambda: _sfm(progress=5), TypeError,
                           "progress must be a callable taking a message, got int"),
    "an output's overwrite 'no'": (
        lambda: __import__("ppo_cv.atomic").atomic.check_target("out", "folder", "no"),
        TypeError, "overwrite must be True or False, got str"),
    "camera_from_exif exif_orientation 'no'": (
        lambda: ppo_cv.camera_from_exif(__file__, exif_orientation="no"), TypeError,
        "exif_orientation must be True or False, got str 'no'"),
    "load_image exif_orientation 'no'": (
        lambda: load_image(__file__, exif_orientation="no"), TypeError,
        "exif_orientation must be True or False, got str 'no'"),
    "load_image None": (lambda: load_image(None), TypeError,
                        "path must be a path (str or os.PathLike), got NoneType"),
    "load_calibration None": (lambda: ppo_cv.load_calibration(None), TypeError,
                              "path must be a path (str or os.PathLike), got NoneType"),
    "parse_intrinsics names no option": (lambda: ppo_cv.parse_intrinsics("a,b"), ValueError,
                                         "intrinsics must be numbers separated by commas"),
    "parse_distortion names no option": (lambda: ppo_cv.calib.parse_distortion("1"), ValueError,
                                         "distortion must be OpenCV distortion coefficients"),
    "reconstruct no image folder": (lambda: _sfm_module().reconstruct(__file__, "no such folder"),
                                    ValueError, "image folder 'no such folder' does not exist"),
    # the sfm helpers: an AttributeError of None, a NaN bound that passed, a log's warning
    "score_pose None": (lambda: _sfm_module().score_pose(None), TypeError,
                        "pose must be a ppo_cv.pose.PoseResult or ppo_cv.result.PairResult, "
                        "got NoneType"),
    "score_pose min_inliers NaN": (
        lambda: _sfm_module().score_pose(ppo_cv.recover_pose(E, P1, P2, K), min_inliers=np.nan),
        ValueError, "min_inliers must be a whole number in 0..2147483647, got nan"),
    "score_pose motion text": (
        lambda: _sfm_module().score_pose(ppo_cv.recover_pose(E, P1, P2, K), motion="rotation"),
        TypeError, "motion must be a ppo_cv.motion_model.MotionDecision, got str"),
    # the pose functions of ppo_cv.refine: numpy's "SVD did not converge" (LinAlgError) for a
    # NaN match, an IndexError or a silent misreading for a mask of indices
    "refine pose_sigmas_deg NaN match": (
        lambda: _refine().pose_sigmas_deg(R_TRUE, T_TRUE, _rays(np.nan), _rays(), _ALL),
        ValueError, "x1 has 1 NaN or infinite value(s)"),
    "refine refine_pose_radial NaN match": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(np.nan), _rays(), _ALL,
                                             scale=1e-3), ValueError, "x1 has 1 NaN"),
    "refine checked_inliers NaN match": (
        lambda: _refine().checked_inliers(R_TRUE, T_TRUE, _rays(np.nan), _rays(), _ALL),
        ValueError, "x1 has 1 NaN"),
    "refine pose_information index mask": (
        lambda: _refine().pose_information(R_TRUE, T_TRUE, _rays(), _rays(), np.arange(40)),
        TypeError, "inliers must be a mask of bool, got dtype int64"),
    "refine refine_pose points of two": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, P1, P2, _ALL, 800.0), ValueError,
        "x1 must have shape (N, 3), got (40, 2)"),
    "refine translation_sigma_deg no rotation": (
        lambda: _refine().translation_sigma_deg(2 * R_TRUE, T_TRUE, _rays(), _rays(), _ALL),
        ValueError, "R is not a rotation matrix"),
    "refine k1_noise_bias NaN t": (
        lambda: _refine().k1_noise_bias(R_TRUE, [np.nan, 0, 1], _rays(), _rays(), 1e-3),
        ValueError, "t has 1 NaN"),
    # pycolmap stopped the process (a failed Ceres check) for a focal length of 0, NaN or
    # 1e300, a t of 1e300 and rays far out; NaN and RuntimeWarnings for a t of 1e-300, priors
    # and counts read as given (a negative iteration count, a NaN prior), numpy's own errors
    "refine refine_pose zero focal": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, 0.0), ValueError,
        "focal must be a finite number > 0, got 0.0"),
    "refine refine_pose NaN focal": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, np.nan),
        ValueError, "focal must be a finite number > 0, got nan"),
    "refine refine_pose huge focal": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, 1e300), ValueError,
        "focal must be in (0, 1e+08] pixels, got 1e+300"),
    "refine refine_pose rays at infinity": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, _rays() * [1, 1, 0], _rays(), _ALL, 800.0),
        ValueError, "x1 has 40 row(s) with w = 0 or |(x, y)| beyond 1e+06 |w|"),
    "refine refine_pose rays near the image plane": (
        lambda: _refine().refine_pose(R_TRUE, T_TRUE, _rays(), _rays() * [1e8, 1e8, 1], _ALL,
                                      800.0), ValueError, "x2 has 40 row(s) with w = 0"),
    "refine refine_pose_radial zero scale": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=0.0),
        ValueError, "scale must be a finite number > 0, got 0.0"),
    "refine refine_pose_radial zero k1_prior": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=1e-3,
                                             k1_prior=0.0), ValueError, "k1_prior must be"),
    "refine refine_pose_radial negative iterations": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=1e-3,
                                             iterations=-1), ValueError,
        "iterations must be a whole number in 0.."),
    "refine refine_pose_radial NaN max_k1": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=1e-3,
                                             max_k1=np.nan), ValueError,
        "max_k1 must be a finite number >= 0, got nan"),
    "refine refine_pose_radial NaN focal_prior": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=1e-3,
                                             focal_prior=np.nan), ValueError,
        "focal_prior must be a finite number >= 0, got nan"),
    "refine refine_pose_radial principal_prior of three": (
        lambda: _refine().refine_pose_radial(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, scale=1e-3,
                                             principal_prior=np.ones(3)), ValueError,
        "principal_prior must be one number or two (x, y), got shape (3,)"),
    "refine pose_sigmas_deg zero step": (
        lambda: _refine().pose_sigmas_deg(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, step=0.0),
        ValueError, "step must be a finite number > 0, got 0.0"),
    "refine pose_sigmas_deg negative noise": (
        lambda: _refine().pose_sigmas_deg(R_TRUE, T_TRUE, _rays(), _rays(), _ALL, noise=-1.0),
        ValueError, "noise must be a finite number >= 0, got -1.0"),
    "refine pose_sigmas_deg NaN held_k1_prior": (
        lambda: _refine().pose_sigmas_deg(R_TRUE, T_TRUE, _rays(), _rays(), _ALL,
                                          held_k1_prior=np.nan), ValueError,
        "held_k1_prior must be a finite number >= 0, got nan"),
    "refine pose_sigmas_deg negative k1_prior": (
        lambda: _refine().pose_sigmas_deg(R_TRUE, T_TRUE, _rays(), _rays(), _ALL,
                                          k1_prior=-1.0), ValueError,
        "k1_prior must be a finite number > 0, got -1.0"),
    "refine k1_noise_bias one replicate": (
        lambda: _refine().k1_noise_bias(R_TRUE, T_TRUE, _rays(), _rays(), 1e-3, replicates=1),
        ValueError, "replicates must be a whole number in 2.."),
    "refine released_lens_shift_deg NaN k1": (
        lambda: _refine().released_lens_shift_deg(R_TRUE, T_TRUE, np.nan, _rays(), _rays(),
                                                  _ALL, 1e-3), ValueError,
        "k1 must be a finite number in [-10, 10], got nan"),
    "refine released_lens_shift_deg negative replicates": (
        lambda: _refine().released_lens_shift_deg(R_TRUE, T_TRUE, 0.1, _rays(), _rays(), _ALL,
                                                  1e-3, replicates=-1), ValueError,
        "replicates must be a whole number in 0.."),
    "refine fit_rotation matches of two lengths": (
        lambda: _refine().fit_rotation(_rays(), _rays()[:30], _ALL, 1e-3), ValueError,
        "x1 and x2 must have the same length, got 40 and 30"),
    "refine fit_rotation index mask": (
        lambda: _refine().fit_rotation(_rays(), _rays(), np.arange(40), 1e-3), TypeError,
        "inliers must be a mask of bool, got dtype int64"),
    "refine fit_rotation no match allowed": (
        lambda: _refine().fit_rotation(_rays(), _rays(), ~_ALL, 1e-3), ValueError,
        "inliers selects 0 matches: a rotation needs at least 2"),
    "refine fit_rotation NaN threshold": (
        lambda: _refine().fit_rotation(_rays(), _rays(), _ALL, np.nan), ValueError,
        "threshold must be a finite number > 0, got nan"),
    "refine fit_rotation a zero row": (
        lambda: _refine().fit_rotation(_rays() * (np.arange(40) > 0)[:, None], _rays(), _ALL,
                                       1e-3), ValueError, "x1 has a zero row"),
    "refine rotation_residuals points of two": (
        lambda: _refine().rotation_residuals(R_TRUE, P1, P2), ValueError,
        "x1 must have shape (N, 3), got (40, 2)"),
    "refine checked_matches flat J": (
        lambda: _refine().checked_matches(np.ones(3)), ValueError,
        "J must have shape (N, P), got (3,)"),
    "refine checked_matches NaN J": (
        lambda: _refine().checked_matches(np.full((10, 3), np.nan)), ValueError,
        "J has 30 NaN or infinite value(s)"),
    "refine huber_bound_px negative threshold": (
        lambda: _refine().huber_bound_px(-1.0, 0.5), ValueError,
        "threshold_px must be a finite number > 0, got -1.0"),
    # AttributeErrors ("'NoneType' object has no attribute 'pure_rotation'", "... 'n'",
    # "... 'R'", "... 'num_inliers'", "... 'backend'", "... 'dimension'", "... 'camera_size'"),
    # a count of 10**400 chunked without end, a scale of 0 divided by
    "guessed_camera fitted_focal_scale None": (
        lambda: __import__("ppo_cv.guessed_camera").guessed_camera.fitted_focal_scale(None),
        TypeError, "result must be a ppo_cv.result.PairResult, got NoneType (estimate_pair)"),
    "guessed_camera decide_with_fitted_focal text": (
        lambda: __import__("ppo_cv.guessed_camera").guessed_camera.decide_with_fitted_focal(
            "result.json", [GREY, GREY], PairOptions()), TypeError,
        "result must be a ppo_cv.result.PairResult, got str (estimate_pair)"),
    "guessed_camera clipped_lens_focal_scale None": (
        lambda: __import__("ppo_cv.guessed_camera").guessed_camera.clipped_lens_focal_scale(
            None, 1.0), TypeError,
        "result must be a ppo_cv.result.PairResult, got NoneType (estimate_pair)"),
    "guessed_camera lens_focal_scale zero scale": (
        lambda: __import__("ppo_cv.guessed_camera").guessed_camera.lens_focal_scale(
            None, 0.0, 1.0), ValueError, "scale must be a finite number > 0, got 0.0"),
    "plane frontality None": (
        lambda: __import__("ppo_cv.plane").plane.frontality(None), TypeError,
        "candidates must be a ppo_cv.plane.HomographyCandidates, got NoneType"),
    "motion_model with_rotation None": (
        lambda: __import__("ppo_cv.motion_model").motion_model.with_rotation(
            None, None, RAYS, RAYS2, 800.0), TypeError,
        "motion must be a ppo_cv.motion_model.MotionDecision, got NoneType"),
    "motion_model with_tracks None": (
        lambda: __import__("ppo_cv.motion_model").motion_model.with_tracks(
            None, None, None, RAYS, RAYS2, 800.0), TypeError,
        "motion must be a ppo_cv.motion_model.MotionDecision, got NoneType"),
    "homography require_unmirrored text": (
        lambda: __import__("ppo_cv.homography").homography.require_unmirrored("H"), TypeError,
        "homography must be a ppo_cv.homography.HomographyEstimate or None, got str"),
    "consensus ransac_keywords dict": (
        lambda: __import__("ppo_cv.consensus").consensus.ransac_keywords({"backend": "x"}),
        TypeError, "options must be a ppo_cv.options.PairOptions, got dict"),
    "model_selection model_noise None": (
        lambda: ppo_cv.model_selection.model_noise(None), TypeError,
        "candidates must be a list of ModelResiduals, got NoneType"),
    "model_selection select_model texts": (
        lambda: ppo_cv.model_selection.select_model(["rotation", "general"]), TypeError,
        "each of candidates must be a ppo_cv.model_selection.ModelResiduals, got str"),
    "model_selection select_model empty": (
        lambda: ppo_cv.model_selection.select_model([]), ValueError,
        "candidates is empty: at least one candidate model is needed"),
    "calib exif_focal_scale None": (
        lambda: ppo_cv.calib.exif_focal_scale(None, (640, 480)), TypeError,
        "layout must be a ppo_cv.images.ExifLayout, got NoneType"),
    # the image's size was read as "side" (max(size)), a 0-d one raised numpy's iteration error
    "calib fitted_exif_focal size 0-d": (
        lambda: ppo_cv.calib.fitted_exif_focal(500.0, ppo_cv.images.ExifLayout(), np.array(640)),
        TypeError, "size must be (width, height)"),
    "calib fitted_exif_focal size NaN": (
        lambda: ppo_cv.calib.fitted_exif_focal(500.0, ppo_cv.images.ExifLayout(), (640, np.nan)),
        ValueError, "size height must be a whole number"),
    "calib warn_implausible shape NaN": (
        lambda: ppo_cv.calib.warn_implausible(K, (np.nan, 640), "K"), ValueError,
        "image_shape height must be a whole number"),
    "calib fitted_exif_focal text focal": (
        lambda: ppo_cv.calib.fitted_exif_focal("500", None, (640, 480)), TypeError,
        "focal must be a number, got str"),
    "lsq row_chunks huge count": (
        lambda: __import__("ppo_cv.lsq").lsq.row_chunks(10**400, 3), ValueError,
        "count must be a whole number in 0..2147483647, got <401-digit integer>"),
    # parallax: IndexErrors ("invalid index to scalar variable") for None or a number as the
    # scales, numpy's LinAlgError for None as H, "could not convert string to float"; a
    # scale of 1e3 overflowed exp into NaN spreads
    "parallax focal_conjugates scalar scales": (
        lambda: __import__("ppo_cv.parallax").parallax.focal_conjugates(np.eye(3), 0.1), ValueError,
        "log_scales must be a sequence of numbers, got shape ()"),
    "parallax rotation_spread None H": (
        lambda: __import__("ppo_cv.parallax").parallax.rotation_spread(None, [0.0, 0.1]), TypeError,
        "H is required, got None"),
    "parallax nearest_rotation_log_scale huge scales": (
        lambda: __import__("ppo_cv.parallax").parallax.nearest_rotation_log_scale(
            np.eye(3), [-1e3, 0.0, 1e3]),
        ValueError, "log_scales must ascend within +-50"),
    "parallax nearest_rotation_log_scale unsorted": (
        lambda: __import__("ppo_cv.parallax").parallax.nearest_rotation_log_scale(
            np.eye(3), [0.1, 0.0, -0.1]),
        ValueError, "log_scales must ascend within +-50, got [0.1, 0.0, -0.1]"),
    "parallax homography_parallax H of two rows": (
        lambda: __import__("ppo_cv.parallax").parallax.homography_parallax(np.eye(3)[:2]),
        ValueError, "H must be a 3x3 matrix, got shape (2, 3)"),
    "parallax fit_plane_parallax text": (
        lambda: __import__("ppo_cv.parallax").parallax.fit_plane_parallax("x1", RAYS), TypeError,
        "x1 must be an array of real numbers, got str"),
    # '<' not supported for None; a fractional consensus, a negative one and no sample read as
    # given (a count of trials for 20.5 matches; inf; 1 trial)
    "robust trials_for_consensus None": (
        lambda: ppo_cv.robust.trials_for_consensus(None, 100, 0.05), TypeError,
        "consensus must be a whole number, got NoneType None"),
    "robust trials_for_consensus fraction": (
        lambda: ppo_cv.robust.trials_for_consensus(20.5, 100, 0.05), ValueError,
        "consensus must be a whole number in 0..2147483647, got 20.5"),
    "robust trials_for_consensus no sample": (
        lambda: ppo_cv.robust.trials_for_consensus(20, 100, 0.05, 0), ValueError,
        "sample_size must be a whole number in 1..2147483647, got 0"),
    # an AttributeError for None ("'NoneType' object has no attribute 'tolist'"); matrices that
    # are no SVD's gave "rotations" that are none, zero singular values NaN
    "ppo candidates_from_svd None": (
        lambda: ppo_cv.ppo.candidates_from_svd(None, [1.0, 1.0, 0.0], np.eye(3)), TypeError,
        "U is required, got None"),
    "ppo candidates_from_svd not orthogonal": (
        lambda: ppo_cv.ppo.candidates_from_svd(np.eye(3), [1.0, 1.0, 0.0], np.ones((3, 3))),
        ValueError, "Vt must be an orthogonal 3x3 matrix (of an SVD)"),
    "ppo candidates_from_svd zero singular values": (
        lambda: ppo_cv.ppo.candidates_from_svd(np.eye(3), np.zeros(3), np.eye(3)), ValueError,
        "s must be three singular values >= 0, not all zero"),
    # unique_pixel_pairs: a negative index wrapped to the last keypoint, five distances for ten
    # matches kept five rows, a step of 0 raised RuntimeWarnings, NaN keypoints a cast warning;
    # require_detectable: "'NoneType' object is not subscriptable", "tuple index out of range"
    "features unique_pixel_pairs negative index": (
        lambda: ppo_cv.features.unique_pixel_pairs(np.c_[np.arange(40), np.arange(40)] - 1, P1,
                                                   P2, np.ones(40)), ValueError,
        "matches column 0 must index keypoints1 (0..39)"),
    "features unique_pixel_pairs distances short": (
        lambda: ppo_cv.features.unique_pixel_pairs(np.c_[np.arange(40), np.arange(40)], P1, P2,
                                                   np.ones(5)), ValueError,
        "distances must have one per match (40,), got (5,)"),
    "features unique_pixel_pairs zero step": (
        lambda: ppo_cv.features.unique_pixel_pairs(np.c_[np.arange(40), np.arange(40)], P1, P2,
                                                   np.ones(40), 0.0), ValueError,
        "resolution must be a finite number > 0, got 0.0"),
    "features unique_pixel_pairs float matches": (
        lambda: ppo_cv.features.unique_pixel_pairs(np.ones((40, 2)), P1, P2, np.ones(40)),
        TypeError, "matches must be index pairs of integers, got dtype float64"),
    "features require_detectable None": (
        lambda: ppo_cv.features.require_detectable(None, "image"), TypeError,
        "shape must be an image's shape (H, W[, C]), got None"),
    "features require_detectable one side": (
        lambda: ppo_cv.features.require_detectable((5,), "image"), TypeError,
        "shape must be an image's shape (H, W[, C]), got (5,)"),
    # AttributeErrors: "'NoneType' object has no attribute 'backend'", "... 'img1'"; numpy's
    # "diag requires an array of at least two dimensions", AxisError; a NaN covariance gave a
    # NaN angle and flags of 0.5 read as True
    "consensus detect_both no options": (
        lambda: __import__("ppo_cv.consensus").consensus.detect_both(GREY, GREY, None),
        TypeError, "options must be a ppo_cv.options.PairOptions, got NoneType"),
    "consensus best_consensus no inputs": (
        lambda: __import__("ppo_cv.consensus").consensus.best_consensus(
            None, None, None, PairOptions(), print), TypeError,
        "inputs must be a ppo_cv.consensus.PairInputs, got NoneType"),
    "plane rms_rotation_angle_deg NaN": (
        lambda: __import__("ppo_cv.plane").plane.rms_rotation_angle_deg(np.full((3, 3), np.nan)),
        ValueError, "covariance has 9 NaN or infinite value(s)"),
    "plane rms_rotation_angle_deg None": (
        lambda: __import__("ppo_cv.plane").plane.rms_rotation_angle_deg(None), TypeError,
        "covariance is required, got None"),
    "plane support_ties fractions": (
        lambda: __import__("ppo_cv.plane").plane.support_ties(np.full((2, 5), 0.5)), TypeError,
        "in_front must be a (K, N) array of bool, got float64 of shape (2, 5)"),
    "ppo frame_scores None": (
        lambda: ppo_cv.ppo.frame_scores(None, np.ones((2, 3, 5))), TypeError,
        "F is required, got None"),
    "ppo frame_scores points of one view": (
        lambda: ppo_cv.ppo.frame_scores(np.ones((2, 3, 3)), np.ones((3, 5))), ValueError,
        "points must have shape (2, 3, N), got (3, 5)"),
    "ppo frame_scores NaN point": (
        lambda: ppo_cv.ppo.frame_scores(np.ones((2, 3, 3)), np.full((2, 3, 5), np.nan)),
        ValueError, "points has 30 NaN or infinite value(s)"),
    "ppo frame_maps not orthogonal": (
        lambda: ppo_cv.ppo.frame_maps(np.ones((3, 3)), np.eye(3)), ValueError,
        "U must be an orthogonal 3x3 matrix (of an SVD)"),
    # estimate_essential_ordered: "'NoneType' object is not subscriptable", LinAlgError for a
    # singular K2, the text "no" read as true and a NaN bar as no bar
    "robust estimate_essential_ordered no image size": (
        lambda: ppo_cv.robust.estimate_essential_ordered(RAYS, RAYS2, 800.0, np.ones(40), None),
        TypeError, "image_size must be (width, height), got None"),
    "robust estimate_essential_ordered singular K2": (
        lambda: ppo_cv.robust.estimate_essential_ordered(
            RAYS, RAYS2, 800.0, np.ones(40), (640, 480), K2=np.ones((3, 3))), ValueError,
        "K2 must be upper triangular"),
    "robust estimate_essential_ordered flag text": (
        lambda: ppo_cv.robust.estimate_essential_ordered(
            RAYS, RAYS2, 800.0, np.ones(40), (640, 480), uniform_when_weak="no"), TypeError,
        "uniform_when_weak must be True or False, got str 'no'"),
    "robust estimate_essential_ordered NaN bar": (
        lambda: ppo_cv.robust.estimate_essential_ordered(
            RAYS, RAYS2, 800.0, np.ones(40), (640, 480), max_log10_nfa=np.nan), ValueError,
        "max_log10_nfa must be a number (inf: every consensus), got nan"),
    # ZeroDivisionError for a Huber bound of 0, LinAlgError for NaN; "Value after * must be an
    # iterable" and AttributeErrors for minima that are none; a RuntimeWarning for a plane at
    # distance 0 and a zero normal read as a plane; RuntimeWarnings for a zero homography
    "valley valley_minima zero scale": (
        lambda: __import__("ppo_cv.valley").valley.valley_minima(R_TRUE, T_TRUE, _rays(), RAYS2,
                                                                0.0), ValueError,
        "scale must be a finite number > 0, got 0.0"),
    "valley valley_outcome minima None": (
        lambda: __import__("ppo_cv.valley").valley.valley_outcome(R_TRUE, T_TRUE, None),
        TypeError, "minima must be a list of ValleyMinimum, got NoneType"),
    "valley valley_outcome minima texts": (
        lambda: __import__("ppo_cv.valley").valley.valley_outcome(R_TRUE, T_TRUE, ["a"]),
        TypeError, "each of minima must be a ppo_cv.valley.ValleyMinimum, got str"),
    "plane homography_from_pose zero distance": (
        lambda: __import__("ppo_cv.plane").plane.homography_from_pose(R_TRUE, T_TRUE, [0, 0, 1],
                                                                      0.0), ValueError,
        "d must be a finite distance other than 0, got 0.0"),
    "plane homography_from_pose zero normal": (
        lambda: __import__("ppo_cv.plane").plane.homography_from_pose(R_TRUE, T_TRUE, [0, 0, 0],
                                                                      1.0), ValueError,
        "n is zero: a plane needs a normal"),
    "plane decompose_homography zeros": (
        lambda: __import__("ppo_cv.plane").plane.decompose_homography(np.zeros((3, 3))),
        ValueError, "H has rank below 2: not a homography between two views"),
    # NaN points out for a NaN k1 or NaN points in; a k1 folding points over divided by zero
    # or turned them about the centre without a word
    "plane undistort_division NaN k1": (
        lambda: __import__("ppo_cv.plane").plane.undistort_division(_rays(), np.nan), ValueError,
        "k1 must be a finite number, got nan"),
    "plane undistort_division NaN point": (
        lambda: __import__("ppo_cv.plane").plane.undistort_division(_rays(np.nan), 0.1),
        ValueError, "x has 1 NaN or infinite value(s)"),
    "plane undistort_division folding k1": (
        lambda: __import__("ppo_cv.plane").plane.undistort_division(_rays() * [10, 10, 1], -1.0),
        ValueError, "k1 = -1 folds"),
    "valley valley_minima NaN match": (
        lambda: __import__("ppo_cv.valley").valley.valley_minima(
            R_TRUE, T_TRUE, _rays(np.nan), _rays(), 1e-3), ValueError, "x1 has 1 NaN"),
    # a pose of the identity without a word for a NaN match (plane), "SVD did not converge"
    "plane planar_pose NaN match": (
        lambda: __import__("ppo_cv.plane").plane.planar_pose(np.eye(3), _rays(np.nan), _rays()),
        ValueError, "x1 has 1 NaN"),
    "plane refine_planar_pose NaN match": (
        lambda: __import__("ppo_cv.plane").plane.refine_planar_pose(
            R_TRUE, T_TRUE, [0, 0, 1], _rays(np.nan), _rays()), ValueError, "x1 has 1 NaN"),
    "plane planar_pose NaN H": (
        lambda: __import__("ppo_cv.plane").plane.planar_pose(np.full((3, 3), np.nan), _rays(),
                                                             _rays()), ValueError, "H has 9 NaN"),
    "motion_model translation_for_rotation NaN match": (
        lambda: __import__("ppo_cv.motion_model").motion_model.translation_for_rotation(
            R_TRUE, _rays(np.nan), _rays()), ValueError, "x1 has 1 NaN"),
    # os.stat's "path should be string, bytes, os.PathLike or integer" naming no argument, an
    # AttributeError for bytes, a ZeroDivisionError for a size of 0, a size of -1 computed on
    "images exif_layout None": (lambda: ppo_cv.images.exif_layout(None), TypeError,
                                "path must be a path (str or os.PathLike), got NoneType"),
    "images case_alike bytes": (lambda: ppo_cv.images.case_alike(b"IMG_1.jpg"), TypeError,
                                "path must be a path (str or os.PathLike), got bytes"),
    "images decoded_transposed width 0": (
        lambda: ppo_cv.images.decoded_transposed("a.jpg", 0, 480), ValueError,
        "stored size width must be a whole number in 1.."),
    "features detection_size 0": (
        lambda: ppo_cv.features.detection_size((480, 640), 0), ValueError,
        "max_image_size must be a whole number in 1.."),
    "features detection_scale -1": (
        lambda: ppo_cv.features.detection_scale((480, 640), -1), ValueError,
        "max_image_size must be a whole number in 1.."),
    # significance: IndexErrors for a negative count ("index 11 is out of bounds"), NaN read as
    # an answer (101), a RuntimeWarning for a negative threshold, AttributeErrors for lists
    "significance log10_binomial k beyond n": (
        lambda: _significance().log10_binomial(10, -1), ValueError,
        "log10_binomial needs 0 <= k <= n, got n=array(10) and k=array(-1)"),
    "significance log10_binomial fractions": (
        lambda: _significance().log10_binomial(10.5, 3), TypeError,
        "n and k must be integers, got dtypes float64 and int64"),
    "significance log10_binomial shapes that do not broadcast": (
        lambda: _significance().log10_binomial(np.array([10, 20, 30]), np.array([1, 2])),
        ValueError, "n and k must broadcast together, got shapes (3,) and (2,)"),
    "significance log10_binomial no n for some k": (
        lambda: _significance().log10_binomial(np.array([], int), np.array([1, 2])),
        ValueError, "n and k must broadcast together, got shapes (0,) and (2,)"),
    "significance smallest consensus NaN threshold": (
        lambda: _significance().smallest_significant_consensus(100, (640, 480), np.nan, 5.0),
        ValueError, "threshold must be a finite number > 0, got nan"),
    "significance smallest consensus negative threshold": (
        lambda: _significance().smallest_significant_consensus(100, (640, 480), -1.0, 5.0),
        ValueError, "threshold must be a finite number > 0, got -1.0"),
    "significance smallest consensus NaN bar": (
        lambda: _significance().smallest_significant_consensus(100, (640, 480), 1.0, np.nan),
        ValueError, "max_log10_nfa must be a number (inf: every consensus), got nan"),
    "significance smallest consensus no size": (
        lambda: _significance().smallest_significant_consensus(100, None, 1.0, 5.0), TypeError,
        "image_size2 must be (width, height), got None"),
    "significance distinctiveness index mask": (
        lambda: _significance().distinctiveness(np.array([0.5, 0.7, 0.9]), np.array([0, 1, 1])),
        TypeError, "consistent must be a mask of bool, got dtype int64"),
    # homography errors: AttributeErrors ("'NoneType' object has no attribute 'T'"), numpy's
    # LinAlgError "Singular matrix", NaN errors for a NaN homography without a word
    "homography transfer_errors None": (
        lambda: ppo_cv.homography.transfer_errors(None, _rays(), _rays()), TypeError,
        "H is required, got None"),
    "homography symmetric singular": (
        lambda: ppo_cv.homography.symmetric_transfer_errors(np.zeros((3, 3)), _rays(), _rays()),
        ValueError, "H is singular"),
    "homography sampson NaN H": (
        lambda: ppo_cv.homography.homography_sampson_errors(np.full((3, 3), np.nan), _rays(),
                                                            _rays()), ValueError, "H has 9 NaN"),
    "homography sampson points of two": (
        lambda: ppo_cv.homography.homography_sampson_errors(np.eye(3), P1, P2), ValueError,
        "x1 must have shape (N, 3), got (40, 2)"),
    # model_selection: int("5") read a text as a codimension of 5, True as 1; IndexErrors and
    # Python's operator messages naming nothing
    "model_selection robust_sigma text codimension": (
        lambda: ppo_cv.model_selection.robust_sigma(np.ones(10), "2"), TypeError,
        "codimension must be a whole number, got str '2'"),
    "model_selection robust_sigma codimension 0": (
        lambda: ppo_cv.model_selection.robust_sigma(np.ones(10), 0), ValueError,
        "codimension must be a whole number in 1..4, got 0"),
    "model_selection gric no sigma": (
        lambda: ppo_cv.model_selection.gric(np.ones(10), None, 2, 3), TypeError,
        "sigma must be a number, got NoneType"),
    "model_selection gric dimension beyond": (
        lambda: ppo_cv.model_selection.gric(np.ones(10), 1.0, 7, 3), ValueError,
        "dimension must be a whole number in 0..4, got 7"),
    "model_selection nearest_neighbours one point": (
        lambda: ppo_cv.model_selection.nearest_neighbours(np.zeros((1, 2))), ValueError,
        "points must have shape (N, 2) with N >= 2, got (1, 2)"),
    "model_selection nearest_neighbours NaN": (
        lambda: ppo_cv.model_selection.nearest_neighbours(np.full((4, 2), np.nan)), ValueError,
        "points has 8 NaN"),
    # plane helpers: Python's operator messages ("unsupported operand type(s) for *"), an
    # AttributeError ("'NoneType' object has no attribute 'hypot'")
    "plane undistort_division text k1": (
        lambda: __import__("ppo_cv.plane").plane.undistort_division(_rays(), "0.1"), TypeError,
        "k1 must be a number, got str '0.1'"),
    "plane undistort_division no points": (
        lambda: __import__("ppo_cv.plane").plane.undistort_division(None, 0.1), TypeError,
        "x is required, got None"),
    "plane held_k1_deviation None": (
        lambda: __import__("ppo_cv.plane").plane.held_k1_deviation(None, 0.1), TypeError,
        "k1_fitted must be a number, got NoneType"),
    # Python's OverflowError
    "rotation_focal_scale H beyond a float": (
        lambda: _sfm_module().rotation_focal_scale([[10**400, 0, 0], [0, 1, 0], [0, 0, 1]], 500.0,
                                                   640), ValueError,
        "H holds a number beyond the range of a float"),
    "rotation_focal_scale negative focal": (
        lambda: _sfm_module().rotation_focal_scale(np.eye(3), -500.0, 640), ValueError,
        "focal must be a finite number > 0, got -500.0"),
    "format_pairs ints": (lambda: _sfm_module().format_pairs([1, 2]), TypeError,
                          "each pair must be a ppo_cv.sfm.PairScore, got int"),
    "pose_errors None": (lambda: _sfm_module().pose_errors(None, {}), TypeError,
                         "reconstruction must be a pycolmap.Reconstruction, got NoneType"),
    "write_model None": (lambda: _sfm_module().write_model(None, "never written"), TypeError,
                         "result must be a ppo_cv.sfm.SfmResult, got NoneType"),
    # calibration helpers: an AttributeError of None, a 0x0 image read as one, a text as a size
    "fit_to_image None": (lambda: ppo_cv.calib.fit_to_image(None, (640, 480), "cal"), TypeError,
                          "camera must be a ppo_cv.calib.Camera, got NoneType"),
    "fit_to_image size text": (
        lambda: ppo_cv.calib.fit_to_image(ppo_cv.Camera(K, None, (640, 480)), "ab", "cal"),
        TypeError, "size must be (width, height), got 'ab'"),
    "fit_to_image negative size": (
        lambda: ppo_cv.calib.fit_to_image(ppo_cv.Camera(K, None, (640, 480)), (-640, 480), "cal"),
        ValueError, "size width must be a whole number in 1..2147483647, got -640"),
    "implausible_intrinsics None": (
        lambda: ppo_cv.calib.implausible_intrinsics(None, (640, 480), "K1"), TypeError,
        "K1 is required, got None"),
    "implausible_intrinsics 0x0": (
        lambda: ppo_cv.calib.implausible_intrinsics(K, (0, 0), "K1"), ValueError,
        "size width must be a whole number in 1..2147483647, got 0"),
    # the image checks: os.stat's own words ('stat: path should be string, bytes, ...')
    "check_decodes None": (lambda: ppo_cv.images.check_decodes(None), TypeError,
                           "path must be a path (str or os.PathLike), got NoneType"),
    "check_header 5": (lambda: ppo_cv.images.check_header(5), TypeError,
                       "path must be a path (str or os.PathLike), got int"),
    "image_size None": (lambda: ppo_cv.images.image_size(None), TypeError,
                        "path must be a path (str or os.PathLike), got NoneType"),
    # a text where points belong: no advice to parse it as intrinsics
    "recoverPose points text": (lambda: ppo_cv.recoverPose(E, "1,2", P2, K), TypeError,
                                "points1 must be an array of real numbers, got str"),
    # ragged lists: numpy's 'setting an array element with a sequence' named no argument
    "recoverPose ragged mask": (lambda: ppo_cv.recoverPose(E, P1, P2, K, mask=[[1, 1], [1]]),
                                TypeError, "mask must be a numeric array: setting an array"),
    "form 4 ragged distortion": (_form4(distCoeffs1=[[0.1], [0, 0]]), TypeError,
                                 "distCoeffs1 must be a numeric array: setting an array"),
    "Camera ragged dist": (lambda: ppo_cv.Camera(K, [[0.1], [0, 0]]), TypeError,
                           "Camera.dist must be a numeric array: setting an array"),
    # the form with points, its first camera matrix not 3x3: "E must be a 3x3 matrix, got (40, 2)"
    "form 4 camera matrix of nine numbers": (
        lambda: ppo_cv.recoverPose(P1, P2, K.ravel(), None, K, None), ValueError,
        "cameraMatrix1 must be a 3x3 matrix, got shape (9,)"),
    "form 4 camera matrix None": (lambda: ppo_cv.recoverPose(P1, P2, None, None, K, None),
                                  TypeError, "cameraMatrix1 is required"),
    # one camera matrix and no E, as recoverPose(E, points1, points2, K) without E: OpenCV 5
    # reads the points as E and fails on an assertion; "cameraMatrix2 is required" gave no form
    "form 4 one camera matrix": (
        lambda: ppo_cv.recoverPose(P1, P2, K), TypeError,
        "cameraMatrix2 is required, got None: the form with points is recoverPose(points1, "
        "points2, cameraMatrix1, distCoeffs1, cameraMatrix2, distCoeffs2), recoverPose(p1, p2, K, "
        "None, K, None) for one camera without distortion; with an essential matrix, "
        "recoverPose(E, points1, points2, cameraMatrix)"),
    "form 4 second camera matrix for distCoeffs1": (
        lambda: ppo_cv.recoverPose(P1, P2, K, K), TypeError,
        "cameraMatrix2 is required, got None, and distCoeffs1 is a 3x3 matrix: the second "
        "camera's in its place?"),
    "form 4 points alone": (lambda: ppo_cv.recoverPose(P1, P2), TypeError,
                            "cameraMatrix1 is required, got None: the form with points is"),
    "form 4 points as lists": (lambda: ppo_cv.recoverPose(P1.tolist(), P2, [1] * 9, None, K, None),
                               ValueError, "cameraMatrix1 must be a 3x3 matrix"),
    # pose's public helpers: AttributeError, ZeroDivisionError, numpy's unpacking messages
    "inverse_camera list": (lambda: ppo_cv.pose.inverse_camera(K.tolist()[:2]), ValueError,
                            "K must be a 3x3 matrix, got shape (2, 3)"),
    "inverse_camera zeros": (lambda: ppo_cv.pose.inverse_camera(np.zeros((3, 3))), ValueError,
                             "K must be upper triangular"),
    "inverse_camera None": (lambda: ppo_cv.pose.inverse_camera(None), TypeError,
                            "K is required"),
    "pixel_rays points (N, 3)": (lambda: ppo_cv.pose.pixel_rays(np.ones((4, 3)), K), ValueError,
                                 "points must have shape (N, 2)"),
    "pixel_rays NaN point": (lambda: ppo_cv.pose.pixel_rays([[np.nan, 1.0]], K), ValueError,
                             "points has 1 NaN"),
    "pixel_rays K text": (lambda: ppo_cv.pose.pixel_rays(P1, "800,800,320,240"), TypeError,
                          "K must be an array of real numbers, got str"),
    # the robust fits: a negative trial count ran pycolmap's sampler without end, None failed
    # with an IndexError, a text focal length with Python's "'>' not supported"
    "estimate_essential max_trials -1": (lambda: _robust_fit("essential", max_trials=-1),
                                         ValueError, "max_trials must be a whole number in 0.."),
    "estimate_essential x1 None": (lambda: _robust_fit("essential", x1=None), TypeError,
                                   "x1 is required"),
    "estimate_essential focal 0": (lambda: _robust_fit("essential", focal=0), ValueError,
                                   "focal must be a finite number > 0"),
    "estimate_essential confidence 2": (lambda: _robust_fit("essential", confidence=2.0),
                                        ValueError, "confidence must be in (0, 1]"),
    "estimate_essential seed text": (lambda: _robust_fit("essential", seed="1"), TypeError,
                                     "seed must be a whole number, got str"),
    "estimate_homography min_trials -1": (lambda: _robust_fit("homography", min_trials=-1),
                                          ValueError, "min_trials must be a whole number in 0.."),
    "estimate_homography focal text": (lambda: _robust_fit("homography", focal="800"),
                                       TypeError, "focal must be a number, got str"),
    "estimate_homography x2 complex": (lambda: _robust_fit("homography", x2=RAYS + 0j),
                                       TypeError, "x2 must hold real numbers, got dtype complex"),
    # "object of type 'NoneType' has no len()"; a text was read as no matches
    "homography_rotation_focal None": (
        lambda: _sfm_module().homography_rotation_focal(None, RAYS, 800.0, 640), TypeError,
        "x1 is required"),
    "homography_rotation_focal text": (
        lambda: _sfm_module().homography_rotation_focal(RAYS, "x", 800.0, 640), TypeError,
        "x2 must be an array of real numbers, got str"),
    # the rotation-only fits: IndexError of None or two lengths, numpy's matmul message, a
    # threshold of 0, NaN or a text read as one, an integer mask indexing the matches
    "ransac_rotation x1 None": (lambda: _rotation().ransac_rotation(None, RAYS, 0.01), TypeError,
                                "x1 is required"),
    "ransac_rotation two lengths": (lambda: _rotation().ransac_rotation(RAYS, RAYS2[:10], 0.01),
                                    ValueError, "x1 and x2 must have the same length, got 40 "
                                    "and 10"),
    "ransac_rotation threshold 0": (lambda: _rotation().ransac_rotation(RAYS, RAYS2, 0), ValueError,
                                    "threshold must be a finite number > 0"),
    "ransac_rotation threshold NaN": (lambda: _rotation().ransac_rotation(RAYS, RAYS2, np.nan),
                                      ValueError, "threshold must be a finite number > 0"),
    "ransac_rotation threshold text": (lambda: _rotation().ransac_rotation(RAYS, RAYS2, "0.01"),
                                       TypeError, "threshold must be a number, got str"),
    "ransac_rotation NaN point": (lambda: _rotation().ransac_rotation(RAYS, _nan_row(RAYS2), 0.01),
                                  ValueError, "x2 has 1 NaN"),
    "ransac_rotation (N, 4)": (lambda: _rotation().ransac_rotation(np.ones((5, 4)), RAYS, 0.01),
                               ValueError, "x1 must have shape (N, 2) or (N, 3), got (5, 4)"),
    "ransac_rotation max_trials -1": (
        lambda: _rotation().ransac_rotation(RAYS, RAYS2, 0.01, max_trials=-1), ValueError,
        "max_trials must be a whole number in 0.."),
    "ransac_rotation confidence 2": (
        lambda: _rotation().ransac_rotation(RAYS, RAYS2, 0.01, confidence=2), ValueError,
        "confidence must be in (0, 1]"),
    "ransac_rotation seed text": (lambda: _rotation().ransac_rotation(RAYS, RAYS2, 0.01, seed="1"),
                                  TypeError, "seed must be a whole number, got str"),
    "rotation_residuals R None": (lambda: _rotation().rotation_residuals(None, RAYS, RAYS2),
                                  TypeError, "R is required"),
    "rotation_residuals R 2x2": (lambda: _rotation().rotation_residuals(np.eye(2), RAYS, RAYS2),
                                 ValueError, "R must be a 3x3 rotation matrix"),
    "rotation_residuals two lengths": (
        lambda: _rotation().rotation_residuals(np.eye(3), RAYS, RAYS2[:3]), ValueError,
        "x1 and x2 must have the same length"),
    "rotations_from_two_rays None": (
        lambda: _rotation().rotations_from_two_rays(None, RAYS, RAYS, RAYS), TypeError,
        "a1 is required"),
    "rotations_from_two_rays two lengths": (
        lambda: _rotation().rotations_from_two_rays(RAYS, RAYS, RAYS, RAYS[:3]), ValueError,
        "a1, a2, b1 and b2 must have the same length, got a1 40, a2 40, b1 40, b2 3"),
    "fit_rotation_lens x2 None": (lambda: _lens_fit(x2=None), TypeError, "x2 is required"),
    "fit_rotation_lens used of ints": (lambda: _lens_fit(used=np.ones(40, int)), TypeError,
                                       "used must be a boolean mask of the matches, got dtype "
                                       "int64"),
    "fit_rotation_lens used short": (lambda: _lens_fit(used=np.ones(5, bool)), ValueError,
                                     "used must have one entry per match (40), got shape (5,)"),
    "fit_rotation_lens R None": (lambda: _lens_fit(R=None), TypeError, "R is required"),
    "fit_rotation_lens noise text": (lambda: _lens_fit(noise="a"), TypeError,
                                     "noise must be a number, got str"),
    "fit_rotation_lens noise -1": (lambda: _lens_fit(noise=-1.0), ValueError,
                                   "noise must be a finite number >= 0"),
    "fit_rotation_lens iterations 1.5": (lambda: _lens_fit(iterations=1.5), ValueError,
                                         "iterations must be a whole number"),
    "fit_rotation_lens k1_prior 0": (lambda: _lens_fit(k1_prior=0.0), ValueError,
                                     "k1_prior must be a finite number > 0"),
    "fit_rotation_lens principal_prior NaN": (lambda: _lens_fit(principal_prior=np.nan),
                                              ValueError, "principal_prior has 1 NaN"),
    "fit_rotation_lens lens_start text": (lambda: _lens_fit(lens_start="fit"), TypeError,
                                          "lens_start must be a ppo_cv.rotation.LensRotationFit"),
    "fit_rotation_lens deviations 'no'": (lambda: _lens_fit(deviations="no"), TypeError,
                                          "deviations must be True, False or a callable"),
    "correct_points x None": (lambda: _rotation().correct_points(None, 1.0, 0.0), TypeError,
                              "x is required"),
    "correct_points focal_scale 0": (lambda: _rotation().correct_points(RAYS, 0.0, 0.0), ValueError,
                                     "focal_scale must be a number in [0.001, 1000]"),
    "correct_points focal_scale NaN": (lambda: _rotation().correct_points(RAYS, np.nan, 0.0),
                                       ValueError, "focal_scale must be a number in"),
    "correct_points k1 text": (lambda: _rotation().correct_points(RAYS, 1.0, "0.1"), TypeError,
                               "k1 must be a number, got str"),
    "correct_points offset of three": (
        lambda: _rotation().correct_points(RAYS, 1.0, 0.0, (0, 0, 0)), TypeError,
        "principal_offset must be two numbers (x, y)"),
    "transfer_points focal_ratio -1": (
        lambda: _rotation().transfer_points(RAYS, np.eye(3), 1.0, 0.0, focal_ratio=-1.0),
        ValueError, "focal_ratio must be a number in [0.001, 1000]"),
    "transfer_points R None": (lambda: _rotation().transfer_points(RAYS, None, 1.0, 0.0),
                               TypeError, "R is required"),
    "lens_rotation_residuals two lengths": (
        lambda: _rotation().lens_rotation_residuals(np.eye(3), 1.0, 0.0, RAYS, RAYS2[:3]),
        ValueError, "x1 and x2 must have the same length"),
    "lens_rotation_residuals vectors 'no'": (
        lambda: _rotation().lens_rotation_residuals(np.eye(3), 1.0, 0.0, RAYS, RAYS2,
                                                    vectors="no"),
        TypeError, "vectors must be True or False, got str"),
    "seen_through_lens ray None": (
        lambda: _rotation().seen_through_lens(None, 1.0, 0.0, 0.0, 1.0), TypeError,
        "ray is required"),
    "seen_through_lens scale 0": (
        lambda: _rotation().seen_through_lens(RAYS, 0.0, 0.0, 0.0, 1.0), ValueError,
        "scale must be > 0"),
    "seen_through_lens terms of another shape": (
        lambda: _rotation().seen_through_lens(RAYS, np.ones(3), 0.0, 0.0, 1.0), ValueError,
        "the lens terms (scale (3,), k1 (), offset (), ratio ()) do not broadcast"),
    "focal_ratio_prior None": (lambda: _rotation().focal_ratio_prior(None), TypeError,
                               "given_ratio must be a number, got NoneType"),
    "focal_ratio_prior NaN": (lambda: _rotation().focal_ratio_prior(np.nan), ValueError,
                              "given_ratio must be a finite number > 0"),
    "focal_ratio_prior text": (lambda: _rotation().focal_ratio_prior("1.01"), TypeError,
                               "given_ratio must be a number, got str"),
    "focal_ratio_keywords text": (lambda: _rotation().focal_ratio_keywords("ab"), TypeError,
                                  "prior must be None or (mean, deviation)"),
    # a 0-d prior raised len()'s TypeError; a complex number warned and lost its imaginary part
    "focal_ratio_keywords 0-d": (lambda: _rotation().focal_ratio_keywords(np.array(1.0)),
                                 TypeError, "prior must be None or (mean, deviation)"),
    "focal_ratio_keywords complex": (
        lambda: _rotation().focal_ratio_keywords((np.complex128(1.0), 0.1)), TypeError,
        "prior mean must be a real number, got complex128"),
    "correct_points w = 0": (lambda: _rotation().correct_points(RAYS * [1.0, 1.0, 0.0], 1.0, 0.0),
                             ValueError, "x has 40 row(s) with w = 0"),
    # rays parallel to the image plane overflowed |q2|^2
    "seen_through_lens ray 1e300": (
        lambda: _rotation().seen_through_lens([[1e300, 0.0, 1.0]], 1.0, 0.0, 0.0, 1.0),
        ValueError, "ray has 1 ray(s) at or near right angles to the optical axis"),
    # zero rows: an inlier of every rotation at angle 0, then numpy's SVD failed (LinAlgError)
    "ransac_rotation zero rows": (
        lambda: _rotation().ransac_rotation(np.vstack([RAYS, np.zeros((2, 3))]),
                                            np.vstack([RAYS2, np.zeros((2, 3))]), 0.01),
        ValueError, "x1 has 2 zero row(s): a ray needs a direction"),
    "rotation_residuals zero rows": (
        lambda: _rotation().rotation_residuals(np.eye(3), RAYS, np.zeros((40, 3))),
        ValueError, "x2 has 40 zero row(s)"),
    "ransac_rotation w = 0": (
        lambda: _rotation().ransac_rotation(RAYS, RAYS2 * [1.0, 1.0, 0.0], 0.01), ValueError,
        "x2 has 40 row(s) with w <= 0 (a ray at or behind the image plane)"),
    # bearings turned 90 degrees, half of them behind view 2's image plane: the least-squares
    # rotation read them as the image points x / w and answered a rotation 180 degrees off
    "ransac_rotation rays behind": (lambda: _rotation().ransac_rotation(*_turned_bearings(), 0.01),
                                    ValueError, "x2 has 17 row(s) with w <= 0"),
    "focal_ratio_keywords NaN": (lambda: _rotation().focal_ratio_keywords((1.0, np.nan)),
                                 ValueError, "prior deviation must be a finite number > 0"),
    # complex numbers lost their imaginary part with a ComplexWarning and were used
    "recoverPose pp complex": (
        lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=np.array([320 + 1j, 240])),
        TypeError, "pp must be two numbers"),
    "rigid3d_from_pose t complex": (
        lambda: ppo_cv.colmap.rigid3d_from_pose(R_TRUE, T_TRUE.astype(complex)), TypeError,
        "t must be three numbers"),
    "triangulation_angles points complex": (
        lambda: ppo_cv.colmap.triangulation_angles(RAYS.astype(complex), R_TRUE, T_TRUE),
        TypeError, "points3d must be an array of real numbers"),
    # a 0-d array failed in len() ("len() of unsized object")
    "principal_point_is_centre size 0-d": (
        lambda: principal_point_is_centre(K, np.array(640)), TypeError,
        "image_size must be (width, height)"),
    # a negative focal length gave a field beyond 180 degrees, a huge integer an OverflowError
    "field_of_view_deg negative focal": (lambda: ppo_cv.calib.field_of_view_deg(-500.0, 640),
                                         ValueError, "focal must be a finite number > 0"),
    "field_of_view_deg huge focal": (lambda: ppo_cv.calib.field_of_view_deg(10**400, 640),
                                     ValueError, "focal is beyond the range of a float"),
    "field_of_view_deg text extent": (lambda: ppo_cv.calib.field_of_view_deg(500.0, "640"),
                                      TypeError, "extent must be a number"),
    "unusable_exif_focal huge side": (lambda: ppo_cv.calib.unusable_exif_focal(500.0, 10**400),
                                      ValueError, "side is beyond the range of a float"),
    "unusable_exif_focal complex focal": (
        lambda: ppo_cv.calib.unusable_exif_focal(500 + 1j, 640), TypeError,
        "focal must be a number"),
    # 1 - confidence rounded to 1: pycolmap drew no hypothesis and the fit found no model
    "PairOptions confidence 1e-17": (lambda: PairOptions(confidence=1e-17), ValueError,
                                     "confidence must be in (0, 1] with 1 - confidence below 1"),
    "estimate_essential confidence 1e-17": (
        lambda: ppo_cv.robust.estimate_essential(RAYS, RAYS2, 800.0, confidence=1e-17),
        ValueError, "1 - confidence below 1"),
    "estimate_homography confidence 1e-17": (
        lambda: ppo_cv.homography.estimate_homography(RAYS, RAYS2, 800.0, confidence=1e-17),
        ValueError, "1 - confidence below 1"),
    # rows of w = 0 were read as the image points (x, y)
    "estimate_essential row at infinity": (
        lambda: ppo_cv.robust.estimate_essential(RAYS * [1, 1, 0], RAYS2, 800.0), ValueError,
        "x1 has 40 row(s) with w = 0"),
    "sampson_errors point at infinity": (
        lambda: ppo_cv.robust.sampson_errors(E, RAYS, RAYS2 * [1, 1, 0]), ValueError,
        "x2 has 40 point(s) with w = 0"),
    "transfer_errors row at infinity": (
        lambda: ppo_cv.homography.transfer_errors(np.eye(3), RAYS * [1, 1, 0], RAYS2),
        ValueError, "x1 has 40 row(s) with w = 0"),
    # a zero n gave a basis of NaN, two numbers an IndexError
    "tangent_basis zero": (lambda: __import__("ppo_cv.lsq").lsq.tangent_basis(np.zeros(3)),
                           ValueError, "n is zero: it has no tangent plane"),
    "tangent_basis two numbers": (
        lambda: __import__("ppo_cv.lsq").lsq.tangent_basis(np.ones(2)), ValueError,
        "n must be 3 numbers"),
    # an all-zero H gave Sampson errors of 0, every match on the homography
    "homography sampson zero H": (
        lambda: ppo_cv.homography.homography_sampson_errors(np.zeros((3, 3)), RAYS, RAYS2),
        ValueError, "H is singular (all zeros)"),
}  # fmt: skip


HUGE = 10**5000  # more digits than Python prints (4300)
LONG_TEXT = "1," * 3000
LONG_VALUE_CASES = {
    "estimate_pair image1 huge int": (_pair(image1=HUGE), TypeError,
                                      "image1 must be an image array or a path (str or "
                                      "os.PathLike), got int <5001-digit integer>"),
    "parse_intrinsics huge int": (lambda: ppo_cv.parse_intrinsics(HUGE, "K"), TypeError,
                                  "K must be a text of numbers, got int <5001-digit integer>"),
    "parse_intrinsics long text": (lambda: ppo_cv.parse_intrinsics("x" + LONG_TEXT, "K"),
                                   ValueError, "K must be numbers separated by commas, spaces or "
                                   "semicolons: field 1 of 3000 is 'x1'"),
    "parse_intrinsics long NaN text": (lambda: ppo_cv.parse_intrinsics("nan," + LONG_TEXT, "K"),
                                       ValueError, "K has NaN or infinite values: 'nan,1,1,"),
    "PairOptions ratio huge int": (lambda: PairOptions(ratio=HUGE), ValueError,
                                   "ratio is beyond the range of a float: <5001-digit integer>"),
    "PairOptions seed huge int": (lambda: PairOptions(seed=HUGE), ValueError,
                                  "seed must be a whole number in 0..2147483647, got "
                                  "<5001-digit integer>"),
    "PairOptions seed long text": (lambda: PairOptions(seed=LONG_TEXT), TypeError,
                                   "seed must be a whole number, got str '1,1,1,"),
    "PairOptions plane huge int": (lambda: PairOptions(plane=HUGE), TypeError,
                                   "plane must be True or False, got int <5001-digit integer>"),
    "PairOptions pri_threshold long text": (lambda: PairOptions(pri_threshold=LONG_TEXT),
                                            TypeError, "pri_threshold must be a number, got str"),
    "PairOptions features long text": (lambda: PairOptions(features=LONG_TEXT), ValueError,
                                       "unknown features '1,1,1,"),
    "load_image max_pixels long text": (lambda: load_image(__file__, max_pixels=LONG_TEXT),
                                        TypeError, "max_pixels must be a whole number, got '1,"),
    "run_sfm min_inliers huge int": (lambda: _sfm(min_inliers=HUGE), ValueError,
                                     "min_inliers must be a whole number in 0..2147483647"),
    "recoverPose pp huge int": (lambda: ppo_cv.recoverPose(E, P1, P2, focal=800.0, pp=(HUGE, 0)),
                                ValueError, "pp must be two finite numbers within 1e+08"),
    "recoverPose long keyword": (lambda: ppo_cv.recoverPose(E, P1, P2, K, **{"x" * 5000: 1}),
                                 TypeError, "recoverPose got an unexpected keyword argument 'xxx"),
    "run_sfm initialization long text": (lambda: _sfm(initialization=LONG_TEXT), ValueError,
                                         "initialization must be one of ppo, colmap, got '1,1,"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(LONG_VALUE_CASES), ids=list(LONG_VALUE_CASES))
def test_a_huge_or_long_value_is_quoted_short_in_its_error(case):
    call, exception, words = LONG_VALUE_CASES[case]
    with pytest.raises(exception) as info:
        call()
    assert words in str(info.value) and len(str(info.value)) < 120


@pytest.mark.parametrize(
    "value, quoted",
    [(5, "5"), (1.5, "1.5"), ("ab", "'ab'"), ("a" * 50, "'" + "a" * 36 + "..."),
     (HUGE, "<5001-digit integer>"), (np.int64(7), "7"), (2**150, str(2**150)[:37] + "...")],
    ids=["int", "float", "text", "long text", "huge int", "numpy int", "long int"],
)  # fmt: skip
def test_shown_quotes_a_value_in_at_most_its_width(value, quoted):
    from ppo_cv.checks import shown

    assert shown(value) == quoted and len(shown(value)) <= 40


def test_distinctiveness_takes_its_ratios_as_a_list():
    # "'list' object has no attribute 'shape'"
    from ppo_cv.significance import distinctiveness

    consistent = np.array([True, True, False, False, False])
    ratios = [0.3, 0.4, 0.8, 0.85, 0.9]
    assert distinctiveness(ratios, consistent) == distinctiveness(np.array(ratios), consistent)
    assert distinctiveness(ratios, consistent) < 0.1


@pytest.mark.filterwarnings("ignore::ppo_cv.calib.ImplausibleCameraWarning")  # 800 px on 64x48
@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_hostile_input_is_an_error_naming_the_argument(case):
    call, exception, words = CASES[case]
    with pytest.raises(exception) as info:
        call()
    assert words in str(info.value)
    assert "parse a text" not in str(info.value) or "K" in words or "dist" in words


DROPIN_CASES = [case for case in CASES if case.startswith(("recoverPose", "form 4"))]


@pytest.mark.parametrize("case", DROPIN_CASES, ids=DROPIN_CASES)
def test_dropin_errors_are_also_cv2_errors(case):
    call, exception, words = CASES[case]
    with ppo_cv.installed(), pytest.raises(cv2.error) as info:
        call()
    assert isinstance(info.value, exception) and words in str(info.value)


def test_existing_code_catching_cv2_error_keeps_working_under_install():
    with ppo_cv.installed():
        try:
            cv2.recoverPose(E, P1, P2, _K(fx=-800))
        except cv2.error as exc:
            assert "negative focal length" in str(exc)
        else:
            pytest.fail("no error")


@pytest.mark.parametrize("scale", [1e80, 1e-200, 1e300, -3.0, 1e-300, 1e-310, -2.5e-315])
def test_any_finite_scale_of_E_gives_the_same_pose(scale):
    retval, R, t, mask = ppo_cv.recoverPose(E * scale, P1, P2, K)
    assert retval == 40 and abs(np.linalg.det(R) - 1) < 1e-9
    np.testing.assert_allclose(R, R_TRUE, atol=1e-9)
    np.testing.assert_allclose(t.ravel(), T_TRUE, atol=1e-9)
    result = ppo_cv.recover_pose(E * scale, P1, P2, K)
    np.testing.assert_allclose(result.R, R_TRUE, atol=1e-9)


@pytest.mark.parametrize("scale", [1e300, 1e-300, 5e-324, -1e200])
def test_any_finite_scale_of_t_gives_the_same_refined_pose(scale):
    refine = _refine()
    R, t = refine.refine_pose(R_TRUE, T_TRUE, _rays(), RAYS2, _ALL, 800.0)
    R_scaled, t_scaled = refine.refine_pose(R_TRUE, T_TRUE * scale, _rays(), RAYS2, _ALL, 800.0)
    np.testing.assert_allclose(R_scaled, R, atol=1e-9)
    np.testing.assert_allclose(t_scaled, np.sign(scale) * t, atol=1e-9)
    radial = refine.refine_pose_radial(R_TRUE, T_TRUE * scale, _rays(), RAYS2, _ALL, scale=1e-3)
    assert np.all(np.isfinite(radial.t)) and abs(np.linalg.norm(radial.t) - 1) < 1e-12
    huber = refine.refine_pose_huber(R_TRUE, T_TRUE, _rays(), RAYS2, _ALL, scale=1e-3)
    R_huber, t_huber = refine.refine_pose_huber(
        R_TRUE, T_TRUE * scale, _rays(), RAYS2, _ALL, scale=1e-3
    )
    np.testing.assert_allclose(R_huber, huber[0], atol=1e-9)
    np.testing.assert_allclose(t_huber, np.sign(scale) * huber[1], atol=1e-9)


def test_refine_pose_reads_rows_as_homogeneous_points():
    refine = _refine()
    R, t = refine.refine_pose(R_TRUE, T_TRUE, _rays(), RAYS2, _ALL, 800.0)
    w = np.linspace(0.5, 4.0, 40)[:, None]
    R_w, t_w = refine.refine_pose(R_TRUE, T_TRUE, _rays() * w, RAYS2 / w, _ALL, 800.0)
    np.testing.assert_allclose(R_w, R, atol=1e-9)
    np.testing.assert_allclose(t_w, t, atol=1e-9)


@pytest.mark.parametrize("noise_px", [0.5, 2.0, 5.0])
def test_a_linear_eight_point_E_of_noisy_points_is_still_read(noise_px):
    rng = np.random.default_rng(3)
    noisy = [p + rng.normal(0.0, noise_px, p.shape) for p in (P1, P2)]
    rays = [np.c_[p, np.ones(len(p))] @ np.linalg.inv(K).T for p in noisy]
    design = np.einsum("ni,nj->nij", rays[1], rays[0]).reshape(len(P1), 9)
    E_linear = np.linalg.svd(design)[2][-1].reshape(3, 3)  # not projected onto essentials
    spread = np.linalg.svd(E_linear, compute_uv=False)
    assert spread[0] > 1.001 * spread[1] and spread[2] > 1e-6 * spread[0]
    retval, R, t, _ = ppo_cv.recoverPose(E_linear, *noisy, K)
    reference = OPENCV_RECOVER_POSE(E_linear, *noisy, K)
    np.testing.assert_allclose(R, reference[1], atol=1e-9)
    assert np.degrees(np.arccos((np.trace(R @ R_TRUE.T) - 1) / 2)) < 3.0


@pytest.mark.parametrize("shape", [(9,), (1, 9), (9, 1), (3, 3, 1)])
def test_dropin_reads_E_of_nine_entries_as_opencv_does(shape):
    reference = OPENCV_RECOVER_POSE(E.reshape(shape), P1, P2, K)
    ours = ppo_cv.recoverPose(E.reshape(shape), P1, P2, K)
    assert ours[0] == reference[0] == 40
    np.testing.assert_allclose(ours[1], reference[1], atol=1e-9)


@pytest.mark.parametrize(
    "call, r_index",
    [(lambda f, K3: f(E, P1, P2, K3), 1), (lambda f, K3: f(E, P1, P2, K3, 50.0), 1),
     (lambda f, K3: f(P1, P2, K3, None, K3, None), 2),
     (lambda f, K3: f(P1, P2, cameraMatrix1=K3, distCoeffs1=None, cameraMatrix2=K3,
                      distCoeffs2=None), 2)],
    ids=["form 1", "form 3", "form 4", "form 4 keywords"],
)  # fmt: skip
def test_dropin_reads_a_camera_matrix_of_one_channel_as_opencv_does(call, r_index):
    # refused as "cameraMatrix must be a 3x3 matrix, got shape (3, 3, 1)"
    reference = call(OPENCV_RECOVER_POSE, K.reshape(3, 3, 1))
    ours = call(ppo_cv.recoverPose, K.reshape(3, 3, 1))
    assert ours[0] == reference[0] == 40
    np.testing.assert_allclose(ours[r_index], reference[r_index], atol=1e-6)


def test_umat_inputs_give_umat_outputs_with_the_same_pose():
    ours = ppo_cv.recoverPose(cv2.UMat(E), cv2.UMat(P1), cv2.UMat(P2), cv2.UMat(K))
    reference = OPENCV_RECOVER_POSE(cv2.UMat(E), cv2.UMat(P1), cv2.UMat(P2), cv2.UMat(K))
    assert [type(out) for out in ours] == [type(out) for out in reference]
    np.testing.assert_allclose(ours[1].get(), reference[1].get(), atol=1e-9)
    np.testing.assert_array_equal(ours[3].get(), reference[3].get())


def test_a_positional_number_after_the_camera_is_the_R_buffer_as_in_opencv():
    reference = OPENCV_RECOVER_POSE(E, P1, P2, K, 50.0)
    ours = ppo_cv.recoverPose(E, P1, P2, K, 50.0)
    assert len(ours) == len(reference) == 4
    assert ours[0] == reference[0]
    np.testing.assert_allclose(ours[1], reference[1], atol=1e-9)
    np.testing.assert_array_equal(ours[3], reference[3])


def test_form_with_points_overwrites_the_input_mask_as_opencv_does():
    rng = np.random.default_rng(5)
    noisy = P2 + rng.normal(0, 0.2, P2.shape)
    plain = ppo_cv.recoverPose(P1, noisy, K, None, K, None)
    zeros = np.zeros((40, 1), np.uint8)
    given = ppo_cv.recoverPose(P1, noisy, K, None, K, None, mask=zeros)
    opencv = OPENCV_RECOVER_POSE(P1, noisy, K, None, K, None, mask=np.zeros((40, 1), np.uint8))
    assert given[0] == plain[0] > 30 and opencv[0] > 30
    np.testing.assert_array_equal(given[4], plain[4])
    assert set(np.unique(given[4])) == set(np.unique(opencv[4])) == {1}
    np.testing.assert_array_equal(zeros, given[4])  # written in place, as OpenCV does


MASK_CALLS = {
    "camera matrix": lambda f, mask: f(E, P1, 640.0 - P2, K, mask=mask)[3],
    "focal": lambda f, mask: f(E, P1, 640.0 - P2, focal=800.0, pp=(320.0, 240.0), mask=mask)[3],
    "distanceThresh": lambda f, mask: f(E, P1, 640.0 - P2, K, distanceThresh=50.0, mask=mask)[3],
    "points": lambda f, mask: f(P1, P2, K, None, K, None, mask=mask)[4],
}


@pytest.mark.parametrize("shape", [(40, 1), (1, 40), (40,)])
@pytest.mark.parametrize("form", list(MASK_CALLS))
def test_the_mask_is_written_in_place_where_opencv_writes_it(form, shape):
    returned = {}
    for function in (OPENCV_RECOVER_POSE, ppo_cv.recoverPose):
        mask = np.full(shape, 7, np.uint8)
        out = MASK_CALLS[form](function, mask)
        returned[function] = (out is mask, mask.copy(), out.copy())
    opencv, ours = returned[OPENCV_RECOVER_POSE], returned[ppo_cv.recoverPose]
    assert ours[0] == opencv[0] == (shape == (40, 1))
    if ours[0]:
        np.testing.assert_array_equal(ours[1], ours[2])
        assert set(np.unique(ours[1])) == set(np.unique(opencv[1]))
    assert set(np.unique(ours[2])) == set(np.unique(opencv[2]))


class _CountedWrites(np.ndarray):
    """An 8-bit mask that counts the assignments into it and into its views."""

    writes = 0

    def __setitem__(self, key, value):
        type(self).writes += 1
        super().__setitem__(key, value)


@pytest.mark.parametrize("shape", [(40, 1), (1, 40), (40,)])
def test_the_form_with_points_writes_a_given_mask_once(shape):
    expected = OPENCV_RECOVER_POSE(P1, P2, K, None, K, None, mask=np.zeros(shape, np.uint8))[4]
    mask = np.full(shape, 7, np.uint8).view(_CountedWrites)
    _CountedWrites.writes = 0
    out = ppo_cv.recoverPose(P1, P2, K, None, K, None, mask=mask)[4]
    assert _CountedWrites.writes == 1
    assert (out is mask) == (shape == (40, 1))
    np.testing.assert_array_equal(np.asarray(mask).reshape(-1, 1), expected)


def test_uninstall_restores_what_install_replaced():
    def wrapper(*args, **kwargs):
        return OPENCV_RECOVER_POSE(*args, **kwargs)

    saved = cv2.recoverPose
    cv2.recoverPose = wrapper
    try:
        ppo_cv.install()
        ppo_cv.install()
        assert cv2.recoverPose is ppo_cv.recoverPose
        ppo_cv.uninstall()
        assert cv2.recoverPose is wrapper
    finally:
        cv2.recoverPose = saved


@pytest.mark.parametrize("shape", [(1, 1), (7, 7), (1, 100)])
def test_an_image_narrower_than_eight_pixels_is_checked_whole(tmp_path, shape):
    # OpenCV's reduced decode of such a PNG raised cv2.error ("inv_scale_x > 0") from
    # camera_from_exif
    path = tmp_path / "small.png"
    cv2.imwrite(str(path), np.zeros(shape, np.uint8))
    ppo_cv.images.check_decodes(path)
    camera, _ = ppo_cv.camera_from_exif(path)
    assert camera.K[0, 2] == shape[1] / 2 and camera.K[1, 2] == shape[0] / 2
    path.write_bytes(path.read_bytes()[:40])
    with pytest.raises(ValueError, match="not a readable image"):
        ppo_cv.images.check_decodes(path)


def test_decompression_bomb_is_refused_from_the_header(tmp_path, monkeypatch):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_header(30000, 30000))
    with pytest.raises(ValueError, match="bomb.png declares 30000x30000 pixels, above the limit"):
        load_image(bomb)
    with pytest.raises(ValueError, match="declares 30000x30000"):
        ppo_cv.estimate_pair(bomb, bomb, K)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), GREY)
    with pytest.raises(ValueError, match="declares 64x48 pixels, above the limit of 1000"):
        load_image(small, max_pixels=1000)
    monkeypatch.setenv("PPO_CV_MAX_IMAGE_PIXELS", "3072")
    assert load_image(small).shape == (48, 64, 3)
    monkeypatch.setenv("PPO_CV_MAX_IMAGE_PIXELS", "3071")
    with pytest.raises(ValueError, match="above the limit of 3071"):
        load_image(small)
    monkeypatch.setenv("PPO_CV_MAX_IMAGE_PIXELS", "lots")
    with pytest.raises(ValueError, match="PPO_CV_MAX_IMAGE_PIXELS must be a whole number"):
        load_image(small)
    for empty in ("", " "):  # unset, as an empty OMP_NUM_THREADS is: it was "got ''"
        monkeypatch.setenv("PPO_CV_MAX_IMAGE_PIXELS", empty)
        with pytest.warns(UserWarning, match=f"^PPO_CV_MAX_IMAGE_PIXELS={empty!r} is empty; "
                                             "ignored$"):  # fmt: skip
            assert load_image(small).shape == (48, 64, 3)
        with pytest.warns(UserWarning), pytest.raises(ValueError, match="above the limit of "
                                                                         "100000000"):  # fmt: skip
            load_image(bomb)


@pytest.mark.parametrize("extension", list(HEADERS))
def test_the_real_header_size_is_named_in_every_format(tmp_path, extension):
    path = tmp_path / f"huge.{extension}"
    path.write_bytes(HEADERS[extension](30000, 30000))
    with pytest.raises(ValueError, match=f"huge.{extension} declares 30000x30000 pixels, above"):
        load_image(path)


def test_jpeg_size_is_read_from_the_header_too(tmp_path):
    path = tmp_path / "a.jpg"
    cv2.imwrite(str(path), np.zeros((300, 200, 3), np.uint8))
    with pytest.raises(ValueError, match="declares 200x300 pixels"):
        load_image(path, max_pixels=59_999)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_read_text_file_refuses_a_fifo_and_names_a_path_that_is_none(tmp_path):
    # it opened the FIFO and waited for a writer; None failed in open(), naming nothing
    fifo = tmp_path / "pairs.txt"
    os.mkfifo(fifo)
    with ThreadPoolExecutor(1) as pool:
        future = pool.submit(ppo_cv.calib.read_text_file, fifo, "pairs file")
        try:
            with pytest.raises(ValueError, match="pairs file .* is not a regular file"):
                future.result(timeout=10)
        except FutureTimeout:
            with open(fifo, "w"):  # release the reader
                pass
            raise
    with pytest.raises(TypeError, match="path must be a path"):
        ppo_cv.calib.read_text_file(None, "pairs file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):
        load_image(fifo)


SFM_FOLDER_ENTRIES = {
    "list_images": lambda folder, root: _sfm_module().list_images(folder),
    "screen_images": lambda folder, root: _sfm_module().screen_images(folder),
    "prepare_database": lambda folder, root: _sfm_module().prepare_database(folder, root / "d.db"),
    "run_sfm": lambda folder, root: _sfm_module().run_sfm(folder, root / "model", K=K),
}


@pytest.mark.parametrize("entry", list(SFM_FOLDER_ENTRIES))
def test_an_image_folder_in_a_loop_of_symbolic_links_is_named_so(tmp_path, entry):
    os.symlink("loop2", tmp_path / "loop1")
    os.symlink("loop1", tmp_path / "loop2")
    with pytest.raises(ValueError, match="^cannot read image folder .*loop1: Too many levels of "
                       "symbolic links$"):  # fmt: skip
        SFM_FOLDER_ENTRIES[entry](tmp_path / "loop1", tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop1", "loop2"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
@pytest.mark.parametrize(
    "call, expected",
    [(lambda path: ppo_cv.images.image_size(path), None),
     (lambda path: ppo_cv.images.exif_layout(path), ppo_cv.images.ExifLayout()),
     (lambda path: ppo_cv.images.decoded_transposed(path, 640, 480), False)],
    ids=["image_size", "exif_layout", "decoded_transposed"],
)  # fmt: skip
def test_the_header_readers_never_open_a_fifo(tmp_path, call, expected):
    # each opened it and waited for a writer: ppo-cv pairs --calib hung on a FIFO in the folder
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    with ThreadPoolExecutor(1) as pool:
        answer = pool.submit(call, fifo)
        try:
            result = answer.result(timeout=20)
        except FutureTimeout:
            _release_readers(fifo, answer)
            pytest.fail("it opened the FIFO and waited for a writer")
    assert result == expected


def _release_readers(fifo: Path, answer) -> None:
    """Open and close ``fifo`` for writing until ``answer`` is done, so that each reader it
    waits in sees an end of file (never blocking: without a reader the open fails)."""
    while not answer.done():
        try:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            time.sleep(0.01)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(ValueError, match="image not found"):
        load_image(tmp_path / "none.png")
    with pytest.raises(ValueError, match="got a directory"):
        load_image(tmp_path)


def test_deep_images_are_scaled_by_their_range(tmp_path):
    ramp = np.tile(np.arange(64, dtype=np.uint16), (48, 1))
    twelve_bit = tmp_path / "twelve.png"
    cv2.imwrite(str(twelve_bit), ramp * 65)  # 0 .. 4095
    loaded = load_image(twelve_bit)
    assert loaded.dtype == np.uint8 and loaded.min() == 0 and loaded.max() == 255
    low = tmp_path / "low.png"
    cv2.imwrite(str(low), ramp * 4)  # a uint16 file holding 0..252: already 8-bit values
    np.testing.assert_array_equal(load_image(low)[:, :, 0], (ramp * 4).astype(np.uint8))
    gray = ppo_cv.features.to_gray(ramp.astype(np.uint16) * 1000)
    assert gray.min() == 0 and gray.max() == 255 and np.all(np.diff(gray[0].astype(int)) >= 0)
    unit = ppo_cv.features.to_gray(ramp / 63.0)
    assert unit.max() == 255 and unit.min() == 0


@pytest.mark.parametrize(
    "deep",
    [
        lambda ramp: ramp.astype(np.float64) * 1e300,
        lambda ramp: ramp.astype(np.float64) + 1e9,
        lambda ramp: ramp.astype(np.int64) + 2**40,
        lambda ramp: ramp.astype(np.uint64) * 2**50,
    ],
    ids=["float64 1e300", "float64 offset 1e9", "int64 offset 2^40", "uint64 2^50"],
)
def test_deep_images_of_extreme_values_keep_their_contrast(deep):
    ramp = np.tile(np.arange(256, dtype=np.int64), (4, 1)) * 3
    expected = np.arange(256).astype(np.uint8)  # [min, max] onto [0, 255]
    gray = ppo_cv.features.to_uint8(deep(ramp))
    np.testing.assert_array_equal(gray[0], expected)


def test_a_single_channel_float_tiff_is_read(tmp_path):
    path = tmp_path / "float.tiff"
    assert cv2.imwrite(str(path), GREY.astype(np.float32) / 255.0)
    loaded = load_image(path)
    assert loaded.shape == (48, 64, 3)
    for channel in range(3):
        np.testing.assert_array_equal(loaded[:, :, channel], GREY)


@pytest.mark.filterwarnings("ignore::ppo_cv.calib.ImplausibleCameraWarning")
def test_a_constant_deep_image_reads_as_blank(tmp_path):
    path = tmp_path / "constant.png"
    cv2.imwrite(str(path), np.full((48, 64), 1000, np.uint16))
    assert not load_image(path).any()
    with pytest.raises(ValueError, match="too few features"):
        ppo_cv.estimate_pair(path, GREY, K)


DEMO_IMAGES = [str(Path(ppo_cv.__file__).parent / "data" / f"demo{i}.png") for i in (1, 2)]
K_DEMO = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("scale", [1.0, 3.0])
def test_a_camera_of_another_image_size_is_warned_about(scale):
    """The demo pair with the camera of a 1920x1440 copy: a confident pose 19 degrees off."""
    K1 = K_DEMO * [[scale], [scale], [1.0]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = ppo_cv.estimate_pair(*DEMO_IMAGES, K1)
    doubts = [w for w in caught if issubclass(w.category, ImplausibleCameraWarning)]
    angle = np.degrees(np.linalg.norm(cv2.Rodrigues(result.R)[0]))
    if scale == 1.0:
        assert doubts == [] and abs(angle - 10.9) < 0.5
        return
    assert abs(angle - 10.9) > 5.0  # what the warning is about
    (doubt,) = doubts
    assert str(doubt.message) == (
        "K1 looks implausible for a 640x480 image: principal point (960.3, 742.8) is outside "
        "the 640x480 image"
    )
    assert doubt.filename == __file__  # points at the caller's line


def test_options_of_other_number_types_are_held_as_python_numbers():
    # seed=3.0 passed the check and reached numpy's SeedSequence mid-run: "SeedSequence expects
    # int or sequence of ints for entropy not 3.0", naming no option
    options = PairOptions(seed=3.0, max_features=np.int32(600), ratio=np.float32(0.75),
                          max_image_size=640.0, plane=np.bool_(True))  # fmt: skip
    held = [getattr(options, name)
            for name in ("seed", "max_features", "ratio", "max_image_size", "plane")]  # fmt: skip
    assert [type(value) for value in held] == [int, int, float, int, bool]
    result = ppo_cv.estimate_pair(*DEMO_IMAGES, K_DEMO, options=options)
    same = PairOptions(seed=3, max_features=600, ratio=0.75, max_image_size=640)
    expected = ppo_cv.estimate_pair(*DEMO_IMAGES, K_DEMO, options=same)
    np.testing.assert_array_equal(result.R, expected.R)


def test_run_sfm_refuses_a_skewed_K_before_any_work(tmp_path):
    images = tmp_path / "images"
    images.mkdir()
    for name in ("demo1.png", "demo2.png"):
        (images / name).write_bytes((Path(ppo_cv.__file__).parent / "data" / name).read_bytes())
    skewed = K.copy()
    skewed[0, 1] = 2.0
    database = tmp_path / "db.db"
    with pytest.raises(ValueError, match=r"K has skew 2\.0, which pycolmap's PINHOLE camera"):
        _sfm_module().run_sfm(images, tmp_path / "model", K=skewed, database_path=database)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["images"]


@pytest.mark.parametrize(
    "numbers", [{"seed": 3.0}, {"num_threads": 2.0}], ids=str
)
def test_sfm_numbers_of_other_types_reach_pycolmap_as_ints(tmp_path, numbers):
    # they passed the check and failed in pycolmap's option setters: "incompatible function
    # arguments ... Invoked with: RANSACOptions(...)"
    images = tmp_path / "images"
    images.mkdir()
    for image in DEMO_IMAGES:
        (images / Path(image).name).write_bytes(Path(image).read_bytes())
    assert _sfm_module().prepare_database(images, tmp_path / "db.db", **numbers) == 2


def test_sfm_of_images_in_subfolders_says_that_subfolders_are_not_read(tmp_path):
    # "need at least 2 images in 'images', found 0" left a newcomer to guess why
    (tmp_path / "images" / "cam0").mkdir(parents=True)
    for image in DEMO_IMAGES:
        (tmp_path / "images" / "cam0" / Path(image).name).write_bytes(Path(image).read_bytes())
    with pytest.raises(ValueError, match=r"found 0; sub-folders are not read, and cam0 holds"):
        _sfm_module().run_sfm(tmp_path / "images", tmp_path / "model")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["images"]


@pytest.mark.parametrize("shape", [(0, 0), (1, 48, 64, 3), (48, 64, 2), (48, 64, 5), (48,)])
def test_an_image_array_of_another_shape_is_refused_naming_every_accepted_shape(shape):
    with pytest.raises(ValueError) as error:
        ppo_cv.estimate_pair(np.zeros(shape, np.uint8), GREY, K)
    assert str(error.value) == (
        f"image1 must be an image of shape (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), got {shape}"
    )


@pytest.mark.parametrize(
    "scoring, error, words",
    [
        ({"pri_threshold": -1.0}, ValueError, r"pri_threshold must be a number in \[0, 1\]"),
        ({"pri_threshold": 1.5}, ValueError, r"pri_threshold must be a number in \[0, 1\]"),
        ({"min_inliers": "50"}, TypeError, r"min_inliers must be a whole number, got str '50'"),
        ({"min_inliers": 2.5}, ValueError, r"min_inliers must be a whole number in .*, got 2\.5"),
        ({"min_tri_angle": np.nan}, ValueError, r"min_tri_angle must be a finite number >= 0"),
        ({"max_forward_motion": -1.0}, ValueError, r"max_forward_motion must be a finite"),
    ],
    ids=["negative PRI threshold", "PRI threshold above 1", "inliers as text",
         "a fraction of an inlier", "NaN angle", "negative forward motion"],
)
def test_score_pairs_checks_its_options_before_the_database(tmp_path, scoring, error, words):
    with pytest.raises(error, match=words):
        _sfm_module().score_pairs(tmp_path / "absent.db", **scoring)


def test_too_few_images_gives_the_first_reasons_and_counts_the_rest():
    skipped = {f"{i}.png": f"not a readable image: d/{i}.png" for i in range(5)}
    with pytest.raises(ValueError) as error:
        _sfm_module().require_two_images("d", ["a.png"], skipped)
    assert str(error.value) == (
        "need at least 2 images in 'd', found 1 (5 skipped: not a readable image: d/0.png; "
        "not a readable image: d/1.png; not a readable image: d/2.png; 2 more)"
    )


def test_images_are_read_in_a_process_without_standard_error(monkeypatch):
    """``sys.stderr`` is None where Python starts without descriptor 2 (``2>&-``, some
    services); reading an image held back the native libraries' messages by flushing it."""
    monkeypatch.setattr("sys.stderr", None)
    image = load_image(Path(ppo_cv.__file__).parent / "data" / "demo1.png")
    assert image.shape == (480, 640, 3)


def _sqlite_file(path: Path, *statements: str) -> None:
    import sqlite3

    with sqlite3.connect(path) as db:
        for statement in statements:
            db.execute(statement)
    db.close()


DATABASES = {
    "no COLMAP table": (("CREATE TABLE notes (text)",),
                        "is an SQLite file but not a COLMAP database: it lacks cameras, images, "
                        "keypoints, matches, two_view_geometries"),
    "tables without COLMAP's columns": (
        ("CREATE TABLE cameras (a)", "CREATE TABLE images (a)", "CREATE TABLE keypoints (a)",
         "CREATE TABLE matches (a)", "CREATE TABLE two_view_geometries (a)"),
        "it lacks cameras.camera_id, cameras.model"),
    "truncated": (None, "cannot be read: database disk image is malformed"),
}  # fmt: skip


@pytest.mark.parametrize("call", ["score_pairs", "reconstruct"])
@pytest.mark.parametrize("case", list(DATABASES))
def test_an_sqlite_file_that_is_no_colmap_database_is_refused_untouched(tmp_path, case, call):
    """pycolmap wrote its tables into such a file (score_pairs then returned no pairs), or
    raised a RuntimeError after a log line of its own."""
    statements, words = DATABASES[case]
    path = tmp_path / "other.db"
    if statements is None:
        _sqlite_file(tmp_path / "whole.db", "CREATE TABLE notes (text)",
                     *[f"INSERT INTO notes VALUES ('{'x' * 2000}')"] * 20)  # fmt: skip
        path.write_bytes((tmp_path / "whole.db").read_bytes()[:5000])
    else:
        _sqlite_file(path, *statements)
    before = path.read_bytes()
    (tmp_path / "images").mkdir()
    sfm = _sfm_module()
    with pytest.raises(ValueError, match=re.escape(words)):
        if call == "score_pairs":
            sfm.score_pairs(path)
        else:
            sfm.reconstruct(path, tmp_path / "images")
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["other.db", "images", *(["whole.db"] if statements is None else [])]
    )


def test_prepare_database_names_a_missing_folder_before_any_work(tmp_path):
    (tmp_path / "images").mkdir()
    for image in ("demo1.png", "demo2.png"):
        (tmp_path / "images" / image).write_bytes(
            (Path(ppo_cv.__file__).parent / "data" / image).read_bytes()
        )
    with pytest.raises(ValueError, match="cannot write .*no/x.db: folder .*no does not exist"):
        _sfm_module().prepare_database(tmp_path / "images", tmp_path / "no" / "x.db", K=K)


@pytest.mark.parametrize(
    "output, database, words",
    [("images", None, "the output output_dir {root}/images is the input {root}/images"),
     (".", None, "the output output_dir {root} holds the input {root}/images"),
     ("model", "images/demo1.png", "database '{root}/images/demo1.png' already exists; give a "
      "new file name (a database is never replaced)")],
    ids=["the image folder", "a folder holding it", "an image as database"],
)  # fmt: skip
def test_run_sfm_never_replaces_its_images_even_with_overwrite(tmp_path, output, database, words):
    """run_sfm(images, images, overwrite=True) replaced the photos by the model."""
    (tmp_path / "images").mkdir()
    for image in ("demo1.png", "demo2.png"):
        (tmp_path / "images" / image).write_bytes(
            (Path(ppo_cv.__file__).parent / "data" / image).read_bytes()
        )
    before = {p.name: p.read_bytes() for p in (tmp_path / "images").iterdir()}
    target = tmp_path / output if output != "." else tmp_path
    with pytest.raises(ValueError, match=re.escape(words.format(root=tmp_path))):
        _sfm_module().run_sfm(tmp_path / "images", target, K=K, overwrite=True,
                              database_path=database and tmp_path / database)  # fmt: skip
    assert {p.name: p.read_bytes() for p in (tmp_path / "images").iterdir()} == before


def _demo_result_and_images():
    """(result, image1, image2) of the demo pair, the images as paths."""
    folder = Path(ppo_cv.__file__).parent / "data"
    images = [str(folder / name) for name in ("demo1.png", "demo2.png")]
    K_demo = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
    return ppo_cv.estimate_pair(*images, K_demo), *images


@pytest.mark.parametrize(
    "call, words",
    [(lambda out: ppo_cv.write_outputs(out, *_demo_result_and_images()),
      "exists and is not an empty directory; pass overwrite=True to replace it"),
     (lambda out: _sfm_module().run_sfm(Path(ppo_cv.__file__).parent / "data", out, K=K),
      "exists and is not an empty directory; pass overwrite=True to replace it"),
     (lambda out: _sfm_module().run_sfm(Path(ppo_cv.__file__).parent / "data", out.parent / "m",
                                        K=K, database_path=out / "kept", overwrite=True),
      "already exists; give a new file name (a database is never replaced)")],
    ids=["write_outputs", "run_sfm output_dir", "run_sfm database with overwrite"],
)  # fmt: skip
def test_an_existing_output_of_the_api_names_the_api_s_way(tmp_path, call, words):
    # the API's messages said 'pass --overwrite', an option of the command line; for a
    # database, which overwrite=True never replaces, they said it even with overwrite=True
    out = tmp_path / "out"
    out.mkdir()
    (out / "kept").write_text("kept")
    with pytest.raises(ValueError, match=re.escape(words)):
        call(out)
    assert [p.name for p in tmp_path.iterdir()] == ["out"] and (out / "kept").read_text() == "kept"


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.int64, np.longdouble])
def test_a_camera_matrix_of_another_number_type_is_its_values_exactly(dtype):
    # no float type is refused: each is converted to float64 exactly (float16 holds the camera
    # it was given, 800 and 320 here), as OpenCV reads them
    K_typed = K.astype(dtype)
    camera = ppo_cv.Camera(K_typed, np.array([0.01, 0, 0, 0], dtype=np.float16), (640.0, 480))
    assert camera.K.dtype == np.float64 and np.array_equal(camera.K, K)
    assert camera.dist.dtype == np.float64 and camera.dist[0] == np.float16(0.01)
    assert camera.image_size == (640, 480)
    pose, expected = ppo_cv.recover_pose(E, P1, P2, K_typed), ppo_cv.recover_pose(E, P1, P2, K)
    assert np.array_equal(pose.R, expected.R) and np.array_equal(pose.t, expected.t)


@pytest.mark.parametrize(
    "fields, exception, words",
    [(("hello",), TypeError, "Camera.K must be an array of real numbers, got str: parse a text"),
     ((K[:2],), ValueError, "Camera.K must be a 3x3 matrix"),
     ((-K,), ValueError, "Camera.K must be upper triangular"),
     ((K, [0.1, 0.2, 0.3]), ValueError, "Camera.dist must be OpenCV distortion coefficients"),
     ((K, None, 640), TypeError, "Camera.image_size must be (width, height) or None, got 640"),
     ((K, None, (640, -1)), ValueError, "Camera.image_size: image width and height must be"),
     # (True, True) was a 1x1 image
     ((K, None, (True, True)), ValueError, "Camera.image_size: image width and height must be"),
     # texts were read as numbers (b"640" too), and 10**400 failed in float(): OverflowError
     ((K, None, ("640", "480")), TypeError, "Camera.image_size must be two whole numbers"),
     ((K, None, (b"640", 480)), TypeError, "Camera.image_size must be two whole numbers"),
     ((K, None, (10**400, 480)), ValueError, "got <401-digit integer> and 480")],
    ids=["K text", "K 2x3", "K negative", "dist of 3", "size a number", "size negative",
         "size of flags", "size of texts", "size of bytes", "size beyond a float"],
)  # fmt: skip
def test_a_camera_is_checked_when_made(fields, exception, words):
    with pytest.raises(exception, match=re.escape(words)):
        ppo_cv.Camera(*fields)


def test_a_camera_holds_its_own_read_only_arrays():
    # Camera kept the caller's float64 arrays: changing them later changed the checked camera
    # (a negative focal length, unchecked), and so did writing into camera.K
    K_given, dist_given = K.copy(), np.array([0.01, 0.0, 0.0, 0.0])
    camera = ppo_cv.Camera(K_given, dist_given)
    K_given[0, 0], dist_given[0] = -800.0, 5.0
    assert camera.K[0, 0] == 800.0 and camera.dist[0] == 0.01
    for array in (camera.K, camera.dist):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0.0


@pytest.mark.parametrize(
    "call",
    [lambda dist: ppo_cv.Camera(K, dist),
     lambda dist: ppo_cv.recoverPose(P1, P2, K, dist, K, None),
     lambda dist: ppo_cv.estimate_pair(GREY, GREY[::-1], K, dist1=dist)],
    ids=["Camera", "recoverPose", "estimate_pair"],
)  # fmt: skip
@pytest.mark.parametrize("shape", [(2, 4), (3, 4), (2, 7)])
def test_the_coefficients_of_several_cameras_are_refused_as_distortion(call, shape):
    # two cameras' k1,k2,p1,p2 stacked (2, 4) were read as one rational model of 8 (and
    # (3, 4) as 12, (2, 7) as 14): OpenCV refuses them
    with pytest.raises(ValueError) as error:
        call(np.full(shape, 0.01))
    assert f"must be one row or column of coefficients, got shape {shape}" in str(error.value)


def test_a_camera_takes_its_image_size_as_a_numpy_pair():
    # np.array([640, 480]) was "Camera.image_size must be (width, height) or None"
    assert ppo_cv.Camera(K, None, np.array([640, 480])).image_size == (640, 480)


@pytest.mark.skipif(
    np.finfo(np.longdouble).max <= np.finfo(np.float64).max, reason="long double is float64 here"
)
def test_a_long_double_pixel_beyond_float64_is_named_so():
    image = GREY.astype(np.longdouble)
    image[3, 4] = np.longdouble("1e400")  # finite in long double, infinite in float64
    with pytest.raises(ValueError, match=r"^image1 has 1 pixel value\(s\) beyond the range of "):
        ppo_cv.estimate_pair(image, GREY, K)


def test_a_float_image_that_overshoots_one_keeps_its_contrast():
    # [0, 1.2] was read as 0..255 values: two grey levels, "too few features: blank or
    # textureless image"
    ramp = np.tile(np.linspace(0.0, 1.2, 64), (4, 1))
    gray = ppo_cv.features.to_uint8(ramp)
    assert gray.min() == 0 and gray.max() == 255 and len(np.unique(gray)) == 64
    dim = np.tile(np.arange(20.0), (4, 1))  # a float 0..255 image of 20 levels is kept
    np.testing.assert_array_equal(ppo_cv.features.to_uint8(dim), dim.astype(np.uint8))
    data = Path(ppo_cv.__file__).parent / "data"
    image1, image2 = load_image(data / "demo1.png"), load_image(data / "demo2.png")
    K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])
    reference = ppo_cv.estimate_pair(image1, image2, K)
    result = ppo_cv.estimate_pair(image1 / 255.0 * 1.2, image2 / 255.0 * 1.2, K)
    assert result.model == reference.model and result.num_inliers > 0.9 * reference.num_inliers


def test_the_alpha_channel_of_a_deep_image_does_not_scale_its_colours():
    # a 12-bit BGRA array with an opaque 16-bit alpha was scaled by 0..65535: colours 0..16
    data = Path(ppo_cv.__file__).parent / "data"
    image1, image2 = load_image(data / "demo1.png"), load_image(data / "demo2.png")
    K = np.array([[535.4, 0.0, 320.1], [0.0, 539.2, 247.6], [0.0, 0.0, 1.0]])

    def twelve_bit(image, alpha=None):
        deep = image.astype(np.uint16) * 16
        return deep if alpha is None else np.dstack([deep, np.full(image.shape[:2], alpha)])

    from ppo_cv.images import as_image

    opaque = twelve_bit(image1, np.uint16(65535))
    np.testing.assert_array_equal(as_image(opaque, "image1"), as_image(twelve_bit(image1), "x"))
    reference = ppo_cv.estimate_pair(twelve_bit(image1), twelve_bit(image2), K)
    result = ppo_cv.estimate_pair(opaque, twelve_bit(image2, np.uint16(65535)), K)
    assert result.num_inliers == reference.num_inliers
    np.testing.assert_array_equal(result.R, reference.R)


@pytest.mark.parametrize("order", ["K first", "K between the images"])
def test_a_camera_matrix_in_an_images_place_is_named_so(order):
    # estimate_pair(K, img1, img2) said "image1 is 3x3 pixels: too small or too thin to detect
    # features on", a fault of the image
    arguments = (K, GREY, GREY) if order == "K first" else (GREY, K, GREY)
    name = "image1" if order == "K first" else "image2"
    with pytest.raises(ValueError) as error:
        ppo_cv.estimate_pair(*arguments)
    assert str(error.value) == (
        f"{name} is a 3x3 array, no image: a camera matrix given in its place? (the images "
        "come first, then the camera matrices)"
    )


@pytest.mark.parametrize(
    "matrix, hint",
    [(K.T, "(transposed, as MATLAB's IntrinsicMatrix? pass its transpose)"),
     (2 * K, "(scaled as a whole? divide it by K[2,2] = 2)"),
     (skew([0.6, 0.0, 0.8]) @ random_rotation(np.random.default_rng(1), 20.0),
      "(an essential matrix? the arguments may be out of order)"),
     (np.eye(3)[::-1], "")],
    ids=["transposed", "scaled", "essential", "another matrix"],
)  # fmt: skip
def test_a_matrix_that_is_no_camera_matrix_is_named_for_what_it_likely_is(matrix, hint):
    # recoverPose(points1, points2, E, K) and a MATLAB IntrinsicMatrix got only "must be upper
    # triangular with last row (0, 0, 1)"
    with pytest.raises(ValueError) as error:
        ppo_cv.checks.as_camera_matrix(matrix, "K")
    assert str(error.value).endswith("]]" + (f" {hint}" if hint else ""))
    assert str(error.value).startswith("K must be upper triangular with last row (0, 0, 1)")
    points = np.random.default_rng(0).uniform(0, 640, (20, 2))
    with pytest.raises(cv2.error, match=re.escape(hint) if hint else "cameraMatrix1"):
        ppo_cv.recoverPose(points, points, matrix, K)


@pytest.mark.parametrize("dist", [np.zeros(5), [0.1, -0.05, 0.0, 0.0, 0.01], np.zeros(8)],
                         ids=["five zeros", "a list", "rational"])  # fmt: skip
def test_distortion_coefficients_in_the_place_of_K2_are_named_so(dist):
    # estimate_pair(img1, img2, K, dist), in OpenCV's order, said "K2 must be a 3x3 matrix, got
    # shape (5,)"
    with pytest.raises(ValueError) as error:
        ppo_cv.estimate_pair(GREY, GREY[::-1], K, dist)
    assert str(error.value) == (
        f"K2 must be a 3x3 matrix, got {len(dist)} numbers: distortion coefficients? "
        "estimate_pair takes image1, image2, K1, K2, dist1, dist2; pass them as dist1="
    )
    with pytest.raises(ValueError, match=r"^K2 must be a 3x3 matrix, got shape \(1, 5\)$"):
        ppo_cv.estimate_pair(GREY, GREY[::-1], K, [[0, 0, 0, 0, 0]])
    with pytest.raises((TypeError, ValueError), match="K2"):
        ppo_cv.estimate_pair(GREY, GREY[::-1], K, [1, [2, 3], 4, 5, 6])


def test_run_sfm_into_a_folder_of_photos_says_the_image_folder_comes_first(tmp_path):
    # run_sfm(model, images), the two folders the other way round, said "images exists and is
    # not an empty directory; pass overwrite=True to replace it": the photos' deletion
    for folder in ("model", "images"):
        (tmp_path / folder).mkdir()
    for image in ("demo1.png", "demo2.png"):
        (tmp_path / "model" / f"m_{image}").write_bytes(b"")
        (tmp_path / "images" / image).write_bytes(
            (Path(ppo_cv.__file__).parent / "data" / image).read_bytes()
        )
    before = {p.name: p.read_bytes() for p in (tmp_path / "images").iterdir()}
    for overwrite in (False, True):
        with pytest.raises(ValueError) as error:
            _sfm_module().run_sfm(tmp_path / "model", tmp_path / "images", K=K,
                                  overwrite=overwrite)  # fmt: skip
        assert str(error.value) == (
            f"output_dir {tmp_path / 'images'} holds 2 images (demo1.png, demo2.png), which a "
            "model folder never does: the image folder comes first, run_sfm(image_dir, "
            "output_dir); give an output folder without images"
        )
    assert {p.name: p.read_bytes() for p in (tmp_path / "images").iterdir()} == before


@pytest.mark.parametrize("recorded", [("640 px", 480), (0, 480), (-640, 480)],
                         ids=["text", "zero", "negative"])  # fmt: skip
def test_a_recorded_pixel_size_that_is_none_is_ignored_keeping_the_orientation(tmp_path, recorded):
    # a text PixelXDimension raised "invalid literal for int() with base 10: '640 px'" from
    # exif_layout, which pair calls on every photo, --K or not
    from PIL import Image

    path = tmp_path / "photo.jpg"
    exif = Image.Exif()
    exif[0x0112] = 6
    exif.get_ifd(0x8769)[0xA002], exif.get_ifd(0x8769)[0xA003] = recorded
    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(path, exif=exif)
    assert ppo_cv.images.exif_layout(path) == ppo_cv.images.ExifLayout(6, None, None)


def test_what_camera_from_exif_and_load_calibration_return_is_named_when_passed_as_K(tmp_path):
    # estimate_pair(a, b, camera_from_exif(a)) said "K1 must hold real numbers, got dtype object"
    camera = ppo_cv.Camera(K)
    words = (
        "K1 must be an array of real numbers, got a {} holding a Camera (as camera_from_exif "
        "and load_calibration return them): pass the camera's .K (and its .dist as the "
        "distortion)"
    )
    for given, kind in (((camera, True), "tuple"), ([camera], "list")):
        with pytest.raises(TypeError) as error:
            ppo_cv.estimate_pair(GREY, GREY[::-1], given)
        assert str(error.value) == words.format(kind)


def test_a_name_not_found_names_the_file_that_differs_in_case_only(tmp_path):
    """A camera's ``IMG_1.JPG`` named ``IMG_1.jpg``, as a list written where case is ignored
    names it: the error says which file is there."""
    photo = tmp_path / "IMG_1.JPG"
    photo.write_bytes((Path(ppo_cv.__file__).parent / "data" / "demo1.png").read_bytes())
    with pytest.raises(ValueError) as info:
        ppo_cv.estimate_pair(tmp_path / "IMG_1.jpg", photo, K)
    assert str(info.value) == (
        f"image not found: {tmp_path / 'IMG_1.jpg'} (IMG_1.JPG exists: names are case-sensitive)"
    )
    with pytest.raises(ValueError, match=r"not found: \S+IMG_2\.jpg$"):
        ppo_cv.estimate_pair(tmp_path / "IMG_2.jpg", photo, K)


def test_homogeneous_rows_of_any_w_are_the_image_points_they_stand_for():
    # the robust fits and the residuals read (x, y) of a row as its image point whatever its
    # w: rows scaled by 2 or -0.5, the same points, gave another E and other residuals
    scaled1, scaled2 = RAYS * 2.0, RAYS2 * -0.5
    fit = ppo_cv.robust.estimate_essential(RAYS, RAYS2, 800.0)
    again = ppo_cv.robust.estimate_essential(scaled1, scaled2, 800.0)
    assert np.array_equal(fit.E, again.E) and np.array_equal(fit.inliers, again.inliers)
    residuals = ppo_cv.robust.sampson_errors(E, RAYS, RAYS2)
    np.testing.assert_allclose(ppo_cv.robust.sampson_errors(E, scaled1, scaled2), residuals)
    np.testing.assert_allclose(
        ppo_cv.robust.sampson_signed_rows(E, scaled1.T, scaled2.T),
        ppo_cv.robust.sampson_signed(E, RAYS, RAYS2),
    )
    H = np.array([[1.0, 0.02, 0.01], [-0.03, 0.98, 0.02], [0.01, 0.0, 1.0]])
    for errors in (
        ppo_cv.homography.homography_sampson_errors,
        ppo_cv.homography.transfer_errors,
        ppo_cv.homography.symmetric_transfer_errors,
    ):
        np.testing.assert_allclose(errors(H, scaled1, scaled2), errors(H, RAYS, RAYS2))


def test_the_lens_maps_read_rows_of_any_w_as_their_image_points():
    # correct_points, transfer_points, lens_rotation_residuals and fit_rotation_lens read x and y
    # of a row as its point whatever its w: rows scaled by 2 (the same points) moved 0.4
    rotation = _rotation()
    scaled1, scaled2 = RAYS * 2.0, RAYS2 * -0.5
    lens = (1.01, -0.02, (0.001, 0.0))
    for name, args in (("correct_points", ()), ("transfer_points", (R_TRUE,))):
        mapped = getattr(rotation, name)
        np.testing.assert_allclose(mapped(scaled1, *args, *lens), mapped(RAYS, *args, *lens),
                                   rtol=1e-15)  # fmt: skip
    np.testing.assert_allclose(
        rotation.lens_rotation_residuals(R_TRUE, 1.01, -0.02, scaled1, scaled2),
        rotation.lens_rotation_residuals(R_TRUE, 1.01, -0.02, RAYS, RAYS2), rtol=1e-12)
    fits = [rotation.fit_rotation_lens(a, b, _ALL, R_TRUE) for a, b in ((RAYS, RAYS2),
                                                                       (scaled1, scaled2))]
    np.testing.assert_allclose(fits[1].R, fits[0].R, atol=1e-12)
    assert fits[1].focal_scale == pytest.approx(fits[0].focal_scale, abs=1e-12)


def test_homography_errors_do_not_depend_on_the_scale_of_H():
    H = np.array([[1.0, 0.02, 0.01], [-0.03, 0.98, 0.02], [0.01, 0.0, 1.0]])
    for errors in (
        ppo_cv.homography.homography_sampson_errors,
        ppo_cv.homography.transfer_errors,
        ppo_cv.homography.symmetric_transfer_errors,
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an overflow to NaN warned
            for scale in (1e200, 1e-200):
                np.testing.assert_allclose(errors(H * scale, RAYS, RAYS2), errors(H, RAYS, RAYS2))


def test_composed_distortion_takes_the_lens_as_a_list_or_empty():
    from ppo_cv.export import composed_distortion

    dist = np.array([-0.1, 0.01, 0.0, 0.0])
    expected = composed_distortion(K, dist, (640, 480), 0.05)  # a list or [] failed in OpenCV
    np.testing.assert_array_equal(composed_distortion(K, dist.tolist(), (640, 480), 0.05), expected)
    np.testing.assert_array_equal(
        composed_distortion(K, [], (640, 480), 0.05), composed_distortion(K, None, (640, 480), 0.05)
    )
    zeros = composed_distortion(K, np.zeros(8), (640, 480), 0.05)
    assert zeros.shape == (8,)  # as many coefficients as before: zeros are kept
    np.testing.assert_array_equal(composed_distortion(K, [0.0] * 8, (640, 480), 0.05), zeros)


def test_an_image_size_of_float16_is_read_without_an_overflow_warning():
    size = np.array([640, 480], np.float16)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the comparison with 2**31 - 1 overflowed its cast
        assert ppo_cv.calib.resize_scale(size, (320, 240)) == 0.5
        assert principal_point_is_centre(K, size) is True
