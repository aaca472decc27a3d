"""``deckpose estimator-tables``: the thesis's tables for several estimators side by side."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: "argparse._SubParsersAction[argparse.ArgumentParser]") -> None:
    p = sub.add_parser(
        "estimator-tables",
        help="the thesis's tables 4.2-4.13 and 4.15 for several estimators side by side",
        description=(
            "Run the thesis's experiment (eq. 4.1 noise) for each estimator with identical noise draws and "
            "write the comparison into OUTPUT/estimators.md (between marker comments) and "
            "OUTPUT/estimators_thesis_tables.csv."
        ),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--methods", nargs="+", default=["thesis"], help="estimators to compare")
    p.add_argument("--repetitions", type=int, default=20, help="passes over the 495-sample series per cell")
    p.add_argument("--seed", type=int, default=20221)
    p.add_argument("--workers", type=int, default=0, help="worker processes (0 = one per core)")
    p.add_argument("-o", "--output", type=Path, default=Path("reports"))
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from deckpose.errors import ConfigError
    from deckpose.estimate import registry
    from deckpose.evaluate.estimator_tables import write_estimator_tables

    unknown = [m for m in args.methods if m not in registry.names()]
    if unknown:
        raise ConfigError(f"unknown estimator(s) {unknown}; choose from {registry.names()}")
    if args.repetitions < 1:
        raise ConfigError("--repetitions must be at least 1")
    bar = tqdm(desc="estimator tables", unit="cell", disable=None)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    md = write_estimator_tables(args.output, args.methods, args.repetitions, args.seed, args.workers, progress)
    bar.close()
    print(f"wrote {md}")
    return 0
