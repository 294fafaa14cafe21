"""Exact pure rotations with real image statistics: real photos warped by ``K R K^-1``.

A photo is used as a picture of the sphere of directions, seen by a pinhole source camera
``K_source``. Two virtual views share the intrinsics ``K`` and the lens distortion ``dist``
and are rotated by ``-R/2`` and ``+R/2`` (half the rotation angle about the same axis) from the
source camera, so that ``x2 = R x1`` exactly (``t = 0``). A pixel ``u`` of view ``c`` is
undistorted to the normalised ray ``r`` (``cv2.undistortPoints``, the camera model of the
renderer), turned into the source frame ``d = A_c^T r`` and looked up at
``K_source d / d_z`` by bilinear inverse warping (``cv2.remap``). Between the undistorted views
this is exactly the homography ``K R K^-1``.

Unless given, ``K_source`` has a centred principal point and the largest focal length, at most
``K``'s, for which every pixel of both views falls inside the photo: no black borders, and the
photo is never minified (``upsampling = fx / f_source >= 1``).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from ppo_cv.checks import as_number
from ppo_cv.images import check_header, load_image

from .imperfect import REAL_PHOTO, Imperfections, given_intrinsics, jpeg_roundtrip
from .motion import _panorama, intrinsics
from .render import (
    RenderedPair,
    _check_dist,
    _check_intrinsics,
    _check_rotation,
    _check_size,
    _finish,
)

__all__ = ["WARP_HFOV_RANGE", "WARP_SIZE_FRACTION", "make_warped_pair", "source_photos",
           "warp_pair"]  # fmt: skip

WARP_HFOV_RANGE = (25.0, 35.0)
"""Field of view (degrees) of warped views when the imperfections do not set one."""

WARP_SIZE_FRACTION = 0.65
"""Default output size of :func:`make_warped_pair` as a fraction of the photo's size."""

MARGIN_PX = 1.0
FREIBURG_IMAGES = Path("shared") / "data" / "freiburg" / "images"
PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
_PERFECT = Imperfections(k1_range=(0.0, 0.0), focal_error=0.0, hfov_range=None,
                         jpeg_quality=None, noise_std=0.0, blur_sigma=0.0)  # fmt: skip


def _half_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation ``H`` with ``H H = R`` (half the angle about the same axis)."""
    rvec = cv2.Rodrigues(R)[0]
    return cv2.Rodrigues(rvec / 2.0)[0]


def _source_rays(K: np.ndarray, dist: np.ndarray, A: np.ndarray, size) -> np.ndarray:
    """Direction in the source frame of every pixel centre of view ``A``, shape (H, W, 3)."""
    width, height = size
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pixels = np.stack([u, v], -1).reshape(-1, 1, 2)
    if dist.size and np.any(dist):
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)
        xy = cv2.undistortPoints(pixels, K, dist, criteria=criteria).reshape(-1, 2)
    else:
        xy = (pixels.reshape(-1, 2) - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T
    rays = np.column_stack([xy, np.ones(len(xy))])
    return (rays @ A).reshape(height, width, 3)


def _fit_source_focal(xy: np.ndarray, shape: tuple[int, int], f_max: float) -> float:
    """Largest focal ``<= f_max`` putting the normalised points ``xy`` (m, 2) inside the photo."""
    height, width = shape
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    room = centre - MARGIN_PX
    reach = np.abs(xy).max(axis=0)
    bounds = np.where(reach > 0, room / np.maximum(reach, 1e-300), np.inf)
    return float(min(f_max, bounds.min()))


def _as_photo(image) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise TypeError(f"image must be uint8, got {image.dtype}")
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must have shape (H, W, 3) or (H, W), got {image.shape}")
    if min(image.shape[:2]) < 16:
        raise ValueError(f"image must be at least 16x16 pixels, got {image.shape[1::-1]}")
    return image


def warp_pair(
    image: np.ndarray,
    K: np.ndarray,
    R: np.ndarray,
    dist: np.ndarray | None = None,
    size: tuple[int, int] | None = None,
    K_source: np.ndarray | None = None,
    focal_factor: float = 1.0,
    jpeg_quality: int | None = None,
    noise_std: float = 0.0,
    blur_sigma: float = 0.0,
    seed: int | Sequence[int] = 0,
    params: dict | None = None,
) -> RenderedPair:
    """Two views of a photo related by the pure rotation ``R`` (see the module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W), uint8
        The photo (RGB or grey).
    K : array_like, shape (3, 3)
        True intrinsics of both views.
    R : array_like, shape (3, 3)
        Rotation, ``x2 = R x1``.
    dist : array_like, optional
        OpenCV distortion coefficients of both views (not told to the estimator).
    size : (int, int), optional
        Width and height of the views (default: the photo's).
    K_source : array_like, shape (3, 3), optional
        Pinhole intrinsics of the photo; fitted to the views if None (module docstring).
    focal_factor : float, default 1
        ``K_given = K`` with ``fx, fy`` times this factor (what the estimator is told).
    jpeg_quality : int, optional
        JPEG quality (1-100) both views are encoded and decoded at.
    noise_std, blur_sigma : float, default 0
        Gaussian noise (grey levels) and blur (pixels), as :func:`render_pair`.
    seed : int or sequence of int, default 0
        Seed of the noise.
    params : dict, optional
        Extra parameters to record.

    Returns
    -------
    RenderedPair
        ``t = 0``, ``K1 = K2 = K``, ``dist1 = dist2 = dist``, ``depth1`` NaN (unknown).

    Raises
    ------
    ValueError
        If a view looks behind the photo or, with ``K_source`` given, leaves the photo.
    """
    photo = _as_photo(image)
    K = _check_intrinsics("K", K)
    R = _check_rotation(R)
    dist = _check_dist("dist", dist)
    size = photo.shape[1::-1] if size is None else _check_size(size)
    for name, value, high in (("noise_std", noise_std, 50.0), ("blur_sigma", blur_sigma, 50.0),
                              ("focal_factor", focal_factor, 2.0)):  # fmt: skip
        if not (np.isfinite(as_number(value, name)) and 0.0 <= value <= high):
            raise ValueError(f"{name} must be in [0, {high}], got {value}")
    if focal_factor == 0.0:
        raise ValueError("focal_factor must be > 0")
    if jpeg_quality is not None and not 1 <= int(jpeg_quality) <= 100:
        raise ValueError(f"jpeg_quality must be in 1..100, got {jpeg_quality}")
    half = _half_rotation(R)
    rays = [_source_rays(K, dist, A, size) for A in (half.T, half)]
    if min(float(r[..., 2].min()) for r in rays) <= 1e-6:
        raise ValueError("the rotation turns a view behind the photo; use a smaller rotation")
    xy = [r[..., :2] / r[..., 2:] for r in rays]
    height, width = photo.shape[:2]
    if K_source is None:
        f = _fit_source_focal(np.concatenate([p.reshape(-1, 2) for p in xy]), (height, width),
                              float(min(K[0, 0], K[1, 1])))  # fmt: skip
        K_source = intrinsics((width, height), 2.0 * np.degrees(np.arctan(width / (2.0 * f))))
    K_source = _check_intrinsics("K_source", K_source)
    maps = [p @ K_source[:2, :2].T + K_source[:2, 2] for p in xy]
    for view, m in enumerate(maps, start=1):
        if m.min() < 0 or np.any(m.reshape(-1, 2).max(axis=0) > (width - 1, height - 1)):
            raise ValueError(f"view {view} leaves the photo; use a smaller rotation, field of "
                             "view or size, or let K_source be fitted")  # fmt: skip
    source = photo.astype(np.float32) * np.float32(1 / 255)
    rng = np.random.default_rng([*np.atleast_1d(seed).tolist(), 7])
    views = []
    for m in maps:
        warped = cv2.remap(source, m[..., 0].astype(np.float32), m[..., 1].astype(np.float32),
                           cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
        views.append(jpeg_roundtrip(_finish(warped, blur_sigma, noise_std, rng), jpeg_quality))
    record = {
        "source": "warp",
        "size": list(size),
        "K_source": K_source.tolist(),
        "upsampling": float(K[0, 0] / K_source[0, 0]),
        "noise_std": float(noise_std),
        "blur_sigma": float(blur_sigma),
        "jpeg_quality": None if jpeg_quality is None else int(jpeg_quality),
        "focal_factor": float(focal_factor),
    }
    record.update(params or {})
    K_given = given_intrinsics(K, focal_factor)
    return RenderedPair(
        image1=views[0], image2=views[1], K1=K, K2=K.copy(), R=R, t=np.zeros(3),
        depth1=np.full(size[::-1], np.nan, np.float32), dist1=dist, dist2=dist.copy(),
        params=record, K1_given=K_given, K2_given=K_given.copy(),
    )  # fmt: skip


def _bundled_photos() -> list[Path]:
    root = resources.files("ppo_cv") / "data"
    return [Path(str(root / name)) for name in ("demo1.png", "demo2.png")]


def source_photos(source: str | os.PathLike | Sequence | None = None) -> list[Path]:
    """The photos :func:`make_warped_pair` draws from.

    Parameters
    ----------
    source : path, sequence of paths, or None
        A folder (its PNG/JPEG/TIFF/BMP files, sorted), one file, or a list of files. None: the
        freiburg frames if ``$PPO_CV_SHARED/data/freiburg/images`` exists (when
        ``PPO_CV_SHARED`` is set, only there) or ``../shared/data/freiburg/images`` (relative to
        the working directory or to the source tree), else the two TUM frames shipped in
        ``ppo_cv/data``.

    Returns
    -------
    list of pathlib.Path
    """
    if source is None:
        here = Path(__file__).resolve().parents[2]
        folders = [Path.cwd().parent / FREIBURG_IMAGES, here / FREIBURG_IMAGES]
        if os.environ.get("PPO_CV_SHARED"):
            folders = [Path(os.environ["PPO_CV_SHARED"]) / FREIBURG_IMAGES.relative_to("shared")]
        for folder in folders:
            if folder.is_dir():
                return source_photos(folder)
        return _bundled_photos()
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.is_dir():
            paths = sorted(p for p in path.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES)
            if not paths:
                raise ValueError(f"no photos (png, jpg, tif, bmp) in {path}")
            return paths
        source = [path]
    paths = [Path(p) for p in source]
    if not paths:
        raise ValueError("source must name at least one photo")
    for path in paths:
        if not path.exists():
            raise ValueError(f"photo {path} does not exist")
        check_header(path)  # a FIFO, or a header declaring more pixels than accepted
    return paths


@functools.lru_cache(maxsize=32)
def _load_photo(path: str) -> np.ndarray:
    image = cv2.cvtColor(load_image(path), cv2.COLOR_BGR2RGB)
    image.setflags(write=False)
    return image


def make_warped_pair(
    seed: int = 0,
    index: int = 0,
    imperfections: Imperfections | None = REAL_PHOTO,
    source: str | os.PathLike | Sequence | None = None,
    size: tuple[int, int] | None = None,
) -> RenderedPair:
    """Pair ``index`` of the warped-photo dataset ``seed``: a tripod pan of a real photo.

    Everything is drawn from ``numpy.random.default_rng([seed, index])``: the photo (one of
    :func:`source_photos`), the imperfections, the field of view (``imperfections.hfov_range``
    or :data:`WARP_HFOV_RANGE`), a principal point within 2 % of the centre, and the rotation
    of the ``panorama`` preset (yaw ``U(0.35, 0.7) * hfov``, random sign; pitch and roll
    ``N(0, 1.5^2)`` degrees). The views are then made by :func:`warp_pair`.

    Parameters
    ----------
    seed, index : int
        Dataset seed and pair index (non-negative).
    imperfections : Imperfections or None, default REAL_PHOTO
        None: no distortion, exact focal length, no JPEG, noise or blur (same photo, field of
        view and rotation as with imperfections).
    source : path, sequence of paths, or None
        See :func:`source_photos`.
    size : (int, int), optional
        Output width and height; default :data:`WARP_SIZE_FRACTION` of the photo's (even).

    Returns
    -------
    RenderedPair
        ``params`` records the photo, the drawn ``k1``, ``focal_factor``, ``hfov_deg``,
        ``jpeg_quality`` and the rotation angles.
    """
    for name, value in (("seed", seed), ("index", index)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    if imperfections is not None and not isinstance(imperfections, Imperfections):
        raise TypeError(f"imperfections must be Imperfections or None, got {imperfections!r}")
    paths = source_photos(source)
    rng = np.random.default_rng([seed, index])
    path = paths[int(rng.integers(len(paths)))]
    photo = _load_photo(str(path))
    settings = _PERFECT if imperfections is None else imperfections
    drawn = settings.draw(rng)
    hfov = float(rng.uniform(*(settings.hfov_range or WARP_HFOV_RANGE)))
    if size is None:
        height, width = photo.shape[:2]
        size = (
            2 * round(WARP_SIZE_FRACTION * width / 2),
            2 * round(WARP_SIZE_FRACTION * height / 2),
        )
    size = _check_size(size)
    offset = rng.uniform(-0.02, 0.02, 2) * np.asarray(size)
    K = intrinsics(size, hfov, offset)
    record = {"seed": int(seed), "index": int(index), "motion": "panorama", "photo": path.name,
              "hfov1_deg": hfov, "hfov2_deg": hfov, "hfov_deg": hfov}  # fmt: skip
    R, _ = _panorama(rng, hfov, record)
    record.update(drawn.record())
    record["imperfect"] = imperfections is not None
    if imperfections is not None:
        record["imperfections"] = imperfections.record()
    pair = warp_pair(
        photo, K, R, drawn.dist if np.any(drawn.dist) else None, size,
        focal_factor=drawn.focal_factor, noise_std=drawn.noise_std,
        blur_sigma=drawn.blur_sigma, seed=[seed, index], params=record,
    )  # fmt: skip
    return drawn.apply_to(pair, size if settings.centred_principal_point else None)
