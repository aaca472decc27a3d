"""The independent spot generator (``benchmarks/independent_spots.py``), and any benchmark, loaded as a module for tests.

It lives with the benchmarks (it is not part of the package); the tests that judge the
detectors on frames the project did not render import it from here.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module ``name`` (loaded once): the benchmarks are not a package."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, REPO / "benchmarks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def load_independent_generator() -> ModuleType:
    """``benchmarks/independent_spots.py`` as the module ``independent_spots`` (loaded once)."""
    return load_benchmark("independent_spots")
