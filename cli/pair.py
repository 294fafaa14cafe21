"""``ppo-cv pair`` and ``ppo-cv demo``: relative pose of a real image pair."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, NoReturn

import typer

from .common import (
    NO_RESULT,
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
    Quiet,
    Ratio,
    RedetectBelow,
    Seed,
    StageReport,
    Threshold,
    calibration_dist2,
    check_image_file,
    error_message,
    exif_camera,
    exif_note,
    fail,
    given_cameras,
    implausible_intrinsics,
    one_line,
    pipeline_options,
    print_result,
    upright_model_warning,
    warn,
)

__all__ = ["register", "pipeline_options"]


def _fail(message: str, command: str = "pair") -> NoReturn:
    fail(command, message)


def _warn(message: str, command: str = "pair") -> None:
    warn(command, message)


def _require_one_size(images, sizes, source: str) -> None:
    """ValueError when one camera matrix (``source``) would serve images of two sizes, as
    :func:`ppo_cv.pipeline.estimate_pair` refuses it."""
    if sizes[0] != sizes[1]:
        (w1, h1), (w2, h2) = sizes
        raise ValueError(
            f"{images[0]} is {w1}x{h1} and {images[1]} {w2}x{h2} pixels: one camera matrix "
            f"({source}) cannot fit both sizes; pass --K2 for the second image"
        )


def _calibrated_cameras(calib, images, sizes, K2, dist, dist2, exif_orientation=True):
    """(Cameras, notes) of a calibration file, each camera fitted to its image's size
    (:func:`ppo_cv.calib.fit_to_image`, told which images their EXIF orientation turned);
    ``--K2``, ``--dist``, ``--dist2`` override it, ``--dist`` both images' when the file
    describes one camera (as with ``--K``)."""
    from ppo_cv.calib import fit_to_image, load_calibration, parse_distortion, parse_intrinsics
    from ppo_cv.images import exif_layout

    cameras = load_calibration(calib)
    if len(cameras) == 1 and K2 is None and cameras[0].image_size is None:
        _require_one_size(images, sizes, f"--calib {calib}")
    name = f"--calib {calib}"
    turned = [exif_orientation and exif_layout(image).turned for image in images]
    first, note1 = fit_to_image(cameras[0], sizes[0], name, str(images[0]), turned[0])
    alike = len(cameras) == 1 and sizes[0] == sizes[1] and turned[0] == turned[1]
    if note1 and alike and K2 is None:  # one warning for the two images
        both = f"{images[0]} and {images[1]}"
        note1 = fit_to_image(cameras[0], sizes[0], name, both, turned[0])[1]
    notes = [note1] if note1 else []
    if K2 is not None:
        K2v, d2 = parse_intrinsics(K2, "--K2"), None
    else:
        second, note2 = fit_to_image(cameras[-1], sizes[1], name, str(images[1]), turned[1])
        K2v, d2 = second.K, second.dist
        notes += [note2] if note2 and not alike else []
    given1 = parse_distortion(dist, "--dist") if dist is not None else None
    given2 = parse_distortion(dist2, "--dist2") if dist2 is not None else None
    d2 = calibration_dist2(len(cameras), K2, given1, given2, d2)
    return Cameras(first.K, first.dist if given1 is None else given1, K2v, d2), notes


def _cameras(images, sizes, K, K2, dist, dist2, calib, exif_orientation=True):
    """(Cameras, EXIF note, warnings) from the options, a calibration file or EXIF;
    ``sizes`` are the images' (width, height)."""
    from ppo_cv.calib import parse_distortion

    if calib is not None:
        if K is not None:
            raise ValueError("give either --K or --calib, not both")
        cameras, notes = _calibrated_cameras(
            calib, images, sizes, K2, dist, dist2, exif_orientation
        )
        return cameras, None, notes
    cameras = given_cameras(K, K2, dist, dist2, None)
    if cameras is not None:
        if K2 is None:
            _require_one_size(images, sizes, "--K")
        return cameras, None, []
    (K1, found1, warnings1), (K2v, found2, warnings2) = (
        exif_camera(image, exif_orientation) for image in images
    )
    note = exif_note((K1[0, 0], K2v[0, 0]), (found1, found2), tuple(str(i) for i in images))
    d1 = parse_distortion(dist, "--dist") if dist is not None else None
    d2 = parse_distortion(dist2, "--dist2") if dist2 is not None else d1
    return Cameras(K1, d1, K2v, d2), note, [*warnings1, *warnings2]


def _demo_inputs():
    from importlib import resources

    data = resources.files("ppo_cv.data")
    info = json.loads((data / "demo.json").read_text(encoding="utf-8"))
    image1 = str(data / info["image1"])
    image2 = str(data / info["image2"])
    return image1, image2, info


def _plane_lines(result) -> list[str]:
    """Summary lines of the homography: its fit always, the plane when the model is one."""
    selection = result.evidence.selection
    residual = selection.plane_residual_px
    if residual != residual:
        return []
    lines = [
        f"  homography   median residual {residual:.2f} px, GRIC difference plane - general "
        f"{selection.gric_plane_difference:+.3f} per match"
        + (
            ", as for any rotation: its matches fit a homography"
            if result.pure_rotation and selection.gric_plane_difference < 0
            else ""
        )
    ]
    plane = result.plane
    if plane is not None:
        n = plane.normal
        lines.append(
            f"  plane        normal ({n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f}) in camera 1, "
            f"distance {plane.distance:.3f} baselines"
            + (
                ", two-fold ambiguity broken by the off-plane matches or frontality"
                if plane.ambiguous
                else ""
            )
        )
    return lines


def _radial_lines(result) -> list[str]:
    """The radial term fitted with the pose, when one was kept."""
    k1 = result.plane.k1 if result.plane is not None else result.lens.radial_k1
    if not k1 or k1 != k1:
        return []
    return [f"  radial k1    {k1:+.4f} (division model on normalized points, fitted with the pose)"]


def _denser_note(result) -> str:
    """Says when the features are those of the second, lower-threshold detection."""
    scale = result.evidence.significance.threshold_scale
    if scale == 1.0:
        return ""
    return f" (features detected again at {scale:g} x the threshold)"


_ROTATION_SOURCES = {
    "rotation": "the rotation-only fit",
    "essential": "the essential matrix's refined pose",
    "plane": "the plane's pose",
}


def _rotation_sigma_lines(result) -> list[str]:
    """How well the evidence determines the rotation, and which estimate it came from."""
    sigma, source = result.uncertainty.rotation_sigma_deg, result.rotation_source
    lines = []
    if result.pure_rotation and sigma == sigma:
        tracks = result.uncertainty.rotation_tracks
        evidence = f"{tracks} intensity-aligned windows" if tracks else "the feature matches"
        lines.append(
            f"  R sigma      {sigma:.3f} deg (rotation angle error, root mean square, {evidence})"
        )
    elif sigma == sigma and sigma < float("inf"):
        lines.append(f"  R sigma      {sigma:.3f} deg (rotation angle error, root mean square)")
    if not result.pure_rotation:
        why = ""
        if source == "rotation":
            bias = result.uncertainty.rotation_bias_deg
            why = f", bias from the translation's parallax {bias:.3f} deg"
        lines.append(
            f"  R source     {_ROTATION_SOURCES.get(source, source)}: the smallest expected "
            f"error{why}"
        )
    return lines


def _lens_lines(result) -> list[str]:
    """The lens terms a pure rotation's fit absorbed (focal scale, focal ratio, principal point)
    and, when the matches saw a translation, the negligible parallax that overruled them; or why
    a rotation was refused."""
    from ppo_cv.motion_model import LENS_SIGNIFICANCE, MAX_COHERENT_SHARE, NEGLIGIBLE_PARALLAX
    from ppo_cv.rotation import PRINCIPAL_BOUND

    lens, selection, tracks = result.lens, result.evidence.selection, result.evidence.tracks
    excess, share = lens.lens_excess, selection.coherent_share
    won = not result.pure_rotation and selection.gric_difference < 0
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
    parallax, sigma = tracks.parallax, tracks.parallax_sigma
    if won and parallax != parallax and lens.principal_bound > PRINCIPAL_BOUND:
        x, y = lens.principal_offset_px
        return [
            f"  lens fit     a rotation would need the principal point moved ({x:+.1f}, {y:+.1f}) "
            "px, more than a lens plausibly has, and no intensity-aligned windows confirmed "
            "it: not called a pure rotation"
        ]
    if not result.pure_rotation and parallax == parallax:
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
    if parallax == parallax and selection.gric_difference > 0:
        lines.append(
            f"  parallax     the matches see a translation, but the intensity-aligned windows "
            f"fit a plane that moved {parallax:.4f} +- {sigma:.4f} of its distance: negligible"
        )
    fitted = result.cameras.K1[0, 0] / lens.focal_scale
    text = (
        f"focal scale {lens.focal_scale:.4f} (given over fitted: the matches fit fx "
        f"{fitted:.2f} px)"
    )
    ratio = lens.focal_ratio
    if ratio != 1.0:
        text += f", image 2 / image 1 {ratio:.4f}"
    offset = lens.principal_offset_px
    if any(offset):
        text += f", principal point moved ({offset[0]:+.1f}, {offset[1]:+.1f}) px"
    return [*lines, f"  lens fit     {text}"]


def _deciding_test(result) -> str:
    """Which test settled the model: the test, then what it found."""
    from ppo_cv.motion_model import LENS_SIGNIFICANCE, MAX_COHERENT_SHARE
    from ppo_cv.rotation import PRINCIPAL_BOUND

    selection, lens = result.evidence.selection, result.lens
    gric = f"{selection.gric_difference:+.3f} per match"
    parallax = result.evidence.tracks.parallax
    tracks = (
        f"the tracks' parallax: the intensity-aligned windows fit a plane that moved {parallax:.4f}"
        " of its distance"
    )
    if result.pure_rotation:
        if parallax == parallax and selection.gric_difference > 0:
            return f"{tracks}, negligible (GRIC alone preferred a translation, {gric})"
        return f"GRIC and PRI: a rotation explains the matches ({gric}), PRI below its threshold"
    if result.model == "plane":
        return (
            "GRIC: the homography explains the matches better than the essential matrix "
            f"({selection.gric_plane_difference:+.3f} per match)"
        )
    if selection.gric_difference > 0:
        agrees = "; PRI agrees" if result.pri >= selection.pri_threshold else ""
        if parallax == parallax:
            agrees += f"; so do the tracks' parallax ({parallax:.4f} of the distance)"
        return (
            f"GRIC: the essential matrix explains the matches better than a rotation ({gric})"
            + agrees
        )
    if lens.lens_excess > LENS_SIGNIFICANCE:
        return (
            "the lens fit: a rotation would need an implausible lens "
            f"({lens.lens_excess:.1f} deviations)"
        )
    if selection.coherent_share > MAX_COHERENT_SHARE:
        return "coherent parallax: many matches move together off the rotation"
    if parallax == parallax:
        return f"{tracks}, more than a rotation shows"
    if lens.principal_bound > PRINCIPAL_BOUND:
        return "the lens fit: a rotation would need the principal point moved implausibly far"
    return "PRI: a rotation explains the matches, but their PRI is at or above its threshold"


def _verdict(result) -> str:
    """The model and the test that decided it (GRIC, PRI, the lens fit, the tracks' parallax)."""
    model = (
        "pure rotation (translation undetermined, no 3D points)"
        if result.pure_rotation
        else "plane (translation determined, pose from its homography)"
        if result.model == "plane"
        else "general motion (translation determined)"
    )
    return f"{model}; decided by {_deciding_test(result)}"


def _pri_text(result) -> str:
    """PRI against its threshold, saying when another test overruled what PRI alone says."""
    threshold = result.evidence.selection.pri_threshold
    below = result.pri < threshold
    side = "below" if below else "at or above"
    text = f"{result.pri:.4f} ({side} the threshold {threshold:g}"
    if below != bool(result.pure_rotation):
        return text + "; not the deciding test, see verdict)"
    return text + ")"


def _summary(result, name1: str, name2: str, note: str | None, reference=None) -> str:
    import numpy as np

    from ppo_cv.export import POSE_CONVENTION, camera_euler_degrees, rotation_angle_axis
    from ppo_cv.metrics import direction_error_deg, rotation_error_deg

    angle, axis = rotation_angle_axis(result.R)
    yaw, pitch, roll = camera_euler_degrees(result.R)
    t = np.asarray(result.t)
    cameras, selection = result.cameras, result.evidence.selection
    t_sigma, log10_nfa = result.uncertainty.t_sigma_deg, result.evidence.significance.log10_nfa
    vector = f"({t[0]:+.4f}, {t[1]:+.4f}, {t[2]:+.4f})"

    def camera(K, dist):
        text = f"fx {K[0, 0]:.2f}  fy {K[1, 1]:.2f}  cx {K[0, 2]:.2f}  cy {K[1, 2]:.2f}"
        coefficients = "none" if dist is None else ",".join(f"{v:g}" for v in np.ravel(dist))
        return f"{text}  distortion {coefficients}"

    lines = [
        f"{one_line(str(name1))} -> {one_line(str(name2))}",
        f"  verdict      {_verdict(result)}",
        f"  convention   {POSE_CONVENTION}; camera axes x right, y down, z forward",
        f"  rotation     {angle:.3f} deg about ({axis[0]:+.4f}, {axis[1]:+.4f}, {axis[2]:+.4f})",
        f"  euler        yaw {yaw:+.3f} (about y)  pitch {pitch:+.3f} (about x)  "
        f"roll {roll:+.3f} (about z) deg, R = Ry Rx Rz",
        "  translation  undetermined (pure rotation); best unit guess " + vector
        if result.pure_rotation
        else f"  translation  {vector}  [unit direction]",
        f"  camera 1     {camera(cameras.K1, cameras.dist1)}",
        f"  camera 2     {camera(cameras.K2, cameras.dist2)}",
        f"  PRI          {_pri_text(result)}",
        f"  model        {result.model}: median residual rotation "
        f"{selection.rotation_residual_px:.2f} px, general {selection.general_residual_px:.2f} "
        f"px, GRIC difference {selection.gric_difference:+.3f} per match",
        *_plane_lines(result),
        *_radial_lines(result),
        f"  t sigma      {t_sigma:.2f} deg (direction of t, one standard deviation"
        + ("; undetermined for a pure rotation)" if result.pure_rotation else ")"),
        *_rotation_sigma_lines(result),
        *_lens_lines(result),
        f"  log10 NFA    {log10_nfa:.1f} (consensus against chance; lower is stronger)",
        f"  matches      {result.num_matches} putative, {result.num_inliers} inliers, "
        f"{result.num_points} 3D points" + _denser_note(result),
        f"  threshold    {result.evidence.significance.ransac_threshold_px:.3g} px "
        "(inliers, full-size pixels)",
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


def _camera_doubts(cameras, images, names, turned) -> list[str]:
    """The warning (one at most) that a given camera matrix does not fit its image."""
    for matrix, img, name, exif_turned in zip(
        (cameras.K1, cameras.K2), images, names, turned, strict=True
    ):
        doubt = implausible_intrinsics(matrix, (img.shape[1], img.shape[0]), name, exif_turned)
        if doubt:
            return [doubt]
    return []


def _check_colmap_names(image1, image2) -> None:
    """Before the run: ValueError when ``--out``'s COLMAP model cannot hold an image name."""
    from ppo_cv.export import check_colmap_names

    try:
        check_colmap_names((Path(image1).name, Path(image2).name))
    except ValueError as exc:
        raise ValueError(f"--out: {exc}; run without --out") from None


def _check_colmap_cameras(cameras) -> None:
    """Before the run: ValueError when ``--out``'s COLMAP model cannot hold a camera."""
    from ppo_cv.export import check_colmap_camera

    try:
        check_colmap_camera(cameras.K1, cameras.dist1, "camera 1")
        check_colmap_camera(cameras.K2, cameras.dist2, "camera 2")
    except ValueError as exc:
        raise ValueError(f"--out: {exc}; run without --out") from None


_FILE_SUFFIXES = (".json", ".ply", ".png", ".jpg", ".txt", ".yml", ".yaml")
"""Suffixes of the files ``--out`` writes, and of others: an ``--out`` named so is a file
name where a folder is wanted."""


def _require_folder_name(out) -> None:
    """ValueError for an ``--out`` named as a file (``result.json``) that is no folder yet:
    it would become a folder of that name holding ``result.json``."""
    from pathlib import Path

    if Path(out).suffix.lower() in _FILE_SUFFIXES and not Path(out).is_dir():
        raise ValueError(
            f"--out takes a folder, and {out} names a file: the folder receives result.json, "
            "points.ply, matches.png and a COLMAP model; --json > result.json writes the JSON "
            "object alone"
        )


_LIST_SUFFIXES = {".txt", ".lst", ".list", ""}
"""Suffixes of a pairs file, as ``ppo-cv pairs`` reads one."""


def _require_images_not_a_batch(image1, image2) -> None:
    """ValueError naming ``ppo-cv pairs`` when the two arguments are a pairs file and a folder
    (in either order): the arguments of ``pairs`` given to ``pair``."""
    from pathlib import Path

    first, second = Path(image1), Path(image2)
    try:
        if first.is_dir() == second.is_dir():
            return
        listing, folder = (first, second) if second.is_dir() else (second, first)
        batch = listing.is_file() and listing.suffix.lower() in _LIST_SUFFIXES
    except OSError:  # a name too long or unreadable: the image checks name it
        return
    if batch:
        raise ValueError(
            f"{one_line(str(folder))} is a folder and {one_line(str(listing))} no image: "
            "'pair' takes two images; a pairs file and an image folder are run by "
            f"ppo-cv pairs {one_line(str(listing))} {one_line(str(folder))}"
        )


def _run_pair(
    image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note=None, reference=None,
    overwrite=False, command="pair", exif_orientation=True, quiet=False,
):  # fmt: skip
    from ppo_cv.atomic import check_target
    from ppo_cv.features import require_detectable
    from ppo_cv.images import exif_layout
    from ppo_cv.pipeline import estimate_pair, load_image

    try:
        if out is not None and str(out) == "-":
            raise ValueError(
                "--out takes a folder, not '-' (standard output): without --out the summary, "
                "or with --json the JSON object, goes to standard output"
            )
        if out is not None:
            inputs = [image1, image2, *([calib] if calib is not None else [])]
            check_target(out, "folder", overwrite, inputs, "--out ")
            _require_folder_name(out)
            _check_colmap_names(image1, image2)
        _require_images_not_a_batch(image1, image2)
        for image in (image1, image2):
            check_image_file(image)
        img1, img2 = (load_image(i, exif_orientation=exif_orientation) for i in (image1, image2))
        for img, image in ((img1, image1), (img2, image2)):
            require_detectable(img.shape, str(image), options.max_image_size)
        sizes = [(img.shape[1], img.shape[0]) for img in (img1, img2)]
        cameras, exif_text, notes = _cameras(
            (image1, image2), sizes, K, K2, dist, dist2, calib, exif_orientation
        )
        warnings = [exif_text, *notes] if exif_text else notes
        if not exif_text:
            second = "--K2" if K2 is not None else "--K"
            sources = ("--calib", "--calib") if calib is not None else ("--K", second)
            turned = [exif_orientation and exif_layout(i).turned for i in (image1, image2)]
            warnings += _camera_doubts(cameras, (img1, img2), sources, turned)
        d1, d2 = cameras.dist1, cameras.dist2
        if out is not None:
            _check_colmap_cameras(cameras)
            warnings += upright_model_warning(
                (image1, image2), exif_orientation, f"the COLMAP model {out}/colmap"
            )
        with StageReport(command, quiet) as report:
            try:
                result = estimate_pair(
                    img1, img2, cameras.K1, cameras.K2, d1, d2, options=options,
                    progress=report.stage,
                )  # fmt: skip
            except ValueError as exc:
                if "load" not in report.done:  # the pipeline refused its input
                    raise
                doubts = "".join(f"; warning: {one_line(w)}" for w in warnings)
                fail(command, f"no pose: {error_message(exc)}{doubts}", NO_RESULT)
            if exif_text:
                from ppo_cv.guessed_camera import decide_with_fitted_focal

                result, focal_note = decide_with_fitted_focal(result, (img1, img2), options)
                warnings += [focal_note] if focal_note else []
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
        _fail(error_message(exc), command)
    for message in warnings:  # after the run: a failure is its one line
        _warn(message, command)
    if as_json:
        from ppo_cv.export import result_to_dict

        print_result(command, json.dumps(result_to_dict(result, **extra)))
    else:
        summary = _summary(result, str(image1), str(image2), note, reference)
        if out is not None:
            summary += f"\n  written      {out}/result.json, points.ply, matches.png, colmap/"
        print_result(command, summary)


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
    """Add ``pair`` and ``demo`` to ``app``."""
    from ppo_cv.ppo import DEFAULT_PRI_THRESHOLD
    from ppo_cv.significance import DEFAULT_MAX_LOG10_NFA

    @app.command()
    def pair(
        image1: Annotated[
            Path | None,
            typer.Argument(metavar="IMAGE1", help="First image (none: the built-in demo pair)."),
        ] = None,
        image2: Annotated[
            Path | None, typer.Argument(metavar="IMAGE2", help="Second image.")
        ] = None,
        K: KOption = None,
        K2: K2Option = None,
        dist: Annotated[
            str | None,
            typer.Option("--dist", help="Distortion k1,k2,p1,p2[,k3] (or OpenCV's 8, 12 or 14)."),
        ] = None,
        dist2: Annotated[
            str | None, typer.Option("--dist2", help="Distortion of camera 2 (default: --dist).")
        ] = None,
        calib: CalibOption = None,
        exif_orientation: ExifOrientation = True,
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
        warning, and another when the EXIF pixel size is not the image's or
        the field of view it implies is outside 15..120 deg); a pair that
        is not a pure rotation with that guess is decided again with the
        focal length that makes its homography a rotation, and reported
        as a rotation (with a warning) when that decision is one. Photos are
        turned upright as their EXIF orientation says unless
        --no-exif-orientation. Without images it runs on the built-in demo
        pair. On a terminal, stderr shows the stage reached while it runs.

        Exit code 0 with a pose, 1 when the images gave none (too few
        features, matches or inliers: one line on stderr, --out not
        written), 2 for bad input.
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
            if K is not None or K2 is not None or calib is not None:
                _fail("intrinsics given without images")
            image1, image2, info = _demo_inputs()
            K = ",".join(str(v) for v in info["intrinsics"])
            note = f"built-in demo pair: {info['attribution']}"
            reference = (info["reference_R"], info["reference_t"])
        elif image2 is None:
            _fail("give two images (or none for the demo pair)")
        _run_pair(
            image1, image2, K, K2, dist, dist2, calib, as_json, out, options, note, reference,
            overwrite, exif_orientation=exif_orientation, quiet=quiet,
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
