"""Scenes of textured planar quads, in camera-1 coordinates (X right, Y down, Z forward).

A quad is the parallelogram ``P(s, q) = origin + s * u + q * v`` for ``s, q in [0, 1]``. A
quad "at infinity" is the set of directions ``origin + s * u + q * v``: it is seen through the
rotation only (its image moves by the infinite homography ``K2 R K1^-1``), has infinite depth,
and is the exact model of a far-away backdrop.

Texture coordinates of a hit are ``(x, y) = (uv[0] + s * (uv[2] - uv[0])) * w - 0.5`` and
likewise for ``y`` with ``h`` (pixel-centre convention, ``uv`` a rectangle in the unit texture
square; values beyond 1 repeat the texture).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar
from dataclasses import dataclass, field

import numpy as np

from ppo_cv.checks import (
    MAX_WHOLE_NUMBER,
    as_number,
    as_positive,
    as_vector3,
    as_whole_number,
    shown,
)

from .names import SCENES
from .textures import Texture, checker_texture, texture_pool, texture_set_photos

__all__ = [
    "SCENES",
    "Quad",
    "Scene",
    "box_quads",
    "checker_plane",
    "make_scene",
    "texture_set",
]


TEXELS_PER_METRE = 256.0

_TEXTURE_SET: ContextVar[int | None] = ContextVar("texture_set", default=None)


@contextlib.contextmanager
def _textures_from(index: int | None) -> Iterator[None]:
    texture_set_photos(index)
    token = _TEXTURE_SET.set(index)
    try:
        yield
    finally:
        _TEXTURE_SET.reset(token)


def texture_set(index: int | None) -> contextlib.AbstractContextManager[None]:
    """Texture the scenes built inside the ``with`` block from texture set ``index`` only.

    Scenes built under different sets (:data:`~.textures.TEXTURE_SETS`) share no image
    content, so two renders of them are unrelated images; ``None`` restores the shared pool.
    This also applies to :func:`~.io.make_pair`, which builds its scene with :func:`make_scene`.
    """
    texture_set_photos(index)
    return _textures_from(index)


@dataclass(frozen=True, eq=False)
class Quad:
    """Textured parallelogram ``origin + s u + q v``, ``s, q in [0, 1]`` (see module docstring).

    Attributes
    ----------
    origin, u, v : ndarray, shape (3,)
        Corner and edge vectors in camera-1 coordinates (metres), or directions if
        ``at_infinity``.
    texture : Texture
    uv : tuple of 4 floats
        Texture rectangle ``(s0, q0, s1, q1)`` in unit texture coordinates.
    at_infinity : bool
        Plane at infinity (see module docstring).
    """

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    texture: Texture
    uv: tuple = (0.0, 0.0, 1.0, 1.0)
    at_infinity: bool = False

    def corners(self) -> np.ndarray:
        """The four corners (or corner directions), shape (4, 3)."""
        o, u, v = self.origin, self.u, self.v
        return np.stack([o, o + u, o + u + v, o + v])


@dataclass(frozen=True, eq=False)
class Scene:
    """A list of quads and the hints a motion preset needs.

    Attributes
    ----------
    name : str
    quads : tuple of Quad
    target : ndarray, shape (3,)
        A point near the middle of the visible structure (for look-at cameras).
    depth : float
        Typical distance of the structure from camera 1 (metres).
    params : dict
        Parameters the scene was generated with.
    """

    name: str
    quads: tuple
    target: np.ndarray
    depth: float
    params: dict = field(default_factory=dict)


def _vec(*values: float) -> np.ndarray:
    return np.array(values, dtype=np.float64)


def _textured_quad(
    rng: np.random.Generator, origin, u, v, density: float = TEXELS_PER_METRE
) -> Quad:
    """Quad with a random window of a random pool texture, ``density`` texels per metre."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    pool = texture_pool(texture_set=_TEXTURE_SET.get())
    texture = pool[rng.integers(len(pool))]
    tw, th = texture.size
    s0, q0 = rng.random(2)
    uv = (s0, q0, s0 + np.linalg.norm(u) * density / tw, q0 + np.linalg.norm(v) * density / th)
    return Quad(np.asarray(origin, float), u, v, texture, tuple(float(c) for c in uv))


def box_quads(
    rng: np.random.Generator, centre: np.ndarray, size: np.ndarray, yaw_deg: float
) -> list[Quad]:
    """Six textured faces of a box.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the face textures.
    centre : array_like, shape (3,)
        Box centre (metres, camera-1 coordinates).
    size : array_like, shape (3,)
        Extents along the box axes (X, Y, Z before the yaw).
    yaw_deg : float
        Rotation of the box about the vertical (Y) axis, degrees.
    """
    centre, size = as_vector3(centre, "centre"), as_vector3(size, "size")
    if not (np.isfinite(as_number(yaw_deg, "yaw_deg")) and (size > 0).all()):
        raise ValueError(f"need a finite yaw_deg and a size > 0, got {yaw_deg} and {size.tolist()}")
    c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
    axes = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]) * size[:, None]
    ex, ey, ez = axes
    lo = centre - 0.5 * (ex + ey + ez)
    hi = lo + ex + ey + ez
    faces = [
        (lo, ex, ey), (lo, ez, ey), (lo, ex, ez),
        (hi, -ex, -ey), (hi, -ez, -ey), (hi, -ex, -ez),
    ]  # fmt: skip
    return [_textured_quad(rng, *f) for f in faces]


def _room(rng: np.random.Generator) -> tuple[list[Quad], dict]:
    width = rng.uniform(6.0, 9.0)
    floor, ceiling = rng.uniform(1.2, 1.7), rng.uniform(1.0, 1.5)
    back, front = rng.uniform(5.5, 8.0), -2.5
    x0, x1, depth = -width / 2, width / 2, back - front
    height = floor + ceiling
    quads = [
        _textured_quad(rng, _vec(x0, -ceiling, back), _vec(width, 0, 0), _vec(0, height, 0)),
        _textured_quad(rng, _vec(x0, -ceiling, front), _vec(0, 0, depth), _vec(0, height, 0)),
        _textured_quad(rng, _vec(x1, -ceiling, front), _vec(0, 0, depth), _vec(0, height, 0)),
        _textured_quad(rng, _vec(x0, floor, front), _vec(width, 0, 0), _vec(0, 0, depth)),
        _textured_quad(rng, _vec(x0, -ceiling, front), _vec(width, 0, 0), _vec(0, 0, depth)),
        _textured_quad(rng, _vec(x0, -ceiling, front), _vec(width, 0, 0), _vec(0, height, 0)),
    ]
    params = {"width": width, "floor": floor, "ceiling": ceiling, "back": back, "front": front}
    return quads, params


def _clutter(rng: np.random.Generator, room: dict, n_boxes: int) -> list[Quad]:
    quads: list[Quad] = []
    for _ in range(n_boxes):
        size = rng.uniform([0.5, 0.4, 0.4], [1.4, 1.3, 1.0])
        z = rng.uniform(2.8, room["back"] - 0.6)
        x = rng.uniform(-room["width"] / 2 + 0.8, room["width"] / 2 - 0.8)
        on_floor = rng.random() < 0.7
        y = room["floor"] - size[1] / 2 if on_floor else rng.uniform(-0.6, 0.6)
        quads += box_quads(rng, _vec(x, y, z), size, rng.uniform(-40, 40))
    return quads


def _plane(rng: np.random.Generator) -> tuple[list[Quad], np.ndarray, float, dict]:
    distance = rng.uniform(3.0, 5.0)
    tilt_x, tilt_y = rng.uniform(-35, 35), rng.uniform(-35, 35)
    cx, sx = np.cos(np.deg2rad(tilt_x)), np.sin(np.deg2rad(tilt_x))
    cy, sy = np.cos(np.deg2rad(tilt_y)), np.sin(np.deg2rad(tilt_y))
    rot = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array(
        [[1, 0, 0], [0, cx, -sx], [0, sx, cx]]
    )
    side = 4.0 * distance
    centre = _vec(0, 0, distance)
    u, v = rot @ _vec(side, 0, 0), rot @ _vec(0, side, 0)
    quads = [_textured_quad(rng, centre - (u + v) / 2, u, v, density=2048 / side)]
    return quads, centre, distance, {"distance": distance, "tilt_deg": [tilt_x, tilt_y]}


def _backdrop(rng: np.random.Generator) -> tuple[list[Quad], np.ndarray, float, dict]:
    extent = 2.2
    flat = _textured_quad(rng, _vec(-extent, -extent, 1.0), _vec(2 * extent, 0, 0),
                          _vec(0, 2 * extent, 0), density=2048 / (2 * extent))  # fmt: skip
    sky = Quad(flat.origin, flat.u, flat.v, flat.texture, flat.uv, at_infinity=True)
    quads = [sky]
    n_boxes = int(rng.integers(2, 5))
    for _ in range(n_boxes):
        z = rng.uniform(3.0, 7.0)
        size = rng.uniform(0.4, 1.2, 3)
        xy = rng.uniform(-0.35, 0.35, 2) * z
        quads += box_quads(rng, _vec(xy[0], xy[1], z), size, rng.uniform(-40, 40))
    return quads, _vec(0, 0, 5.0), 5.0, {"n_boxes": n_boxes, "extent": extent}


def checker_plane(
    distance: float = 3.0, squares: tuple[int, int] = (10, 8), square_m: float = 0.25
) -> Scene:
    """Fronto-parallel checkerboard at ``Z = distance`` centred on the optical axis (tests).

    Its inner corners are the 3D points ``origin + i * u / nx + j * v / ny``.
    """
    distance, square_m = as_positive(distance, "distance"), as_positive(square_m, "square_m")
    nx, ny = (as_whole_number(n, "squares", 1, 1000) for n in _two(squares, "squares"))
    u, v = _vec(nx * square_m, 0, 0), _vec(0, ny * square_m, 0)
    origin = _vec(0, 0, distance) - (u + v) / 2
    tex = Texture.from_image(checker_texture(squares, texels_per_square=16))
    quad = Quad(origin, u, v, tex)
    return Scene("checker", (quad,), origin + (u + v) / 2, distance, {"squares": list(squares)})


def _two(value, name: str) -> tuple:
    """``value`` unpacked as a pair; TypeError naming ``name`` otherwise."""
    try:
        first, second = value
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a pair (x, y), got {shown(value)}") from None
    return first, second


def make_scene(
    name: str, seed: int | np.random.Generator = 0, texture_set: int | None = None
) -> Scene:
    """Build a named random scene.

    Parameters
    ----------
    name : {"room", "clutter", "plane", "backdrop"}
        ``room``: the inside of a textured box (walls, floor, ceiling) seen from near its front;
        ``clutter``: the room with 2-4 textured boxes in front of the walls; ``plane``: one
        large textured plane, tilted up to 35 degrees, 3-5 m away; ``backdrop``: a textured
        plane at infinity with a few boxes 3-7 m in front of it.
    seed : int or numpy.random.Generator
        Seed (or generator) of the layout and textures.
    texture_set : int, optional
        Draw the textures from this disjoint texture set only (:func:`texture_set`); by
        default from the set of the enclosing ``with texture_set(...)`` block, else the shared
        pool.

    Returns
    -------
    Scene
    """
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; choose one of {', '.join(SCENES)}")
    if texture_set is not None:
        with _textures_from(texture_set):
            return make_scene(name, seed)
    if not isinstance(seed, np.random.Generator):
        seed = np.random.default_rng(as_whole_number(seed, "seed", 0, MAX_WHOLE_NUMBER))
    rng = seed
    if name in ("room", "clutter"):
        quads, params = _room(rng)
        if name == "clutter":
            n_boxes = int(rng.integers(2, 5))
            quads += _clutter(rng, params, n_boxes)
            params["n_boxes"] = n_boxes
        depth = 0.6 * params["back"]
        return Scene(name, tuple(quads), _vec(0, 0, depth), depth, params)
    builder = _plane if name == "plane" else _backdrop
    quads, target, depth, params = builder(rng)
    return Scene(name, tuple(quads), target, depth, params)
