"""``ppo-cv synth``: render synthetic image pairs with exact ground truth."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Annotated

import typer

from ppo_cv.data_gen.names import MOTIONS, SCENES

from .common import ProgressReport, Quiet, fail

__all__ = ["register", "MAX_BLUR", "MAX_NOISE"]

MAX_BLUR = 50.0
MAX_NOISE = 255.0
MAX_PAIRS = 100_000


def _fail(message: str) -> None:
    fail("synth", message)


def _check(out_dir: Path, pairs: int, seed: int, motion: str, scene: str | None, width: int,
           height: int, alpha: float | None, supersample: int, noise: float, blur: float,
           workers: int | None, overwrite: bool) -> None:  # fmt: skip
    if motion not in MOTIONS:
        _fail(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    if scene is not None and scene not in SCENES:
        _fail(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}")
    if not 0 <= seed <= 2**32 - 1:
        _fail(f"--seed must be in 0..{2**32 - 1}, got {seed}")
    if not 1 <= pairs <= MAX_PAIRS:
        _fail(f"--pairs must be in 1..{MAX_PAIRS}, got {pairs}")
    if not (8 <= width <= 8192 and 8 <= height <= 8192):
        _fail(f"--width and --height must be in 8..8192, got {width}x{height}")
    if alpha is not None and not 0.0 < alpha <= 1.0:
        _fail(f"--alpha must be in (0, 1], got {alpha}")
    if not 1 <= supersample <= 8:
        _fail(f"--supersample must be in 1..8, got {supersample}")
    if not 0.0 <= noise <= MAX_NOISE:
        _fail(f"--noise must be in 0..{MAX_NOISE:g} grey levels, got {noise}")
    if not 0.0 <= blur <= MAX_BLUR:
        _fail(f"--blur must be in 0..{MAX_BLUR:g} pixels, got {blur}")
    if workers is not None and not 1 <= workers <= 256:
        _fail(f"--workers must be in 1..256, got {workers}")
    from ppo_cv.atomic import check_target

    try:
        check_target(out_dir, "folder", overwrite)
    except ValueError as exc:
        _fail(str(exc))


def _watch(staging: Path, total: int, quiet: bool, stop: threading.Event) -> None:
    """Progress of a render into ``staging``: counts the finished second images of the pairs."""
    with ProgressReport("synth", "pairs", total, quiet) as report:
        pattern = ".render.*/images/pair_*_2.png"
        while not stop.wait(0.25):
            done = min(sum(1 for _ in staging.glob(pattern)), total)
            if done > report.done:
                report.advance(done - report.done)
        if (staging / "render").is_dir() and report.done < total:
            report.advance(total - report.done)  # the rename came before the last look


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
        overwrite: Annotated[
            bool, typer.Option("--overwrite", help="Replace an existing non-empty OUT_DIR.")
        ] = False,
        quiet: Quiet = False,
    ) -> None:
        """Render synthetic pairs with exact ground truth and a freiburg-style pairs file."""
        from ppo_cv.atomic import atomic_directory
        from ppo_cv.data_gen import make_dataset

        _check(out_dir, pairs, seed, motion, scene, width, height, alpha, supersample, noise, blur,
               workers, overwrite)  # fmt: skip
        stop = threading.Event()
        try:
            with atomic_directory(out_dir, overwrite) as staging:
                watcher = threading.Thread(
                    target=_watch, args=(staging, pairs, quiet, stop), daemon=True
                )
                watcher.start()
                try:
                    make_dataset(  # its own staging folder lands inside ours
                        staging / "render", pairs=pairs, motion=motion, seed=seed,
                        size=(width, height), scene=scene, alpha=alpha, supersample=supersample,
                        noise_std=noise,
                        blur_sigma=blur, same_intrinsics=not different_k, workers=workers,
                    )  # fmt: skip
                finally:
                    stop.set()
                    watcher.join()
                for entry in (staging / "render").iterdir():
                    entry.rename(staging / entry.name)
                (staging / "render").rmdir()
        except (ValueError, TypeError, OSError) as error:
            _fail(str(error))
        from ppo_cv.data_gen.io import PAIRS_FILE

        typer.echo(f"wrote {pairs} pairs to {out_dir} ({out_dir / PAIRS_FILE})")
