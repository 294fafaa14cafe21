"""``ppo-cv pair``, ``ppo-cv demo`` and ``ppo-cv pairs``: relative pose of real image pairs."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]

_PANEL = "Pipeline"


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(2)


def _warn(message: str) -> None:
    typer.echo(f"warning: {message}", err=True)


def _options(features, max_features, max_size, ratio, backend, threshold, seed, max_nfa=0.0):
    from ppo_cv.pipeline import PairOptions

    return PairOptions(
        features=features.lower(),
        max_features=max_features,
        max_image_size=max_size if max_size and max_size > 0 else None,
        ratio=ratio,
        backend=backend.lower(),
        ransac_threshold=threshold,
        seed=seed,
        max_log10_nfa=max_nfa,
    )


def _exif_cameras(image1, image2):
    """K1, K2 and a warning, from the EXIF focal lengths of the two images."""
    from ppo_cv.calib import camera_from_exif

    (camera1, exif1), (camera2, exif2) = camera_from_exif(image1), camera_from_exif(image2)
    focal = f"f={camera1.K[0, 0]:.1f} and {camera2.K[0, 0]:.1f} px"
    if exif1 and exif2:
        note = (
            f"no intrinsics given: using the EXIF focal lengths ({focal}, centred principal "
            "point); pass --K or --calib for accurate results"
        )
    else:
        note = (
            f"no intrinsics given and no EXIF focal length in "
            f"{'both images' if not (exif1 or exif2) else (image2 if exif1 else image1)}: "
            f"guessing {focal} (1.2 x image size); the pose will be rough, pass --K or --calib"
        )
    return camera1.K, camera2.K, note


def _cameras(image1, image2, K, K2, dist, dist2, calib):
    """(K1, dist1, K2, dist2, note) from the options, a calibration file or EXIF."""
    from ppo_cv.calib import load_calibration, parse_distortion, parse_intrinsics

    d1 = parse_distortion(dist, "--dist") if dist else None
    d2 = parse_distortion(dist2, "--dist2") if dist2 else None
    if calib is not None:
        if K is not None:
            raise ValueError("give either --K or --calib, not both")
        cameras = load_calibration(calib)
        first, second = cameras[0], cameras[1] if len(cameras) > 1 else cameras[0]
        K1, d1 = first.K, d1 if d1 is not None else first.dist
        K2v = parse_intrinsics(K2, "--K2") if K2 else second.K
        d2 = d2 if d2 is not None else (second.dist if not K2 else None)
        return K1, d1, K2v, d2, None
    if K is None:
        if K2:
            raise ValueError("--K2 needs --K (or --calib) for the first camera")
        K1, K2v, note = _exif_cameras(image1, image2)
        return K1, d1, K2v, d2 if d2 is not None else d1, note
    K1 = parse_intrinsics(K, "--K")
    if K2:
        return K1, d1, parse_intrinsics(K2, "--K2"), d2, None
    return K1, d1, K1, d2 if d2 is not None else d1, None


def _demo_inputs():
    from importlib import resources

    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    image1 = str(data / info["image1"])
    image2 = str(data / info["image2"])
    return image1, image2, info


def _summary(result, name1: str, name2: str, note: str | None, reference=None) -> str:
    import numpy as np

    from ppo_cv.export import POSE_CONVENTION, camera_euler_degrees, rotation_angle_axis

    angle, axis = rotation_angle_axis(result.R)
    yaw, pitch, roll = camera_euler_degrees(result.R)
    verdict = (
        "pure rotation: translation undetermined, no 3D points"
        if result.pure_rotation
        else "general motion (translation determined)"
    )
    t = np.asarray(result.t)
    vector = f"({t[0]:+.4f}, {t[1]:+.4f}, {t[2]:+.4f})"

    def camera(K, dist):
        text = f"fx {K[0, 0]:.2f}  fy {K[1, 1]:.2f}  cx {K[0, 2]:.2f}  cy {K[1, 2]:.2f}"
        coefficients = "none" if dist is None else ",".join(f"{v:g}" for v in np.ravel(dist))
        return f"{text}  distortion {coefficients}"

    lines = [
        f"{name1} -> {name2}",
        f"  convention   {POSE_CONVENTION}; camera axes x right, y down, z forward",
        f"  rotation     {angle:.3f} deg about ({axis[0]:+.4f}, {axis[1]:+.4f}, {axis[2]:+.4f})",
        f"  euler        yaw {yaw:+.3f} (about y)  pitch {pitch:+.3f} (about x)  "
        f"roll {roll:+.3f} (about z) deg, R = Ry Rx Rz",
        "  translation  undetermined (pure rotation); best unit guess " + vector
        if result.pure_rotation
        else f"  translation  {vector}  [unit direction]",
        f"  camera 1     {camera(result.K1, result.dist1)}",
        f"  camera 2     {camera(result.K2, result.dist2)}",
        f"  PRI          {result.pri:.4f} (threshold {result.pri_threshold:g}): {verdict}",
        f"  log10 NFA    {result.log10_nfa:.1f} (consensus against chance; lower is stronger)",
        f"  matches      {result.num_matches} putative, {result.num_inliers} inliers, "
        f"{result.num_points} 3D points",
        "  time         "
        + ", ".join(f"{k} {1000 * v:.1f} ms" for k, v in result.timings.items())
        + f" (total {1000 * sum(result.timings.values()):.0f} ms)",
    ]
    if reference is not None:
        R_ref, t_ref = (np.asarray(v, dtype=np.float64) for v in reference)
        R_err = np.degrees(np.arccos(np.clip((np.trace(result.R.T @ R_ref) - 1) / 2, -1, 1)))
        t_err = np.degrees(np.arccos(np.clip(float(t @ t_ref) / np.linalg.norm(t), -1, 1)))
        lines.append(
            f"  reference    rotation error {R_err:.2f} deg, translation direction error "
            f"{t_err:.2f} deg (against the pseudo ground truth in demo.json)"
        )
    if note:
        lines.append(f"  note         {note}")
    return "\n".join(lines)


def _run_pair(
    image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note=None, reference=None
):
    from ppo_cv.pipeline import estimate_pair, load_image

    try:
        img1, img2 = load_image(image1), load_image(image2)
        K1, d1, K2v, d2, exif_note = _cameras(image1, image2, K, K2, dist, dist2, calib)
        if exif_note:
            _warn(exif_note)
        result = estimate_pair(img1, img2, K1, K2v, d1, d2, options=options)
        names = (Path(image1).name, Path(image2).name)
        if names[0] == names[1]:
            names = (f"1_{names[0]}", f"2_{names[1]}")
        extra = {"image1": str(image1), "image2": str(image2)}
        if out is not None:
            from ppo_cv.export import write_outputs

            write_outputs(out, result, img1, img2, names, (d1, d2), extra)
    except (ValueError, OSError) as exc:
        _fail(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    if as_json:
        from ppo_cv.export import result_to_dict

        sys.stdout.write(json.dumps(result_to_dict(result, **extra)) + "\n")
    else:
        typer.echo(_summary(result, str(image1), str(image2), note, reference))
        if out is not None:
            typer.echo(f"  written      {out}/result.json, points.ply, matches.png, colmap/")


def _read_pairs(pairs_file: Path, K: str | None) -> list[dict]:
    """Rows of a pairs file: names, intrinsics and, when present, the ground-truth motion."""
    import numpy as np

    from ppo_cv.calib import parse_intrinsics
    from ppo_cv.checks import as_camera_matrix

    if not pairs_file.is_file():
        raise ValueError(f"pairs file not found: {pairs_file}")
    default = parse_intrinsics(K, "--K") if K else None
    rows = []
    for number, line in enumerate(pairs_file.read_text(encoding="utf-8").splitlines(), 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        if len(parts) not in (2, 4, 22, 38):
            raise ValueError(
                f"{pairs_file}:{number}: expected 'name1 name2 [0 0 K1(9) K2(9) [T(16)]]', "
                f"got {len(parts)} fields"
            )
        row = {"image1": parts[0], "image2": parts[1], "K1": default, "K2": default, "T": None}
        try:
            if len(parts) >= 22:
                values = np.array(parts[4:], dtype=np.float64)
                row["K1"] = as_camera_matrix(values[0:9].reshape(3, 3), "K1")
                row["K2"] = as_camera_matrix(values[9:18].reshape(3, 3), "K2")
                if len(parts) == 38:
                    row["T"] = values[18:34].reshape(4, 4)
        except ValueError as exc:
            raise ValueError(f"{pairs_file}:{number}: {exc}") from None
        if row["K1"] is None:
            raise ValueError(f"{pairs_file}:{number}: no intrinsics in the file; pass --K")
        rows.append(row)
    if not rows:
        raise ValueError(f"no pairs in {pairs_file}")
    return rows


def _init_worker() -> None:
    import cv2

    cv2.setNumThreads(1)


def _pair_job(job: tuple) -> dict:
    """One pair in a worker: a JSON-ready dict, with ``error`` instead of a pose on failure."""
    from ppo_cv.export import result_to_dict
    from ppo_cv.pipeline import estimate_pair

    row, image_dir, options = job
    names = {"image1": row["image1"], "image2": row["image2"]}
    try:
        result = estimate_pair(
            Path(image_dir) / row["image1"],
            Path(image_dir) / row["image2"],
            row["K1"],
            row["K2"],
            options=options,
        )
    except (ValueError, OSError) as exc:
        return {**names, "error": str(exc).splitlines()[0]}
    data = result_to_dict(result, **names)
    if row["T"] is not None:
        data.update(_pose_errors(result.R, result.t, row["T"]))
    return data


def _pose_errors(R, t, T) -> dict:
    """Rotation error and (sign-free) translation-direction error in degrees."""
    import numpy as np

    R_gt, t_gt = T[:3, :3], T[:3, 3]
    cos_r = np.clip((np.trace(R.T @ R_gt) - 1.0) / 2.0, -1.0, 1.0)
    norm = np.linalg.norm(t) * np.linalg.norm(t_gt)
    cos_t = np.clip(abs(float(t @ t_gt)) / max(norm, 1e-12), -1.0, 1.0)
    return {
        "R_err_deg": float(np.degrees(np.arccos(cos_r))),
        "t_err_deg": float(np.degrees(np.arccos(cos_t))),
    }


def pose_auc(errors, thresholds=(5.0, 10.0, 20.0)) -> list[float]:
    """Area under the recall curve of pose errors (degrees) up to each threshold, in [0, 1]."""
    import numpy as np

    errors = np.sort(np.asarray(errors, dtype=np.float64))
    recall = np.arange(1, errors.size + 1) / errors.size
    errors, recall = np.r_[0.0, errors], np.r_[0.0, recall]
    areas = []
    for threshold in thresholds:
        last = np.searchsorted(errors, threshold)
        e = np.r_[errors[:last], threshold]
        r = np.r_[recall[:last], recall[last - 1]]
        areas.append(float(np.trapezoid(r, x=e) / threshold))
    return areas


def run_pairs(pairs_file, image_dir, K, output, workers, options) -> int:
    """Run every pair of a pairs file; returns the exit code."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    rows = _read_pairs(Path(pairs_file), K)
    if not Path(image_dir).is_dir():
        raise ValueError(f"image folder not found: {image_dir}")
    workers = workers if workers > 0 else (os.cpu_count() or 1)
    jobs = [(row, str(image_dir), options) for row in rows]
    results: list[dict] = []
    sink = open(output, "w", encoding="utf-8") if output is not None else sys.stdout
    console = Console(stderr=True)
    try:
        with (
            Progress(
                TextColumn("pairs"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=console,
                transient=True,
            ) as progress,
            ProcessPoolExecutor(
                workers,
                mp_context=multiprocessing.get_context("spawn"),  # no fork of a threaded process
                initializer=_init_worker,
            ) as pool,
        ):
            task = progress.add_task("pairs", total=len(jobs))
            for data in pool.map(_pair_job, jobs):
                sink.write(json.dumps(data) + "\n")
                sink.flush()
                results.append(data)
                progress.advance(task)
    finally:
        if output is not None:
            sink.close()
    failed = sum("error" in r for r in results)
    if rows[0]["T"] is not None:
        errors = [
            max(r["R_err_deg"], r["t_err_deg"]) if "error" not in r else 180.0 for r in results
        ]
        auc = pose_auc(errors)
        table = (
            "| pairs | failed | AUC@5 | AUC@10 | AUC@20 |\n|---|---|---|---|---|\n"
            f"| {len(results)} | {failed} | {100 * auc[0]:.1f} | {100 * auc[1]:.1f} "
            f"| {100 * auc[2]:.1f} |"
        )
        typer.echo(table, err=output is None)
    elif failed:
        _warn(f"{failed} of {len(results)} pairs failed")
    return 0


_Features = Annotated[str, typer.Option(help="sift, orb or akaze.", rich_help_panel=_PANEL)]
_MaxFeatures = Annotated[int, typer.Option(help="Keypoints per image.", rich_help_panel=_PANEL)]
_Ratio = Annotated[float, typer.Option(help="Lowe's ratio test.", rich_help_panel=_PANEL)]
_Backend = Annotated[
    str,
    typer.Option(
        help="Robust E: pycolmap (LO-RANSAC) or opencv (USAC MAGSAC++).", rich_help_panel=_PANEL
    ),
]
_Threshold = Annotated[
    float, typer.Option(help="RANSAC threshold, pixels.", rich_help_panel=_PANEL)
]
_Seed = Annotated[int, typer.Option(help="RANSAC seed.", rich_help_panel=_PANEL)]
_Json = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
_Out = Annotated[
    Path | None,
    typer.Option("--out", help="Write result.json, points.ply, matches.png and a COLMAP model."),
]


def register(app: typer.Typer) -> None:
    @app.command()
    def pair(
        image1: Annotated[
            Path | None, typer.Argument(help="First image (none: the built-in demo pair).")
        ] = None,
        image2: Annotated[Path | None, typer.Argument(help="Second image.")] = None,
        K: Annotated[
            str | None, typer.Option("--K", help="Intrinsics fx,fy,cx,cy or the 9 numbers of K.")
        ] = None,
        K2: Annotated[
            str | None, typer.Option("--K2", help="Intrinsics of camera 2 (default: --K).")
        ] = None,
        dist: Annotated[
            str | None, typer.Option("--dist", help="Distortion k1,k2,p1,p2[,k3].")
        ] = None,
        dist2: Annotated[
            str | None, typer.Option("--dist2", help="Distortion of camera 2 (default: --dist).")
        ] = None,
        calib: Annotated[
            Path | None,
            typer.Option(
                "--calib", help="OpenCV YAML/XML, COLMAP cameras.txt or JSON calibration file."
            ),
        ] = None,
        as_json: _Json = False,
        out: _Out = None,
        features: _Features = "sift",
        max_features: _MaxFeatures = 8000,
        max_size: Annotated[
            int,
            typer.Option(
                help="Detect on a copy whose longer side is at most this (0: full size).",
                rich_help_panel=_PANEL,
            ),
        ] = 2000,
        ratio: _Ratio = 0.9,
        backend: _Backend = "pycolmap",
        threshold: _Threshold = 1.0,
        seed: _Seed = 0,
        max_log10_nfa: Annotated[
            float,
            typer.Option(
                help="Significance bar: report a pose only when log10 of the number of false "
                "alarms of its consensus is at most this (lower is stricter, inf disables).",
                rich_help_panel=_PANEL,
            ),
        ] = 0.0,
    ) -> None:
        """Relative pose (R, t), pure-rotation verdict and 3D points of two photos.

        Convention: X2 = R X1 + t maps camera-1 coordinates to camera 2,
        t of unit length; camera axes x right, y down, z forward. The
        summary and the JSON state the intrinsics and distortion used.
        A pure rotation leaves t undetermined: the JSON then has "t": null
        and the best unit guess under "t_guess".

        Without intrinsics the focal length is read from EXIF (with a
        warning). Without images it runs on the built-in demo pair.
        """
        try:
            options = _options(
                features, max_features, max_size, ratio, backend, threshold, seed, max_log10_nfa
            )
        except ValueError as exc:
            _fail(str(exc))
        note = reference = None
        if image1 is None and image2 is None:
            if K or K2 or calib:
                _fail("intrinsics given without images")
            image1, image2, info = _demo_inputs()
            K = ",".join(str(v) for v in info["intrinsics"])
            note = f"built-in demo pair: {info['attribution']}"
            reference = (info["reference_R"], info["reference_t"])
        elif image2 is None:
            _fail("give two images (or none for the demo pair)")
        _run_pair(image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note, reference)

    @app.command()
    def demo(as_json: _Json = False, out: _Out = None) -> None:
        """Run the pipeline on the built-in demo pair (two TUM RGB-D frames)."""
        image1, image2, info = _demo_inputs()
        K = ",".join(str(v) for v in info["intrinsics"])
        options = _options("sift", 8000, 2000, 0.9, "pycolmap", 1.0, 0)
        note = f"built-in demo pair: {info['attribution']}"
        reference = (info["reference_R"], info["reference_t"])
        _run_pair(image1, image2, K, None, None, None, None, as_json, out, options, note, reference)

    @app.command()
    def pairs(
        pairs_file: Annotated[
            Path, typer.Argument(help="Lines 'name1 name2 [0 0 K1(9) K2(9) [T_1to2(16)]]'.")
        ],
        image_dir: Annotated[Path, typer.Argument(help="Folder holding the images.")],
        K: Annotated[
            str | None, typer.Option("--K", help="Intrinsics for lines that carry none.")
        ] = None,
        output: Annotated[
            Path | None, typer.Option("--output", "-o", help="JSON lines file (default: stdout).")
        ] = None,
        workers: Annotated[int, typer.Option(help="Worker processes (0: one per CPU).")] = 0,
        features: _Features = "sift",
        max_features: _MaxFeatures = 8000,
        ratio: _Ratio = 0.9,
        backend: _Backend = "pycolmap",
        threshold: _Threshold = 1.0,
        seed: _Seed = 0,
    ) -> None:
        """Run many pairs in parallel, one JSON line each; AUC@5/10/20 given ground truth."""
        try:
            options = _options(features, max_features, 2000, ratio, backend, threshold, seed)
            code = run_pairs(pairs_file, image_dir, K, output, workers, options)
        except ValueError as exc:
            _fail(str(exc))
        raise typer.Exit(code)
