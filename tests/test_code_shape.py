"""The shape of the source: short functions, ``estimate_pair`` as its stages, no import cycle.

Read from the source files with :mod:`ast`: the import graph counts every import of a module of
``ppo_cv`` or ``ppo_cv.cli``, at the top of a module or inside a function.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"ppo_cv": ROOT / "ppo_cv", "ppo_cv.cli": ROOT / "cli"}
MAX_FUNCTION_LINES = 100
MAX_ESTIMATE_PAIR_LINES = 60


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the packages but their ``__init__``."""
    return {
        f"{package}.{path.stem}": path
        for package, folder in PACKAGES.items()
        for path in sorted(folder.glob("*.py"))
        if path.stem != "__init__"
    }


def _functions(path: Path):
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _imported(module: str, path: Path, known: set[str]) -> set[str]:
    """The modules of ``known`` that ``module`` imports, relatively or absolutely."""
    package = module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}" if base else parent
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return (found & known) - {module}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph``, as the modules along it, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


@pytest.mark.parametrize("path", sorted((ROOT / "ppo_cv").glob("*.py")), ids=lambda p: p.name)
def test_no_function_is_longer_than_100_lines(path):
    long = {
        node.name: node.end_lineno - node.lineno + 1
        for node in _functions(path)
        if node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    }
    assert not long, f"{path.name}: functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_estimate_pair_reads_as_its_stages():
    (node,) = [f for f in _functions(ROOT / "ppo_cv" / "pipeline.py") if f.name == "estimate_pair"]
    docstring = node.body[0]
    assert isinstance(docstring, ast.Expr) and isinstance(docstring.value, ast.Constant)
    assert node.end_lineno - node.lineno + 1 < MAX_ESTIMATE_PAIR_LINES  # docstring included


def test_no_import_cycle_in_ppo_cv_or_its_cli():
    modules = _modules()
    graph = {name: _imported(name, path, set(modules)) for name, path in modules.items()}
    assert graph["ppo_cv.pipeline"] >= {"ppo_cv.ppo", "ppo_cv.result"}  # the graph sees imports
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_the_cycle_finder_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None
