"""Names of the motion presets and scenes, importable without the renderer."""

from __future__ import annotations

__all__ = ["MOTIONS", "SCENES"]

MOTIONS = (
    "general",
    "pure-rotation",
    "small-parallax",
    "forward",
    "planar",
    "panorama",
    "tiny-baseline",
)
"""Names accepted by :func:`ppo_cv.data_gen.motion.sample_motion`."""

SCENES = ("room", "clutter", "plane", "backdrop")
"""Names accepted by :func:`ppo_cv.data_gen.scenes.make_scene`."""
