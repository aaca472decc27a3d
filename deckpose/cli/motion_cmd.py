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

from deckpose.errors import ConfigError

_KNOTS_PER_M_S = 1.94384


def register(subparsers: Any) -> None:
    """Add the ``motion`` subcommand."""
    p = subparsers.add_parser(
        "motion", help="generate (thesis / regular / sea state) or read a ship-motion series",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", choices=["thesis", "regular", "sea", "read"], help="where the motion comes from")
    p.add_argument("file", nargs="?", help="input file for 'read' (.csv or .parquet)")
    p.add_argument("-o", "--output", help="write the series here (.csv or .parquet)")
    p.add_argument("--plot", help="write a PNG of the channels and their spectra here")
    p.add_argument("--radians", action="store_true", help="angle columns in radians (roll_rad, ...) in and out")
    p.add_argument("--thesis-table", action="store_true",
                   help="thesis: write the table exactly as the reference CSV (thesis X-Y-Z angles)")
    g = p.add_argument_group("ship and waves (regular, sea)")
    g.add_argument("--ship", default="ffg7", help="ship preset: ffg7 (default) or thesis")
    g.add_argument("--heading-deg", type=float, default=135.0,
                   help="wave heading relative to the ship: 180 head, 135 bow quartering (default), 90 beam, 0 following")
    g.add_argument("--speed-kn", type=float, default=15.0, help="ship speed, knots (default 15)")
    g.add_argument("--duration-s", type=float, default=600.0, help="series length, s (default 600)")
    g.add_argument("--dt-s", type=float, default=0.1, help="sample step, s (default 0.1)")
    g.add_argument("--amplitude-m", type=float, default=2.5, help="regular: wave amplitude, m")
    g.add_argument("--period-s", type=float, default=10.0, help="regular: wave period, s")
    g.add_argument("--sea-state", type=int, default=6, help="sea: Douglas sea state 1-9 (default 6)")
    g.add_argument("--hs-m", type=float, help="sea: significant wave height (default: the state's most probable)")
    g.add_argument("--tp-s", type=float, help="sea: peak period (default: the state's most probable)")
    g.add_argument("--spectrum", choices=["jonswap", "pm"], default="jonswap", help="sea: spectrum shape")
    g.add_argument("--gamma", type=float, default=3.3, help="sea: JONSWAP peak enhancement (default 3.3)")
    g.add_argument("--components", type=int, default=600, help="sea: number of wave components")
    g.add_argument("--seed", type=int, default=0, help="sea: random seed (default 0)")
    g.add_argument("--yaw-sigma-deg", type=float, default=1.0, help="sea: yaw std, deg (0 disables)")
    g.add_argument("--yaw-period-s", type=float, default=30.0, help="sea: yaw period, s")
    g.add_argument("--drift-sigma-m", type=float, default=0.5, help="sea: surge/sway drift std, m (0 disables)")
    g.add_argument("--drift-period-s", type=float, default=60.0, help="sea: surge/sway drift period, s")
    g.add_argument("--deck-offset-m", type=float, nargs=3, metavar=("X", "Y", "Z"), default=(0.0, 0.0, 0.0),
                   help="sea: deck centre relative to the centre of gravity (x bow, y port, z up), m")
    p.set_defaults(func=run)


def _sea(args: argparse.Namespace) -> tuple[Any, Any, dict[str, Any]]:
    from deckpose.motion.filtered_noise import FilteredNoise
    from deckpose.motion.irregular import IrregularSea, default_drift, default_yaw
    from deckpose.motion.ship import ship_preset
    from deckpose.motion.spectrum import SpectrumKind, spectrum_for_sea_state

    ship = ship_preset(args.ship)
    spec = spectrum_for_sea_state(args.sea_state, hs_m=args.hs_m, tp_s=args.tp_s,
                                  kind=SpectrumKind(args.spectrum), gamma=args.gamma)
    yaw = FilteredNoise(math.radians(args.yaw_sigma_deg), args.yaw_period_s, default_yaw().damping_ratio)
    drift = FilteredNoise(args.drift_sigma_m, args.drift_period_s, default_drift().damping_ratio)
    sea = IrregularSea(spectrum=spec, heading_rad=math.radians(args.heading_deg),
                       speed_m_s=args.speed_kn / _KNOTS_PER_M_S, n_components=args.components,
                       yaw=yaw, surge=drift, sway=drift, deck_offset_m=tuple(args.deck_offset_m))
    resolved = {
        "source": "sea", "ship": ship.as_dict(), "sea_state": args.sea_state,
        "spectrum": {"kind": spec.kind.value, "hs_m": spec.hs_m, "tp_s": spec.tp_s, "gamma": spec.gamma},
        "heading_deg": args.heading_deg, "speed_kn": args.speed_kn, "n_components": args.components,
        "yaw": {"sigma_deg": args.yaw_sigma_deg, "period_s": args.yaw_period_s,
                "damping_ratio": yaw.damping_ratio},
        "drift": {"sigma_m": args.drift_sigma_m, "period_s": args.drift_period_s,
                  "damping_ratio": drift.damping_ratio},
        "deck_offset_m": list(sea.deck_offset_m), "duration_s": args.duration_s, "dt_s": args.dt_s,
        "seed": args.seed,
    }
    return ship, sea, resolved


def _series(args: argparse.Namespace) -> tuple[Any, dict[str, Any], str]:
    import numpy as np

    from deckpose.motion.closed_form import RegularWave, regular_series
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
    if args.source == "regular":
        ship = ship_preset(args.ship)
        wave = RegularWave(args.amplitude_m, args.period_s, math.radians(args.heading_deg),
                           args.speed_kn / _KNOTS_PER_M_S)
        resolved = {"source": "regular", "ship": ship.as_dict(), "amplitude_m": args.amplitude_m,
                    "period_s": args.period_s, "heading_deg": args.heading_deg, "speed_kn": args.speed_kn,
                    "duration_s": args.duration_s, "dt_s": args.dt_s}
        title = (f"{ship.name}: regular wave a={args.amplitude_m} m, T={args.period_s} s, "
                 f"heading {args.heading_deg:g} deg, {args.speed_kn:g} kn")
        return regular_series(ship, wave, duration_s=args.duration_s, dt_s=args.dt_s), resolved, title
    ship, sea, resolved = _sea(args)
    series = irregular_series(ship, sea, duration_s=args.duration_s, dt_s=args.dt_s,
                              rng=np.random.default_rng(args.seed))
    title = (f"{ship.name}: sea state {args.sea_state} ({sea.spectrum.kind.value}, Hs={sea.spectrum.hs_m:g} m, "
             f"Tp={sea.spectrum.tp_s:g} s), heading {args.heading_deg:g} deg, {args.speed_kn:g} kn, "
             f"seed {args.seed}")
    return series, resolved, title


def run(args: argparse.Namespace) -> int:
    """Run ``deckpose motion``."""
    import yaml

    from deckpose.atomic_io import atomic_open
    from deckpose.motion.irregular import series_significant_amplitudes
    from deckpose.motion.series import write_series

    if not args.output and not args.plot:
        raise ConfigError("nothing to do: give -o/--output FILE (.csv/.parquet) and/or --plot FILE.png")
    if args.thesis_table:
        if args.source != "thesis" or not args.output:
            raise ConfigError("--thesis-table goes with 'thesis' and -o FILE.csv")
        from deckpose.motion.thesis_series import thesis_motion_table

        out = Path(args.output)
        with atomic_open(out, "w", newline="") as fh:
            thesis_motion_table().to_csv(fh, index=False, float_format="%.17g")
        print(f"wrote {out} (thesis table, thesis X-Y-Z angles in degrees)")
        return 0
    series, resolved, title = _series(args)
    angles = "rad" if args.radians else "deg"
    if args.output:
        out = Path(args.output)
        write_series(series, out, angles=angles)
        cfg = out.with_name(out.stem + ".motion.yaml")
        with atomic_open(cfg, "w") as fh:
            yaml.safe_dump({**resolved, "angles": angles, "samples": len(series)}, fh, sort_keys=False)
        print(f"wrote {out} ({len(series)} samples) and {cfg}")
    if args.plot:
        from deckpose.motion.plot import plot_series

        plot_series(series, args.plot, title=title)
        print(f"wrote {args.plot}")
    sig = series_significant_amplitudes(series)
    print("significant amplitudes (2 sigma): " + ", ".join(f"{k} {v:.2f}" for k, v in sig.items()))
    return 0
