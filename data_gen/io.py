"""Synthetic datasets on disk: images, ground-truth JSON, depth maps and a pairs file.

Layout of a dataset directory::

    OUT/pairs_with_gt.txt           one line per pair, same format as the freiburg set
    OUT/images/pair_000_1.png       view 1 (RGB PNG)
    OUT/images/pair_000_2.png       view 2
    OUT/gt/pair_000.json            K1, K2, R, t, T_1to2, distortion, parameters
    OUT/gt/pair_000_depth1.npy      float32 (H, W): Z in camera 1 at each pixel centre (inf:
                                    at infinity)

A pairs-file line is ``name1 name2 0 0 K1(9, row-major) K2(9) T_1to2(16, row-major)`` where
``T_1to2 = [[R, t], [0, 0, 0, 1]]`` maps camera-1 to camera-2 coordinates; image names are
relative to ``OUT/images``.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import tempfile
from pathlib import Path

import cv2
import numpy as np

from .motion import DEFAULT_SCENE, MOTIONS, sample_motion
from .render import RenderedPair, render_pair
from .scenes import SCENES, make_scene
from .textures import texture_pool

__all__ = ["PAIRS_FILE", "make_dataset", "make_pair", "pairs_line", "read_pairs", "write_pair"]

PAIRS_FILE = "pairs_with_gt.txt"


def _check_args(motion, scene, seed, index, size, alpha, supersample, noise_std, blur_sigma):
    """Validate the arguments of :func:`make_pair`; returns the scene name to use."""
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    scene = DEFAULT_SCENE[motion] if scene is None else scene
    if scene not in SCENES:
        raise ValueError(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}")
    for name, value in (("seed", seed), ("index", index), ("supersample", supersample)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    if not 1 <= supersample <= 8:
        raise ValueError(f"supersample must be in 1..8, got {supersample}")
    try:
        width, height = (int(v) for v in size)
    except (TypeError, ValueError):
        raise TypeError(f"size must be (width, height), got {size!r}") from None
    if not (8 <= width <= 8192 and 8 <= height <= 8192):
        raise ValueError(f"size must be between 8 and 8192 pixels per side, got {size!r}")
    if alpha is not None and not (np.isfinite(alpha) and 0.0 < alpha <= 1.0):
        raise ValueError(f"alpha must be in (0, 1], got {alpha}")
    for name, value in (("noise_std", noise_std), ("blur_sigma", blur_sigma)):
        if not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
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

    Returns
    -------
    RenderedPair
    """
    scene = _check_args(motion, scene, seed, index, size, alpha, supersample, noise_std,
                        blur_sigma)  # fmt: skip
    rng = np.random.default_rng([seed, index])
    world = make_scene(scene, rng)
    cams = sample_motion(motion, world, rng, size, alpha, same_intrinsics)
    return render_pair(
        world, cams.K1, cams.K2, cams.R, cams.t, size, supersample,
        noise_std=noise_std, blur_sigma=blur_sigma, seed=[seed, index],
        params={"seed": int(seed), "index": int(index), **cams.params},
    )  # fmt: skip


def _matrix_text(values: np.ndarray, fmt: str) -> str:
    return " ".join(fmt % v for v in np.asarray(values, float).ravel())


def pairs_line(
    name1: str, name2: str, K1: np.ndarray, K2: np.ndarray, R: np.ndarray, t: np.ndarray
) -> str:
    """One pairs-file line ``name1 name2 0 0 K1(9) K2(9) T_1to2(16)`` (no newline)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.asarray(t, float).ravel()
    return " ".join(
        [name1, name2, "0", "0", _matrix_text(K1, "%.6f"), _matrix_text(K2, "%.6f"),
         _matrix_text(T, "%.12f")]
    )  # fmt: skip


def read_pairs(path: str | os.PathLike) -> list[dict]:
    """Parse a pairs file into dicts with keys name1, name2, K1, K2, R, t (float64)."""
    records = []
    for number, line in enumerate(Path(path).read_text().splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 38:
            raise ValueError(f"{path}:{number}: expected 38 fields, got {len(fields)}")
        values = np.array(fields[4:], dtype=np.float64)
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
    root = Path(root)
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
        "R": pair.R.tolist(),
        "t": pair.t.tolist(),
        "T_1to2": T.tolist(),
        "dist1": pair.dist1.tolist(),
        "dist2": pair.dist2.tolist(),
        "depth1": f"gt/{name}_depth1.npy",
        "depth1_meaning": "float32 (H, W): Z in camera 1 at pixel centres, inf at infinity",
        "params": pair.params,
    }
    text = json.dumps(record, indent=1, sort_keys=True, default=_json_default)
    (root / "gt" / f"{name}.json").write_text(text + "\n")
    return pairs_line(image1, image2, pair.K1, pair.K2, pair.R, pair.t)


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def _job(args: tuple) -> str:
    root, name, kwargs = args
    return write_pair(make_pair(**kwargs), root, name)


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    cv2.setNumThreads(1)
    texture_pool()


def make_dataset(
    out_dir: str | os.PathLike,
    pairs: int = 20,
    motion: str = "general",
    seed: int = 0,
    size: tuple[int, int] = (640, 480),
    scene: str | None = None,
    alpha: float | None = None,
    supersample: int = 2,
    noise_std: float = 0.0,
    blur_sigma: float = 0.0,
    same_intrinsics: bool = True,
    workers: int | None = None,
) -> Path:
    """Render ``pairs`` pairs of one motion preset into a new directory ``out_dir``.

    The directory is built in a temporary sibling and renamed at the end, so ``out_dir``
    either holds a complete dataset or is not created. Pair ``i`` is :func:`make_pair` with
    ``index = i``; the bytes written depend only on the arguments, not on ``workers``.

    Parameters
    ----------
    out_dir : path
        Must not exist, or be an empty directory.
    pairs : int
        Number of pairs (>= 1).
    workers : int, optional
        Worker processes (default: number of CPUs, at most ``pairs``).
    motion, seed, size, scene, alpha, supersample, noise_std, blur_sigma, same_intrinsics
        See :func:`make_pair`.

    Returns
    -------
    pathlib.Path
        ``out_dir``; its pairs file is ``out_dir / PAIRS_FILE``.
    """
    out = Path(out_dir)
    if isinstance(pairs, bool) or not isinstance(pairs, (int, np.integer)) or pairs < 1:
        raise ValueError(f"pairs must be a positive integer, got {pairs!r}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"{out} exists and is not an empty directory")
    kwargs = {
        "motion": motion, "seed": seed, "size": size, "scene": scene, "alpha": alpha,
        "supersample": supersample, "noise_std": noise_std, "blur_sigma": blur_sigma,
        "same_intrinsics": same_intrinsics,
    }  # fmt: skip
    _check_args(motion, scene, seed, 0, size, alpha, supersample, noise_std, blur_sigma)
    workers = min(os.cpu_count() or 1, pairs) if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        jobs = [(tmp, f"pair_{i:03d}", {**kwargs, "index": i}) for i in range(pairs)]
        if workers == 1:
            lines = [_job(job) for job in jobs]
        else:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(workers, context, initializer=_init_worker) as pool:
                lines = list(pool.map(_job, jobs))
        (tmp / PAIRS_FILE).write_text("\n".join(lines) + "\n")
        tmp.chmod(0o755)
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
