"""Synthetic datasets on disk: images, ground-truth JSON, depth maps and a pairs file.

Layout of a dataset directory::

    OUT/pairs_with_gt.txt           one line per pair, same format as the freiburg set
    OUT/images/pair_000_1.png       view 1 (RGB PNG)
    OUT/images/pair_000_2.png       view 2
    OUT/gt/pair_000.json            true K1, K2, distortion; K1_given, K2_given; R, t, T_1to2,
                                    parameters
    OUT/gt/pair_000_depth1.npy      float32 (H, W): Z in camera 1 at each pixel centre (inf:
                                    at infinity)

A pairs-file line is ``name1 name2 0 0 K1(9, row-major) K2(9) T_1to2(16, row-major)`` where
``T_1to2 = [[R, t], [0, 0, 0, 1]]`` maps camera-1 to camera-2 coordinates; image names are
relative to ``OUT/images``. The pairs file carries the intrinsics an estimator is given
(``K1_given``, ``K2_given``: a focal length a few percent off for imperfect pairs), the JSON
file also the true ones and the lens distortion nobody is told about.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from ppo_cv.atomic import linked_output, staging_folder, worker_count, worker_pool
from ppo_cv.calib import read_text_file
from ppo_cv.checks import (
    as_camera_matrix,
    as_number,
    as_path,
    as_rotation,
    as_vector3,
    require_instance,
    shown,
)
from ppo_cv.images import file_mode

from .imperfect import Imperfections
from .motion import DEFAULT_SCENE, MAX_BASELINE_RATIO, MOTIONS, check_pivot_offset, sample_motion
from .names import BASELINE_MOTIONS
from .render import RenderedPair, _check_size, render_pair
from .scenes import SCENES, make_scene
from .textures import texture_pool
from .warp import make_warped_pair, source_photos

__all__ = ["PAIRS_FILE", "make_dataset", "make_pair", "pairs_line", "read_pairs", "write_pair"]

PAIRS_FILE = "pairs_with_gt.txt"


def _check_args(motion, scene, seed, index, size, alpha, supersample, noise_std, blur_sigma,
                baseline_ratio=None, imperfections=None, pivot_offset=0.0):  # fmt: skip
    """Validate the arguments of :func:`make_pair`; returns the scene name to use."""
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    check_pivot_offset(motion, pivot_offset)
    scene = DEFAULT_SCENE[motion] if scene is None else scene
    if scene not in SCENES:
        raise ValueError(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}")
    for name, value in (("seed", seed), ("index", index), ("supersample", supersample)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer, got {type(value).__name__} {shown(value)}")
        if value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    if not 1 <= supersample <= 8:
        raise ValueError(f"supersample must be in 1..8, got {supersample}")
    _check_size(size)
    if alpha is not None and not (np.isfinite(as_number(alpha, "alpha")) and 0.0 < alpha <= 1.0):
        raise ValueError(f"alpha must be in (0, 1], got {alpha}")
    if baseline_ratio is not None:
        ratio = as_number(baseline_ratio, "baseline_ratio")
        if not (np.isfinite(ratio) and 0.0 <= ratio <= MAX_BASELINE_RATIO):
            raise ValueError(
                f"baseline_ratio must be in [0, {MAX_BASELINE_RATIO}], got {baseline_ratio}"
            )
        if motion not in BASELINE_MOTIONS:
            raise ValueError(
                f"baseline_ratio applies to {' and '.join(BASELINE_MOTIONS)} only, not {motion!r}"
            )
    for name, value in (("noise_std", noise_std), ("blur_sigma", blur_sigma)):
        if not np.isfinite(as_number(value, name)) or value < 0:
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
    if imperfections is not None:
        if not isinstance(imperfections, Imperfections):
            raise TypeError(f"imperfections must be Imperfections or None, got {imperfections!r}")
        if noise_std or blur_sigma:
            raise ValueError("give noise_std and blur_sigma through imperfections, not both")
    return scene


def make_pair(
    motion: str = "general",
    seed: int = 0,
    index: int = 0,
    size: tuple[int, int] = (640, 480),
    scene: str | None = None,
    alpha: float | None = None,
    supersample: int = 2,
    noise_std: float = 0.0,
    blur_sigma: float = 0.0,
    same_intrinsics: bool = True,
    baseline_ratio: float | None = None,
    imperfections: Imperfections | None = None,
    pivot_offset: float = 0.0,
) -> RenderedPair:
    """Render pair ``index`` of the dataset ``(motion, seed)``.

    The scene, cameras and noise are drawn from ``numpy.random.default_rng([seed, index])``,
    so a pair does not depend on how many pairs are generated or in which order.

    Parameters
    ----------
    motion : str
        One of :data:`MOTIONS`.
    seed, index : int
        Dataset seed and pair index (non-negative).
    size : (int, int)
        Image width and height.
    scene : str, optional
        One of :data:`SCENES`; default :data:`DEFAULT_SCENE` of the motion.
    alpha : float, optional
        Parallax factor of ``small-parallax``.
    supersample, noise_std, blur_sigma
        See :func:`render_pair`.
    same_intrinsics : bool
        ``K2 = K1`` if True.
    baseline_ratio : float, optional
        ``baseline / median depth`` of ``tiny-baseline`` and ``tripod`` in [0, 0.5]; drawn
        if None.
    imperfections : Imperfections, optional
        Render as a real camera would (:class:`Imperfections`): the drawn radial distortion
        is applied to both views, the field of view drawn in ``hfov_range``, the views blurred,
        noised and JPEG-compressed, and ``K1_given``, ``K2_given`` carry the focal length off
        by the drawn factor. ``params`` records ``k1``, ``k2``, ``focal_factor``,
        ``hfov_deg`` and ``jpeg_quality``. Without it the pair is exactly as before this
        option existed.
    pivot_offset : float, default 0
        ``panorama`` only: the camera turns about a point this many metres behind its centre
        (a tripod screw behind the lens), so ``t = P - R P`` is a few centimetres instead of 0.

    Returns
    -------
    RenderedPair
    """
    scene = _check_args(motion, scene, seed, index, size, alpha, supersample, noise_std,
                        blur_sigma, baseline_ratio, imperfections, pivot_offset)  # fmt: skip
    rng = np.random.default_rng([seed, index])
    world = make_scene(scene, rng)
    drawn = None if imperfections is None else imperfections.draw(rng)
    dist = None if drawn is None else drawn.dist
    hfov_range = None if imperfections is None else imperfections.hfov_range
    cams = sample_motion(motion, world, rng, size, alpha, same_intrinsics, hfov_range,
                         baseline_ratio, dist, pivot_offset)  # fmt: skip
    params = {"seed": int(seed), "index": int(index), **cams.params}
    if drawn is not None:
        noise_std, blur_sigma = drawn.noise_std, drawn.blur_sigma
        params.update(drawn.record(), hfov_deg=cams.params["hfov1_deg"], imperfect=True,
                      imperfections=imperfections.record())  # fmt: skip
    pair = render_pair(
        world, cams.K1, cams.K2, cams.R, cams.t, size, supersample, dist1=dist, dist2=dist,
        noise_std=noise_std, blur_sigma=blur_sigma, seed=[seed, index], params=params,
    )  # fmt: skip
    if drawn is None:
        return pair
    centre = pair.image1.shape[1::-1] if imperfections.centred_principal_point else None
    return drawn.apply_to(pair, centre)


def _matrix_text(values: np.ndarray, fmt: str) -> str:
    return " ".join(fmt % v for v in np.asarray(values, float).ravel())


def pairs_line(
    name1: str, name2: str, K1: np.ndarray, K2: np.ndarray, R: np.ndarray, t: np.ndarray
) -> str:
    """One pairs-file line ``name1 name2 0 0 K1(9) K2(9) T_1to2(16)`` (no newline).

    ValueError or TypeError naming what :func:`read_pairs` could not read back: a name that is
    empty, holds a space or starts with ``#``, a camera matrix, rotation or translation (3
    finite numbers) that is not one.
    """
    for label, name in (("name1", name1), ("name2", name2)):
        if not isinstance(name, str):
            raise TypeError(f"{label} must be a text, got {type(name).__name__}")
        if not name or name.startswith("#") or len(name.split()) != 1 or name.strip() != name:
            raise ValueError(
                f"{label} must be a name without spaces, not starting with '#', got {shown(name)}"
            )
    K1, K2 = as_camera_matrix(K1, "K1"), as_camera_matrix(K2, "K2")
    T = np.eye(4)
    t = as_vector3(t, "t")
    T[:3, :3], T[:3, 3] = as_rotation(R, "R"), t
    return " ".join(
        [name1, name2, "0", "0", _matrix_text(K1, "%.6f"), _matrix_text(K2, "%.6f"),
         _matrix_text(T, "%.12f")]
    )  # fmt: skip


def read_pairs(path: str | os.PathLike) -> list[dict]:
    """Parse a pairs file into dicts with keys name1, name2, K1, K2, R, t (float64).

    A path that is no readable text file is a ValueError naming it, as for a calibration file
    (:func:`ppo_cv.calib.load_calibration`).
    """
    path = os.fspath(as_path(path, "path"))
    if not stat.S_ISREG(file_mode(path, "pairs file")):  # a FIFO would block the reader
        raise ValueError(f"pairs file {path} is not a regular file")
    records = []
    for number, line in enumerate(read_text_file(path, "pairs file").splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 38:
            raise ValueError(f"{path}:{number}: expected 38 fields, got {len(fields)}")
        try:
            values = np.array(fields[4:], dtype=np.float64)
        except ValueError:
            raise ValueError(f"{path}:{number}: fields 5 to 38 must be numbers") from None
        if not np.all(np.isfinite(values)):
            raise ValueError(f"{path}:{number}: K1, K2 and T_1to2 must be finite numbers")
        T = values[18:].reshape(4, 4)
        records.append({
            "name1": fields[0], "name2": fields[1],
            "K1": values[:9].reshape(3, 3), "K2": values[9:18].reshape(3, 3),
            "R": T[:3, :3].copy(), "t": T[:3, 3].copy(),
        })  # fmt: skip
    return records


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {path}")


def write_pair(pair: RenderedPair, root: str | os.PathLike, name: str) -> str:
    """Write one pair under ``root`` (see the module layout); returns its pairs-file line."""
    require_instance(pair, RenderedPair, "pair")
    root = as_path(root, "root")
    if not isinstance(name, str) or not name or name != Path(name).name:
        raise ValueError(f"name must be a file name without folders, got {shown(name)}")
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "gt").mkdir(parents=True, exist_ok=True)
    image1, image2 = f"{name}_1.png", f"{name}_2.png"
    _write_png(root / "images" / image1, pair.image1)
    _write_png(root / "images" / image2, pair.image2)
    np.save(root / "gt" / f"{name}_depth1.npy", pair.depth1)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = pair.R, pair.t
    height, width = pair.image1.shape[:2]
    record = {
        "name": name,
        "convention": "x2 = R x1 + t (camera coordinates, metres); pixels at integer centres",
        "image1": f"images/{image1}",
        "image2": f"images/{image2}",
        "width": width,
        "height": height,
        "K1": pair.K1.tolist(),
        "K2": pair.K2.tolist(),
        "K1_given": pair.K1_given.tolist(),
        "K2_given": pair.K2_given.tolist(),
        "R": pair.R.tolist(),
        "t": pair.t.tolist(),
        "T_1to2": T.tolist(),
        "dist1": pair.dist1.tolist(),
        "dist2": pair.dist2.tolist(),
        "depth1": f"gt/{name}_depth1.npy",
        "depth1_meaning": "float32 (H, W): Z in camera 1 at pixel centres, inf at infinity, "
        "NaN unknown",
        "params": pair.params,
    }
    text = json.dumps(record, indent=1, sort_keys=True, default=_json_default)
    (root / "gt" / f"{name}.json").write_text(text + "\n", encoding="utf-8")
    return pairs_line(image1, image2, pair.K1_given, pair.K2_given, pair.R, pair.t)


def _check_warp_args(motion, scene, alpha, baseline_ratio, noise_std, blur_sigma, same):
    if motion not in (None, "panorama"):
        raise ValueError(f"warped photos are tripod pans (motion panorama), not {motion!r}")
    for name, value in (("scene", scene), ("alpha", alpha), ("baseline_ratio", baseline_ratio)):
        if value is not None:
            raise ValueError(f"{name} does not apply to warped photos")
    if noise_std or blur_sigma:
        raise ValueError("give noise_std and blur_sigma of warped photos through imperfections")
    if not same:
        raise ValueError("warped photos share one camera: same_intrinsics must be True")


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def _job(args: tuple) -> str:
    root, name, kind, kwargs = args
    if kind == "warp":
        return write_pair(make_warped_pair(**kwargs), root, name)
    return write_pair(make_pair(**kwargs), root, name)


def _init_worker() -> None:
    cv2.setNumThreads(1)
    texture_pool()


def make_dataset(
    out_dir: str | os.PathLike,
    pairs: int = 20,
    motion: str | None = None,
    seed: int = 0,
    size: tuple[int, int] | None = None,
    scene: str | None = None,
    alpha: float | None = None,
    supersample: int = 2,
    noise_std: float = 0.0,
    blur_sigma: float = 0.0,
    same_intrinsics: bool = True,
    workers: int | None = None,
    baseline_ratio: float | None = None,
    imperfections: Imperfections | None = None,
    source: str = "render",
    warp_source: str | os.PathLike | Sequence | None = None,
    pivot_offset: float = 0.0,
) -> Path:
    """Render ``pairs`` pairs of one motion preset into a new directory ``out_dir``.

    The directory is built in a temporary sibling and renamed at the end, so ``out_dir``
    either holds a complete dataset or is not created. Pair ``i`` is :func:`make_pair` (or
    :func:`make_warped_pair`) with ``index = i``; the bytes written depend only on the
    arguments, not on ``workers``.

    Parameters
    ----------
    out_dir : path
        Must not exist, or be an empty directory; a symbolic link to one is kept and the folder
        it leads to written (:func:`ppo_cv.atomic.linked_output`).
    pairs : int
        Number of pairs (>= 1).
    motion : str, optional
        One of :data:`MOTIONS` (default ``general``); with ``source="warp"`` only
        ``panorama`` (the default there).
    size : (int, int), optional
        Image width and height; default 640x480 for renders, 0.65 of the photo for warps.
    workers : int, optional
        Worker processes (default: one per available CPU), capped at the available CPUs and
        at ``pairs`` (:func:`ppo_cv.atomic.worker_count`).
    source : {"render", "warp"}, default "render"
        Rendered scenes (:func:`make_pair`) or real photos warped by a pure rotation
        (:func:`make_warped_pair`; ``scene``, ``alpha``, ``baseline_ratio``, ``supersample``,
        ``noise_std``, ``blur_sigma`` and ``same_intrinsics`` do not apply).
    warp_source : path or sequence of paths, optional
        Photos to warp (see :func:`source_photos`).
    seed, scene, alpha, supersample, noise_std, blur_sigma, same_intrinsics, baseline_ratio, \
imperfections, pivot_offset
        See :func:`make_pair`.

    Returns
    -------
    pathlib.Path
        ``out_dir``; its pairs file is ``out_dir / PAIRS_FILE``.
    """
    given = as_path(out_dir, "out_dir")
    out = linked_output(given, "folder")
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} is a file, not a folder")
    if isinstance(pairs, bool) or not isinstance(pairs, (int, np.integer)) or pairs < 1:
        raise ValueError(f"pairs must be a positive integer, got {pairs!r}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"{out} exists and is not an empty directory")
    if source == "render":
        motion = "general" if motion is None else motion
        size = (640, 480) if size is None else size
        kwargs = {
            "motion": motion, "seed": seed, "size": size, "scene": scene, "alpha": alpha,
            "supersample": supersample, "noise_std": noise_std, "blur_sigma": blur_sigma,
            "same_intrinsics": same_intrinsics, "baseline_ratio": baseline_ratio,
            "imperfections": imperfections, "pivot_offset": pivot_offset,
        }  # fmt: skip
        _check_args(motion, scene, seed, 0, size, alpha, supersample, noise_std, blur_sigma,
                    baseline_ratio, imperfections, pivot_offset)  # fmt: skip
    elif source == "warp":
        _check_warp_args(motion, scene, alpha, baseline_ratio, noise_std, blur_sigma,
                         same_intrinsics)  # fmt: skip
        if pivot_offset:
            raise ValueError("pivot_offset does not apply to warped photos")
        kwargs = {"seed": seed, "imperfections": imperfections, "size": size,
                  "source": source_photos(warp_source)}  # fmt: skip
        make_warped_pair(**kwargs, index=0)
    else:
        raise ValueError(f"source must be 'render' or 'warp', got {source!r}")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    workers = worker_count(workers, pairs)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = staging_folder(out)
    try:
        jobs = [(tmp, f"pair_{i:03d}", source, {**kwargs, "index": i}) for i in range(pairs)]
        if workers == 1:
            lines = [_job(job) for job in jobs]
        else:
            with worker_pool(workers, _init_worker) as pool:
                lines = pool.map(_job, jobs)
        (tmp / PAIRS_FILE).write_text("\n".join(lines) + "\n", encoding="utf-8")
        tmp.chmod(0o755)
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return given
