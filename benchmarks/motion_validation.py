"""Print the figures behind the motion generator's validation.

Run: ``.venv/bin/python benchmarks/motion_validation.py [--hours 3] [--seeds 5]``

1. The thesis series regenerated against ``deckpose/data/thesis_motion_series.csv`` (the published series).
2. Predicted significant amplitudes (2 sigma) of the FFG-7-like frigate in sea
   state 6 over headings and speeds, for JONSWAP and Pierson-Moskowitz seas.
3. For the SS6 frigate scenario: variance of long seeded series over the
   frequency-domain value, the roll spectral peak, and the synthesis speed.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from deckpose.motion.closed_form import KNOTS_PER_M_S
from deckpose.motion.filtered_noise import FilteredNoise
from deckpose.motion.irregular import (
    IrregularSea,
    irregular_series,
    predicted_variances,
    series_significant_amplitudes,
    ss6_frigate_sea,
)
from deckpose.motion.plot import channel_psd
from deckpose.motion.ship import ffg7_ship
from deckpose.motion.spectrum import SpectrumKind, spectrum_for_sea_state
from deckpose.motion.thesis_series import thesis_motion_table

#: The thesis's published series (a copy of the team's shared reference, byte for byte, in the package data).
REFERENCE = Path(__file__).resolve().parents[1] / "deckpose" / "data" / "thesis_motion_series.csv"


def thesis_check() -> None:
    if not REFERENCE.is_file():
        print(f"[thesis] {REFERENCE} absent: skipped")
        return
    ref = pd.read_csv(REFERENCE)
    ours = thesis_motion_table()
    cols = ["t_in_segment_s", "roll_deg", "pitch_deg", "yaw_deg", "heave_m"]
    err = np.abs(ours[cols].to_numpy() - ref[cols].to_numpy()).max(axis=0)
    print("[thesis] max |ours - reference| per column: "
          + ", ".join(f"{c} {e:.1e}" for c, e in zip(cols, err)))


def sweep() -> None:
    ship = ffg7_ship()
    print("\n[sweep] FFG-7-like frigate, sea state 6 (Hs 5.0 m, Tp 12.4 s): significant amplitudes (2 sigma)")
    print(f"{'spectrum':9s} {'heading':>7s} {'speed':>5s} {'heave m':>8s} {'pitch deg':>9s} {'roll deg':>8s}")
    for kind in SpectrumKind:
        for heading in (180.0, 135.0, 90.0, 45.0):
            for kn in (0.0, 10.0, 15.0, 20.0):
                sea = IrregularSea(spectrum_for_sea_state(6, kind=kind), math.radians(heading), kn / KNOTS_PER_M_S)
                sig = predicted_variances(ship, sea).significant_amplitudes()
                print(f"{kind.value:9s} {heading:7.0f} {kn:5.0f} {sig['heave_m']:8.2f} {sig['pitch_deg']:9.2f} "
                      f"{sig['roll_deg']:8.2f}")


def long_series(hours: float, seeds: int) -> None:
    ship = ffg7_ship()
    quiet = FilteredNoise(0.0, 10.0)
    base = ss6_frigate_sea()
    sea = IrregularSea(base.spectrum, base.heading_rad, base.speed_m_s, yaw=quiet, surge=quiet, sway=quiet)
    v = predicted_variances(ship, sea)
    pred = v.significant_amplitudes()
    print(f"\n[long] SS6 frigate scenario, {hours:g} h at 0.1 s, {sea.n_components} components")
    print("predicted 2-sigma: " + ", ".join(f"{k} {x:.3f}" for k, x in pred.items()))
    w4 = 2 * math.pi / ship.roll_period_s
    for seed in range(seeds):
        t0 = time.perf_counter()
        s = irregular_series(ship, sea, duration_s=hours * 3600.0, dt_s=0.1, rng=np.random.default_rng(seed))
        dt = time.perf_counter() - t0
        w, p = channel_psd(s.t_s, s.roll_rad)
        meas = series_significant_amplitudes(s)
        print(f"seed {seed}: var ratio heave {np.var(s.heave_m) / v.heave_m2:.4f} "
              f"pitch {np.var(s.pitch_rad) / v.pitch_rad2:.4f} roll {np.var(s.roll_rad) / v.roll_rad2:.4f}; "
              f"2-sigma roll {meas['roll_deg']:.2f} deg; roll PSD peak {w[np.argmax(p)]:.3f} rad/s "
              f"(roll natural {w4:.3f}, wave peak {sea.spectrum.omega_peak_rad_s:.3f}); "
              f"{len(s)} samples in {dt:.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=3.0)
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    thesis_check()
    sweep()
    long_series(args.hours, args.seeds)


if __name__ == "__main__":
    main()
