"""Command-line interface of ppo-cv (installed as ``ppo_cv.cli``)."""
