"""``docs/decision.md`` follows the constants of the motion decision.

Each module constant of the decision's modules has one row in the page's constant tables, its
value written as the code writes it (``ast.unparse``); a constant defined as another one also
gives that one's value in brackets. Every test, report and script the page cites exists.
"""

from __future__ import annotations

import ast
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "decision.md"
MODULES = {
    "motion_model": None,
    "rotation": None,
    "parallax": None,
    "model_selection": None,
    "photometric": None,
    "significance": None,
    "plane": None,
    "pipeline": None,
    "guessed_camera": None,
    "ppo": ("DEFAULT_PRI_THRESHOLD",),
    "refine": ("LEVERAGE_MAX",),
    "consensus": None,
    "options": None,
    "homography": ("MIRROR_MIN_INLIERS",),
    "valley": None,
    "rotation_choice": ("SETTLED_DEVIATIONS",),
}
CONSTANT = re.compile(r"_?[A-Z][A-Z0-9_]*")
ROW = re.compile(r"^\| `(\w+)\.(\w+)` \| (.*?) \|")
CITED_TEST = re.compile(r"`(tests/\w+\.py)::(\w+)`")
CITED_FILE = re.compile(r"`((?:docs|benchmarks|tests)/[\w/]+\.(?:md|py|json))`")


def module_constants(module: str) -> dict[str, ast.expr]:
    """Module-level constants (upper-case names, private ones included) and their values."""
    path = Path(importlib.util.find_spec(f"ppo_cv.{module}").origin)
    constants = {}
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        else:
            continue
        for target in targets:
            if isinstance(target, ast.Name) and CONSTANT.fullmatch(target.id):
                constants[target.id] = value
    wanted = MODULES[module]
    return {k: v for k, v in constants.items() if wanted is None or k in wanted}


def section(text: str, title: str) -> str:
    """The lines of the ``## title`` section of ``text``."""
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start : None if end < 0 else end]


def table_rows(text: str) -> dict[tuple[str, str], list[str]]:
    """Value cells of the constant tables, by ``(module, name)``; a name listed twice has two."""
    rows: dict[tuple[str, str], list[str]] = {}
    for line in section(text, "Every constant").splitlines():
        match = ROW.match(line)
        if match:
            rows.setdefault((match[1], match[2]), []).append(match[3])
    return rows


def expected_value(name: str, constants: dict[str, ast.expr]) -> str:
    value = constants[name]
    written = f"`{ast.unparse(value)}`"
    if isinstance(value, ast.Name) and value.id in constants:
        written += f" ({ast.unparse(constants[value.id])})"
    return written


def mismatches(module: str, text: str) -> list[str]:
    """What the page's tables say wrongly or not at all about ``module``'s constants."""
    constants = module_constants(module)
    rows = {name: cells for (mod, name), cells in table_rows(text).items() if mod == module}
    problems = [f"{module}.{name}: no row" for name in constants if name not in rows]
    problems += [f"{module}.{name}: no such constant" for name in rows if name not in constants]
    for name in sorted(set(rows) & set(constants)):
        expected = expected_value(name, constants)
        if rows[name] != [expected]:
            problems.append(f"{module}.{name}: page says {rows[name]}, code {expected}")
    return problems


@pytest.mark.parametrize("module", sorted(MODULES))
def test_every_constant_has_its_row_with_the_code_value(module):
    assert mismatches(module, DOC.read_text(encoding="utf-8")) == []


def test_no_row_names_a_module_outside_the_checked_ones():
    assert {module for module, _ in table_rows(DOC.read_text(encoding="utf-8"))} <= set(MODULES)


@pytest.mark.parametrize(
    ("edit", "problem"),
    [
        (("SHARE` | `0.2` |", "SHARE` | `0.25` |"), "MAX_COHERENT_SHARE: page says"),
        (("| `rotation.FOCAL_PRIOR` |", "| `rotation.FOCAL_PRIOR_OLD` |"), "PRIOR: no row"),
        (("| `rotation.FOCAL_PRIOR` |", "| `rotation.FOCAL_PRIOR_OLD` |"), "no such constant"),
        (("`NEGLIGIBLE_PARALLAX` (0.003)", "`NEGLIGIBLE_PARALLAX`"), "GAP: page says"),
        (("| `photometric._CONVERGED` |", "| `photometric._converged` |"), "_CONVERGED: no row"),
    ],
)
def test_a_page_that_lags_the_code_is_caught(edit, problem):
    text = DOC.read_text(encoding="utf-8")
    assert edit[0] in text
    edited = text.replace(edit[0], edit[1], 1)
    found = [p for module in MODULES for p in mismatches(module, edited)]
    assert any(problem in p for p in found), found


def test_every_public_constant_takes_its_place_in_the_order_of_the_tests():
    order = section(DOC.read_text(encoding="utf-8"), "The tests in the order they run")
    missing = [
        f"{module}.{name}"
        for module in MODULES
        for name in module_constants(module)
        if not name.startswith("_") and not re.search(rf"\b{name}\b", order)
    ]
    assert missing == []


def test_cited_tests_reports_and_scripts_exist():
    text = DOC.read_text(encoding="utf-8")
    cited = CITED_TEST.findall(text)
    assert len(cited) > 20
    missing = [path for path in CITED_FILE.findall(text) if not (ROOT / path).is_file()]
    for path, name in cited:
        file = ROOT / path
        defined = (
            {n.name for n in ast.parse(file.read_text(encoding="utf-8")).body
             if isinstance(n, ast.FunctionDef)}
            if file.is_file()
            else set()
        )  # fmt: skip
        if name not in defined:
            missing.append(f"{path}::{name}")
    assert missing == []
