"""Estimation stage: ship attitude and position from identified beacon detections."""

from typing import TYPE_CHECKING

__all__ = [
    "EstimateOptions",
    "EstimateRunResult",
    "MethodSpec",
    "estimate_batch",
    "estimate_frames",
    "estimate_run",
    "estimate_table",
    "get",
    "names",
    "parse_method",
    "register",
    "run_estimator",
]

#: Where each name of the stage API lives.
_API: dict[str, str] = {
    "EstimateOptions": "deckpose.estimate.registry",
    "MethodSpec": "deckpose.estimate.registry",
    "parse_method": "deckpose.estimate.registry",
    "register": "deckpose.estimate.registry",
    "names": "deckpose.estimate.registry",
    "get": "deckpose.estimate.registry",
    "estimate_batch": "deckpose.estimate.batch",
    "run_estimator": "deckpose.estimate.batch",
    "EstimateRunResult": "deckpose.estimate.run",
    "estimate_frames": "deckpose.estimate.run",
    "estimate_run": "deckpose.estimate.run",
    "estimate_table": "deckpose.estimate.run",
}

if TYPE_CHECKING:  # the same names for type checkers (at run time __getattr__ imports them)
    from deckpose.estimate.batch import estimate_batch, run_estimator
    from deckpose.estimate.registry import (
        EstimateOptions,
        MethodSpec,
        get,
        names,
        parse_method,
        register,
    )
    from deckpose.estimate.run import (
        EstimateRunResult,
        estimate_frames,
        estimate_run,
        estimate_table,
    )


def __getattr__(name: str) -> object:
    """The stage API, imported on first use (so that ``import deckpose.estimate`` stays cheap)."""
    import importlib

    try:
        module = _API[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted(__all__)
