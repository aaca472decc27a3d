"""Each stage package states its API (``__all__``) and imports it only when used."""

from __future__ import annotations

import importlib
import subprocess
import sys
import types

import pytest

STAGES = ["deckpose.render", "deckpose.detect", "deckpose.estimate", "deckpose.evaluate"]


@pytest.mark.parametrize("name", STAGES)
def test_every_name_of_the_stage_api_resolves_to_what_its_module_defines(name):
    pkg = importlib.import_module(name)
    assert pkg.__all__ and sorted(pkg.__all__) == sorted(pkg._API)
    for attr in pkg.__all__:
        obj = getattr(pkg, attr)
        assert not isinstance(obj, types.ModuleType), f"{name}.{attr} is a module, not the API's {attr}"
        assert obj is getattr(importlib.import_module(pkg._API[attr]), attr)
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        _ = pkg.nothing_here


def test_the_stage_entry_points_import_from_their_packages():
    from deckpose.detect import detect_run
    from deckpose.estimate import estimate_run
    from deckpose.evaluate import evaluate_run, write_report
    from deckpose.render import render_dataset

    assert all(callable(f) for f in (render_dataset, detect_run, estimate_run, evaluate_run, write_report))


def test_importing_a_stage_package_imports_none_of_its_modules():
    code = ("import sys, deckpose.render, deckpose.detect, deckpose.estimate, deckpose.evaluate; "
            "print(sorted(m for m in sys.modules if m.count('.') >= 2 and m.startswith('deckpose.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out


@pytest.mark.parametrize("name", STAGES)
def test_type_checkers_see_the_same_stage_api(name):
    """The package's ``if TYPE_CHECKING:`` imports (what pyright sees) are its ``_API``."""
    import ast

    pkg = importlib.import_module(name)
    with open(pkg.__file__, encoding="utf-8") as fh:
        tree = ast.parse(fh.read())
    seen: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.module
                seen.update({alias.name: imp.module for alias in imp.names})
    assert seen == pkg._API
