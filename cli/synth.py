"""``ppo-cv synth``: render synthetic image pairs with exact ground truth."""

from __future__ import annotations

import re
import threading
from pathlib import Path
from typing import Annotated

import typer

from ppo_cv.checks import shown
from ppo_cv.data_gen.names import (
    BASELINE_MOTIONS,
    MAX_BASELINE_RATIO,
    MAX_PIVOT_OFFSET,
    MOTIONS,
    SCENES,
)

from .common import WORKERS_MAX, ProgressReport, Quiet, error_message, fail, print_result

__all__ = ["register", "MAX_BLUR", "MAX_NOISE"]

MAX_PAIRS = 10_000
MAX_SIDE = 4096
MAX_SAMPLES = 20_000_000
"""Bound on ``width * height * supersample^2`` (rays cast per view): about 15 s a pair."""
MIN_SIDE = 16
"""Smallest ``--width`` and ``--height``: the shortest side features are detected on
(:data:`ppo_cv.features.MIN_IMAGE_SIDE`, not imported here to keep OpenCV out of ``--help``)."""
MAX_NOISE = 50.0
MAX_BLUR = 50.0


def _fail(message: str) -> None:
    fail("synth", message)


def _check(out_dir: Path, pairs: int, seed: int, motion: str | None, scene: str | None,
           width: int | None, height: int | None, alpha: float | None, supersample: int,
           noise: float | None, blur: float | None, workers: int | None,
           baseline_ratio: float | None, warp: bool, overwrite: bool,
           pivot_offset: float = 0.0) -> None:  # fmt: skip
    if motion is not None and motion not in MOTIONS:
        _fail(f"unknown motion {shown(motion)}; choose one of {', '.join(MOTIONS)}")
    if scene is not None and scene not in SCENES:
        _fail(f"unknown scene {shown(scene)}; choose one of {', '.join(SCENES)}")
    if not 0 <= seed <= 2**32 - 1:
        _fail(f"--seed must be in 0..{2**32 - 1}, got {shown(seed)}")
    if not 1 <= pairs <= MAX_PAIRS:
        _fail(f"--pairs must be in 1..{MAX_PAIRS}, got {shown(pairs)}")
    for name, value in (("--width", width), ("--height", height)):
        if value is not None and not MIN_SIDE <= value <= MAX_SIDE:
            _fail(f"{name} must be in {MIN_SIDE}..{MAX_SIDE}, got {shown(value)}")
    sides = [v for v in (width, height) if v is not None]
    if not 1 <= supersample <= 8:
        _fail(f"--supersample must be in 1..8, got {shown(supersample)}")
    samples = (width or 640) * (height or 480) * supersample**2
    if not warp and samples > MAX_SAMPLES:
        _fail(f"--width x --height x --supersample^2 must be at most {MAX_SAMPLES:,} samples, "
              f"got {samples:,}")  # fmt: skip
    if alpha is not None and not 0.0 < alpha <= 1.0:
        _fail(f"--alpha must be in (0, 1], got {shown(alpha)}")
    if alpha is not None and motion != "small-parallax" and not warp:
        _fail("--alpha applies to --motion small-parallax only")
    if baseline_ratio is not None and not 0.0 <= baseline_ratio <= MAX_BASELINE_RATIO:
        _fail(f"--baseline-ratio must be in [0, {MAX_BASELINE_RATIO}], got {shown(baseline_ratio)}")
    if baseline_ratio is not None and (motion not in BASELINE_MOTIONS or warp):
        _fail(f"--baseline-ratio applies to --motion {' and '.join(BASELINE_MOTIONS)} only")
    if not 0.0 <= pivot_offset <= MAX_PIVOT_OFFSET:
        _fail(f"--pivot-offset must be in [0, {MAX_PIVOT_OFFSET:g}] m, got {shown(pivot_offset)}")
    if pivot_offset and (motion != "panorama" or warp):
        _fail("--pivot-offset applies to rendered --motion panorama only")
    if noise is not None and not 0.0 <= noise <= MAX_NOISE:
        _fail(f"--noise must be in [0, {MAX_NOISE:g}], got {shown(noise)}")
    if blur is not None and not 0.0 <= blur <= MAX_BLUR:
        _fail(f"--blur must be in [0, {MAX_BLUR:g}], got {shown(blur)}")
    if workers is not None and not 0 <= workers <= WORKERS_MAX:
        _fail(f"--workers must be in 0..{WORKERS_MAX}, got {shown(workers)}")
    if warp:
        if motion not in (None, "panorama"):
            _fail(f"--warp makes tripod pans (--motion panorama), not {shown(motion)}")
        if scene is not None or alpha is not None:
            _fail("--scene and --alpha do not apply to --warp")
        if len(sides) == 1:
            _fail("--warp needs both --width and --height, or neither")
    from ppo_cv.atomic import check_target

    try:
        check_target(out_dir, "folder", overwrite)
    except ValueError as exc:
        _fail(str(exc))


def _imperfections(imperfect: bool, noise: float | None, blur: float | None,
                   narrow_lens: bool = False, **told):  # fmt: skip
    """``REAL_PHOTO`` (``NARROW_LENS`` with ``narrow_lens``) with the noise, blur and what the
    estimator is told (``told``: fields of ``Imperfections``) asked for, or None without
    ``--imperfect``."""
    if not imperfect:
        if any(told.values()) or narrow_lens:
            _fail("--centred-principal-point, --view-focal-error, --exposure-ev, --vignetting "
                  "and --narrow-lens need --imperfect")  # fmt: skip
        return None
    import dataclasses

    from ppo_cv.data_gen import NARROW_LENS, REAL_PHOTO

    changes = {"noise_std": noise, "blur_sigma": blur, **told}
    changes = {key: value for key, value in changes.items() if value is not None}
    try:
        return dataclasses.replace(NARROW_LENS if narrow_lens else REAL_PHOTO, **changes)
    except ValueError as exc:
        message = str(exc)
        for field, option in _IMPERFECTION_OPTIONS.items():
            message = re.sub(rf"\b{field}\b", option, message)
        _fail(message)


_IMPERFECTION_OPTIONS = {
    "noise_std": "--noise", "blur_sigma": "--blur", "view_focal_error": "--view-focal-error",
    "exposure_ev": "--exposure-ev", "vignetting": "--vignetting",
}  # fmt: skip
"""The options of ``synth`` that set fields of ``Imperfections``, by field: its errors name the
option."""


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
        out_dir: Annotated[
            Path, typer.Argument(metavar="OUT_DIR", help="New (or empty) output directory.")
        ],
        pairs: Annotated[
            int, typer.Option("--pairs", "-n", help=f"Number of image pairs (1..{MAX_PAIRS}).")
        ] = 20,
        motion: Annotated[
            str | None, typer.Option(help=f"Motion preset: {', '.join(MOTIONS)} (default general).")
        ] = None,
        seed: Annotated[
            int, typer.Option(help=f"Seed (0..{2**32 - 1}): same seed, same bytes.")
        ] = 0,
        scene: Annotated[
            str | None,
            typer.Option(help=f"Scene: {', '.join(SCENES)}; the default depends on the motion."),
        ] = None,
        width: Annotated[
            int | None,
            typer.Option(help=f"Image width (pixels, {MIN_SIDE}..{MAX_SIDE}); 640, or 0.65 of the "
                         "photo."),  # fmt: skip
        ] = None,
        height: Annotated[
            int | None,
            typer.Option(help=f"Image height (pixels, {MIN_SIDE}..{MAX_SIDE}); 480, or 0.65 of "
                         "the photo."),  # fmt: skip
        ] = None,
        alpha: Annotated[
            float | None,
            typer.Option(help="Parallax factor of small-parallax in (0, 1]; random if omitted."),
        ] = None,
        baseline_ratio: Annotated[
            float | None,
            typer.Option(
                help="Baseline / median depth of tiny-baseline or tripod in [0, 0.5]; if "
                "omitted log-uniform in [0.001, 0.05] (tiny-baseline) or [0.002, 0.01] (tripod)."
            ),
        ] = None,
        pivot_offset: Annotated[
            float,
            typer.Option(
                help="Metres behind the camera of the point a panorama turns about (a tripod "
                "screw behind the lens), in [0, 1]."
            ),
        ] = 0.0,
        imperfect: Annotated[
            bool,
            typer.Option(
                "--imperfect",
                help="As real photos: unmodelled radial distortion, focal length given 3 % "
                "off, 25-35 deg field of view, JPEG, noise 1, blur 0.5.",
            ),
        ] = False,
        narrow_lens: Annotated[
            bool,
            typer.Option(
                "--narrow-lens",
                help="With --imperfect: a consumer zoom near its long end, 15-25 deg field, "
                "division-model k1 of 0.05-0.15 (barrel on 7 lenses of 10).",
            ),
        ] = False,
        centred_principal_point: Annotated[
            bool,
            typer.Option(
                "--centred-principal-point",
                help="With --imperfect: write the image centre as principal point (as EXIF or a "
                "stitcher gives it); the true one lies within 2 % of it.",
            ),
        ] = False,
        view_focal_error: Annotated[
            float | None,
            typer.Option(
                help="With --imperfect: each view's focal length written off by a further "
                "factor of its own, up to this fraction (0..0.5; focal lengths estimated per "
                "photo)."
            ),
        ] = None,
        exposure_ev: Annotated[
            float | None,
            typer.Option(
                help="With --imperfect: view 2 exposed up to this many stops (0..3) brighter or "
                "darker than view 1 (automatic exposure), clipped at white."
            ),
        ] = None,
        vignetting: Annotated[
            float | None,
            typer.Option(
                help="With --imperfect: share of the light lost in the image corners (0-0.9), "
                "the same in both views."
            ),
        ] = None,
        warp: Annotated[
            bool,
            typer.Option(
                "--warp",
                help="Warp real photos by a pure rotation K R K^-1 instead of rendering.",
            ),
        ] = False,
        warp_source: Annotated[
            Path | None,
            typer.Option(help="Photo or folder of photos for --warp (default: freiburg frames)."),
        ] = None,
        supersample: Annotated[
            int, typer.Option(help="Anti-aliasing samples per pixel and axis (1..8).")
        ] = 2,
        noise: Annotated[
            float | None,
            typer.Option(help=f"Gaussian image noise (grey levels, 0..{MAX_NOISE:g}); 0, or 1 "
                         "with --imperfect."),  # fmt: skip
        ] = None,
        blur: Annotated[
            float | None,
            typer.Option(help=f"Gaussian blur sigma (pixels, 0..{MAX_BLUR:g}); 0, or 0.5 with "
                         "--imperfect."),  # fmt: skip
        ] = None,
        different_k: Annotated[
            bool, typer.Option("--different-k", help="Draw K2 independently of K1.")
        ] = False,
        workers: Annotated[
            int | None,
            typer.Option(
                help=f"Worker processes (0..{WORKERS_MAX}; 0 or none: one per CPU); never more "
                "than the CPUs this process may use or --pairs."
            ),
        ] = None,
        overwrite: Annotated[
            bool, typer.Option("--overwrite", help="Replace an existing non-empty OUT_DIR.")
        ] = False,
        quiet: Quiet = False,
    ) -> None:
        """Render synthetic pairs with exact ground truth and a freiburg-style pairs file."""
        from ppo_cv.atomic import atomic_directory, check_apart
        from ppo_cv.data_gen import make_dataset

        if warp_source is not None:
            try:
                check_apart(out_dir, [warp_source], "OUT_DIR ")
            except ValueError as exc:
                _fail(str(exc))
        _check(out_dir, pairs, seed, motion, scene, width, height, alpha, supersample, noise, blur,
               workers, baseline_ratio, warp, overwrite, pivot_offset)  # fmt: skip
        if warp_source is not None and not warp:
            _fail("--warp-source needs --warp")
        if warp and different_k:
            _fail("--different-k does not apply to --warp (one camera)")
        imperfections = _imperfections(
            imperfect, noise, blur, narrow_lens,
            centred_principal_point=centred_principal_point or None,
            view_focal_error=view_focal_error, exposure_ev=exposure_ev, vignetting=vignetting,
        )  # fmt: skip
        photometric = {}
        if imperfections is None and not warp:
            photometric = {"noise_std": noise or 0.0, "blur_sigma": blur or 0.0}
        elif imperfections is None and (noise or blur):
            _fail("--warp takes --noise and --blur with --imperfect only")
        size = None if width is None and height is None else (width or 640, height or 480)
        stop = threading.Event()
        try:
            with atomic_directory(out_dir, overwrite) as staging:
                watcher = threading.Thread(
                    target=_watch, args=(staging, pairs, quiet, stop), daemon=True
                )
                watcher.start()
                try:
                    make_dataset(  # its own staging folder lands inside ours
                        staging / "render", pairs=pairs, motion=motion, seed=seed, size=size,
                        scene=scene, alpha=alpha, supersample=supersample,
                        same_intrinsics=not different_k, workers=workers or None,
                        baseline_ratio=baseline_ratio, imperfections=imperfections,
                        source="warp" if warp else "render", warp_source=warp_source,
                        pivot_offset=pivot_offset,
                        **photometric,
                    )  # fmt: skip
                finally:
                    stop.set()
                    watcher.join()
                for entry in (staging / "render").iterdir():
                    entry.rename(staging / entry.name)
                (staging / "render").rmdir()
        except (ValueError, TypeError, OSError) as error:
            _fail(error_message(error))
        from ppo_cv.data_gen.io import PAIRS_FILE

        print_result(
            "synth",
            f"wrote {pairs} pair{'s' * (pairs != 1)} to {out_dir} ({out_dir / PAIRS_FILE}, "
            f"images in {out_dir / 'images'}); run them with: ppo-cv pairs {out_dir / PAIRS_FILE} "
            f"{out_dir / 'images'}",
        )
