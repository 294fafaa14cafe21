"""``ppo-cv sfm``: incremental structure from motion seeded by the PPO initial-pair ranking."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ppo_cv.checks import shown
from ppo_cv.limits import MAX_FEATURES, MAX_THREADS

from .common import (
    NO_RESULT,
    PRI_THRESHOLD_RANGE,
    SEED_MAX,
    ExifOrientation,
    Overwrite,
    PriThreshold,
    Quiet,
    check_range,
    error_message,
    exif_camera,
    fail,
    implausible_intrinsics,
    print_result,
    read_layout,
    upright_model_warning,
    warn,
    with_warnings,
)

__all__ = ["register", "parse_K"]


def parse_K(text: str) -> np.ndarray:
    """``fx,fy,cx,cy`` or nine values (row-major) as a 3x3 matrix, separated by commas, spaces
    or semicolons."""
    from ppo_cv.calib import parse_intrinsics

    return parse_intrinsics(text, "--K")


def _fail(message: str, code: int = 2) -> None:
    fail("sfm", message, code)


MAX_EXIF_WARNINGS = 3


def _exif_warnings(image_dir: Path, names: list[str], exif_orientation: bool) -> None:
    """The doubts about the images' EXIF focal lengths (:func:`exif_camera`), the first few."""
    doubts = []
    for name in names:
        try:
            doubts += exif_camera(image_dir / name, exif_orientation)[2]
        except (ValueError, RuntimeError, OSError):  # unreadable: pycolmap's reading says so
            continue
    for message in doubts[:MAX_EXIF_WARNINGS]:
        warn("sfm", message)
    if len(doubts) > MAX_EXIF_WARNINGS:
        warn("sfm", f"{len(doubts) - MAX_EXIF_WARNINGS} more doubtful EXIF focal lengths")


def _check(image_dir, out_dir, K, init, seeding, database, max_features, threads, seed,
           pri_threshold, overwrite, exif_orientation=True):  # fmt: skip
    """Every argument checked before the run; returns the camera matrix (or None) and the
    warning that it does not fit the images (:func:`implausible_intrinsics`), if it does not:
    given after the run, as ``ppo-cv pair`` gives it, on the line of a failure."""
    from ppo_cv import sfm
    from ppo_cv.atomic import check_apart, check_target

    if init not in sfm.INITIALIZATIONS:
        raise ValueError(
            f"--init must be one of {', '.join(sfm.INITIALIZATIONS)}, got {shown(init)}"
        )
    if seeding not in sfm.SEEDINGS:
        raise ValueError(
            f"--seeding must be one of {', '.join(sfm.SEEDINGS)}, got {shown(seeding)}"
        )
    check_range("--max-features", max_features, 1, MAX_FEATURES)
    check_range("--threads", threads, 1, MAX_THREADS)
    check_range("--seed", seed, 0, SEED_MAX)
    check_range("--pri-threshold", pri_threshold, *PRI_THRESHOLD_RANGE)
    check_apart(out_dir, [image_dir], "OUT_DIR ")
    sfm.require_no_images(out_dir, "OUT_DIR ", "ppo-cv sfm IMAGE_DIR OUT_DIR")
    check_target(out_dir, "folder", overwrite, [image_dir], "OUT_DIR ")
    if database is not None:
        check_apart(database, [image_dir], "--database ")
        if database.exists() or database.is_symlink():
            raise ValueError(f"database {database} already exists; give a new file name (a "
                             "database is never replaced, --overwrite or not)")  # fmt: skip
        check_target(database, "file")
        sfm.require_database_outside(database, out_dir, ("--database", "OUT_DIR"))
    matrix = None if K is None else parse_K(K)
    names, skipped = sfm.screen_images(image_dir)
    sfm.require_two_images(image_dir, names, skipped)
    for reason in skipped.values():
        warn("sfm", f"skipping an image: {reason}")
    if matrix is None:
        warn(
            "sfm",
            "no intrinsics given: pycolmap guesses the focal length from EXIF or the image "
            "size, and each checked pair is decided as ppo-cv pair decides it without --K, "
            "again with focal lengths fitted to its matches; pass --K fx,fy,cx,cy for accurate "
            "poses",
        )
        _exif_warnings(Path(image_dir), names, exif_orientation)
        return None, []
    size, turned = read_layout(Path(image_dir) / names[0], exif_orientation)
    doubt = implausible_intrinsics(matrix, size, exif_turned=turned)
    return matrix, [doubt] if doubt else []


def register(app: typer.Typer) -> None:
    """Add the ``sfm`` command to ``app``."""
    from ppo_cv.ppo import DEFAULT_PRI_THRESHOLD

    @app.command(
        "sfm",
        help="Reconstruct IMAGE_DIR into a COLMAP model in OUT_DIR, never from a pure rotation."
        "\n\npycolmap extracts SIFT features and matches all pairs; PPO ranks the candidate "
        "initial pairs, rejecting pure rotations and pairs without parallax (initial_pairs.txt "
        "in OUT_DIR); pycolmap's incremental mapper starts from the best pair. Without --K "
        "pycolmap estimates a camera per image size and EXIF focal length (per image without "
        "one). OUT_DIR is written "
        "completely or not at all; --database once the images are matched, and it is kept "
        "when no model can be built from them (exit code 1).",
    )
    def sfm_command(
        image_dir: Annotated[Path, typer.Argument(metavar="IMAGE_DIR", help="Folder of images.")],
        out_dir: Annotated[
            Path, typer.Argument(metavar="OUT_DIR", help="New folder for the COLMAP model.")
        ],
        K: Annotated[
            str | None,
            typer.Option(
                "--K",
                help="Intrinsics in pixels, fx,fy,cx,cy (OpenCV's: the first pixel's centre "
                "at 0,0), held fixed (all images of one size). Give them "
                "when known: without them pycolmap guesses a focal length, and the initial "
                "pairs are checked for a pure rotation as ppo-cv pair checks them without "
                "--K, with focal lengths fitted to each pair.",
            ),
        ] = None,
        init: Annotated[
            str, typer.Option("--init", help="Initial pair: 'ppo' (PPO ranking) or 'colmap'.")
        ] = "ppo",
        seeding: Annotated[
            str,
            typer.Option("--seeding", help="'two-view' (PPO pose and points) or 'pair-options'."),
        ] = "two-view",
        database: Annotated[
            Path | None, typer.Option("--database", help="Keep the feature database here (new).")
        ] = None,
        overwrite: Overwrite = False,
        exif_orientation: ExifOrientation = True,
        max_features: Annotated[
            int,
            typer.Option("--max-features", help=f"SIFT features per image (1..{MAX_FEATURES})."),
        ] = 8192,
        threads: Annotated[
            int, typer.Option("--threads", help=f"Threads for pycolmap (1..{MAX_THREADS}).")
        ] = 2,
        seed: Annotated[int, typer.Option(help=f"RANSAC seed (0..{SEED_MAX}).")] = 0,
        pri_threshold: PriThreshold = DEFAULT_PRI_THRESHOLD,
        as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
        verbose: Annotated[bool, typer.Option("--verbose", help="Show pycolmap's log.")] = False,
        quiet: Quiet = False,
    ) -> None:
        """Features, matches, PPO-ranked initial pair and incremental mapping of a folder."""
        from ppo_cv import sfm  # imports pycolmap, which replaces the SIGTERM handler
        from ppo_cv.atomic import sigterm_as_interrupt

        sigterm_as_interrupt()

        try:
            matrix, doubts = _check(image_dir, out_dir, K, init, seeding, database, max_features,
                            threads, seed, pri_threshold, overwrite, exif_orientation)  # fmt: skip
        except ValueError as exc:
            _fail(str(exc))

        def progress(message: str) -> None:
            if not quiet:
                typer.echo(f"ppo-cv sfm: {message}", err=True)

        try:
            result = sfm.run_sfm(
                image_dir, out_dir, K=matrix, initialization=init, seeding=seeding,
                database_path=database, max_num_features=max_features, num_threads=threads,
                seed=seed, verbose=verbose, progress=progress, overwrite=overwrite,
                pri_threshold=pri_threshold, exif_orientation=exif_orientation,
            )  # fmt: skip
        except sfm.ReconstructionFailed as exc:
            kept = f"; the matched features are in {database}" if database is not None else ""
            _fail(with_warnings(f"{exc}{kept}", doubts), code=NO_RESULT)
        except (ValueError, OSError) as exc:
            _fail(error_message(exc))
        except RuntimeError as exc:
            _fail(with_warnings(f"pycolmap failed: {exc}", doubts), code=NO_RESULT)
        for doubt in doubts:  # after the run, as pair gives it: a failure is its one line
            warn("sfm", doubt)
        paths = [Path(image_dir) / name for name in sfm.list_images(image_dir)]
        for message in upright_model_warning(paths, exif_orientation, f"the model {out_dir}"):
            warn("sfm", message)
        print_result("sfm", _summary(result, out_dir, as_json))


def _summary(result, out_dir: Path, as_json: bool) -> str:
    from ppo_cv import sfm

    pair = list(result.initial_pair) if result.initial_pair else None
    error = result.mean_reprojection_error
    summary = {
        "model": str(out_dir),
        "initialization": result.initialization,
        "initial_pair": pair,
        "registered": result.num_registered,
        "images": result.num_images,
        "points3D": result.num_points3D,
        "mean_reprojection_error": None if math.isnan(error) else error,
        "models": result.num_models,
        "seconds": result.elapsed,
    }
    if as_json:
        return json.dumps(summary)
    pair_text = sfm.pair_text(*pair) if pair else "-"
    return (
        f"registered {result.num_registered}/{result.num_images} images, "
        f"{result.num_points3D} points, mean reprojection error {error:.3f} px, "
        f"initial pair {pair_text} ({result.initialization}), "
        f"scoring+mapping {result.elapsed:.1f} s -> {out_dir}"
    )
