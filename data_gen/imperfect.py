"""Imperfections of real photographs, to make rendered and warped pairs as hard as real ones.

A real photo differs from the exact pinhole renders in ways no estimator is told about:

* unmodelled radial distortion ``(k1, k2)`` of the OpenCV model, or the one coefficient of the
  division model (``division``), applied in rendering but not given to the estimator;
* a focal length known only to a few percent: the estimator is given ``K_given`` whose ``fx``
  and ``fy`` are the true ones times one factor ``f ~ U(1 - focal_error, 1 + focal_error)``;
* optionally focal lengths estimated per photo, as a panorama stitcher gives them: each view's
  given focal length off by a further factor of its own;
* optionally a principal point known only as the image centre (an EXIF or panorama-stitcher
  focal length comes without one), while the true one lies up to 2 % of the image off it;
* a narrow horizontal field of view (consumer zooms, 25-35 degrees), which makes rotation and
  translation hard to tell apart;
* JPEG compression, sensor noise and a slight optical blur;
* optionally the photometry of a consumer camera: an automatic exposure that changes between
  the shots, and vignetting, the lens darkening towards the corners (the same in both views,
  so a scene point seen near the centre of one view and near a corner of the other changes
  brightness), both applied in linear light and clipped at white.

:class:`Imperfections` holds the ranges; :meth:`Imperfections.draw` draws one pair's values.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import cv2
import numpy as np

from ppo_cv.checks import (
    MAX_FOCAL,
    MIN_FOCAL,
    as_camera_matrix,
    as_number,
    as_positive,
    as_whole_number,
    shown,
)

from .render import _check_size

__all__ = [
    "LONG_ZOOM",
    "NARROW_LENS",
    "REAL_PHOTO",
    "DrawnImperfections",
    "Imperfections",
    "expose",
    "given_intrinsics",
    "jpeg_roundtrip",
]

MAX_K1 = 0.5
MAX_FOCAL_ERROR = 0.5
MAX_NOISE = 50.0
MAX_BLUR = 50.0
MAX_EXPOSURE_EV = 3.0
MAX_VIGNETTING = 0.9
MAX_GAIN = 2.0**16
"""Largest exposure gain of :func:`expose`, 16 stops (its reciprocal the smallest): beyond, the
image is white (black) long before, and a gain past float32's range overflowed."""
GAMMA = 2.2
"""Power law between the stored grey levels and linear light (close to sRGB's curve)."""
DIVISION_SERIES = (1.0, 2.0, 5.0)
"""OpenCV's ``(k1, k2, k3)`` of a division-model lens ``lambda`` are ``lambda`` times these
powers of it: undistorting ``x = q m`` by ``q = x / (1 + lambda |x|^2)`` needs
``m = 1 + lambda |q|^2 m^2``, whose series in ``lambda |q|^2`` has the Catalan numbers as
coefficients (1, 1, 2, 5, 14, ...). The first left out, ``14 lambda^4 |q|^9``, is below 2e-7 of
the focal length for ``|lambda| <= 0.15`` and ``|q| <= 0.3`` (a 30 degree diagonal)."""


def division_dist(k1: float) -> np.ndarray:
    """OpenCV distortion coefficients ``(k1, k2, p1, p2, k3)`` of the division-model lens
    ``q = x / (1 + k1 |x|^2)`` (``x`` distorted, ``q`` pinhole; :data:`DIVISION_SERIES`).

    >>> division_dist(-0.1).round(6).tolist()
    [-0.1, 0.02, 0.0, 0.0, -0.005]
    """
    k = as_number(k1, "k1")
    if not abs(k) <= MAX_K1:  # the series holds for small k1 only; 1e300 overflowed
        raise ValueError(
            f"k1 must be finite, within +-{MAX_K1} (as Imperfections draws it), got {k}"
        )
    first, second, third = (c * k ** (i + 1) for i, c in enumerate(DIVISION_SERIES))
    return np.array([first, second, 0.0, 0.0, third])


def _pair(name: str, value, low: float, high: float) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair of numbers (low, high), got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and low <= a <= b <= high):
        raise ValueError(f"{name} must satisfy {low} <= low <= high <= {high}, got {value!r}")
    return a, b


def _scalar(name: str, value, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    number = float(value) if abs(value) < 2**1024 else math.inf  # an int beyond a float
    if not (math.isfinite(number) and low <= number <= high):
        raise ValueError(f"{name} must be in [{low}, {high}], got {shown(value)}")
    return number


@dataclass(frozen=True)
class DrawnImperfections:
    """The imperfections of one pair, drawn by :meth:`Imperfections.draw`.

    Attributes
    ----------
    k1, k2 : float
        Radial distortion of both views (same lens), OpenCV ``dist = (k1, k2, 0, 0, 0)``; with
        ``division`` ``k1`` is the division model's coefficient and ``k2`` is 0.
    focal_factor : float
        ``fx_given / fx_true = fy_given / fy_true`` for both views.
    view_factors : (float, float)
        Further factor of each view's given focal length (``(1, 1)`` unless
        :attr:`Imperfections.view_focal_error`).
    jpeg_quality : int or None
        JPEG quality both views are encoded at (None: no compression).
    noise_std, blur_sigma : float
        Gaussian noise (grey levels) and blur (pixels), as :class:`Imperfections`.
    exposure_ev : float
        Exposure of view 2 over view 1, stops (0 unless :attr:`Imperfections.exposure_ev`);
        view 1 is exposed ``-exposure_ev / 2`` stops, view 2 ``+exposure_ev / 2``.
    vignetting : float
        Light lost in the image corners by both views, as :attr:`Imperfections.vignetting`.
    division : bool
        ``k1`` is the coefficient of the division model (:attr:`Imperfections.division`).
    """

    k1: float
    k2: float
    focal_factor: float
    jpeg_quality: int | None
    noise_std: float
    blur_sigma: float
    view_factors: tuple = (1.0, 1.0)
    exposure_ev: float = 0.0
    vignetting: float = 0.0
    division: bool = False

    @property
    def dist(self) -> np.ndarray:
        """OpenCV distortion coefficients ``(k1, k2, 0, 0, 0)``, or those of the division-model
        lens ``k1`` (:func:`division_dist`), shape (5,)."""
        if self.division:
            return division_dist(self.k1)
        return np.array([self.k1, self.k2, 0.0, 0.0, 0.0])

    def record(self) -> dict:
        """The drawn values as JSON-serialisable parameters."""
        record = asdict(self)
        record["view_factors"] = [float(v) for v in self.view_factors]
        return record

    def focal_factors(self) -> tuple[float, float]:
        """Given over true focal length of view 1 and view 2."""
        return tuple(self.focal_factor * float(v) for v in self.view_factors)

    def gains(self) -> tuple[float, float]:
        """Exposure gain (linear light) of view 1 and view 2; their ratio is ``2**exposure_ev``."""
        half = 2.0 ** (0.5 * self.exposure_ev)
        return 1.0 / half, half

    def apply_to(self, pair, centre_of: tuple[int, int] | None = None):
        """``pair`` (a ``RenderedPair``) as a camera with these imperfections gives it.

        Its views exposed (:func:`expose`) and JPEG-compressed, ``K1_given`` and ``K2_given``
        its true intrinsics with the drawn focal factors and, with ``centre_of = (width,
        height)``, the image centre as principal point (:func:`given_intrinsics`).
        """
        image1, image2 = (
            jpeg_roundtrip(expose(image, gain, self.vignetting), self.jpeg_quality)
            for image, gain in zip((pair.image1, pair.image2), self.gains(), strict=True)
        )
        K1_given, K2_given = (
            given_intrinsics(K, factor, centre_of)
            for K, factor in zip((pair.K1, pair.K2), self.focal_factors(), strict=True)
        )
        return replace(pair, image1=image1, image2=image2, K1_given=K1_given, K2_given=K2_given)


@dataclass(frozen=True)
class Imperfections:
    """Ranges of the imperfections of real photos (see the module docstring).

    Attributes
    ----------
    k1_range : (float, float), default (0.02, 0.1)
        ``|k1| ~ U(k1_range)`` with a random sign (:attr:`barrel_share`);
        ``0 <= low <= high <= 0.5``.
    k2_fraction : float, default 0
        ``k2 = k2_fraction * k1``; ``|k2_fraction| <= 5``.
    focal_error : float, default 0.03
        The focal length given to the estimator is the true one times ``U(1 -+ focal_error)``;
        in ``[0, 0.5]``.
    hfov_range : (float, float) or None, default (25, 35)
        Horizontal field of view (degrees) drawn uniformly in this range; None keeps the motion
        preset's own field of view (55-70 degrees for renders, 25-35 for warped photos).
    jpeg_quality : (int, int) or None, default (70, 95)
        JPEG quality drawn uniformly (integers) in this range, in 1..100; None: no JPEG.
    noise_std : float, default 1
        Gaussian noise, grey levels (0-255), in ``[0, 50]``.
    blur_sigma : float, default 0.5
        Gaussian blur, pixels, in ``[0, 50]``.
    centred_principal_point : bool, default False
        Give the estimator the image centre, ``((w - 1) / 2, (h - 1) / 2)``, as principal point
        instead of the true one (drawn within 2 % of the image size of the centre by
        ``ppo_cv.data_gen``'s cameras). Draws nothing: the same pair, told less.
    view_focal_error : float, default 0
        Focal lengths given per photo: each view's given focal length is further scaled by its
        own factor ``U(1 -+ view_focal_error)``, in ``[0, 0.5]``. The factors come from a
        generator seeded with the pair's other draws, so the pair is the same, told
        differently.
    exposure_ev : float, default 0
        Automatic exposure between the shots: view 2 is exposed ``U(-exposure_ev,
        exposure_ev)`` stops brighter than view 1 (drawn from a generator of its own, as
        ``view_focal_error``), in ``[0, 3]``.
    vignetting : float, default 0
        Fraction of the light lost in the image corners, ``1 - vignetting * (r / r_corner)^2``
        at distance ``r`` from the image centre, the same in both views; in ``[0, 0.9]``.
    barrel_share : float, default 0.5
        Probability that the lens has barrel distortion (``k1 < 0``, the common case of
        consumer zooms), in ``[0, 1]``; the sign is drawn from the same number either way.
    division : bool, default False
        ``k1`` is the coefficient of the division model ``q = x / (1 + k1 |x|^2)`` on
        normalised points (``x`` distorted, ``q`` pinhole), as radial refinements fit it,
        rendered through :func:`division_dist`; needs ``k2_fraction = 0``.
    """

    k1_range: tuple = (0.02, 0.1)
    k2_fraction: float = 0.0
    focal_error: float = 0.03
    hfov_range: tuple | None = (25.0, 35.0)
    jpeg_quality: tuple | None = (70, 95)
    noise_std: float = 1.0
    blur_sigma: float = 0.5
    centred_principal_point: bool = False
    view_focal_error: float = 0.0
    exposure_ev: float = 0.0
    vignetting: float = 0.0
    barrel_share: float = 0.5
    division: bool = False

    def __post_init__(self) -> None:
        put = object.__setattr__
        if not isinstance(self.centred_principal_point, (bool, np.bool_)):
            raise ValueError(
                "centred_principal_point must be True or False, got "
                f"{self.centred_principal_point!r}"
            )
        put(self, "centred_principal_point", bool(self.centred_principal_point))
        if not isinstance(self.division, (bool, np.bool_)):
            raise ValueError(f"division must be True or False, got {self.division!r}")
        put(self, "division", bool(self.division))
        put(self, "barrel_share", _scalar("barrel_share", self.barrel_share, 0.0, 1.0))
        put(self, "k1_range", _pair("k1_range", self.k1_range, 0.0, MAX_K1))
        put(self, "k2_fraction", _scalar("k2_fraction", self.k2_fraction, -5.0, 5.0))
        if self.division and self.k2_fraction != 0.0:
            raise ValueError("k2_fraction must be 0 for a division-model lens (division=True)")
        put(self, "focal_error", _scalar("focal_error", self.focal_error, 0.0, MAX_FOCAL_ERROR))
        put(self, "view_focal_error",
            _scalar("view_focal_error", self.view_focal_error, 0.0, MAX_FOCAL_ERROR))  # fmt: skip
        put(self, "exposure_ev", _scalar("exposure_ev", self.exposure_ev, 0.0, MAX_EXPOSURE_EV))
        put(self, "vignetting", _scalar("vignetting", self.vignetting, 0.0, MAX_VIGNETTING))
        if self.hfov_range is not None:
            hfov = _pair("hfov_range", self.hfov_range, 1.0, 179.0)
            if hfov[0] <= 1.0 or hfov[1] >= 179.0:
                raise ValueError(f"hfov_range must lie inside (1, 179) degrees, got {hfov}")
            put(self, "hfov_range", hfov)
        if self.jpeg_quality is not None:
            low, high = _pair("jpeg_quality", self.jpeg_quality, 1, 100)
            if low != int(low) or high != int(high):
                raise ValueError(f"jpeg_quality must be integers, got {self.jpeg_quality!r}")
            put(self, "jpeg_quality", (int(low), int(high)))
        put(self, "noise_std", _scalar("noise_std", self.noise_std, 0.0, MAX_NOISE))
        put(self, "blur_sigma", _scalar("blur_sigma", self.blur_sigma, 0.0, MAX_BLUR))

    def draw(self, rng: np.random.Generator) -> DrawnImperfections:
        """Draw one pair's distortion, focal factor and JPEG quality from ``rng``.

        Always makes the same four draws (sign and size of ``k1``, focal factor, quality), so
        the rest of a pair's random stream does not depend on the settings.
        """
        sign = 1.0 if rng.random() < 1.0 - self.barrel_share else -1.0
        k1 = sign * float(rng.uniform(*self.k1_range))
        factor = float(rng.uniform(1.0 - self.focal_error, 1.0 + self.focal_error))
        quality_draw = rng.random()
        quality = None
        if self.jpeg_quality is not None:
            low, high = self.jpeg_quality
            quality = min(high, low + int(quality_draw * (high - low + 1)))
        key = np.array([k1, factor, quality_draw]).view(np.uint32)
        views = (1.0, 1.0)
        if self.view_focal_error > 0:
            error = self.view_focal_error
            drawn = np.random.default_rng(key).uniform(1.0 - error, 1.0 + error, 2)
            views = tuple(float(v) for v in drawn)
        exposure = 0.0
        if self.exposure_ev > 0:
            side = np.random.default_rng([*key.tolist(), 1])
            exposure = float(side.uniform(-self.exposure_ev, self.exposure_ev))
        return DrawnImperfections(
            k1=k1, k2=self.k2_fraction * k1, focal_factor=factor, jpeg_quality=quality,
            noise_std=self.noise_std, blur_sigma=self.blur_sigma, view_factors=views,
            exposure_ev=exposure, vignetting=self.vignetting, division=self.division,
        )  # fmt: skip

    def record(self) -> dict:
        """The settings as JSON-serialisable parameters."""
        return {key: list(v) if isinstance(v, tuple) else v for key, v in asdict(self).items()}


REAL_PHOTO = Imperfections()
"""Imperfections of a consumer camera on a tripod: the defaults of :class:`Imperfections`."""

NARROW_LENS = Imperfections(
    k1_range=(0.05, 0.15), division=True, barrel_share=0.7, hfov_range=(15.0, 25.0)
)
"""A consumer zoom near its long end on a tripod: a 15-25 degree field, where a small
translation and a pan are nearly the same flow, and a lens of strong distortion, the division
model's ``|k1|`` 0.05-0.15 on normalised points, barrel on seven lenses of ten; the focal
length, JPEG, noise and blur of :data:`REAL_PHOTO`."""

LONG_ZOOM = Imperfections(k1_range=(0.3, 0.5), barrel_share=0.0, hfov_range=(19.0, 20.0))
"""A consumer zoom at its long end, as the real tripod panoramas of a 19.5 degree field
(720 x 540 at a focal length of about 2000 pixels) show it: a 19-20 degree field through a
pincushion lens of OpenCV ``k1`` 0.3-0.5 on normalised points, 1.4-2.3 % of displacement at
the image corner (``|q|`` about 0.21 there), beyond the rotation model's box
(``ppo_cv.rotation.MAX_K1``); the focal length, JPEG, noise and blur of :data:`REAL_PHOTO`."""


def given_intrinsics(
    K: np.ndarray, focal_factor: float, centre_of: tuple[int, int] | None = None
) -> np.ndarray:
    """``K`` with ``fx``, ``fy`` (and the skew) scaled by ``focal_factor``, shape (3, 3).

    With ``centre_of = (width, height)`` the principal point is that image's centre
    ``((width - 1) / 2, (height - 1) / 2)`` instead of ``K``'s. A factor that takes a focal
    length out of ``[MIN_FOCAL, MAX_FOCAL]`` (:mod:`ppo_cv.checks`) is a ValueError: no camera
    matrix the estimator takes.
    """
    K_given = as_camera_matrix(K, "K").copy()
    K_given[:2, :2] *= as_positive(focal_factor, "focal_factor")
    focal = K_given[0, 0], K_given[1, 1]
    if not MIN_FOCAL <= min(focal) <= max(focal) <= MAX_FOCAL:
        raise ValueError(
            f"focal_factor {shown(focal_factor)} takes the focal lengths to "
            f"({focal[0]:.3g}, {focal[1]:.3g}), outside [{MIN_FOCAL:g}, {MAX_FOCAL:g}] pixels"
        )
    if centre_of is not None:
        width, height = _check_size(centre_of)
        K_given[:2, 2] = (width - 1) / 2.0, (height - 1) / 2.0
    return K_given


def expose(image: np.ndarray, gain: float = 1.0, vignetting: float = 0.0) -> np.ndarray:
    """An RGB or grey uint8 image, (H, W, 3) or (H, W), exposed ``gain`` times, vignetted.

    In linear light ``L = (I / 255)^GAMMA`` the image becomes
    ``L * gain * (1 - vignetting * (r / r_corner)^2)``, ``r`` the distance from the image
    centre, then clipped at white and stored back through the same power law. A gain of 1
    without vignetting returns the image itself.

    Raises
    ------
    ValueError
        An image that is not uint8 of shape (H, W) or (H, W, C), a gain that is not a positive
        number, a vignetting outside ``[0, 0.9]``.
    """
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise ValueError(f"image must be uint8 of shape (H, W) or (H, W, C), got {image.dtype} "
                         f"{image.shape}")  # fmt: skip
    gain = _scalar("gain", gain, 1.0 / MAX_GAIN, MAX_GAIN)
    vignetting = _scalar("vignetting", vignetting, 0.0, MAX_VIGNETTING)
    if gain == 1.0 and vignetting == 0.0:
        return image
    height, width = image.shape[:2]
    y, x = np.ogrid[:height, :width]
    r2 = ((x - (width - 1) / 2.0) ** 2 + (y - (height - 1) / 2.0) ** 2) / (
        ((width - 1) / 2.0) ** 2 + ((height - 1) / 2.0) ** 2
    )
    scale = (gain * (1.0 - vignetting * r2)).astype(np.float32)
    scale = scale.reshape(scale.shape + (1,) * (image.ndim - 2))
    linear = (image.astype(np.float32) * np.float32(1 / 255)) ** np.float32(GAMMA) * scale
    stored = np.minimum(linear, 1.0) ** np.float32(1 / GAMMA) * np.float32(255)
    return np.rint(stored).astype(np.uint8)


def jpeg_roundtrip(image: np.ndarray, quality: int | None) -> np.ndarray:
    """Encode an RGB uint8 image (H, W, 3) as JPEG at ``quality`` and decode it (None: as is)."""
    if quality is None:
        return image
    quality = as_whole_number(quality, "quality", 0, 100)
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must be RGB uint8 of shape (H, W, 3), got {image.dtype} "
                         f"{image.shape}")  # fmt: skip
    ok, data = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR),
                            [cv2.IMWRITE_JPEG_QUALITY, int(quality)])  # fmt: skip
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
