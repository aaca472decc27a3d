"""Evaluation stage: errors against ground truth, tables, logs and reports."""

from typing import TYPE_CHECKING

from deckpose.lazy_api import lazy_api

__all__ = [
    "evaluate_run",
    "write_bop",
    "write_coco",
    "write_report",
]

#: Where each name of the stage API lives.
_API: dict[str, str] = {
    "evaluate_run": "deckpose.evaluate.run",
    "write_report": "deckpose.evaluate.report",
    "write_bop": "deckpose.evaluate.export_bop",
    "write_coco": "deckpose.evaluate.export_coco",
}

if TYPE_CHECKING:  # the same names for type checkers (at run time __getattr__ imports them)
    from deckpose.evaluate.export_bop import write_bop
    from deckpose.evaluate.export_coco import write_coco
    from deckpose.evaluate.report import write_report
    from deckpose.evaluate.run import evaluate_run

__getattr__, __dir__ = lazy_api(__name__, _API)
