"""Camera intrinsics from the forms people have them in.

- Strings: ``"fx,fy,cx,cy"`` or the 9 entries of ``K`` row-major; distortion ``"k1,k2,p1,p2[,k3]"``.
- OpenCV FileStorage YAML/XML as written after ``cv2.calibrateCamera`` (``camera_matrix`` /
  ``cameraMatrix`` / ``K`` / ``M1``, ``distortion_coefficients`` / ``dist_coeffs`` / ``D1``, ...),
  and ROS ``camera_info`` YAML (``distortion_model`` plumb_bob, rational_polynomial or
  Kalibr's radtan: OpenCV's pinhole distortion; Kalibr's none: no distortion; another model,
  a fisheye's, is refused). Kalibr's ``distortion_coeffs`` are read as OpenCV's, and a Kalibr
  ``camchain.yaml`` of pinhole cameras camera by camera (``cam0``, ``cam1``).
- COLMAP ``cameras.txt`` (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV),
  its principal point moved from COLMAP's pixel coordinates to OpenCV's
  (:data:`COLMAP_PIXEL_OFFSET`).
- JSON: ``{"K": ..., "dist": ...}``, ``{"fx", "fy", "cx", "cy"}``, ``{"K1", "K2", "dist1",
  "dist2"}`` or ``{"cameras": [camera, camera]}``; a ``distortion_model`` must name OpenCV's
  pinhole distortion or none, as in ROS YAML.
- EXIF: a guess from the image's focal length tags (``pycolmap.infer_camera_from_image``).

A file may describe one camera (used for both images) or two (image 1, image 2). A camera
that states the size of its images (COLMAP's WIDTH HEIGHT, OpenCV's ``image_width`` and
``image_height``, JSON ``width`` and ``height``) is fitted to an image of another size by
:func:`fit_to_image`: scaled when the aspect ratio is the same, refused otherwise.
"""

from __future__ import annotations

import codecs
import json
import math
import os
import re
import stat
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .checks import (
    as_camera_matrix,
    as_distortion,
    as_flag,
    as_image_size,
    as_nonnegative,
    as_number,
    as_path,
    as_positive,
    cut,
    require_instance,
    shown,
)

__all__ = [
    "Camera",
    "parse_intrinsics",
    "parse_distortion",
    "load_calibration",
    "camera_from_exif",
    "read_text_file",
    "fit_to_image",
    "implausible_intrinsics",
    "warn_implausible",
    "ImplausibleCameraWarning",
    "ASPECT_TOLERANCE",
    "TURNED_CENTRE_TOLERANCE",
    "EXIF_FIELD_RANGE_DEG",
    "EXIF_PLAUSIBLE_FIELD_DEG",
    "field_of_view_deg",
    "exif_focal_scale",
    "fitted_exif_focal",
    "resize_scale",
    "GUESSED_FOCAL_FACTOR",
    "MAX_PIXEL_ASPECT",
    "COLMAP_PIXEL_OFFSET",
    "unusable_exif_focal",
]

COLMAP_PIXEL_OFFSET = 0.5
"""COLMAP puts the centre of an image's first pixel at (0.5, 0.5), OpenCV at (0, 0); every
``K`` and pixel of ppo_cv is in OpenCV's coordinates (a blob centred on pixel column 100 is
at x 100 to OpenCV, 100.5 to pycolmap's SIFT). A principal point or keypoint in COLMAP's
coordinates is OpenCV's plus this: added where a COLMAP model is written, taken off where a
COLMAP ``cameras.txt`` is read."""

ASPECT_TOLERANCE = 0.01
"""Relative difference of the horizontal and vertical scale factors within which an image is
taken for a resized copy of the calibrated one (:func:`fit_to_image`)."""

MAX_PIXEL_ASPECT = 4.0
"""Largest ratio of ``fx`` to ``fy`` (either way) a calibration may give: an anamorphic lens
squeezes by 2 at most, so a larger ratio is a typing error (``535,4,539,2`` for 535.4 and
539.2 reads as fx 535 and fy 4)."""


@dataclass(frozen=True)
class Camera:
    """Pinhole intrinsics and OpenCV distortion of one camera.

    Attributes
    ----------
    K : ndarray, shape (3, 3)
    dist : ndarray, shape (D,) or None
        ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``; None for an undistorted camera.
    image_size : tuple of int or None
        ``(width, height)`` of the images the camera was calibrated on, when the file says.

    Each field is checked as the pipeline checks its arguments (a ValueError or TypeError
    naming it) and held as float64: a K of float16, float32 or integers is converted exactly,
    all-zero distortion is None. ``K`` and ``dist`` are read-only copies of the arrays given.
    """

    K: np.ndarray
    dist: np.ndarray | None = None
    image_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", _held(as_camera_matrix(self.K, "Camera.K")))
        dist = as_distortion(self.dist, "Camera.dist")
        object.__setattr__(self, "dist", None if dist is None else _held(dist))
        size = self.image_size
        if size is None:
            return
        if isinstance(size, np.ndarray) and size.shape == (2,):  # as numpy gives it
            size = tuple(size.tolist())
        if not (isinstance(size, (tuple, list)) and len(size) == 2):
            raise TypeError(f"Camera.image_size must be (width, height) or None, got {shown(size)}")
        if any(isinstance(side, (str, bytes)) for side in size):  # texts are a file's to read
            raise TypeError(f"Camera.image_size must be two whole numbers, got {shown(size)}")
        object.__setattr__(self, "image_size", _image_size(*size, "Camera.image_size"))


def _held(array: np.ndarray) -> np.ndarray:
    """A read-only copy: a camera checked when made does not change with its caller's array."""
    array = array.copy()
    array.flags.writeable = False
    return array


def _numbers(text: str, name: str) -> np.ndarray:
    if not isinstance(text, str):
        raise TypeError(
            f"{name} must be a text of numbers, got {type(text).__name__} {shown(text)}"
        )
    parts = [p for p in re.split(r"[,\s;\[\]()]+", str(text)) if p]  # nested lists as printed
    try:
        values = np.array([float(p) for p in parts], dtype=np.float64)
    except ValueError:
        number, bad = next((i, p) for i, p in enumerate(parts, 1) if not _is_number(p))
        raise ValueError(
            f"{name} must be numbers separated by commas, spaces or semicolons: field {number} "
            f"of {len(parts)} is {shown(bad)}"
        ) from None
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} has NaN or infinite values: {shown(text)}")
    return values


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _matrix_from_values(values: np.ndarray, name: str) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim > 1 and values.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 matrix, got shape {values.shape}")
    values = values.reshape(-1)
    if values.size == 4:
        fx, fy, cx, cy = values
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    elif values.size == 9:
        K = values.reshape(3, 3)
    else:
        hint = (" (a focal length alone, or f,cx,cy: give f,f,cx,cy, the principal point at "
                "the image centre, (width-1)/2,(height-1)/2 in OpenCV's pixels, when it is not "
                "known)")  # fmt: skip
        raise ValueError(
            f"{name} must be 4 numbers fx,fy,cx,cy or the 9 entries of K, got {values.size}"
            + (hint if values.size < 4 else "")
        )
    K = as_camera_matrix(K, name)
    if K[0, 0] < 0 or K[1, 1] < 0:
        raise ValueError(f"{name} must have positive focal lengths, got fx={K[0, 0]} fy={K[1, 1]}")
    if not 1.0 / MAX_PIXEL_ASPECT <= K[0, 0] / K[1, 1] <= MAX_PIXEL_ASPECT:
        raise ValueError(
            f"{name} gives fx={K[0, 0]:g} and fy={K[1, 1]:g}, a pixel {K[0, 0] / K[1, 1]:.3g} "
            "times as wide as tall, which no camera has (a decimal comma? write 535.4, not 535,4)"
        )
    return K


def parse_intrinsics(text: str, name: str = "intrinsics") -> np.ndarray:
    """``"fx,fy,cx,cy"`` or 9 row-major numbers to a 3x3 ``K``.

    >>> parse_intrinsics("535.4,539.2,320.1,247.6")[0]
    array([535.4,   0. , 320.1])
    """
    return _matrix_from_values(_numbers(text, name), name)


def parse_distortion(text: str, name: str = "distortion") -> np.ndarray | None:
    """``"k1,k2,p1,p2[,k3]"`` to OpenCV distortion coefficients; None when all are zero.
    ValueError for a text without numbers (an empty option is no way to say "none")."""
    values = _numbers(text, name)
    if values.size == 0:
        raise ValueError(f"{name} is empty: give k1,k2,p1,p2[,k3] (or 8, 12 or 14 numbers)")
    return as_distortion(values, name)


def _read_opencv(path: str) -> list[Camera]:
    """Cameras of an OpenCV FileStorage file; ValueError for anything OpenCV cannot parse."""
    import cv2

    if os.path.getsize(path) == 0:
        raise ValueError(f"calibration file {path} is empty")
    kalibr = _kalibr_chain(path)
    if kalibr is not None:
        return _one_or_two(kalibr, path)
    try:
        K1, D1, K2, D2, size = _opencv_matrices(path)
    except (cv2.error, SystemError) as exc:
        cause = exc.__cause__ or exc.__context__ or exc
        reason = (str(cause).strip().splitlines() or [type(cause).__name__])[-1]
        reason = re.sub(r"^OpenCV\(.*?\) \S+: error: \(.*?\) ", "", reason)
        raise ValueError(f"malformed OpenCV calibration file {path}: {reason}") from None
    if K1 is None:
        raise ValueError(f"no camera matrix (camera_matrix, cameraMatrix, K or M1) in {path}")
    dist1 = as_distortion(D1, f"distortion coefficients in {path}")
    cameras = [Camera(_matrix_from_values(K1, f"camera matrix in {path}"), dist1, size)]
    if K2 is not None:
        K2 = _matrix_from_values(K2, f"camera matrix 2 in {path}")
        cameras.append(Camera(K2, as_distortion(D2, f"distortion coefficients 2 in {path}"), size))
    return cameras


_KALIBR_CAMERA = re.compile(r"^(cam\d+):[ \t]*\n((?:[ \t]+.*\n?|[ \t]*\n)*)", re.MULTILINE)
_KALIBR_ENTRY = re.compile(r"^[ \t]+(\w+):[ \t]*(.*?)[ \t]*$", re.MULTILINE)


def _kalibr_chain(path: str) -> list[Camera] | None:
    """The cameras of a Kalibr ``camchain.yaml`` (``cam0:``, ``cam1:`` blocks holding
    ``intrinsics: [fu, fv, pu, pv]``, ``distortion_coeffs``, ``resolution: [w, h]``), or None
    for another file. OpenCV's YAML parser fails on its nested lists ("Incorrect
    indentation"), so its one-line entries are read here. A ``camera_model`` other than
    ``pinhole`` or a ``distortion_model`` other than ``radtan`` or ``none`` is refused."""
    with open(path, encoding="utf-8-sig", errors="replace") as handle:
        text = handle.read()
    blocks = [(name, dict(_KALIBR_ENTRY.findall(body))) for name, body in
              _KALIBR_CAMERA.findall(text.replace("\r\n", "\n"))]  # fmt: skip
    blocks = [(name, entries) for name, entries in blocks if "intrinsics" in entries]
    if not blocks:
        return None
    blocks.sort(key=lambda block: int(block[0][3:]))
    return [_kalibr_camera(entries, f"{path} {name}") for name, entries in blocks]


def _kalibr_camera(entries: dict[str, str], where: str) -> Camera:
    """One ``camN`` block of a Kalibr camchain as a :class:`Camera`."""
    model = entries.get("camera_model", "pinhole")
    if model != "pinhole":
        raise ValueError(f"camera_model {shown(model)} in {where} is not a pinhole camera")
    distortion = entries.get("distortion_model")
    _require_opencv_model(distortion, f"in {where}")

    def numbers(key: str) -> np.ndarray | None:
        text = entries.get(key)
        if text is None:
            return None
        if not (text.startswith("[") and text.endswith("]")):
            raise ValueError(
                f"{where}: {key} must be a list of numbers on its line, [a, b, ...], got "
                f"{shown(text)}"
            )
        return _numbers(text[1:-1], f"{where}: {key}") if text[1:-1].strip() else np.zeros(0)

    intrinsics, coefficients = numbers("intrinsics"), numbers("distortion_coeffs")
    dist = as_distortion(coefficients, f"{where}: distortion_coeffs")
    _require_no_coefficients(distortion, (dist,), f"in {where}")
    resolution = numbers("resolution")
    if resolution is not None and resolution.size != 2:
        raise ValueError(f"{where}: resolution must be [width, height], got {resolution.tolist()}")
    size = None if resolution is None else _image_size(*resolution, where)
    return Camera(_matrix_from_values(intrinsics, f"{where}: intrinsics"), dist, size)


def _open_storage(path: str):
    """OpenCV's FileStorage of ``path``, read from memory past a UTF-8 byte-order mark (which
    text editors on Windows write and OpenCV's parsers refuse)."""
    import cv2

    with open(path, "rb") as handle:
        head = handle.read(len(codecs.BOM_UTF8))
        if head != codecs.BOM_UTF8:
            return cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
        text = handle.read().decode("utf-8", errors="replace")
    return cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)


_OPENCV_DISTORTION_KEYS = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "D1",
                           "dist1", "distortion_coeffs", "D2", "dist2",
                           "distortion_coefficients_2")  # fmt: skip
_FIRST_DISTORTION_KEYS = 7
"""How many of :data:`_OPENCV_DISTORTION_KEYS` name the first camera's coefficients (Kalibr's
``distortion_coeffs`` the last of them); the others name the second camera's."""


def _require_known_distortion(storage, path: str) -> str | None:
    """ValueError for numbers under a key that names a distortion but is none of
    :data:`_OPENCV_DISTORTION_KEYS` (``distortion``, ``dist``): they would be dropped, and the
    camera read without its distortion; and for a ROS ``distortion_model`` other than OpenCV's
    (``equidistant``, a fisheye). Returns that ``distortion_model``, None for none."""
    node = storage.getNode("distortion_model")  # ROS camera_info
    model = node.string() if node.isString() else None
    _require_opencv_model(model, f"in {path}")
    for key in storage.root().keys():
        if key.lower().startswith("dist") and key not in _OPENCV_DISTORTION_KEYS:
            if not storage.getNode(key).isString():
                raise ValueError(
                    f"{key} in {path} is no distortion key this reader knows, and would be "
                    f"ignored; name the coefficients {', '.join(_OPENCV_DISTORTION_KEYS[:6])} "
                    "(a second camera's D2, dist2)"
                )
    return model


_OPENCV_DISTORTION_MODELS = ("plumb_bob", "rational_polynomial", "radtan")
"""Names of OpenCV's pinhole distortion in a ``distortion_model`` (ROS ``camera_info``,
Kalibr): the one model the readers take; another (``equidistant``, a fisheye) is refused."""

NO_DISTORTION_MODELS = ("none", "")
"""Names of no distortion in a ``distortion_model``: Kalibr's ``none`` and the empty text of
an uncalibrated ROS ``camera_info``. Read as no distortion, with coefficients none, empty or
zeros (:func:`_require_no_coefficients`)."""


def _require_opencv_model(model: Any, where: str) -> None:
    """ValueError for a ``distortion_model`` named in ``where`` that is not OpenCV's pinhole
    distortion nor none: its coefficients would be read as OpenCV's, a silent wrong camera."""
    if model is not None and model not in _OPENCV_DISTORTION_MODELS + NO_DISTORTION_MODELS:
        raise ValueError(
            f"distortion_model {shown(model)} {where} is not OpenCV's pinhole distortion "
            f"({', '.join(_OPENCV_DISTORTION_MODELS)}) nor none, which this reader takes"
        )


def _require_no_coefficients(model: Any, dists: tuple, where: str) -> None:
    """ValueError when a ``distortion_model`` of no distortion (:data:`NO_DISTORTION_MODELS`)
    comes with non-zero coefficients: the file says two things."""
    given = [np.asarray(d, float).ravel() for d in dists if d is not None and np.any(d)]
    if model in NO_DISTORTION_MODELS and given:
        raise ValueError(
            f"distortion_model {shown(model)} {where} says no distortion, but the coefficients "
            f"{cut(str(given[0].tolist()))} are given; remove one of the two"
        )


def _opencv_matrices(path: str) -> tuple:
    storage = _open_storage(path)
    if not storage.isOpened():
        raise ValueError(f"cannot read OpenCV calibration file {path}")
    if not storage.root().isMap():
        storage.release()
        raise ValueError(f"{path} holds no named entries (expected camera_matrix: ...)")
    try:

        def matrix(*keys):
            for key in keys:
                node = storage.getNode(key)
                if not node.empty():
                    if not (node.isMap() or node.isSeq()):
                        raise ValueError(f"{key} in {path} is a scalar, not a matrix")
                    if node.isMap() and node.getNode("dt").empty():  # ROS: rows, cols, data
                        node = node.getNode("data")
                        if not node.isSeq():
                            raise ValueError(f"{key} in {path} has no dt and no list of data")
                    if node.isSeq():
                        return _sequence_values(node, f"{key} in {path}")
                    value = node.mat()
                    if value is not None:
                        return np.asarray(value, dtype=np.float64)
            return None

        K1 = matrix("camera_matrix", "cameraMatrix", "K", "M1", "K1", "camera_matrix_1")
        D1 = matrix(*_OPENCV_DISTORTION_KEYS[:_FIRST_DISTORTION_KEYS])
        K2 = matrix("M2", "K2", "camera_matrix_2")
        D2 = matrix(*_OPENCV_DISTORTION_KEYS[_FIRST_DISTORTION_KEYS:])
        _require_no_coefficients(_require_known_distortion(storage, path), (D1, D2), f"in {path}")
        width, height = (storage.getNode(key) for key in ("image_width", "image_height"))
        _require_both(("image_width", "image_height"), (width.empty(), height.empty()), path)
        size = None
        if not (width.empty() or height.empty()):
            if not all(node.isInt() or node.isReal() for node in (width, height)):
                raise ValueError(f"image_width and image_height in {path} must be numbers")
            size = _image_size(width.real(), height.real(), path)
    finally:
        storage.release()
    return K1, D1, K2, D2, size


def _sequence_values(node, where: str) -> np.ndarray:
    """The numbers of a YAML list, flat or of rows (``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``,
    as a JSON camera may give them)."""
    items = [node.at(i) for i in range(node.size())]
    if items and all(item.isSeq() for item in items):
        items = [row.at(j) for row in items for j in range(row.size())]
    if not all(item.isReal() or item.isInt() for item in items):
        raise ValueError(f"{where} must be a list of numbers, flat or of rows")
    return np.array([item.real() for item in items], dtype=np.float64)


def _require_both(keys: tuple[str, str], missing: tuple[bool, bool], where: str) -> None:
    """ValueError when a calibration names one of the image width and height ``keys`` and not
    the other: the size it states would be dropped, and a camera of other images not fitted."""
    if missing[0] != missing[1]:
        given, absent = keys if missing[1] else keys[::-1]
        raise ValueError(
            f"{where}: {given} without {absent}; give both (the size of the images the camera "
            "was calibrated on) or neither"
        )


def _image_size(width, height, where: str) -> tuple[int, int]:
    """A calibration's stated ``(width, height)``: whole numbers from 1 to 1e6 (True is none)."""
    try:
        if isinstance(width, (bool, np.bool_)) or isinstance(height, (bool, np.bool_)):
            raise TypeError("a flag is no size")
        size = float(width), float(height)
    except OverflowError:  # an integer of more digits than a float holds
        size = math.inf, math.inf
    except (TypeError, ValueError):
        raise ValueError(f"{where}: image width and height must be numbers") from None
    if not all(math.isfinite(v) and v == round(v) and 1 <= v <= 1e6 for v in size):
        raise ValueError(
            f"{where}: image width and height must be whole numbers from 1 to 1e6, got "
            f"{shown(width)} and {shown(height)}"
        )
    return int(size[0]), int(size[1])


def _colmap_camera(model: str, params: np.ndarray, where: str, size=None) -> Camera:
    counts = {
        "SIMPLE_PINHOLE": 3,
        "PINHOLE": 4,
        "SIMPLE_RADIAL": 4,
        "RADIAL": 5,
        "OPENCV": 8,
        "FULL_OPENCV": 12,
    }
    if model not in counts:
        raise ValueError(
            f"{where}: unsupported COLMAP camera model {model} (supported: {', '.join(counts)})"
        )
    if params.size != counts[model]:
        raise ValueError(f"{where}: {model} takes {counts[model]} parameters, got {params.size}")
    shift = np.array([0.0, 0.0, COLMAP_PIXEL_OFFSET, COLMAP_PIXEL_OFFSET])  # to OpenCV's pixels
    if model in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"):
        f, cx, cy = params[:3]
        K = _matrix_from_values(np.array([f, f, cx, cy]) - shift, where)
        radial = params[3:]  # k or (k1, k2): OpenCV (k1, k2, p1=0, p2=0)
        dist = np.r_[radial, np.zeros(4 - radial.size)] if radial.size else None
    else:  # OPENCV: k1 k2 p1 p2; FULL_OPENCV: k1 k2 p1 p2 k3 k4 k5 k6, OpenCV's order
        K = _matrix_from_values(params[:4] - shift, where)
        dist = params[4:] if params.size > 4 else None
    return Camera(K, as_distortion(dist, where), size)


def _read_colmap(path: str, text: str) -> list[Camera]:
    """The cameras of a COLMAP ``cameras.txt`` in the order of their ``CAMERA_ID`` (COLMAP
    writes them in any order); ValueError for an id that names two different cameras or is
    no whole number."""
    cameras, lines = {}, {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < 5:
            raise ValueError(f"{path}:{number}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...")
        where = f"{path}:{number}"
        params = _numbers(" ".join(parts[4:]), f"{where}: PARAMS")
        size = _image_size(parts[2], parts[3], where)
        camera_id = _camera_id(parts[0], where)
        camera = _colmap_camera(parts[1].upper(), params, where, size)
        if camera_id in cameras and not _same_camera(camera, cameras[camera_id]):
            raise ValueError(
                f"{where}: camera {camera_id} is described otherwise on line "
                f"{lines[camera_id]}; each CAMERA_ID names one camera"
            )
        cameras[camera_id], lines[camera_id] = camera, lines.get(camera_id, number)
    if not cameras:
        raise ValueError(f"no camera in {path}")
    return [cameras[camera_id] for camera_id in sorted(cameras)]


def _camera_id(text: str, where: str) -> int:
    """A COLMAP ``CAMERA_ID``: a whole number >= 0 (COLMAP's are unsigned 32-bit)."""
    if not text.isascii() or not text.isdigit() or int(text) > 2**32 - 1:
        raise ValueError(f"{where}: CAMERA_ID must be a whole number >= 0, got {shown(text)}")
    return int(text)


_JSON_DISTORTION_KEYS = ("dist", "distortion", "dist_coeffs", "distortion_coeffs")
_JSON_NUMBER_KEYS = ("K", "camera_matrix", "fx", "fy", "cx", "cy", "f", *_JSON_DISTORTION_KEYS,
                     "width", "height")  # fmt: skip
_JSON_RIG_KEYS = ("K1", "K2", "dist1", "dist2", "width", "height")


def _require_known_keys(entry: dict, known: tuple[str, ...], where: str) -> None:
    """ValueError naming a key of ``entry`` outside ``known`` whose value is not text: the
    reader would drop it, and with it a distortion (``D``, ``k1``) or an image size
    (``image_size``) the file gives. Text (a name, a note) is left to the reader."""
    unknown = [key for key, value in entry.items()
               if key not in known and not isinstance(value, (str, type(None)))]  # fmt: skip
    if unknown:
        raise ValueError(
            f"{where}: unknown key {shown(unknown[0])}, which would be ignored; the keys read "
            f"are {', '.join(known)}"
        )


def _require_no_booleans(value: Any, where: str, key: str = "") -> None:
    """ValueError for a JSON ``true`` or ``false`` where a number belongs (numpy reads them as
    1 and 0)."""
    if isinstance(value, bool):
        raise ValueError(f"{where}: {key or 'a camera'} must be numbers, got {str(value).lower()}")
    if isinstance(value, (list, tuple)):
        for item in value:
            _require_no_booleans(item, where, key)


def _json_numbers(value: Any, where: str, key: str) -> np.ndarray:
    """``value`` of JSON ``key`` as float64; ValueError naming the key for anything else."""
    _require_no_booleans(value, where, key)
    try:
        return np.asarray(value, dtype=np.float64)
    except OverflowError:  # an integer of more digits than a float holds
        raise ValueError(f"{where}: {key} holds a number beyond the range of a float") from None
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {key} must be numbers, got {cut(json.dumps(value))}") from None


def _json_camera(entry, where: str) -> Camera:
    if isinstance(entry, (list, tuple)):
        return Camera(_matrix_from_values(_json_numbers(entry, where, "a camera"), where))
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected an object with K or fx, fy, cx, cy")
    for key in _JSON_NUMBER_KEYS:
        _require_no_booleans(entry.get(key), where, key)
    if "K" in entry or "camera_matrix" in entry:
        key = "K" if "K" in entry else "camera_matrix"
        K = _matrix_from_values(_json_numbers(entry[key], where, key), where)
    elif all(k in entry for k in ("fx", "fy", "cx", "cy")):
        values = [_json_numbers(entry[k], where, k) for k in ("fx", "fy", "cx", "cy")]
        K = _matrix_from_values(values, where)
    elif all(k in entry for k in ("f", "cx", "cy")):
        values = [_json_numbers(entry[k], where, k) for k in ("f", "f", "cx", "cy")]
        K = _matrix_from_values(values, where)
    else:
        raise ValueError(f"{where}: expected K or fx, fy, cx, cy")
    _require_known_keys(entry, _JSON_NUMBER_KEYS, where)
    _require_json_model(entry, where)
    key = next((k for k in _JSON_DISTORTION_KEYS if k in entry), None)
    dist = None if key is None or entry[key] is None else _json_numbers(entry[key], where, key)
    dist = as_distortion(dist, f"{where}: {key}")
    _require_no_coefficients(entry.get("distortion_model"), (dist,), f"in {where}")
    width, height = entry.get("width"), entry.get("height")
    _require_both(("width", "height"), (width is None, height is None), where)
    if width is None:
        return Camera(K, dist)
    return Camera(K, dist, _image_size(width, height, where))


def _require_json_model(entry: dict, where: str) -> None:
    """ValueError for a ``distortion_model`` text of ``entry`` (Kalibr's key) other than
    OpenCV's pinhole distortion."""
    model = entry.get("distortion_model")
    if isinstance(model, str):
        _require_opencv_model(model, f"in {where}")


def _object_of_unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """A JSON object as a dict; ValueError for a key given twice (JSON readers keep the last
    one, each its own way: the file says two things)."""
    data = dict(pairs)
    if len(data) < len(pairs):
        repeated = next(key for key, _ in pairs if sum(k == key for k, _ in pairs) > 1)
        raise ValueError(f"the key {shown(repeated)} is given twice in one object")
    return data


def _read_json(path: str, text: str) -> list[Camera]:
    try:
        data = json.loads(text, object_pairs_hook=_object_of_unique_keys)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path} is not valid JSON: {exc.msg} (line {exc.lineno})") from None
    except RecursionError:
        raise ValueError(f"{path} is nested too deeply to be a calibration file") from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise ValueError(f"{path} is not a calibration file: {str(exc).split(';')[0]}") from None
    try:
        if isinstance(data, dict):
            _require_json_model(data, path)
        listed = data.get("cameras") if isinstance(data, dict) else data
        if isinstance(data, dict) and "cameras" in data and not isinstance(listed, list):
            raise ValueError(f"{path}: cameras must be a list of cameras")
        if isinstance(data, dict) and "cameras" in data:
            _require_known_keys(data, ("cameras",), path)
        if (
            isinstance(data, dict)
            and "cameras" in data
            or (isinstance(data, list) and data and all(isinstance(c, dict) for c in data))
        ):
            cameras = [_json_camera(c, f"{path} camera {i + 1}") for i, c in enumerate(listed)]
        elif isinstance(data, dict) and "K1" in data:
            _require_known_keys(data, _JSON_RIG_KEYS, path)
            size = {"width": data.get("width"), "height": data.get("height"),
                    "distortion_model": data.get("distortion_model")}  # fmt: skip
            cameras = [_json_camera({"K": data["K1"], "dist": data.get("dist1"), **size}, path)]
            if "K2" in data:
                second = {"K": data["K2"], "dist": data.get("dist2"), **size}
                cameras.append(_json_camera(second, path))
        else:
            cameras = [_json_camera(data, path)]
    except (TypeError, ValueError, RecursionError) as exc:
        raise ValueError(str(exc) if path in str(exc) else f"{path}: {exc}") from None
    if not cameras:
        raise ValueError(f"no camera in {path}")
    return cameras


def read_text_file(path: str | os.PathLike, what: str) -> str:
    """The text of ``path`` as UTF-8, a byte-order mark dropped; ValueError naming ``what`` and
    the file when it cannot be read or holds other bytes (Python's decoding error alone named
    neither what was read nor that it was no text); a NUL byte, which no text holds, is named
    with its line (a name holding it reached the file system as 'embedded null byte'). A
    ``path`` that is no path is a TypeError; one that is no regular file (a FIFO, whose reader
    would wait for a writer) a ValueError."""
    from .images import file_mode

    if not stat.S_ISREG(file_mode(path, what)):
        raise ValueError(f"{what} {os.fspath(path)} is not a regular file")
    try:
        with open(path, encoding="utf-8-sig") as handle:
            text = handle.read()
    except UnicodeDecodeError as exc:
        utf16 = exc.object.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
        binary = b"\x00" in exc.object and not utf16
        hint = "a binary file, such as an image?" if binary else "save it as UTF-8"
        kind = "UTF-16 text, not UTF-8" if utf16 else "not UTF-8 text"
        raise ValueError(
            f"{what} {path} is {kind} (byte 0x{exc.object[exc.start]:02x}): {hint}"
        ) from None
    except OSError as exc:
        raise ValueError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise ValueError(f"{what} {path} is not text: line {line} holds a NUL byte")
    return text


def load_calibration(path: str | os.PathLike) -> list[Camera]:
    """Cameras described by a calibration file: one (shared) or two (image 1, image 2).

    The format follows the extension: ``.yml``/``.yaml``/``.xml`` OpenCV FileStorage, ``.json``
    (OpenCV FileStorage too when its matrices are ``opencv-matrix`` objects), anything else a
    COLMAP ``cameras.txt``, or, when it holds numbers only, the 9 entries of ``K`` (as
    ``numpy.savetxt`` writes it) or ``fx fy cx cy``. A JSON key the reader does not know is
    refused unless it holds text.
    """
    from .images import file_mode

    path = os.fspath(as_path(path, "path"))
    if not stat.S_ISREG(file_mode(path, "calibration file")):  # a FIFO would block the reader
        raise ValueError(f"calibration file {path} is not a regular file")
    extension = os.path.splitext(path)[1].lower()
    if extension in (".yml", ".yaml", ".xml"):
        return _read_opencv(path)
    text = read_text_file(path, "calibration file")
    if not text.strip():  # JSON's reader said "Expecting value"
        raise ValueError(f"calibration file {path} is empty")
    if '"opencv-matrix"' in text:  # cv2.FileStorage's JSON, as calibrateCamera's YAML
        return _read_opencv(path)
    plain = _read_plain_matrix(path, text) if extension != ".json" else None
    if plain is not None:
        return [plain]
    if extension == ".json" or text.lstrip().startswith(("{", "[")):
        return _one_or_two(_read_json(path, text), path)
    return _one_or_two(_read_colmap(path, text), path)


def _read_plain_matrix(path: str, text: str) -> Camera | None:
    """The camera of a text file holding numbers only, as ``numpy.savetxt`` writes ``K``: its
    9 entries (or ``fx fy cx cy``), read as ``--K`` reads them, ``#`` lines left out; None
    for a text with any other word (a COLMAP ``cameras.txt`` names its camera models)."""
    body = " ".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    fields = [p for p in re.split(r"[,\s;\[\]()]+", body) if p]
    if not fields or not all(_is_number(field) for field in fields):
        return None
    return Camera(parse_intrinsics(body, f"camera matrix in {path}"))


def _one_or_two(cameras: list[Camera], path: str) -> list[Camera]:
    """The cameras of a file, which must be one (shared) or two (image 1, image 2): a file of
    more cannot say which is whose, unless they are all the same camera."""
    first = cameras[0]
    if all(_same_camera(first, camera) for camera in cameras[1:]):
        return [first]
    if len(cameras) > 2:
        raise ValueError(
            f"{path} describes {len(cameras)} different cameras; give a file of one camera "
            "(both images) or two (image 1, image 2)"
        )
    return cameras


def _same_camera(a: Camera, b: Camera) -> bool:
    if (a.dist is None) != (b.dist is None):
        return False
    same_dist = a.dist is None or np.array_equal(a.dist, b.dist)
    return np.array_equal(a.K, b.K) and same_dist and a.image_size == b.image_size


TURNED_CENTRE_TOLERANCE = 0.02
"""Distance, as a fraction of the larger image side, within which a principal point counts as
the centre of the image turned a quarter (:func:`implausible_intrinsics`)."""


def _at_turned_centre(cx: float, cy: float, width: int, height: int) -> bool:
    tolerance = TURNED_CENTRE_TOLERANCE * max(width, height)
    turned = math.hypot(cx - height / 2, cy - width / 2)
    centre = math.hypot(cx - width / 2, cy - height / 2)
    return turned <= tolerance < centre - turned


def implausible_intrinsics(
    K: Any, size: tuple[int, int] | None, name: str = "--K", exif_turned: bool = False
) -> str | None:
    """A warning when ``K`` does not fit an image of ``size`` (width, height), else None.

    Plausible: focal lengths within 0.1 to 10 times the larger image side and the principal
    point inside the image, and not at the centre of the image turned a quarter, within
    :data:`TURNED_CENTRE_TOLERANCE` of the larger side and closer to it than to the centre.
    ``exif_turned``: the image was turned upright by its EXIF orientation, and the warning
    then names that likely cause (a camera matrix of the stored pixels). A ``K`` that is no
    camera matrix or a ``size`` that is no image size is a ValueError or TypeError.
    """
    K = as_camera_matrix(K, name)
    if size is None:
        return None
    width, height = as_image_size(size, "size")
    fx, fy, cx, cy = float(K[0][0]), float(K[1][1]), float(K[0][2]), float(K[1][2])
    side = max(width, height)
    problems = []
    if not all(0.1 * side <= f <= 10.0 * side for f in (fx, fy)):
        problems.append(
            f"focal length fx={fx:g} fy={fy:g} px is outside 0.1..10 x {side} px"
            + _normalised_hint(fx, fy, cx, cy, width, height)
        )
    if not (0.0 <= cx <= width and 0.0 <= cy <= height):
        problems.append(f"principal point ({cx:g}, {cy:g}) is outside the {width}x{height} image")
    elif _at_turned_centre(cx, cy, width, height):
        cause = (
            "a camera for the pixels as stored, where the EXIF orientation turns the image "
            "upright (--no-exif-orientation reads them as stored)?"
            if exif_turned
            else "a camera of the image turned a quarter?"
        )
        problems.append(
            f"principal point ({cx:g}, {cy:g}) is the centre of a {height}x{width} image: {cause}"
        )
    if not problems:
        return None
    return f"{name} looks implausible for a {width}x{height} image: " + "; ".join(problems)


def _normalised_hint(fx: float, fy: float, cx: float, cy: float, width: int, height: int) -> str:
    """The pixel values of intrinsics some datasets give in units of the image size (``fx`` and
    ``cx`` over the width, ``fy`` and ``cy`` over the height), when the focal lengths are below
    a pixel's scale and the principal point lies inside the unit square; empty otherwise."""
    if not (0.0 < cx < 1.0 and 0.0 < cy < 1.0 and 0.0 < fx < 10.0 and 0.0 < fy < 10.0):
        return ""
    pixels = f"{fx * width:g},{fy * height:g},{cx * width:g},{cy * height:g}"
    return f" (in units of the image size? in pixels fx,fy,cx,cy are {pixels})"


class ImplausibleCameraWarning(UserWarning):
    """A camera matrix that does not fit its image (:func:`implausible_intrinsics`)."""


def warn_implausible(
    K: np.ndarray, image_shape: tuple[int, ...], name: str, stacklevel: int = 1
) -> None:
    """Warn with :class:`ImplausibleCameraWarning` when ``K`` does not fit an image of
    ``image_shape`` (rows, columns, ...): a camera of another image size or of the image turned
    a quarter gives a confident wrong pose. ``stacklevel`` counts from the caller, as in
    :func:`warnings.warn`."""
    if isinstance(image_shape, (str, bytes)) or len(np.shape(image_shape)) != 1 or not (
        2 <= len(image_shape) <= 3
    ):
        raise TypeError(f"image_shape must be an image's shape (rows, columns[, channels]), "
                        f"got {shown(image_shape)}")  # fmt: skip
    size = as_image_size((image_shape[1], image_shape[0]), "image_shape")
    message = implausible_intrinsics(K, size, name)
    if message is not None:
        warnings.warn(message, ImplausibleCameraWarning, stacklevel=stacklevel + 1)


def camera_from_exif(path: str | os.PathLike, exif_orientation: bool = True) -> tuple[Camera, bool]:
    """A camera guessed from an image's EXIF focal length, centred principal point.

    The camera is that of the image as :func:`ppo_cv.images.load_image` (OpenCV) decodes it:
    upright when the EXIF orientation turns the stored pixels by a quarter (a photo taken with
    the camera held upright), where COLMAP's guess describes the stored pixels (its principal
    point then lies at ``(h / 2, w / 2)`` of the upright image). ``exif_orientation=False``
    gives the camera of the stored pixels, as ``load_image(..., exif_orientation=False)``
    shows them.

    The focal length is pycolmap's reading of the EXIF (``FocalLengthIn35mmFilm`` times the
    image diagonal over the 35 mm frame's, else ``FocalLength`` times
    ``FocalPlaneXResolution``), scaled to a resized copy by :func:`exif_focal_scale`.

    Returns
    -------
    camera : Camera
    from_exif : bool
        False when the image has no usable EXIF focal length: the focal length is then COLMAP's
        default guess, 1.2 times the larger image side. A focal length whose field of view
        lies outside :data:`EXIF_FIELD_RANGE_DEG` is not used, with an
        :class:`ImplausibleCameraWarning` saying so.

    Raises
    ------
    ValueError
        Naming the file: missing, a folder or other non-regular file, above the pixel limit,
        or not a readable image (:func:`ppo_cv.images.check_decodes`).
    """
    import pycolmap

    from .images import check_decodes, decoded_transposed, exif_layout

    as_path(path, "path")
    as_flag(exif_orientation, "exif_orientation")
    check_decodes(path)  # pycolmap guessed a camera for a damaged image, after libpng's errors
    camera = pycolmap.infer_camera_from_image(os.fspath(path))
    width, height = int(camera.width), int(camera.height)
    K = np.asarray(camera.calibration_matrix(), dtype=np.float64)
    from_exif = bool(camera.has_prior_focal_length)
    if from_exif:
        focal, doubt = fitted_exif_focal(K[0, 0], exif_layout(path), (width, height))
        K[[0, 1], [0, 1]], from_exif = focal, doubt is None
        if doubt is not None:
            warnings.warn(f"{os.fspath(path)}: {doubt}", ImplausibleCameraWarning, stacklevel=2)
    if exif_orientation and decoded_transposed(path, width, height):
        K = K[[1, 0, 2]][:, [1, 0, 2]]
    return Camera(_matrix_from_values(K, "EXIF camera")), from_exif


def exif_focal_scale(layout: Any, size: tuple[int, int]) -> float:
    """The factor that takes the focal length pycolmap reads from an image's EXIF to the image.

    pycolmap's focal length in pixels from ``FocalLength`` (mm) times ``FocalPlaneXResolution``
    (pixels per mm of the sensor) is in the pixels the camera wrote. A copy resized later (a
    phone's sharing at 1600 px, a download for the web) keeps those tags and the size the
    camera wrote, ``PixelXDimension`` x ``PixelYDimension``: its focal length is that one times
    its size over the recorded size (a 4000 px photo shared at 1600 px: 0.4; unscaled, the field
    of view came out 2.5 times too narrow). A resizer that rewrites those two to the copy's own
    size leaves the interoperability tags' ``RelatedImageWidth`` x ``RelatedImageLength``, the
    size of the file the camera wrote: the larger of the two sizes is the camera's
    (``layout.camera_size``; a Canon PowerShot S45's 2272 x 1704 photo shared at 720 x 540 with
    its own size in ``PixelXDimension``: 0.317, where 1 left its focal length 3.2 times too
    long). The factor is 1 when

    - the EXIF records no size, or the image's own in both places;
    - it has a 35 mm equivalent (``FocalLengthIn35mmFilm``), which pycolmap reads first and
      multiplies by the image's own diagonal: a resized copy keeps the ratio of focal length to
      diagonal, so this focal length fits it as it is;
    - it has no ``FocalPlaneXResolution`` with a unit of length
      (``layout.sensor_resolution``): pycolmap then takes the sensor's width from its table of
      cameras and multiplies by the image's own size, which fits a resized copy as it is;
    - the recorded size has another aspect ratio (beyond :data:`ASPECT_TOLERANCE`): a crop,
      whose pixels are the camera's unless it was resized too, which no tag tells.

    Parameters
    ----------
    layout : ppo_cv.images.ExifLayout
        The image's EXIF (:func:`ppo_cv.images.exif_layout`).
    size : tuple of int
        ``(width, height)`` of the image, pixels, either way round: the recorded size is
        compared both ways (a copy whose pixels were turned upright).

    Returns
    -------
    float
        The ratio of the image's larger side to the recorded larger side, or 1.
    """
    from .images import ExifLayout

    require_instance(layout, ExifLayout, "layout", " (ppo_cv.images.exif_layout(path))")
    if layout.camera_size is None or not layout.focal_in_recorded_pixels:
        return 1.0
    scale = resize_scale(layout.camera_size, size)
    return 1.0 if scale is None else scale


def fitted_exif_focal(focal: float, layout: Any, size: tuple[int, int]) -> tuple[float, str | None]:
    """The focal length (pixels) pycolmap read from an image's EXIF, ``focal``, fitted to the
    image of ``size`` (width, height) and EXIF ``layout`` (:func:`ppo_cv.images.exif_layout`):
    scaled to a resized copy (:func:`exif_focal_scale`), or, where that is none
    (:func:`unusable_exif_focal`), COLMAP's guess for an image without one
    (:data:`GUESSED_FOCAL_FACTOR` times its larger side); with why it was replaced, None when
    it is the EXIF's. ValueError or TypeError naming an argument of another kind."""
    size = as_image_size(size, "size")
    focal = as_number(focal, "focal") * exif_focal_scale(layout, size)
    doubt = unusable_exif_focal(focal, max(size))
    return (focal, None) if doubt is None else (GUESSED_FOCAL_FACTOR * max(size), doubt)


def resize_scale(original: tuple[int, int], size: tuple[int, int]) -> float | None:
    """The factor by which an image of ``size`` is a resized copy of one of ``original`` size
    (both ``(width, height)``, compared either way round): the ratio of their larger sides, or
    None when their aspect ratios differ by more than :data:`ASPECT_TOLERANCE` (a crop).

    >>> resize_scale((4000, 3000), (1200, 1600))
    0.4
    """
    original, size = as_image_size(original, "original"), as_image_size(size, "size")
    (short, long), (original_short, original_long) = sorted(size), sorted(original)
    scale_short, scale_long = short / original_short, long / original_long
    return float(scale_long) if _one_scale(scale_short, scale_long) else None


def _one_scale(sx: float, sy: float) -> bool:
    """Whether scales ``sx`` and ``sy`` along two axes agree within :data:`ASPECT_TOLERANCE`
    (of the larger): a resize that keeps the aspect ratio."""
    return abs(sx - sy) <= ASPECT_TOLERANCE * max(sx, sy)


GUESSED_FOCAL_FACTOR = 1.2
"""The focal length of an image without a usable EXIF one, in its larger side: COLMAP's guess
(``pycolmap.ImageReaderOptions().default_focal_length_factor``)."""

EXIF_FIELD_RANGE_DEG = (0.5, 150.0)
"""Fields of view across the larger image side outside which an EXIF focal length is no focal
length (:func:`camera_from_exif`): 0.5 degrees is narrower than the longest camera zoom (a
3000 mm equivalent gives 0.66), 150 degrees wider than any rectilinear lens (a 10 mm
equivalent gives 120); beyond are placeholders such as 65535 mm (0.03 degrees)."""

EXIF_PLAUSIBLE_FIELD_DEG = (15.0, 120.0)
"""Horizontal fields of view an EXIF focal length that is used may imply without a warning
(``ppo_cv.cli.common.exif_camera``): 15 degrees is a 135 mm lens on a full-frame camera, about
a phone's longest telephoto; 120 degrees is a 10 mm lens, beyond which lenses are fisheyes
that a pinhole camera with a centred principal point does not describe. Outside, the focal
length is more likely that of another image size (a resized or cropped copy). Within
:data:`EXIF_FIELD_RANGE_DEG`, outside which the focal length is not used at all."""


def field_of_view_deg(focal: float, extent: float) -> float:
    """Field of view (degrees) across ``extent`` pixels centred on the principal point of a
    pinhole camera of focal length ``focal`` pixels: ``2 atan(extent / (2 focal))``.

    >>> round(field_of_view_deg(500.0, 1000.0), 6)
    90.0

    ``focal`` must be a number > 0 and ``extent`` one >= 0 (ValueError or TypeError naming
    it): a negative focal length gave a field beyond 180 degrees, a huge integer an
    OverflowError.
    """
    return _field_deg(as_positive(focal, "focal"), as_nonnegative(extent, "extent"))


def _field_deg(focal: float, extent: float) -> float:
    """:func:`field_of_view_deg`, unchecked (a focal length of 0 gives 180 degrees)."""
    return math.degrees(2.0 * math.atan2(extent, 2.0 * focal))


def unusable_exif_focal(focal: float, side: int) -> str | None:
    """Why an EXIF focal length is not used, or None when it is.

    Parameters
    ----------
    focal : float
        The focal length the EXIF gives, pixels.
    side : int
        The larger side of the image, pixels.

    Returns
    -------
    str or None
        A sentence for a warning when the field of view across ``side`` lies outside
        :data:`EXIF_FIELD_RANGE_DEG` (the focal length is then replaced by COLMAP's default
        guess, 1.2 times ``side``).
    """
    as_positive(side, "side")
    field = _field_deg(as_number(focal, "focal"), side)  # an EXIF focal length may be 0
    low, high = EXIF_FIELD_RANGE_DEG
    if low <= field <= high:
        return None
    return (
        f"the EXIF focal length f={focal:.1f} px gives a {field:.3g} deg field of view across "
        f"{side} px, outside {low:g}..{high:g} deg (a placeholder?): not used, guessing "
        f"f={GUESSED_FOCAL_FACTOR * side:.1f} px ({GUESSED_FOCAL_FACTOR:g} x image size) as "
        "without one; pass --K or --calib"
    )


def fit_to_image(
    camera: Camera, size: tuple[int, int], name: str, image: str = "the image",
    turned: bool = False,
) -> tuple[Camera, str | None]:  # fmt: skip
    """``camera`` for an image of ``size`` (width, height), and a note when it was scaled.

    A camera without a stated image size, or calibrated on images of this size, is returned
    as it is. An image of another size but the same aspect ratio (within
    :data:`ASPECT_TOLERANCE`) is a resized copy: ``K`` is scaled per axis about the pixel
    centres (``c' = (c + 0.5) s - 0.5``); distortion, on normalized coordinates, is unchanged.

    Parameters
    ----------
    camera : Camera
    size : tuple of int
        ``(width, height)`` of the image, pixels.
    name, image : str
        The calibration and the image, as messages name them.
    turned : bool
        The image was turned upright by its EXIF orientation (``size`` is the upright one): a
        calibration of the pixels as stored is then refused with that cause and the way out.

    Returns
    -------
    camera : Camera
        With ``image_size`` set to ``size``.
    note : str or None
        What was scaled, for a warning; None when nothing was.

    Raises
    ------
    ValueError
        Naming ``name`` and both sizes, when the aspect ratios differ: a cropped or rotated
        image, for which no scaling of ``K`` is right; or a ``size`` that is not two whole
        numbers >= 1 (TypeError for no pair, or ``camera`` not a :class:`Camera`).
    """
    require_instance(camera, Camera, "camera")
    size = as_image_size(size, "size")
    as_flag(turned, "turned")
    if camera.image_size is None or tuple(camera.image_size) == tuple(size):
        return camera, None
    (width, height), (calibrated_width, calibrated_height) = size, camera.image_size
    sx, sy = width / calibrated_width, height / calibrated_height
    if not _one_scale(sx, sy):
        if turned and _one_scale(height / calibrated_width, width / calibrated_height):
            raise ValueError(
                f"{name} describes a camera of {calibrated_width}x{calibrated_height} images, "
                f"the pixels of {image} as stored ({height}x{width}), but its EXIF orientation "
                f"turns them upright to {width}x{height}: --no-exif-orientation (or "
                "exif_orientation=False) reads them as stored, as the calibration describes them"
            )
        raise ValueError(
            f"{name} describes a camera of {calibrated_width}x{calibrated_height} images but "
            f"{image} is {width}x{height} pixels, another aspect ratio (cropped or turned?): "
            "no scaling of the camera matrix fits it"
        )
    K = camera.K.copy()
    K[0, [0, 1]] *= sx
    K[1, 1] *= sy
    K[0, 2] = (camera.K[0, 2] + 0.5) * sx - 0.5
    K[1, 2] = (camera.K[1, 2] + 0.5) * sy - 0.5
    note = (
        f"{name} describes a camera of {calibrated_width}x{calibrated_height} images: its "
        f"camera matrix scaled by {sx:.4g} to {image}, {width}x{height} pixels"
    )
    return replace(camera, K=K, image_size=(width, height)), note
