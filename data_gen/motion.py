"""Camera-motion presets: intrinsics of both views and the relative pose ``x2 = R x1 + t``.

Camera 1 is ``(I | 0)``; camera 2 has centre ``C2`` (camera-1 coordinates) and rotation ``R``,
so ``t = -R C2``. Presets:

``general``
    ``C2`` in a random, mostly lateral direction, ``||C2|| ~ U(0.08, 0.15) * depth``; camera 2
    looks at the scene's target (jittered) with a small roll (sigma 3 degrees).
``pure-rotation``
    ``t = 0`` exactly; Euler angles about X, Y, Z ~ N(0, diag(4^2, 6^2, 8^2)) degrees,
    truncated at two sigma.
``small-parallax``
    The paper's protocol scaled to the scene: ``C2 = alpha * t_max (cos phi, sin phi, 0)`` with
    ``t_max = 0.14 * depth`` (the paper's 4.2 m at 30 m), ``phi ~ U(0, 2 pi)``, Euler angles
    ~ N(0, diag(5^2, 5^2, 20^2)) degrees truncated at two sigma; ``alpha`` is given or drawn
    log-uniformly in [1e-3, 1].
``forward``
    ``t = (0, 0, -b)`` exactly along the optical axis (camera 2 is ``b`` metres ahead along its
    own axis), ``b ~ U(0.1, 0.2) * depth``, small rotation (sigma 1.5, 1.5, 3 degrees).
``planar``
    The ``general`` motion, meant for the single-plane scene.
``panorama``
    A tripod pan: ``t = 0`` exactly; yaw (about the camera's Y axis)
    ``~ U(0.35, 0.7) * hfov`` with a random sign, pitch and roll ``~ N(0, 1.5^2)`` degrees,
    ``R = Rz(roll) Ry(yaw) Rx(pitch)``. Meant for the ``room`` scene, which surrounds the
    camera so that textured walls fill both views. With ``pivot_offset = d`` the camera turns
    about a point ``d`` metres behind its centre on the optical axis, as on a tripod whose
    screw is not under the lens's entrance pupil: ``P = (0, 0, -d)`` in camera-1 coordinates,
    ``x2 = R (x1 - P) + P``, so ``t = P - R P`` (``|t| = 2 d sin(angle / 2)``, a few
    centimetres for a 20 degree turn on a consumer tripod).
``tiny-baseline``
    The ``pure-rotation`` rotation plus a camera-centre displacement in a random, mostly
    lateral direction with ``||C2|| = baseline_ratio * median depth``, where the median depth
    is that of the surfaces camera 1 actually sees (ray-cast at the pixel centres) and
    ``baseline_ratio`` is given or drawn log-uniformly in [0.001, 0.05]. The scene, cameras
    and rotation are those of ``pure-rotation`` for the same random stream, and a given ratio
    changes nothing else: a sweep of ``baseline_ratio`` at one seed starts from the
    ``pure-rotation`` pair (ratio 0 renders it exactly).
``tripod``
    The ``panorama`` pan about a pivot on the optical axis behind the lens (a tripod whose
    screw is not under the lens's entrance pupil), the pivot's distance set so that the
    baseline is ``baseline_ratio`` times the median depth that camera 1 sees:
    ``|t| = |(I - R) P| = baseline_ratio * median depth``. ``baseline_ratio`` is given (in
    [0, 0.5]) or drawn log-uniformly in [0.002, 0.01], where a sideways translation and a pan
    are nearly the same flow in a narrow field; ratio 0 renders the exact rotation, and a given
    ratio changes nothing else.

Here ``depth`` is the scene's typical depth (:attr:`Scene.depth`), ``hfov`` the horizontal
field of view of camera 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ppo_cv.checks import (
    MAX_COORDINATE,
    as_finite_rows,
    as_flag,
    as_image_size,
    as_number,
    shown,
)

from .names import MAX_BASELINE_RATIO, MAX_PIVOT_OFFSET, MOTIONS
from .protocol import euler_to_matrix
from .scenes import Scene

__all__ = [
    "MOTIONS",
    "DEFAULT_SCENE",
    "MAX_PIVOT_OFFSET",
    "Motion",
    "check_pivot_offset",
    "intrinsics",
    "look_at",
    "sample_motion",
]


DEFAULT_SCENE = {
    "general": "clutter",
    "pure-rotation": "clutter",
    "small-parallax": "clutter",
    "forward": "clutter",
    "planar": "plane",
    "panorama": "room",
    "tiny-baseline": "clutter",
    "tripod": "room",
}
"""Scene used with each motion preset unless another one is asked for."""

PARALLAX_T_MAX_RATIO = 4.2 / 30.0
DEFAULT_HFOV_RANGE = (55.0, 70.0)
PANORAMA_YAW_FRACTION = (0.35, 0.7)
PANORAMA_TILT_SIGMA_DEG = 1.5
TINY_BASELINE_RANGE = (1e-3, 0.05)
TRIPOD_BASELINE_RANGE = (2e-3, 1e-2)


@dataclass(frozen=True)
class Motion:
    """Intrinsics and relative pose of a two-view set-up.

    Attributes
    ----------
    K1, K2 : ndarray, shape (3, 3)
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        ``x2 = R x1 + t``.
    params : dict
        Preset name and the values drawn (JSON-serialisable).
    """

    K1: np.ndarray
    K2: np.ndarray
    R: np.ndarray
    t: np.ndarray
    params: dict = field(default_factory=dict)


def intrinsics(size: tuple[int, int], hfov_deg: float, principal_offset=(0.0, 0.0)) -> np.ndarray:
    """Pinhole ``K`` with square pixels for a horizontal field of view.

    ``f = W / (2 tan(hfov / 2))``, principal point ``((W - 1) / 2, (H - 1) / 2) + offset``.
    """
    width, height = as_image_size(size, "size")
    if not 1.0 < as_number(hfov_deg, "hfov_deg") < 179.0:
        raise ValueError(f"hfov_deg must be in (1, 179), got {hfov_deg}")
    offset = _offset(principal_offset)
    f = width / (2.0 * np.tan(np.deg2rad(hfov_deg) / 2.0))
    cx = (width - 1) / 2.0 + offset[0]
    cy = (height - 1) / 2.0 + offset[1]
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def _offset(value) -> np.ndarray:
    """A principal-point offset ``(dx, dy)``: two finite numbers within ``MAX_COORDINATE``."""
    if np.size(value) != 2:
        raise ValueError(f"principal_offset must be two numbers (dx, dy), got {shown(value)}")
    offset = as_finite_rows(np.reshape(value, (1, 2)), "principal_offset", 2)[0]
    if np.abs(offset).max() > MAX_COORDINATE:
        raise ValueError(
            f"principal_offset must be within {MAX_COORDINATE:.0e} px, got {shown(value)}"
        )
    return offset


def _point(value, name: str) -> np.ndarray:
    """A 3D point of three finite numbers; ValueError or TypeError naming ``name``."""
    rows = as_finite_rows(np.atleast_2d(value), name, 3)
    if rows.shape[0] != 1:
        raise ValueError(f"{name} must be one point (x, y, z), got shape {np.shape(value)}")
    return rows[0]


def look_at(centre: np.ndarray, target: np.ndarray, roll_deg: float = 0.0) -> np.ndarray:
    """World-to-camera rotation of a camera at ``centre`` looking at ``target``.

    The camera's Y axis points as close to world +Y (down) as possible; ``roll_deg`` then
    rotates about the viewing axis. Returns shape (3, 3).
    """
    forward = _point(target, "target") - _point(centre, "centre")
    roll_deg = as_number(roll_deg, "roll_deg")
    norm = np.linalg.norm(forward)
    if not np.isfinite(roll_deg):
        raise ValueError(f"roll_deg must be finite, got {roll_deg}")
    if norm == 0:
        raise ValueError("target must differ from centre")
    forward /= norm
    right = np.cross([0.0, 1.0, 0.0], forward)
    if np.linalg.norm(right) < 1e-12:
        raise ValueError("cannot look straight along world Y (up or down): no roll is defined")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return euler_to_matrix([0.0, 0.0, roll_deg]) @ np.stack([right, down, forward])


def _truncated_normal(rng: np.random.Generator, sigma) -> np.ndarray:
    sigma = np.asarray(sigma, float)
    return np.clip(rng.standard_normal(sigma.shape), -2.0, 2.0) * sigma


def _camera_intrinsics(rng: np.random.Generator, size, same: bool, hfov_range) -> tuple:
    def draw():
        hfov = rng.uniform(*hfov_range)
        offset = rng.uniform(-0.02, 0.02, 2) * np.asarray(size)
        return intrinsics(size, hfov, offset), hfov

    K1, hfov1 = draw()
    K2, hfov2 = (K1, hfov1) if same else draw()
    return K1, K2.copy(), {"hfov1_deg": hfov1, "hfov2_deg": hfov2}


def sample_motion(
    name: str,
    scene: Scene,
    rng: np.random.Generator,
    size: tuple[int, int] = (640, 480),
    alpha: float | None = None,
    same_intrinsics: bool = True,
    hfov_range: tuple[float, float] | None = None,
    baseline_ratio: float | None = None,
    dist: np.ndarray | None = None,
    pivot_offset: float = 0.0,
) -> Motion:
    """Draw the cameras of preset ``name`` for ``scene`` (see the module docstring).

    Parameters
    ----------
    name : {"general", "pure-rotation", "small-parallax", "forward", "planar", "panorama", \
"tiny-baseline", "tripod"}
    scene : Scene
        Supplies the look-at target and the typical depth.
    rng : numpy.random.Generator
    size : (int, int)
        Image width and height (for the intrinsics).
    alpha : float, optional
        Parallax factor of ``small-parallax`` in (0, 1]; drawn if None.
    same_intrinsics : bool, default True
        ``K2 = K1`` if True, else both are drawn independently.
    hfov_range : (float, float), optional
        Range of the horizontal field of view in degrees (default 55-70).
    baseline_ratio : float, optional
        ``baseline / median depth`` of ``tiny-baseline`` and ``tripod`` in [0, 0.5]; drawn
        if None.
    dist : array_like, optional
        Lens distortion of camera 1, used to find the surfaces it sees (``tiny-baseline``,
        ``tripod``).
    pivot_offset : float, default 0
        Distance (metres, in [0, 1]) of the centre of a ``panorama`` turn behind the camera.

    Returns
    -------
    Motion
    """
    if name not in MOTIONS:
        raise ValueError(f"unknown motion {name!r}; choose one of {', '.join(MOTIONS)}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    same_intrinsics = as_flag(same_intrinsics, "same_intrinsics")
    alpha = None if alpha is None else as_number(alpha, "alpha")
    if alpha is not None and (not np.isfinite(alpha) or not 0.0 < alpha <= 1.0):
        raise ValueError(f"alpha must be in (0, 1], got {alpha}")
    ratio = None if baseline_ratio is None else as_number(baseline_ratio, "baseline_ratio")
    if ratio is not None and not (np.isfinite(ratio) and 0.0 <= ratio <= MAX_BASELINE_RATIO):
        raise ValueError(f"baseline_ratio must be in [0, {MAX_BASELINE_RATIO}], got {ratio}")
    check_pivot_offset(name, pivot_offset)
    hfov_range = DEFAULT_HFOV_RANGE if hfov_range is None else hfov_range
    K1, K2, params = _camera_intrinsics(rng, size, same_intrinsics, hfov_range)
    params["motion"] = name
    depth = float(scene.depth)
    if name in ("general", "planar"):
        direction = rng.standard_normal(3) * np.array([1.0, 0.4, 0.4])
        baseline = rng.uniform(0.08, 0.15) * depth
        centre = baseline * direction / np.linalg.norm(direction)
        target = scene.target + rng.standard_normal(3) * 0.05 * depth
        roll = float(_truncated_normal(rng, 3.0))
        R = look_at(centre, target, roll)
        t = -R @ centre
        params.update(baseline=baseline, roll_deg=roll, target=target.tolist())
    elif name == "pure-rotation":
        euler = _truncated_normal(rng, [4.0, 6.0, 8.0])
        R, t = euler_to_matrix(euler), np.zeros(3)
        params.update(euler_deg=euler.tolist())
    elif name == "small-parallax":
        if alpha is None:
            alpha = float(10.0 ** rng.uniform(-3.0, 0.0))
        t_max = PARALLAX_T_MAX_RATIO * depth
        phi = rng.uniform(0.0, 2.0 * np.pi)
        euler = _truncated_normal(rng, [5.0, 5.0, 20.0])
        R = euler_to_matrix(euler)
        centre = alpha * t_max * np.array([np.cos(phi), np.sin(phi), 0.0])
        t = -R @ centre
        params.update(alpha=alpha, t_max=t_max, phi=phi, euler_deg=euler.tolist())
    elif name == "panorama":
        R, t = _panorama(rng, params["hfov1_deg"], params, float(pivot_offset))
    elif name == "tiny-baseline":
        R, t = _tiny_baseline(rng, scene, K1, size, dist, baseline_ratio, params)
    elif name == "tripod":
        R, t = _tripod(rng, scene, K1, size, dist, baseline_ratio, params)
    else:
        baseline = rng.uniform(0.1, 0.2) * depth
        euler = _truncated_normal(rng, [1.5, 1.5, 3.0])
        R, t = euler_to_matrix(euler), np.array([0.0, 0.0, -baseline])
        params.update(baseline=baseline, euler_deg=euler.tolist())
    return Motion(K1=K1, K2=K2, R=R, t=np.asarray(t, float), params=params)


def check_pivot_offset(motion: str, pivot_offset) -> None:
    """ValueError unless ``pivot_offset`` is a distance in [0, MAX_PIVOT_OFFSET] of ``panorama``."""
    if isinstance(pivot_offset, bool) or not isinstance(pivot_offset, (int, float, np.number)):
        raise TypeError(f"pivot_offset must be a number, got {type(pivot_offset).__name__}")
    if not (np.isfinite(pivot_offset) and 0.0 <= pivot_offset <= MAX_PIVOT_OFFSET):
        raise ValueError(f"pivot_offset must be in [0, {MAX_PIVOT_OFFSET}] m, got {pivot_offset}")
    if pivot_offset and motion != "panorama":
        raise ValueError(f"pivot_offset applies to panorama only, not {motion!r}")


def _panorama(rng: np.random.Generator, hfov_deg: float, params: dict, pivot: float = 0.0) -> tuple:
    """Tripod pan: yaw a fraction of the field of view, small pitch and roll, about a pivot."""
    yaw = rng.uniform(*PANORAMA_YAW_FRACTION) * hfov_deg * (1.0 if rng.random() < 0.5 else -1.0)
    pitch, roll = rng.normal(0.0, PANORAMA_TILT_SIGMA_DEG, 2)
    euler = np.array([pitch, yaw, roll])
    R = euler_to_matrix(euler)
    P = np.array([0.0, 0.0, -pivot])
    params.update(yaw_deg=float(yaw), pitch_deg=float(pitch), roll_deg=float(roll),
                  euler_deg=euler.tolist())  # fmt: skip
    if pivot:
        params["pivot_offset"] = pivot
    return R, P - R @ P


def _tiny_baseline(rng, scene, K1, size, dist, baseline_ratio, params) -> tuple:
    """``pure-rotation`` rotation, centre ``baseline_ratio * median depth`` away."""
    from .render import median_depth

    euler = _truncated_normal(rng, [4.0, 6.0, 8.0])
    direction = rng.standard_normal(3) * np.array([1.0, 0.4, 0.4])
    direction /= np.linalg.norm(direction)
    low, high = np.log10(TINY_BASELINE_RANGE)
    drawn = float(10.0 ** rng.uniform(low, high))
    ratio = drawn if baseline_ratio is None else float(baseline_ratio)
    depth = median_depth(scene, K1, size, dist)
    R = euler_to_matrix(euler)
    centre = ratio * depth * direction
    params.update(baseline_ratio=ratio, median_depth=depth, baseline=ratio * depth,
                  centre=centre.tolist(), euler_deg=euler.tolist())  # fmt: skip
    return R, -R @ centre


def _tripod(rng, scene, K1, size, dist, baseline_ratio, params) -> tuple:
    """``panorama`` pan about the pivot behind the lens that makes ``|t|`` the drawn or given
    ``baseline_ratio`` of the median depth."""
    from .render import median_depth

    R, _ = _panorama(rng, params["hfov1_deg"], params)
    low, high = np.log10(TRIPOD_BASELINE_RANGE)
    drawn = float(10.0 ** rng.uniform(low, high))
    ratio = drawn if baseline_ratio is None else float(baseline_ratio)
    depth = median_depth(scene, K1, size, dist)
    behind = np.array([0.0, 0.0, -1.0])
    pivot = ratio * depth / float(np.linalg.norm(behind - R @ behind))
    t = pivot * (behind - R @ behind)
    params.update(baseline_ratio=ratio, median_depth=depth, baseline=ratio * depth,
                  pivot_offset=pivot)  # fmt: skip
    return R, t
