"""``deckpose track``: a deck-motion filter over a run's per-frame estimates, with prediction ahead."""

from __future__ import annotations

import argparse
from pathlib import Path

from deckpose.cli.common_options import HelpFormatter, add_progress, frame_bar
from deckpose.cli.console import say, wrote
from deckpose.shell_command import deckpose_command


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "track",
        help="filter a run's per-frame estimates over time and predict deck roll, pitch and heave ahead",
        description=(
            "Run a Kalman filter over RUN/estimates/DETECTOR--METHOD.parquet, one time sequence at a time "
            "(each camera x height x lighting of the render plan, in capture-time order): roll, pitch and "
            "heave as banks of wave-frequency oscillators, yaw, surge, sway and the camera's height as "
            "near-constant-velocity channels. Each frame's estimate updates the filter with its full "
            "covariance; frames with ok = false are predicted only, and an estimate beyond the chi-square "
            "gate is rejected as an outlier. Writes RUN/tracks/DETECTOR--METHOD--TRACKER.parquet (filtered "
            "pose, heave, heave rate, sigmas, covariance and the landing-window indicator per frame), "
            ".predictions.parquet (roll, pitch, heave and heave rate predicted at each horizon, with sigmas) "
            "and .run.json (the resolved tracker config and counts)."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("run", type=Path, help="run folder with estimates (deckpose estimate --run RUN)")
    # the default is resolved in run() (the tracking package imports scipy: every command's parser paid it)
    p.add_argument("--method", default=None,
                   help="the tracker: wave-bank (default), the wave-frequency oscillator-bank Kalman filter "
                        "(the estimator whose estimates are tracked is --estimates)")
    p.add_argument("--detector", default=None, help="whose estimates (default: the run's only estimates table)")
    p.add_argument("--estimates", default=None, metavar="METHOD",
                   help="which estimator's estimates, with its variant (pnp, conic+refine; default: the run's only one)")
    p.add_argument("--config", type=Path, default=None,
                   help="tracker config YAML (model, landing, gate_probability, reacquire_after, horizons_s; "
                        "configs/track/wave_bank.yaml lists them; default: the built-in values)")
    p.add_argument("--name", default=None,
                   help="the track's name in the run folder, tracks/DETECTOR--METHOD--NAME.parquet (default: the "
                        "tracker's, wave-bank): give each config its own to keep their tracks side by side")
    p.add_argument("--horizons", default=None, metavar="S,S,...",
                   help="prediction horizons in seconds, comma list (overrides the config's horizons_s)")
    add_progress(p)
    p.set_defaults(func=run)


def _horizons(text: str) -> tuple[float, ...]:
    from deckpose.errors import ConfigError

    try:
        return tuple(float(s) for s in text.split(",") if s.strip())
    except ValueError:
        raise ConfigError(f"--horizons: expected seconds as a comma list (0.5,1,2), got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from deckpose.errors import ConfigError
    from deckpose.estimate.registry import names as estimator_names
    from deckpose.output_folder import claim_output
    from deckpose.run_folder import read_frames, run_paths
    from deckpose.tracking.config import TRACKERS, load_track_config
    from deckpose.tracking.run import track_run

    if args.method is None:
        args.method = TRACKERS[0]
    if args.method not in TRACKERS:
        hint = (f"; --method picks the tracker, the estimator is --estimates {args.method}"
                if args.method.split("+")[0] in estimator_names() else "")
        raise ConfigError(f"unknown tracker {args.method!r} (choose from {', '.join(TRACKERS)}){hint}")
    config = load_track_config(args.config)
    if args.horizons is not None:
        config = dataclasses.replace(config, horizons_s=_horizons(args.horizons))
    run_folder = run_paths(args.run)
    n_frames = len(read_frames(run_folder))  # a missing run is one line before the lock
    claim_output(run_folder.root, what="track")
    command = ["deckpose", "track", str(args.run), "--method", args.method,
               *(["--detector", args.detector] if args.detector else []),
               *(["--estimates", args.estimates] if args.estimates else []),
               *(["--config", str(args.config)] if args.config else []),
               *(["--horizons", args.horizons] if args.horizons else []),
               *(["--name", args.name] if args.name else [])]
    with frame_bar(f"track ({args.method})", enabled=not args.no_progress) as bar:
        bar.total = n_frames
        res = track_run(run_folder.root, config, tracker=args.method, detector=args.detector,
                        method=args.estimates, command=command, progress=bar.update, name=args.name)
    wrote(args, res.path, res.summary())
    say(args, f"predictions: {res.predictions_path}")
    say(args, "to play it in Foxglove (filtered and predicted decks, roll against time): "
          + deckpose_command("evaluate", run_folder.root))
    return 0
