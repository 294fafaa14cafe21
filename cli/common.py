"""What every ``ppo-cv`` command shares: the error format, bounds on numbers, progress on stderr.

Errors are one line ``ppo-cv <command>: <message>`` on stderr with exit code 2; warnings are
``ppo-cv <command>: warning: <message>``.
"""

from __future__ import annotations

import math
import os
import sys
import time
from typing import Annotated, NoReturn

import typer

__all__ = [
    "SEED_MAX",
    "MAX_FEATURES_MAX",
    "RedetectBelow",
    "fail",
    "warn",
    "check_range",
    "check_image_file",
    "implausible_intrinsics",
    "image_size",
    "ProgressReport",
    "StageReport",
]

SEED_MAX = 2**31 - 1  # pycolmap and OpenCV take the seed as a 32-bit signed integer
MAX_FEATURES_MAX = 1_000_000
WORKERS_MAX = 256
MAX_SIZE_MAX = 100_000
_PANEL = "Pipeline"

Features = Annotated[str, typer.Option(help="sift, orb or akaze.", rich_help_panel=_PANEL)]
MaxFeatures = Annotated[
    int, typer.Option(help=f"Keypoints per image (8..{MAX_FEATURES_MAX}).", rich_help_panel=_PANEL)
]
MaxSize = Annotated[
    int,
    typer.Option(
        help=f"Detect on a copy whose longer side is at most this (32..{MAX_SIZE_MAX}; "
        "0: full size).",
        rich_help_panel=_PANEL,
    ),
]
Ratio = Annotated[float, typer.Option(help="Lowe's ratio test.", rich_help_panel=_PANEL)]
Backend = Annotated[
    str,
    typer.Option(
        help="Robust E: pycolmap (LO-RANSAC) or opencv (USAC MAGSAC++).", rich_help_panel=_PANEL
    ),
]
Threshold = Annotated[float, typer.Option(help="RANSAC threshold, pixels.", rich_help_panel=_PANEL)]
Seed = Annotated[int, typer.Option(help=f"RANSAC seed (0..{SEED_MAX}).", rich_help_panel=_PANEL)]
PriThreshold = Annotated[
    float,
    typer.Option(
        "--pri-threshold",
        help="Pure rotation when PRI (mean |M2|, eq. 84) is below this (paper: 0.015).",
        rich_help_panel=_PANEL,
    ),
]
MaxLog10Nfa = Annotated[
    float,
    typer.Option(
        "--max-log10-nfa",
        help="Significance bar: a pose only when log10 of the number of false alarms of its "
        "consensus is at most this (lower is stricter; inf disables the test).",
        rich_help_panel=_PANEL,
    ),
]
Plane = Annotated[
    bool,
    typer.Option(
        "--plane/--no-plane",
        help="Also fit a homography and let the model decision call the pair a plane "
        "(--no-plane: rotation or general only).",
        rich_help_panel=_PANEL,
    ),
]
Photometric = Annotated[
    bool,
    typer.Option(
        "--photometric/--no-photometric",
        help="For a pure rotation, refit the rotation on windows of the images aligned by "
        "intensity (--no-photometric: the rotation of the feature matches).",
        rich_help_panel=_PANEL,
    ),
]
PrincipalPoint = Annotated[
    str,
    typer.Option(
        "--principal-point",
        help="May a pure rotation's fit move the principal point: auto (when both are given "
        "at the image centre, a guess), fit (always) or given (never).",
        rich_help_panel=_PANEL,
    ),
]
FocalRatio = Annotated[
    str,
    typer.Option(
        "--focal-ratio",
        help="May a pure rotation's fit scale image 2's focal length against image 1's: auto "
        "(when the two given focal lengths differ by at most 5 %, two estimates of one lens) or "
        "given (never: two calibrated cameras).",
        rich_help_panel=_PANEL,
    ),
]
RedetectBelow = Annotated[
    int,
    typer.Option(
        "--redetect-below",
        help="When E finds fewer inliers than this, detect again at a quarter of the detector's "
        "threshold and keep the consensus chance explains less (0: never).",
        rich_help_panel=_PANEL,
    ),
]
Overwrite = Annotated[
    bool,
    typer.Option("--overwrite", help="Replace an existing output (never done without it)."),
]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="No progress on stderr.")]


def fail(command: str, message: str, code: int = 2) -> NoReturn:
    """Print ``ppo-cv <command>: <message>`` (its first line) on stderr and exit with ``code``."""
    first = message.strip().splitlines()[0] if message.strip() else "failed"
    typer.echo(f"ppo-cv {command}: {first}", err=True)
    raise typer.Exit(code)


def warn(command: str, message: str) -> None:
    """Print ``ppo-cv <command>: warning: <message>`` on stderr."""
    typer.echo(f"ppo-cv {command}: warning: {message}", err=True)


def check_range(name: str, value: float, low: float, high: float) -> None:
    """ValueError naming the option unless ``low <= value <= high`` (NaN fails)."""
    if not (isinstance(value, (int, float)) and low <= value <= high):
        raise ValueError(f"{name} must be in {low:{_fmt(low)}}..{high:{_fmt(high)}}, got {value}")


def _fmt(value: float) -> str:
    return "d" if isinstance(value, int) else "g"


def check_image_file(path: str | os.PathLike) -> None:
    """ValueError unless ``path`` is an existing regular file (a FIFO would block a reader)."""
    from ppo_cv.images import check_regular_file

    check_regular_file(path)


def image_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """``(width, height)`` from the image header, without decoding; None when unknown."""
    from ppo_cv.images import image_size as header_size

    try:
        return header_size(path)
    except OSError:
        return None


TURNED_CENTRE_TOLERANCE = 0.02
"""Distance, as a fraction of the larger image side, within which a principal point counts as
the centre of the image turned a quarter (:func:`implausible_intrinsics`)."""


def _at_turned_centre(cx: float, cy: float, width: int, height: int) -> bool:
    tolerance = TURNED_CENTRE_TOLERANCE * max(width, height)
    turned = math.hypot(cx - height / 2, cy - width / 2)
    centre = math.hypot(cx - width / 2, cy - height / 2)
    return turned <= tolerance < centre - turned


def implausible_intrinsics(K, size: tuple[int, int] | None, name: str = "--K") -> str | None:
    """A warning when ``K`` does not fit an image of ``size`` (width, height), else None.

    Plausible: focal lengths within 0.1 to 10 times the larger image side and the principal
    point inside the image, and not at the centre of the image turned a quarter (a camera
    matrix of the stored pixels of a photo that its EXIF orientation shows upright), within
    :data:`TURNED_CENTRE_TOLERANCE` of the larger side and closer to it than to the centre.
    """
    if size is None:
        return None
    width, height = size
    fx, fy, cx, cy = float(K[0][0]), float(K[1][1]), float(K[0][2]), float(K[1][2])
    side = max(width, height)
    problems = []
    if not all(0.1 * side <= f <= 10.0 * side for f in (fx, fy)):
        problems.append(f"focal length fx={fx:g} fy={fy:g} px is outside 0.1..10 x {side} px")
    if not (0.0 <= cx <= width and 0.0 <= cy <= height):
        problems.append(f"principal point ({cx:g}, {cy:g}) is outside the {width}x{height} image")
    elif _at_turned_centre(cx, cy, width, height):
        problems.append(
            f"principal point ({cx:g}, {cy:g}) is the centre of a {height}x{width} image: a "
            "camera for the pixels as stored, where the EXIF orientation turns the image upright?"
        )
    if not problems:
        return None
    return f"{name} looks implausible for a {width}x{height} image: " + "; ".join(problems)


class ProgressReport:
    """Progress of ``total`` steps on stderr: a rich bar on a terminal, plain lines otherwise.

    Plain lines (``ppo-cv <command>: <done>/<total> <unit>, <seconds> s``) come after the first
    step, then at most every ``interval`` seconds, and after the last. ``quiet`` prints nothing.
    """

    def __init__(
        self, command: str, unit: str, total: int, quiet: bool = False, interval: float = 5.0
    ) -> None:
        self.command, self.unit, self.total = command, unit, int(total)
        self.quiet, self.interval = quiet, interval
        self.done = 0
        self._start = self._last = time.monotonic()
        self._rich = None
        self._task = None

    def __enter__(self) -> ProgressReport:
        if not self.quiet and sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._rich = Progress(
                TextColumn(self.unit),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=Console(stderr=True),
                transient=True,
            )
            self._rich.__enter__()
            self._task = self._rich.add_task(self.unit, total=self.total)
        return self

    def __exit__(self, *exc) -> None:
        if self._rich is not None:
            self._rich.__exit__(*exc)

    def advance(self, steps: int = 1) -> None:
        """Count ``steps`` more steps done."""
        self.done += steps
        if self.quiet:
            return
        if self._rich is not None:
            self._rich.advance(self._task, steps)
            return
        now = time.monotonic()
        if self.done == steps or self.done >= self.total or now - self._last >= self.interval:
            self._last = now
            print(
                f"ppo-cv {self.command}: {self.done}/{self.total} {self.unit}, "
                f"{math.floor(now - self._start)} s",
                file=sys.stderr,
                flush=True,
            )


class StageReport:
    """The stage one long computation has reached, on stderr: on a terminal, a transient
    rich line (a spinner, the last stage done, the time elapsed); elsewhere nothing, since
    scripts read stderr for warnings and errors. ``quiet`` prints nothing.

    Pass :meth:`stage` as the ``progress`` of :func:`ppo_cv.pipeline.estimate_pair`.
    """

    def __init__(self, command: str, quiet: bool = False) -> None:
        self.command, self.quiet = command, quiet
        self._rich = None
        self._task = None

    def __enter__(self) -> StageReport:
        if not self.quiet and sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

            self._rich = Progress(
                SpinnerColumn(),
                TextColumn("{task.description}"),
                TimeElapsedColumn(),
                console=Console(stderr=True),
                transient=True,
            )
            self._rich.__enter__()
            self._task = self._rich.add_task(f"ppo-cv {self.command}: starting", total=None)
        return self

    def __exit__(self, *exc) -> None:
        if self._rich is not None:
            self._rich.__exit__(*exc)

    def stage(self, name: str) -> None:
        """Show that stage ``name`` has ended."""
        if self._rich is not None:
            self._rich.update(self._task, description=f"ppo-cv {self.command}: {name} done")
