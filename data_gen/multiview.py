"""Multi-view sequences of one rendered scene with exact poses, for structure-from-motion."""

from __future__ import annotations

import math
import os
from typing import Any

import cv2
import numpy as np

from ppo_cv.checks import (
    MAX_WHOLE_NUMBER,
    as_number,
    as_path,
    as_rotation,
    as_vector3,
    as_whole_number,
    shown,
)

from .render import _check_size, render_view
from .scenes import make_scene

__all__ = ["relative_gt_from_poses", "render_tripod_then_move", "tripod_then_move_poses"]


def _yaw(degrees: float) -> np.ndarray:
    a = np.deg2rad(degrees)
    return np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])


def tripod_then_move_poses(
    n_pan: int = 4, n_move: int = 4, pan_step: float = 8.0, step: float = 0.45
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``cam_from_world`` poses ``(R, t)``: a pan about the origin, then a sideways walk.

    The pan turns by ``pan_step`` degrees between views around the centre ``(0, 0, 0)``; the walk
    moves the centre by ``step`` metres along x (and a little backwards), turning to keep the
    room's middle in view. World coordinates are those of the first pan view's tripod at yaw 0.
    """
    n_pan = as_whole_number(n_pan, "n_pan", 0, 1000)
    n_move = as_whole_number(n_move, "n_move", 0, 1000)
    for name, value in (("pan_step", pan_step), ("step", step)):
        if not math.isfinite(as_number(value, name)):
            raise ValueError(f"{name} must be finite, got {value}")
    poses = []
    for k in range(n_pan):
        yaw = (k - (n_pan - 1) / 2) * pan_step
        poses.append((_yaw(yaw), np.zeros(3)))
    for k in range(1, n_move + 1):
        centre = np.array([step * k, 0.05 * k, -0.1 * k])
        R = _yaw(-4.0 * k)
        poses.append((R, -R @ centre))
    return poses


def render_tripod_then_move(
    out_dir: str | os.PathLike,
    n_pan: int = 4,
    n_move: int = 4,
    size: tuple[int, int] = (480, 360),
    seed: int = 0,
    step: float = 0.45,
) -> tuple[list[str], np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Render the tripod-then-move views of the ``clutter`` scene into ``out_dir``.

    ``step`` is the walk's stride in metres (the room's walls are 5-8 m away).

    Returns
    -------
    names : list of str
        File names, ``pan_*`` then ``move_*`` (alphabetical order is capture order).
    K : ndarray, shape (3, 3)
    poses : list of (R, t)
        ``cam_from_world`` of each view.
    """
    out_dir = as_path(out_dir, "out_dir")
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise FileExistsError(
            f"out_dir {out_dir} is a file or a folder holding files; give a new or empty folder "
            "(the views would mix with what is there)"
        )
    width, height = _check_size(size)
    poses = tripod_then_move_poses(n_pan, n_move, step=step)
    seed = as_whole_number(seed, "seed", 0, MAX_WHOLE_NUMBER)
    out_dir.mkdir(parents=True, exist_ok=True)
    focal = 0.85 * width
    K = np.array([[focal, 0.0, (width - 1) / 2], [0.0, focal, (height - 1) / 2], [0.0, 0.0, 1.0]])
    scene = make_scene("clutter", seed)
    rng = np.random.default_rng(seed)
    names = []
    for index, (R, t) in enumerate(poses):
        kind = "pan" if index < n_pan else "move"
        name = f"{index:02d}_{kind}.png"
        image, _ = render_view(scene, K, R, t, size=size, supersample=2)
        pixels = image * 255.0 + rng.normal(0.0, 1.0, image.shape)
        cv2.imwrite(
            str(out_dir / name), np.clip(np.rint(pixels), 0, 255).astype(np.uint8)[..., ::-1]
        )
        names.append(name)
    return names, K, poses


def _checked_pose(pose: Any, name: str) -> tuple[np.ndarray, np.ndarray]:
    if not (isinstance(pose, (tuple, list)) and len(pose) == 2):
        raise TypeError(f"{name} must be a pair (R, t), got {type(pose).__name__}")
    t = as_vector3(pose[1], f"{name} t")
    return as_rotation(pose[0], f"{name} R"), t


def relative_gt_from_poses(
    names: list[str], poses: list[tuple[np.ndarray, np.ndarray]]
) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """Ground-truth ``cam2_from_cam1`` of every pair of views from their ``cam_from_world``.

    ``poses`` holds one ``(R (3, 3), t (3,))`` per name; a ValueError or TypeError names a
    count that differs, a pose that is no pair, a rotation or translation that is not one,
    names that are not distinct texts.
    """
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise TypeError(f"names must be a list of texts, got {shown(names)}")
    if len(set(names)) != len(names):
        raise ValueError(f"names must differ, one per view, got {shown(names)}")
    if not isinstance(poses, (list, tuple)):
        raise TypeError(f"poses must be a list of (R, t), got {type(poses).__name__}")
    if len(names) != len(poses):
        raise ValueError(f"names and poses must have one entry per view, got {len(names)} "
                         f"names and {len(poses)} poses")  # fmt: skip
    poses = [_checked_pose(pose, f"poses[{i}]") for i, pose in enumerate(poses)]
    gt = {}
    for i, (R1, t1) in enumerate(poses):
        for j in range(i + 1, len(poses)):
            R2, t2 = poses[j]
            gt[(names[i], names[j])] = (R2 @ R1.T, t2 - R2 @ R1.T @ t1)
    return gt
