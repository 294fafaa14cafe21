"""ppo_cv.camera: its public function checks K and the image size at the boundary; the point
conversions are inner helpers (left out of ``__all__``) that the photometric polish calls per
window."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv import camera

K = np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]])
NAN_K = np.where(np.eye(3, dtype=bool), np.nan, K)

BAD = {  # name: (K, image_size, error, words)
    "K_none": (None, (640, 480), TypeError, "K"),
    "K_nan": (NAN_K, (640, 480), ValueError, "K"),
    "K_2x3": (K[:2], (640, 480), ValueError, "K must be a 3x3"),
    "K_flipped": (-K, (640, 480), ValueError, "K"),
    "size_one_side": (K, (640,), TypeError, "image_size"),
    "size_text": (K, "640x480", TypeError, "image_size"),
    "size_fractional": (K, (640.5, 480), ValueError, "image_size width"),
    "size_zero": (K, (640, 0), ValueError, "image_size height"),
}


def test_only_the_checked_function_is_public():
    assert camera.__all__ == ["principal_point_is_centre"]


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_principal_point_is_centre_refuses_what_is_no_camera_or_size(case):
    K_given, size, error, words = BAD[case]
    with pytest.raises(error, match=words):
        camera.principal_point_is_centre(K_given, size)


@pytest.mark.parametrize("size, centre", [((640, 480), True), ((641, 480), True),
                                          ((800, 480), False), ((640.0, 479.0), True)])  # fmt: skip
def test_principal_point_is_centre_reads_either_convention(size, centre):
    assert camera.principal_point_is_centre(K, size) is centre
