"""Reference two-view pipelines on shared SIFT matches, and the pose-error metrics.

Every anchor receives the same matches: OpenCV SIFT (4000 features), brute-force 2-NN and
Lowe's ratio test at 0.8, the protocol of the real-pair evaluation of the shared data. The
anchors then estimate the relative pose ``x2 = R x1 + t``:

``opencv``
    ``cv2.findEssentialMat`` (USAC_MAGSAC, confidence 0.99999, 1 px on normalized points)
    and ``cv2.recoverPose`` (cheirality).
``opencv + ppo_cv``
    The same essential matrix and inliers, the pose chosen by ``ppo_cv.recoverPose``: the
    drop-in use of the library.
``pycolmap``
    ``estimate_calibrated_two_view_geometry`` then ``estimate_two_view_geometry_pose``; its
    configuration (CALIBRATED, PLANAR, PANORAMIC, PLANAR_OR_PANORAMIC, ...) is kept.
``pycolmap relpose``
    ``estimate_relative_pose`` (LO-RANSAC on the tangent Sampson error, 1 px) then
    ``refine_relative_pose``.
``poselib``
    ``poselib.estimate_relative_pose`` (1 px epipolar error).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

import ppo_cv
from ppo_cv import ppo
from ppo_cv.metrics import direction_error_deg, rotation_error_deg

__all__ = [
    "ANCHORS",
    "Matches",
    "AnchorResult",
    "sift_matches",
    "run_anchor",
    "pose_error_deg",
    "auc",
    "read_pairs_file",
]

ANCHORS = ("opencv", "opencv + ppo_cv", "pycolmap", "pycolmap relpose", "poselib")


@dataclass(frozen=True)
class Matches:
    """Matched pixel coordinates (N, 2) of two images, their sizes (W, H) and the time taken."""

    points1: np.ndarray
    points2: np.ndarray
    size1: tuple[int, int]
    size2: tuple[int, int]
    seconds: float


@dataclass(frozen=True)
class AnchorResult:
    """Pose of one anchor (None when it failed), its time and extra outputs."""

    R: np.ndarray | None
    t: np.ndarray | None
    seconds: float
    extra: dict = field(default_factory=dict)


def _gray(image: np.ndarray) -> np.ndarray:
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def sift_matches(image1: np.ndarray, image2: np.ndarray) -> Matches:
    """SIFT (4000) + 2-NN ratio test (0.8) matches between two BGR or grey images."""
    start = time.perf_counter()
    g1, g2 = _gray(image1), _gray(image2)
    sift = cv2.SIFT_create(4000)
    k1, d1 = sift.detectAndCompute(g1, None)
    k2, d2 = sift.detectAndCompute(g2, None)
    p1 = np.empty((0, 2))
    p2 = np.empty((0, 2))
    if d1 is not None and d2 is not None and len(k1) >= 2 and len(k2) >= 2:
        knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
        good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
        p1 = np.array([k1[m.queryIdx].pt for m in good], dtype=np.float64).reshape(-1, 2)
        p2 = np.array([k2[m.trainIdx].pt for m in good], dtype=np.float64).reshape(-1, 2)
    return Matches(
        p1, p2, (g1.shape[1], g1.shape[0]), (g2.shape[1], g2.shape[0]), time.perf_counter() - start
    )


def _pinhole(K: np.ndarray) -> list[float]:
    return [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]


def _opencv(m: Matches, K1: np.ndarray, K2: np.ndarray, use_ppo: bool) -> AnchorResult:
    start = time.perf_counter()
    n1 = cv2.undistortPoints(m.points1.reshape(-1, 1, 2), K1, None).reshape(-1, 2)
    n2 = cv2.undistortPoints(m.points2.reshape(-1, 1, 2), K2, None).reshape(-1, 2)
    focal = (K1[0, 0] + K1[1, 1] + K2[0, 0] + K2[1, 1]) / 4.0
    E, mask = cv2.findEssentialMat(n1, n2, np.eye(3), cv2.USAC_MAGSAC, 0.99999, 1.0 / focal)
    if E is None or mask is None:
        return AnchorResult(None, None, time.perf_counter() - start)
    recover = ppo_cv.recoverPose if use_ppo else cv2.recoverPose
    _, R, t, _ = recover(E[:3], n1, n2, np.eye(3), mask=mask)
    extra = {}
    if use_ppo:
        used = mask.ravel() != 0
        result = ppo_cv.recover_pose(E[:3], n1, n2, np.eye(3), mask=used)
        extra = {"pure_rotation": result.pure_rotation, "pri": result.pri, "m3": result.m3}
    return AnchorResult(R, t.ravel(), time.perf_counter() - start, extra)


def _pycolmap(m: Matches, K1: np.ndarray, K2: np.ndarray) -> AnchorResult:
    import pycolmap

    start = time.perf_counter()
    c1 = pycolmap.Camera(model="PINHOLE", width=m.size1[0], height=m.size1[1], params=_pinhole(K1))
    c2 = pycolmap.Camera(model="PINHOLE", width=m.size2[0], height=m.size2[1], params=_pinhole(K2))
    pairs = np.repeat(np.arange(len(m.points1), dtype=np.uint32)[:, None], 2, axis=1)
    geometry = pycolmap.estimate_calibrated_two_view_geometry(c1, m.points1, c2, m.points2, pairs)
    config = pycolmap.TwoViewGeometryConfiguration(int(geometry.config)).name
    posed = pycolmap.estimate_two_view_geometry_pose(c1, m.points1, c2, m.points2, geometry)
    seconds = time.perf_counter() - start
    extra = {"config": config, "tri_angle_deg": float(np.degrees(geometry.tri_angle))}
    if not posed:
        return AnchorResult(None, None, seconds, extra)
    pose = geometry.cam2_from_cam1
    return AnchorResult(pose.rotation.matrix(), np.asarray(pose.translation), seconds, extra)


def _pycolmap_relpose(m: Matches, K1: np.ndarray, K2: np.ndarray) -> AnchorResult:
    import pycolmap

    start = time.perf_counter()
    c1 = pycolmap.Camera(model="PINHOLE", width=m.size1[0], height=m.size1[1], params=_pinhole(K1))
    c2 = pycolmap.Camera(model="PINHOLE", width=m.size2[0], height=m.size2[1], params=_pinhole(K2))
    options = pycolmap.RANSACOptions()
    options.max_error = 1.0
    found = pycolmap.estimate_relative_pose(c1, m.points1, c2, m.points2, options)
    if found is None:
        return AnchorResult(None, None, time.perf_counter() - start)
    pose = found["cam2_from_cam1"]
    refined = pycolmap.refine_relative_pose(
        pose, c1, m.points1, c2, m.points2, found["inlier_mask"]
    )
    if refined is not None:
        pose = refined["cam2_from_cam1"] if isinstance(refined, dict) else refined
    return AnchorResult(
        pose.rotation.matrix(), np.asarray(pose.translation), time.perf_counter() - start
    )


def _poselib(m: Matches, K1: np.ndarray, K2: np.ndarray) -> AnchorResult:
    import poselib

    start = time.perf_counter()
    c1 = {"model": "PINHOLE", "width": m.size1[0], "height": m.size1[1], "params": _pinhole(K1)}
    c2 = {"model": "PINHOLE", "width": m.size2[0], "height": m.size2[1], "params": _pinhole(K2)}
    pose, _ = poselib.estimate_relative_pose(
        m.points1, m.points2, c1, c2, {"max_epipolar_error": 1.0}, {}
    )
    return AnchorResult(np.asarray(pose.R), np.asarray(pose.t), time.perf_counter() - start)


def run_anchor(name: str, matches: Matches, K1: np.ndarray, K2: np.ndarray) -> AnchorResult:
    """Pose of anchor ``name`` (one of :data:`ANCHORS`) from shared matches.

    Failures are returned, not raised.
    """
    if len(matches.points1) < 8:
        return AnchorResult(None, None, 0.0)
    try:
        if name == "opencv":
            return _opencv(matches, K1, K2, use_ppo=False)
        if name == "opencv + ppo_cv":
            return _opencv(matches, K1, K2, use_ppo=True)
        if name == "pycolmap":
            return _pycolmap(matches, K1, K2)
        if name == "pycolmap relpose":
            return _pycolmap_relpose(matches, K1, K2)
        if name == "poselib":
            return _poselib(matches, K1, K2)
    except Exception as exc:  # a failure is a benchmark outcome: record it, keep going
        return AnchorResult(None, None, 0.0, {"error": repr(exc)})
    raise ValueError(f"unknown anchor {name!r}")


def pose_error_deg(
    R: np.ndarray | None, t: np.ndarray | None, R_gt: np.ndarray, t_gt: np.ndarray
) -> tuple[float, float, float]:
    """(rotation error, translation-direction error, pose error) in degrees.

    The translation error ignores the sign of ``t`` (the usual relative-pose AUC convention);
    the pose error is the larger of the two, or the rotation error alone when the true
    translation is zero (pure rotation). An estimate without a translation direction
    (``t = 0``, e.g. pycolmap's PANORAMIC) of a moving camera has a 90 degree translation error;
    a failed estimate counts as 180 degrees.
    """
    if R is None or t is None:
        return 180.0, 180.0, 180.0
    e_R = rotation_error_deg(R, R_gt)
    if np.linalg.norm(t_gt) < 1e-12:
        return e_R, float("nan"), e_R
    norm = np.linalg.norm(t) * np.linalg.norm(t_gt)
    if norm < 1e-12:
        return e_R, 90.0, max(e_R, 90.0)
    e_t = direction_error_deg(t, t_gt, signed=False)
    return e_R, e_t, max(e_R, e_t)


def auc(errors, threshold: float) -> float:
    """Area under the recall-error curve up to ``threshold`` degrees, normalised to [0, 1]."""
    errors = np.sort(np.asarray(errors, dtype=np.float64))
    recall = np.arange(1, len(errors) + 1) / len(errors)
    errors = np.concatenate([[0.0], errors])
    recall = np.concatenate([[0.0], recall])
    last = int(np.searchsorted(errors, threshold))
    x = np.concatenate([errors[:last], [threshold]])
    y = np.concatenate([recall[:last], [recall[last - 1]]])
    return float(np.trapezoid(y, x) / threshold)


def read_pairs_file(path: Path) -> list[dict]:
    """Rows of a pairs-with-ground-truth file: names, K1, K2, R and t of ``T_1to2``."""
    rows = []
    for line in Path(path).read_text().splitlines():
        f = line.split()
        if not f:
            continue
        T = np.array(f[22:38], dtype=np.float64).reshape(4, 4)
        rows.append(
            {
                "name1": f[0],
                "name2": f[1],
                "K1": np.array(f[4:13], dtype=np.float64).reshape(3, 3),
                "K2": np.array(f[13:22], dtype=np.float64).reshape(3, 3),
                "R": T[:3, :3],
                "t": T[:3, 3],
            }
        )
    return rows


def m3_of(
    points1: np.ndarray, points2: np.ndarray, K1: np.ndarray, K2: np.ndarray, R: np.ndarray
) -> float:
    """The paper's M3 (eq. 78) of matches under rotation R."""
    if len(points1) == 0:
        return float("nan")
    n1 = cv2.undistortPoints(points1.reshape(-1, 1, 2).astype(np.float64), K1, None).reshape(-1, 2)
    n2 = cv2.undistortPoints(points2.reshape(-1, 1, 2).astype(np.float64), K2, None).reshape(-1, 2)
    ones = np.ones((len(n1), 1))
    return ppo.m3_indicator(np.hstack([n1, ones]), np.hstack([n2, ones]), R)


if __name__ == "__main__":
    raise SystemExit(
        "anchors.py is a module of compare.py, model_choice.py, planar_pairs.py and "
        "guided_matching.py, not a script; run python benchmarks/compare.py --help"
    )
