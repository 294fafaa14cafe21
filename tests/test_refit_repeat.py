"""A photometric refit that clips no lens fit to its box is the same with ``keep_clipped``, so
the rotation choice does not repeat one that aligned no tracks (``pipeline._misses_again``)."""

import cv2
import numpy as np
import pytest

from ppo_cv.photometric import refine_rotation_photometric


def _pan(focal2_factor: float):
    """A 2 degree pan of a random texture (320x240), image 2 taken with a focal length
    ``focal2_factor`` times image 1's; the camera given for both and the rotation."""
    rng = np.random.default_rng(0)
    image1 = cv2.GaussianBlur(rng.uniform(0, 255, (240, 320)), (0, 0), 2).astype(np.uint8)
    K = np.array([[400.0, 0, 159.5], [0, 400.0, 119.5], [0, 0, 1]])
    K2 = K @ np.diag([focal2_factor, focal2_factor, 1.0])
    c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    image2 = cv2.warpPerspective(image1, K2 @ R @ np.linalg.inv(K), (320, 240))
    return image1, image2, K, R


@pytest.mark.parametrize(
    ("focal2_factor", "clipped"),
    [
        (1.0, False),  # the lens as given: every fit inside the box
        (1.12, True),  # 12 % more focal length than given, beyond the 5 % box
    ],
)
def test_keep_clipped_changes_only_refits_that_clip_a_lens_fit(focal2_factor, clipped):
    image1, image2, K, R = _pan(focal2_factor)
    calls = {False: 0, True: 0}
    refits = {}
    for keep in (False, True):

        def count(keep=keep):
            calls[keep] += 1

        refits[keep] = refine_rotation_photometric(
            image1, image2, K, K, R, keep_clipped=keep, on_clipped=count
        )
    assert (calls[False] > 0) is clipped and (calls[True] > 0) is clipped
    if not clipped:
        held, kept = refits[False], refits[True]
        assert np.array_equal(held.fit.R, kept.fit.R)
        assert np.array_equal(held.tracks.points2, kept.tracks.points2)
        assert np.array_equal(held.inliers, kept.inliers)


def test_on_clipped_must_be_callable():
    image1, image2, K, R = _pan(1.0)
    with pytest.raises(TypeError, match="on_clipped"):
        refine_rotation_photometric(image1, image2, K, K, R, on_clipped=1)


@pytest.mark.parametrize(
    "names",
    [
        ("book_DSC04228.JPG", "book_DSC04229.JPG"),
        ("bookshelf_DSC04154.JPG", "bookshelf_DSC04155.JPG"),
    ],
)
def test_the_rotation_choice_does_not_repeat_a_refit_that_aligned_nothing(
    pano_dev, names, monkeypatch
):
    """Tripod pairs called general whose first refit aligns no tracks and clips no lens fit:
    the rotation choice's refit with ``keep_clipped`` over the same search deviation would
    find none either; the pose is that of the run that repeats it, bit for bit."""
    import ppo_cv.pipeline as pipeline
    from ppo_cv import estimate_pair

    line = next(
        row.split()
        for row in (pano_dev / "pairs_with_gt.txt").read_text().splitlines()
        if row.split()[:2] == list(names)
    )
    K1, K2 = (np.array(line[i : i + 9], float).reshape(3, 3) for i in (4, 13))
    images = [cv2.imread(str(pano_dev / "images" / name)) for name in names]
    align = pipeline._align_tracks

    def run() -> tuple:
        aligned = []

        def recording(*args, keep_clipped=False, **keywords):
            found = align(*args, keep_clipped=keep_clipped, **keywords)
            aligned.append((keep_clipped, found))
            return found

        monkeypatch.setattr(pipeline, "_align_tracks", recording)
        return estimate_pair(*images, K1, K2), aligned

    result, aligned = run()
    monkeypatch.setattr(pipeline, "_misses_again", lambda state, sigma_deg: False)
    repeated, aligned_twice = run()
    assert [keep for keep, _ in aligned] == [False]
    assert [(keep, found) for keep, found in aligned_twice] == [(False, None), (True, None)]
    assert result.model == repeated.model == "general" and not result.pure_rotation
    assert np.array_equal(result.R, repeated.R) and np.array_equal(result.t, repeated.t)
    assert result.rotation_source == repeated.rotation_source
