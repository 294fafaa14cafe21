"""Writing a :class:`~ppo_cv.pipeline.PairResult`: JSON, coloured PLY, match image, COLMAP model.

``write_outputs`` builds everything in a temporary directory beside the target and moves it into
place at the end, so a failure leaves no partial output.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from .pipeline import PairResult

__all__ = [
    "result_to_dict",
    "rotation_angle_axis",
    "euler_zyx_degrees",
    "write_ply",
    "draw_matches",
    "write_colmap_model",
    "write_outputs",
]


def rotation_angle_axis(R: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle (degrees) and unit axis (3,) of a rotation matrix; axis (0, 0, 1) for no rotation."""
    angle = np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    norm = np.linalg.norm(axis)
    if norm < 1e-12:
        if angle < 1e-6:
            return 0.0, np.array([0.0, 0.0, 1.0])
        # angle near 180 degrees: the axis is the dominant column of R + I
        column = (R + np.eye(3))[:, int(np.argmax(np.diag(R)))]
        return float(np.degrees(angle)), column / np.linalg.norm(column)
    return float(np.degrees(angle)), axis / norm


def euler_zyx_degrees(R: np.ndarray) -> tuple[float, float, float]:
    """Yaw (about z), pitch (about y) and roll (about x), degrees, with ``R = Rz Ry Rx``."""
    pitch = np.arcsin(np.clip(-R[2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[1, 0], R[0, 0])
    roll = np.arctan2(R[2, 1], R[2, 2])
    return float(np.degrees(yaw)), float(np.degrees(pitch)), float(np.degrees(roll))


def result_to_dict(result: PairResult, **extra: Any) -> dict:
    """A JSON-ready summary: pose, verdict, counts, intrinsics and timings (plus ``extra``).

    ``t`` is always the unit translation estimate; for a pure rotation it is undetermined and
    ``translation_determined`` is False.
    """
    angle, axis = rotation_angle_axis(result.R)
    data = {
        "R": np.asarray(result.R).tolist(),
        "t": np.asarray(result.t).tolist(),
        "pure_rotation": bool(result.pure_rotation),
        "translation_determined": bool(result.translation_determined),
        "pri": float(result.pri),
        "pri_threshold": float(result.pri_threshold),
        "model": str(result.model),
        "t_sigma_deg": float(result.t_sigma_deg),
        "model_selection": {
            "rotation_residual_px": float(result.rotation_residual_px),
            "general_residual_px": float(result.general_residual_px),
            "gric_difference": float(result.gric_difference),
            "noise_sigma_px": float(result.noise_sigma_px),
            "focal_scale": float(result.focal_scale),
        },
        "rotation_angle_deg": angle,
        "rotation_axis": axis.tolist(),
        "euler_zyx_deg": list(euler_zyx_degrees(result.R)),
        "num_keypoints": [int(len(result.keypoints1)), int(len(result.keypoints2))],
        "num_matches": result.num_matches,
        "num_inliers": result.num_inliers,
        "num_points": result.num_points,
        "K1": np.asarray(result.K1).tolist(),
        "K2": np.asarray(result.K2).tolist(),
        "image_size1": list(result.image_size1),
        "image_size2": list(result.image_size2),
        "timings": {k: round(float(v), 6) for k, v in result.timings.items()},
    }
    data.update(extra)
    return data


def write_ply(path: str | os.PathLike, points: np.ndarray, colours: np.ndarray) -> None:
    """Binary little-endian PLY of points (N, 3) float with uint8 RGB colours (N, 3)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    colours = np.asarray(colours, dtype=np.uint8).reshape(-1, 3)
    vertex = np.empty(
        len(points),
        dtype=[
            ("x", "<f4"),
            ("y", "<f4"),
            ("z", "<f4"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    vertex["x"], vertex["y"], vertex["z"] = points.T.astype(np.float32)
    vertex["red"], vertex["green"], vertex["blue"] = colours.T
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(points)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with open(path, "wb") as handle:
        handle.write(header.encode("ascii"))
        handle.write(vertex.tobytes())


def draw_matches(image1: np.ndarray, image2: np.ndarray, result: PairResult) -> np.ndarray:
    """Side-by-side BGR image with inlier matches in green and outliers in red."""
    import cv2

    def bgr(image):
        image = np.asarray(image)
        if image.dtype != np.uint8:
            image = np.clip(image, 0, 255).astype(np.uint8)
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image[:, :, :3]

    a, b = bgr(image1), bgr(image2)
    height = max(a.shape[0], b.shape[0])
    canvas = np.zeros((height, a.shape[1] + b.shape[1], 3), dtype=np.uint8)
    canvas[: a.shape[0], : a.shape[1]] = a
    canvas[: b.shape[0], a.shape[1] :] = b
    p1 = result.keypoints1[result.matches[:, 0]]
    p2 = result.keypoints2[result.matches[:, 1]] + (a.shape[1], 0)
    segments = np.rint(np.stack([p1, p2], axis=1)).astype(np.int32)
    outliers, inliers = segments[~result.inliers], segments[result.inliers]
    cv2.polylines(canvas, list(outliers), False, (0, 0, 255), 1, cv2.LINE_AA)
    cv2.polylines(canvas, list(inliers), False, (0, 200, 0), 1, cv2.LINE_AA)
    return canvas


def _colmap_camera(K: np.ndarray, dist: np.ndarray | None, size: tuple[int, int], camera_id: int):
    import pycolmap

    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if dist is None or not np.any(dist):
        model, params = "PINHOLE", [fx, fy, cx, cy]
    elif np.asarray(dist).size <= 4:
        model, params = "OPENCV", [fx, fy, cx, cy, *np.asarray(dist)[:4]]
    else:
        coeffs = np.r_[np.asarray(dist, float)[:8], np.zeros(8)][:8]
        model, params = "FULL_OPENCV", [fx, fy, cx, cy, *coeffs]
    return pycolmap.Camera(
        model=model, width=size[0], height=size[1], params=params, camera_id=camera_id
    )


def write_colmap_model(
    directory: str | os.PathLike,
    result: PairResult,
    names: tuple[str, str] = ("image1.png", "image2.png"),
    dists: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
) -> None:
    """COLMAP text model (cameras, images, points3D) of the two views and the analytic points.

    Camera 1 is the world frame; camera 2 has pose ``(R, t)`` (``t`` zero for a pure rotation);
    the unit is the baseline.
    """
    import pycolmap

    reconstruction = pycolmap.Reconstruction()
    same = (
        np.allclose(result.K1, result.K2)
        and result.image_size1 == result.image_size2
        and (
            (dists[0] is None and dists[1] is None)
            or (
                dists[0] is not None and dists[1] is not None and np.array_equal(dists[0], dists[1])
            )
        )
    )
    reconstruction.add_camera_with_trivial_rig(
        _colmap_camera(result.K1, dists[0], result.image_size1, 1)
    )
    if not same:
        reconstruction.add_camera_with_trivial_rig(
            _colmap_camera(result.K2, dists[1], result.image_size2, 2)
        )
    p1, p2 = result.inlier_points
    t = np.zeros(3) if result.pure_rotation else np.asarray(result.t, float)
    poses = (
        pycolmap.Rigid3d(pycolmap.Rotation3d(np.eye(3)), np.zeros(3)),
        pycolmap.Rigid3d(pycolmap.Rotation3d(np.asarray(result.R, float)), t),
    )
    for image_id, (name, points, pose) in enumerate(zip(names, (p1, p2), poses, strict=True), 1):
        image = pycolmap.Image(
            name=name,
            keypoints=np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2),
            camera_id=1 if (same or image_id == 1) else 2,
            image_id=image_id,
        )
        reconstruction.add_image_with_trivial_frame(image, pose)
    # Index of each inlier among the inliers: the keypoint index within both images.
    inlier_rank = np.cumsum(result.inliers) - 1
    for xyz, colour, row in zip(result.points3d, result.colours, result.point_matches, strict=True):
        k = int(inlier_rank[row])
        track = pycolmap.Track()
        track.add_element(1, k)
        track.add_element(2, k)
        reconstruction.add_point3D(np.asarray(xyz, float), track, np.asarray(colour, np.uint8))
    os.makedirs(directory, exist_ok=True)
    reconstruction.write_text(os.fspath(directory))


def write_outputs(
    directory: str | os.PathLike,
    result: PairResult,
    image1: np.ndarray,
    image2: np.ndarray,
    names: tuple[str, str] = ("image1.png", "image2.png"),
    dists: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
    extra: dict | None = None,
) -> Path:
    """Write ``result.json``, ``points.ply``, ``matches.png`` and ``colmap/`` into ``directory``.

    ``extra`` entries are added to ``result.json``. Files are written to a temporary sibling
    directory that replaces ``directory`` only when all
    of them are complete; an existing ``directory`` keeps its other files.
    """
    import cv2

    target = Path(directory)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        (staging / "result.json").write_text(
            json.dumps(result_to_dict(result, **(extra or {})), indent=2) + "\n", encoding="utf-8"
        )
        write_ply(staging / "points.ply", result.points3d, result.colours)
        if not cv2.imwrite(str(staging / "matches.png"), draw_matches(image1, image2, result)):
            raise OSError("could not encode matches.png")
        write_colmap_model(staging / "colmap", result, names, dists)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(staging, 0o777 & ~umask)  # mkdtemp creates it private
        if target.exists():
            for entry in staging.iterdir():
                destination = target / entry.name
                if destination.is_dir():
                    shutil.rmtree(destination)
                os.replace(entry, destination)
            staging.rmdir()
        else:
            os.replace(staging, target)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return target
