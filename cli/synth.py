"""``ppo-cv synth``: render synthetic image pairs with exact ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ppo_cv.data_gen.names import MOTIONS, SCENES


def _fail(message: str) -> None:
    typer.echo(f"ppo-cv synth: {message}", err=True)
    raise typer.Exit(2)


def _check(out_dir: Path, pairs: int, seed: int, motion: str, scene: str | None, width: int,
           height: int, alpha: float | None, supersample: int, noise: float, blur: float,
           workers: int | None) -> None:  # fmt: skip
    if motion not in MOTIONS:
        _fail(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    if scene is not None and scene not in SCENES:
        _fail(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}")
    if seed < 0:
        _fail(f"--seed must be >= 0, got {seed}")
    if pairs < 1:
        _fail(f"--pairs must be >= 1, got {pairs}")
    if not (8 <= width <= 8192 and 8 <= height <= 8192):
        _fail(f"--width and --height must be in 8..8192, got {width}x{height}")
    if alpha is not None and not 0.0 < alpha <= 1.0:
        _fail(f"--alpha must be in (0, 1], got {alpha}")
    if not 1 <= supersample <= 8:
        _fail(f"--supersample must be in 1..8, got {supersample}")
    if noise < 0 or blur < 0:
        _fail("--noise and --blur must be >= 0")
    if workers is not None and workers < 1:
        _fail(f"--workers must be >= 1, got {workers}")
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        _fail(f"{out_dir} exists and is not an empty directory")


def register(app: typer.Typer) -> None:
    """Add the ``synth`` command to ``app``."""

    @app.command()
    def synth(
        out_dir: Annotated[Path, typer.Argument(help="New (or empty) output directory.")],
        pairs: Annotated[int, typer.Option("--pairs", "-n", help="Number of image pairs.")] = 20,
        motion: Annotated[str, typer.Option(help=f"Motion preset: {'|'.join(MOTIONS)}.")] = (
            "general"
        ),
        seed: Annotated[int, typer.Option(help="Seed (>= 0): same seed, same bytes.")] = 0,
        scene: Annotated[
            str | None,
            typer.Option(help=f"Scene ({'|'.join(SCENES)}); default depends on the motion."),
        ] = None,
        width: Annotated[int, typer.Option(help="Image width (pixels).")] = 640,
        height: Annotated[int, typer.Option(help="Image height (pixels).")] = 480,
        alpha: Annotated[
            float | None,
            typer.Option(help="Parallax factor of small-parallax in (0, 1]; random if omitted."),
        ] = None,
        supersample: Annotated[
            int, typer.Option(help="Anti-aliasing samples per pixel and axis.")
        ] = 2,
        noise: Annotated[float, typer.Option(help="Gaussian image noise (grey levels).")] = 0.0,
        blur: Annotated[float, typer.Option(help="Gaussian blur sigma (pixels).")] = 0.0,
        different_k: Annotated[
            bool, typer.Option("--different-k", help="Draw K2 independently of K1.")
        ] = False,
        workers: Annotated[
            int | None, typer.Option(help="Worker processes (default: CPUs).")
        ] = None,
    ) -> None:
        """Render synthetic pairs with exact ground truth and a freiburg-style pairs file."""
        from ppo_cv.data_gen import make_dataset

        _check(out_dir, pairs, seed, motion, scene, width, height, alpha, supersample, noise, blur,
               workers)  # fmt: skip
        try:
            out = make_dataset(
                out_dir, pairs=pairs, motion=motion, seed=seed, size=(width, height),
                scene=scene, alpha=alpha, supersample=supersample, noise_std=noise,
                blur_sigma=blur, same_intrinsics=not different_k, workers=workers,
            )  # fmt: skip
        except (ValueError, TypeError, OSError) as error:
            _fail(str(error))
        from ppo_cv.data_gen.io import PAIRS_FILE

        typer.echo(f"wrote {pairs} pairs to {out} ({out / PAIRS_FILE})")
