"""``deckpose bench-detectors``: centroid accuracy, recall, identification and speed."""

from __future__ import annotations

import argparse

from deckpose.cli.common_options import add_output
from deckpose.cli.console import wrote
from deckpose.cli.detect_cmd import add_detector_arguments


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "bench-detectors",
        help="benchmark the beacon detectors on a dataset with ground truth",
        description=(
            "Run every detector (or --detectors) on DATASET and compare with its beacons.parquet: "
            "centroid error (RMS, bias, 95th percentile), recall, precision, identification "
            "accuracy and time per frame, per detector x resolution x height, beside the "
            "centroid Cramér–Rao bound "
            "where the dataset declares its noise model, with a bootstrap interval on RMS/CRB and "
            "a ranking of the detectors. Writes a Markdown report, CSVs and plots."
        ),
    )
    p.add_argument("dataset", metavar="DATASET", help="dataset folder (deckpose-dataset/1)")
    p.add_argument("--detectors", help="comma-separated detector names (default: all registered)")
    add_output(p, "report folder (default DATASET/bench-detectors)", metavar="DIR", dest="out")
    p.add_argument(
        "--threshold-sigma", type=float, default=6.0, help="detection threshold (sigmas)"
    )
    add_detector_arguments(p)
    p.add_argument("--note", default="", help="a line of text for the top of the report")
    p.add_argument(
        "--seed", type=int, default=0,
        help="seed of the bootstrap intervals on RMS/CRB (recorded in the report)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from deckpose.detect import registry
    from deckpose.detect.bench_report import run_benchmark, write_report
    from deckpose.detect.registry import DetectorOptions
    from deckpose.detect.sources import declared_gain, open_dataset

    for mod in args.plugin:
        registry.load_plugin(mod)
    names = args.detectors.split(",") if args.detectors else registry.names()
    for n in names:
        registry.get(n)
    manifest = open_dataset(args.dataset).manifest
    options = DetectorOptions(
        threshold_sigma=args.threshold_sigma,
        gain_dn_per_e=args.gain if args.gain is not None else declared_gain(manifest),
        background_kernel_px=args.background_kernel_px,
        spot_level=args.spot_level,
        significance_sigma=args.significance_sigma,
    )
    tables = run_benchmark(args.dataset, names, options=options, progress=not args.no_progress)
    out = Path(args.out) if args.out else Path(args.dataset) / "bench-detectors"
    md = write_report(
        out,
        tables,
        dataset=str(args.dataset),
        manifest=manifest,
        options=options,
        note=args.note,
        seed=args.seed,
    )
    wrote(args, md, md.read_text() + f"\nreport -> {md}")
    return 0
