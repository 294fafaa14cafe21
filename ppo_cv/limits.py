"""Bounds on the numbers both the API and the command line check, in a module that imports
nothing: the command line builds its help without importing :mod:`ppo_cv.sfm` (and pycolmap).
"""

from __future__ import annotations

__all__ = ["MAX_THREADS", "MAX_FEATURES", "MAX_KEYPOINTS", "MAX_MATCHES"]

MAX_THREADS = 256
"""Upper bound of ``num_threads`` (``sfm --threads``): a million threads makes pycolmap abort
the process."""

MAX_FEATURES = 100_000
"""Upper bound of ``max_num_features`` (``sfm --max-features``), SIFT features per image."""

MAX_KEYPOINTS = 1_000_000
"""Upper bound of ``max_features`` (``PairOptions``, ``detect_features``, ``--max-features``),
keypoints per image: OpenCV's ORB reserves room for that many per pyramid level, and 2^31 - 1
failed in it with ``std::bad_alloc``."""

MAX_MATCHES = 10_000_000
"""Upper bound of the match count of the consensus test (``significance.log10_binomial``'s
``n``, ``smallest_significant_consensus``'s ``num_matches``): it tabulates one logarithm per
match, 80 MB at this bound, ten times the matches of two images of ``MAX_KEYPOINTS`` keypoints;
a count of 2^31 asked for 17 GB."""
