"""``deckpose motion``: generate or read a ship-motion series, write it, plot it.

Sources (the first argument):

* ``thesis``: the thesis's 495-sample closed-form series (``--thesis-table``
  writes it exactly as ``thesis_motion_series.csv``, thesis angles);
* ``regular``: one regular wave through the closed-form model;
* ``sea``: an irregular sea of a given sea state (JONSWAP or Pierson-Moskowitz);
* ``read FILE``: a recorded series (CSV or Parquet).

The output (``-o``, ``.csv`` or ``.parquet``) gets a ``<name>.motion.yaml``
beside it with the resolved parameters and seed.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from deckpose.cli.console import say, wrote
from deckpose.errors import ConfigError

_KNOTS_PER_M_S = 1.94384
#: Keys this command adds to the resolved ``.motion.yaml``; dropped when it is read back with --config.
_METADATA_KEYS = ("source", "angles", "samples")


def register(subparsers: Any) -> None:
    """Add the ``motion`` subcommand."""
    p = subparsers.add_parser(
        "motion", help="generate (thesis / regular / sea state) or read a ship-motion series",
        description=(__doc__ or "").replace("``", ""), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", choices=["thesis", "regular", "sea", "read"], help="where the motion comes from")
    p.add_argument("file", nargs="?", help="input file for 'read' (.csv or .parquet)")
    p.add_argument("-o", "--output", help="write the series here (.csv or .parquet)")
    p.add_argument(
        "--plot",
        help="write a figure of the channels and their spectra here (.png, .jpg, .pdf, .svg)",
    )
    p.add_argument("--radians", action="store_true", help="angle columns in radians (roll_rad, ...) in and out")
    p.add_argument("--thesis-table", action="store_true",
                   help="thesis: write the table exactly as the reference CSV (thesis X-Y-Z angles)")
    g = p.add_argument_group("ship and waves (regular, sea); sea defaults: the SS6 frigate scenario")
    g.add_argument("--config", help="sea: YAML run configuration (schema in deckpose.motion.config); "
                   "flags given on the command line override it")
    g.add_argument("--ship", help="ship preset: ffg7 (default) or thesis")
    g.add_argument("--heading-deg", type=float,
                   help="wave heading relative to the ship: 180 head, 135 bow quartering (default), 90 beam, "
                   "0 following")
    g.add_argument("--speed-kn", type=float, help="ship speed, knots (default 15)")
    g.add_argument("--duration-s", type=float, help="series length, s (default 600)")
    g.add_argument("--dt-s", type=float, help="sample step, s (default 0.1)")
    g.add_argument("--amplitude-m", type=float, default=2.5, help="regular: wave amplitude, m (default 2.5)")
    g.add_argument("--period-s", type=float, default=10.0, help="regular: wave period, s (default 10)")
    g.add_argument("--sea-state", type=int, help="sea: Douglas sea state 1-9 (default 6)")
    g.add_argument("--hs-m", type=float, help="sea: significant wave height (default: the state's most probable)")
    g.add_argument("--tp-s", type=float, help="sea: peak period (default: the state's most probable)")
    g.add_argument("--spectrum", choices=["jonswap", "pm"], help="sea: spectrum shape (default jonswap)")
    g.add_argument("--gamma", type=float, help="sea: JONSWAP peak enhancement (default 3.3)")
    g.add_argument("--components", type=int, help="sea: number of wave components (default 600)")
    g.add_argument("--seed", type=int, help="sea: random seed (default 0)")
    g.add_argument("--yaw-sigma-deg", type=float, help="sea: yaw std, deg (default 1; 0 disables)")
    g.add_argument("--yaw-period-s", type=float, help="sea: yaw period, s (default 30)")
    g.add_argument("--drift-sigma-m", type=float, help="sea: surge/sway drift std, m (default 0.5; 0 disables)")
    g.add_argument("--drift-period-s", type=float, help="sea: surge/sway drift period, s (default 60)")
    g.add_argument("--deck-offset-m", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="sea: deck centre relative to the centre of gravity (x bow, y port, z up), m")
    p.set_defaults(func=run)


def _sea_mapping(args: argparse.Namespace) -> dict[str, Any]:
    """The configuration file (if any) with the flags given on the command line on top."""
    from deckpose.typed_config import load_yaml

    mapping: dict[str, Any] = {}
    if args.config:
        loaded = load_yaml(args.config, "motion configuration")
        if not isinstance(loaded, dict):
            raise ConfigError(f"{args.config}: expected a mapping at the top level")
        mapping = {k: v for k, v in loaded.items() if k not in _METADATA_KEYS}
    sea = dict(mapping.get("sea") or {})
    flags = {"sea_state": args.sea_state, "hs_m": args.hs_m, "tp_s": args.tp_s, "spectrum": args.spectrum,
             "gamma": args.gamma, "heading_deg": args.heading_deg, "speed_kn": args.speed_kn,
             "n_components": args.components,
             "deck_offset_m": None if args.deck_offset_m is None else list(args.deck_offset_m)}
    sea.update({k: v for k, v in flags.items() if v is not None})
    for key, sigma_key, sigma, period in (("yaw", "sigma_deg", args.yaw_sigma_deg, args.yaw_period_s),
                                          ("drift", "sigma_m", args.drift_sigma_m, args.drift_period_s)):
        sub = dict(sea.get(key) or {})
        if sigma is not None:
            sub[sigma_key] = sigma
        if period is not None:
            sub["period_s"] = period
        if sub:
            sea[key] = sub
    mapping["sea"] = sea
    top = {"ship": args.ship, "duration_s": args.duration_s, "dt_s": args.dt_s, "seed": args.seed}
    mapping.update({k: v for k, v in top.items() if v is not None})
    return mapping


def _series(args: argparse.Namespace) -> tuple[Any, dict[str, Any], str]:
    import numpy as np

    from deckpose.motion.closed_form import RegularWave, regular_series
    from deckpose.motion.config import parse_sea_run, sea_run_to_mapping
    from deckpose.motion.irregular import irregular_series
    from deckpose.motion.series import read_series
    from deckpose.motion.ship import ship_preset
    from deckpose.motion.thesis_series import thesis_motion_series

    angles = "rad" if args.radians else "deg"
    if args.source == "read":
        if not args.file:
            raise ConfigError("'deckpose motion read' needs an input FILE (.csv or .parquet)")
        return read_series(args.file, angles=angles), {"source": "read", "file": str(args.file)}, Path(args.file).name
    if args.file:
        raise ConfigError(f"a FILE is only for 'read', not for {args.source!r}")
    if args.source == "thesis":
        return thesis_motion_series(), {"source": "thesis"}, "thesis closed-form series (ZYX angles)"
    duration_s = 600.0 if args.duration_s is None else args.duration_s
    dt_s = 0.1 if args.dt_s is None else args.dt_s
    heading_deg = 135.0 if args.heading_deg is None else args.heading_deg
    speed_kn = 15.0 if args.speed_kn is None else args.speed_kn
    if args.source == "regular":
        ship = ship_preset(args.ship or "ffg7")
        wave = RegularWave(args.amplitude_m, args.period_s, math.radians(heading_deg), speed_kn / _KNOTS_PER_M_S)
        resolved = {"source": "regular", "ship": ship.as_dict(), "amplitude_m": args.amplitude_m,
                    "period_s": args.period_s, "heading_deg": heading_deg, "speed_kn": speed_kn,
                    "duration_s": duration_s, "dt_s": dt_s}
        title = (f"{ship.name}: regular wave a={args.amplitude_m:g} m, T={args.period_s:g} s, "
                 f"heading {heading_deg:g} deg, {speed_kn:g} kn")
        return regular_series(ship, wave, duration_s=duration_s, dt_s=dt_s), resolved, title
    run = parse_sea_run(_sea_mapping(args))
    series = irregular_series(run.ship, run.sea, duration_s=run.duration_s, dt_s=run.dt_s,
                              rng=np.random.default_rng(run.seed))
    spec = run.sea.spectrum
    title = (f"{run.ship.name}: sea state {run.sea_state} ({spec.kind.value}, Hs={spec.hs_m:g} m, "
             f"Tp={spec.tp_s:g} s), heading {math.degrees(run.sea.heading_rad):.4g} deg, "
             f"{run.sea.speed_m_s * _KNOTS_PER_M_S:.4g} kn, seed {run.seed}")
    return series, {"source": "sea", **sea_run_to_mapping(run)}, title


def run(args: argparse.Namespace) -> int:
    """Run ``deckpose motion``."""
    import yaml

    from deckpose.atomic_io import atomic_open
    from deckpose.motion.irregular import series_significant_amplitudes
    from deckpose.motion.series import write_series

    if not args.output and not args.plot:
        raise ConfigError("nothing to do: give -o/--output FILE (.csv/.parquet) and/or --plot FILE.png")
    from deckpose.output_folder import ensure_writable

    for target in (args.output, args.plot):  # before the work
        if target:
            ensure_writable(Path(target).parent)
    if args.thesis_table:
        if args.source != "thesis" or not args.output:
            raise ConfigError("--thesis-table goes with 'thesis' and -o FILE.csv")
        from deckpose.motion.thesis_series import thesis_motion_table

        out = Path(args.output)
        with atomic_open(out, "w", newline="") as fh:
            thesis_motion_table().to_csv(fh, index=False, float_format="%.17g")
        wrote(args, out, f"wrote {out} (thesis table, thesis X-Y-Z angles in degrees)")
        return 0
    series, resolved, title = _series(args)
    angles = "rad" if args.radians else "deg"
    if args.output:
        out = Path(args.output)
        write_series(series, out, angles=angles)
        cfg = out.with_name(out.stem + ".motion.yaml")
        with atomic_open(cfg, "w") as fh:
            yaml.safe_dump({**resolved, "angles": angles, "samples": len(series)}, fh, sort_keys=False)
        wrote(args, out, f"wrote {out} ({len(series)} samples) and {cfg}")
    if args.plot:
        from deckpose.motion.plot import plot_series

        plot_series(series, args.plot, title=title)
        if args.output:  # the series is the result; the plot a summary line
            say(args, f"wrote {args.plot}")
        else:
            wrote(args, args.plot, f"wrote {args.plot}")
    sig = series_significant_amplitudes(series)
    say(args, "significant amplitudes (2 sigma): " + ", ".join(f"{k} {v:.2f}" for k, v in sig.items()))
    return 0
