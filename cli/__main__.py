"""``python -m ppo_cv.cli``: the ``ppo-cv`` command line, as ``python -m ppo_cv``."""

from ppo_cv.cli.main import main

if __name__ == "__main__":
    main()
