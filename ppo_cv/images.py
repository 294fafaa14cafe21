"""Reading images safely: size checked from the header before decoding, any depth to 8 bits.

A small compressed file can declare an enormous image (a 878 KB PNG of 30000 x 30000 pixels
decodes to 2.7 GB); :func:`load_image` reads the width and height from the file header first
(PNG by its IHDR chunk, other formats through Pillow's lazy ``Image.open``, which parses only
the header) and refuses images above ``max_pixels``: by default :data:`DEFAULT_MAX_PIXELS`
(100 megapixels), overridable per call or by the environment variable ``PPO_CV_MAX_IMAGE_PIXELS``
(set to nothing, it is unset, with a warning).
Named pipes, devices and other non-regular files are refused without being opened, so a FIFO
given as an image cannot block.

Images of 16 bits (or any integer depth) and float images (also single-channel float TIFF,
which OpenCV decodes only unchanged) are scaled to 8 bits by their actual range
(:func:`ppo_cv.features.to_uint8`): a 12-bit PNG keeps its contrast instead of reading as
blank. What the codecs print while failing (libpng's and OpenCV's own lines on stderr, Pillow's
warnings about a damaged EXIF block) is held back: the ValueError says what went wrong.
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
import struct
import sys
import unicodedata
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import as_flag, as_image_size, as_path, shown
from .features import to_uint8

__all__ = [
    "DEFAULT_MAX_PIXELS",
    "MAX_PIXELS_ENV",
    "ExifLayout",
    "as_image",
    "alike_remedy",
    "case_alike",
    "check_decodes",
    "check_header",
    "check_regular_file",
    "file_mode",
    "decoded_transposed",
    "exif_layout",
    "image_size",
    "load_image",
    "native_messages_silenced",
]

DEFAULT_MAX_PIXELS = 100_000_000
MAX_PIXELS_ENV = "PPO_CV_MAX_IMAGE_PIXELS"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _max_pixels(max_pixels: int | None) -> int:
    if max_pixels is None:
        text = os.environ.get(MAX_PIXELS_ENV)
        if text is not None and not text.strip():
            warnings.warn(f"{MAX_PIXELS_ENV}={text!r} is empty; ignored", stacklevel=3)
        if text is None or not text.strip():
            return DEFAULT_MAX_PIXELS
        try:
            max_pixels = int(text)
        except ValueError:
            raise ValueError(
                f"{MAX_PIXELS_ENV} must be a whole number, got {shown(text)}"
            ) from None
        name = MAX_PIXELS_ENV
    else:
        name = "max_pixels"
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, (int, np.integer)):
        raise TypeError(f"{name} must be a whole number, got {shown(max_pixels)}")
    if max_pixels < 1:
        raise ValueError(f"{name} must be >= 1, got {max_pixels}")
    return int(max_pixels)


def file_mode(path: str | os.PathLike, what: str) -> int:
    """``st_mode`` of ``path`` (symbolic links followed); ValueError naming ``what`` the path
    is when it does not exist or cannot be reached (a loop of symbolic links, no permission);
    TypeError for a ``path`` that is no path."""
    as_path(path, "path")
    try:
        return os.stat(path).st_mode
    except FileNotFoundError:
        raise ValueError(f"{what} not found: {os.fspath(path)}{_case_hint(path)}") from None
    except OSError as exc:
        raise ValueError(f"cannot read {what} {os.fspath(path)}: {exc.strerror or exc}") from None


def case_alike(path: str | os.PathLike) -> str | None:
    """The name in the folder of ``path``, a name not found, that differs from it in case or in
    the Unicode encoding of its accents only (``IMG_1.JPG`` for ``IMG_1.jpg``, as a list
    written on a system that ignores case gives it; ``e`` and a combining accent for ``é``, as
    macOS writes names), or None."""
    folder, name = os.path.split(os.fspath(as_path(path, "path")))
    try:
        names = os.listdir(folder or ".")
    except (OSError, ValueError):
        return None
    alike = sorted(other for other in names if _loose(other) == _loose(name))
    return alike[0] if alike else None


def _loose(name: str) -> str:
    return unicodedata.normalize("NFC", name).casefold()


def alike_remedy(path: str | os.PathLike) -> str | None:
    """What to tell of the name :func:`case_alike` finds for ``path``: that names are
    case-sensitive, or, for one that looks the same, that its accents are encoded otherwise
    (its code points shown); None when it finds none."""
    alike = case_alike(path)
    if alike is None:
        return None
    name = os.path.basename(os.fspath(path))
    if unicodedata.normalize("NFC", alike) != unicodedata.normalize("NFC", name):
        return f"{alike} exists: names are case-sensitive"
    return (
        f"{ascii(alike)} exists: the same name with its accents encoded otherwise than "
        f"{ascii(name)} (Unicode NFD, as macOS writes names, or NFC); names must match code "
        "point for code point"
    )


def _case_hint(path: str | os.PathLike) -> str:
    remedy = alike_remedy(path)
    return f" ({remedy})" if remedy else ""


def check_regular_file(path: str | os.PathLike) -> None:
    """ValueError unless ``path`` is an existing regular file; never opens it (a FIFO would
    block a reader)."""
    mode = file_mode(path, "image")
    if stat.S_ISDIR(mode):
        raise ValueError(f"expected an image file, got a directory: {path}")
    if not stat.S_ISREG(mode):
        raise ValueError(f"not a regular file: {path} (a pipe, socket or device?)")


def _is_regular_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is an existing regular file (symbolic links followed), without opening
    it."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):  # missing, unreachable, or a name holding a NUL byte
        return False


def image_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """``(width, height)`` from the file header without decoding, or None when unknown: a
    path that is no regular file (missing, a folder, or a FIFO, which is never opened: a reader
    would wait for a writer) or a header Pillow does not know.

    PNG is parsed directly (signature, then the IHDR chunk); other formats go through Pillow,
    which reads only the header on open.
    """
    path = os.fspath(as_path(path, "path"))
    if not _is_regular_file(path):
        return None
    with open(path, "rb") as file:
        head = file.read(24)
    if head[:8] == _PNG_SIGNATURE and head[12:16] == b"IHDR":
        width, height = struct.unpack(">II", head[16:24])
        return int(width), int(height)
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow comes with scikit-image
        return None
    bomb_limit = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = None  # only the header is read: the real size, however large
    try:
        with _pillow_warnings_held(), Image.open(path) as image:
            return _stored_tiff_size(image) or tuple(int(v) for v in image.size)
    except Exception:  # not a format Pillow knows: OpenCV may still read it
        return None
    finally:
        Image.MAX_IMAGE_PIXELS = bomb_limit


@contextlib.contextmanager
def _pillow_warnings_held() -> Iterator[None]:
    """No warning from Pillow while opening a file (a truncated TIFF's "Corrupt EXIF data"
    printed two lines before the command's own)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def check_header(path: str | os.PathLike, max_pixels: int | None = None) -> None:
    """ValueError naming ``path`` unless it is a regular file whose header, when it can be read,
    declares at most ``max_pixels`` pixels (default as :func:`load_image`); nothing is decoded.
    """
    limit = _max_pixels(max_pixels)
    check_regular_file(path)
    try:
        size = image_size(path)
    except OSError as exc:
        raise ValueError(f"cannot read image {path}: {exc.strerror or exc}") from None
    if size is not None and size[0] * size[1] > limit:
        raise ValueError(
            f"image too large: {path} declares {size[0]}x{size[1]} pixels, above the limit of "
            f"{limit} (max_pixels or {MAX_PIXELS_ENV})"
        )


def check_decodes(path: str | os.PathLike, max_pixels: int | None = None) -> None:
    """:func:`check_header`, then a decode at 1/8 scale (cheaper than a full one, and still a
    read of all the data): ValueError naming ``path`` when the file is not a readable image,
    e.g. truncated."""
    check_header(path, max_pixels)
    data = np.fromfile(os.fspath(path), dtype=np.uint8)
    with native_messages_silenced():
        image = _reduced_gray(data)
    if image is None:
        raise ValueError(f"not a readable image: {path}")


def _reduced_gray(data: np.ndarray) -> np.ndarray | None:
    """The encoded image ``data`` decoded grey at 1/8 scale, None when it does not decode;
    whole where OpenCV cannot reduce it (a PNG narrower than 8 pixels raises ``cv2.error``)."""
    import cv2

    if not data.size:
        return None
    try:
        return cv2.imdecode(data, cv2.IMREAD_REDUCED_GRAYSCALE_8)
    except cv2.error:
        return cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)


@dataclass(frozen=True)
class ExifLayout:
    """What an image's EXIF tags say about its pixels.

    Attributes
    ----------
    orientation : int or None
        The Orientation tag (1: stored upright, 5-8: stored turned a quarter); None without one.
    pixel_size : tuple of (int, int) or None
        ``(PixelXDimension, PixelYDimension)``: the size the camera wrote, which a resized or
        cropped copy no longer has; None without them.
    focal_35mm : float or None
        ``FocalLengthIn35mmFilm`` when above zero, mm: the focal length relative to the
        frame's diagonal, which pycolmap reads before ``FocalLength`` and which a resized copy
        keeps true; None without one.
    sensor_resolution : bool
        Whether ``FocalPlaneXResolution`` is given with a unit of length
        (``FocalPlaneResolutionUnit`` inch, cm, mm or um): pycolmap then reads ``FocalLength``
        through it, in the pixels the camera wrote, rather than through its table of sensor
        widths, which it multiplies by the image's own size.
    related_size : tuple of (int, int) or None
        ``(RelatedImageWidth, RelatedImageLength)`` of the interoperability tags: the size of
        the image file the camera wrote, which a resizer that rewrites :attr:`pixel_size` to
        the copy's own size leaves; None without them.
    """

    orientation: int | None = None
    pixel_size: tuple[int, int] | None = None
    focal_35mm: float | None = None
    sensor_resolution: bool = False
    related_size: tuple[int, int] | None = None

    @property
    def turned(self) -> bool:
        """Whether the orientation shows the stored pixels turned a quarter."""
        return self.orientation in (5, 6, 7, 8)

    @property
    def focal_in_recorded_pixels(self) -> bool:
        """Whether pycolmap reads the focal length in the pixels the camera wrote
        (``FocalLength`` through :attr:`sensor_resolution`, no :attr:`focal_35mm` read before
        it), which a resized copy must scale; else in the image's own."""
        return self.focal_35mm is None and self.sensor_resolution

    @property
    def camera_size(self) -> tuple[int, int] | None:
        """The size the camera wrote, ``(width, height)``: :attr:`related_size` where its
        larger side exceeds :attr:`pixel_size`'s (a copy whose resizer rewrote those to its own
        size, or dropped them), else :attr:`pixel_size`; None without either. A resizer only
        shrinks: the larger of the two is the camera's."""
        sizes = [size for size in (self.pixel_size, self.related_size) if size is not None]
        return max(sizes, key=max, default=None)


_ORIENTATION_TAG, _EXIF_IFD, _PIXEL_X_TAG, _PIXEL_Y_TAG = 0x0112, 0x8769, 0xA002, 0xA003
_FOCAL_35MM_TAG = 0xA405
_INTEROP_IFD, _RELATED_TAGS = 0xA005, (0x1001, 0x1002)  # RelatedImageWidth, RelatedImageLength
_PLANE_X_TAG, _PLANE_UNIT_TAG, _PLANE_UNITS = 0xA20E, 0xA210, (2, 3, 4, 5)


def _stored_tiff_size(image: Any) -> tuple[int, int] | None:
    """A TIFF's stored ``(width, height)`` by its tags, None for another format: Pillow reports
    a TIFF's size turned as its orientation turns it, other formats' as stored."""
    tags = getattr(image, "tag_v2", None)
    width, height = (tags.get(tag) for tag in (256, 257)) if tags is not None else (None, None)
    if isinstance(width, int) and isinstance(height, int):
        return width, height
    return None


def exif_layout(path: str | os.PathLike) -> ExifLayout:
    """The EXIF orientation, pixel dimensions and focal length tags of an image file (empty
    when it has none, Pillow cannot read it or it is no regular file: a FIFO is
    never opened)."""
    if not _is_regular_file(as_path(path, "path")):
        return ExifLayout()
    try:
        from PIL import Image

        with _pillow_warnings_held(), Image.open(os.fspath(path)) as image:
            exif = image.getexif()
            orientation = exif.get(_ORIENTATION_TAG)
            sub = exif.get_ifd(_EXIF_IFD)
            width, height = _positive(sub.get(_PIXEL_X_TAG)), _positive(sub.get(_PIXEL_Y_TAG))
            focal_35mm = _positive(sub.get(_FOCAL_35MM_TAG))
            plane = sub.get(_PLANE_X_TAG) is not None and sub.get(_PLANE_UNIT_TAG) in _PLANE_UNITS
            related = _related_size(exif)
    except Exception:  # no Pillow, not an image Pillow knows, a damaged EXIF block
        return ExifLayout()
    known = isinstance(orientation, int) and 1 <= orientation <= 8
    return ExifLayout(
        orientation if known else None, _whole_size(width, height), focal_35mm, plane,
        related,
    )  # fmt: skip


def _related_size(exif: Any) -> tuple[int, int] | None:
    """The interoperability tags' ``(RelatedImageWidth, RelatedImageLength)`` of Pillow's
    ``exif``, None without them or where that block is damaged (the other tags still count)."""
    try:
        interop = exif.get_ifd(_INTEROP_IFD)
        return _whole_size(*(_positive(interop.get(tag)) for tag in _RELATED_TAGS))
    except Exception:  # an offset past the end, a block of another type
        return None


def _whole_size(width: float | None, height: float | None) -> tuple[int, int] | None:
    """``(width, height)`` as whole numbers when both are at least 1, else None."""
    if width is None or height is None or width < 1 or height < 1:
        return None
    return int(width), int(height)


def _positive(value: Any) -> float | None:
    """An EXIF number (int or rational) as a float when it is finite and above zero, else
    None (text, a list, a rational over zero)."""
    if isinstance(value, (str, bytes)):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None
    return number if math.isfinite(number) and number > 0 else None


def decoded_transposed(path: str | os.PathLike, width: int, height: int) -> bool:
    """Whether :func:`load_image` shows a file stored as ``width x height`` pixels turned by a
    quarter (EXIF orientation 5-8: a camera held upright stores its pixels sideways, and
    OpenCV decodes them upright). Decides by the aspect of a decode at 1/8 scale; False for
    square images, unreadable files, files above the pixel limit and what is no regular file.
    """
    path, (width, height) = as_path(path, "path"), as_image_size((width, height), "stored size")
    if width == height or width * height > _max_pixels(None) or not _is_regular_file(path):
        return False
    shown = _reduced_gray(np.fromfile(os.fspath(path), dtype=np.uint8))
    if shown is None:
        return False
    aspect = shown.shape[1] / shown.shape[0]
    return abs(aspect - height / width) < abs(aspect - width / height)


def load_image(
    path: str | os.PathLike, max_pixels: int | None = None, exif_orientation: bool = True
) -> np.ndarray:
    """Read an image file as 8-bit BGR (H, W, 3), checking its size before decoding.

    Parameters
    ----------
    path : str or PathLike
        A regular image file (PNG, JPEG, TIFF, ... anything OpenCV decodes).
    max_pixels : int, optional
        Largest accepted ``width * height``; default ``PPO_CV_MAX_IMAGE_PIXELS`` from the
        environment, else :data:`DEFAULT_MAX_PIXELS` (100 megapixels).
    exif_orientation : bool
        Turn the pixels as the EXIF orientation says (upright); False: as stored, for a photo
        whose tag is stale.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        Deeper images (16-bit, float) scaled to 8 bits by their actual range.

    Raises
    ------
    ValueError
        Naming the file: missing, a directory or non-regular file, larger than ``max_pixels``,
        or not a readable image.
    """
    import cv2

    path = os.fspath(as_path(path, "path"))
    as_flag(exif_orientation, "exif_orientation")
    limit = _max_pixels(max_pixels)
    check_header(path, limit)
    data = np.fromfile(path, dtype=np.uint8)
    image = _decode(data, exif_orientation) if data.size else None
    if image is None:
        raise ValueError(f"not a readable image: {path}")
    if image.shape[0] * image.shape[1] > limit:
        raise ValueError(
            f"image too large: {path} is {image.shape[1]}x{image.shape[0]} pixels, above the "
            f"limit of {limit} (max_pixels or {MAX_PIXELS_ENV})"
        )
    image = to_uint8(image, path)
    if image.ndim == 3 and image.shape[2] == 3:
        return image
    grey = image if image.ndim == 2 else image[:, :, 0]
    return cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)


def _decode(data: np.ndarray, exif_orientation: bool = True) -> np.ndarray | None:
    """The encoded image ``data`` decoded as BGR of its own depth, else unchanged (a
    single-channel float TIFF, which OpenCV's colour decoding refuses, and never turns), else
    None; turned by its EXIF orientation unless ``exif_orientation`` is False."""
    import cv2

    ignore = 0 if exif_orientation else cv2.IMREAD_IGNORE_ORIENTATION
    with native_messages_silenced():
        image = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH | ignore)
        if image is None:
            image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if image is not None and image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    return image


@contextlib.contextmanager
def native_messages_silenced() -> Iterator[None]:
    """Hold back what native libraries print on the process's stderr (file descriptor 2) in the
    block: libpng's warnings and errors, OpenCV's log; the caller reports the outcome itself."""
    import cv2

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    with contextlib.suppress(ValueError, OSError):
        if sys.stderr is not None:  # None: a process started without standard error
            sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to protect
        saved = None
    try:
        if saved is not None:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 2)
            os.close(null)
        yield
    finally:
        if saved is not None:
            os.dup2(saved, 2)
            os.close(saved)
        cv2.utils.logging.setLogLevel(level)


def as_image(image: Any, name: str) -> np.ndarray:
    """An image argument as an 8-bit array (H, W) or (H, W, C): a path is loaded, an array
    checked (shape, numeric, no NaN; a 3x3 one is refused as a camera matrix in an image's
    place), its alpha channel dropped (BGRA to BGR: an opaque 16-bit
    alpha would widen the range by which the colours are scaled) and scaled to 8 bits by its
    range."""
    if isinstance(image, (str, os.PathLike)):
        return load_image(as_path(image, name))
    if image is None:
        raise TypeError(f"{name} is required: an image array or a path, got None")
    if isinstance(image, (bytes, bytearray, memoryview)):
        raise TypeError(
            f"{name} must be an image array or a path (str or os.PathLike), got "
            f"{type(image).__name__}: decode a file's bytes with cv2.imdecode first"
        )
    array = np.asarray(image)
    if array.ndim == 0:
        raise TypeError(
            f"{name} must be an image array or a path (str or os.PathLike), got "
            f"{type(image).__name__} {shown(image)}"
        )
    if (
        array.ndim not in (2, 3)
        or array.size == 0
        or (array.ndim == 3 and array.shape[2] not in (1, 3, 4))
    ):
        raise ValueError(
            f"{name} must be an image of shape (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), got "
            f"{array.shape}"
        )
    if array.dtype.kind not in "buif":
        raise TypeError(f"{name} must hold numbers, got dtype {array.dtype}")
    if array.shape == (3, 3):
        raise ValueError(
            f"{name} is a 3x3 array, no image: a camera matrix given in its place? (the "
            "images come first, then the camera matrices)"
        )
    return to_uint8(array[:, :, :3] if array.ndim == 3 else array, name)
