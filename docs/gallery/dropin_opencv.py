"""Drop-in replacement for ``cv2.recoverPose``
===========================================

An ordinary OpenCV two-view snippet (SIFT, Lowe's ratio test, ``cv2.findEssentialMat`` with
USAC MAGSAC++, then ``cv2.recoverPose``) is run twice on the demo pair shipped with ppo-cv, two
frames of the TUM RGB-D benchmark. The second time it runs inside ``ppo_cv.installed()``, which
puts the PPO pose identification in place of OpenCV's cheirality test for the duration of the
block: the snippet itself is unchanged. Both poses are printed with their angular error against
the pair's reference pose.
"""

import json
from importlib.resources import files

import cv2
import numpy as np

import ppo_cv

data = files("ppo_cv.data")
meta = json.loads(data.joinpath("demo.json").read_text())
fx, fy, cx, cy = meta["intrinsics"]
K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
image1 = cv2.imread(str(data.joinpath(meta["image1"])), cv2.IMREAD_GRAYSCALE)
image2 = cv2.imread(str(data.joinpath(meta["image2"])), cv2.IMREAD_GRAYSCALE)


def two_view_pose(image1, image2, K):
    """The existing OpenCV code: nothing in here knows about ppo-cv."""
    sift = cv2.SIFT_create(nfeatures=4000)
    kp1, des1 = sift.detectAndCompute(image1, None)
    kp2, des2 = sift.detectAndCompute(image2, None)
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(des1, des2, k=2)
    good = [m for m, n in knn if m.distance < 0.8 * n.distance]
    pts1 = np.float64([kp1[m.queryIdx].pt for m in good])
    pts2 = np.float64([kp2[m.trainIdx].pt for m in good])
    E, mask = cv2.findEssentialMat(pts1, pts2, K, cv2.USAC_MAGSAC, 0.999, 1.0)
    count, R, t, mask = cv2.recoverPose(E, pts1, pts2, K, mask=mask)
    return count, R, t.ravel(), len(good)


def angle_deg(a, b):
    """Angle between two vectors, degrees."""
    return np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def rotation_error_deg(R, R_ref):
    return np.degrees(np.arccos(np.clip((np.trace(R.T @ R_ref) - 1) / 2, -1, 1)))


R_ref, t_ref = np.array(meta["reference_R"]), np.array(meta["reference_t"])
cv2.setRNGSeed(0)  # same seed for both runs: same E, same RANSAC inliers
opencv = two_view_pose(image1, image2, K)
cv2.setRNGSeed(0)
with ppo_cv.installed():  # cv2.recoverPose is ppo_cv.recoverPose inside this block only
    print(f"inside the block, PPO installed: {ppo_cv.is_installed()}")
    ppo = two_view_pose(image1, image2, K)
print(f"after the block, PPO installed: {ppo_cv.is_installed()}")

print(f"{opencv[3]} matches after the ratio test; errors against the reference pose:")
for name, (count, R, t, _) in (("OpenCV cheirality", opencv), ("ppo_cv PPO", ppo)):
    rvec = np.degrees(cv2.Rodrigues(R)[0].ravel())
    print(
        f"{name:18s} inliers {count:4d}  rotation vector (deg) {np.round(rvec, 2)}  "
        f"t {np.round(t, 3)}  R err {rotation_error_deg(R, R_ref):.2f} deg  "
        f"t err {angle_deg(t, t_ref):.2f} deg"
    )
