"""``ppo-cv pairs``: many image pairs in parallel, one JSON line each, AUC given ground truth.

Each image's features are computed once per run (a cache keyed by the resolved path and the
feature options, filled up front by the workers and shared through ``.npz`` files in a temporary
folder); ``--no-cache`` detects per pair, as :func:`~ppo_cv.pipeline.estimate_pair` alone does.
Each process also keeps the images it decoded last (and their features), read-only, for the next
pairs that name them (:data:`RECENT_BYTES`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    NO_RESULT,
    WORKERS_MAX,
    Backend,
    CalibOption,
    Cameras,
    ExifOrientation,
    Features,
    FocalRatio,
    K2Option,
    KOption,
    MaxFeatures,
    MaxLog10Nfa,
    MaxSize,
    Overwrite,
    Photometric,
    Plane,
    PrincipalPoint,
    PriThreshold,
    ProgressReport,
    Quiet,
    Ratio,
    RedetectBelow,
    Seed,
    Threshold,
    check_image_file,
    check_range,
    error_message,
    exif_camera,
    fail,
    given_cameras,
    ignore_library_camera_warnings,
    implausible_intrinsics,
    one_line,
    pipeline_options,
    print_result,
    short_words,
    stdout_failure,
    warn,
)

__all__ = [
    "PAIRS_FILE_FORMAT",
    "register",
    "run_pairs",
    "read_pairs",
    "pose_errors",
    "pose_auc",
    "FeatureCache",
]

_ZERO_TRANSLATION = 1e-9
MAX_TRIALS_MAX = 10_000_000


PAIRS_FILE_FORMAT = (
    "One pair a line: 'name1 name2', optionally followed by '0 0', the 9 numbers of K1 and "
    "the 9 of K2 (row-major), optionally followed by the 16 numbers of the ground-truth "
    "motion T_1to2 (row-major 4x4, X2 = R X1 + t). The '0 0' are the EXIF orientations of "
    "the two images in the format of the SuperGlue / LoFTR pair lists: they must be 0 (turn "
    "a rotated image upright rather than say so). "
    "Names are relative to IMAGE_DIR; a name with spaces goes in double quotes; '#' starts a "
    "comment, on its own line or after the fields."
)
_FIELD = re.compile(r'\s*(?:"([^"]*)"|([^\s"]+))(?=\s|$)')


def _fields(line: str) -> list[str]:
    """The fields of a pairs-file line: separated by whitespace, a double-quoted name kept
    whole, a field starting with '#' ending the line; ValueError for a double quote that does
    not enclose a whole field."""
    fields, position = [], 0
    while line[position:].strip() and not line[position:].lstrip().startswith("#"):
        match = _FIELD.match(line, position)
        if match is None:
            rest = line[position:].strip()
            raise ValueError(
                f"a double quote is not closed or does not enclose a whole name: {rest!r}"
            )
        quoted, plain = match.groups()
        fields.append(plain if quoted is None else quoted)
        position = match.end()
    return fields


def _remedy(parts: list[str]) -> str:
    """What a line of the wrong number of fields most likely lacks."""
    if len(parts) == 1:
        separator = next((c for c in ",;" if c in parts[0]), None)
        if separator is not None:
            return f"a pair needs two image names, separated by spaces, not {separator!r}"
        return "a pair needs two image names"
    try:
        [float(part) for part in parts[2:]]
    except ValueError:
        return "put a name with spaces in double quotes"
    return "after the names: 0 0, then 9 numbers for K1, 9 for K2 and optionally 16 for T_1to2"


def read_pairs(pairs_file: Path, K: str | None = None, cameras=None) -> list[dict]:
    """Rows of a pairs file: names, intrinsics and, when present, the ground-truth motion.

    Lines are ``name1 name2 [0 0 K1(9) K2(9) [T_1to2(16)]]`` (:data:`PAIRS_FILE_FORMAT`); the two
    fields after the names (EXIF rotations, in the format's origin) must be 0. Either every line
    carries a ground-truth ``T`` (a rigid motion: a proper rotation, bottom row 0 0 0 1) or none
    does; a ValueError names the first line that breaks a rule. A line without intrinsics takes
    ``cameras`` (:class:`~ppo_cv.cli.common.Cameras`, with their distortion) or ``K`` for both
    images, else ``K1`` and ``K2`` are None (the caller guesses them from EXIF); a line with
    intrinsics has no distortion. ``shared_K`` marks the lines whose two images take one given
    camera matrix. ``repeats`` is the number of the first line with the same fields (the
    line's own number when it is the first).
    """
    import numpy as np

    from ppo_cv.calib import parse_intrinsics, read_text_file
    from ppo_cv.checks import as_camera_matrix

    _require_regular_file(pairs_file, "pairs file")
    if cameras is None and K:
        matrix = parse_intrinsics(K, "--K")
        cameras = Cameras(matrix, None, matrix, None)
    one_matrix = cameras is not None and np.array_equal(cameras.K1, cameras.K2)
    text = read_text_file(pairs_file, "pairs file")
    rows, first_gt, seen = [], None, {}
    for number, line in enumerate(text.splitlines(), 1):
        where = f"{pairs_file}:{number}"
        try:  # a byte-order mark within: files saved by Windows editors, concatenated
            parts = _fields(line.lstrip("\ufeff"))
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        if not parts:
            continue
        if len(parts) not in (2, 4, 22, 38):
            raise ValueError(
                f"{where}: expected 'name1 name2 [0 0 K1(9) K2(9) [T(16)]]', "
                f"got {len(parts)} field{'' if len(parts) == 1 else 's'} ({_remedy(parts)})"
            )
        row = {"image1": parts[0], "image2": parts[1], "K1": None, "K2": None, "T": None}
        if cameras is not None:
            row.update(K1=cameras.K1, K2=cameras.K2, dist1=cameras.dist1, dist2=cameras.dist2)
        row["given_cameras"] = cameras is not None and len(parts) < 22
        row["shared_K"] = one_matrix and row["given_cameras"]
        try:
            if len(parts) >= 4:
                _require_unturned(parts[2:4])
            if len(parts) >= 22:
                row["K1"] = parse_intrinsics(",".join(parts[4:13]), "K1")
                row["K2"] = parse_intrinsics(",".join(parts[13:22]), "K2")
                row["dist1"] = row["dist2"] = None  # the line's own cameras, not --calib's
            if len(parts) == 38:
                row["T"] = _motion(parts[22:38])
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        if row["K1"] is not None:
            row["K1"] = as_camera_matrix(row["K1"], "K1")
            row["K2"] = as_camera_matrix(row["K2"], "K2")
        has_gt = row["T"] is not None
        if first_gt is None:
            first_gt = (has_gt, number)
        elif has_gt != first_gt[0]:
            given, missing = (number, first_gt[1]) if has_gt else (first_gt[1], number)
            raise ValueError(
                f"{pairs_file}:{number}: line {given} carries a ground-truth motion and line "
                f"{missing} does not; give it on every line or on none"
            )
        row["line"] = number
        row["repeats"] = seen.setdefault(tuple(parts), number)
        rows.append(row)
    if not rows:
        raise ValueError(f"no pairs in {pairs_file}")
    return rows


RIGID_TOLERANCE = 1e-4
"""Largest deviation of a ground-truth rotation from orthonormal (``|R^T R - I|``) accepted:
files print their numbers to about six digits."""


def _require_some_image(rows: list[dict], image_dir: Path, pairs_file: Path) -> None:
    """ValueError when the image folder holds none of the images the pairs file names: the
    wrong folder, not pairs that each fail."""
    names = dict.fromkeys(row[key] for row in rows for key in ("image1", "image2"))
    if not any((image_dir / name).exists() for name in names):
        from ppo_cv.images import alike_remedy

        first = next(iter(names))
        remedy = alike_remedy(image_dir / first) or "names are relative to the image folder"
        raise ValueError(
            f"image folder {image_dir} holds none of the {len(names)} images {pairs_file} names "
            f"(the first: {first}); {remedy}"
        )


def _warn_repeated_lines(rows: list[dict], pairs_file: Path) -> None:
    """One warning naming the lines that repeat an earlier line's fields: they run again."""
    repeated = [row for row in rows if row["repeats"] != row["line"]]
    if repeated:
        pairs = ", ".join(f"{row['line']} (= {row['repeats']})" for row in repeated[:5])
        more = f" and {len(repeated) - 5} more" if len(repeated) > 5 else ""
        lines = f"lines {pairs}{more} repeat" if len(repeated) > 1 else f"line {pairs} repeats"
        warn(
            "pairs",
            f"{pairs_file}: {lines} an earlier line; each runs again and gives its own JSON line",
        )


def _warn_unused_cameras(rows: list[dict], pairs_file: Path, given: str) -> None:
    """One warning when the cameras of the command line (``given``) serve no line: each line
    carries its own, which stand."""
    if not any(row["given_cameras"] for row in rows):
        verb = "are" if " and " in given else "is"
        warn("pairs", f"{given} {verb} not used: every line of {pairs_file} carries its own "
                      "camera matrices, which stand")  # fmt: skip


def _require_regular_file(path: Path, what: str) -> None:
    """ValueError naming what ``path`` is when it is not an existing regular file; ``-``, which
    is no file here, is named as standard input, which is not read (``-o -`` writes to
    standard output)."""
    from ppo_cv.images import file_mode

    if str(path) == "-" and not path.exists():
        raise ValueError(f"{what} '-': standard input is not read; give the {what}'s path")
    file_mode(path, what)
    if path.is_dir():
        raise ValueError(f"{what} {path} is a directory")
    if not path.is_file():
        raise ValueError(f"{what} {path} is not a regular file (a pipe, socket or device?)")


def _require_order(pairs_file: Path, image_dir: Path) -> None:
    """ValueError when the pairs file is a folder and the image folder a file: the two
    arguments given the other way round."""
    if pairs_file.is_dir() and image_dir.is_file():
        raise ValueError(
            f"pairs file {pairs_file} is a directory and image folder {image_dir} a file: "
            "the pairs file comes first, ppo-cv pairs PAIRS_FILE IMAGE_DIR"
        )


def _require_unturned(fields: list[str]) -> None:
    """The two EXIF rotation fields of a line, which must read 0: turned images are not read
    turned."""
    if fields != ["0", "0"]:
        try:
            turns = [float(field) for field in fields]
        except ValueError:
            raise ValueError(
                f"fields 3 and 4 must be 0 0, got {' '.join(fields)} (two names with spaces? "
                "put each in double quotes)"
            ) from None
        if any(turns):
            raise ValueError(
                f"fields 3 and 4 (EXIF rotations) must be 0 0, got {' '.join(fields)}: turn "
                "the images upright instead"
            )


def _motion(fields: list[str]):
    """The ground truth ``T_1to2`` of 16 text fields, checked as a rigid motion."""
    import numpy as np

    try:
        T = np.array([float(field) for field in fields]).reshape(4, 4)
    except ValueError:
        raise ValueError(
            f"the ground-truth T_1to2 must be numbers, got {' '.join(fields)}"
        ) from None
    if not np.all(np.isfinite(T)):
        raise ValueError("the ground-truth T_1to2 has NaN or infinite entries")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=1e-9):
        raise ValueError(
            f"the ground-truth T_1to2 must end with the row 0 0 0 1, got "
            f"{' '.join(f'{v:g}' for v in T[3])}"
        )
    R = T[:3, :3]
    deviation = float(np.abs(R.T @ R - np.eye(3)).max())
    if deviation > RIGID_TOLERANCE:
        hint = _rounding_hint(fields[:3] + fields[4:7] + fields[8:11], R)
        raise ValueError(
            f"the ground-truth rotation is not orthonormal (|R^T R - I| up to {deviation:.2g}, "
            f"above {RIGID_TOLERANCE:g}){hint}"
        )
    if np.linalg.det(R) < 0:
        raise ValueError(
            "the ground-truth rotation has determinant -1: a reflection, not a rigid motion"
        )
    return T


def _rounding_hint(fields: list[str], R) -> str:
    """The end of the message for a ground-truth rotation ``R`` (3x3) of text ``fields`` (its 9
    entries) that is a rotation rounded to the 2 to 5 decimals written (nearer the nearest
    rotation than the 9 entries' rounding, ``1.5 x 10^-decimals`` in Frobenius norm): that they
    need more decimals; empty otherwise (a shear)."""
    import numpy as np

    decimals = max((len(f.partition(".")[2]) for f in fields if "e" not in f.lower()), default=0)
    U, _, Vt = np.linalg.svd(R)
    if not 2 <= decimals <= 5 or np.linalg.norm(R - U @ Vt) > 1.5 * 10.0**-decimals:
        return ""
    return f": its entries, written to {decimals} decimals, are rounded too far; write 6 or more"


def pose_errors(R, t, T) -> dict:
    """Rotation, translation-direction and pose errors (degrees) against a ground truth ``T``.

    The translation error is sign-free (the angle between the lines of ``t`` and the true t).
    The pose error is the larger of the two; where the true t is zero (a pure rotation) the
    direction is undefined, ``t_err_deg`` is None and the pose error is the rotation error.
    """
    import numpy as np

    from ppo_cv.checks import as_finite_array, as_vector3
    from ppo_cv.metrics import direction_error_deg, rotation_error_deg

    T = as_finite_array(T, "T")
    if T.shape not in ((4, 4), (3, 4)):
        raise ValueError(f"T must be a 4x4 (or 3x4) motion [R | t], got shape {T.shape}")
    if not as_vector3(t, "t").any():
        raise ValueError("t is zero: it has no direction to compare")
    R_gt, t_gt = T[:3, :3], T[:3, 3]
    r_err = rotation_error_deg(R, R_gt)
    if float(np.linalg.norm(t_gt)) <= _ZERO_TRANSLATION:
        return {"R_err_deg": r_err, "t_err_deg": None, "pose_err_deg": r_err}
    t_err = direction_error_deg(t, t_gt, signed=False)
    return {"R_err_deg": r_err, "t_err_deg": t_err, "pose_err_deg": max(r_err, t_err)}


def pose_auc(errors, thresholds=(5.0, 10.0, 20.0)) -> list[float]:
    """Area under the recall curve of pose errors (degrees) up to each threshold, in [0, 1]:
    ``errors`` a sequence of finite numbers >= 0 (a failure counted as 180), ``thresholds``
    positive; ValueError or TypeError naming the argument otherwise."""
    import numpy as np

    from ppo_cv.checks import as_finite_array, as_positive

    errors = as_finite_array(errors, "errors")
    if errors.ndim != 1:
        raise ValueError(f"errors must be a sequence of numbers, got shape {errors.shape}")
    if (errors < 0).any():
        raise ValueError(f"errors must be angles >= 0, got {errors.min():g}")
    thresholds = [as_positive(threshold, "thresholds") for threshold in thresholds]
    errors = np.sort(errors)
    recall = np.arange(1, errors.size + 1) / errors.size
    errors, recall = np.r_[0.0, errors], np.r_[0.0, recall]
    areas = []
    for threshold in thresholds:
        last = np.searchsorted(errors, threshold)
        e = np.r_[errors[:last], threshold]
        r = np.r_[recall[:last], recall[last - 1]]
        areas.append(float(np.trapezoid(r, x=e) / threshold))
    return areas


def auc_table(results: list[dict]) -> str:
    """Markdown table of the AUC of the pose errors, failures counted as 180 degrees."""
    errors = [r.get("pose_err_deg", 180.0) if "error" not in r else 180.0 for r in results]
    auc = pose_auc(errors)
    failed = sum("error" in r for r in results)
    rotations = sum(r.get("t_err_deg", 0.0) is None for r in results)
    note = (
        "pose error = max(rotation error, translation-direction error), degrees; failed pairs "
        "count as 180"
    )
    if rotations:
        note += f"; rotation error alone for the {rotations} pairs whose true t is zero"
    return (
        f"{note}\n| pairs | failed | AUC@5 | AUC@10 | AUC@20 |\n|---|---|---|---|---|\n"
        f"| {len(results)} | {failed} | {100 * auc[0]:.1f} | {100 * auc[1]:.1f} "
        f"| {100 * auc[2]:.1f} |"
    )


def _require_one_size(
    rows: list[dict], image_dir: Path, pairs_file: Path, calib, exif_orientation: bool
) -> None:
    """ValueError naming the first line whose images, of two sizes as they are read (by their
    headers, turned where the EXIF orientation turns them and ``exif_orientation``), would
    share one camera matrix (``--K``, or a calibration ``calib`` that states no image size:
    one that states it is scaled to each image; as :func:`ppo_cv.pipeline.estimate_pair`
    refuses it); images whose size cannot be read are left to their pair's error."""
    from ppo_cv.calib import load_calibration

    from .common import read_size

    if calib is not None and any(c.image_size is not None for c in load_calibration(calib)):
        return
    given = "--K" if calib is None else f"--calib {calib}"
    for row in rows:
        if not row["shared_K"]:
            continue
        names = (row["image1"], row["image2"])
        paths = [image_dir / name for name in names]
        if not all(path.is_file() for path in paths):
            continue
        sizes = [read_size(path, exif_orientation) for path in paths]
        if None not in sizes and sizes[0] != sizes[1]:
            (w1, h1), (w2, h2) = sizes
            raise ValueError(
                f"{pairs_file}:{row['line']}: {names[0]} is {w1}x{h1} and {names[1]} {w2}x{h2} "
                f"pixels: one camera matrix ({given}) cannot fit both sizes; give K1 and K2 on "
                "the line"
            )


def _init_worker() -> None:
    from ppo_cv.atomic import import_pycolmap

    ignore_library_camera_warnings()

    import_pycolmap()  # first: numpy's threads, started by it, then block SIGTERM too
    import cv2

    cv2.setNumThreads(1)


@contextlib.contextmanager
def _worker_pool(workers: int):
    """A pool of ``workers`` spawned processes (None for one: run here), stopped on any error
    (:func:`ppo_cv.atomic.worker_pool`)."""
    if workers <= 1:
        yield None
        return
    from ppo_cv.atomic import worker_pool

    with worker_pool(workers, _init_worker) as pool:
        yield pool


class FeatureCache:
    """Features of each image of a run, computed once and kept as ``.npz`` files in ``folder``.

    Keyed by the resolved path and the feature options (kind, ``max_features``,
    ``max_image_size``); an image that cannot be read keeps its error message instead.
    """

    def __init__(
        self, folder: str | os.PathLike, options, exif_orientation: bool = True
    ) -> None:
        self.folder = Path(folder)
        self.options = options
        self.exif_orientation = exif_orientation
        self.files: dict[tuple, str] = {}
        self.errors: dict[tuple, str] = {}

    def key(self, path: str | os.PathLike) -> tuple:
        """The cache key of an image path under this run's options."""
        o = self.options
        return (os.path.realpath(path), o.features, o.max_features, o.max_image_size)

    def jobs(self, paths) -> list[tuple]:
        """One detection job per image not yet cached: ``(path, options, npz file,
        exif_orientation)``."""
        keys = dict.fromkeys(self.key(p) for p in paths)
        fresh = [k for k in keys if k not in self.files and k not in self.errors]
        start = len(self.files) + len(self.errors)
        return [
            (k[0], self.options, str(self.folder / f"{start + i}.npz"), self.exif_orientation)
            for i, k in enumerate(fresh)
        ]

    def store(self, path: str, outcome: tuple[str, str]) -> None:
        """Record a job's outcome: ``("file", npz path)`` or ``("error", message)``."""
        kind, value = outcome
        (self.files if kind == "file" else self.errors)[self.key(path)] = value

    def lookup(self, path: str | os.PathLike) -> tuple[str, str]:
        """``("file", npz path)`` or ``("error", message)`` for an image of the run."""
        key = self.key(path)
        return ("error", self.errors[key]) if key in self.errors else ("file", self.files[key])


def _features_job(job: tuple) -> tuple[str, str]:
    """Detect one image's features into an ``.npz`` file; an unreadable image gives its error.

    SIFT is detected at the threshold of a second detection when ``redetect_below`` may ask
    for one: ``estimate_pair`` thins the features to the first threshold itself, and a weak
    pair then needs no detection of its own. When that detection reaches ``max_features``,
    OpenCV keeps the strongest in another order than a detection at the first threshold
    gives, so the image is detected at the first threshold instead.
    """
    import numpy as np

    from ppo_cv import features as features_module
    from ppo_cv.pipeline import REDETECT_THRESHOLD_SCALE, load_image

    path, options, target, exif_orientation = job
    denser = options.features == "sift" and options.redetect_below > 0
    try:
        check_image_file(path)
        image = load_image(path, exif_orientation=exif_orientation)
        detect = (image, options.features, options.max_features, options.max_image_size)
        found = features_module.detect_features(
            *detect, threshold_scale=REDETECT_THRESHOLD_SCALE if denser else 1.0, name=path
        )
        if denser and len(found) >= options.max_features:  # cut by strength, in another order
            found = features_module.detect_features(*detect, name=path)
    except Exception as exc:  # one image's failure is its pairs' error line, not the batch's
        return "error", _error_line(exc, path)
    np.savez(
        target, keypoints=found.keypoints, descriptors=found.descriptors, kind=found.kind,
        responses=found.responses, threshold_scale=found.threshold_scale,
    )  # fmt: skip
    return "file", target


def _error_line(exc: Exception, path: str | None = None) -> str:
    """The first line of an error's message; an unexpected error also named by its type (and
    ``path``), as it may not say what it concerns."""
    message = (str(exc).strip().splitlines() or [""])[0]
    if isinstance(exc, (ValueError, OSError)):
        return message or type(exc).__name__
    where = f" on {path}" if path else ""
    return f"{type(exc).__name__}{where}: {message}" if message else f"{type(exc).__name__}{where}"


def _backslash_remedy(paths: tuple[Path, Path]) -> str:
    """The remedy for a name written with Windows' separator (``sub\\a.png``) that names no
    file where the same name with ``/`` does; empty otherwise."""
    for path in paths:
        forward = Path(str(path).replace("\\", "/"))
        if "\\" in str(path) and not path.exists() and forward.is_file():
            return f" ({forward} exists: separate folders in names with /, not \\)"
    return ""


def _load_features(target: str):
    import numpy as np

    from ppo_cv.features import Features

    with np.load(target) as data:
        return Features(
            data["keypoints"], data["descriptors"], str(data["kind"]),
            data["responses"], float(data["threshold_scale"]),
        )  # fmt: skip


RECENT_BYTES = 128 * 2**20
"""Bytes of decoded images and loaded features each process of ``ppo-cv pairs`` keeps for the
next pairs that name the same image (the least recently used go first)."""


class _Recent:
    """The arrays last read by a process, up to :data:`RECENT_BYTES`, read-only: an image is
    decoded (and its features loaded) once for all the consecutive pairs that name it."""

    def __init__(self, budget: int = RECENT_BYTES) -> None:
        self.budget = budget
        self.entries: dict[tuple, tuple[object, int]] = {}

    def get(self, key: tuple, read: Callable[[], object], arrays: Callable[[object], list]):
        """The value of ``key``, read by ``read()`` when not kept; ``arrays(value)`` lists
        its arrays (made read-only and counted against the budget)."""
        if key in self.entries:
            self.entries[key] = self.entries.pop(key)  # most recent last
            return self.entries[key][0]
        value = read()
        held = arrays(value)
        for array in held:
            array.flags.writeable = False
        size = sum(array.nbytes for array in held)
        if size > self.budget:
            return value
        while sum(n for _, n in self.entries.values()) + size > self.budget:
            self.entries.pop(next(iter(self.entries)))
        self.entries[key] = (value, size)
        return value

    def clear(self) -> None:
        """Forget every entry."""
        self.entries.clear()


_recent = _Recent()


def _recent_image(path: Path, exif_orientation: bool):
    """:func:`ppo_cv.pipeline.load_image` of ``path``, decoded again only when the file
    changed (its size or modification time) or left :data:`_recent`."""
    from ppo_cv.pipeline import load_image

    try:
        stat = os.stat(path)
    except OSError:
        return load_image(path, exif_orientation=exif_orientation)  # its error names the file
    key = ("image", os.path.realpath(path), stat.st_mtime_ns, stat.st_size, exif_orientation)
    return _recent.get(key, lambda: load_image(path, exif_orientation=exif_orientation), _one)


def _recent_features(target: str):
    """:func:`_load_features` of a cache file (written once per run), from :data:`_recent`."""
    return _recent.get(
        ("features", target),
        lambda: _load_features(target),
        lambda f: [a for a in (f.keypoints, f.descriptors, f.responses) if a is not None],
    )


def _own_detection(features, image: str):
    """The run's own detection of ``image``; ValueError naming the image, not the features,
    when it holds too few to match (a blank image), as :func:`ppo_cv.estimate_pair` names an
    image it detects itself."""
    from ppo_cv.consensus import require_enough_features

    require_enough_features(features, image)
    return features


def _one(array) -> list:
    return [array]


def _pair_job(job: tuple) -> dict:
    """One pair: a JSON-ready dict, with ``error`` instead of a pose on failure."""
    from ppo_cv.export import result_to_dict
    from ppo_cv.pipeline import estimate_pair

    row, image_dir, options, cached, exif_orientation = job
    names = {"image1": row["image1"], "image2": row["image2"]}
    paths = (Path(image_dir) / row["image1"], Path(image_dir) / row["image2"])
    try:
        given = {}
        if cached is not None:
            for (kind, value), name in zip(cached, ("features1", "features2"), strict=True):
                if kind == "error":
                    raise ValueError(value)
                given[name] = _own_detection(_recent_features(value), "image" + name[-1])
        images = [_recent_image(path, exif_orientation) for path in paths]
        if row["K1"] is None or row["K2"] is None:
            raise ValueError("no camera: the EXIF of an image could not be read; pass --K")
        dist = (row.get("dist1"), row.get("dist2"))
        result = estimate_pair(*images, row["K1"], row["K2"], *dist, options=options, **given)
        note = None
        if row.get("guessed_cameras"):
            from ppo_cv.guessed_camera import decide_with_fitted_focal

            result, note = decide_with_fitted_focal(result, images, options, **given)
    except Exception as exc:  # one pair's failure is its error line, not the batch's
        return {**names, "error": _error_line(exc) + _backslash_remedy(paths)}
    data = result_to_dict(result, **names)
    if note:
        data["camera_note"] = note
    if row["T"] is not None:
        data.update(pose_errors(result.R, result.t, row["T"]))
    return data


def _run_all(function, jobs, pool, report: ProgressReport):
    """Results of ``function`` over ``jobs`` in order, in ``pool`` (or here when None)."""
    iterator = map(function, jobs) if pool is None else pool.imap(function, jobs)
    for outcome in iterator:
        report.advance()
        yield outcome


def _fit_calibration(
    rows: list[dict], image_dir: Path, calib, K2, exif_orientation: bool = True
) -> None:
    """Fit the cameras of ``calib`` to the images of the rows that take them, by the sizes in
    the image headers, turned where the EXIF orientation turns the image as it is read
    (``exif_orientation``; :func:`ppo_cv.calib.fit_to_image`; ``--K2`` replaces the second
    one), warning once for all the images scaled; a ValueError for another aspect ratio."""
    from ppo_cv.calib import fit_to_image, load_calibration
    from ppo_cv.images import exif_layout

    from .common import image_size

    cameras = load_calibration(calib)
    if all(camera.image_size is None for camera in cameras):
        return
    fitted, notes = {}, []
    for row in (r for r in rows if r["given_cameras"]):
        sides = [("K1", cameras[0], row["image1"])]
        sides += [] if K2 else [("K2", cameras[-1], row["image2"])]
        for key, camera, name in sides:
            size = image_size(image_dir / name)
            if size is None:  # unreadable: the pair reports it
                continue
            if (key, name) not in fitted:
                turned = exif_orientation and exif_layout(image_dir / name).turned
                fitted[key, name], note = fit_to_image(
                    camera, size[::-1] if turned else size, f"--calib {calib}", name, turned
                )
                notes += [note] if note else []
            row[key] = fitted[key, name].K
    if notes:
        more = f" (and {len(notes) - 1} more images)" if len(notes) > 1 else ""
        warn("pairs", notes[0] + more)


def _usable_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` of an image by its header; None when it is missing, unreadable,
    above the pixel limit or too small to detect features on (its pair's error says which)."""
    from ppo_cv.features import require_detectable
    from ppo_cv.images import check_header

    from .common import image_size

    try:
        check_header(path)
    except ValueError:
        return None
    size = image_size(path)
    try:
        require_detectable(size[::-1] if size else (0, 0), str(path))
    except ValueError:
        return None
    return size


def _warn_implausible_cameras(
    rows: list[dict], image_dir: Path, pairs_file: Path, exif_orientation: bool, given: str
) -> None:
    """Warn once per distinct doubt, naming its first line, where a camera matrix given (by
    ``given``, the option, or on the line) does not fit its image as read (upright when
    ``exif_orientation``), by the header sizes (:func:`ppo_cv.calib.implausible_intrinsics`)."""
    from ppo_cv.images import exif_layout

    doubts: dict[str, dict[int, None]] = {}  # each doubt's lines, in order
    layouts: dict[Path, tuple] = {}  # an image's size and whether it is turned, read once

    def layout(path: Path) -> tuple:
        if path not in layouts:
            size = _usable_size(path)
            layouts[path] = size, size is not None and exif_orientation and exif_layout(path).turned
        return layouts[path]

    for row in (r for r in rows if r["K1"] is not None):
        for key in ("K1", "K2"):
            path = image_dir / row[{"K1": "image1", "K2": "image2"}[key]]
            size, turned = layout(path)
            if size is None:  # the pair reports why it cannot be used
                continue
            second = key == "K2" and given == "--K" and not row["shared_K"]
            name = f"{given}2" if second else given
            name = name if row["given_cameras"] else f"{key} of {path.name}"
            doubt = implausible_intrinsics(row[key], size[::-1] if turned else size, name, turned)
            if doubt is not None:
                doubts.setdefault(doubt, {})[row["line"]] = None
    for doubt, lines in doubts.items():
        first, others = next(iter(lines)), len(lines) - 1
        more = f" (and {others} more line{'s' * (others > 1)})" if others else ""
        warn("pairs", f"{pairs_file}:{first}: {doubt}{more}")


def _exif_intrinsics(rows: list[dict], image_dir: Path, exif_orientation: bool) -> None:
    """Give the rows without intrinsics the cameras of their images' EXIF, warning once for
    the run and once for each image whose EXIF focal length is doubtful."""
    missing = [r for r in rows if r["K1"] is None]
    names = dict.fromkeys(r[k] for r in missing for k in ("image1", "image2"))
    cameras, doubts = {}, []
    for name in names:
        try:
            K, found, warnings = exif_camera(image_dir / name, exif_orientation)
        except (ValueError, RuntimeError, OSError):  # unreadable: the pair reports it
            continue
        cameras[name] = (K, found)
        doubts += [(name, message) for message in warnings]
    for row in missing:
        row["K1"], row["K2"] = (cameras.get(row[k], (None,))[0] for k in ("image1", "image2"))
        row["guessed_cameras"] = True
    if not missing:
        return
    found = sum(f for _, f in cameras.values())
    guessed = "" if found == len(cameras) else f", 1.2 x image size for the {len(cameras) - found}"
    warn(
        "pairs",
        f"no intrinsics given for {len(missing)} of {len(rows)} pairs: using the EXIF focal "
        f"lengths of {found} of {len(cameras)} images (centred principal point{guessed}); pass "
        "--K or --calib for accurate results",
    )
    for message in _grouped_doubts(doubts, image_dir):
        warn("pairs", message)


def _grouped_doubts(doubts: list[tuple[str, str]], image_dir: Path) -> list[str]:
    """The doubts about images' EXIF cameras, one line for the images a doubt says alike of
    (a folder of one camera's photos gave one line per photo)."""
    names_by_text: dict[str, list[str]] = {}
    for name, message in doubts:
        text = message.removeprefix(f"{image_dir / name}: ")
        names_by_text.setdefault(text, []).append(name)
    lines = []
    for text, names in names_by_text.items():
        listed = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
        where = f"{image_dir / names[0]}" if len(names) == 1 else (
            f"{len(names)} images in {image_dir} ({listed})"
        )
        lines.append(f"{where}: {text}")
    return lines


_OTHER_FORMATS = {
    ".json": "one JSON document", ".csv": "CSV", ".tsv": "tab-separated values",
    ".xlsx": "a spreadsheet", ".xls": "a spreadsheet", ".yaml": "YAML", ".yml": "YAML",
    ".xml": "XML", ".npz": "numpy arrays", ".npy": "a numpy array", ".pkl": "a pickle",
    ".parquet": "Parquet", ".ply": "a point cloud", ".md": "Markdown",
}  # fmt: skip
"""Suffixes of ``pairs -o`` that name a format other than the JSON lines it writes."""

_COMPRESSED = {
    ".gz": "gzip", ".bz2": "bzip2", ".xz": "xz", ".lzma": "lzma", ".zst": "zstd",
    ".zip": "zip", ".7z": "7-Zip", ".tgz": "gzip",
}  # fmt: skip
"""Suffixes of ``pairs -o`` that promise compressed data: readers (pandas, ``gzip.open``)
decompress by the name, and the plain text written fails them."""


def _require_json_lines_name(output: Path) -> None:
    """ValueError for a ``pairs -o`` name whose suffix promises another format than the JSON
    lines written (``poses.csv`` would hold one JSON object per line, ``poses.jsonl.gz``
    plain text); the message names the ``.jsonl`` name to give."""
    suffix, base = output.suffix.lower(), output
    other = _OTHER_FORMATS.get(suffix)
    if suffix in _COMPRESSED:
        other = f"{_COMPRESSED[suffix]}-compressed data (compress the file after the run)"
        base = output.with_suffix("")
    if other is not None:
        name = base if base.suffix.lower() == ".jsonl" else base.with_suffix(".jsonl")
        raise ValueError(
            f"-o {output}: pairs writes JSON lines (one JSON object per pair and line), not "
            f"{other}; name the file {name.name}"
        )


def run_pairs(
    pairs_file, image_dir, K, output, workers, options, *, cache=True, quiet=False,
    overwrite=False, K2=None, calib=None, exif_orientation=True,
) -> int:  # fmt: skip
    """Run every pair of a pairs file, writing JSON lines to ``output`` (None or ``-``: stdout).

    Lines without intrinsics take ``K`` (and ``K2``) or the cameras of ``calib``, else those of
    the images' EXIF (with a warning). The output file is written completely or not at all (an
    interrupt leaves nothing). Returns the exit code: 0 when some pair has a pose (a warning
    counts the failed ones), 1 when none has (one line on stderr); ValueError for bad
    arguments, raised before any image is decoded.
    """
    from ppo_cv.atomic import (
        atomic_file,
        check_apart,
        check_target,
        import_pycolmap,
        names_a_stream,
        worker_count,
    )

    check_range("--workers", workers, 0, WORKERS_MAX)
    if output is not None and str(output) == "-":
        output = None
    if output is not None and names_a_stream(output):
        raise ValueError(f"-o {output} is a device or a stream; -o - writes to standard output")
    if output is not None:
        _require_json_lines_name(Path(output))
        check_target(output, "file", overwrite, [pairs_file, image_dir], "-o ")
    cameras = given_cameras(K, K2, None, None, calib)
    _require_order(Path(pairs_file), Path(image_dir))
    rows = read_pairs(Path(pairs_file), cameras=cameras)
    from ppo_cv.images import file_mode

    file_mode(image_dir, "image folder")
    if not Path(image_dir).is_dir():
        raise ValueError(f"image folder {image_dir} is not a folder")
    _require_some_image(rows, Path(image_dir), Path(pairs_file))
    _require_one_size(rows, Path(image_dir), Path(pairs_file), calib, exif_orientation)
    if output is not None:
        images = {Path(image_dir) / r[k] for r in rows for k in ("image1", "image2")}
        check_apart(output, sorted(images), "-o ")
    if calib is not None:
        _fit_calibration(rows, Path(image_dir), calib, K2, exif_orientation)
    _warn_repeated_lines(rows, Path(pairs_file))
    given = "--K" if calib is None else f"--calib {calib}"
    if cameras is not None:
        _warn_unused_cameras(rows, Path(pairs_file), given + " and --K2" * (K2 is not None))
    _warn_implausible_cameras(rows, Path(image_dir), Path(pairs_file), exif_orientation, given)
    _exif_intrinsics(rows, Path(image_dir), exif_orientation)
    workers = worker_count(workers, len(rows))
    import_pycolmap()
    sink = atomic_file(output, overwrite) if output is not None else contextlib.nullcontext(None)
    with contextlib.ExitStack() as stack:
        scratch = stack.enter_context(tempfile.TemporaryDirectory(prefix="ppo-cv-features-"))
        handle = stack.enter_context(sink) or sys.stdout
        pool = stack.enter_context(_worker_pool(workers))
        features = FeatureCache(scratch, options, exif_orientation) if cache else None
        paths = [Path(image_dir) / r[k] for r in rows for k in ("image1", "image2")]
        if features is not None:
            detect = features.jobs(paths)
            with ProgressReport("pairs", "images (features)", len(detect), quiet) as report:
                for job, outcome in zip(
                    detect, _run_all(_features_job, detect, pool, report), strict=True
                ):
                    features.store(job[0], outcome)
        jobs = [
            (
                row,
                str(image_dir),
                options,
                None
                if features is None
                else tuple(features.lookup(Path(image_dir) / row[k]) for k in ("image1", "image2")),
                exif_orientation,
            )
            for row in rows
        ]
        results = []
        stack.callback(_recent.clear)
        with ProgressReport("pairs", "pairs", len(jobs), quiet) as report:
            for data in _run_all(_pair_job, jobs, pool, report):
                try:
                    handle.write(json.dumps(data) + "\n")
                    handle.flush()
                except OSError as exc:
                    if output is not None:
                        raise
                    fail("pairs", stdout_failure(exc))
                results.append(data)
    failed = sum("error" in r for r in results)
    if rows[0]["T"] is not None and output is None:
        typer.echo(auc_table(results), err=True)
    elif rows[0]["T"] is not None:
        print_result("pairs", auc_table(results))
    elif 0 < failed < len(results):
        warn("pairs", f"{failed} of {len(results)} pairs failed")
    if rows[0]["T"] is None and output is not None and failed < len(results):
        print_result("pairs", _written(results, output))
    if failed < len(results):
        return 0
    typer.echo(f"ppo-cv pairs: {_no_pose(results)}", err=True)
    return NO_RESULT


def _written(results: list[dict], output) -> str:
    """The line a run without ground truth ends with: the file and what its lines hold."""
    posed = [r for r in results if "error" not in r]
    kinds = {
        "pure rotation": sum(r["pure_rotation"] for r in posed),
        "general motion": sum(r["model"] == "general" and not r["pure_rotation"] for r in posed),
        "plane": sum(r["model"] == "plane" and not r["pure_rotation"] for r in posed),
        "failed": len(results) - len(posed),
    }
    counts = ", ".join(f"{n} {kind}" for kind, n in kinds.items() if n)
    return f"wrote {len(results)} lines to {one_line(str(output))}: {counts}"


def _no_pose(results: list[dict]) -> str:
    """The one-line message of a run in which every pair failed, with the first one's error."""
    first = results[0]
    every = "the pair" if len(results) == 1 else f"all {len(results)} pairs"
    return short_words(
        one_line(
            f"no pose: {every} failed (each JSON line names its error); "
            f"{first['image1']} {first['image2']}: {first['error']}"
        )
    )


def register(app: typer.Typer) -> None:
    """Add the ``pairs`` command to ``app``."""
    from ppo_cv.pipeline import PairOptions
    from ppo_cv.ppo import DEFAULT_PRI_THRESHOLD
    from ppo_cv.significance import DEFAULT_MAX_LOG10_NFA

    @app.command(
        help="Run many pairs in parallel, one JSON line each; AUC@5/10/20 given ground truth."
        "\n\nFeatures are computed once per image for the whole run (--no-cache: once per "
        "pair). Progress goes to stderr. With ground truth the AUC is that of the pose error "
        "max(rotation error, translation-direction error), the rotation error alone where the "
        "true translation is zero. -o is written completely or not at all. Exit code 0 when "
        "some pair has a pose, 1 when every pair failed (each JSON line names its error)."
        "\n\nPAIRS_FILE: " + PAIRS_FILE_FORMAT + " Lines without intrinsics take --K (and "
        "--K2) or --calib, else the EXIF focal length of each image, with a warning (and, as "
        "in 'ppo-cv pair', the focal length fitted to a pair's homography when that one makes "
        "it a pure rotation: the line's camera_note says so).",
    )
    def pairs(
        pairs_file: Annotated[
            Path,
            typer.Argument(
                metavar="PAIRS_FILE",
                help="Lines 'name1 name2 [0 0 K1(9) K2(9) [T_1to2(16)]]' (see above).",
            ),
        ],
        image_dir: Annotated[
            Path, typer.Argument(metavar="IMAGE_DIR", help="Folder holding the images.")
        ],
        K: KOption = None,
        K2: K2Option = None,
        calib: CalibOption = None,
        exif_orientation: ExifOrientation = True,
        output: Annotated[
            Path | None,
            typer.Option(
                "--output",
                "-o",
                help="JSON lines file (default, or '-': stdout); written at the end.",
            ),
        ] = None,
        overwrite: Overwrite = False,
        workers: Annotated[
            int,
            typer.Option(
                help=f"Worker processes (0..{WORKERS_MAX}; 0: one per CPU); never more than "
                "the CPUs this process may use or the pairs.",
            ),
        ] = 0,
        no_cache: Annotated[
            bool,
            typer.Option("--no-cache", help="Detect features per pair instead of once per image."),
        ] = False,
        quiet: Quiet = False,
        features: Features = "sift",
        max_features: MaxFeatures = 8000,
        max_size: MaxSize = 2000,
        ratio: Ratio = 0.9,
        backend: Backend = "pycolmap",
        threshold: Threshold = 1.0,
        seed: Seed = 0,
        pri_threshold: PriThreshold = DEFAULT_PRI_THRESHOLD,
        max_log10_nfa: MaxLog10Nfa = DEFAULT_MAX_LOG10_NFA,
        plane: Plane = True,
        photometric: Photometric = True,
        principal_point: PrincipalPoint = "auto",
        focal_ratio: FocalRatio = "auto",
        redetect_below: RedetectBelow = 100,
        max_trials: Annotated[
            int,
            typer.Option(
                help=f"Cap on the RANSAC hypotheses per pair (1..{MAX_TRIALS_MAX}; it stops "
                "earlier once confident).",
                rich_help_panel="Pipeline",
            ),
        ] = PairOptions.max_trials,
        ordered_sampling: Annotated[
            bool,
            typer.Option(
                "--ordered-sampling/--no-ordered-sampling",
                help="Fit E on the best-ranked matches (ratio test) first, over all matches "
                "only when that is not significant; --no-ordered-sampling: one fit over all "
                "matches, up to --max-trials hypotheses.",
                rich_help_panel="Pipeline",
            ),
        ] = PairOptions.ordered_sampling,
    ) -> None:
        """Many pairs, one JSON line each, and the AUC given ground truth."""
        try:
            check_range("--max-trials", max_trials, 1, MAX_TRIALS_MAX)
            options = pipeline_options(
                features, max_features, max_size, ratio, backend, threshold, seed, pri_threshold,
                max_log10_nfa, plane, photometric, principal_point, focal_ratio, redetect_below,
            )  # fmt: skip
            options = dataclasses.replace(
                options,
                max_trials=max_trials,
                min_trials=min(options.min_trials, max_trials),
                ordered_sampling=ordered_sampling,
            )
            code = run_pairs(
                pairs_file, image_dir, K, output, workers, options,
                cache=not no_cache, quiet=quiet, overwrite=overwrite, K2=K2, calib=calib,
                exif_orientation=exif_orientation,
            )  # fmt: skip
        except (ValueError, OSError) as exc:
            fail("pairs", error_message(exc))
        raise typer.Exit(code)
