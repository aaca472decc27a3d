"""``deckpose painted-ring``: the painted ring's edges and the pose from them, for a rendered run."""

from __future__ import annotations

import argparse

from deckpose.cli.console import say, wrote


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "painted-ring",
        help="detect a painted ring's edges and estimate the deck pose from them",
        description=(
            "For every frame of RUN (a dataset rendered with a painted_ring: section), find the "
            "painted ring's inner and outer edges to sub-pixel accuracy, fit their ellipses, find "
            "the bow mark, and estimate the deck pose from the edge points (camera attitude known). "
            "Writes RUN/detections/ring-edges.parquet, RUN/estimates/ring-edges--painted-ring.parquet "
            "(read by 'deckpose evaluate') and its .bound.parquet (the image-derived bound)."
        ),
    )
    p.add_argument("run", metavar="RUN", help="a dataset folder rendered with painted_ring:")
    p.add_argument("--centre-disc", action="store_true",
                   help="also fit the centre disc's edge: it makes the tilt first order (a 1.6-1.8x lower bound); "
                        "a frame keeps it only where its pose agrees with the ring's (a chi-square test, "
                        "recorded as disc_check_chi2)")
    p.add_argument("--strict", action="store_true",
                   help="exit 4 when any frame failed (default: 0 when some succeeded, 3 when none did)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from deckpose.cli.exit_codes import frames_exit_code
    from deckpose.painted_ring_run import painted_ring_run
    from deckpose.tables import read_table

    res = painted_ring_run(args.run, progress=not args.no_progress, centre_disc=args.centre_disc)
    wrote(args, res.estimates, res.summary())
    est = read_table(res.estimates, "estimates")
    for r in est.itertuples():
        if not r.ok:
            say(args, f"  frame {r.frame_id}: {r.reason}")
    return frames_exit_code(res.n_frames, res.n_ok, strict=args.strict)
