"""``ppo-cv sfm``: incremental structure from motion seeded by the PPO initial-pair ranking."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

__all__ = ["register", "parse_K"]


def parse_K(text: str) -> np.ndarray:
    """``fx,fy,cx,cy`` or nine comma-separated values (row-major) as a 3x3 matrix."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        raise ValueError(f"--K must be numbers separated by commas, got {text!r}") from None
    if len(values) == 4:
        fx, fy, cx, cy = values
        return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    if len(values) == 9:
        return np.array(values).reshape(3, 3)
    raise ValueError(f"--K needs 4 values (fx,fy,cx,cy) or 9 (row-major), got {len(values)}")


def _fail(message: str, code: int = 2) -> None:
    typer.echo(f"ppo-cv sfm: {message}", err=True)
    raise typer.Exit(code)


def register(app: typer.Typer) -> None:
    @app.command(
        "sfm",
        help="Reconstruct IMAGE_DIR into a COLMAP model in OUT_DIR, never from a pure rotation."
        "\n\npycolmap extracts SIFT features and matches all pairs; PPO ranks the candidate "
        "initial pairs, rejecting pure rotations and pairs without parallax (initial_pairs.txt "
        "in OUT_DIR); pycolmap's incremental mapper starts from the best pair.",
    )
    def sfm_command(
        image_dir: Annotated[Path, typer.Argument(help="Folder of images of one camera.")],
        out_dir: Annotated[Path, typer.Argument(help="New folder for the COLMAP model.")],
        K: Annotated[
            str | None,
            typer.Option(
                "--K",
                help="Intrinsics fx,fy,cx,cy, held fixed. Give them when known: without them "
                "pycolmap guesses a focal length and pure rotations are not reliably detected.",
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
        max_features: Annotated[
            int, typer.Option("--max-features", help="SIFT features per image.")
        ] = 8192,
        threads: Annotated[int, typer.Option("--threads", help="Threads for pycolmap.")] = 2,
        as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
        verbose: Annotated[bool, typer.Option("--verbose", help="Show pycolmap's log.")] = False,
    ) -> None:
        """Features, matches, PPO-ranked initial pair and incremental mapping of a folder."""
        from ppo_cv import sfm
        from ppo_cv.checks import as_camera_matrix

        if init not in sfm.INITIALIZATIONS:
            _fail(f"--init must be one of {', '.join(sfm.INITIALIZATIONS)}, got {init!r}")
        if seeding not in sfm.SEEDINGS:
            _fail(f"--seeding must be one of {', '.join(sfm.SEEDINGS)}, got {seeding!r}")
        if out_dir.exists():
            _fail(f"output folder {str(out_dir)!r} already exists")
        if database is not None and database.exists():
            _fail(f"database {str(database)!r} already exists")
        if max_features < 1 or threads < 1:
            _fail("--max-features and --threads must be positive")
        try:
            matrix = as_camera_matrix(parse_K(K), "--K") if K is not None else None
            sfm.list_images(image_dir)
        except ValueError as exc:
            _fail(str(exc))

        def progress(message: str) -> None:
            typer.echo(f"[sfm] {message}", err=True)

        try:
            result = sfm.run_sfm(
                image_dir, None, K=matrix, initialization=init, seeding=seeding,
                database_path=database,
                max_num_features=max_features, num_threads=threads, verbose=verbose,
                progress=progress,
            )  # fmt: skip
        except ValueError as exc:
            _fail(str(exc))
        except RuntimeError as exc:
            _fail(f"pycolmap failed: {exc}", code=1)
        if result.reconstruction is None:
            _fail("nothing was reconstructed; no model written", code=1)
        sfm.write_model(result, out_dir)
        progress(f"wrote {out_dir}")
        typer.echo(_summary(result, out_dir, as_json))


def _summary(result, out_dir: Path, as_json: bool) -> str:
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
    pair_text = " ".join(pair) if pair else "-"
    return (
        f"registered {result.num_registered}/{result.num_images} images, "
        f"{result.num_points3D} points, mean reprojection error {error:.3f} px, "
        f"initial pair {pair_text} ({result.initialization}), "
        f"scoring+mapping {result.elapsed:.1f} s -> {out_dir}"
    )
