"""What every ``ppo-cv`` command shares: the error format, bounds on numbers, the pipeline and
camera options with their checks, the cameras from EXIF, progress on stderr.

Errors are one line ``ppo-cv <command>: <message>`` on stderr with exit code 2 for bad input and
:data:`NO_RESULT` when the input was accepted but no pose or model was found; warnings are
``ppo-cv <command>: warning: <message>``.
"""

from __future__ import annotations

import math
import os
import re
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer
from typer.core import TyperCommand, TyperGroup

if TYPE_CHECKING:  # typer brings click, or its own copy of it in recent releases
    import click

from ppo_cv.calib import implausible_intrinsics
from ppo_cv.checks import shown
from ppo_cv.limits import MAX_KEYPOINTS

__all__ = [
    "NO_RESULT",
    "SEED_MAX",
    "MAX_FEATURES_MAX",
    "RedetectBelow",
    "ExifOrientation",
    "Cameras",
    "fail",
    "with_warnings",
    "one_line",
    "error_message",
    "warn",
    "stdout_failure",
    "print_result",
    "check_range",
    "check_image_file",
    "implausible_intrinsics",
    "ignore_library_camera_warnings",
    "image_size",
    "pipeline_options",
    "given_cameras",
    "calibration_dist2",
    "exif_camera",
    "exif_note",
    "ProgressReport",
    "StageReport",
    "PanelledHelpCommand",
    "WrappedHelpGroup",
]

NO_RESULT = 1
"""Exit code of a run whose input was accepted but gave no pose (``pair``, every pair of
``pairs``) or no model (``sfm``); bad input is 2, an interrupt 130 (SIGINT) or 143 (SIGTERM)."""
SEED_MAX = 2**31 - 1  # pycolmap and OpenCV take the seed as a 32-bit signed integer
MAX_FEATURES_MAX = MAX_KEYPOINTS
WORKERS_MAX = 256
MAX_SIZE_MAX = 100_000
RATIO_RANGE = (1e-6, 1.0)
THRESHOLD_RANGE_PX = (1e-6, 100.0)
PRI_THRESHOLD_RANGE = (0.0, 1.0)
MAX_LOG10_NFA_RANGE = (-1e6, 1e6)
_PANEL = "Pipeline"

Features = Annotated[str, typer.Option(help="sift, orb or akaze.", rich_help_panel=_PANEL)]
MaxFeatures = Annotated[
    int, typer.Option(help=f"Keypoints per image (8..{MAX_FEATURES_MAX}).", rich_help_panel=_PANEL)
]
MaxSize = Annotated[
    int,
    typer.Option(
        help=f"Detect on a copy whose longer side is at most this many pixels "
        f"(32..{MAX_SIZE_MAX}; 0: full size).",
        rich_help_panel=_PANEL,
    ),
]
Ratio = Annotated[
    float,
    typer.Option(
        help="Lowe's ratio test: a match when its descriptor distance is at most this times "
        f"the second nearest's ({RATIO_RANGE[0]:g}..{RATIO_RANGE[1]:g}).",
        rich_help_panel=_PANEL,
    ),
]
Backend = Annotated[
    str,
    typer.Option(
        help="Robust E: pycolmap (LO-RANSAC) or opencv (USAC MAGSAC++).", rich_help_panel=_PANEL
    ),
]
Threshold = Annotated[
    float,
    typer.Option(
        help="RANSAC threshold, pixels of the full-size image; an image detected on a reduced "
        "copy is fitted at this times its reduction "
        f"({THRESHOLD_RANGE_PX[0]:g}..{THRESHOLD_RANGE_PX[1]:g}).",
        rich_help_panel=_PANEL,
    ),
]
Seed = Annotated[int, typer.Option(help=f"RANSAC seed (0..{SEED_MAX}).", rich_help_panel=_PANEL)]
PriThreshold = Annotated[
    float,
    typer.Option(
        "--pri-threshold",
        help="Pure rotation when PRI (mean |M2|, eq. 84) is below this "
        f"({PRI_THRESHOLD_RANGE[0]:g}..{PRI_THRESHOLD_RANGE[1]:g}; paper: 0.015).",
        rich_help_panel=_PANEL,
    ),
]
MaxLog10Nfa = Annotated[
    float,
    typer.Option(
        "--max-log10-nfa",
        help="Significance bar: a pose only when log10 of the number of false alarms of its "
        f"consensus is at most this ({MAX_LOG10_NFA_RANGE[0]:g}..{MAX_LOG10_NFA_RANGE[1]:g}; "
        "lower is stricter; inf disables the test).",
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
        f"threshold and keep the consensus chance explains less (0..{MAX_FEATURES_MAX}; 0: "
        "never).",
        rich_help_panel=_PANEL,
    ),
]
KOption = Annotated[
    str | None,
    typer.Option(
        "--K",
        help="Intrinsics in pixels, fx,fy,cx,cy or the 9 numbers of K (none: --calib, else the "
        "EXIF focal length, with a warning).",
    ),
]
K2Option = Annotated[
    str | None, typer.Option("--K2", help="Intrinsics of camera 2 (default: --K).")
]
CalibOption = Annotated[
    Path | None,
    typer.Option(
        "--calib",
        help="Calibration file: OpenCV YAML/XML, COLMAP cameras.txt, JSON, or a text of the 9 "
        "numbers of K (as numpy.savetxt writes it).",
    ),
]
ExifOrientation = Annotated[
    bool,
    typer.Option(
        "--exif-orientation/--no-exif-orientation",
        help="Turn each photo upright as its EXIF orientation says (--no-exif-orientation: "
        "the pixels as stored, for a stale tag).",
    ),
]
Overwrite = Annotated[
    bool,
    typer.Option("--overwrite", help="Replace an existing output (never done without it)."),
]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="No progress on stderr.")]


def _refusing_empty(convert: Callable) -> Callable:
    """``convert`` of a path parameter, refusing the empty text: ``Path("")`` is the current
    folder, so an unset shell variable (``ppo-cv pairs "$PAIRS" "$DIR"``) would read it, or
    name ``.`` in its errors."""

    def checked(value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str) and not value:
            message = "the path is empty (an unset variable?); give a name"
            raise typer.BadParameter(message, ctx, param)
        return convert(value, param, ctx)

    return checked


class PanelledHelpCommand(TyperCommand):
    """A command whose ``--help`` is plain text wrapped to the terminal, every option name whole
    on its own line when it is long, the options grouped under their ``rich_help_panel``; its
    path arguments and options refuse an empty path.

    typer's tables cut long option names (``--no-exif-orientation``) and words of the help at
    80 columns.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        for param in self.params:
            if getattr(param.type, "name", None) == "path":
                param.type.convert = _refusing_empty(param.type.convert)

    def collect_usage_pieces(self, ctx: click.Context) -> list[str]:
        """``[OPTIONS] PAIRS_FILE IMAGE_DIR``: each argument by its metavar, the upper-case
        name the help text uses, in brackets when optional (typer writes ``{pairs_file}``)."""
        pieces = [self.options_metavar] if self.options_metavar else []
        for param in self.get_params(ctx):
            if param.param_type_name == "argument":
                name = param.metavar or (param.name or "").upper()
                pieces.append(name if param.required else f"[{name}]")
        return pieces

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        sections: dict[str, list[tuple[str, str]]] = {"Arguments": [], "Options": []}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is None:
                continue
            if param.param_type_name == "argument":
                title = "Arguments"
            else:
                title = getattr(param, "rich_help_panel", None) or "Options"
            sections.setdefault(title, []).append(record)
        for title, records in sections.items():
            if records:
                with formatter.section(title):
                    formatter.write_dl(records)


COMMAND_ORDER = ("pair", "pairs", "sfm", "synth", "demo")
"""The order ``ppo-cv --help`` lists the commands in: one pair, many pairs, a reconstruction,
then rendered data and the demo."""


class WrappedHelpGroup(TyperGroup):
    """The ``ppo-cv`` group: its ``--help`` gives each command's first sentence whole, wrapped,
    where click cuts it at the terminal width with an ellipsis. It lists the commands in the
    order of :data:`COMMAND_ORDER`, any other after them."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        names = super().list_commands(ctx)
        return sorted(names, key=lambda n: COMMAND_ORDER.index(n) if n in COMMAND_ORDER else 99)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        records = []
        for name in self.list_commands(ctx):
            command = self.get_command(ctx, name)
            if command is not None and not command.hidden:
                records.append((name, command.get_short_help_str(limit=1_000)))
        if records:
            with formatter.section("Commands"):
                formatter.write_dl(records)


def one_line(text: str) -> str:
    """``text`` on one line, each line break in it shown as ``\\n`` and every other control
    character but a tab by its code (``\\x1b``): a file name may hold them, and a message cut at
    a line break would name another file, one holding a terminal escape would restyle the
    terminal."""
    joined = "\\n".join(text.strip().splitlines())
    return _CONTROL.sub(lambda found: f"\\x{ord(found[0]):02x}", joined)


_CONTROL = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f]")


MESSAGE_WORD_MAX = 300
"""Longest word or quoted value an error or warning line shows whole (longer ones are cut,
:func:`short_words`): a path beyond the system's limits, a value of thousands of digits."""


def short_words(text: str, width: int = MESSAGE_WORD_MAX) -> str:
    """``text`` with each quoted value (``'...'``) or word longer than ``width`` characters cut
    to ``width`` (:func:`ppo_cv.checks.cut`)."""
    from ppo_cv.checks import cut

    def short(word: re.Match) -> str:
        return f"'{cut(word[1], width)}'" if word[1] is not None else cut(word[2], width)

    return re.sub(rf"'([^']{{{width + 1},}})'|([^\s']{{{width + 1},}})", short, text)


def with_warnings(message: str, warnings: list[str]) -> str:
    """``message``, the one line of a failure, followed by each of ``warnings`` (``; warning:
    ...``): a camera that does not fit its image may be why the run found nothing."""
    return message + "".join(f"; warning: {one_line(text)}" for text in warnings)


def fail(command: str, message: str, code: int = 2) -> NoReturn:
    """Print ``ppo-cv <command>: <message>`` on one line (:func:`one_line`, long words cut by
    :func:`short_words`) on stderr and exit with ``code``."""
    typer.echo(f"ppo-cv {command}: {short_words(one_line(message)) or 'failed'}", err=True)
    raise typer.Exit(code)


_STAGING_NAME = re.compile(r"\.(?P<name>.+)\.(?:\d+|old)\.[a-z0-9_]{8}")


def error_message(exc: BaseException) -> str:
    """The one-line message of a failure: an operating-system error as its reason and the path
    the user gave (not the hidden name its output was being built under), else ``str(exc)``."""
    if isinstance(exc, OSError) and exc.strerror:
        if not exc.filename:
            return exc.strerror
        path = Path(os.fsdecode(exc.filename))
        staged = _STAGING_NAME.fullmatch(path.name)
        shown = path.parent / staged["name"] if staged else path
        return f"cannot write {shown}: {exc.strerror}" if staged else f"{exc.strerror}: {shown}"
    return str(exc) or type(exc).__name__


def stdout_failure(exc: OSError) -> str:
    """The message for a write to standard output that failed (a full disk, ``/dev/full``)."""
    return f"cannot write to standard output: {exc.strerror or exc}"


def print_result(command: str, text: str) -> None:
    """Print ``text`` and a newline on standard output; one line and exit code 2 when it cannot
    be written."""
    try:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
    except OSError as exc:
        fail(command, stdout_failure(exc))


def warn(command: str, message: str) -> None:
    """Print ``ppo-cv <command>: warning: <message>`` on stderr."""
    typer.echo(f"ppo-cv {command}: warning: {short_words(one_line(message))}", err=True)


def ignore_library_camera_warnings() -> None:
    """Silence the library's :class:`~ppo_cv.calib.ImplausibleCameraWarning`: the commands
    check their cameras themselves and say so in their own one-line warnings; and its
    :class:`~ppo_cv.consensus.GivenFeaturesReplacedWarning`: the features the commands give
    ``estimate_pair`` are their own detection of the images, which a second detection on the
    images may follow as it does without them."""
    from ppo_cv.calib import ImplausibleCameraWarning
    from ppo_cv.consensus import GivenFeaturesReplacedWarning

    warnings.filterwarnings("ignore", category=ImplausibleCameraWarning)
    warnings.filterwarnings("ignore", category=GivenFeaturesReplacedWarning)


def check_range(name: str, value: float, low: float, high: float) -> None:
    """ValueError naming the option unless ``low <= value <= high`` (NaN fails)."""
    if not (isinstance(value, (int, float)) and low <= value <= high):
        raise ValueError(
            f"{name} must be in {low:{_fmt(low)}}..{high:{_fmt(high)}}, got {shown(value)}"
        )


def _fmt(value: float) -> str:
    return "d" if isinstance(value, int) else "g"


def pipeline_options(
    features: str = "sift",
    max_features: int = 8000,
    max_size: int = 2000,
    ratio: float = 0.9,
    backend: str = "pycolmap",
    threshold: float = 1.0,
    seed: int = 0,
    pri_threshold: float | None = None,
    max_log10_nfa: float | None = None,
    plane: bool = True,
    photometric: bool = True,
    principal_point: str = "auto",
    focal_ratio: str = "auto",
    redetect_below: int = 100,
):
    """PairOptions from command-line values, each bounded up front (ValueError naming it)."""
    from ppo_cv.pipeline import PairOptions
    from ppo_cv.ppo import DEFAULT_PRI_THRESHOLD
    from ppo_cv.significance import DEFAULT_MAX_LOG10_NFA

    check_range("--seed", seed, 0, SEED_MAX)
    check_range("--max-features", max_features, 8, MAX_FEATURES_MAX)
    if max_size != 0:
        check_range("--max-size (0: full size)", max_size, 32, MAX_SIZE_MAX)
    check_range("--ratio", ratio, *RATIO_RANGE)
    check_range("--redetect-below", redetect_below, 0, MAX_FEATURES_MAX)
    check_range("--threshold (pixels)", threshold, *THRESHOLD_RANGE_PX)
    pri_threshold = DEFAULT_PRI_THRESHOLD if pri_threshold is None else pri_threshold
    check_range("--pri-threshold", pri_threshold, *PRI_THRESHOLD_RANGE)
    max_log10_nfa = DEFAULT_MAX_LOG10_NFA if max_log10_nfa is None else max_log10_nfa
    if max_log10_nfa != float("inf"):
        check_range("--max-log10-nfa", max_log10_nfa, *MAX_LOG10_NFA_RANGE)
    return PairOptions(
        features=features.lower(),
        max_features=max_features,
        max_image_size=max_size or None,
        ratio=ratio,
        backend=backend.lower(),
        ransac_threshold=threshold,
        seed=seed,
        pri_threshold=pri_threshold,
        max_log10_nfa=max_log10_nfa,
        plane=plane,
        photometric=photometric,
        principal_point=principal_point.lower(),
        focal_ratio=focal_ratio.lower(),
        redetect_below=redetect_below,
    )


@dataclass(frozen=True)
class Cameras:
    """The intrinsics and distortion of the two images of a pair (``dist``: None for none)."""

    K1: Any
    dist1: Any
    K2: Any
    dist2: Any


def calibration_dist2(num_cameras: int, K2, dist1, dist2, file_dist2):
    """Image 2's distortion with a calibration file of ``num_cameras``: ``--dist2`` (parsed
    ``dist2``); else none beside ``--K2``; else ``--dist`` (parsed ``dist1``) when the file
    describes one camera of both images, as with ``--K``; else the file's ``file_dist2``."""
    if dist2 is not None:
        return dist2
    if K2 is not None:
        return None
    return dist1 if num_cameras == 1 and dist1 is not None else file_dist2


def given_cameras(K, K2, dist, dist2, calib) -> Cameras | None:
    """The cameras the options give (``--K``, ``--K2``, ``--dist``, ``--dist2``, ``--calib``);
    None when they give no intrinsics. ValueError naming a malformed or conflicting option."""
    from ppo_cv.calib import load_calibration, parse_distortion, parse_intrinsics

    d1 = parse_distortion(dist, "--dist") if dist is not None else None
    d2 = parse_distortion(dist2, "--dist2") if dist2 is not None else None
    if calib is not None:
        if K is not None:
            raise ValueError("give either --K or --calib, not both")
        cameras = load_calibration(calib)
        first, second = cameras[0], cameras[1] if len(cameras) > 1 else cameras[0]
        K2v = parse_intrinsics(K2, "--K2") if K2 is not None else second.K
        d2 = calibration_dist2(len(cameras), K2, d1, d2, second.dist)
        return Cameras(first.K, d1 if d1 is not None else first.dist, K2v, d2)
    if K is None:
        if K2 is not None:
            raise ValueError("--K2 needs --K (or --calib) for the first camera")
        return None
    K1 = parse_intrinsics(K, "--K")
    if K2 is not None:
        return Cameras(K1, d1, parse_intrinsics(K2, "--K2"), d2)
    return Cameras(K1, d1, K1, d2 if d2 is not None else d1)


def exif_camera(path, exif_orientation: bool = True) -> tuple[Any, bool, list[str]]:
    """``(K, from_exif, warnings)`` of the camera guessed from an image's EXIF.

    ``from_exif`` is False when the image has no usable EXIF focal length (the focal length is
    then 1.2 times the larger image side). The warnings say when the EXIF pixel dimensions are
    not those of the image (a resized copy's focal length was scaled to it, a cropped copy's may
    not fit) and when the horizontal field of view the focal length implies lies outside
    :data:`ppo_cv.calib.EXIF_PLAUSIBLE_FIELD_DEG`; and, with ``from_exif`` False,
    when an EXIF focal length was not used (:data:`ppo_cv.calib.EXIF_FIELD_RANGE_DEG`).
    """
    from ppo_cv.calib import (
        EXIF_PLAUSIBLE_FIELD_DEG,
        ImplausibleCameraWarning,
        camera_from_exif,
        field_of_view_deg,
    )
    from ppo_cv.images import exif_layout

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImplausibleCameraWarning)
        camera, from_exif = camera_from_exif(path, exif_orientation)
    doubts = [str(w.message) for w in caught if issubclass(w.category, ImplausibleCameraWarning)]
    for other in (w for w in caught if not issubclass(w.category, ImplausibleCameraWarning)):
        warnings.warn_explicit(other.message, other.category, other.filename, other.lineno)
    K = camera.K
    if not from_exif:
        return K, False, doubts
    width, height = round(2 * K[0, 2]), round(2 * K[1, 2])
    doubt = _recorded_size_doubt(exif_layout(path), (width, height), K[0, 0])
    if doubt is not None:
        doubts.append(f"{path}: {doubt}")
    field, (low, high) = field_of_view_deg(K[0, 0], width), EXIF_PLAUSIBLE_FIELD_DEG
    if not low <= field <= high:
        doubts.append(
            f"{path}: the EXIF focal length f={K[0, 0]:.1f} px gives a {field:.1f} deg "
            f"horizontal field of view at {width} px wide, outside {low:g}..{high:g} deg; pass "
            "--K or --calib"
        )
    return K, True, doubts


def _recorded_size_doubt(layout: Any, size: tuple[int, int], focal: float) -> str | None:
    """What the EXIF's recorded pixel size, when it is not the image's ``size`` (width,
    height), says of the focal length ``focal`` (pixels) read from it: a resized copy's was
    scaled (:func:`ppo_cv.calib.exif_focal_scale`) or, from a 35 mm equivalent or pycolmap's
    table of sensor widths, fits as it is (None); a crop's may not fit. The recorded size is
    the camera's (:attr:`ppo_cv.images.ExifLayout.camera_size`), named by its tags where it is
    the interoperability tags' and not ``PixelXDimension``'s."""
    from ppo_cv.calib import resize_scale

    recorded = layout.camera_size
    if recorded is None or sorted(recorded) == sorted(size):
        return None
    said = f"the EXIF says the photo was {recorded[0]}x{recorded[1]} pixels, the image is "
    if recorded != layout.pixel_size:
        said = (
            f"the EXIF's RelatedImageWidth and RelatedImageLength say the camera wrote "
            f"{recorded[0]}x{recorded[1]} pixels ({_pixel_dimensions(layout.pixel_size)}), the "
            "image is "
        )
    scale = resize_scale(recorded, size)
    if scale is None:
        return (
            f"{said}{size[0]}x{size[1]}, another aspect ratio (cropped?), so its EXIF focal "
            "length may not fit; pass --K or --calib"
        )
    if not layout.focal_in_recorded_pixels:
        return None
    return (
        f"{said}{size[0]}x{size[1]}, a resized copy: its EXIF focal length, in the original's "
        f"pixels, is scaled by {scale:.4g} to f={focal:.1f} px (not right if it was cropped "
        "too; pass --K or --calib)"
    )


def _pixel_dimensions(size: tuple[int, int] | None) -> str:
    """What ``PixelXDimension`` x ``PixelYDimension`` say beside a larger related size."""
    if size is None:
        return "PixelXDimension and PixelYDimension are missing"
    return f"PixelXDimension and PixelYDimension say {size[0]}x{size[1]}, rewritten by a resizer"


def exif_note(focals: tuple[float, float], found: tuple[bool, bool], names=("", "")) -> str:
    """The warning of intrinsics taken from EXIF: which images had a focal length, what was
    guessed for the others (``names``: of the two images, for the one without)."""
    focal = f"f={focals[0]:.1f} and {focals[1]:.1f} px"
    if all(found):
        return (
            f"no intrinsics given: using the EXIF focal lengths ({focal}, centred principal "
            "point); pass --K or --calib for accurate results"
        )
    where = "either image" if not any(found) else (names[1] if found[0] else names[0])
    return (
        f"no intrinsics given and no EXIF focal length in {where}: guessing {focal} "
        "(1.2 x image size); the pose will be rough, pass --K or --calib"
    )


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


def read_size(path: str | os.PathLike, exif_orientation: bool = True) -> tuple[int, int] | None:
    """``(width, height)`` of the image as the commands read it: by its header, turned where
    its EXIF orientation turns it a quarter and ``exif_orientation``; None when unknown."""
    return read_layout(path, exif_orientation)[0]


def read_layout(
    path: str | os.PathLike, exif_orientation: bool = True
) -> tuple[tuple[int, int] | None, bool]:
    """:func:`read_size`, and whether the EXIF orientation turned the image a quarter (False
    when the size is unknown or ``exif_orientation`` is off)."""
    from ppo_cv.images import exif_layout

    size = image_size(path)
    turned = size is not None and exif_orientation and exif_layout(path).turned
    return (size[::-1] if turned else size), turned


def upright_model_warning(paths, exif_orientation: bool, model: str) -> list[str]:
    """The warning that the COLMAP ``model`` describes images shown turned or flipped by their
    EXIF orientation (``exif_orientation``), whose pixels COLMAP reads as stored; none when no
    image of ``paths`` has such an orientation."""
    from ppo_cv.images import exif_layout

    if not exif_orientation:
        return []
    names = [Path(p).name for p in paths if exif_layout(p).orientation not in (None, 1)]
    if not names:
        return []
    listed = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
    its, it = ("its", "it") if len(names) == 1 else ("their", "them")
    return [
        f"{model} describes {listed} as {its} EXIF orientation turns {it} upright, but COLMAP "
        "reads the pixels as stored: give COLMAP upright copies, or pass --no-exif-orientation "
        "(with the intrinsics of the stored pixels) for a model of the files as they are"
    ]


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

    Pass :meth:`stage` as the ``progress`` of :func:`ppo_cv.pipeline.estimate_pair`; ``done``
    lists the stages ended so far (after ``load`` the pipeline has accepted its input).
    """

    def __init__(self, command: str, quiet: bool = False) -> None:
        self.command, self.quiet = command, quiet
        self.done: list[str] = []
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
        self.done.append(name)
        if self._rich is not None:
            self._rich.update(self._task, description=f"ppo-cv {self.command}: {name} done")
