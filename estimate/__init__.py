"""Estimation stage: ship attitude and position from identified beacon detections."""

from typing import TYPE_CHECKING

from deckpose.lazy_api import lazy_api

__all__ = [
    "EstimateOptions",
    "EstimateRunResult",
    "MethodSpec",
    "estimate_batch",
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
        estimate_run,
        estimate_table,
    )

__getattr__, __dir__ = lazy_api(__name__, _API)
