"""Writing a :class:`~ppo_cv.pipeline.PairResult`: JSON, coloured PLY, match image, COLMAP model.

Conventions of every export: ``X2 = R X1 + t`` maps camera-1 coordinates to camera-2
coordinates, ``t`` has unit length (the images fix no scale), camera axes are x right, y down,
z forward (OpenCV's), and the 3D points are in camera-1 coordinates with a unit baseline.

``write_outputs`` builds everything in a temporary directory beside the target and moves it into
place at the end, so a failure leaves no partial output.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .calib import COLMAP_PIXEL_OFFSET
from .checks import (
    MAX_RADIAL,
    MAX_WHOLE_NUMBER,
    as_camera_matrix,
    as_distortion,
    as_image_size,
    as_number,
    as_path,
    as_rotation,
    as_whole_number,
    shown,
)
from .result import (
    DecisionEvidence,
    LensTerms,
    PairCameras,
    PairResult,
    PlaneGeometry,
    PoseUncertainty,
)

__all__ = [
    "POSE_CONVENTION",
    "CAMERA_AXES",
    "EULER_CONVENTION",
    "CameraEuler",
    "camera_euler_degrees",
    "result_to_dict",
    "rotation_angle_axis",
    "euler_zyx_degrees",
    "write_ply",
    "matches_to_draw",
    "draw_matches",
    "MAX_DRAWN_MATCHES",
    "check_colmap_camera",
    "check_colmap_names",
    "write_colmap_model",
    "write_outputs",
    "fitted_radial_k1",
    "composed_distortion",
    "require_result",
]

POSE_CONVENTION = "X2 = R X1 + t: camera-1 coordinates to camera-2 coordinates, |t| = 1"
CAMERA_AXES = "x right, y down, z forward"
EULER_CONVENTION = (
    "R = Ry(yaw) Rx(pitch) Rz(roll) in camera axes: yaw (pan) about y, pitch (tilt) about x, "
    "roll about z, degrees"
)
MAX_DRAWN_MATCHES = 150


class CameraEuler(NamedTuple):
    """Euler angles of a rotation in camera axes (x right, y down, z forward), degrees.

    ``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)``: yaw (pan) about y, pitch (tilt) about x, roll about
    the optical axis z, each right-handed.
    """

    yaw: float
    pitch: float
    roll: float


def camera_euler_degrees(R: np.ndarray) -> CameraEuler:
    """Yaw, pitch and roll of a rotation in the camera convention, degrees.

    Parameters
    ----------
    R : ndarray, shape (3, 3)
        Rotation matrix, e.g. the ``R`` of ``X2 = R X1 + t``.

    Returns
    -------
    CameraEuler
        ``(yaw, pitch, roll)`` with ``R = Ry(yaw) Rx(pitch) Rz(roll)``, yaw and roll in
        (-180, 180], pitch in [-90, 90]. At pitch +-90 (gimbal lock) roll is set to 0.

    Notes
    -----
    With ``c = cos``, ``s = sin``: ``R[1, 2] = -s(pitch)``, ``(R[0, 2], R[2, 2]) = c(pitch)
    (s(yaw), c(yaw))`` and ``(R[1, 0], R[1, 1]) = c(pitch) (s(roll), c(roll))``.

    Examples
    --------
    >>> import cv2, numpy as np
    >>> [round(a, 6) for a in camera_euler_degrees(cv2.Rodrigues(np.radians([0, 10, 0]))[0])]
    [10.0, 0.0, 0.0]
    """
    R = as_rotation(R, "R")
    pitch = np.arcsin(np.clip(-R[1, 2], -1.0, 1.0))
    if np.hypot(R[1, 0], R[1, 1]) < 1e-9:
        yaw, roll = np.arctan2(-R[2, 0], R[0, 0]), 0.0
    else:
        yaw, roll = np.arctan2(R[0, 2], R[2, 2]), np.arctan2(R[1, 0], R[1, 1])
    return CameraEuler(*(float(np.degrees(a)) + 0.0 for a in (yaw, pitch, roll)))


def rotation_angle_axis(R: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle (degrees) and unit axis (3,) of a rotation matrix; axis (0, 0, 1) for no rotation.
    ValueError for a matrix that is no rotation (:func:`ppo_cv.checks.as_rotation`)."""
    R = as_rotation(R, "R")
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
    """Angles about z, y and x (degrees) with ``R = Rz Ry Rx``: the aerospace sequence.

    Kept for existing callers. Its names yaw/pitch/roll fit a body with z up, not a camera
    (z forward, y down); the exports label angles with :func:`camera_euler_degrees`.
    """
    R = as_rotation(R, "R")
    pitch = np.arcsin(np.clip(-R[2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[1, 0], R[0, 0])
    roll = np.arctan2(R[2, 1], R[2, 2])
    return float(np.degrees(yaw)), float(np.degrees(pitch)), float(np.degrees(roll))


def require_result(result: Any) -> None:
    """TypeError unless ``result`` is a :class:`PairResult`, the answer of ``estimate_pair``."""
    if not isinstance(result, PairResult):
        raise TypeError(f"result must be a PairResult (estimate_pair), got {type(result).__name__}")


def _listed(array: Any) -> list | None:
    return None if array is None else np.asarray(array, dtype=np.float64).tolist()


def _cameras(cameras: PairCameras) -> dict:
    return {
        "K1": np.asarray(cameras.K1).tolist(),
        "K2": np.asarray(cameras.K2).tolist(),
        "dist1": _listed(cameras.dist1),
        "dist2": _listed(cameras.dist2),
        "image_size1": list(cameras.image_size1),
        "image_size2": list(cameras.image_size2),
    }


def _uncertainty(uncertainty: PoseUncertainty) -> dict:
    return {
        "t_sigma_deg": float(uncertainty.t_sigma_deg),
        "rotation_sigma_deg": _finite_or_none(uncertainty.rotation_sigma_deg),
        "rotation_tracks": int(uncertainty.rotation_tracks),
        "rotation_bias_deg": _finite_or_none(uncertainty.rotation_bias_deg),
    }


def _lens(lens: LensTerms) -> dict:
    return {
        "focal_scale": float(lens.focal_scale),
        "focal_ratio": float(lens.focal_ratio),
        "principal_offset_px": _listed(lens.principal_offset_px),
        "principal_bound": _finite_or_none(lens.principal_bound),
        "lens_excess": _finite_or_none(lens.lens_excess),
        "radial_k1": _finite_or_none(lens.radial_k1),
        "wanted_focal_scale": _finite_or_none(lens.wanted_focal_scale),
    }


def _evidence(evidence: DecisionEvidence) -> dict:
    selection = evidence.selection
    return {
        "selection": {
            "pri_threshold": float(selection.pri_threshold),
            "rotation_residual_px": float(selection.rotation_residual_px),
            "general_residual_px": float(selection.general_residual_px),
            "plane_residual_px": _finite_or_none(selection.plane_residual_px),
            "gric_difference": float(selection.gric_difference),
            "gric_plane_difference": _finite_or_none(selection.gric_plane_difference),
            "plane_epipolar_ratio": _finite_or_none(selection.plane_epipolar_ratio),
            "noise_sigma_px": float(selection.noise_sigma_px),
            "rotation_noise_px": _finite_or_none(selection.rotation_noise_px),
            "coherent_share": float(selection.coherent_share),
            "rotation_gap_deg": _finite_or_none(selection.rotation_gap_deg),
        },
        "tracks": {
            "parallax": _finite_or_none(evidence.tracks.parallax),
            "parallax_sigma": _finite_or_none(evidence.tracks.parallax_sigma),
        },
        "significance": {
            "log10_nfa": float(evidence.significance.log10_nfa),
            "threshold_scale": float(evidence.significance.threshold_scale),
            "ransac_threshold_px": float(evidence.significance.ransac_threshold_px),
        },
    }


def _plane(plane: PlaneGeometry | None) -> dict | None:
    if plane is None:
        return None
    return {
        "normal": np.asarray(plane.normal, dtype=np.float64).tolist(),
        "distance": float(plane.distance),
        "ambiguous": bool(plane.ambiguous),
        "k1": _finite_or_none(plane.k1),
    }


def _finite_or_none(value: float) -> float | None:
    value = float(value)
    return value if np.isfinite(value) else None


def result_to_dict(result: PairResult, **extra: Any) -> dict:
    """A JSON-ready summary whose keys follow the paths of :class:`PairResult` (+ ``extra``).

    At the top: ``R`` and ``t`` following ``X2 = R X1 + t`` with ``|t| = 1`` (``convention``),
    ``pure_rotation``, ``model`` (``"rotation"``, ``"plane"`` or ``"general"``), ``pri``, the
    angle, axis and camera Euler angles of ``R`` (``rotation_euler_deg``, yaw, pitch and roll
    in camera axes: :func:`camera_euler_degrees`) and the counts. When the translation is not
    determined (a pure rotation) ``t`` is None and the best unit guess, which the images do not
    support, is under ``t_guess``. Then the records: ``cameras`` (``K1``, ``K2``, ``dist1`` and
    ``dist2``, the OpenCV coefficients removed from the points, None for none, image sizes),
    ``uncertainty``, ``lens``, ``evidence`` (``selection``, ``tracks``, ``significance``; its
    ``threshold_scale`` is below 1 after a second, denser detection:
    ``PairOptions.redetect_below``), ``plane`` (the plane's unit ``normal`` in camera 1, its
    ``distance`` in baselines, whether the homography's two-fold ambiguity had to be broken
    and its radial ``k1``; None unless the model is a plane) and ``timings``. A value that is
    not finite where the model does not define it is None. An ``extra`` key that is one of
    these top-level keys is a ValueError.
    """
    require_result(result)
    angle, axis = rotation_angle_axis(result.R)
    t = np.asarray(result.t, dtype=np.float64).tolist()
    data = {
        "convention": POSE_CONVENTION,
        "camera_axes": CAMERA_AXES,
        "R": np.asarray(result.R).tolist(),
        "t": t if result.translation_determined else None,
        **({} if result.translation_determined else {"t_guess": t}),
        "pure_rotation": bool(result.pure_rotation),
        "translation_determined": bool(result.translation_determined),
        "model": str(result.model),
        "rotation_source": str(result.rotation_source),
        "pri": float(result.pri),
        "rotation_angle_deg": angle,
        "rotation_axis": axis.tolist(),
        "rotation_euler_deg": camera_euler_degrees(result.R)._asdict(),
        "euler_convention": EULER_CONVENTION,
        "num_keypoints": [int(len(result.keypoints1)), int(len(result.keypoints2))],
        "num_matches": result.num_matches,
        "num_inliers": result.num_inliers,
        "num_points": result.num_points,
        "cameras": _cameras(result.cameras),
        "uncertainty": _uncertainty(result.uncertainty),
        "lens": _lens(result.lens),
        "evidence": _evidence(result.evidence),
        "plane": _plane(result.plane),
        "timings": {k: round(float(v), 6) for k, v in result.timings.items()},
    }
    replaced = sorted(set(extra) & set(data))
    if replaced:
        raise ValueError(
            f"extra would replace the result's own field(s) {', '.join(map(repr, replaced))}; "
            "give them other names"
        )
    data.update(extra)
    return data


def write_ply(path: str | os.PathLike, points: np.ndarray, colours: np.ndarray) -> None:
    """Binary little-endian PLY of points (N, 3) float with uint8 RGB colours (N, 3).

    The file is written whole or not at all, replacing an existing one
    (:func:`ppo_cv.atomic.atomic_file`). ValueError for points that are not finite rows of
    three within float32, or colours that are not one row of three 0..255 whole numbers per
    point.
    """
    from .atomic import atomic_file

    path = as_path(path, "path")
    points, colours = _ply_rows(points, colours)
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
    with atomic_file(path, overwrite=True, mode="wb") as handle:
        handle.write(header.encode("ascii"))
        handle.write(vertex.tobytes())


def _ply_rows(points: Any, colours: Any) -> tuple[np.ndarray, np.ndarray]:
    """The points (N, 3) and colours (N, 3) of :func:`write_ply`, checked."""
    from .checks import as_finite_rows

    points = as_finite_rows(points, "points", 3)
    if points.size and np.abs(points).max() > np.finfo(np.float32).max:
        raise ValueError("points must lie within float32's range, which PLY stores")
    colours = np.asarray(colours)
    if colours.shape != points.shape:
        raise ValueError(
            f"colours must have the shape of points {points.shape}, got {colours.shape}"
        )
    bytes_only = not colours.size or 0 <= colours.min() <= colours.max() <= 255
    if colours.dtype.kind not in "bui" or not bytes_only:
        raise ValueError(f"colours must be 0..255 whole numbers, got dtype {colours.dtype}")
    return points, colours.astype(np.uint8)


def _max_lines(value: Any) -> int | None:
    """``max_lines`` checked: None or a whole number >= 0, named in the error."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"max_lines must be a whole number or None, got {type(value).__name__} "
                        f"{shown(value)}")  # fmt: skip
    whole = isinstance(value, (int, np.integer)) or float(value).is_integer()
    if not (value >= 0 and whole):  # an int beyond float's range compares, whole
        raise ValueError(f"max_lines must be a whole number >= 0 or None, got {shown(value)}")
    return int(value)


def matches_to_draw(
    inliers: np.ndarray, max_lines: int | None = MAX_DRAWN_MATCHES, seed: int = 0
) -> np.ndarray:
    """Rows of the matches to draw: all when they fit in ``max_lines``, else inliers first.

    Parameters
    ----------
    inliers : ndarray of bool, shape (M,)
        Inlier flag of each match.
    max_lines : int or None
        Most lines to draw; None draws every match.
    seed : int
        Seed of the uniform sample taken within the inliers, then within the outliers.

    Returns
    -------
    ndarray of int, shape (D,)
        Sorted rows, ``D = min(M, max_lines)``.
    """
    inliers = np.asarray(inliers)
    if inliers.ndim != 1 or inliers.dtype != bool:
        raise TypeError(
            f"inliers must be a one-dimensional array of bool, got {inliers.dtype} of shape "
            f"{inliers.shape}"
        )
    seed = as_whole_number(seed, "seed", 0, MAX_WHOLE_NUMBER)
    max_lines = _max_lines(max_lines)
    if max_lines is None or inliers.size <= max_lines:
        return np.arange(inliers.size)
    rng = np.random.default_rng(seed)
    inlier_rows, outlier_rows = np.flatnonzero(inliers), np.flatnonzero(~inliers)
    take = min(inlier_rows.size, max_lines)
    chosen = (
        rng.choice(inlier_rows, take, replace=False),
        rng.choice(outlier_rows, max_lines - take, replace=False),
    )
    return np.sort(np.concatenate(chosen))


_INLIER_BGR, _OUTLIER_BGR = (0, 200, 0), (0, 0, 255)
_LEGEND_BGR, _TEXT_BGR = (40, 40, 40), (255, 255, 255)


def _as_bgr(image: np.ndarray) -> np.ndarray:
    import cv2

    image = np.asarray(image)
    if image.dtype != np.uint8:
        image = np.clip(image, 0, 255).astype(np.uint8)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image[:, :, :3]


def _legend_lines(result: PairResult, drawn: np.ndarray) -> list[tuple[str, tuple | None]]:
    inliers = np.asarray(result.inliers, dtype=bool)
    drawn_in = int(np.count_nonzero(inliers[drawn]))
    threshold = result.evidence.selection.pri_threshold
    verdict = (
        f"pure rotation (PRI {result.pri:.4f} < {threshold:g}): translation undetermined"
        if result.pure_rotation
        else f"general motion (PRI {result.pri:.4f} >= {threshold:g})"
    )
    return [
        (f"inliers  {result.num_inliers}  ({drawn_in} drawn)", _INLIER_BGR),
        (
            f"outliers {result.num_matches - result.num_inliers}  ({drawn.size - drawn_in} drawn)",
            _OUTLIER_BGR,
        ),
        (f"{drawn.size} of {result.num_matches} matches drawn, inliers first", None),
        (verdict, None),
    ]


def draw_matches(
    image1: np.ndarray,
    image2: np.ndarray,
    result: PairResult,
    max_lines: int | None = MAX_DRAWN_MATCHES,
) -> np.ndarray:
    """Side-by-side BGR image of the matches with a legend band underneath.

    Inliers are green and outliers red; at most ``max_lines`` matches are drawn
    (:func:`matches_to_draw`, inliers first). The legend gives the inlier and outlier counts,
    how many of each are drawn and the pure-rotation verdict with PRI.

    Parameters
    ----------
    image1, image2 : ndarray, shape (H, W) or (H, W, 3), or path
        The two images the result was computed on, grey or BGR (a path is read); another size
        than the result's, NaN pixels or no image is a ValueError or TypeError.
    result : PairResult
        The estimate whose matches are drawn.
    max_lines : int or None
        Most match lines drawn; None draws all.

    Returns
    -------
    ndarray of uint8, shape (max(H1, H2) + legend height, W1 + W2, 3)
    """
    import cv2

    a, b = (_as_bgr(image) for image in _checked_images(result, (image1, image2)))
    width = a.shape[1] + b.shape[1]
    scale = max(0.6, width / 1280.0)  # text readable on the canvas, whatever its width
    line_height = round(24 * scale)
    drawn = matches_to_draw(result.inliers, max_lines)
    legend = _legend_lines(result, drawn)
    height = max(a.shape[0], b.shape[0])
    canvas = np.zeros((height + line_height * len(legend) + line_height // 2, width, 3), np.uint8)
    canvas[: a.shape[0], : a.shape[1]] = a
    canvas[: b.shape[0], a.shape[1] :] = b
    canvas[height:] = _LEGEND_BGR
    rows = result.matches[drawn]
    p1 = result.keypoints1[rows[:, 0]]
    p2 = result.keypoints2[rows[:, 1]] + (a.shape[1], 0)
    segments = np.rint(np.stack([p1, p2], axis=1)).astype(np.int32)
    inlier = np.asarray(result.inliers, dtype=bool)[drawn]
    thickness = max(1, round(scale))
    for colour, chosen in ((_OUTLIER_BGR, ~inlier), (_INLIER_BGR, inlier)):
        cv2.polylines(canvas, list(segments[chosen]), False, colour, thickness, cv2.LINE_AA)
    for row, (text, swatch) in enumerate(legend):
        y = height + (row + 1) * line_height
        x = round(10 * scale)
        if swatch is not None:
            cv2.line(
                canvas,
                (x, y - line_height // 3),
                (x + line_height, y - line_height // 3),
                swatch,
                max(2, thickness * 2),
            )
        cv2.putText(
            canvas,
            text,
            (x + line_height + x, y),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.55 * scale,
            _TEXT_BGR,
            thickness,
            cv2.LINE_AA,
        )
    return canvas


_BEYOND_FULL_OPENCV = {
    "thin-prism coefficients s1..s4": slice(8, 12),
    "tilt coefficients tauX, tauY": slice(12, 14),
}


def check_colmap_camera(K: np.ndarray, dist: np.ndarray | None, name: str) -> None:
    """ValueError naming what COLMAP's camera models cannot hold: a skew in ``K`` or OpenCV's
    thin-prism and tilt distortion terms (``FULL_OPENCV`` ends at k6); what is no camera
    matrix or no distortion at all is an error naming ``name`` too."""
    K = as_camera_matrix(K, name)
    as_distortion(dist, name)
    if K[0, 1] != 0:
        raise ValueError(
            f"{name} has skew {K[0, 1]}, which no COLMAP camera model holds; the COLMAP model "
            "would describe another camera"
        )
    coefficients = np.zeros(0) if dist is None else np.asarray(dist, float).ravel()
    for terms, where in _BEYOND_FULL_OPENCV.items():
        if np.any(coefficients[where]):
            raise ValueError(
                f"{name} has {terms} {coefficients[where].tolist()}, which no COLMAP camera "
                "model holds; the COLMAP model would describe another camera"
            )


def check_colmap_names(names: tuple[str, str]) -> None:
    """ValueError naming an image name that is not valid UTF-8 (a file name of other bytes, as
    Python gives it with surrogate escapes) or holds a NUL character (the end of a name in
    COLMAP's binary files), which a COLMAP model cannot hold; TypeError for anything but two
    texts."""
    if not (isinstance(names, (tuple, list)) and len(names) == 2) or not all(
        isinstance(name, str) for name in names
    ):
        raise TypeError(f"names must be two image names (texts), got {shown(names)}")
    for name in names:
        if "\0" in name:
            raise ValueError(
                f"image name {shown(name)} holds a NUL character, which no file name and no "
                "COLMAP model can hold"
            )
        try:
            name.encode("utf-8")
        except UnicodeEncodeError:
            escaped = os.fsencode(name).decode("utf-8", "backslashreplace")
            raise ValueError(
                f"image name '{escaped}' is not valid UTF-8, which a COLMAP model cannot hold"
            ) from None


def _colmap_camera(
    K: np.ndarray, dist: np.ndarray | None, size: tuple[int, int], camera_id: int, k1: float = 0.0
):
    """The COLMAP camera of intrinsics ``K``, OpenCV distortion ``dist`` and the pose's radial
    term ``k1`` (:func:`fitted_radial_k1`) composed after it (:func:`composed_distortion`):
    ``PINHOLE`` without distortion, ``OPENCV`` for up to four coefficients, else
    ``FULL_OPENCV``. Its principal point is in COLMAP's pixel coordinates
    (:data:`~ppo_cv.calib.COLMAP_PIXEL_OFFSET` added)."""
    import pycolmap

    fx, fy = K[0, 0], K[1, 1]
    cx, cy = K[0, 2] + COLMAP_PIXEL_OFFSET, K[1, 2] + COLMAP_PIXEL_OFFSET
    coefficients = np.zeros(0) if dist is None else np.asarray(dist, float).ravel()[:8]
    if k1 != 0.0:
        coefficients = _composed(K, dist, size, k1)
    if not np.any(coefficients):
        model, params = "PINHOLE", [fx, fy, cx, cy]
    elif coefficients.size <= 4:
        model, params = "OPENCV", [fx, fy, cx, cy, *np.r_[coefficients, np.zeros(4)][:4]]
    else:
        model, params = "FULL_OPENCV", [fx, fy, cx, cy, *np.r_[coefficients, np.zeros(8)][:8]]
    return pycolmap.Camera(
        model=model, width=size[0], height=size[1], params=params, camera_id=camera_id
    )


COMPOSED_GRID = 17
"""Samples per image side on which :func:`composed_distortion` fits its coefficients."""

COMPOSED_TOLERANCE_PX = 0.05
"""Largest distance (pixels, over the grid) from the composed lens at which
:func:`composed_distortion` keeps four coefficients (``OPENCV``); beyond, as for a strong
radial term in a wide field, it fits ``k3`` too (``FULL_OPENCV``)."""


def fitted_radial_k1(result: PairResult) -> float:
    """The radial (division-model) coefficient the pose of ``result`` was fitted with:
    ``lens.radial_k1`` of a general motion, ``plane.k1`` of a plane, 0 for a rotation."""
    require_result(result)
    if np.isfinite(result.lens.radial_k1):
        return float(result.lens.radial_k1)
    return 0.0 if result.plane is None else float(result.plane.k1)


def composed_distortion(
    K: np.ndarray, dist: np.ndarray | None, size: tuple[int, int], k1: float
) -> np.ndarray:
    """OpenCV coefficients of the lens ``dist`` followed by the division term ``k1``.

    The pipeline removes ``dist`` from the pixels, then divides the normalised points ``x`` by
    ``1 + k1 |x|^2`` (:func:`ppo_cv.plane.undistort_division`); the pose and the points are
    those of the result, so the camera that reprojects them onto the pixels is the inverse of
    both. Its radial coefficients, and the tangential ones when ``dist`` has any, are fitted by
    linear least squares on a ``COMPOSED_GRID`` square grid over the image, the rational terms
    of ``dist`` held.

    Parameters
    ----------
    K : ndarray, shape (3, 3)
        Intrinsics.
    dist : ndarray or None
        OpenCV coefficients removed from the pixels; None for none.
    size : tuple of int
        ``(width, height)`` of the image.
    k1 : float
        Division coefficient fitted with the pose.

    Returns
    -------
    ndarray, shape (4,) or (8,)
        ``(k1, k2, p1, p2)`` when ``dist`` has at most four coefficients and these reproduce
        the composed lens within :data:`COMPOSED_TOLERANCE_PX`, else
        ``(k1, k2, p1, p2, k3, k4, k5, k6)``.
    """
    from .camera import pixels_to_normalized

    K, size = as_camera_matrix(K, "K"), as_image_size(size, "size")
    checked = as_distortion(dist, "dist")
    if checked is None and dist is not None and np.size(dist):  # zeros: kept, as many
        checked = np.zeros(np.size(dist))
    dist = checked  # a list or an empty array failed in OpenCV (cv2.error)
    _require_division_k1(k1, pixels_to_normalized(_composed_grid(size), K, dist))
    return _composed(K, dist, size, k1)


def _composed_grid(size: tuple[int, int]) -> np.ndarray:
    """The ``COMPOSED_GRID`` square grid of pixels (M, 2) over an image of ``size``."""
    u, v = np.meshgrid(*(np.linspace(0.0, n - 1.0, COMPOSED_GRID) for n in size))
    return np.column_stack([u.ravel(), v.ravel()])


def _composed(
    K: np.ndarray, dist: np.ndarray | None, size: tuple[int, int], k1: float
) -> np.ndarray:
    """:func:`composed_distortion` of checked arguments (a fitted pose's ``k1``)."""
    from .camera import pixels_to_normalized
    from .plane import _undistort_division

    given = np.zeros(0) if dist is None else np.asarray(dist, float).ravel()
    pixels = _composed_grid(size)
    seen = (pixels - K[:2, 2]) / np.diag(K)[:2]
    c = _undistort_division(pixels_to_normalized(pixels, K, dist), k1)[:, :2]
    if given.size <= 4:
        solved, error = _composed_fit(c, seen, given, full=False)
        if np.max(np.abs(error) * np.diag(K)[:2]) <= COMPOSED_TOLERANCE_PX:
            return solved
    return _composed_fit(c, seen, given, full=True)[0]


def _require_division_k1(k1: Any, normalized: np.ndarray) -> None:
    """ValueError unless ``k1`` is a division term within OpenCV's radial range
    (``checks.MAX_RADIAL``) keeping ``1 + k1 |x|^2`` positive over the points ``normalized``
    (N, 2) of the image: NaN hung the least-squares fit in LAPACK, a lens folding the image
    gave coefficients of nothing."""
    k1 = as_number(k1, "k1")
    reach = float(np.max(np.sum(normalized[:, :2] ** 2, axis=1)))
    if not (abs(k1) <= MAX_RADIAL and 1.0 + k1 * reach > 0):
        raise ValueError(
            f"k1 must be a division term within +-{MAX_RADIAL:g} under which 1 + k1 |x|^2 "
            f"stays positive over the image (|x|^2 up to {reach:.3g}), got {shown(k1)}"
        )


def _composed_fit(
    c: np.ndarray, seen: np.ndarray, given: np.ndarray, full: bool
) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV coefficients (4, or 8 when ``full``) taking the undistorted normalised points
    ``c`` (M, 2) to the seen ones (M, 2), the rational terms of ``given`` held, and the
    misfit (M, 2) of each point in normalised units."""
    rational = np.r_[given[5:8], np.zeros(3)][:3]
    r2 = np.sum(c**2, axis=1)
    den = 1.0 + r2 * (rational[0] + r2 * (rational[1] + r2 * rational[2]))
    x, y = c.T
    zero = np.zeros_like(c)
    tangential = np.any(given[2:4])
    columns = [c * (r2**power / den)[:, None] for power in (1, 2)] + [
        np.column_stack([2 * x * y, r2 + 2 * y**2]) if tangential else zero,
        np.column_stack([r2 + 2 * x**2, 2 * x * y]) if tangential else zero,
    ]
    columns += [c * (r2**3 / den)[:, None]] if full else []
    A = np.stack([column.ravel() for column in columns], axis=1)
    target = (seen - c / den[:, None]).ravel()
    solved = np.linalg.lstsq(A, target, rcond=None)[0]
    error = (A @ solved - target).reshape(-1, 2)
    return (np.r_[solved, rational] if full else solved), error


def write_colmap_model(
    directory: str | os.PathLike,
    result: PairResult,
    names: tuple[str, str] = ("image1.png", "image2.png"),
    dists: tuple[np.ndarray | None, np.ndarray | None] | None = None,
) -> None:
    """COLMAP text model (cameras, images, points3D) of the two views and the analytic points;
    COLMAP's binary model when an image name holds whitespace, which the text format cannot keep.

    Camera 1 is the world frame; camera 2 has pose ``(R, t)`` (``t`` zero for a pure rotation);
    the unit is the baseline. Principal points and keypoints are in COLMAP's pixel coordinates,
    where the centre of the first pixel is (0.5, 0.5): those of ``result`` (OpenCV's, (0, 0))
    plus :data:`~ppo_cv.calib.COLMAP_PIXEL_OFFSET`. Each point's error is its mean
    reprojection error over the two views in pixels, through the camera models (distortion
    included), as COLMAP defines it. ``dists`` defaults to the distortion the result was
    computed with. The cameras are those the pose was fitted with: the radial term of a
    general or plane pose (:func:`fitted_radial_k1`) composed after ``dists``
    (:func:`composed_distortion`, an ``OPENCV`` or ``FULL_OPENCV`` camera), so the points
    reproject onto their pixels. A camera no COLMAP model holds (:func:`check_colmap_camera`),
    ``names`` that are not two distinct non-empty texts, ``dists`` that are not two
    distortions, or a ``directory`` that is no path or names a file is a ValueError or
    TypeError; an existing folder keeps its other files.
    """
    import pycolmap

    from .atomic import API_REPLACE_HINT, check_target

    as_path(directory, "directory")
    require_result(result)
    cameras = result.cameras
    dists = _colmap_model_inputs(result, names, dists)
    check_target(directory, "folder", overwrite=True, replace_hint=API_REPLACE_HINT)
    reconstruction = pycolmap.Reconstruction()
    same = (
        np.allclose(cameras.K1, cameras.K2)
        and cameras.image_size1 == cameras.image_size2
        and (
            (dists[0] is None and dists[1] is None)
            or (
                dists[0] is not None and dists[1] is not None and np.array_equal(dists[0], dists[1])
            )
        )
    )
    k1 = fitted_radial_k1(result)
    reconstruction.add_camera_with_trivial_rig(
        _colmap_camera(cameras.K1, dists[0], cameras.image_size1, 1, k1)
    )
    if not same:
        reconstruction.add_camera_with_trivial_rig(
            _colmap_camera(cameras.K2, dists[1], cameras.image_size2, 2, k1)
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
            keypoints=np.asarray(points, dtype=np.float64).reshape(-1, 2) + COLMAP_PIXEL_OFFSET,
            camera_id=1 if (same or image_id == 1) else 2,
            image_id=image_id,
        )
        reconstruction.add_image_with_trivial_frame(image, pose)
    # Index of each inlier among the inliers: the keypoint index within both images.
    inlier_rank = np.cumsum(result.inliers) - 1
    rows = result.point_matches
    for xyz, colour, row in zip(result.points3d[rows], result.colours[rows], rows, strict=True):
        k = int(inlier_rank[row])
        track = pycolmap.Track()
        track.add_element(1, k)
        track.add_element(2, k)
        reconstruction.add_point3D(np.asarray(xyz, float), track, np.asarray(colour, np.uint8))
    reconstruction.update_point_3d_errors()
    os.makedirs(directory, exist_ok=True)
    if all(name.split() == [name] for name in names):
        reconstruction.write_text(os.fspath(directory))
    else:  # COLMAP's text reader cuts a name at its first space; the binary format keeps it
        reconstruction.write_binary(os.fspath(directory))


def write_outputs(
    directory: str | os.PathLike,
    result: PairResult,
    image1: np.ndarray,
    image2: np.ndarray,
    names: tuple[str, str] = ("image1.png", "image2.png"),
    dists: tuple[np.ndarray | None, np.ndarray | None] | None = None,
    extra: dict | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``result.json``, ``points.ply``, ``matches.png`` and ``colmap/`` into ``directory``.

    ``image1`` and ``image2`` are the images the result was computed on (arrays or paths),
    ``names`` two distinct names for the COLMAP model. ``extra`` entries are added to
    ``result.json`` (numpy numbers and arrays of numbers as Python numbers and lists).
    Everything is written into a temporary sibling folder renamed to ``directory`` once complete
    (:func:`ppo_cv.atomic.atomic_directory`): a failure or an interrupt leaves no partial
    output. An existing non-empty ``directory`` is a ValueError unless ``overwrite``, which
    replaces it as a whole; so is a camera or an image name that the COLMAP model cannot hold
    (:func:`check_colmap_camera`, :func:`check_colmap_names`), and any argument that cannot make
    its files (an image of another size than the result's, ``extra`` holding NaN, which JSON
    cannot), before anything is written. Images given as paths are inputs: a ``directory`` that
    is one or holds one is a ValueError even with ``overwrite``
    (:func:`ppo_cv.atomic.check_apart`).
    """
    import cv2

    from .atomic import API_REPLACE_HINT, atomic_directory, check_apart

    as_path(directory, "directory")
    paths = [image for image in (image1, image2) if isinstance(image, (str, os.PathLike))]
    image1, image2, extra = _checked_output_arguments(result, (image1, image2), names, extra)
    check_apart(directory, paths, "directory ")
    dists = _colmap_model_inputs(result, names, dists)
    with atomic_directory(directory, overwrite, API_REPLACE_HINT) as staging:
        (staging / "result.json").write_text(
            json.dumps(result_to_dict(result, **(extra or {})), indent=2) + "\n", encoding="utf-8"
        )
        rows = result.point_matches
        write_ply(staging / "points.ply", result.points3d[rows], result.colours[rows])
        if not cv2.imwrite(str(staging / "matches.png"), draw_matches(image1, image2, result)):
            raise OSError("could not encode matches.png")
        write_colmap_model(staging / "colmap", result, names, dists)
    return Path(directory)


def _checked_output_arguments(
    result: Any, images: tuple[Any, Any], names: Any, extra: Any
) -> tuple[np.ndarray, np.ndarray, dict | None]:
    """The two images of :func:`write_outputs` as 8-bit arrays (a path is read) and ``extra``
    as JSON values (:func:`_json_number`); TypeError or
    ValueError naming the argument that cannot make its files: not a PairResult, an image not
    of the size the result describes, names that are not two distinct, non-empty texts (COLMAP
    names each image once), ``extra`` that JSON cannot hold (NaN and infinity are no JSON) or
    whose keys would replace the result's own fields."""
    arrays = _checked_images(result, images)
    _check_names(names)
    if extra is not None and not isinstance(extra, dict):
        raise TypeError(f"extra must be a dict of JSON values, got {type(extra).__name__}")
    key = next((key for key in extra or {} if not isinstance(key, str)), None)
    if key is not None:
        raise TypeError(f"extra's keys must be texts, got {type(key).__name__} {shown(key)}")
    try:
        extra = json.loads(json.dumps(extra, allow_nan=False, default=_json_number))
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"extra cannot be written as JSON: {exc}") from None
    except RecursionError:
        raise ValueError("extra cannot be written as JSON: it is nested too deeply") from None
    result_to_dict(result, **(extra or {}))
    return (*arrays, extra)


def _json_number(value: Any) -> Any:
    """A numpy number (``np.int64(3)``, ``np.float32(1.5)``, ``np.bool_``) or array of numbers
    as the Python number or list JSON writes; TypeError for anything else, as ``json`` says."""
    if isinstance(value, (np.generic, np.ndarray)) and value.dtype.kind in "biuf":
        # a long double's tolist() is itself, which json would hand back here without end
        return (value.astype(np.float64) if value.dtype.kind == "f" else value).tolist()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def _checked_images(result: Any, images: tuple[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The two images a result was computed on as 8-bit arrays (a path is read); TypeError or
    ValueError for no PairResult, no image, NaN pixels or another size than the result's."""
    from .images import as_image

    require_result(result)
    sizes = (result.cameras.image_size1, result.cameras.image_size2)
    arrays = tuple(as_image(image, f"image{i}") for i, image in enumerate(images, 1))
    for number, (image, size) in enumerate(zip(arrays, sizes, strict=True), 1):
        shape = image.shape
        if size is not None and (shape[1], shape[0]) != tuple(size):
            raise ValueError(
                f"image{number} is {shape[1]}x{shape[0]} pixels, but the result's image {number} "
                f"is {size[0]}x{size[1]}"
            )
    return arrays


def _colmap_model_inputs(result: PairResult, names: Any, dists: Any) -> tuple:
    """The two cameras' distortions of ``result``'s COLMAP model (``dists``, by default those
    the result was computed with), checked with the image ``names`` and the cameras: a
    ValueError or TypeError for what the model cannot hold."""
    cameras = result.cameras
    dists = _checked_dists((cameras.dist1, cameras.dist2) if dists is None else dists)
    _check_names(names)
    check_colmap_camera(cameras.K1, dists[0], "camera 1")
    check_colmap_camera(cameras.K2, dists[1], "camera 2")
    check_colmap_names(names)
    return dists


def _check_names(names: Any) -> None:
    """TypeError or ValueError unless ``names`` are two distinct non-empty texts (a COLMAP
    model names each image once)."""
    if not (isinstance(names, (tuple, list)) and len(names) == 2):
        raise TypeError(f"names must be two image names, got {shown(names, 60)}")
    if not all(isinstance(name, str) and name.strip() for name in names):
        raise TypeError(f"names must be two non-empty texts, got {shown(names, 60)}")
    if names[0] == names[1]:
        raise ValueError(
            f"names must differ: a COLMAP model names each image once, got {shown(names, 60)}"
        )


def _checked_dists(dists: Any) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The two distortions of :func:`write_outputs` checked as OpenCV coefficients."""
    from .checks import as_distortion

    if not (isinstance(dists, (tuple, list)) and len(dists) == 2):
        raise TypeError(f"dists must be two distortions (None for none), got {shown(dists, 60)}")
    return as_distortion(dists[0], "dists[0]"), as_distortion(dists[1], "dists[1]")
