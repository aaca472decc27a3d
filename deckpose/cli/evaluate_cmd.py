"""``deckpose evaluate`` and ``deckpose report``: errors, tables, MCAP log and report of a run."""

from __future__ import annotations

import argparse
from pathlib import Path

from deckpose.cli.common_options import (
    HelpFormatter,
    add_progress,
    add_scheduler,
    add_workers,
    done_of_total,
    frame_bar,
    workers,
)
from deckpose.cli.console import wrote


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "evaluate",
        help="join ground truth, detections and estimates of a run into errors, tables and an MCAP log",
        description=(
            "Read RUN (a rendered dataset with RUN/detections/*.parquet and RUN/estimates/*.parquet) and "
            "write RUN/evaluation/errors.parquet (per frame: pose errors, centroid errors, ok flags, sigmas), "
            "RUN/evaluation/resolution_tables.{md,csv} (thesis-format tables per detector x estimator x "
            "resolution), RUN/log.mcap and RUN/foxglove_layout.json (open the log in Foxglove and import the layout)."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("run", type=Path, help="run folder")
    p.add_argument("--no-mcap", action="store_true", help="skip the MCAP log")
    from deckpose.preview import PREVIEW_PX

    p.add_argument("--preview-px", type=int, default=PREVIEW_PX,
                   help="long side of the image previews in the log (<= 4096); at the default the render "
                        "stage's previews are used, another size decodes every frame again")
    add_workers(p, "evaluation (Cramér-Rao bounds and the log's messages, by chunks of frames; the files "
                   "do not depend on it)", zero="in this process")
    add_scheduler(p, "the Cramér-Rao bounds (the log's messages, which read the previews, stay on --workers)")
    add_progress(p)
    p.set_defaults(func=run_evaluate)
    r = sub.add_parser(
        "report",
        help="write a Markdown report with plots for an evaluated run",
        description="Write RUN/report/report.md with figures under RUN/report/figures (needs 'deckpose evaluate RUN' first).",
        formatter_class=HelpFormatter,
    )
    r.add_argument("run", type=Path, help="run folder")
    add_progress(r)
    r.set_defaults(func=run_report)


def run_evaluate(args: argparse.Namespace) -> int:
    from deckpose.evaluate.run import evaluate_run
    from deckpose.output_folder import claim_output
    from deckpose.run_folder import run_paths

    n_workers = workers(args)  # a bad count is refused before any work
    run = run_paths(args.run)
    if run.root.is_dir():
        claim_output(run.root, what="evaluate")
    # (the recorded command leaves out --workers and --scheduler: the log does not depend on them)
    command = ["deckpose", "evaluate", str(args.run), *(["--no-mcap"] if args.no_mcap else []),
               "--preview-px", str(args.preview_px)]
    with frame_bar("evaluate", enabled=not args.no_progress) as bar:
        paths = evaluate_run(run, mcap=not args.no_mcap, preview_px=args.preview_px, command=command,
                             progress=done_of_total(bar), workers=n_workers, scheduler=args.scheduler)
    wrote(args, paths["errors"], "\n".join(f"{k}: {v}" for k, v in paths.items()))
    return 0


def run_report(args: argparse.Namespace) -> int:
    from deckpose.evaluate.report import write_report
    from deckpose.output_folder import claim_output
    from deckpose.run_folder import run_paths

    run = run_paths(args.run)
    if run.root.is_dir():
        claim_output(run.root, what="report")
    with frame_bar("report", enabled=not args.no_progress, unit="figure") as bar:
        md = write_report(run, progress=done_of_total(bar))
    wrote(args, md, f"report: {md}")
    return 0
