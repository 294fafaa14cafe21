"""Synthetic two-view data with exact ground truth (installed as ``ppo_cv.data_gen``).

* :func:`paper_protocol`: the point-level Monte-Carlo generator of the paper (Section 5).
* :func:`render_pair` / :func:`make_pair`: ray-cast image pairs of textured planar scenes with
  exact ``K1, K2, R, t`` (``x2 = R x1 + t``) and the depth map of view 1.
* :class:`Imperfections` / :data:`REAL_PHOTO`, :data:`NARROW_LENS`, :data:`LONG_ZOOM`:
  unmodelled distortion, a focal length a few percent off, a narrow field of view, JPEG, noise
  and blur, for :func:`make_pair`.
* :func:`warp_pair` / :func:`make_warped_pair`: exact pure rotations of real photos.
* :func:`make_dataset`: a directory of pairs with a freiburg-style pairs file.
"""

from __future__ import annotations

import importlib

_SUBMODULE = {
    "DEFAULT_SCENE": "motion",
    "DrawnImperfections": "imperfect",
    "LONG_ZOOM": "imperfect",
    "NARROW_LENS": "imperfect",
    "division_dist": "imperfect",
    "Imperfections": "imperfect",
    "REAL_PHOTO": "imperfect",
    "given_intrinsics": "imperfect",
    "jpeg_roundtrip": "imperfect",
    "expose": "imperfect",
    "make_warped_pair": "warp",
    "median_depth": "render",
    "source_photos": "warp",
    "warp_pair": "warp",
    "MOTIONS": "names",
    "Motion": "motion",
    "PAIRS_FILE": "io",
    "PAPER_K": "protocol",
    "PAPER_T_MAX": "protocol",
    "ProtocolSample": "protocol",
    "Quad": "scenes",
    "RenderedPair": "render",
    "SCENES": "names",
    "Scene": "scenes",
    "Texture": "textures",
    "box_quads": "scenes",
    "checker_plane": "scenes",
    "checker_texture": "textures",
    "euler_to_matrix": "protocol",
    "intrinsics": "motion",
    "look_at": "motion",
    "make_dataset": "io",
    "make_pair": "io",
    "make_scene": "scenes",
    "texture_set": "scenes",
    "TEXTURE_SETS": "textures",
    "pairs_line": "io",
    "paper_protocol": "protocol",
    "photo_texture": "textures",
    "project_points": "render",
    "read_pairs": "io",
    "relative_gt_from_poses": "multiview",
    "render_pair": "render",
    "render_tripod_then_move": "multiview",
    "render_view": "render",
    "sample_motion": "motion",
    "tripod_then_move_poses": "multiview",
    "write_pair": "io",
}
"""Public name -> submodule that defines it; submodules load on first use (PEP 562)."""


def __getattr__(name: str):
    if name not in _SUBMODULE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_SUBMODULE[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "DEFAULT_SCENE",
    "REAL_PHOTO",
    "NARROW_LENS",
    "LONG_ZOOM",
    "DrawnImperfections",
    "division_dist",
    "Imperfections",
    "given_intrinsics",
    "expose",
    "jpeg_roundtrip",
    "make_warped_pair",
    "median_depth",
    "source_photos",
    "warp_pair",
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
    "texture_set",
    "TEXTURE_SETS",
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
