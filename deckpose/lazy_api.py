"""A package's API imported on first use (PEP 562), so that importing the package stays cheap.

A stage package lists its API in ``__all__`` and, in ``_API``, the module each name
lives in; ``__getattr__, __dir__ = lazy_api(__name__, _API)`` imports the owning module
the first time a name is asked for (``from deckpose.estimate import estimate_run``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

__all__ = ["lazy_api"]


def lazy_api(package: str, api: Mapping[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package`` for the names of ``api``.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (for the error message).
    api : mapping of str to str
        Each public name and the module that defines it.

    Returns
    -------
    getattr, dir : callables
        ``getattr(name)`` imports and returns ``name`` from its module (AttributeError for a
        name not in ``api``); ``dir()`` lists the names.
    """

    def __getattr__(name: str) -> object:
        try:
            module = api[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        return getattr(importlib.import_module(module), name)

    def __dir__() -> list[str]:
        return sorted(api)

    return __getattr__, __dir__
