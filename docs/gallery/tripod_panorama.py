"""Tripod panorama: the rotation of a camera that only turned, to hundredths of a degree
=====================================================================================

Real panorama shots come with a focal length a few percent off, lens distortion nobody
calibrated, JPEG and exposure changes. ``ppo_cv.data_gen.make_warped_pair`` cuts such pairs
from a real photo (the demo frame shipped with the package) by an exact rotation (``t = 0``)
with those imperfections. ``estimate_pair`` flags a pure rotation, then refits its rotation on
windows of the images aligned by intensity (``ppo_cv.photometric``), which also pins down the
focal length. The script prints, per pair, the rotation error of the feature matches alone
(``PairOptions(photometric=False)``) and of the refit, the refit's ``rotation_sigma_deg``, and
the focal scale it found against the true one; the last pair is shot again with the second
exposure 30 % darker and vignetted. A pair the decision does not flag keeps the pose of its
essential matrix and has no refit. With a hundred windows or more the refit is ten times closer
than the matches; with the 56-87 windows of pairs 2-4 its focal scale lands 0.4-0.9 % off and
its rotation a few hundredths of a degree further than the matches'.
"""

from importlib import resources

import numpy as np

import ppo_cv
from ppo_cv.data_gen import make_warped_pair

PHOTO = resources.files("ppo_cv") / "data" / "demo1.png"


def rotation_error_deg(R, R_true):
    return np.degrees(np.arccos(np.clip((np.trace(R.T @ R_true) - 1) / 2, -1, 1)))


def darker_and_vignetted(image):
    h, w = image.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    return np.clip(image * (0.7 * (1 - 0.3 * r2))[..., None], 0, 255).astype(np.uint8)


print(f"{'pair':12s}  flagged  R err matches  R err refit  R sigma  windows  focal scale (true)")
errors = {"matches": [], "refit": []}  # over the flagged pairs
pairs = [(index, make_warped_pair(seed=0, index=index, source=PHOTO)) for index in range(5)]
pairs.append(("4, exposure", pairs[-1][1]))
for name, pair in pairs:
    image1, image2 = pair.image1[..., ::-1], pair.image2[..., ::-1]  # RGB to OpenCV's BGR
    if name == "4, exposure":
        image2 = darker_and_vignetted(image2)
    K1, K2 = pair.K1_given, pair.K2_given
    result = ppo_cv.estimate_pair(image1, image2, K1, K2)
    matches = ppo_cv.estimate_pair(
        image1, image2, K1, K2, options=ppo_cv.PairOptions(photometric=False)
    )
    err_matches = rotation_error_deg(matches.R, pair.R)
    err_refit = rotation_error_deg(result.R, pair.R)
    true_scale = pair.K1_given[0, 0] / pair.K1[0, 0]
    if result.pure_rotation:
        errors["matches"].append(err_matches)
        errors["refit"].append(err_refit)
        sigma = f"{result.uncertainty.rotation_sigma_deg:7.3f}"
        scale = f"{result.lens.focal_scale:.4f}"
    else:
        sigma, scale = f"{'-':>7s}", f"{'-':>6s}"
    print(
        f"{name!s:12s}  {result.pure_rotation!s:7s}  {err_matches:13.3f}  {err_refit:11.3f}"
        f"  {sigma}  {result.uncertainty.rotation_tracks:7d}  {scale} ({true_scale:.4f})"
    )

print(
    f"{len(errors['refit'])} of {len(pairs)} flagged; median rotation error over them: "
    f"matches {np.median(errors['matches']):.3f} deg, refit {np.median(errors['refit']):.3f} deg"
)
