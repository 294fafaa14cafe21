"""The pinhole camera with OpenCV's lens model: pixels to normalised points and back.

``x = K^-1 [u, v, 1]`` for a camera without distortion (:func:`ppo_cv.ppo.normalize`); with
OpenCV distortion coefficients ``dist`` the pixels are undistorted first
(``cv2.undistortPoints``) and normalised points are distorted on their way back
(``cv2.projectPoints``), the model every OpenCV calibration writes.

:func:`pixels_to_normalized` and :func:`normalized_to_pixels` are inner helpers: they take ``K``
and ``dist`` as the API has checked them (:func:`ppo_cv.checks.as_camera_matrix`,
:func:`ppo_cv.checks.as_distortion`) and check nothing themselves, since the photometric polish
calls them for every window it moves.
"""

from __future__ import annotations

import numpy as np

from . import ppo
from .checks import as_camera_matrix, as_image_size
from .features import detection_size

__all__ = ["principal_point_is_centre"]

CENTRE_TOLERANCE_PX = 0.5
"""How far from ``(w - 1) / 2`` or ``w / 2`` (likewise ``h``) a principal point may lie and still
be the image centre; the two conventions are half a pixel apart."""


def reduced_view(
    image: np.ndarray, K: np.ndarray, max_size: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """``image`` (H, W) or (H, W, C) with its longer side reduced to ``max_size`` (area
    averaging), the copy :func:`ppo_cv.features.detect_features` detects on
    (:func:`ppo_cv.features.detection_size`), and the camera matrix ``K`` (3, 3) of its
    pixels; both unchanged when ``max_size`` is None or the image no larger. Pixel centres map
    as ``u' = (u + 1/2) W' / W - 1/2`` (as :func:`ppo_cv.features.detect_features` maps its
    keypoints back), so ``K' = S K`` with ``S`` that map; distortion coefficients, which act
    on normalised points, are those of ``K``. An inner helper of the refit: it checks
    nothing.

    >>> import numpy as np
    >>> K = np.array([[1000.0, 0, 1999.5], [0, 1000.0, 1499.5], [0, 0, 1]])
    >>> small, K_small = reduced_view(np.zeros((3000, 4000), np.uint8), K, 2000)
    >>> small.shape, K_small[0].tolist(), K_small[1].tolist()
    ((1500, 2000), [500.0, 0.0, 999.5], [0.0, 500.0, 749.5])
    """
    size = detection_size(image.shape, max_size)
    if size is None:
        return image, K
    import cv2

    sx, sy = size[0] / image.shape[1], size[1] / image.shape[0]
    S = np.array([[sx, 0.0, (sx - 1.0) / 2.0], [0.0, sy, (sy - 1.0) / 2.0], [0.0, 0.0, 1.0]])
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA), S @ K


def pixels_to_normalized(points: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Pixel points (N, 2) to normalised points (N, 2), distortion ``dist`` removed.

    An inner helper that checks nothing: ``K`` and ``dist`` as checked by
    :func:`ppo_cv.checks.as_camera_matrix` and :func:`ppo_cv.checks.as_distortion` (None: no
    distortion), ``points`` finite.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if dist is None:
        return ppo._normalize(points, K)
    import cv2

    return cv2.undistortPoints(points.reshape(-1, 1, 2), K, dist).reshape(-1, 2)


def normalized_to_pixels(xy: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Normalised points (N, 2) to pixel points (N, 2) through the distortion ``dist``.

    An inner helper that checks nothing, as :func:`pixels_to_normalized`.

    Examples
    --------
    >>> K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    >>> dist = np.array([-0.1, 0.01, 0.0, 0.0])
    >>> pixels = np.array([[100.0, 50.0], [600.0, 400.0]])
    >>> back = normalized_to_pixels(pixels_to_normalized(pixels, K, dist), K, dist)
    >>> bool(np.allclose(back, pixels, atol=1e-3))
    True
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if dist is None:
        return xy @ K[:2, :2].T + K[:2, 2]
    import cv2

    rays = np.column_stack([xy, np.ones(len(xy))])
    zero = np.zeros(3)
    return cv2.projectPoints(rays, zero, zero, K, dist)[0].reshape(-1, 2)


def principal_point_is_centre(K: np.ndarray, image_size: tuple[int, int]) -> bool:
    """Whether ``K``'s principal point is the centre of a ``(width, height)`` image.

    A calibration never lands there exactly; a principal point at the centre was set, not
    measured (EXIF or stitcher focal lengths), so it may be off by a percent or two.

    Examples
    --------
    >>> K = np.array([[500.0, 0, 319.5], [0, 500.0, 240.0], [0, 0, 1]])
    >>> principal_point_is_centre(K, (640, 480))
    True
    >>> principal_point_is_centre(np.array([[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]),
    ...                           (640, 480))
    False
    """
    width, height = as_image_size(image_size, "image_size")
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    offset = np.abs(as_camera_matrix(K, "K")[:2, 2] - centre)
    return bool(np.all(offset <= CENTRE_TOLERANCE_PX + 1e-9))
