"""Public helpers of ppo_cv.data_gen refuse bad arguments with an error naming them (they
returned NaN rotations, silently truncated sizes or failed deep inside OpenCV)."""

from __future__ import annotations

import numpy as np
import pytest

import ppo_cv.data_gen as dg

NAN, INF = float("nan"), float("inf")
K = dg.intrinsics((64, 48), 60.0)
RGB = np.zeros((16, 16, 3), np.uint8)

CASES = {  # name: (call, error type, words of its message)
    "make_pair_fractional_width": (lambda: dg.make_pair(size=(64.5, 48)), ValueError, "width"),
    "make_pair_nan_height": (lambda: dg.make_pair(size=(64, NAN)), ValueError, "height"),
    "make_pair_true_width": (lambda: dg.make_pair(size=(True, 48)), TypeError, "width"),
    "make_pair_three_sides": (lambda: dg.make_pair(size=(64, 48, 3)), TypeError, "size"),
    "make_pair_text_seed": (lambda: dg.make_pair(seed="a"), TypeError, "seed"),
    "make_pair_fractional_index": (lambda: dg.make_pair(index=1.5), TypeError, "index"),
    "make_pair_negative_seed": (lambda: dg.make_pair(seed=-1), ValueError, "seed"),
    "make_pair_text_alpha": (lambda: dg.make_pair(alpha="a"), TypeError, "alpha"),
    "make_pair_no_blur": (lambda: dg.make_pair(blur_sigma=None), TypeError, "blur_sigma"),
    "make_pair_text_baseline": (
        lambda: dg.make_pair("tiny-baseline", baseline_ratio="0.1"), TypeError, "baseline_ratio",
    ),
    "render_view_fractional_size": (
        lambda: dg.render_view(dg.checker_plane(), K, np.eye(3), np.zeros(3), (64, 47.5)),
        ValueError, "height",
    ),
    "look_at_nan_centre": (lambda: dg.look_at([NAN, 0, 0], [0, 0, 1]), ValueError, "centre"),
    "look_at_two_numbers": (lambda: dg.look_at([0, 0], [0, 0, 1]), ValueError, "centre"),
    "look_at_nan_roll": (lambda: dg.look_at([0, 0, 0], [0, 0, 1], NAN), ValueError, "roll_deg"),
    "look_at_straight_down": (lambda: dg.look_at([0, 0, 0], [0, 2, 0]), ValueError, "world Y"),
    "division_dist_nan": (lambda: dg.division_dist(NAN), ValueError, "k1"),
    "division_dist_text": (lambda: dg.division_dist("0.1"), TypeError, "k1"),
    # an OverflowError; RuntimeWarnings from float32; NaN rotations without a word
    "division_dist_huge": (lambda: dg.division_dist(1e300), ValueError,
                           "k1 must be finite, within .+0.5 .as Imperfections draws it."),
    "expose_huge_gain": (lambda: dg.expose(RGB, 1e300), ValueError,
                         "gain must be in .1.52587890625e-05, 65536.0., got 1e.300"),
    "euler_to_matrix_nan": (lambda: dg.euler_to_matrix([NAN, 0.0, 0.0]), ValueError,
                            "angles_deg has 1 NaN"),
    "euler_to_matrix_none": (lambda: dg.euler_to_matrix(None), TypeError,
                             "angles_deg is required"),
    "given_intrinsics_none": (lambda: dg.given_intrinsics(None, 1.0), TypeError, "K"),
    "given_intrinsics_nan_K": (
        lambda: dg.given_intrinsics(np.full((3, 3), NAN), 1.0), ValueError, "K",
    ),
    "given_intrinsics_nan_factor": (
        lambda: dg.given_intrinsics(K, NAN), ValueError, "focal_factor",
    ),
    "given_intrinsics_negative_factor": (
        lambda: dg.given_intrinsics(K, -1.03), ValueError, "focal_factor",
    ),
    "given_intrinsics_fractional_centre": (
        lambda: dg.given_intrinsics(K, 1.0, (64.5, 48)), ValueError, "width",
    ),
    "jpeg_quality_200": (lambda: dg.jpeg_roundtrip(RGB, 200), ValueError, "quality"),
    "jpeg_float_image": (
        lambda: dg.jpeg_roundtrip(np.full((16, 16, 3), NAN), 90), ValueError, "uint8",
    ),
    "jpeg_grey_image": (
        lambda: dg.jpeg_roundtrip(np.zeros((16, 16), np.uint8), 90), ValueError, "(H, W, 3)",
    ),
    "texture_set_unknown": (lambda: dg.texture_set(7), ValueError, "texture_set"),
    "checker_plane_nan_distance": (lambda: dg.checker_plane(NAN), ValueError, "distance"),
    "checker_plane_no_squares": (
        lambda: dg.checker_plane(squares=(0, 8)), ValueError, "squares",
    ),
    "checker_plane_negative_square": (
        lambda: dg.checker_plane(square_m=-0.25), ValueError, "square_m",
    ),
    "tripod_poses_fractional_views": (
        lambda: dg.tripod_then_move_poses(n_pan=2.5), ValueError, "n_pan",
    ),
    "tripod_poses_nan_step": (lambda: dg.tripod_then_move_poses(step=NAN), ValueError, "step"),
    "tripod_poses_inf_pan": (
        lambda: dg.tripod_then_move_poses(pan_step=INF), ValueError, "pan_step",
    ),
    # pairs_line wrote lines read_pairs cannot read back (39 fields, a comment, "nan" for None)
    "pairs_line_name_with_space": (
        lambda: dg.pairs_line("a b.png", "c.png", K, K, np.eye(3), np.ones(3)), ValueError,
        "name1 must be a name without spaces, not starting with '#', got 'a b.png'",
    ),
    "pairs_line_comment_name": (
        lambda: dg.pairs_line("a.png", "#c.png", K, K, np.eye(3), np.ones(3)), ValueError,
        "name2 must be a name without spaces",
    ),
    "pairs_line_no_K2": (
        lambda: dg.pairs_line("a.png", "c.png", K, None, np.eye(3), np.ones(3)), TypeError,
        "K2 is required",
    ),
    "pairs_line_no_rotation": (
        lambda: dg.pairs_line("a.png", "c.png", K, K, np.ones((3, 3)), np.ones(3)), ValueError,
        "R is not a rotation matrix",
    ),
    "pairs_line_nan_t": (
        lambda: dg.pairs_line("a.png", "c.png", K, K, np.eye(3), [NAN, 0, 0]), ValueError,
        "t has 1 NaN",
    ),
    # two names and one pose gave no pair without a word, one name and two an IndexError
    "relative_gt_counts": (
        lambda: dg.relative_gt_from_poses(["a", "b"], [(np.eye(3), np.zeros(3))]), ValueError,
        "names and poses must have one entry per view, got 2 names and 1 poses",
    ),
    "relative_gt_three_poses": (
        lambda: dg.relative_gt_from_poses(["a", "b"], [(np.eye(3), np.zeros(3))] * 3),
        ValueError, "got 2 names and 3 poses",
    ),
    # a text of names was read letter by letter, a repeated name overwrote its pairs, None
    # failed on len()
    "relative_gt_names_text": (
        lambda: dg.relative_gt_from_poses("ab", [(np.eye(3), np.zeros(3))] * 2), TypeError,
        "names must be a list of texts, got 'ab'",
    ),
    "relative_gt_repeated_name": (
        lambda: dg.relative_gt_from_poses(["a", "a", "b"], [(np.eye(3), np.zeros(3))] * 3),
        ValueError, r"names must differ, one per view, got \['a', 'a', 'b'\]",
    ),
    "relative_gt_poses_none": (
        lambda: dg.relative_gt_from_poses(["a", "b"], None), TypeError,
        "poses must be a list of .R, t., got NoneType",
    ),
    "relative_gt_scaled_rotation": (
        lambda: dg.relative_gt_from_poses(["a", "b"], [(np.eye(3), np.zeros(3)),
                                                       (2 * np.eye(3), np.zeros(3))]),
        ValueError, r"poses\[1\] R is not a rotation matrix",
    ),
    # Python's and numpy's messages naming nothing ("cannot unpack non-iterable NoneType
    # object", "'<' not supported", "cannot reshape array of size 1 into shape (3)"), a NaN
    # texture without a word, a seed True read as 1, an OverflowError
    "intrinsics_no_size": (lambda: dg.intrinsics(None, 60.0), TypeError,
                           "size must be .width, height., got None"),
    "intrinsics_text_field": (lambda: dg.intrinsics((64, 48), "60"), TypeError,
                              "hfov_deg must be a number, got str"),
    "intrinsics_one_offset": (lambda: dg.intrinsics((64, 48), 60.0, (1.0,)), ValueError,
                              "principal_offset must be two numbers .dx, dy., got .1.0,."),
    "intrinsics_nan_offset": (lambda: dg.intrinsics((64, 48), 60.0, (NAN, 0)), ValueError,
                              "principal_offset has 1 NaN"),
    "checker_texture_nan_dark": (lambda: dg.checker_texture(dark=NAN), ValueError,
                                 "dark must be a reflectance in .0, 1., got nan"),
    "checker_texture_text_light": (lambda: dg.checker_texture(light="1"), TypeError,
                                   "light must be a number, got str"),
    "checker_texture_no_squares": (lambda: dg.checker_texture(None), TypeError,
                                   "squares must be .width, height., got None"),
    "checker_texture_fractional_texels": (
        lambda: dg.checker_texture(texels_per_square=1.5), ValueError,
        "texels_per_square must be a whole number"),
    "project_points_none": (lambda: dg.project_points(None, K), TypeError, "X is required"),
    "project_points_of_two": (lambda: dg.project_points(np.ones((4, 2)), K), ValueError,
                              "X must have shape .m, 3., got .4, 2."),
    "project_points_nan": (lambda: dg.project_points([[0, 0, NAN]], K), ValueError,
                           "X has 1 NaN"),
    "project_points_short_t": (lambda: dg.project_points([[0, 0, 5]], K, None, [1, 0]),
                               ValueError, "t must be 3 numbers"),
    "make_scene_true_seed": (lambda: dg.make_scene("room", True), TypeError,
                             "seed must be a whole number, got bool True"),
    "make_scene_nan_seed": (lambda: dg.make_scene("room", NAN), ValueError,
                            "seed must be a whole number in 0.."),
    "expose_integer_beyond_a_float": (lambda: dg.expose(RGB, 10**400), ValueError,
                                      "gain must be in .+, got <401-digit integer>"),
    # AttributeErrors ("'NoneType' object has no attribute 'uniform'", "... 'quads'"),
    # numpy's ufunc messages, an IndexError; a shared_points of NaN "cannot convert float NaN
    # to integer", of "no" read as true
    "sample_motion_no_rng": (lambda: dg.sample_motion("general", dg.checker_plane(), None),
                             TypeError, "rng must be a numpy.random.Generator, got NoneType"),
    "sample_motion_text_alpha": (
        lambda: dg.sample_motion("small-parallax", dg.checker_plane(), np.random.default_rng(),
                                 alpha="0.5"), TypeError, "alpha must be a number, got str"),
    "sample_motion_text_flag": (
        lambda: dg.sample_motion("general", dg.checker_plane(), np.random.default_rng(),
                                 same_intrinsics="no"), TypeError, "same_intrinsics must be True"),
    "median_depth_no_scene": (lambda: dg.median_depth(None, K, (64, 48)), TypeError,
                              "scene must be a Scene, got NoneType"),
    "warp_pair_no_focal_factor": (
        lambda: dg.warp_pair(RGB, dg.intrinsics((16, 16), 60.0), np.eye(3), focal_factor=None),
        TypeError, "focal_factor must be a number, got NoneType"),
    "box_quads_no_size": (lambda: dg.box_quads(np.random.default_rng(), [0, 0, 5], None, 0.0),
                          TypeError, "size is required"),
    "box_quads_text_yaw": (lambda: dg.box_quads(np.random.default_rng(), [0, 0, 5], [1, 1, 1],
                                                "30"), TypeError, "yaw_deg must be a number"),
    "photo_texture_no_width": (lambda: dg.photo_texture(np.random.default_rng(), None, 64),
                               TypeError, "texture width must be a whole number, got NoneType"),
    "paper_protocol_nan_flag": (lambda: dg.paper_protocol(3, 20, 0.5, 0.5, shared_points=NAN),
                                TypeError, "points must be True or False"),
    "paper_protocol_text_flag": (lambda: dg.paper_protocol(3, 20, 0.5, 0.5, shared_points="no"),
                                 TypeError, "points must be True or False"),
    "paper_protocol_alpha_beyond_a_float": (lambda: dg.paper_protocol(3, 20, 10**400, 0.5),
                                            ValueError, "alpha must be finite"),
}  # fmt: skip


def _pairs_file(tmp_path, field: str):
    path = tmp_path / "pairs.txt"
    path.write_text("a.png b.png 0 0 " + " ".join([field] + ["1"] * 33) + "\n")
    return path


def _file(tmp_path):
    (tmp_path / "taken").write_text("")
    return tmp_path / "taken"


def _full_folder(tmp_path):
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "keep.png").write_text("")
    return tmp_path / "old"


OUTPUT_CASES = {  # name: (call on tmp_path, error type, words of its message)
    "make_dataset_none": (lambda d: dg.make_dataset(None, pairs=1), TypeError, "out_dir"),
    "make_dataset_file": (
        lambda d: dg.make_dataset(_file(d), pairs=1), FileExistsError, "is a file, not a folder",
    ),
    "read_pairs_nan": (lambda d: dg.read_pairs(_pairs_file(d, "nan")), ValueError, "finite"),
    "read_pairs_word": (lambda d: dg.read_pairs(_pairs_file(d, "one")), ValueError, "numbers"),
    # FileNotFoundError and IsADirectoryError: the calibration reader's ValueError now
    "read_pairs_missing": (lambda d: dg.read_pairs(d / "pairs.txt"), ValueError,
                           "pairs file not found: "),
    "read_pairs_folder": (lambda d: dg.read_pairs(d), ValueError, "is not a regular file"),
    "write_pair_none": (lambda d: dg.write_pair(None, d, "p"), TypeError, "RenderedPair"),
    "write_pair_name_with_folder": (
        lambda d: dg.write_pair(dg.make_pair(size=(16, 16), supersample=1), d, "../p"),
        ValueError, "file name",
    ),
    "tripod_into_full_folder": (
        lambda d: dg.render_tripod_then_move(_full_folder(d), size=(16, 16)),
        FileExistsError, "holding files",
    ),
    "tripod_fractional_size": (
        lambda d: dg.render_tripod_then_move(d / "new", size=(16.5, 16)), ValueError, "width",
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", list(OUTPUT_CASES), ids=list(OUTPUT_CASES))
def test_a_bad_output_or_input_file_is_an_error_that_writes_nothing(case, tmp_path):
    call, error, words = OUTPUT_CASES[case]
    with pytest.raises(error, match=words):
        call(tmp_path)
    assert not (tmp_path / "new").exists() and not (tmp_path / "p_1.png").exists()
    if (tmp_path / "old").exists():
        assert [p.name for p in (tmp_path / "old").iterdir()] == ["keep.png"]


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_a_bad_argument_is_an_error_naming_it(case):
    call, error, words = CASES[case]
    with pytest.raises(error, match=words.replace("(", r"\(").replace(")", r"\)")):
        call()


def test_good_arguments_still_give_what_they_gave():
    assert dg.make_pair(size=(64.0, 48), seed=3).image1.shape[:2] == (48, 64)
    given = dg.given_intrinsics(K, 1.03, (64, 48))
    np.testing.assert_allclose(given[:2, :2], K[:2, :2] * 1.03)
    np.testing.assert_allclose(given[:2, 2], [31.5, 23.5])
    R = dg.look_at([0, 0, 0], [0, 0, 5])
    np.testing.assert_allclose(R, np.eye(3), atol=1e-12)
    assert dg.jpeg_roundtrip(RGB, 90).shape == RGB.shape
    assert len(dg.tripod_then_move_poses(2, 3)) == 5
    assert dg.pairs_line("a.png", "b.png", K, K, np.eye(3), np.ones((3, 1))).split()[-4:] == [
        "0.000000000000", "0.000000000000", "0.000000000000", "1.000000000000"]  # fmt: skip
