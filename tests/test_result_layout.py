"""``PairResult``: the answer at the top, the rest in nested records, the flat names deprecated.

``tests/data/result_layout.npz`` holds every field, by its flat name, of the demo pair and three
renders (``tests/result_layout.py``). Recorded first with the flat layout of 0.1.0, it showed
the nested records bit for bit equal to it; it is recorded again, on purpose, when a change of
behaviour moves a value (the rotation with the smallest expected error gave every model a
``rotation_sigma_deg``; the refit polishing one window side moved the pure rotation by 1e-6; the
rotation's wider lens box moved the rotation fit's residuals and lens excess, not the answers;
the polish's row sums taken from its normal matrices moved the pure rotation by 1e-10; the
general pose refined on the Huber cost without a radial term moved the demo pair's ``t`` by
3e-6 and the general render's by 4e-4, and their points, deviations and bias with them).
Each field, read through its current path, holds the recorded value (to 1e-9, where another BLAS
may round differently).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import typing
from pathlib import Path

import numpy as np
import pytest
from result_layout import ADDED_FIELDS, FLAT_FIELDS, NO_PLANE, RENDERS, read_renamed, run_case

from ppo_cv.export import result_to_dict
from ppo_cv.result import RENAMED_FIELDS, PairResult

RECORD = Path(__file__).parent / "data" / "result_layout.npz"
CASES = ("demo", *RENDERS)
ANSWER = ("R", "t", "pure_rotation", "model", "rotation_source", "pri", "keypoints1",
          "keypoints2", "matches",
          "inliers", "points3d", "point_matches", "colours")  # fmt: skip


@pytest.fixture(scope="module")
def results() -> dict[str, PairResult]:
    return {case: run_case(case) for case in CASES}


def _recorded(case: str) -> dict[str, object]:
    with np.load(RECORD) as data:
        none = set(data[f"{case}/:none"].tolist())
        return {name: None if name in none else data[f"{case}/{name}"] for name in FLAT_FIELDS}


def _leaf_paths(cls, prefix: str = "") -> list[str]:
    """Dotted paths of the fields of ``cls`` that are not themselves records."""
    paths = []
    hints = {f.name: f.type for f in dataclasses.fields(cls)}
    for name, hint in hints.items():
        record = next((r for r in _RECORDS if hint.split(" |")[0] == r.__name__), None)
        if record is None:
            paths.append(prefix + name)
        else:
            paths.extend(_leaf_paths(record, f"{prefix}{name}."))
    return paths


def _record_classes():
    from ppo_cv import result

    return [getattr(result, name) for name in result.__all__ if dataclasses.is_dataclass(
        getattr(result, name, None))]  # fmt: skip


_RECORDS = _record_classes()


@pytest.mark.parametrize("case", CASES)
def test_every_flat_field_keeps_its_value_under_its_new_path(case, results):
    recorded = _recorded(case)
    for name in FLAT_FIELDS:
        value, old = read_renamed(results[case], name), recorded[name]
        if old is None:
            assert value is None, name
            continue
        value = np.asarray(value)
        assert value.shape == old.shape and value.dtype.kind == old.dtype.kind, name
        if old.dtype.kind == "f":
            np.testing.assert_allclose(value, old, rtol=1e-9, atol=1e-12, err_msg=name)
        else:
            assert np.array_equal(value, old), name


def test_the_renders_cover_the_three_models(results):
    assert {results[case].model for case in RENDERS} == {"general", "plane", "rotation"}
    assert results["rotation"].uncertainty.rotation_tracks > 0
    assert results["planar"].plane is not None and results["general"].plane is None


def test_each_field_lives_in_one_place():
    leaves = _leaf_paths(PairResult)
    assert len(leaves) == len(set(leaves))
    moved = [p for p in leaves if p not in (*ANSWER, "timings")]
    added = [p for p in ADDED_FIELDS.values() if p not in ANSWER]
    assert sorted([*RENAMED_FIELDS.values(), *added]) == sorted(moved)
    assert set(FLAT_FIELDS) == set(RENAMED_FIELDS) | set(ANSWER) | set(ADDED_FIELDS)


@pytest.mark.parametrize("name", sorted(RENAMED_FIELDS))
def test_a_flat_name_warns_with_its_new_path_and_reads_it(name, results):
    for result in (results["planar"], results["general"]):
        with pytest.warns(DeprecationWarning, match=rf"PairResult\.{RENAMED_FIELDS[name]}\b"):
            value = getattr(result, name)
        expected = read_renamed(result, name)
        assert value is expected or (value != value and expected != expected)


def test_flat_names_stay_out_of_dir_and_unknown_names_fail(results):
    result = results["demo"]
    assert not set(RENAMED_FIELDS) & set(dir(result))
    assert {"cameras", "uncertainty", "lens", "evidence", "plane", "timings"} <= set(dir(result))
    with pytest.raises(AttributeError, match="no attribute 'gric'"):
        result.gric  # noqa: B018


def test_no_plane_holds_what_the_flat_fields_said_without_one(results):
    result = results["general"]
    for key, value in NO_PLANE.items():
        with pytest.warns(DeprecationWarning):
            flat = getattr(result, f"plane_{key}")
        assert flat is value or (math.isnan(flat) and math.isnan(value))


def _json_value(data: dict, path: str):
    for part in path.split("."):
        data = data[part]
    return data


@pytest.mark.parametrize("case", ["planar", "rotation"])
def test_the_json_keys_follow_the_python_paths(case, results):
    result = results[case]
    data = json.loads(json.dumps(result_to_dict(result)))
    assert {"R", "t", "pure_rotation", "model", "pri", "timings"} <= set(data)
    for name, path in RENAMED_FIELDS.items():
        if path.startswith("plane.") and result.plane is None:
            assert data["plane"] is None
            continue
        value, shown = read_renamed(result, name), _json_value(data, path)
        if value is None or (isinstance(value, float) and math.isnan(value)):
            assert shown is None or math.isnan(shown), path
        else:
            np.testing.assert_allclose(shown, np.asarray(value, dtype=float), err_msg=path)


def test_the_changelog_lists_every_renamed_field():
    text = (Path(__file__).resolve().parents[1] / "CHANGELOG.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `result\.(\w+)` \| `result\.([\w.]+)` \|$", text, re.M))
    assert rows == RENAMED_FIELDS


def test_the_python_docs_table_names_every_field_of_the_records():
    """``docs/python.md``'s table of ``result.<record>`` paths names each field of the record."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "python.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `result\.([\w.]+)` \| (.*) \|$", text, re.M))
    records = {"cameras", "uncertainty", "lens", "evidence.selection", "evidence.tracks",
               "evidence.significance", "plane"}  # fmt: skip
    assert records <= set(rows)
    for path in records:
        record = _record_type(path)
        missing = [f.name for f in dataclasses.fields(record) if f"`{f.name}`" not in rows[path]]
        assert not missing, (path, missing)


def _record_type(path: str) -> type:
    """The record class at ``path`` below ``PairResult`` (``evidence.tracks``), None left out."""
    first, _, rest = path.partition(".")
    hint = typing.get_type_hints(PairResult)[first]
    kind = typing.get_args(hint)[0] if typing.get_args(hint) else hint
    return typing.get_type_hints(kind)[rest] if rest else kind
