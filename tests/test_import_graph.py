"""The library's modules import one another without cycles, function-level imports included.

A function-level import hides a cycle from the interpreter but not from the design: the
candidate search imported the gain estimate inside a function because gain -> cog ->
candidates -> gain was a cycle. The graph here is read from the source (``ast``), one
node per module, an edge per ``import``/``from ... import`` of a library module anywhere in
it (``if TYPE_CHECKING:`` blocks aside: they run only under a type checker).
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: Source folder -> the package it installs as (pyproject's package-dir).
PACKAGES = {"deckpose": "deckpose", "render": "deckpose.render", "detect": "deckpose.detect",
            "estimate": "deckpose.estimate", "evaluate": "deckpose.evaluate"}


def _modules() -> dict[str, Path]:
    out = {}
    for folder, pkg in PACKAGES.items():
        for path in (REPO / folder).rglob("*.py"):
            parts = path.relative_to(REPO / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join((pkg, *parts))] = path
    return out


def _imported(tree: ast.AST, known: set[str]) -> set[str]:
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, ast.ImportFrom) and child.module:
                found.add(child.module)
                found.update(f"{child.module}.{a.name}" for a in child.names)
            elif isinstance(child, ast.Import):
                found.update(a.name for a in child.names)
            visit(child)

    visit(tree)
    return found & known


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def dfs(u: str, path: list[str]) -> None:
        state[u] = 1
        path.append(u)
        for v in sorted(graph[u]):
            if state.get(v) == 1:
                cycles.append([*path[path.index(v):], v])
            elif v not in state:
                dfs(v, path)
        path.pop()
        state[u] = 2

    for m in sorted(graph):
        if m not in state:
            dfs(m, [])
    return cycles


def test_the_graph_is_read_from_every_module():
    mods = _modules()
    assert {"deckpose.detect.candidates", "deckpose.estimate.batch", "deckpose.render.scene"} <= set(mods)
    graph = {m: _imported(ast.parse(p.read_text()), set(mods)) - {m} for m, p in mods.items()}
    assert "deckpose.detect.gain" in graph["deckpose.detect.candidates"]  # an edge it must see


def test_no_import_cycles_among_library_modules():
    mods = _modules()
    graph = {m: _imported(ast.parse(p.read_text()), set(mods)) - {m} for m, p in mods.items()}
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c", "a"]]


def test_only_the_run_folder_module_names_the_run_folders_files():
    # One owner of the run-folder contract (deckpose/run_folder.py): the render stage, the
    # synthetic dataset writer, detect, estimate and evaluate reach its files through it.
    owned = {"frames.parquet", "beacons.parquet", "manifest.json", "log.mcap",
             "deckpose-dataset/1", "deckpose-detections/1"}
    found = []
    for path in _modules().values():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and node.value in owned:
                found.append(f"{path.relative_to(REPO)}:{node.lineno} {node.value!r}")
    assert found and all(f.startswith("deckpose/run_folder.py:") for f in found), found


def test_no_private_name_is_imported_from_another_module():
    # library modules and the benchmarks alike (a benchmark broke when a private name moved)
    found = []
    for path in [*_modules().values(), *sorted((REPO / "benchmarks").glob("*.py"))]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("deckpose"):
                found += [f"{path.relative_to(REPO)}: {node.module}.{a.name}" for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
    assert found == []
