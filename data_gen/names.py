"""Names of the motion presets and scenes, importable without the renderer."""

from __future__ import annotations

__all__ = ["BASELINE_MOTIONS", "MOTIONS", "SCENES", "MAX_BASELINE_RATIO", "MAX_PIVOT_OFFSET"]

MOTIONS = (
    "general",
    "pure-rotation",
    "small-parallax",
    "forward",
    "planar",
    "panorama",
    "tiny-baseline",
    "tripod",
)
"""Names accepted by :func:`ppo_cv.data_gen.motion.sample_motion`."""

SCENES = ("room", "clutter", "plane", "backdrop")
"""Names accepted by :func:`ppo_cv.data_gen.scenes.make_scene`."""

MAX_BASELINE_RATIO = 0.5
"""Largest ``baseline_ratio`` (baseline over scene depth) of ``tiny-baseline`` and ``tripod``."""

BASELINE_MOTIONS = ("tiny-baseline", "tripod")
"""Presets that take a ``baseline_ratio``."""

MAX_PIVOT_OFFSET = 1.0
"""Largest ``pivot_offset`` of ``panorama``, metres."""
