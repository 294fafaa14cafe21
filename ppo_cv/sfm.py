"""Initial pair selection for incremental structure from motion, and the reconstruction it seeds.

An incremental reconstruction grows from one image pair, and a pair without parallax (a camera
turning on a tripod, or barely moving) is the classic way it fails: its relative pose and its
triangulated points are unconstrained. Here every verified pair of a COLMAP database gets a PPO
pose from pycolmap's essential matrix and inlier matches, and a score:

* rejected when PPO reports a pure rotation (PRI below its threshold) or the model comparison
  of :mod:`ppo_cv.motion_model` judges the pair's inlier matches a pure rotation, when fewer than
  ``min_inliers`` matches satisfy both PPO inequalities, when the median triangulation angle of
  the analytic points is below ``min_tri_angle`` degrees, or for a near forward motion
  (``|t_z| > max_forward_motion``, the epipole deep inside the image);
* otherwise ``score = num_inliers * min(1, tri_angle / target_tri_angle)``: many inliers, and
  parallax up to the angle beyond which depth is well conditioned.

The best pair seeds pycolmap's incremental mapper, either as a two-view reconstruction from the
PPO pose and analytic points or through pycolmap's initial-pair options, and the mapper
registers the other images. :func:`run_sfm` does everything from an image folder.

Examples
--------
>>> from ppo_cv import sfm
>>> K = [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]
>>> result = sfm.run_sfm("images/", "model/", K=K)  # doctest: +SKIP
>>> result.num_registered, result.initial_pair  # doctest: +SKIP
(17, ('1341847987.758741.png', '1341847988.769740.png'))
"""

from __future__ import annotations

import contextlib
import inspect
import itertools
import os
import shutil
import stat
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pycolmap

from . import colmap, ppo
from .atomic import (
    API_REPLACE_HINT,
    atomic_directory,
    check_apart,
    check_target,
    signals_deferred,
    staging_folder,
)
from .calib import COLMAP_PIXEL_OFFSET
from .checks import (
    MAX_WHOLE_NUMBER,
    as_callback,
    as_camera_matrix,
    as_finite_rows,
    as_flag,
    as_nonnegative,
    as_path,
    as_positive,
    as_pri_threshold,
    as_rotation,
    as_whole_number,
    require_instance,
    shown,
)
from .guessed_camera import (
    FIELD_RANGE_DEG,
    HOMOGRAPHY_CONFIDENCE,
    decided_again,
    homography_rotation_focal,
    rotation_focal_scale,
)
from .homography import estimate_homography
from .images import check_decodes, file_mode
from .limits import MAX_FEATURES, MAX_THREADS
from .metrics import direction_error_deg, rotation_error_deg
from .motion_model import MotionDecision, decide_motion, plane_ransac_trials
from .pose import _recover_normalized
from .robust import _essential_from_pose
from .rotation import focal_ratio_keywords, focal_ratio_prior

__all__ = [
    "INITIALIZATIONS",
    "SEEDINGS",
    "ReconstructionFailed",
    "MAX_THREADS",
    "MAX_FEATURES",
    "MAX_IMAGE_CHECKS",
    "FIELD_RANGE_DEG",
    "PairScore",
    "SfmResult",
    "prepare_database",
    "score_pose",
    "score_pairs",
    "rotation_focal_scale",
    "homography_rotation_focal",
    "reconstruct",
    "run_sfm",
    "list_images",
    "screen_images",
    "require_two_images",
    "require_database_outside",
    "require_no_images",
    "format_pairs",
    "pair_text",
    "write_model",
    "pose_errors",
]


INITIALIZATIONS = ("ppo", "colmap")
"""``ppo``: the best-scored pair seeds the mapper; ``colmap``: pycolmap's own initialisation."""

SEEDINGS = ("two-view", "pair-options")
"""How a PPO pair seeds the mapper: a two-view reconstruction from the PPO pose and analytic
points, or pycolmap's initial-pair options (pycolmap then estimates the pair itself)."""

_UNUSABLE_CONFIGS = frozenset(
    int(c)
    for c in (
        pycolmap.TwoViewGeometryConfiguration.UNDEFINED,
        pycolmap.TwoViewGeometryConfiguration.DEGENERATE,
        pycolmap.TwoViewGeometryConfiguration.WATERMARK,
    )
)
_SQLITE_HEADER = b"SQLite format 3\x00"

MAX_IMAGE_CHECKS = 5
"""Candidate initial pairs re-checked on their images, best first, before one seeds the mapper.

The database holds only the matches, so the ranking cannot run what
:func:`ppo_cv.pipeline.estimate_pair` decides from the images (its photometric parallax of the
tracks, its lens fit); a pair the ranking accepts but ``estimate_pair`` (``ppo-cv pair``) calls
a pure rotation is refused, as one that yields no reliable geometry. Each check detects and
matches the two images again (about a second at 640x480), so only the best few are checked: a
folder whose best five candidates are all rotations is taken for a panorama."""

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".ppm", ".pgm")

Progress = Callable[[str], None]


class ReconstructionFailed(ValueError):
    """The images were read and matched, but no model could be built from them (no pair can
    start one, or the mapper registered nothing); the message says why."""


@dataclass(frozen=True)
class PairScore:
    """A candidate initial pair and the PPO evidence behind its score.

    Attributes
    ----------
    image_id1, image_id2 : int
        Database image ids.
    name1, name2 : str
        Image names.
    num_matches : int
        Verified (inlier) matches in the database.
    num_inliers : int
        Matches satisfying both PPO inequalities.
    pri : float
        Pure-rotation indicator of the pair.
    pure_rotation : bool
        ``pri < pri_threshold``, or a rotation-only model explains the matches
        (:func:`ppo_cv.motion_model.decide_motion`), or :func:`ppo_cv.pipeline.estimate_pair`
        called the two images a pure rotation (:func:`reconstruct`).
    tri_angle : float
        Median triangulation angle of the analytic points of the inliers, degrees.
    score : float
        ``num_inliers * min(1, tri_angle / target_tri_angle)``; 0 when rejected.
    rejection : str
        Why the pair cannot seed a reconstruction; empty when it can.
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
        PPO pose ``cam2_from_cam1``, unit ``t``: for a plane, that of its homography.
    model : str
        ``"rotation"``, ``"plane"`` or ``"general"`` (:func:`ppo_cv.motion_model.decide_motion`
        on the verified matches, with a homography fitted to them).
    """

    image_id1: int
    image_id2: int
    name1: str
    name2: str
    num_matches: int
    num_inliers: int
    pri: float
    pure_rotation: bool
    tri_angle: float
    score: float
    rejection: str
    R: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    model: str = "general"

    @property
    def accepted(self) -> bool:
        """Whether the pair may seed a reconstruction."""
        return not self.rejection


@dataclass(frozen=True, repr=False)
class SfmResult:
    """An incremental reconstruction and how it was initialised.

    Its ``repr`` counts the ranked pairs rather than listing them (``result.pairs`` holds them).

    Attributes
    ----------
    reconstruction : pycolmap.Reconstruction or None
        The model with the most registered images; None when nothing was reconstructed.
    initialization : str
        One of :data:`INITIALIZATIONS`.
    initial_pair : tuple of (str, str) or None
        Names of the two images the mapper started from.
    pairs : tuple of PairScore
        The ranked candidates (``ppo`` initialisation only), best first, with those refused on
        their images ranked as rejected.
    num_images : int
        Images in the database.
    num_registered : int
        Images registered in ``reconstruction``.
    num_points3D : int
    mean_reprojection_error : float
        Pixels; NaN without a reconstruction.
    num_models : int
        Reconstructions pycolmap produced (more than one when the scene fell apart).
    elapsed : float
        Wall time of the pair scoring and the mapping, seconds (feature extraction and
        matching excluded).
    """

    reconstruction: Any
    initialization: str
    initial_pair: tuple[str, str] | None
    pairs: tuple[PairScore, ...]
    num_images: int
    num_registered: int
    num_points3D: int
    mean_reprojection_error: float
    num_models: int
    elapsed: float

    def __repr__(self) -> str:
        shown = (
            f"{f.name}=<{len(self.pairs)} PairScore, best first>"
            if f.name == "pairs"
            else f"{f.name}={getattr(self, f.name)!r}"
            for f in fields(self)
        )
        return f"SfmResult({', '.join(shown)})"

    @property
    def all_registered(self) -> bool:
        """Whether every image of the database is in the reconstruction."""
        return self.num_images > 0 and self.num_registered == self.num_images


@contextlib.contextmanager
def _quiet(verbose: bool) -> Iterator[None]:
    """pycolmap's log held back to fatal messages unless ``verbose``: its errors reach the
    caller as exceptions, and an interrupt would otherwise add its "Stopping thread..." line."""
    if verbose:
        yield
        return
    previous = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 3
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = previous


def _say(progress: Progress | None, message: str) -> None:
    if progress is not None:
        progress(message)


def _image_folder(value: Any) -> Path:
    """``value`` as the Path of an existing folder; TypeError or ValueError naming it (and
    why it cannot be reached: a loop of symbolic links, no permission)."""
    image_dir = as_path(value, "image_dir")
    if not os.path.lexists(image_dir):
        raise ValueError(f"image folder {str(image_dir)!r} does not exist")
    if not stat.S_ISDIR(file_mode(image_dir, "image folder")):
        raise ValueError(f"image folder {str(image_dir)!r} is not a folder")
    return image_dir


def _check_new_database(database_path: Path, image_dir: Path) -> None:
    """ValueError unless ``database_path`` can receive a new database: a database is built
    anew, never replaced or added to."""
    if database_path.exists() or database_path.is_symlink():
        raise ValueError(
            f"database {str(database_path)!r} already exists; give a new file name (a database "
            "is never replaced)"
        )
    check_target(database_path, "file", inputs=[image_dir], name="database_path ")


def list_images(image_dir: str | os.PathLike) -> list[str]:
    """Names of the image files directly in ``image_dir``, sorted."""
    image_dir = _image_folder(image_dir)
    return sorted(
        p.name for p in image_dir.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS
    )


def screen_images(image_dir: str | os.PathLike) -> tuple[list[str], dict[str, str]]:
    """The image files of ``image_dir`` (:func:`list_images`) named in UTF-8 that pass
    :func:`ppo_cv.images.check_decodes` and are no copy of an earlier one, and the others with
    the reason, by name: an image declaring more pixels than accepted would be decoded whole
    before pycolmap refused it, a damaged one would have libpng print its own errors, and a
    copy adds no view (two copies alone read as a pure rotation)."""
    kept, skipped = [], {}
    for name in list_images(image_dir):
        try:
            _require_utf8_name(name)
            check_decodes(Path(image_dir) / name)
        except ValueError as exc:
            skipped[name] = str(exc)
        else:
            kept.append(name)
    copies = _copies(Path(image_dir), kept)
    for name, original in copies.items():
        skipped[name] = f"{Path(image_dir) / name} is a copy of {original}: the same bytes"
    return [name for name in kept if name not in copies], dict(sorted(skipped.items()))


def _copies(image_dir: Path, names: Sequence[str]) -> dict[str, str]:
    """Each file of ``names`` whose bytes are those of an earlier one, with that one's name."""
    import hashlib

    by_size: dict[int, list[str]] = {}
    for name in names:
        by_size.setdefault((image_dir / name).stat().st_size, []).append(name)
    copies = {}
    for group in (g for g in by_size.values() if len(g) > 1):
        first: dict[bytes, str] = {}
        for name in group:
            digest = hashlib.sha256((image_dir / name).read_bytes()).digest()
            original = first.setdefault(digest, name)
            if original != name:
                copies[name] = original
    return copies


def _require_utf8_name(name: str) -> None:
    """ValueError for a file name that is not valid UTF-8, which pycolmap cannot take."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        shown = os.fsencode(name).decode("utf-8", "backslashreplace")
        reason = f"the name '{shown}' is not valid UTF-8, which pycolmap cannot read"
        raise ValueError(reason) from None


def require_no_images(output_dir: str | os.PathLike, name: str, usage: str) -> None:
    """ValueError when the output folder ``output_dir`` holds images, which a model folder never
    does: a folder of photos given as the output (the two folders the other way round), which
    the advice to replace an existing output would have deleted, even with ``overwrite``.

    Parameters
    ----------
    output_dir : path
        The output folder; nothing is checked when it is no folder.
    name : str
        How the message calls it (``"OUT_DIR "``, ``"output_dir "``).
    usage : str
        The call in the right order, for the message.
    """
    require_instance(name, str, "name")
    require_instance(usage, str, "usage")
    output_dir = as_path(output_dir, name.strip() or "output_dir")
    try:
        held = sorted(p.name for p in Path(output_dir).iterdir()
                      if p.suffix.lower() in IMAGE_EXTENSIONS and p.is_file())  # fmt: skip
    except OSError:  # missing, a file, unreadable: check_target names it
        return
    if held:
        listed = ", ".join(held[:3]) + (", ..." if len(held) > 3 else "")
        raise ValueError(
            f"{name}{output_dir} holds {len(held)} image{'s' * (len(held) > 1)} ({listed}), "
            f"which a model folder never does: the image folder comes first, {usage}; give "
            "an output folder without images"
        )


def require_database_outside(
    database_path: str | os.PathLike,
    output_dir: str | os.PathLike,
    names: tuple[str, str] = ("database_path", "output_dir"),
) -> None:
    """ValueError when the database would be ``output_dir`` or lie inside it.

    The finished model replaces ``output_dir`` as a whole, so a database kept there would be
    deleted with it, or the model refused at the end for a folder the run filled itself.
    Symbolic links and ``..`` are resolved first; ``names`` are how the message calls the two
    arguments (the command line's ``--database`` and ``OUT_DIR``).
    """
    database = Path(os.path.realpath(as_path(database_path, names[0])))
    folder = Path(os.path.realpath(as_path(output_dir, names[1])))
    if database == folder or database.is_relative_to(folder):
        raise ValueError(
            f"{names[0]} {database_path} lies in {names[1]} {output_dir}, which the model "
            "replaces as a whole; keep the database outside it"
        )


MAX_NAMED_SKIPS = 3
"""Skipped images whose reason the error for too few images gives."""


def require_two_images(
    image_dir: str | os.PathLike, names: Sequence[str], skipped: dict[str, str]
) -> None:
    """ValueError when :func:`screen_images` kept fewer than two images, giving why the first
    :data:`MAX_NAMED_SKIPS` skipped ones were skipped; TypeError naming the argument of
    another kind."""
    image_dir = as_path(image_dir, "image_dir")
    require_instance(names, (list, tuple), "names", " (of image names)")
    require_instance(skipped, dict, "skipped", " (reason by image name)")
    if len(names) < 2:
        reasons = list(skipped.values())[:MAX_NAMED_SKIPS]
        more = f"; {len(skipped) - len(reasons)} more" if len(skipped) > len(reasons) else ""
        refused = f" ({len(skipped)} skipped: {'; '.join(reasons)}{more})" if skipped else ""
        nested = _image_subfolders(Path(image_dir))[:MAX_NAMED_SKIPS]
        below = (
            f"; sub-folders are not read, and {', '.join(nested)} "
            f"{'holds' if len(nested) == 1 else 'hold'} images: give the "
            "folder of the images, or put them in one"
            if nested
            else ""
        )
        raise ValueError(
            f"need at least 2 images in {str(image_dir)!r}, found {len(names)}{refused}{below}"
        )


def _image_subfolders(image_dir: Path) -> list[str]:
    """The sorted names of the sub-folders of ``image_dir`` that hold image files directly
    (those that cannot be listed left out)."""
    try:
        folders = sorted(p for p in image_dir.iterdir() if p.is_dir())
    except OSError:
        return []
    holding = []
    for folder in folders:
        with contextlib.suppress(OSError):
            if any(p.suffix.lower() in IMAGE_EXTENSIONS and p.is_file() for p in folder.iterdir()):
                holding.append(folder.name)
    return holding


def _pycolmap_options(K: np.ndarray | None, max_num_features: int, num_threads: int, seed: int):
    """pycolmap's reader (a ``PINHOLE`` camera of ``K`` when given, its principal point moved
    to COLMAP's pixel coordinates: :data:`~ppo_cv.calib.COLMAP_PIXEL_OFFSET`), extraction,
    matching and verification options of :func:`prepare_database`, on the CPU."""
    reader = pycolmap.ImageReaderOptions()
    if K is not None:
        reader.camera_model = "PINHOLE"
        cx, cy = K[0, 2] + COLMAP_PIXEL_OFFSET, K[1, 2] + COLMAP_PIXEL_OFFSET
        reader.camera_params = ",".join(repr(float(v)) for v in (K[0, 0], K[1, 1], cx, cy))
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = num_threads
    extraction.use_gpu = False
    extraction.sift.max_num_features = int(max_num_features)
    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = num_threads
    matching.use_gpu = False
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = seed
    return reader, extraction, matching, verification


def _check_hooks(progress: Any, **flags: Any) -> None:
    """TypeError naming a flag that is not a bool (the text ``"no"`` read as true) or a
    ``progress`` that is not callable (an int failed at the first message)."""
    for name, value in flags.items():
        as_flag(value, name)
    as_callback(progress, "progress", "a callable taking a message")


def _check_run_numbers(
    num_threads: Any, seed: Any, max_num_features: Any = 1, max_init_trials: Any = 1
) -> tuple[int, int, int, int]:
    """The four as Python ints, which pycolmap's options take (``seed=3.0`` failed there in
    pybind's words); ValueError or TypeError naming the first one out of range."""
    return (
        as_whole_number(num_threads, "num_threads", 1, MAX_THREADS),
        as_whole_number(seed, "seed", 0, MAX_WHOLE_NUMBER),
        as_whole_number(max_num_features, "max_num_features", 1, MAX_FEATURES),
        as_whole_number(max_init_trials, "max_init_trials", 1, MAX_WHOLE_NUMBER),
    )


def prepare_database(
    image_dir: str | os.PathLike,
    database_path: str | os.PathLike,
    *,
    K: Any = None,
    max_num_features: int = 8192,
    num_threads: int = 2,
    seed: int = 0,
    verbose: bool = False,
    progress: Progress | None = None,
) -> int:
    """Extract SIFT features and match all pairs with pycolmap into a new database.

    Parameters
    ----------
    image_dir : path
        Folder of images.
    database_path : path
        The database to create; it must not exist yet.
    K : array_like, shape (3, 3), optional
        Known intrinsics: one ``PINHOLE`` camera with a prior focal length, so that pycolmap
        verifies pairs with an essential matrix; the images must then all have one size.
        Without it pycolmap guesses a ``SIMPLE_RADIAL`` camera from the EXIF focal length or
        the image size, one for each image size and EXIF focal length, and one per image for
        images without an EXIF focal length (``pycolmap.CameraMode.AUTO``); an EXIF focal
        length is scaled to a resized copy (:func:`~ppo_cv.calib.exif_focal_scale`), and one
        that is none (:func:`~ppo_cv.calib.unusable_exif_focal`) is replaced by the image
        size's guess.
    max_num_features : int
        SIFT features per image.
    num_threads : int
    seed : int
        Random seed of pycolmap's geometric verification (RANSAC).
    verbose : bool
        Let pycolmap log to stderr.
    progress : callable, optional
        Called with a one-line message at each stage.

    Returns
    -------
    int
        Number of images in the database: those :func:`screen_images` keeps.

    Raises
    ------
    ValueError
        Fewer than two images, images of several sizes with ``K``, a ``K`` with skew, or images
        pycolmap could not read (named).
    """
    _check_hooks(progress, verbose=verbose)
    num_threads, seed, max_num_features, _ = _check_run_numbers(num_threads, seed, max_num_features)
    if K is not None:
        K = as_camera_matrix(K, "K")
        if K[0, 1] != 0:
            raise ValueError(f"K has skew {K[0, 1]}, which pycolmap's PINHOLE camera cannot hold")
    names, skipped = screen_images(image_dir)
    require_two_images(image_dir, names, skipped)
    _check_new_database(as_path(database_path, "database_path"), image_dir)
    if K is not None:
        _check_one_size(image_dir, names)
    reader, extraction, matching, verification = _pycolmap_options(
        K, max_num_features, num_threads, seed
    )
    with _quiet(verbose):
        _say(progress, f"extracting SIFT features from {len(names)} images")
        pycolmap.extract_features(
            database_path,
            image_dir,
            image_names=names,
            camera_mode=pycolmap.CameraMode.AUTO if K is None else pycolmap.CameraMode.SINGLE,
            reader_options=reader,
            extraction_options=extraction,
            device=pycolmap.Device.cpu,
        )
        if K is None:
            _fit_exif_focals(database_path, image_dir)
        _say(progress, f"matching {len(names) * (len(names) - 1) // 2} image pairs")
        pycolmap.match_exhaustive(
            database_path,
            matching_options=matching,
            verification_options=verification,
            device=pycolmap.Device.cpu,
        )
    with pycolmap.Database.open(database_path) as database:
        read = {image.name for image in database.read_all_images()}
    skipped = [name for name in names if name not in read]
    if skipped:
        more = f" and {len(skipped) - 5} more" if len(skipped) > 5 else ""
        raise ValueError(
            f"pycolmap could not read {len(skipped)} of {len(names)} images "
            f"({', '.join(skipped[:5])}{more}): not an "
            "image, or damaged"
        )
    return len(read)


def _fit_exif_focals(database_path: str | os.PathLike, image_dir: str | os.PathLike) -> None:
    """Fit each camera pycolmap guessed from an EXIF focal length to its images as
    :func:`~ppo_cv.calib.camera_from_exif` does (:func:`~ppo_cv.calib.fitted_exif_focal` of
    its first image): scaled to a resized copy, and one that is none (a placeholder such as
    65535 mm) replaced by the focal length of an image without one."""
    from .calib import fitted_exif_focal
    from .images import exif_layout

    with pycolmap.Database.open(database_path) as database:
        names = {image.camera_id: image.name for image in database.read_all_images()}
        for camera in database.read_all_cameras():
            if not camera.has_prior_focal_length or camera.camera_id not in names:
                continue
            size = (camera.width, camera.height)
            layout = exif_layout(Path(image_dir) / names[camera.camera_id])
            focal, doubt = fitted_exif_focal(camera.mean_focal_length(), layout, size)
            camera.focal_length, camera.has_prior_focal_length = focal, doubt is None
            database.update_camera(camera)


def _check_one_size(image_dir: str | os.PathLike, names: Sequence[str]) -> None:
    """ValueError naming two sizes when the images (as stored) do not all have one."""
    from .images import image_size

    sizes = {}
    for name in names:
        size = image_size(Path(image_dir) / name)
        if size is not None:
            sizes.setdefault(size, name)
    if len(sizes) > 1:
        (size1, name1), (size2, name2) = list(sizes.items())[:2]
        raise ValueError(
            f"the images have {len(sizes)} sizes ({name1} {size1[0]}x{size1[1]}, {name2} "
            f"{size2[0]}x{size2[1]}) and one camera matrix fits one size; omit --K to "
            "estimate a camera per image size"
        )


def _no_initial_pair(pairs: Sequence[PairScore], num_images: int) -> str:
    """Why no pair can start a reconstruction: the rejections counted by reason."""
    if not pairs:
        return (
            f"no image pair qualifies as an initial pair: no two of the {num_images} images "
            "share enough matches verified by pycolmap (different scenes, or too little overlap)"
        )
    reasons: dict[str, int] = {}
    for pair in pairs:
        reason = pair.rejection.split(" (")[0] or "not checked on the images"
        reasons[reason] = reasons.get(reason, 0) + 1
    counted = ", ".join(f"{count} {reason}" for reason, count in reasons.items())
    counts = f"of {len(pairs)} matched pair{'s' if len(pairs) > 1 else ''}, {counted}"
    if _looks_like_panorama(pairs):
        return (
            f"the {num_images} images look like a panorama (pure rotations about one point) "
            f"and hold no structure to reconstruct: {counts}"
        )
    return f"no image pair qualifies as an initial pair: {counts}"


def _looks_like_panorama(pairs: Sequence[PairScore]) -> bool:
    """No pair can seed a model, and rotations explain them: a pair that the ranking accepted
    was refused as a pure rotation on its images, or at least half of the pairs with a pose
    are pure rotations."""
    rotations = [p for p in pairs if p.rejection.startswith("pure rotation")]
    posed = [p for p in pairs if not p.rejection.startswith("no pose")]
    on_images = any("on the images" in p.rejection for p in rotations)
    return bool(rotations) and (on_images or 2 * len(rotations) >= len(posed))


def score_pose(
    pose: Any,
    *,
    motion: Any = None,
    min_inliers: int = 50,
    min_tri_angle: float = 1.0,
    target_tri_angle: float = 8.0,
    max_forward_motion: float = 0.95,
) -> tuple[float, float, str]:
    """Score a PPO pose as an initial pair.

    Parameters
    ----------
    pose : PoseResult
    motion : MotionDecision, optional
        Model decision on the pair's matches; a pure rotation is always rejected, and so is a
        rotation candidate (:attr:`ppo_cv.motion_model.MotionDecision.rotation_candidate`:
        without the images its translation cannot be measured, and
        :func:`ppo_cv.estimate_pair` may call it a pure rotation); a plane is scored as any
        pose (pass the pose of its homography: a planar pair seeds a reconstruction when its
        parallax is sufficient).
    min_inliers : int
        Fewer PPO inliers reject the pair.
    min_tri_angle, target_tri_angle : float
        Degrees. Median triangulation angles below ``min_tri_angle`` reject the pair; the score
        grows linearly with the angle up to ``target_tri_angle``.
    max_forward_motion : float
        A unit translation with ``|t_z|`` above it is rejected.

    Returns
    -------
    score : float
        ``num_inliers * min(1, tri_angle / target_tri_angle)``, 0 when rejected.
    tri_angle : float
        Median triangulation angle of the inliers, degrees (0 for a pure rotation).
    rejection : str
        Empty when accepted, else the reason.
    """
    target_tri_angle = as_positive(target_tri_angle, "target_tri_angle")
    min_inliers = as_whole_number(min_inliers, "min_inliers", 0, MAX_WHOLE_NUMBER)
    min_tri_angle = as_nonnegative(min_tri_angle, "min_tri_angle")
    max_forward_motion = as_nonnegative(max_forward_motion, "max_forward_motion")
    if motion is not None:
        require_instance(motion, MotionDecision, "motion", " (ppo_cv.motion_model.decide_motion)")
    tri_angle = float(np.degrees(colmap.median_tri_angle(pose)))
    if pose.pure_rotation:
        rejection = f"pure rotation (PRI {pose.pri:.4f} < {pose.pri_threshold})"
    elif motion is not None and motion.pure_rotation:
        rejection = (
            f"pure rotation (rotation model: GRIC difference {motion.gric_difference:+.3f} "
            f"per match, PRI {motion.pri:.4f})"
        )
    elif motion is not None and motion.rotation_candidate:
        rejection = (
            "rotation not ruled out (the rotation model passes every test but GRIC, "
            f"difference {motion.gric_difference:+.3f} per match)"
        )
    elif pose.num_inliers < min_inliers:
        rejection = f"too few inliers ({pose.num_inliers} < {min_inliers})"
    elif tri_angle < min_tri_angle:
        rejection = f"small parallax ({tri_angle:.2f} < {min_tri_angle} deg)"
    elif abs(pose.t[2]) > max_forward_motion:
        rejection = f"forward motion (|t_z| {abs(pose.t[2]):.3f} > {max_forward_motion})"
    else:
        rejection = ""
    score = 0.0 if rejection else pose.num_inliers * min(1.0, tri_angle / target_tri_angle)
    return float(score), tri_angle, rejection


def _require_database(path: Path) -> None:
    """ValueError unless ``path`` is an SQLite file, as COLMAP's databases are (pycolmap
    refuses any other with a RuntimeError and a log line)."""
    if not path.exists():
        raise ValueError(f"database {str(path)!r} does not exist")
    if not path.is_file():
        raise ValueError(f"database {str(path)!r} is not a file")
    with open(path, "rb") as handle:
        header = handle.read(len(_SQLITE_HEADER))
    if header != _SQLITE_HEADER:
        raise ValueError(f"database {str(path)!r} is not a COLMAP database (no SQLite header)")
    missing = _missing_colmap_columns(path)
    if missing:
        raise ValueError(
            f"database {str(path)!r} is an SQLite file but not a COLMAP database: it lacks "
            f"{', '.join(missing)}"
        )


_COLMAP_COLUMNS = {
    "cameras": ("camera_id", "model", "width", "height", "params"),
    "images": ("image_id", "name", "camera_id"),
    "keypoints": ("image_id", "rows", "cols", "data"),
    "matches": ("pair_id", "rows", "cols", "data"),
    "two_view_geometries": ("pair_id", "rows", "cols", "data", "config", "E"),
}
"""Tables and columns every COLMAP database has had (3.x and 4.x): pycolmap adds any table it
misses to the file it opens, and refuses a table it reads without its columns with a
RuntimeError."""


def _missing_colmap_columns(path: Path) -> list[str]:
    """The :data:`_COLMAP_COLUMNS` (``table`` or ``table.column``) the SQLite file ``path``
    lacks, read without writing to it; ValueError for a file SQLite cannot read."""
    import sqlite3

    read_only = f"{path.resolve().as_uri()}?mode=ro"
    try:
        with contextlib.closing(sqlite3.connect(read_only, uri=True)) as db:
            columns = {
                table: {row[1] for row in db.execute(f"PRAGMA table_info({table})")}
                for table in _COLMAP_COLUMNS
            }
    except sqlite3.DatabaseError as exc:
        raise ValueError(f"database {str(path)!r} cannot be read: {exc}") from None
    return [
        table if not columns[table] else f"{table}.{column}"
        for table, needed in _COLMAP_COLUMNS.items()
        for column in (needed if columns[table] else needed[:1])
        if column not in columns[table]
    ]


def score_pairs(
    database_path: str | os.PathLike,
    *,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
    min_inliers: int = 50,
    min_tri_angle: float = 1.0,
    target_tri_angle: float = 8.0,
    max_forward_motion: float = 0.95,
) -> list[PairScore]:
    """Score every verified image pair of a COLMAP database as an initial pair.

    The pose of each pair comes from :func:`ppo_cv.colmap.recover_pose_from_geometry` on the
    pair's stored essential matrix and inlier matches; see :func:`score_pose` for the score.

    Returns
    -------
    list of PairScore
        Accepted pairs by decreasing score, then the rejected ones by decreasing inlier count.
        Each pair names its images in sorted order (``name1 < name2``, camera 1 the first):
        pycolmap numbers the images in the order its extraction threads finish them, which
        changes from run to run.

    Raises
    ------
    ValueError, TypeError
        For an option that is not a finite number >= 0 (checked first), or a missing database.
    """
    _check_scoring(
        {"pri_threshold": pri_threshold, "min_inliers": min_inliers,
         "min_tri_angle": min_tri_angle, "target_tri_angle": target_tri_angle,
         "max_forward_motion": max_forward_motion}
    )  # fmt: skip
    database_path = as_path(database_path, "database_path")
    _require_database(database_path)
    scores = []
    with pycolmap.Database.open(database_path) as database:
        cameras = {c.camera_id: c for c in database.read_all_cameras()}
        images = {i.image_id: i for i in database.read_all_images()}
        keypoints: dict[int, np.ndarray] = {}
        pair_ids, geometries = database.read_two_view_geometries()
        for pair_id, geometry in zip(pair_ids, geometries, strict=True):
            id1, id2 = pycolmap.pair_id_to_image_pair(pair_id)
            if images[id1].name > images[id2].name:  # ids follow the extraction threads
                id1, id2 = id2, id1
                geometry = database.read_two_view_geometry(id1, id2)  # inverted
            for image_id in (id1, id2):
                if image_id not in keypoints:
                    keypoints[image_id] = database.read_keypoints(image_id)
            scores.append(
                _score_geometry(
                    geometry,
                    images[id1],
                    images[id2],
                    cameras,
                    keypoints,
                    pri_threshold=pri_threshold,
                    min_inliers=min_inliers,
                    min_tri_angle=min_tri_angle,
                    target_tri_angle=target_tri_angle,
                    max_forward_motion=max_forward_motion,
                )
            )
    return sorted(scores, key=lambda s: (not s.accepted, -s.score, -s.num_inliers))


def _score_geometry(
    geometry, image1, image2, cameras, keypoints, *, pri_threshold, **criteria
) -> PairScore:
    common = {
        "image_id1": int(image1.image_id),
        "image_id2": int(image2.image_id),
        "name1": image1.name,
        "name2": image2.name,
        "num_matches": len(geometry.inlier_matches),
    }
    config = int(geometry.config)
    try:
        if config in _UNUSABLE_CONFIGS:
            name = pycolmap.TwoViewGeometryConfiguration(config).name
            raise ValueError(f"{name} two-view geometry")
        pose = colmap.recover_pose_from_geometry(
            geometry,
            cameras[image1.camera_id],
            keypoints[image1.image_id],
            cameras[image2.camera_id],
            keypoints[image2.image_id],
            pri_threshold=pri_threshold,
        )
    except ValueError as exc:
        return PairScore(
            **common, num_inliers=0, pri=float("nan"), pure_rotation=False, tri_angle=0.0,
            score=0.0, rejection=f"no pose ({exc})", R=np.eye(3), t=np.zeros(3),
        )  # fmt: skip
    motion, pose = _motion_decision(
        geometry, cameras[image1.camera_id], keypoints[image1.image_id],
        cameras[image2.camera_id], keypoints[image2.image_id], pose, pri_threshold,
    )  # fmt: skip
    score, tri_angle, rejection = score_pose(pose, motion=motion, **criteria)
    pure = bool(pose.pure_rotation or (motion is not None and motion.pure_rotation))
    return PairScore(
        **common, num_inliers=pose.num_inliers, pri=float(pose.pri),
        pure_rotation=pure,
        tri_angle=tri_angle, score=score,
        rejection=rejection, R=pose.R, t=pose.t,
        model="rotation" if pure else ("general" if motion is None else motion.model),
    )  # fmt: skip


def _motion_decision(geometry, camera1, keypoints1, camera2, keypoints2, pose, pri_threshold):
    """Model decision on the verified matches (None with fewer than 8), and the pose to score:
    for a plane the PPO pose of its homography with its analytic points, else ``pose``."""
    matches = np.asarray(geometry.inlier_matches, dtype=np.int64).reshape(-1, 2)
    if len(matches) < 8:
        return None, pose
    x1, x2 = (
        np.column_stack([xy, np.ones(len(xy))])
        for xy in (
            colmap.rays_from_camera(camera, np.asarray(kp, dtype=np.float64)[rows, :2])
            for camera, kp, rows in ((camera1, keypoints1, matches[:, 0]),
                                     (camera2, keypoints2, matches[:, 1]))
        )
    )  # fmt: skip
    focal = 0.5 * (camera1.mean_focal_length() + camera2.mean_focal_length())
    used = np.ones(len(matches), dtype=bool)
    # the verified matches are the inliers of COLMAP's two-view model: a plane worth calling
    # one is the bulk of them, as on the pipeline's essential-matrix inliers
    trials = plane_ransac_trials(HOMOGRAPHY_CONFIDENCE)
    homography = estimate_homography(
        x1, x2, focal, confidence=HOMOGRAPHY_CONFIDENCE, max_trials=trials
    )
    motion = decide_motion(
        x1, x2, pose.R, pose.t, used, focal, pri_threshold=pri_threshold, homography=homography,
        **focal_ratio_keywords(
            focal_ratio_prior(camera2.mean_focal_length() / camera1.mean_focal_length())
        ),
    )  # fmt: skip
    if motion.model != "plane":
        return motion, pose
    plane = motion.plane
    E = _essential_from_pose(plane.R, plane.t)
    return motion, _recover_normalized(E, x1[:, :2], x2[:, :2], plane.inliers, pri_threshold)


def _pipeline_options(
    image_dir: Path, fix_intrinsics: bool, num_threads: int, seed: int
) -> pycolmap.IncrementalPipelineOptions:
    options = pycolmap.IncrementalPipelineOptions()
    options.num_threads = num_threads
    options.random_seed = seed
    options.image_path = str(image_dir)
    if fix_intrinsics:
        options.ba_refine_focal_length = False
        options.ba_refine_principal_point = False
        options.ba_refine_extra_params = False
        options.mapper.abs_pose_refine_focal_length = False
        options.mapper.abs_pose_refine_extra_params = False
    return options


def _run_pipeline(
    database: pycolmap.Database,
    options: pycolmap.IncrementalPipelineOptions,
    manager: pycolmap.ReconstructionManager,
    progress: Progress | None,
    candidate: PairScore | None = None,
) -> tuple[list[pycolmap.Reconstruction], tuple[str, str] | None]:
    pipeline = pycolmap.IncrementalPipeline(options, database, manager)
    seeds: list[tuple[str, str]] = []

    def on_initial_pair() -> None:
        reconstruction = manager.get(manager.size() - 1)
        names = _initial_pair_names(reconstruction, candidate)
        seeds.append(names)
        _say(progress, f"initial pair {pair_text(*names)}")

    def on_next_image() -> None:
        reconstruction = manager.get(manager.size() - 1)
        _say(progress, f"registered {reconstruction.num_reg_images()} images")

    Callback = pycolmap.IncrementalPipelineCallback
    pipeline.add_callback(Callback.INITIAL_IMAGE_PAIR_REG_CALLBACK, on_initial_pair)
    pipeline.add_callback(Callback.NEXT_IMAGE_REG_CALLBACK, on_next_image)
    pipeline.run()
    models = [manager.get(i) for i in range(manager.size())]
    first_seed = seeds[0] if seeds else None
    return models, first_seed


def _initial_pair_names(
    reconstruction: pycolmap.Reconstruction, candidate: PairScore | None
) -> tuple[str, str]:
    """The two images the mapper started from: in the order of ``candidate`` when they are its
    two images (camera 1 first, as its pose and the ranking name them), else sorted."""
    names = sorted(reconstruction.image(i).name for i in reconstruction.reg_image_ids())
    if candidate is not None and set(names) == {candidate.name1, candidate.name2}:
        return candidate.name1, candidate.name2
    return names[0], names[-1]


def reconstruct(
    database_path: str | os.PathLike,
    image_dir: str | os.PathLike,
    *,
    initialization: str = "ppo",
    seeding: str = "two-view",
    fix_intrinsics: bool = False,
    max_init_trials: int = 5,
    num_threads: int = 2,
    seed: int = 0,
    verbose: bool = False,
    progress: Progress | None = None,
    **scoring: Any,
) -> SfmResult:
    """Incremental mapping with pycolmap, seeded by the best PPO-scored pair.

    Parameters
    ----------
    database_path : path
        COLMAP database with features, matches and verified two-view geometries.
    image_dir : path
        The images (colours of the points).
    initialization : {"ppo", "colmap"}
        ``ppo``: rank the pairs with :func:`score_pairs` and start from the best, trying the
        next one (up to ``max_init_trials``) if the mapper cannot grow from it. Before a pair
        seeds the mapper, :func:`ppo_cv.pipeline.estimate_pair` (default options, the database
        cameras) decides it on its two images, as ``ppo-cv pair`` does: a pure rotation, or no
        reliable geometry, refuses it and the next pair is checked, up to
        :data:`MAX_IMAGE_CHECKS` pairs; the refusals are in the returned ranking.
        ``colmap``: pycolmap's default initial-pair search (no pair is checked).
    seeding : {"two-view", "pair-options"}
        How a ``ppo`` pair starts the mapper. ``two-view``: a reconstruction of the two images
        with the PPO pose and the analytic points of its inliers
        (:func:`ppo_cv.colmap.two_view_reconstruction`), bundle-adjusted with the cameras
        fixed, which pycolmap's mapper then continues. ``pair-options``: pycolmap's initial
        pair options, with its minimum initial triangulation angle and inlier count lowered to
        what the pair offers; pycolmap estimates the pair's pose itself.
    fix_intrinsics : bool
        Keep the database cameras fixed (known calibration); else the checks on the images
        also try focal lengths fitted to each pair, as ``ppo-cv pair`` does without ``--K``.
    max_init_trials : int, >= 1
    num_threads, seed : int
        pycolmap threads and random seed.
    verbose : bool
        Let pycolmap log to stderr.
    progress : callable, optional
        Called with a one-line message at each stage.
    **scoring
        Keyword arguments of :func:`score_pairs`.

    Returns
    -------
    SfmResult
        ``elapsed`` covers the pair scoring, the checks on the images and the mapping.

    Raises
    ------
    ReconstructionFailed
        No pair can seed the mapper: the ranking rejects them all, or every pair checked on
        its images is refused; the message counts the reasons and, when rotations explain
        them, says the images look like a panorama.
    """
    _check_choices(initialization, seeding, scoring)
    num_threads, seed, _, init_trials = _check_run_numbers(num_threads, seed, 1, max_init_trials)
    _check_hooks(progress, fix_intrinsics=fix_intrinsics, verbose=verbose)
    database_path, image_dir = as_path(database_path, "database_path"), _image_folder(image_dir)
    _require_database(database_path)
    start = time.perf_counter()
    pairs: tuple[PairScore, ...] = ()
    candidates: Iterator[PairScore | None] = iter([None])
    if initialization == "ppo":
        pairs, candidates, refused = _ppo_candidates(
            database_path, image_dir, scoring, progress, not fix_intrinsics
        )
    models: list[pycolmap.Reconstruction] = []
    initial_pair = None
    with _quiet(verbose), pycolmap.Database.open(database_path) as database:
        num_images = int(database.num_images())
        tried = 0
        for candidate in itertools.islice(candidates, init_trials):
            tried += 1
            options = _pipeline_options(image_dir, fix_intrinsics, num_threads, seed)
            manager = pycolmap.ReconstructionManager()
            if candidate is not None:
                _say(progress, f"seeding with {_names_of(candidate)} ({seeding})")
                if seeding == "pair-options":
                    _seed_options(options, candidate)
                else:
                    threshold = scoring.get("pri_threshold", ppo.DEFAULT_PRI_THRESHOLD)
                    _seed_two_view(database, candidate, manager, threshold)
            models, initial_pair = _run_pipeline(database, options, manager, progress, candidate)
            if candidate is not None and seeding == "two-view":
                initial_pair = (candidate.name1, candidate.name2)
            if _grew_from(models, candidate):
                break
    if initialization == "ppo":
        pairs = _with_refusals(pairs, refused)
        if not tried:
            raise ReconstructionFailed(_no_initial_pair(pairs, num_images))
    return _result(models, initialization, initial_pair, pairs, num_images, start)


def _ppo_candidates(
    database_path: Path, image_dir: Path, scoring: dict, progress, fit_focal: bool = False
):
    """The pairs scored by PPO, the accepted ones that ``ppo-cv pair`` also accepts on their
    images (lazily, best first), and the list that collects the refused ones as they are
    checked; :class:`ReconstructionFailed` when PPO accepts none."""
    _say(progress, "scoring candidate initial pairs with PPO")
    pairs = tuple(score_pairs(database_path, **scoring))
    if not any(p.accepted for p in pairs):
        with pycolmap.Database.open(database_path) as database:
            num_images = int(database.num_images())
        raise ReconstructionFailed(_no_initial_pair(pairs, num_images))
    threshold = scoring.get("pri_threshold", ppo.DEFAULT_PRI_THRESHOLD)
    refused: list[PairScore] = []
    candidates = _checked_candidates(
        database_path, image_dir, pairs, refused, threshold, progress, fit_focal
    )
    return pairs, candidates, refused


def _checked_candidates(
    database_path: Path,
    image_dir: Path,
    pairs: Sequence[PairScore],
    refused: list[PairScore],
    pri_threshold: float,
    progress: Progress | None,
    fit_focal: bool = False,
) -> Iterator[PairScore]:
    """The accepted pairs, best first, that :func:`ppo_cv.pipeline.estimate_pair` does not
    refuse on their images (the first :data:`MAX_IMAGE_CHECKS` accepted pairs are checked,
    as they are needed); the refused ones, rejection rewritten, are appended to ``refused``."""
    for pair in [p for p in pairs if p.accepted][:MAX_IMAGE_CHECKS]:
        _say(progress, f"checking {_names_of(pair)} on the images")
        rejection = _image_rejection(
            database_path, image_dir, pair, pri_threshold, fit_focal=fit_focal
        )
        if not rejection:
            yield pair
            continue
        _say(progress, f"refused {_names_of(pair)}: {rejection}")
        pure = rejection.startswith("pure rotation")
        refused.append(
            replace(
                pair,
                rejection=rejection,
                score=0.0,
                pure_rotation=pure or pair.pure_rotation,
                model="rotation" if pure else pair.model,
            )
        )


def _image_rejection(
    database_path: Path,
    image_dir: Path,
    pair: PairScore,
    pri_threshold: float,
    *,
    fit_focal: bool = False,
) -> str:
    """Why ``ppo-cv pair``'s decision refuses ``pair`` as an initial pair; empty when it does
    not. The images are read as pycolmap read them, with the database cameras (those
    ``ppo-cv pair`` guesses without ``--K``: the EXIF focal length or 1.2 times the larger
    side). With ``fit_focal`` (guessed cameras) a pair the guessed cameras do not call a pure
    rotation is refused when the ranking's decision on its verified matches does with the
    focal length of the conjugate rotation nearest their homography
    (:func:`rotation_focal_scale`, in :data:`FIELD_RANGE_DEG`), and when ``ppo-cv pair``'s
    later decisions, with the focal lengths fitted to the homography of its inliers and to
    their lens, do (:func:`ppo_cv.guessed_camera.decided_again`)."""
    from .images import load_image
    from .pipeline import PairOptions, estimate_pair

    with pycolmap.Database.open(database_path) as database:
        stored = _read_stored_pair(database, pair, with_matches=fit_focal)
    images = [
        load_image(image_dir / name, exif_orientation=False) for name in (pair.name1, pair.name2)
    ]
    given = not fit_focal
    (K1, dist1), (K2, dist2) = (_pipeline_camera(camera, given) for camera in stored.cameras)
    options = PairOptions(pri_threshold=pri_threshold)
    try:
        result = estimate_pair(*images, K1, K2, dist1, dist2, options=options)
    except ValueError as exc:
        return f"no reliable geometry on the images ({exc})"
    if result.pure_rotation or not fit_focal:
        return _rotation_refusal(result, "")
    scale = _fitted_focal_scale(stored)
    ranking = "" if scale is None else _ranking_rejection(stored, scale, pri_threshold)
    if ranking:
        focal = f"focal length {scale * K1[0, 0]:.1f} px fitted to the homography"
        return f"pure rotation on the images ({focal}: {ranking})"
    again = decided_again(result, images, options)
    if again is None:
        return ""
    decision, focal, how = again
    return _rotation_refusal(decision, f", focal length {focal:.1f} px {how}")


def _rotation_refusal(result: Any, focal_note: str) -> str:
    """The rejection of :func:`_image_rejection` for a pair ``result`` calls a pure rotation;
    empty for another."""
    if not result.pure_rotation:
        return ""
    return (
        f"pure rotation on the images (ppo-cv pair: PRI {result.pri:.4f}, {result.model}"
        f"{focal_note})"
    )


@dataclass(frozen=True)
class _StoredPair:
    """What a database holds of one pair: its two images and their cameras, and (when read)
    their keypoints and the pair's verified two-view geometry, read once for both the focal
    fit and the ranking."""

    images: tuple
    cameras: tuple
    keypoints: tuple | None = None
    geometry: Any = None


def _read_stored_pair(database, pair: PairScore, with_matches: bool) -> _StoredPair:
    images = tuple(database.read_image(i) for i in (pair.image_id1, pair.image_id2))
    cameras = tuple(database.read_camera(image.camera_id) for image in images)
    if not with_matches:
        return _StoredPair(images, cameras)
    keypoints = tuple(database.read_keypoints(image.image_id) for image in images)
    geometry = database.read_two_view_geometry(pair.image_id1, pair.image_id2)
    return _StoredPair(images, cameras, keypoints, geometry)


def _ranking_rejection(stored: _StoredPair, scale: float, pri_threshold: float) -> str:
    """The rejection :func:`score_pairs` gives the pair when its cameras' focal lengths are
    multiplied by ``scale`` and their distortion dropped; empty unless a pure rotation."""
    cameras = {}
    for image, camera in zip(stored.images, stored.cameras, strict=True):
        K = _scaled_camera(np.asarray(camera.calibration_matrix(), dtype=np.float64), scale)
        cameras[image.camera_id] = pycolmap.Camera(
            model="PINHOLE", width=camera.width, height=camera.height,
            params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2]],
        )  # fmt: skip
    ids = (image.image_id for image in stored.images)
    keypoints = dict(zip(ids, stored.keypoints, strict=True))
    scored = _score_geometry(
        stored.geometry, *stored.images, cameras, keypoints, pri_threshold=pri_threshold
    )
    return scored.rejection if scored.rejection.startswith("pure rotation") else ""


def _scaled_camera(K: np.ndarray, scale: float) -> np.ndarray:
    """``K`` with its focal lengths multiplied by ``scale``."""
    return K @ np.diag([scale, scale, 1.0])


def _fitted_focal_scale(stored: _StoredPair) -> float | None:
    """:func:`rotation_focal_scale` of the homography of the pair's verified matches, in the
    normalized coordinates of the database cameras; None with fewer than 8 matches, no
    homography, or no focal length in :data:`FIELD_RANGE_DEG`."""
    matches = np.asarray(stored.geometry.inlier_matches, dtype=np.int64).reshape(-1, 2)
    if len(matches) < 8:
        return None
    x1, x2 = (
        colmap.rays_from_camera(camera, np.asarray(points, dtype=np.float64)[rows, :2])
        for camera, points, rows in zip(stored.cameras, stored.keypoints, matches.T, strict=True)
    )
    camera = stored.cameras[0]
    fit = homography_rotation_focal(
        x1, x2, camera.mean_focal_length(), max(int(camera.width), int(camera.height))
    )
    return None if fit is None else fit[0]


def _pipeline_camera(camera: pycolmap.Camera, given: bool) -> tuple[np.ndarray, Any]:
    """``K`` and OpenCV distortion coefficients (None for none) of a database camera. A camera
    ``given`` (``--K``) comes back in OpenCV's pixel coordinates, as it was given; one pycolmap
    guessed is read as :func:`ppo_cv.calib.camera_from_exif` reads pycolmap's guess, the camera
    ``ppo-cv pair`` guesses for the image, so that both decide a pair alike."""
    K = np.asarray(camera.calibration_matrix(), dtype=np.float64)
    if given:
        K[:2, 2] -= COLMAP_PIXEL_OFFSET
    params = np.asarray(camera.params, dtype=np.float64)
    radial = {"SIMPLE_RADIAL": params[3:4], "RADIAL": params[3:5]}.get(camera.model_name)
    if camera.model_name == "OPENCV":
        dist = params[4:8]
    elif radial is not None:
        dist = np.concatenate([radial, np.zeros(4 - len(radial))])
    else:
        dist = np.zeros(4)
    return K, (dist if np.any(dist) else None)


def _with_refusals(pairs: Sequence[PairScore], refused: Sequence[PairScore]) -> tuple:
    """The ranking with the pairs refused on their images replaced, ranked as rejected."""
    by_ids = {(p.image_id1, p.image_id2): p for p in refused}
    updated = [by_ids.get((p.image_id1, p.image_id2), p) for p in pairs]
    return tuple(sorted(updated, key=lambda s: (not s.accepted, -s.score, -s.num_inliers)))


def _check_scoring(scoring: dict) -> None:
    """TypeError naming a keyword that :func:`score_pairs` does not take, ValueError for a
    value that is not a finite number >= 0 (> 0 for ``target_tri_angle``, a whole number for
    ``min_inliers``): checked before the features are extracted."""
    accepted = list(inspect.signature(score_pairs).parameters)[1:]
    for name, value in scoring.items():
        if name not in accepted:
            raise TypeError(
                f"unexpected keyword argument {shown(name)}; the scoring takes "
                f"{', '.join(accepted)}"
            )
        if name == "min_inliers":
            as_whole_number(value, name, 0, MAX_WHOLE_NUMBER)
        elif name == "pri_threshold":
            as_pri_threshold(value)
        elif name == "target_tri_angle":
            as_positive(value, name)
        else:
            as_nonnegative(value, name)


def _check_choices(initialization: str, seeding: str, scoring: dict) -> None:
    """ValueError naming an unknown initialization or seeding; the scoring keywords checked
    by :func:`_check_scoring`."""
    if initialization not in INITIALIZATIONS:
        raise ValueError(
            f"initialization must be one of {', '.join(INITIALIZATIONS)}, got "
            f"{shown(initialization)}"
        )
    if seeding not in SEEDINGS:
        raise ValueError(f"seeding must be one of {', '.join(SEEDINGS)}, got {shown(seeding)}")
    _check_scoring(scoring)


def _grew_from(models: list, pair: PairScore | None) -> bool:
    """Whether some model holds at least two images (and, for a given pair, both of them)."""
    for model in models:
        names = {model.image(i).name for i in model.reg_image_ids()}
        if len(names) >= 2 and (pair is None or {pair.name1, pair.name2} <= names):
            return True
    return False


def _seed_two_view(
    database: pycolmap.Database,
    pair: PairScore,
    manager: pycolmap.ReconstructionManager,
    pri_threshold: float,
) -> None:
    """Put the bundle-adjusted PPO two-view reconstruction of ``pair`` into ``manager``."""
    image1, image2 = database.read_image(pair.image_id1), database.read_image(pair.image_id2)
    camera1, camera2 = (
        database.read_camera(image1.camera_id),
        database.read_camera(image2.camera_id),
    )
    keypoints1 = database.read_keypoints(image1.image_id)
    keypoints2 = database.read_keypoints(image2.image_id)
    geometry = database.read_two_view_geometry(image1.image_id, image2.image_id)
    pose = colmap.recover_pose_from_geometry(
        geometry, camera1, keypoints1, camera2, keypoints2, pri_threshold=pri_threshold
    )
    seed = colmap.two_view_reconstruction(
        camera1, camera2, image1, image2, keypoints1, keypoints2, geometry.inlier_matches, pose
    )
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    options.print_summary = False
    config = pycolmap.BundleAdjustmentConfig()
    config.add_image(image1.image_id)
    config.add_image(image2.image_id)
    config.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    pycolmap.create_default_bundle_adjuster(options, config, seed).solve()
    with tempfile.TemporaryDirectory(prefix="ppo-cv-seed-") as folder:
        seed.write(folder)
        manager.read(folder)


def _seed_options(options: pycolmap.IncrementalPipelineOptions, pair: PairScore) -> None:
    options.init_image_id1 = pair.image_id1
    options.init_image_id2 = pair.image_id2
    mapper = options.mapper
    mapper.init_min_tri_angle = min(mapper.init_min_tri_angle, 0.5 * pair.tri_angle)
    mapper.init_min_num_inliers = min(mapper.init_min_num_inliers, max(15, pair.num_inliers // 2))


def _result(models, initialization, initial_pair, pairs, num_images, start) -> SfmResult:
    best = max(models, key=lambda m: (m.num_reg_images(), m.num_points3D()), default=None)
    registered = int(best.num_reg_images()) if best is not None else 0
    error = float(best.compute_mean_reprojection_error()) if registered else float("nan")
    return SfmResult(
        reconstruction=best,
        initialization=initialization,
        initial_pair=initial_pair,
        pairs=pairs,
        num_images=num_images,
        num_registered=registered,
        num_points3D=int(best.num_points3D()) if best is not None else 0,
        mean_reprojection_error=error,
        num_models=len(models),
        elapsed=time.perf_counter() - start,
    )


def run_sfm(
    image_dir: str | os.PathLike,
    output_dir: str | os.PathLike | None = None,
    *,
    K: Any = None,
    initialization: str = "ppo",
    seeding: str = "two-view",
    database_path: str | os.PathLike | None = None,
    max_num_features: int = 8192,
    num_threads: int = 2,
    seed: int = 0,
    verbose: bool = False,
    progress: Progress | None = None,
    overwrite: bool = False,
    exif_orientation: bool = False,
    **scoring: Any,
) -> SfmResult:
    """Structure from motion of an image folder: features, matches, PPO-seeded mapping.

    Parameters
    ----------
    image_dir : path
    output_dir : path, optional
        Where to write the COLMAP model (``cameras.bin``, ``images.bin``, ``points3D.bin``, ...)
        and ``initial_pairs.txt`` (the ranking). It must not exist (or be empty, or
        ``overwrite``); it is checked before any work, written in a temporary sibling folder and
        moved into place at the end.
    K : array_like, shape (3, 3), optional
        Known intrinsics, held fixed; otherwise pycolmap estimates them.
    initialization : {"ppo", "colmap"}
    seeding : {"two-view", "pair-options"}
        See :func:`reconstruct`.
    database_path : path, optional
        Where to keep the feature database (a new file, renamed into place once the features
        are matched, kept when no model can be built from them, never left half-written); a
        temporary one by default. Never inside ``output_dir`` (:func:`require_database_outside`).
    overwrite : bool
        Replace an existing ``output_dir`` (never ``database_path``).
    exif_orientation : bool
        Reconstruct the photos upright as their EXIF orientation says: those stored turned are
        given to pycolmap as upright copies (same names, JPEG quality 95). False: the pixels as
        stored, as pycolmap reads them.
    max_num_features, num_threads, seed, verbose, progress, **scoring
        See :func:`prepare_database` and :func:`reconstruct`.

    Returns
    -------
    SfmResult

    Raises
    ------
    ReconstructionFailed
        When the images were matched but no model could be built (the database is kept).
    ValueError
        For bad arguments or unreadable images, before anything is written.
    """
    _check_choices(initialization, seeding, scoring)
    num_threads, seed, max_num_features, _ = _check_run_numbers(num_threads, seed, max_num_features)
    _check_hooks(progress, verbose=verbose, overwrite=overwrite, exif_orientation=exif_orientation)
    image_dir = _image_folder(image_dir)
    if output_dir is not None:  # never the image folder, nor one holding it, even replaced
        output_dir = as_path(output_dir, "output_dir")
        check_apart(output_dir, [image_dir], "output_dir ")
        require_no_images(output_dir, "output_dir ", "run_sfm(image_dir, output_dir)")
        check_target(output_dir, "folder", overwrite, [image_dir], "output_dir ", API_REPLACE_HINT)
    if database_path is not None:
        _check_new_database(as_path(database_path, "database_path"), image_dir)
        if output_dir is not None:
            require_database_outside(database_path, output_dir)
    with contextlib.ExitStack() as stack:
        scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ppo-cv-sfm-")))
        if exif_orientation:
            image_dir = _upright_images(image_dir, scratch / "upright")
        database = scratch / "db.db"
        if database_path is not None:  # built beside its target, renamed when complete
            database = stack.enter_context(_staged_file(database_path, ReconstructionFailed))
        prepare_database(
            image_dir, database, K=K, max_num_features=max_num_features,
            num_threads=num_threads, seed=seed, verbose=verbose, progress=progress,
        )  # fmt: skip
        result = reconstruct(
            database, image_dir, initialization=initialization, seeding=seeding,
            fix_intrinsics=K is not None,
            num_threads=num_threads, seed=seed, verbose=verbose, progress=progress, **scoring,
        )  # fmt: skip
        if output_dir is not None:
            if result.reconstruction is None:
                raise ReconstructionFailed(_nothing_built(result))
            write_model(result, output_dir, overwrite=overwrite)
            _say(progress, f"wrote {output_dir}")
    return result


def _nothing_built(result: SfmResult) -> str:
    """Why no model is written when the mapper ran: pycolmap's own initialisation found no
    pair, or it grew no model from the PPO pairs tried."""
    if result.initialization == "colmap":
        return (
            f"pycolmap's own initialisation found no pair of the {result.num_images} images to "
            "start a model from (a panorama, or too little parallax) and no model was written; "
            "the PPO initialisation names why each pair is refused"
        )
    return (
        f"pycolmap's mapper grew no model of the {result.num_images} images from the PPO "
        "initial pairs tried, and no model was written"
    )


def _upright_images(image_dir: Path, folder: Path) -> Path:
    """``image_dir`` itself when no image is stored turned or flipped, else a folder of links
    to its images where those are replaced by upright copies of the same name."""
    from PIL import Image, ImageOps

    from .images import exif_layout

    names = list_images(image_dir)
    turned = [n for n in names if exif_layout(image_dir / n).orientation not in (None, 1)]
    if not turned:
        return image_dir
    folder.mkdir()
    for name in names:
        if name not in turned:
            (folder / name).symlink_to((image_dir / name).resolve())
            continue
        with Image.open(image_dir / name) as image:
            upright = ImageOps.exif_transpose(image)
            upright.save(folder / name, format=image.format, quality=95, exif=upright.getexif())
    return folder


@contextlib.contextmanager
def _staged_file(
    path: str | os.PathLike, keep_on: type[BaseException] | tuple = ()
) -> Iterator[Path]:
    """A path for a new file (with its side files) in a temporary sibling folder.

    When the block succeeds, or raises one of ``keep_on`` (the file being complete), the file
    is renamed to ``path``; otherwise the folder and all it holds (a partial SQLite database
    and its journal) are removed.
    """
    target = check_target(path, "file")
    staging = None
    try:
        with signals_deferred():
            staging = staging_folder(target)
        try:
            yield staging / target.name
        except keep_on:
            with signals_deferred():
                os.rename(staging / target.name, target)
            raise
        with signals_deferred():
            os.rename(staging / target.name, target)
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)


def format_pairs(pairs: Sequence[PairScore]) -> str:
    """The ranking as text, one pair a line: names, score, inliers, PRI, angle, verdict; a
    name holding whitespace or starting with ``#`` (a comment) in double quotes, as in a pairs
    file."""
    require_instance(pairs, (list, tuple), "pairs", " (of ppo_cv.sfm.PairScore, sfm.score_pairs)")
    lines = ["# name1 name2 score num_inliers num_matches pri tri_angle_deg verdict"]
    for p in pairs:
        require_instance(p, PairScore, "each pair", " (sfm.score_pairs)")
        verdict = "ok" if p.accepted else p.rejection.replace(" ", "_")
        name1, name2 = (_pairs_file_name(n) for n in (p.name1, p.name2))
        lines.append(
            f"{name1} {name2} {p.score:.1f} {p.num_inliers} {p.num_matches} "
            f"{p.pri:.4f} {p.tri_angle:.2f} {verdict}"
        )
    return "\n".join(lines) + "\n"


def pair_text(name1: str, name2: str) -> str:
    """Two image names as one line shows them, each in double quotes where it holds whitespace
    or starts with ``#`` (as in a pairs file), so that ``a b.png c.png`` reads as one pair.

    >>> pair_text("a b.png", "c.png")
    '"a b.png" c.png'
    """
    require_instance(name1, str, "name1")
    require_instance(name2, str, "name2")
    return f"{_pairs_file_name(name1)} {_pairs_file_name(name2)}"


def _names_of(pair: PairScore) -> str:
    """The pair's two image names as :func:`pair_text` shows them."""
    return pair_text(pair.name1, pair.name2)


def _pairs_file_name(name: str) -> str:
    """``name`` as a pairs-file field: in double quotes when it holds whitespace or starts with
    ``#``, which would start a comment."""
    return f'"{name}"' if name.split() != [name] or name.startswith("#") else name


def write_model(result: SfmResult, output_dir: str | os.PathLike, overwrite: bool = False) -> None:
    """Write the reconstruction (COLMAP binary) and the pair ranking into a new folder.

    The folder is built beside its target and renamed when complete; an existing non-empty
    ``output_dir`` is a ValueError unless ``overwrite``; ``result`` not an :class:`SfmResult`
    a TypeError, before anything is written.
    """
    require_instance(result, SfmResult, "result", " (sfm.run_sfm or sfm.reconstruct)")
    with atomic_directory(output_dir, overwrite, API_REPLACE_HINT) as staging:
        result.reconstruction.write(staging)
        if result.pairs:
            (staging / "initial_pairs.txt").write_text(format_pairs(result.pairs), "utf-8")


def pose_errors(reconstruction, gt) -> tuple[list[float], list[float]]:
    """Relative rotation errors and translation-direction errors (degrees) of registered pairs.

    Translation errors are skipped for ground-truth pairs without translation (pure rotation).
    ``gt`` maps a pair of image names to its ``(R, t)``: a rotation matrix and three finite
    numbers (TypeError or ValueError naming the first entry that is not).
    """
    require_instance(reconstruction, pycolmap.Reconstruction, "reconstruction")
    ids = {reconstruction.image(i).name: i for i in reconstruction.reg_image_ids()}
    rotation_errors, translation_errors = [], []
    for (name1, name2), R_gt, t_gt in _checked_gt(gt):
        if name1 not in ids or name2 not in ids:
            continue
        R, t = colmap.relative_pose(reconstruction, ids[name1], ids[name2])
        rotation_errors.append(rotation_error_deg(R, R_gt))
        if np.linalg.norm(t_gt) > 1e-9 and np.linalg.norm(t) > 1e-12:
            translation_errors.append(direction_error_deg(t, t_gt))
    return rotation_errors, translation_errors


def _checked_gt(gt: Any) -> list[tuple[tuple[str, str], np.ndarray, np.ndarray]]:
    """The entries ``((name1, name2), R, t)`` of :func:`pose_errors`' ``gt``; TypeError or
    ValueError naming the first key that is no pair of names or value that is no ``(R, t)``."""
    require_instance(gt, dict, "gt", ": {(name1, name2): (R, t)}")
    entries = []
    for key, value in gt.items():
        if not (isinstance(key, tuple) and len(key) == 2 and all(isinstance(n, str) for n in key)):
            raise TypeError(f"gt keys must be (name1, name2) image names, got {shown(key)}")
        if not (isinstance(value, (tuple, list)) and len(value) == 2):
            size = f" of length {len(value)}" if hasattr(value, "__len__") else ""
            raise TypeError(f"gt[{key!r}] must be (R, t), got {type(value).__name__}{size}")
        R = as_rotation(value[0], f"gt[{key!r}] R")
        t = as_finite_rows([np.ravel(value[1])], f"gt[{key!r}] t", 3)[0]
        entries.append((key, R, t))
    return entries
