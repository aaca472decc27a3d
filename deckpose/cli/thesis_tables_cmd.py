"""``deckpose thesis-tables``: regenerate the thesis's Tables 4.2-4.15."""

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
        "thesis-tables",
        help="reproduce the thesis's error tables 4.2-4.15 (Monte Carlo)",
        description=(
            "Run the thesis's chapter-4 experiment (eq. 4.1 noise on the 495-sample motion series, "
            "4/8/16/64 MP x 8/6/4 px x heights 20-80) with the faithful thesis estimator and write "
            "thesis_tables.md, thesis_tables.csv and a manifest, each cell as ours / thesis / ratio. "
            "Full scale (500 repetitions, ~15 million estimates) takes a few minutes on 2 cores."
        ),
        formatter_class=HelpFormatter,
    )
    # a folder of its own by default: -o reports would replace the committed tables of a clone
    add_output(p, "output folder; -o reports replaces the committed reports/thesis_tables.*",
               default=Path("runs/thesis_tables"))
    p.add_argument("--repetitions", type=int, default=500, help="passes over the 495-sample series per cell")
    p.add_argument("--seed", type=int, default=20221, help="random seed (recorded in the manifest)")
    add_workers(p, "Monte Carlo")
    add_progress(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from deckpose.evaluate.thesis_tables import ThesisTablesConfig, cell_specs, run_thesis_tables

    config = ThesisTablesConfig(repetitions=args.repetitions, seed=args.seed, workers=workers(args))
    bar = tqdm(total=len(cell_specs()), desc="thesis tables", unit="cell",
               disable=True if args.no_progress else None)

    def progress(done: int, total: int) -> None:
        bar.update(done - bar.n)

    md = run_thesis_tables(config, args.output, progress)
    bar.close()
    wrote(args, md, f"wrote {md} (and thesis_tables.csv, thesis_tables.manifest.json)")
    return 0
