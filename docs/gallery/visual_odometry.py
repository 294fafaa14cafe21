"""Visual odometry over a pan and a walk
=====================================

A short sequence of one rendered room: the camera first pans on a tripod (pure rotations),
then walks sideways. Each consecutive pair goes through ``ppo_cv.estimate_pair``; the relative
rotations are chained into the camera's orientation, and every step says whether it was a pure
rotation, in which case its translation direction is not determined by the images and is
left out. The camera poses come from ``ppo_cv.data_gen.tripod_then_move_poses``, so each step
and the chained orientation are compared with the exact ground truth.
"""

import numpy as np

import ppo_cv
from ppo_cv.data_gen import make_scene, render_view, tripod_then_move_poses


def angle_deg(R):
    """Rotation angle of R, degrees."""
    return np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


width, height = 480, 360
K = np.array([[0.85 * width, 0, (width - 1) / 2], [0, 0.85 * width, (height - 1) / 2], [0, 0, 1]])
scene = make_scene("clutter", seed=0)
poses = tripod_then_move_poses(n_pan=3, n_move=3)  # cam_from_world (R, t) of each view
rng = np.random.default_rng(0)
frames = []
for R, t in poses:
    image, _ = render_view(scene, K, R, t, size=(width, height), supersample=2)
    noisy = image * 255 + rng.normal(0, 1, image.shape)  # one grey level of sensor noise
    frames.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8)[..., ::-1])  # RGB -> BGR

options = ppo_cv.PairOptions(max_features=4000, seed=0)  # 4000 SIFT keypoints are plenty at 480x360
pure_steps, true_pure_steps = [], []
R_world = np.eye(3)  # chained orientation: cam_from_world, with the first view as the world
print("step  rotation  R err   PRI     motion          t dir err  chained R err")
for k in range(1, len(frames)):
    result = ppo_cv.estimate_pair(frames[k - 1], frames[k], K, options=options)
    (R_prev, t_prev), (R_next, t_next) = poses[k - 1], poses[k]
    R_true = R_next @ R_prev.T  # exact relative pose, x_k = R x_{k-1} + t
    t_true = t_next - R_true @ t_prev
    if np.linalg.norm(t_true) < 1e-12:
        true_pure_steps.append(f"{k - 1}->{k}")

    R_world = result.R @ R_world
    step_error = angle_deg(result.R.T @ R_true)
    chained_error = angle_deg(R_world.T @ R_next @ poses[0][0].T)
    if result.pure_rotation:
        motion, t_error = "pure rotation", "-"
        pure_steps.append(f"{k - 1}->{k}")
    else:
        cos = result.t @ t_true / np.linalg.norm(t_true)
        motion, t_error = "translation", f"{np.degrees(np.arccos(np.clip(cos, -1, 1))):.2f}"
    print(
        f"{k - 1}->{k}  {angle_deg(result.R):6.2f}  {step_error:6.3f}  {result.pri:.4f}  "
        f"{motion:14s}  {t_error:>9s}  {chained_error:8.3f}"
    )

print(f"pure rotations flagged at steps {' '.join(pure_steps)}; true: {' '.join(true_pure_steps)}")
print(f"chained orientation after {len(frames) - 1} steps: {chained_error:.3f} deg from the truth")
