"""pycolmap interop: cameras, relative poses and two-view geometries in COLMAP's conventions.

COLMAP names a transform by its direction: ``cam2_from_cam1`` maps a point from camera-1
coordinates to camera-2 coordinates, ``X2 = R X1 + t``, which is exactly the ``(R, t)`` of
:class:`~ppo_cv.pose.PoseResult`; an image's ``cam_from_world`` maps world points into that
camera. Its essential matrix satisfies ``x2^T E x1 = 0`` on normalized rays, as ours does.
A pure rotation is COLMAP's ``PANORAMIC`` configuration, with ``t = 0``.

Examples
--------
>>> import numpy as np
>>> from ppo_cv import colmap
>>> rigid = colmap.rigid3d_from_pose(np.eye(3), np.array([1.0, 0.0, 0.0]))
>>> R, t = colmap.pose_from_rigid3d(rigid.inverse())
>>> t.tolist()
[-1.0, 0.0, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pycolmap

from . import ppo
from .checks import (
    MAX_WHOLE_NUMBER,
    as_camera_matrix,
    as_finite_rows,
    as_matrix3,
    as_nonnegative,
    as_point_pair,
    as_pri_threshold,
    as_real_array,
    as_rotation,
    as_whole_number,
    require_essential_spread,
    require_finite,
    require_instance,
    shown,
)
from .lsq import _cross_matrix
from .metrics import direction_error_deg
from .pose import PoseResult, recover_pose
from .result import PairResult

__all__ = [
    "TwoViewEstimate",
    "camera_from_K",
    "K_from_camera",
    "rays_from_camera",
    "rigid3d_from_pose",
    "pose_from_rigid3d",
    "relative_pose",
    "triangulation_angles",
    "median_tri_angle",
    "two_view_geometry_from_pose",
    "recover_pose_from_geometry",
    "estimate_two_view_geometry",
    "two_view_reconstruction",
]

Config = pycolmap.TwoViewGeometryConfiguration
_POSED_CONFIGS = frozenset(
    int(c)
    for c in (
        Config.CALIBRATED,
        Config.UNCALIBRATED,
        Config.PLANAR,
        Config.PANORAMIC,
        Config.PLANAR_OR_PANORAMIC,
    )
)
_PINHOLE_MODELS = ("SIMPLE_PINHOLE", "PINHOLE")
_MAKE_CAMERA = ": make one with ppo_cv.colmap.camera_from_K(K, width, height)"


def _require_camera(camera: Any, name: str) -> None:
    require_instance(camera, pycolmap.Camera, name, _MAKE_CAMERA)


def _require_pose(pose: Any) -> None:
    require_instance(pose, (PoseResult, PairResult), "pose", " (ppo_cv.recover_pose)")


@dataclass(frozen=True)
class TwoViewEstimate:
    """A pycolmap two-view geometry whose pose was chosen by the PPO inequalities.

    Attributes
    ----------
    geometry : pycolmap.TwoViewGeometry
        ``config``, ``E``, ``F``, ``H`` and ``inlier_matches`` as pycolmap's robust estimation
        found them; ``cam2_from_cam1`` and ``tri_angle`` (radians) from PPO. ``config`` is
        ``PANORAMIC`` when PPO detects a pure rotation; when pycolmap called the pair
        panoramic but PPO measures parallax, ``CALIBRATED`` (``PLANAR`` for pycolmap's
        ``PLANAR_OR_PANORAMIC``).
    pose : PoseResult or None
        The PPO result on the rows of ``geometry.inlier_matches``; None when pycolmap found no
        usable geometry (too few matches, degenerate or watermark).
    """

    geometry: Any
    pose: PoseResult | None

    @property
    def success(self) -> bool:
        """Whether a pose was recovered."""
        return self.pose is not None


def camera_from_K(K: Any, width: int, height: int) -> pycolmap.Camera:
    """A ``PINHOLE`` pycolmap camera ``(fx, fy, cx, cy)`` from a 3x3 intrinsic matrix.

    ``K`` is taken in COLMAP's pixel coordinates, those of the keypoints of a COLMAP database,
    where the centre of the first pixel is (0.5, 0.5): a ``K`` in OpenCV's, as
    ``cv2.calibrateCamera`` or :func:`ppo_cv.load_calibration` gives it, needs
    :data:`~ppo_cv.calib.COLMAP_PIXEL_OFFSET` added to its ``cx`` and ``cy`` first.

    Raises
    ------
    ValueError
        If ``K`` is not a valid camera matrix or has skew, or the image size is not two whole
        numbers >= 1 (TypeError when they are no numbers).
    """
    K = as_camera_matrix(K, "K")
    if K[0, 1] != 0:
        raise ValueError(f"K has skew {K[0, 1]}; a COLMAP PINHOLE camera has none")
    width = as_whole_number(width, "image width", 1, MAX_WHOLE_NUMBER)
    height = as_whole_number(height, "image height", 1, MAX_WHOLE_NUMBER)
    return pycolmap.Camera(
        model="PINHOLE",
        width=width,
        height=height,
        params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2]],
    )


def K_from_camera(camera: pycolmap.Camera) -> np.ndarray:
    """The 3x3 intrinsic matrix of a ``SIMPLE_PINHOLE`` or ``PINHOLE`` camera.

    Raises
    ------
    ValueError
        For models with distortion, which no 3x3 matrix describes; use
        :func:`rays_from_camera` for those. TypeError for anything but a ``pycolmap.Camera``.
    """
    _require_camera(camera, "camera")
    if camera.model_name not in _PINHOLE_MODELS:
        raise ValueError(
            f"camera model {camera.model_name} has distortion; K alone cannot describe it"
        )
    return np.asarray(camera.calibration_matrix(), dtype=np.float64)


def rays_from_camera(camera: pycolmap.Camera, points: np.ndarray) -> np.ndarray:
    """Normalized image points (N, 2) of finite pixel points (N, 2), undistorted by the camera
    model."""
    _require_camera(camera, "camera")
    return np.asarray(camera.cam_from_img(as_finite_rows(points, "points", 2)))


def rigid3d_from_pose(R: Any, t: Any) -> pycolmap.Rigid3d:
    """``cam2_from_cam1`` as a pycolmap ``Rigid3d`` from ``X2 = R X1 + t``."""
    return pycolmap.Rigid3d(pycolmap.Rotation3d(as_rotation(R, "R")), _as_translation(t))


def _as_translation(t: Any) -> np.ndarray:
    """Three finite numbers as float64 (3,); TypeError or ValueError naming ``t``."""
    try:
        t = as_real_array(t, "t").reshape(-1)
    except (TypeError, ValueError, OverflowError):  # also complex, bool or text numbers
        raise TypeError(f"t must be three numbers, got {type(t).__name__} {shown(t)}") from None
    if t.shape != (3,):
        raise ValueError(f"t must be of length 3, got shape {t.shape}")
    require_finite(t, "t")
    return t


def _as_real_rows(value: Any, name: str, width: int, shape: str = "") -> np.ndarray:
    """Real numbers as float64 (N, ``width``), or (N, ``width`` or more) where ``shape`` says
    so (``"(M, >=2)"``); NaN allowed (a point the pose does not define)."""
    try:
        array = as_real_array(value, name)
    except (TypeError, ValueError, OverflowError):  # also complex, bool or text numbers
        raise TypeError(f"{name} must be an array of real numbers, got {shown(value)}") from None
    wide = array.ndim == 2 and (array.shape[1] >= width if shape else array.shape[1] == width)
    if not wide:
        raise ValueError(f"{name} must have shape {shape or f'(N, {width})'}, got {array.shape}")
    return array


def pose_from_rigid3d(rigid: pycolmap.Rigid3d) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` of a pycolmap ``Rigid3d``: ``target = R source + t``."""
    require_instance(rigid, pycolmap.Rigid3d, "rigid")
    return np.array(rigid.rotation.matrix(), dtype=np.float64), np.array(
        rigid.translation, dtype=np.float64
    ).reshape(3)


def relative_pose(
    reconstruction: pycolmap.Reconstruction, image_id1: int, image_id2: int
) -> tuple[np.ndarray, np.ndarray]:
    """``cam2_from_cam1`` of two registered images: ``cam2_from_world * inverse(cam1_from_world)``.

    The translation carries the reconstruction's scale. An id of no registered image is a
    ValueError.
    """
    require_instance(reconstruction, pycolmap.Reconstruction, "reconstruction")
    cam1, cam2 = (_registered_pose(reconstruction, i) for i in (image_id1, image_id2))
    return pose_from_rigid3d(cam2 * cam1.inverse())


def _registered_pose(reconstruction: pycolmap.Reconstruction, image_id: Any) -> pycolmap.Rigid3d:
    """``cam_from_world`` of a registered image; ValueError naming an id of none."""
    image_id = as_whole_number(image_id, "image id", 0, MAX_WHOLE_NUMBER)
    if not reconstruction.exists_image(image_id):
        raise ValueError(f"the reconstruction has no image of id {image_id}")
    image = reconstruction.image(image_id)
    if not image.has_pose:
        raise ValueError(f"image {image_id} ({image.name}) is not registered: it has no pose")
    return image.cam_from_world()


def triangulation_angles(points3d: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Angle (radians) at each point between the rays to both camera centres, shape (N,).

    ``points3d`` (N, 3) are in camera-1 coordinates; camera 2 sits at ``-R^T t``. NaN points
    give NaN.
    """
    points3d = _as_real_rows(points3d, "points3d", 3)
    center2 = -as_rotation(R, "R").T @ _as_translation(t)
    return np.radians(direction_error_deg(points3d, points3d - center2))


def median_tri_angle(pose: PoseResult) -> float:
    """Median triangulation angle (radians) of the analytic points of the PPO inliers.

    0 for a pure rotation or without inliers, as COLMAP's ``tri_angle`` of a panoramic pair.
    """
    _require_pose(pose)
    if pose.pure_rotation or not pose.inliers.any():
        return 0.0
    angles = triangulation_angles(pose.points3d[pose.inliers], pose.R, pose.t)
    angles = angles[np.isfinite(angles)]
    return float(np.median(angles)) if angles.size else 0.0


def two_view_geometry_from_pose(
    pose: PoseResult, E: Any = None, matches: Any = None
) -> pycolmap.TwoViewGeometry:
    """A pycolmap ``TwoViewGeometry`` carrying a PPO pose.

    Parameters
    ----------
    pose : PoseResult
        From :func:`ppo_cv.recover_pose`; sets ``cam2_from_cam1`` (``t = 0`` for a pure
        rotation, as COLMAP stores panoramic pairs), ``config`` (``PANORAMIC`` or
        ``CALIBRATED``) and ``tri_angle`` (median over the inliers, radians).
    E : array_like, shape (3, 3), optional
        The essential matrix the pose came from.
    matches : array_like of int, shape (N, 2), optional
        Keypoint indices of the N correspondences given to ``recover_pose``; the rows of the
        PPO inliers become ``inlier_matches``.
    """
    _require_pose(pose)
    geometry = pycolmap.TwoViewGeometry()
    geometry.config = Config.PANORAMIC if pose.pure_rotation else Config.CALIBRATED
    t = np.zeros(3) if pose.pure_rotation else pose.t
    geometry.cam2_from_cam1 = rigid3d_from_pose(pose.R, t)
    geometry.tri_angle = median_tri_angle(pose)
    if E is not None:
        geometry.E = as_finite_rows(E, "E", 3).reshape(3, 3)
    if matches is not None:
        matches = _as_index_pairs(matches)
        if matches.shape != (pose.inliers.shape[0], 2):
            raise ValueError(
                f"matches must have shape ({pose.inliers.shape[0]}, 2), got {matches.shape}"
            )
        geometry.inlier_matches = np.ascontiguousarray(matches[pose.inliers], dtype=np.uint32)
    return geometry


def recover_pose_from_geometry(
    geometry: pycolmap.TwoViewGeometry,
    camera1: pycolmap.Camera,
    keypoints1: Any,
    camera2: pycolmap.Camera,
    keypoints2: Any,
    *,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
) -> PoseResult:
    """PPO pose from pycolmap's essential matrix and inlier matches (no cheirality test).

    Parameters
    ----------
    geometry : pycolmap.TwoViewGeometry
        With ``E`` and ``inlier_matches`` (e.g. read from a COLMAP database). Without ``E``
        (uncalibrated verification) one is estimated from the inlier matches by pycolmap's
        five-point LO-RANSAC.
    camera1, camera2 : pycolmap.Camera
        Any COLMAP camera model; points are undistorted by it.
    keypoints1, keypoints2 : array_like, shape (M1, >=2), (M2, >=2)
        All keypoints of each image (COLMAP keypoint rows: ``x, y`` first); the matches index
        them.

    Returns
    -------
    PoseResult
        Per-point fields follow the rows of ``geometry.inlier_matches``.

    Raises
    ------
    ValueError
        If the geometry has fewer than 5 inlier matches or no essential matrix can be found.
    TypeError
        If ``geometry`` or a camera is not pycolmap's.
    """
    require_instance(geometry, pycolmap.TwoViewGeometry, "geometry")
    _require_camera(camera1, "camera1")
    _require_camera(camera2, "camera2")
    matches = np.asarray(geometry.inlier_matches, dtype=np.int64).reshape(-1, 2)
    points1, points2 = as_point_pair(
        _matched_keypoints(keypoints1, matches[:, 0], 1),
        _matched_keypoints(keypoints2, matches[:, 1], 2),
    )
    E = geometry.E
    if E is None or not np.any(E):
        E = _essential_by_five_point(camera1, points1, camera2, points2)
    _require_essential_geometry(E, matches)
    x1, x2 = rays_from_camera(camera1, points1), rays_from_camera(camera2, points2)
    return recover_pose(E, x1, x2, np.eye(3), pri_threshold=pri_threshold)


def _require_essential_geometry(E: Any, matches: np.ndarray) -> None:
    """ValueError naming the geometry when its ``E`` is far from an essential matrix
    (:func:`ppo_cv.checks.require_essential_spread`), with the keypoint its inlier
    ``matches`` (K, 2) share most: a degenerate estimate, such as pycolmap's from matches that
    all reuse one keypoint, was refused as an ``E`` given by the caller ("pass E = K2^T F K1")."""
    E = as_matrix3(E, "geometry.E")
    try:
        require_essential_spread(np.linalg.svd(E, compute_uv=False))
    except ValueError as exc:
        shared = ""
        for image in (1, 2):
            keys, counts = np.unique(matches[:, image - 1], return_counts=True)
            if counts.size and counts.max() > 1:
                shared += (f"; keypoint {keys[np.argmax(counts)]} of image {image} is in "
                           f"{counts.max()} of them")  # fmt: skip
        reason = str(exc).split(", and ", 1)[-1].split(" (a fundamental")[0]
        raise ValueError(
            f"the geometry's E, from its {len(matches)} inlier matches, is degenerate: {reason}"
            f"{shared}"
        ) from None


def _keypoint_rows(keypoints: Any, image: int) -> np.ndarray:
    """COLMAP keypoint rows (M, >=2) of image 1 or 2 as float64, ``x, y`` finite."""
    keypoints = _as_real_rows(keypoints, f"keypoints{image}", 2, "(M, >=2)")
    require_finite(keypoints[:, :2], f"keypoints{image}")
    return keypoints


def _matched_keypoints(keypoints: Any, indices: np.ndarray, image: int) -> np.ndarray:
    """The ``x, y`` of the keypoints of image 1 or 2 that the matches index."""
    keypoints = _keypoint_rows(keypoints, image)
    if indices.size and indices.max() >= len(keypoints):
        raise ValueError(
            f"inlier_matches index keypoint {indices.max()} of image {image}, which has "
            f"{len(keypoints)} keypoints"
        )
    return keypoints[indices, :2]


def _essential_by_five_point(
    camera1: pycolmap.Camera, points1: np.ndarray, camera2: pycolmap.Camera, points2: np.ndarray
) -> np.ndarray:
    options = pycolmap.RANSACOptions()
    options.max_error = 2.0
    result = pycolmap.estimate_relative_pose(camera1, points1, camera2, points2, options)
    if result is None:
        raise ValueError("no essential matrix could be estimated from the inlier matches")
    R, t = pose_from_rigid3d(result["cam2_from_cam1"])
    return _cross_matrix(t) @ R


def estimate_two_view_geometry(
    camera1: pycolmap.Camera,
    points1: Any,
    camera2: pycolmap.Camera,
    points2: Any,
    matches: Any = None,
    options: pycolmap.TwoViewGeometryOptions | None = None,
    *,
    pri_threshold: float = ppo.DEFAULT_PRI_THRESHOLD,
) -> TwoViewEstimate:
    """pycolmap's calibrated two-view estimation with the pose chosen by PPO.

    The counterpart of ``pycolmap.estimate_calibrated_two_view_geometry`` followed by
    ``pycolmap.estimate_two_view_geometry_pose``: the robust model fit and inlier matches are
    pycolmap's, while ``(R, t)`` comes from the same-side and intersection inequalities on its
    essential matrix instead of triangulation and cheirality, and a pure rotation is detected
    by PRI rather than by the homography inlier ratio.

    Parameters
    ----------
    camera1, camera2 : pycolmap.Camera
    points1, points2 : array_like, shape (M1, 2), (M2, 2)
        Keypoints of each image, pixels.
    matches : array_like of int, shape (K, 2), optional
        Index pairs into ``points1`` and ``points2``; by default row i matches row i.
    options : pycolmap.TwoViewGeometryOptions, optional
        pycolmap's defaults with RANSAC seed 0 (deterministic) when omitted.
    pri_threshold : float

    Returns
    -------
    TwoViewEstimate
    """
    _require_camera(camera1, "camera1")
    _require_camera(camera2, "camera2")
    pri_threshold = as_pri_threshold(pri_threshold)
    points1, points2 = as_finite_rows(points1, "points1", 2), as_finite_rows(points2, "points2", 2)
    if matches is None:
        if points1.shape != points2.shape:
            raise ValueError(
                f"without matches points1 and points2 must have equal shapes, "
                f"got {points1.shape} and {points2.shape}"
            )
        matches = np.repeat(np.arange(points1.shape[0], dtype=np.uint32)[:, None], 2, axis=1)
    matches = _as_index_pairs(matches, (len(points1), len(points2)))
    if options is not None:
        require_instance(options, pycolmap.TwoViewGeometryOptions, "options")
    if options is None:
        options = pycolmap.TwoViewGeometryOptions()
        options.ransac.random_seed = 0
    geometry = pycolmap.estimate_calibrated_two_view_geometry(
        camera1, points1, camera2, points2, np.ascontiguousarray(matches, np.uint32), options
    )
    if int(geometry.config) not in _POSED_CONFIGS or len(geometry.inlier_matches) < 5:
        return TwoViewEstimate(geometry=geometry, pose=None)
    pose = recover_pose_from_geometry(
        geometry, camera1, points1, camera2, points2, pri_threshold=pri_threshold
    )
    if pose.pure_rotation:
        geometry.config = Config.PANORAMIC
    elif int(geometry.config) == int(Config.PANORAMIC):
        geometry.config = Config.CALIBRATED
    elif int(geometry.config) == int(Config.PLANAR_OR_PANORAMIC):
        geometry.config = Config.PLANAR
    geometry.cam2_from_cam1 = rigid3d_from_pose(
        pose.R, np.zeros(3) if pose.pure_rotation else pose.t
    )
    geometry.tri_angle = median_tri_angle(pose)
    return TwoViewEstimate(geometry=geometry, pose=pose)


def _as_index_pairs(value: Any, sizes: tuple[int, int] | None = None) -> np.ndarray:
    """Whole numbers as int64 (K, 2), each below its column's ``sizes`` entry; TypeError or
    ValueError naming ``matches``."""
    matches = np.asarray(value)
    if matches.size == 0:
        matches = matches.reshape(0, 2)
    if matches.dtype == bool or not np.issubdtype(matches.dtype, np.integer):
        raise TypeError(f"matches must be whole numbers (keypoint indices), got {matches.dtype}")
    if matches.ndim != 2 or matches.shape[1] != 2:
        raise ValueError(f"matches must have shape (K, 2), got {matches.shape}")
    matches = matches.astype(np.int64)
    if matches.size and matches.min() < 0:
        raise ValueError(f"matches must be keypoint indices >= 0, got {matches.min()}")
    for column, size in enumerate(sizes or ()):
        if matches.size and matches[:, column].max() >= size:
            raise ValueError(
                f"matches index keypoint {matches[:, column].max()} of image {column + 1}, "
                f"which has {size} keypoints"
            )
    return matches


def two_view_reconstruction(
    camera1: pycolmap.Camera,
    camera2: pycolmap.Camera,
    image1: pycolmap.Image,
    image2: pycolmap.Image,
    keypoints1: Any,
    keypoints2: Any,
    matches: Any,
    pose: PoseResult,
    *,
    min_tri_angle: float = 1.5,
) -> pycolmap.Reconstruction:
    """A two-view COLMAP reconstruction from a PPO pose and its analytic points (eq. 36).

    The world frame is camera 1; camera 2 is ``cam2_from_world = (R, t)`` with the unit
    baseline of ``pose``. Each match that is a PPO inlier, has a finite analytic point and a
    triangulation angle of at least ``min_tri_angle`` degrees becomes a 3D point with a track
    of length two, carrying its mean reprojection error in pixels (COLMAP's point error).
    Nothing is refined: run ``pycolmap.bundle_adjustment`` on the result if needed.

    Parameters
    ----------
    camera1, camera2 : pycolmap.Camera
        With their ``camera_id`` (equal ids mean one shared camera).
    image1, image2 : pycolmap.Image
        Name, ``image_id`` and ``camera_id`` are used (e.g. from a COLMAP database).
    keypoints1, keypoints2 : array_like, shape (M1, >=2), (M2, >=2)
        All keypoints of each image; they become the images' ``points2D``.
    matches : array_like of int, shape (N, 2)
        The keypoint index pairs ``pose`` was computed on.
    pose : PoseResult
        From :func:`recover_pose_from_geometry` or :func:`ppo_cv.recover_pose`; not a pure
        rotation.
    min_tri_angle : float
        Degrees, >= 0. A keypoint matched twice (a matcher without cross-check) observes the
        point of its first kept match only.

    Raises
    ------
    ValueError
        For a pure rotation (no structure to build), mismatched ``matches``, a camera or image
        without an id, an image whose ``camera_id`` is not its camera's, one id for two
        different cameras, one id or name for both images, or a ``min_tri_angle`` that is not
        a finite number >= 0 (TypeError for no number).
    """
    _require_pose(pose)
    if pose.pure_rotation:
        raise ValueError("a pure rotation has no two-view structure")
    _require_two_views(camera1, camera2, image1, image2)
    min_tri_angle = as_nonnegative(min_tri_angle, "min_tri_angle")
    keypoints1, keypoints2 = _keypoint_rows(keypoints1, 1), _keypoint_rows(keypoints2, 2)
    matches = _as_index_pairs(matches, (len(keypoints1), len(keypoints2)))
    if matches.shape[0] != pose.inliers.shape[0]:
        raise ValueError(
            f"matches has {matches.shape[0]} rows but the pose has {pose.inliers.shape[0]} points"
        )
    reconstruction = pycolmap.Reconstruction()
    for camera in {camera1.camera_id: camera1, camera2.camera_id: camera2}.values():
        reconstruction.add_camera_with_trivial_rig(camera)
    poses = (pycolmap.Rigid3d(), rigid3d_from_pose(pose.R, pose.t))
    for image, keypoints, cam_from_world in zip(
        (image1, image2), (keypoints1, keypoints2), poses, strict=True
    ):
        xy = np.ascontiguousarray(keypoints[:, :2])
        reconstruction.add_image_with_trivial_frame(
            pycolmap.Image(
                name=image.name, keypoints=xy, camera_id=image.camera_id, image_id=image.image_id
            ),
            cam_from_world,
        )
    points = pose.points3d
    angles = triangulation_angles(points, pose.R, pose.t)
    keep = pose.inliers & np.all(np.isfinite(points), axis=1)
    keep &= np.degrees(np.nan_to_num(angles)) >= min_tri_angle
    keep &= _first_uses(matches, keep)
    id1, id2 = image1.image_id, image2.image_id
    for (index1, index2), xyz in zip(matches[keep].tolist(), points[keep], strict=True):
        track = pycolmap.Track(
            [pycolmap.TrackElement(id1, index1), pycolmap.TrackElement(id2, index2)]
        )
        reconstruction.add_point3D(xyz, track)
    reconstruction.update_point_3d_errors()
    return reconstruction


def _first_uses(matches: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Mask (N,) of the kept matches whose keypoints no earlier kept match uses, in both
    images: a COLMAP keypoint observes one 3D point."""
    first = np.zeros(len(matches), dtype=bool)
    rows = np.flatnonzero(keep)
    unique = np.ones(len(rows), dtype=bool)
    for column in (0, 1):
        _, firsts = np.unique(matches[rows, column], return_index=True)
        seen = np.zeros(len(rows), dtype=bool)
        seen[firsts] = True
        unique &= seen
    first[rows[unique]] = True
    return first


def _same_camera(camera1: pycolmap.Camera, camera2: pycolmap.Camera) -> bool:
    return (camera1.model, camera1.width, camera1.height) == (
        camera2.model, camera2.width, camera2.height
    ) and np.array_equal(camera1.params, camera2.params)  # fmt: skip


def _require_two_views(camera1: Any, camera2: Any, image1: Any, image2: Any) -> None:
    """TypeError or ValueError naming what would fail inside pycolmap or describe other views:
    a camera or image without an id, an image whose ``camera_id`` is not its camera's, one id
    for two different cameras, one id or one name for both images."""
    _require_camera(camera1, "camera1")
    _require_camera(camera2, "camera2")
    require_instance(image1, pycolmap.Image, "image1")
    require_instance(image2, pycolmap.Image, "image2")
    for number, (camera, image) in enumerate(((camera1, image1), (camera2, image2)), 1):
        if camera.camera_id == pycolmap.INVALID_CAMERA_ID:
            raise ValueError(f"camera{number} has no camera_id; set camera{number}.camera_id")
        if image.image_id == pycolmap.INVALID_IMAGE_ID:
            raise ValueError(f"image{number} has no image_id; give pycolmap.Image an image_id")
        if image.camera_id != camera.camera_id:
            wanted = "none" if image.camera_id == pycolmap.INVALID_CAMERA_ID else image.camera_id
            raise ValueError(
                f"image{number} has camera_id {wanted}, but camera{number} has {camera.camera_id}"
            )
    if camera1.camera_id == camera2.camera_id and not _same_camera(camera1, camera2):
        raise ValueError(
            f"camera1 and camera2 differ but share camera_id {camera1.camera_id}; give each its "
            "own id, or pass one camera twice"
        )
    if image1.image_id == image2.image_id or image1.name == image2.name:
        raise ValueError(
            "image1 and image2 must have distinct image_id and name, got "
            f"{image1.image_id} {image1.name!r} and {image2.image_id} {image2.name!r}"
        )
