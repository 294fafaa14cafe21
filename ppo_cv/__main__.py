"""``python -m ppo_cv``: the ``ppo-cv`` command line."""

from ppo_cv.cli.main import main

if __name__ == "__main__":
    main()
