"""Textures for rendered scenes: bundled photographs, procedural noise and checkers.

A texture is a float32 image of shape (h, w, 3) with values in [0, 1]. Texture space uses the
OpenCV pixel-centre convention: texel ``(i, j)`` has its centre at ``(x, y) = (j, i)``, so the
texture covers ``[-0.5, w - 0.5] x [-0.5, h - 0.5]``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from ppo_cv.checks import as_image_size, as_number, as_whole_number, shown

__all__ = [
    "BUNDLED_PHOTOS",
    "TEXTURE_SETS",
    "Texture",
    "checker_texture",
    "fractal_noise",
    "load_photo",
    "photo_texture",
    "texture_pool",
    "texture_set_photos",
]

MAX_LEVELS = 6
MAX_TEXTURE_SIDE = 8192
"""Largest side of a checkerboard texture, texels (as a render's largest side, pixels)."""

BUNDLED_PHOTOS = (
    "astronaut",
    "coffee",
    "chelsea",
    "rocket",
    "hubble_deep_field",
    "immunohistochemistry",
    "retina",
    "brick",
    "grass",
    "gravel",
    "camera",
    "moon",
    "coins",
    "clock",
    "cell",
    "text",
    "page",
)
"""scikit-image photographs shipped with the package (no download needed)."""

TEXTURE_SETS = 2
"""Number of disjoint texture sets: set ``j`` draws only from the photographs
``BUNDLED_PHOTOS[j::TEXTURE_SETS]``, so scenes textured from different sets share no texel."""


def texture_set_photos(texture_set: int | None) -> tuple[str, ...]:
    """The photographs of texture set ``texture_set``; all of them for ``None``."""
    if texture_set is None:
        return BUNDLED_PHOTOS
    if isinstance(texture_set, bool) or not isinstance(texture_set, (int, np.integer)):
        raise TypeError(f"texture_set must be an int or None, got {type(texture_set).__name__}")
    if not 0 <= texture_set < TEXTURE_SETS:
        raise ValueError(f"texture_set must be in [0, {TEXTURE_SETS - 1}], got {texture_set}")
    return BUNDLED_PHOTOS[int(texture_set) :: TEXTURE_SETS]


@functools.cache
def load_photo(name: str) -> np.ndarray:
    """Bundled scikit-image photograph as float32 RGB in [0, 1], shape (h, w, 3).

    Raises
    ------
    ValueError
        If ``name`` is not in :data:`BUNDLED_PHOTOS`.
    """
    if name not in BUNDLED_PHOTOS:
        raise ValueError(f"unknown photo {name!r}; choose one of {', '.join(BUNDLED_PHOTOS)}")
    import skimage.data

    image = np.asarray(getattr(skimage.data, name)())
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    image = image[:, :, :3].astype(np.float32) / 255.0
    image.setflags(write=False)
    return image


def fractal_noise(
    rng: np.random.Generator, height: int, width: int, base_cells: int = 4, octaves: int = 6
) -> np.ndarray:
    """Multi-octave value noise in [0, 1], shape (height, width), float32.

    Octave ``k`` is a ``(base_cells * 2^k)``-cell random grid upsampled bicubically to the
    output size, weighted by ``2^-k * 0.7``; the sum is normalised to [0, 1].
    """
    finest = base_cells * 2 ** (octaves - 1)
    scale = min(1.0, 8.0 * finest / max(height, width))
    work_h, work_w = max(2, round(height * scale)), max(2, round(width * scale))
    total = np.zeros((work_h, work_w), np.float32)
    weight = 1.0
    for k in range(octaves):
        cells = base_cells * 2**k
        grid = rng.random((max(2, cells * height // max(height, width)) + 1, cells + 1))
        layer = cv2.resize(grid.astype(np.float32), (work_w, work_h), interpolation=cv2.INTER_CUBIC)
        total += weight * layer
        weight *= 0.7
    if (work_h, work_w) != (height, width):
        total = cv2.resize(total, (width, height), interpolation=cv2.INTER_LINEAR)
    lo, hi = float(total.min()), float(total.max())
    return (total - lo) / max(hi - lo, 1e-6)


def _photo_tile(
    rng: np.random.Generator, size: int, photos: tuple[str, ...] = BUNDLED_PHOTOS
) -> np.ndarray:
    """A ``size x size`` crop of a random one of ``photos`` at (about) native resolution."""
    photo = load_photo(photos[rng.integers(len(photos))])
    ph, pw = photo.shape[:2]
    zoom = rng.uniform(0.8, 1.25) * size / min(ph, pw, 1.5 * size)
    crop = max(8, min(int(round(size / zoom)), ph, pw))
    y0, x0 = rng.integers(0, ph - crop + 1), rng.integers(0, pw - crop + 1)
    tile = photo[y0 : y0 + crop, x0 : x0 + crop]
    if rng.random() < 0.5:
        tile = tile[:, ::-1]
    if rng.random() < 0.5:
        tile = tile[::-1]
    tile = cv2.resize(np.ascontiguousarray(tile), (size, size), interpolation=cv2.INTER_AREA
                      if crop > size else cv2.INTER_CUBIC)  # fmt: skip
    if np.ptp(photo[..., 0] - photo[..., 1]) < 1e-6:
        tile = tile * rng.uniform(0.55, 1.0, 3).astype(np.float32)
    return tile


def photo_texture(
    rng: np.random.Generator, width: int, height: int, photos: tuple[str, ...] = BUNDLED_PHOTOS
) -> np.ndarray:
    """Natural texture of shape (height, width, 3), float32 in [0, 1].

    A mosaic of square crops of the bundled photographs ``photos`` (random photograph, crop,
    flips and a tint for grey ones) at about their native resolution, modulated by
    low-frequency fractal noise and enriched with fine procedural grain so that magnified
    surfaces keep detail.
    """
    width, height = as_image_size((width, height), "texture", 8, MAX_TEXTURE_SIDE)
    tile = int(min(rng.integers(192, 384), max(width, height)))
    nx, ny = -(-width // tile), -(-height // tile)
    rows = [np.hstack([_photo_tile(rng, tile, photos) for _ in range(nx)]) for _ in range(ny)]
    texture = np.vstack(rows)[:height, :width]
    low = fractal_noise(rng, height, width, base_cells=2, octaves=3)
    grain = fractal_noise(rng, height, width, base_cells=max(8, width // 16), octaves=2)
    gain = cv2.merge([0.65 + 0.5 * low] * 3)
    offset = cv2.merge([0.3 * (grain - 0.5)] * 3)
    return np.clip(texture * gain + offset, 0.0, 1.0).astype(np.float32)


def checker_texture(
    squares: tuple[int, int] = (8, 8),
    texels_per_square: int = 16,
    dark: float = 0.1,
    light: float = 0.9,
) -> np.ndarray:
    """Checkerboard texture of shape (squares[1]*n, squares[0]*n, 3), float32.

    With ``n = texels_per_square``, square edges lie exactly on texel boundaries, so in texture
    coordinates ``s in [0, 1]`` the inner corners are at ``s = i / squares[0]`` and
    ``t = j / squares[1]``.
    """
    nx, ny = as_image_size(squares, "squares", 2, MAX_TEXTURE_SIDE)
    n = as_whole_number(texels_per_square, "texels_per_square", 1, MAX_TEXTURE_SIDE)
    if max(nx, ny) * n > MAX_TEXTURE_SIDE:
        raise ValueError(
            f"a texture of {nx}x{ny} squares of {n} texels is beyond {MAX_TEXTURE_SIDE} texels"
        )
    for name, value in (("dark", dark), ("light", light)):
        if not 0 <= as_number(value, name) <= 1:
            raise ValueError(f"{name} must be a reflectance in [0, 1], got {shown(value)}")
    cells = (np.add.outer(np.arange(ny), np.arange(nx)) % 2).astype(np.float32)
    board = np.kron(cells, np.ones((n, n), np.float32))
    board = dark + (light - dark) * board
    return np.repeat(board[:, :, None], 3, axis=2)


@dataclass(frozen=True, eq=False)
class Texture:
    """A texture and its Gaussian pyramid (``cv2.pyrDown``; level ``l`` texel ``x_l = x_0 / 2^l``).

    Attributes
    ----------
    levels : tuple of ndarray
        Level ``l`` has shape (h / 2^l, w / 2^l, 3), uint8; ``h`` and ``w`` are cropped to a
        multiple of ``2^(len(levels) - 1)`` so the pyramid scales are exact.
    wrap : bool
        Repeat the texture outside the unit square (else clamp by reflection).
    """

    levels: tuple
    wrap: bool = False

    @classmethod
    def from_image(cls, image: np.ndarray, wrap: bool = False) -> Texture:
        """Build the pyramid of an (h, w, 3) image, float in [0, 1] or uint8 (stored as uint8)."""
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"texture image must have shape (h, w, 3), got {image.shape}")
        if image.dtype != np.uint8:
            image = np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8)
        h, w = image.shape[:2]
        n = 1
        while n < MAX_LEVELS and min(h, w) >> n >= 4:
            n += 1
        step = 2 ** (n - 1)
        image = np.ascontiguousarray(image[: h - h % step, : w - w % step])
        levels = [image]
        for _ in range(n - 1):
            levels.append(cv2.pyrDown(levels[-1]))
        return cls(levels=tuple(levels), wrap=wrap)

    @property
    def size(self) -> tuple[int, int]:
        """Width and height of level 0 in texels."""
        h, w = self.levels[0].shape[:2]
        return w, h


@functools.lru_cache(maxsize=4)
def texture_pool(size: int = 2048, count: int = 4, texture_set: int | None = None) -> tuple:
    """``count`` fixed ``size x size`` photo mosaics (seeds 0 .. count-1), wrapping Textures.

    Scenes draw random windows of these, so building a scene costs no texture synthesis and
    the same seed always gives the same textures. With ``texture_set`` (see
    :data:`TEXTURE_SETS`) the mosaics use only that set's photographs: pools of different sets
    have no image content in common.
    """
    photos = texture_set_photos(texture_set)
    seed = [7919] if texture_set is None else [7919, 1 + int(texture_set)]
    pool = tuple(
        Texture.from_image(
            photo_texture(np.random.default_rng([*seed, k]), size, size, photos), wrap=True
        )
        for k in range(count)
    )
    load_photo.cache_clear()
    return pool
