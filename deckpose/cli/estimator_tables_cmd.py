"""``deckpose estimator-tables``: the thesis's tables for several estimators side by side."""

from __future__ import annotations

import argparse
from pathlib import Path

from deckpose.cli.common_options import (
    HelpFormatter,
    add_output,
    add_progress,
    add_workers,
    workers,
)
from deckpose.cli.console import wrote


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "estimator-tables",
        help="the thesis's tables 4.2-4.13 and 4.15 for several estimators side by side",
        description=(
            "Run the thesis's experiment (eq. 4.1 noise) for each estimator with identical noise draws and "
            "write the comparison into OUTPUT/estimators.md (between marker comments) and "
            "OUTPUT/estimators_thesis_tables.csv."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("--method", dest="methods", action="append", default=None, metavar="A,B",
                   help="estimators to compare, comma-separated as in 'pipeline' (default: thesis)")
    # the old spelling, a space-separated list: still parsed, not listed
    p.add_argument("--methods", dest="methods", nargs="+", action="extend", help=argparse.SUPPRESS)
    p.add_argument("--repetitions", type=int, default=20, help="passes over the 495-sample series per cell")
    p.add_argument("--seed", type=int, default=20221, help="seed of the noise draws (recorded with the tables)")
    add_workers(p, "Monte Carlo")
    add_output(p, "output folder; its estimators.md gets (or has replaced) the tables' section "
                  "(the committed report: -o reports)", default=Path("runs/estimator_tables"))
    add_progress(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from deckpose.errors import ConfigError
    from deckpose.estimate import registry
    from deckpose.evaluate.estimator_tables import write_estimator_tables

    args.methods = [m.strip() for item in (args.methods or ["thesis"]) for m in item.split(",") if m.strip()]
    unknown = [m for m in args.methods if m not in registry.names()]
    if unknown:
        raise ConfigError(f"unknown estimator(s) {unknown}; choose from {registry.names()}")
    if args.repetitions < 1:
        raise ConfigError("--repetitions must be at least 1")
    bar = tqdm(desc="estimator tables", unit="cell", disable=True if args.no_progress else None)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    md = write_estimator_tables(args.output, args.methods, args.repetitions, args.seed, workers(args), progress)
    bar.close()
    wrote(args, md, f"wrote {md}")
    return 0
