"""Choosing the initial pair of an incremental reconstruction
==========================================================

Structure from motion grows from one image pair, and a pair without parallax is a bad seed.
The pairs with the most matches are often the worst: a camera panning on a tripod sees nearly
the same image twice. Here a rendered sequence (a pan of three views, then three sideways
steps) goes through pycolmap's SIFT extraction and matching (``ppo_cv.sfm.prepare_database``);
``ppo_cv.sfm.score_pairs`` then ranks every verified pair by its PPO pose, rejecting pure
rotations by their PRI, and ``ppo_cv.sfm.reconstruct`` starts pycolmap's mapper from the best
pair. Files go to ``sfm_example/`` in the current directory (or the folder given as first
argument): the images, the COLMAP database and the model of the previous run are replaced.
"""

import shutil
import sys
from pathlib import Path

import numpy as np

from ppo_cv import sfm
from ppo_cv.data_gen import relative_gt_from_poses, render_tripod_then_move

folder = Path(sys.argv[1] if len(sys.argv) > 1 else "sfm_example")
images, database, model = folder / "images", folder / "database.db", folder / "model"
database.unlink(missing_ok=True)
shutil.rmtree(model, ignore_errors=True)
shutil.rmtree(images, ignore_errors=True)

names, K, poses = render_tripod_then_move(images, n_pan=3, n_move=3, size=(480, 360))
sfm.prepare_database(images, database, K=K)  # pycolmap: SIFT, exhaustive matching, verification

ranking = sfm.score_pairs(database)  # accepted pairs first, best score first
print("rank  pair                      matches  PRI     tri angle  score   verdict")
for rank, p in enumerate(ranking, 1):
    verdict = "accepted" if p.accepted else p.rejection
    print(
        f"{rank:4d}  {p.name1} {p.name2}  {p.num_matches:7d}  {p.pri:.4f}  "
        f"{p.tri_angle:6.2f} deg  {p.score:6.1f}  {verdict}"
    )

pan = [p for p in ranking if "pan" in p.name1 and "pan" in p.name2]  # tripod pairs: t = 0
counts = sorted(p.num_matches for p in pan)
print(
    f"{sum(p.pure_rotation for p in pan)}/{len(pan)} tripod pairs rejected as pure rotations "
    f"({counts[0]}-{counts[-1]} matches each); best initial pair: "
    f"{ranking[0].name1} {ranking[0].name2}"
)

# Grow the reconstruction from the best pair (the known intrinsics stay fixed).
result = sfm.reconstruct(database, images, fix_intrinsics=True)
sfm.write_model(result, model)
rotation_errors, _ = sfm.pose_errors(result.reconstruction, relative_gt_from_poses(names, poses))
print(
    f"registered {result.num_registered}/{result.num_images} images from "
    f"{' '.join(result.initial_pair)}, {result.num_points3D} points, reprojection error "
    f"{result.mean_reprojection_error:.3f} px, median relative rotation error "
    f"{np.median(rotation_errors):.3f} deg; model in {model}"
)
