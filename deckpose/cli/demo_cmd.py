"""``deckpose demo``: the main job end to end on the embedded default."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: "argparse._SubParsersAction[argparse.ArgumentParser]") -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job end to end on the embedded default (what the README's first command runs)",
        description=(
            "Reproduce the thesis's error tables at reduced scale with the embedded motion series "
            "and the faithful thesis estimator, and write the report into the output folder."
        ),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("-o", "--output", type=Path, default=Path("runs/demo"), help="output folder")
    p.add_argument("--repetitions", type=int, default=20, help="thesis-table repetitions (500 = full scale)")
    p.add_argument("--seed", type=int, default=20221, help="random seed")
    p.add_argument("--workers", type=int, default=0, help="worker processes (0 = one per core)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from deckpose.evaluate.thesis_tables import ThesisTablesConfig, cell_specs, run_thesis_tables

    out = Path(args.output)
    print(f"[1/1] thesis tables 4.2-4.15, {args.repetitions} x 495 images per cell -> {out}")
    config = ThesisTablesConfig(repetitions=args.repetitions, seed=args.seed, workers=args.workers)
    bar = tqdm(total=len(cell_specs()), desc="thesis tables", unit="cell", disable=None)
    md = run_thesis_tables(config, out, lambda done, total: bar.update(done - bar.n))
    bar.close()
    print(f"done. report: {md}")
    return 0
