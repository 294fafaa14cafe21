"""``ppo-cv pair``, ``ppo-cv demo`` and ``ppo-cv pairs``: relative pose of real image pairs."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, NoReturn

import typer

from .common import (
    MAX_FEATURES_MAX,
    MAX_SIZE_MAX,
    SEED_MAX,
    Backend,
    Features,
    FocalRatio,
    MaxFeatures,
    MaxLog10Nfa,
    MaxSize,
    Overwrite,
    Photometric,
    Plane,
    PrincipalPoint,
    PriThreshold,
    Quiet,
    Ratio,
    RedetectBelow,
    Seed,
    StageReport,
    Threshold,
    check_image_file,
    check_range,
    fail,
    implausible_intrinsics,
    warn,
)

__all__ = ["register", "pipeline_options"]


def _fail(message: str, command: str = "pair") -> NoReturn:
    fail(command, message)


def _warn(message: str, command: str = "pair") -> None:
    warn(command, message)


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
    check_range("--ratio", ratio, 1e-6, 1.0)
    check_range("--redetect-below", redetect_below, 0, MAX_FEATURES_MAX)
    check_range("--threshold (pixels)", threshold, 1e-6, 100.0)
    pri_threshold = DEFAULT_PRI_THRESHOLD if pri_threshold is None else pri_threshold
    check_range("--pri-threshold", pri_threshold, 0.0, 1.0)
    max_log10_nfa = DEFAULT_MAX_LOG10_NFA if max_log10_nfa is None else max_log10_nfa
    if max_log10_nfa != float("inf"):
        check_range("--max-log10-nfa", max_log10_nfa, -1e6, 1e6)
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


def _plane_lines(result) -> list[str]:
    """Summary lines of the homography: its fit always, the plane when the model is one."""
    residual = getattr(result, "plane_residual_px", float("nan"))
    if residual != residual:
        return []
    lines = [
        f"  homography   median residual {residual:.2f} px, GRIC difference plane - general "
        f"{result.gric_plane_difference:+.3f} per match"
    ]
    if result.plane_normal is not None:
        n = result.plane_normal
        lines.append(
            f"  plane        normal ({n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f}) in camera 1, "
            f"distance {result.plane_distance:.3f} baselines"
            + (
                ", two-fold ambiguity broken by the off-plane matches or frontality"
                if result.plane_ambiguous
                else ""
            )
        )
    return lines


def _radial_lines(result) -> list[str]:
    """The radial term fitted with the pose, when one was kept."""
    k1 = result.radial_k1 if result.model == "general" else result.plane_k1
    if not k1 or k1 != k1:
        return []
    return [f"  radial k1    {k1:+.4f} (division model on normalized points, fitted with the pose)"]


def _denser_note(result) -> str:
    """Says when the features are those of the second, lower-threshold detection."""
    if result.threshold_scale == 1.0:
        return ""
    return f" (features detected again at {result.threshold_scale:g} x the threshold)"


def _rotation_sigma_lines(result) -> list[str]:
    """How well the matches determine the rotation of a pure rotation."""
    sigma = getattr(result, "rotation_sigma_deg", float("nan"))
    if not result.pure_rotation or not sigma == sigma:
        return []
    tracks = int(getattr(result, "rotation_tracks", 0))
    source = f"{tracks} intensity-aligned windows" if tracks else "the feature matches"
    return [f"  R sigma      {sigma:.3f} deg (rotation angle error, root mean square, {source})"]


def _lens_lines(result) -> list[str]:
    """The lens terms a pure rotation's fit absorbed (focal scale, focal ratio, principal point)
    and, when the matches saw a translation, the negligible parallax that overruled them; or why
    a rotation was refused."""
    from ppo_cv.motion_model import LENS_SIGNIFICANCE, MAX_COHERENT_SHARE, NEGLIGIBLE_PARALLAX
    from ppo_cv.rotation import PRINCIPAL_BOUND

    excess = float(getattr(result, "lens_excess", float("nan")))
    share = float(getattr(result, "coherent_share", 0.0))
    won = not result.pure_rotation and result.gric_difference < 0
    if won and excess > LENS_SIGNIFICANCE:
        return [
            f"  lens fit     a rotation would need a lens {excess:.1f} deviations beyond "
            "the plausible (focal +-5 %, k1 +-0.15): parallax, not a pure rotation"
        ]
    if won and share > MAX_COHERENT_SHARE:
        return [
            f"  parallax     {100 * share:.0f} % of the matches move together off the rotation "
            "(a nearer surface, or an object that moved): not called a pure rotation"
        ]
    parallax = float(getattr(result, "track_parallax", float("nan")))
    if won and parallax != parallax and getattr(result, "principal_bound", 0) > PRINCIPAL_BOUND:
        x, y = getattr(result, "principal_offset_px", (0.0, 0.0))
        return [
            f"  lens fit     a rotation would need the principal point moved ({x:+.1f}, {y:+.1f}) "
            "px, more than a lens plausibly has, and no intensity-aligned windows confirmed "
            "it: not called a pure rotation"
        ]
    if not result.pure_rotation and parallax == parallax:
        sigma = float(getattr(result, "track_parallax_sigma", float("nan")))
        clipped = ""
        if won and excess > 0:
            clipped = (
                f", more than the {NEGLIGIBLE_PARALLAX:g} a rotation whose lens needed the "
                "edge of the plausible box may show"
            )
        return [
            f"  parallax     the intensity-aligned windows fit a plane that moved "
            f"{parallax:.4f} +- {sigma:.4f} of its distance{clipped}: not called a pure rotation"
        ]
    if not result.pure_rotation:
        return []
    lines = []
    if parallax == parallax and result.gric_difference > 0:
        sigma = float(getattr(result, "track_parallax_sigma", float("nan")))
        lines.append(
            f"  parallax     the matches see a translation, but the intensity-aligned windows "
            f"fit a plane that moved {parallax:.4f} +- {sigma:.4f} of its distance: negligible"
        )
    text = f"focal scale {result.focal_scale:.4f} (given / true)"
    ratio = float(getattr(result, "focal_ratio", 1.0))
    if ratio != 1.0:
        text += f", image 2 / image 1 {ratio:.4f}"
    offset = getattr(result, "principal_offset_px", None)
    if offset is not None and any(offset):
        text += f", principal point moved ({offset[0]:+.1f}, {offset[1]:+.1f}) px"
    return [*lines, f"  lens fit     {text}"]


def _summary(result, name1: str, name2: str, note: str | None, reference=None) -> str:
    import numpy as np

    from ppo_cv.export import POSE_CONVENTION, camera_euler_degrees, rotation_angle_axis
    from ppo_cv.metrics import direction_error_deg, rotation_error_deg

    angle, axis = rotation_angle_axis(result.R)
    yaw, pitch, roll = camera_euler_degrees(result.R)
    verdict = (
        "pure rotation: translation undetermined, no 3D points"
        if result.pure_rotation
        else "plane (translation determined, pose from its homography)"
        if result.model == "plane"
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
        f"  model        {result.model}: median residual rotation "
        f"{result.rotation_residual_px:.2f} px, general {result.general_residual_px:.2f} px, "
        f"GRIC difference {result.gric_difference:+.3f} per match",
        *_plane_lines(result),
        *_radial_lines(result),
        f"  t sigma      {result.t_sigma_deg:.2f} deg (direction of t, one standard deviation)",
        *_rotation_sigma_lines(result),
        *_lens_lines(result),
        f"  log10 NFA    {result.log10_nfa:.1f} (consensus against chance; lower is stronger)",
        f"  matches      {result.num_matches} putative, {result.num_inliers} inliers, "
        f"{result.num_points} 3D points" + _denser_note(result),
        "  time         "
        + ", ".join(f"{k} {1000 * v:.1f} ms" for k, v in result.timings.items())
        + f" (total {1000 * sum(result.timings.values()):.0f} ms)",
    ]
    if reference is not None:
        R_ref, t_ref = (np.asarray(v, dtype=np.float64) for v in reference)
        R_err = rotation_error_deg(result.R, R_ref)
        t_err = direction_error_deg(t, t_ref)
        lines.append(
            f"  reference    rotation error {R_err:.2f} deg, translation direction error "
            f"{t_err:.2f} deg (against the pseudo ground truth in demo.json)"
        )
    if note:
        lines.append(f"  note         {note}")
    return "\n".join(lines)


def _run_pair(
    image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note=None, reference=None,
    overwrite=False, command="pair", quiet=False,
):  # fmt: skip
    from ppo_cv.atomic import check_target
    from ppo_cv.pipeline import estimate_pair, load_image

    try:
        if out is not None:
            check_target(out, "folder", overwrite)
        for image in (image1, image2):
            check_image_file(image)
        img1, img2 = load_image(image1), load_image(image2)
        K1, d1, K2v, d2, exif_note = _cameras(image1, image2, K, K2, dist, dist2, calib)
        if exif_note:
            _warn(exif_note, command)
        sources = ("--calib", "--calib") if calib is not None else ("--K", "--K2" if K2 else "--K")
        for matrix, img, name in ((K1, img1, sources[0]), (K2v, img2, sources[1])):
            doubt = implausible_intrinsics(matrix, (img.shape[1], img.shape[0]), name)
            if doubt and not exif_note:
                _warn(doubt, command)
                break
        with StageReport(command, quiet) as report:
            result = estimate_pair(
                img1, img2, K1, K2v, d1, d2, options=options, progress=report.stage
            )
        names = (Path(image1).name, Path(image2).name)
        if names[0] == names[1]:
            names = (f"1_{names[0]}", f"2_{names[1]}")
        extra = {"image1": str(image1), "image2": str(image2)}
        if out is not None:
            from ppo_cv.atomic import sigterm_as_interrupt
            from ppo_cv.export import write_outputs

            sigterm_as_interrupt()  # again: the pipeline imported pycolmap, which replaces it
            write_outputs(out, result, img1, img2, names, (d1, d2), extra, overwrite=overwrite)
    except (ValueError, TypeError, OSError) as exc:
        _fail(str(exc) or type(exc).__name__, command)
    if as_json:
        from ppo_cv.export import result_to_dict

        sys.stdout.write(json.dumps(result_to_dict(result, **extra)) + "\n")
    else:
        typer.echo(_summary(result, str(image1), str(image2), note, reference))
        if out is not None:
            typer.echo(f"  written      {out}/result.json, points.ply, matches.png, colmap/")


_Json = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
_Out = Annotated[
    Path | None,
    typer.Option(
        "--out",
        help="New folder for result.json, points.ply, matches.png and a COLMAP model; "
        "written completely or not at all.",
    ),
]


def register(app: typer.Typer) -> None:
    """Add ``pair``, ``demo`` and ``pairs`` to ``app``."""
    from ppo_cv.ppo import DEFAULT_PRI_THRESHOLD
    from ppo_cv.significance import DEFAULT_MAX_LOG10_NFA

    from . import batch

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
        overwrite: Overwrite = False,
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
        quiet: Quiet = False,
    ) -> None:
        """Relative pose (R, t), pure-rotation verdict and 3D points of two photos.

        Convention: X2 = R X1 + t maps camera-1 coordinates to camera 2,
        t of unit length; camera axes x right, y down, z forward. The
        summary and the JSON state the intrinsics and distortion used.
        A pure rotation leaves t undetermined: the JSON then has "t": null
        and the best unit guess under "t_guess".

        Without intrinsics the focal length is read from EXIF (with a
        warning). Without images it runs on the built-in demo pair. On a
        terminal, stderr shows the stage reached while it runs.
        """
        try:
            options = pipeline_options(
                features, max_features, max_size, ratio, backend, threshold, seed, pri_threshold,
                max_log10_nfa, plane, photometric, principal_point, focal_ratio, redetect_below,
            )  # fmt: skip
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
        _run_pair(
            image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note, reference,
            overwrite, quiet=quiet,
        )  # fmt: skip

    @app.command()
    def demo(as_json: _Json = False, out: _Out = None, overwrite: Overwrite = False) -> None:
        """Run the pipeline on the built-in demo pair (two TUM RGB-D frames)."""
        image1, image2, info = _demo_inputs()
        K = ",".join(str(v) for v in info["intrinsics"])
        options = pipeline_options()
        note = f"built-in demo pair: {info['attribution']}"
        reference = (info["reference_R"], info["reference_t"])
        _run_pair(
            image1, image2, K, None, None, None, None, as_json, out, options, note, reference,
            overwrite, "demo",
        )  # fmt: skip

    batch.register(app)
