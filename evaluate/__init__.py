"""Evaluation stage: errors against ground truth, tables, logs and reports."""

from typing import TYPE_CHECKING

__all__ = [
    "evaluate_run",
    "write_report",
]

#: Where each name of the stage API lives.
_API: dict[str, str] = {
    "evaluate_run": "deckpose.evaluate.run",
    "write_report": "deckpose.evaluate.report",
}

if TYPE_CHECKING:  # the same names for type checkers (at run time __getattr__ imports them)
    from deckpose.evaluate.report import write_report
    from deckpose.evaluate.run import evaluate_run


def __getattr__(name: str) -> object:
    """The stage API, imported on first use (so that ``import deckpose.evaluate`` stays cheap)."""
    import importlib

    try:
        module = _API[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted(__all__)
