"""What :func:`ppo_cv.pipeline.estimate_pair` returns: the answer and a few records behind it.

``PairResult`` holds the answer at the top (``R``, ``t``, ``pure_rotation``, ``model``, the
matches, inliers and points) and the rest in nested records: ``cameras`` (the intrinsics and
image sizes used), ``uncertainty`` (of ``t`` and ``R``), ``lens`` (the lens terms fitted),
``evidence`` (the statistics of the model decision: ``selection``, ``tracks``,
``significance``), ``plane`` (the plane of a planar pair, None for the other models) and
``timings``. The flat names of 0.1.0 (``result.gric_difference``, ...) still read for one
release, with a :class:`DeprecationWarning` naming the new path (:data:`RENAMED_FIELDS`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields, is_dataclass
from operator import attrgetter
from typing import Any

import numpy as np

__all__ = [
    "PairResult",
    "PairCameras",
    "PoseUncertainty",
    "LensTerms",
    "ModelComparison",
    "TrackParallax",
    "ConsensusSignificance",
    "DecisionEvidence",
    "PlaneGeometry",
    "RENAMED_FIELDS",
    "compact_repr",
]

ARRAY_SHOWN = 16
"""Arrays of at most this many entries are shown in full by :func:`compact_repr`."""


def compact_repr(value: Any) -> str:
    """The ``repr`` of a result on one line, its large arrays by their type and shape.

    Parameters
    ----------
    value : object
        A result record (a dataclass instance), an array, a dict, a tuple or a scalar.

    Returns
    -------
    str
        ``Name(field=value, ...)`` for a record, its nested records alike; an array of at most
        :data:`ARRAY_SHOWN` entries (``R``, ``t``, ``K``) as ``array([[...], ...])`` rounded to
        6 decimals, a larger one (keypoints, matches, points) as
        ``<ndarray float64, shape (1210, 2)>``.
    """
    if is_dataclass(value) and not isinstance(value, type):
        shown = (f for f in fields(value) if f.repr)
        body = ", ".join(f"{f.name}={compact_repr(getattr(value, f.name))}" for f in shown)
        return f"{type(value).__name__}({body})"
    if isinstance(value, np.ndarray):
        if value.size > ARRAY_SHOWN:
            return f"<ndarray {value.dtype}, shape {value.shape}>"
        listed = (np.round(value, 6) if value.dtype.kind == "f" else value).tolist()
        return f"array({listed!r})"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {compact_repr(v)}" for k, v in value.items()) + "}"
    if isinstance(value, tuple):
        return "(" + ", ".join(map(compact_repr, value)) + ("," if len(value) == 1 else "") + ")"
    return repr(value.item() if isinstance(value, np.generic) else value)


@dataclass(frozen=True)
class PairCameras:
    """The cameras a pose was estimated with.

    Attributes
    ----------
    K1, K2 : ndarray, shape (3, 3)
        Intrinsics used.
    dist1, dist2 : ndarray or None
        OpenCV distortion coefficients removed from the points; None for none.
    image_size1, image_size2 : tuple of int
        ``(width, height)`` of each image.
    """

    K1: np.ndarray
    K2: np.ndarray
    dist1: np.ndarray | None
    dist2: np.ndarray | None
    image_size1: tuple[int, int]
    image_size2: tuple[int, int]


@dataclass(frozen=True)
class PoseUncertainty:
    """How well the matches determine the pose.

    Attributes
    ----------
    t_sigma_deg : float
        One standard deviation of the direction of ``t`` (degrees, at most 90) from the
        Jacobian of the Sampson cost of ``E = [t]x R`` at the reported pose over its inliers,
        less what the image noise alone puts there, the given focal length off by
        :data:`ppo_cv.rotation.FOCAL_PRIOR` and the radial term under
        :data:`ppo_cv.rotation.K1_PRIOR` (:func:`ppo_cv.refine.translation_sigma_deg`); grows
        as the baseline shrinks. For a pure rotation it is the cap: the decision is that the
        matches do not determine ``t``, and the essential matrix's apparent confidence there
        comes from lens errors its translation absorbs.
    rotation_sigma_deg : float
        For a pure rotation: root-mean-square angle error (degrees) of ``R``, from the
        covariance of the rotation-only fit with its focal scale and radial term under their
        priors (:attr:`ppo_cv.rotation.LensRotationFit.rotation_sigma_deg`): how well these
        matches determine the rotation when the focal length is known only to a few percent.
        When ``R`` was refitted on intensity-aligned windows (``rotation_tracks > 0``), the
        same bound over those tracks, its variance multiplied by how many windows share a pixel
        (:func:`ppo_cv.photometric.window_overlap`). For the rotation of a general motion: the
        root-mean-square angle of the covariance of the final refinement
        (:func:`ppo_cv.refine.pose_sigmas_deg`, as ``t_sigma_deg``, a ``k1`` the refinement
        held at 0 counted as a considered parameter), combined with ``rotation_bias_deg``
        (:attr:`ppo_cv.rotation_choice.RotationEstimate.rms_error_deg`); of a plane: that of
        its refinement on
        the homography, the focal length and a held ``k1`` counted the same way
        (:attr:`ppo_cv.plane.RefinedPlanarPose.rotation_sigma_deg`); inf when the matches do
        not determine the pose. A pure rotation's adds the parallax of its tracks beyond their
        noise (:func:`ppo_cv.rotation_choice.unbiased_bias_deg`). When ``R`` is the
        rotation-only fit of a moving pair (``PairResult.rotation_source``), that fit's
        deviation combined with its bias's deviation and its bias beyond that deviation
        (:attr:`ppo_cv.rotation_choice.RotationEstimate.rms_error_deg`).
    rotation_tracks : int
        For a pure rotation whose rotation was refitted on windows aligned by intensity
        (:mod:`ppo_cv.photometric`, ``PairOptions.photometric``): the number of tracks behind
        ``R``, ``lens.focal_scale`` and ``rotation_sigma_deg``. 0 when ``R`` is that of the
        feature matches.
    rotation_bias_deg : float
        The bias of ``R`` (degrees) counted by the rule that chose it
        (:mod:`ppo_cv.rotation_choice`): for the rotation-only fit of a pair that moved, the
        parallax of the translation it ignores, measured on intensity-aligned tracks (on the
        feature matches when none were aligned); for the essential matrix's rotation, how far
        it moves when its radial term is fitted anew
        (:func:`ppo_cv.rotation_choice.released_lens_shift_deg`); 0 for a plane's rotation and
        for a pure rotation.
    """

    t_sigma_deg: float
    rotation_sigma_deg: float
    rotation_tracks: int
    rotation_bias_deg: float = 0.0


@dataclass(frozen=True)
class LensTerms:
    """The lens terms fitted with the models: those the rotation-only fit absorbed, and the
    radial term of a general pose.

    Attributes
    ----------
    focal_scale : float
        Focal scale absorbed by the rotation-only fit (given focal length over the true one).
    focal_ratio : float
        Scale of image 2's focal length against image 1's absorbed by the rotation-only fit
        when the two were given slightly different (focal lengths estimated per photo, as by a
        panorama stitcher; :func:`ppo_cv.rotation.focal_ratio_prior`,
        ``PairOptions.focal_ratio``); 1 otherwise.
    principal_offset_px : ndarray, shape (2,)
        Offset of the true principal point from the given one found by the rotation-only fit
        (pixels; zero when it was not fitted, ``PairOptions.principal_point``).
    principal_bound : float
        Largest offset that fit accepted, in deviations of its prior per coordinate:
        :data:`ppo_cv.rotation.PRINCIPAL_BOUND`, or :data:`ppo_cv.rotation.PRINCIPAL_WIDE_BOUND`
        for a pair that only the wider bound makes a rotation candidate (a pure rotation only
        if its tracks confirm it, ``evidence.tracks``).
    lens_excess : float
        How far the lens the rotation-only fit needed (focal scale, ``k1``, focal ratio) lay
        beyond the box of plausible lenses, in its own posterior deviations
        (:attr:`ppo_cv.motion_model.MotionDecision.lens_excess`): above
        :data:`ppo_cv.motion_model.LENS_SIGNIFICANCE` no pair is a pure rotation, whatever
        ``evidence.selection.gric_difference`` says. Negative inside the box; NaN when not
        estimated.
    radial_k1 : float
        For a general motion: the radial (division-model) coefficient fitted with the pose
        (:func:`ppo_cv.refine.refine_pose_radial`; 0 when not kept); ``R``, ``t`` and the
        points are those of the points it undistorts. NaN otherwise (a plane's is
        ``plane.k1``).
    wanted_focal_scale : float
        When the rotation-only fit's lens was clipped to its box (``lens_excess > 0``): the
        focal scale (given over true) of the rotation through the focal length its matches
        want, ``1 / wanted_focal_scale`` times the given one
        (:func:`ppo_cv.rotation_choice.wanted_focal_scale`). A translation before a plane makes
        the same homography, so it says which focal length would make the pair a rotation, not
        that it is one; the rotation choice reads the rotation-only fit's bias through such a
        focal length (``docs/decision.md``, after the table), but ``R`` is never refitted with
        it. NaN otherwise.
    """

    focal_scale: float
    focal_ratio: float
    principal_offset_px: np.ndarray
    principal_bound: float
    lens_excess: float
    radial_k1: float
    wanted_focal_scale: float = float("nan")


@dataclass(frozen=True)
class ModelComparison:
    """The statistics by which rotation, plane and general motion were compared.

    Attributes
    ----------
    pri_threshold : float
        PRI threshold used (``PairOptions.pri_threshold``).
    rotation_residual_px, general_residual_px : float
        Median residual (pixels, distance in the joint image space) of the rotation-only fit
        and of the essential matrix over the union of their inliers.
    plane_residual_px : float
        Median residual (pixels, homography Sampson error) of the homography over the same
        matches; NaN when no homography was fitted.
    gric_difference : float
        ``(GRIC(rotation) - GRIC(general)) / n``: the decision statistic, negative for a rotation.
    gric_plane_difference : float
        ``(GRIC(plane) - GRIC(general)) / n``: negative when the plane explains more.
    plane_epipolar_ratio : float
        How much worse the essential matrix of the homography's pose explains the matches than
        the refined one (about 1 on a plane; a plane needs at most
        :data:`ppo_cv.motion_model.PLANE_EPIPOLAR_TOLERANCE`); NaN without a homography.
    noise_sigma_px : float
        Noise estimated from the essential matrix's residuals (pixels).
    rotation_noise_px : float
        Noise of the rotation-only fit's residuals that changes from a match to its nearest
        neighbour (pixels, :func:`ppo_cv.model_selection.incoherent_sigma`); the model
        comparison divides by the larger of the two.
    coherent_share : float
        Share of the compared matches that the essential matrix explains, the rotation-only
        fit does not, and that move with their nearest neighbour (a surface with parallax or a
        moving object, :func:`ppo_cv.model_selection.coherent_share`); above
        :data:`ppo_cv.motion_model.MAX_COHERENT_SHARE` the pair is not a pure rotation.
    rotation_gap_deg : float
        Angle (degrees) between the refined essential matrix's rotation and the rotation-only
        fit. Beyond :data:`ppo_cv.motion_model.MIN_CANDIDATE_ROTATION_GAP` the essential matrix
        bent its rotation more than a negligible translation would, and a pair GRIC calls
        general may be a rotation candidate (``evidence.tracks``).
    """

    pri_threshold: float
    rotation_residual_px: float
    general_residual_px: float
    plane_residual_px: float
    gric_difference: float
    gric_plane_difference: float
    plane_epipolar_ratio: float
    noise_sigma_px: float
    rotation_noise_px: float
    coherent_share: float
    rotation_gap_deg: float


@dataclass(frozen=True)
class TrackParallax:
    """The parallax measured on windows aligned by intensity (:mod:`ppo_cv.parallax`).

    Attributes
    ----------
    parallax, parallax_sigma : float
        For a pair the matches called a pure rotation, or a rotation candidate
        (:attr:`ppo_cv.motion_model.MotionDecision.rotation_candidate`), whose windows were
        aligned by intensity: the baseline over the distance of the plane those tracks fit
        best, and its deviation. Beyond :data:`ppo_cv.motion_model.MAX_TRACK_PARALLAX` by
        :data:`ppo_cv.motion_model.PARALLAX_SIGNIFICANCE` deviations a pure rotation is not
        one; below :data:`ppo_cv.motion_model.NEGLIGIBLE_PARALLAX` with
        :data:`ppo_cv.motion_model.NEGLIGIBLE_SIGNIFICANCE` deviations to spare a candidate
        is one (:func:`ppo_cv.motion_model.with_tracks`). NaN otherwise.
    """

    parallax: float
    parallax_sigma: float


@dataclass(frozen=True)
class ConsensusSignificance:
    """How far the robust fit's consensus is from chance (:mod:`ppo_cv.significance`).

    Attributes
    ----------
    log10_nfa : float
        ``log10`` of the number of false alarms of the consensus: how many consensus sets this
        good chance alone would produce; the pose is reported only when it is at most
        ``PairOptions.max_log10_nfa``.
    threshold_scale : float
        Detector threshold scale of the features behind the result: 1, or
        :data:`ppo_cv.consensus.REDETECT_THRESHOLD_SCALE` when the second detection
        (``PairOptions.redetect_below``) gave a fit that chance explains less.
    ransac_threshold_px : float
        Inlier threshold the pair was fitted at, pixels of the full-size image:
        ``PairOptions.ransac_threshold`` times the reduction of an image detected on a copy
        reduced to ``PairOptions.max_image_size`` (its keypoints carry that much more noise in
        full-size pixels), at most :data:`ppo_cv.options.MAX_RANSAC_THRESHOLD`.
    features : str
        Where the features behind the result come from: ``"given"``, the ``features1`` and
        ``features2`` given to :func:`ppo_cv.pipeline.estimate_pair` (thinned to the threshold
        or as given); ``"detected"``, detected on the images by ``estimate_pair``: always
        without given features, and with them when their consensus was weak or failed and
        that of a detection on the images was kept (with a
        :class:`ppo_cv.consensus.GivenFeaturesReplacedWarning`).
    """

    log10_nfa: float
    threshold_scale: float
    ransac_threshold_px: float
    features: str = "detected"


@dataclass(frozen=True)
class DecisionEvidence:
    """What the choice among rotation, plane and general motion rests on
    (``docs/decision.md``).

    Attributes
    ----------
    selection : ModelComparison
        Residuals, GRIC differences, noise and the other statistics of the comparison.
    tracks : TrackParallax
        Parallax of the intensity-aligned windows of a rotation or rotation candidate.
    significance : ConsensusSignificance
        The consensus against chance, and the detection it came from.
    """

    selection: ModelComparison
    tracks: TrackParallax
    significance: ConsensusSignificance


@dataclass(frozen=True)
class PlaneGeometry:
    """The plane of a pair whose model is ``"plane"``, ``n^T X1 = d`` in camera 1.

    Attributes
    ----------
    normal : ndarray, shape (3,)
        Unit normal ``n`` in camera 1.
    distance : float
        ``d`` in baselines (the unit of ``points3d``).
    ambiguous : bool
        A second decomposition candidate keeps as many points in front of both cameras, within
        the noise of a sign test (:func:`ppo_cv.plane.support_ties`; the two-fold ambiguity of
        a homography), and the tie was broken by the matches off the plane or by the prior
        that the plane faces the cameras (:func:`ppo_cv.plane.select_plane_pose`).
    k1 : float
        The radial (division-model) coefficient fitted with its homography
        (:func:`ppo_cv.plane.refine_planar_pose`; 0 when not significant).
    """

    normal: np.ndarray
    distance: float
    ambiguous: bool
    k1: float


RENAMED_FIELDS: dict[str, str] = {
    "K1": "cameras.K1",
    "K2": "cameras.K2",
    "dist1": "cameras.dist1",
    "dist2": "cameras.dist2",
    "image_size1": "cameras.image_size1",
    "image_size2": "cameras.image_size2",
    "t_sigma_deg": "uncertainty.t_sigma_deg",
    "rotation_sigma_deg": "uncertainty.rotation_sigma_deg",
    "rotation_tracks": "uncertainty.rotation_tracks",
    "focal_scale": "lens.focal_scale",
    "focal_ratio": "lens.focal_ratio",
    "principal_offset_px": "lens.principal_offset_px",
    "principal_bound": "lens.principal_bound",
    "lens_excess": "lens.lens_excess",
    "radial_k1": "lens.radial_k1",
    "pri_threshold": "evidence.selection.pri_threshold",
    "rotation_residual_px": "evidence.selection.rotation_residual_px",
    "general_residual_px": "evidence.selection.general_residual_px",
    "plane_residual_px": "evidence.selection.plane_residual_px",
    "gric_difference": "evidence.selection.gric_difference",
    "gric_plane_difference": "evidence.selection.gric_plane_difference",
    "plane_epipolar_ratio": "evidence.selection.plane_epipolar_ratio",
    "noise_sigma_px": "evidence.selection.noise_sigma_px",
    "rotation_noise_px": "evidence.selection.rotation_noise_px",
    "coherent_share": "evidence.selection.coherent_share",
    "rotation_gap_deg": "evidence.selection.rotation_gap_deg",
    "track_parallax": "evidence.tracks.parallax",
    "track_parallax_sigma": "evidence.tracks.parallax_sigma",
    "log10_nfa": "evidence.significance.log10_nfa",
    "threshold_scale": "evidence.significance.threshold_scale",
    "plane_normal": "plane.normal",
    "plane_distance": "plane.distance",
    "plane_ambiguous": "plane.ambiguous",
    "plane_k1": "plane.k1",
}
"""Flat name of 0.1.0 -> path in :class:`PairResult`; the flat names read with a
:class:`DeprecationWarning` until the next release."""

_NO_PLANE = {"plane.normal": None, "plane.distance": float("nan"), "plane.ambiguous": False,
             "plane.k1": float("nan")}  # fmt: skip
"""What the flat ``plane_*`` fields held when the model was not a plane."""


@dataclass(frozen=True, repr=False)
class PairResult:
    """Relative pose of two images and its evidence.

    Its ``repr`` is one line, the keypoints, matches and points by their shape
    (:func:`compact_repr`).

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        Rotation from camera 1 to camera 2, ``X2 = R X1 + t``.
    t : ndarray, shape (3,)
        Unit translation direction. When ``pure_rotation`` is True it is the best unit estimate
        but undetermined (``translation_determined`` is False).
    pure_rotation : bool
        The views share a centre, or the baseline is negligible (:mod:`ppo_cv.motion_model`:
        the rotation model wins GRIC and its PRI is below ``pri_threshold``, or GRIC sees a
        translation whose parallax the intensity-aligned windows measure as negligible, with
        ``evidence.selection.gric_difference`` then positive).
    model : str
        ``"rotation"``, ``"plane"`` (the matches lie on one plane: pose from its homography)
        or ``"general"`` (:mod:`ppo_cv.motion_model`).
    rotation_source : str
        Which estimate ``R`` is (:mod:`ppo_cv.rotation_choice`): ``"rotation"`` (the
        rotation-only fit), ``"essential"`` (the essential matrix's refined pose) or
        ``"plane"`` (the homography's pose). A pair that is not a pure rotation returns the
        estimate with the smallest expected error, ``|bias| + deviation``: the rotation-only
        fit is biased by about the parallax of the translation it ignores, the moving model's
        rotation is unbiased with deviation ``uncertainty.rotation_sigma_deg``. ``t`` and
        ``model`` stay the moving model's; the points are recomputed through ``R`` and ``t``,
        so that they, the PLY and the COLMAP model are those of the pose returned.
    pri : float
        Pure-rotation indicator (mean ``|M2|``, eq. 84) of the returned pose over the inliers:
        the essential matrix's refined pose, for a plane the homography's PPO pose, or for a
        pure rotation the rotation-only fit with the ``t`` most consistent with it.
    keypoints1, keypoints2 : ndarray, shape (N1, 2), (N2, 2)
        All detected keypoints, full-resolution pixels.
    matches : ndarray of int, shape (M, 2)
        Putative matches, indices into ``keypoints1`` and ``keypoints2``.
    inliers : ndarray of bool, shape (M,)
        Matches consistent with the estimated two-view geometry (for a plane, the homography).
    points3d : ndarray, shape (M, 3)
        Analytic point (Proposition 3) of each match in camera-1 coordinates with unit
        baseline; NaN outside the inliers, where the PPO inequalities fail or the rays are
        parallel, and everywhere for a pure rotation (as ``PoseResult.points3d``).
    point_matches : ndarray of int, shape (P,)
        Rows of ``matches`` with a finite point: ``points3d[point_matches]``.
    colours : ndarray of uint8, shape (M, 3)
        RGB colour of each match, sampled from image 1.
    cameras : PairCameras
        Intrinsics, distortion and image sizes used.
    uncertainty : PoseUncertainty
        Standard deviations of the direction of ``t`` and of ``R``.
    lens : LensTerms
        Lens terms fitted with the models.
    evidence : DecisionEvidence
        The statistics the model decision rests on.
    plane : PlaneGeometry or None
        The plane when ``model`` is ``"plane"``, None otherwise.
    timings : dict
        Seconds per stage (:mod:`ppo_cv.pipeline`); ``features`` is detection alone and
        ``pycolmap_import`` the wait for the first import of pycolmap that overlaps it.

    Examples
    --------
    The answer, its finite 3D points (P, 3) in camera 1 with a unit baseline, and the files
    ``ppo-cv pair --out`` writes from it (``result.json``, ``points.ply``, ``matches.png`` and
    a COLMAP model):

    >>> import os, tempfile
    >>> from importlib.resources import files
    >>> import ppo_cv
    >>> demo = files("ppo_cv") / "data"
    >>> image1, image2 = str(demo / "demo1.png"), str(demo / "demo2.png")
    >>> K = [[535.4, 0, 320.1], [0, 539.2, 247.6], [0, 0, 1]]
    >>> result = ppo_cv.estimate_pair(image1, image2, K)
    >>> result.model, result.pure_rotation, result.R.shape, result.t.shape
    ('general', False, (3, 3), (3,))
    >>> result.points3d[result.point_matches].shape
    (259, 3)
    >>> scratch = tempfile.TemporaryDirectory()
    >>> written = ppo_cv.write_outputs(os.path.join(scratch.name, "result"), result, image1, image2)
    >>> sorted(os.listdir(written))
    ['colmap', 'matches.png', 'points.ply', 'result.json']
    >>> scratch.cleanup()
    """

    R: np.ndarray
    t: np.ndarray
    pure_rotation: bool
    model: str
    rotation_source: str
    pri: float
    keypoints1: np.ndarray
    keypoints2: np.ndarray
    matches: np.ndarray
    inliers: np.ndarray
    points3d: np.ndarray
    point_matches: np.ndarray
    colours: np.ndarray
    cameras: PairCameras
    uncertainty: PoseUncertainty
    lens: LensTerms
    evidence: DecisionEvidence
    plane: PlaneGeometry | None
    timings: dict[str, float]

    @property
    def translation_determined(self) -> bool:
        """False for a pure rotation, whose translation direction the images do not fix."""
        return not self.pure_rotation

    @property
    def num_matches(self) -> int:
        """Number of putative matches."""
        return int(self.matches.shape[0])

    @property
    def num_inliers(self) -> int:
        """Number of inlier matches."""
        return int(np.count_nonzero(self.inliers))

    @property
    def num_points(self) -> int:
        """Number of finite 3D points."""
        return int(self.point_matches.shape[0])

    @property
    def inlier_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (I, 2) of the inlier matches in image 1 and image 2."""
        m = self.matches[self.inliers]
        return self.keypoints1[m[:, 0]], self.keypoints2[m[:, 1]]

    def __repr__(self) -> str:
        return compact_repr(self)

    def __getattr__(self, name: str):
        path = RENAMED_FIELDS.get(name)
        if path is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        warnings.warn(
            f"PairResult.{name} is deprecated and goes in the next release; use PairResult.{path}",
            DeprecationWarning,
            stacklevel=2,
        )
        if path in _NO_PLANE and self.plane is None:
            return _NO_PLANE[path]
        return attrgetter(path)(self)
