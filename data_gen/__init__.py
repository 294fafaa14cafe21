"""Synthetic two-view data with exact ground truth (installed as ``ppo_cv.data_gen``).

* :func:`paper_protocol`: the point-level Monte-Carlo generator of the paper (Section 5).
* :func:`render_pair` / :func:`make_pair`: ray-cast image pairs of textured planar scenes with
  exact ``K1, K2, R, t`` (``x2 = R x1 + t``) and the depth map of view 1.
* :func:`make_dataset`: a directory of pairs with a freiburg-style pairs file.
"""

from .io import PAIRS_FILE, make_dataset, make_pair, pairs_line, read_pairs, write_pair
from .motion import DEFAULT_SCENE, MOTIONS, Motion, intrinsics, look_at, sample_motion
from .multiview import relative_gt_from_poses, render_tripod_then_move, tripod_then_move_poses
from .protocol import PAPER_K, PAPER_T_MAX, ProtocolSample, euler_to_matrix, paper_protocol
from .render import RenderedPair, project_points, render_pair, render_view
from .scenes import SCENES, Quad, Scene, box_quads, checker_plane, make_scene
from .textures import Texture, checker_texture, photo_texture

__all__ = [
    "DEFAULT_SCENE",
    "MOTIONS",
    "PAIRS_FILE",
    "PAPER_K",
    "PAPER_T_MAX",
    "SCENES",
    "Motion",
    "ProtocolSample",
    "Quad",
    "RenderedPair",
    "Scene",
    "Texture",
    "box_quads",
    "checker_plane",
    "checker_texture",
    "euler_to_matrix",
    "intrinsics",
    "look_at",
    "make_dataset",
    "make_pair",
    "make_scene",
    "pairs_line",
    "paper_protocol",
    "photo_texture",
    "project_points",
    "read_pairs",
    "relative_gt_from_poses",
    "render_tripod_then_move",
    "render_pair",
    "render_view",
    "sample_motion",
    "tripod_then_move_poses",
    "write_pair",
]
