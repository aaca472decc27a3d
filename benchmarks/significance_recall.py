"""Recall of the significance search against a spot's integrated SNR (prints a table).

Frames from :mod:`independent_spots` (1920x1080 RGB, 12-bit in 16, background
30 e and read noise 5 e per pixel and channel) whose 13 beacons all have one
sigma and one flux, the flux chosen for an integrated SNR
``F / sqrt(F + 4 pi sigma^2 var_px)`` (``var_px`` the channel sum's per-pixel
variance), searched by :func:`deckpose.detect.significance.significant_spots` at the
default threshold. A found spot lies within 4 px of the truth; *false* counts the
rest.

Usage::

    .venv/bin/python benchmarks/significance_recall.py [--frames 6] [--seed 1]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_spots as gen
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.significance import significant_spots


def flux_for_snr(snr: float, sigma_px: float, var_px_e2: float) -> float:
    """Electrons of a Gaussian spot of ``sigma_px`` with integrated SNR ``snr``."""
    b = 4.0 * math.pi * sigma_px**2 * var_px_e2
    return snr**2 / 2.0 + math.sqrt(snr**4 / 4.0 + snr**2 * b)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=6, help="frames per cell (default 6)")
    ap.add_argument("--seed", type=int, default=1, help="seed (default 1)")
    args = ap.parse_args(argv)
    base = gen.SpotFrameSpec(width_px=1920, height_px=1080, focal_px=1250.0)
    var_px = 3 * (base.background_e + base.read_noise_e**2)
    thr = DetectorOptions().significance_sigma
    print(f"significance_sigma {thr}; {args.frames} frames x 13 beacons per cell; seed {args.seed}")
    print("| sigma px | SNR 6 | SNR 8 | SNR 10 | SNR 12 | SNR 15 | false (all cells) |")
    print("|---|---|---|---|---|---|---|")
    for sigma in (0.8, 1.5, 2.5, 3.0):
        cells, false = [], 0
        for snr in (6, 8, 10, 12, 15):
            f_e = flux_for_snr(snr, sigma, var_px)
            spec = replace(base, sigma_px=(sigma, sigma), flux_e=(f_e, f_e))
            rng = np.random.default_rng([args.seed, int(10 * sigma), snr])
            found = total = 0
            for _ in range(args.frames):
                t = gen.make_frame(spec, rng)
                c, _r, _why, _note = significant_spots(t.image, thr, 200)
                idx, _ = gen.match(c, t, tol_px=4.0)
                found += int((idx >= 0).sum())
                total += idx.size
                false += len(c) - int((idx >= 0).sum())
            cells.append(f"{found / total:.3f}")
        print(f"| {sigma} | " + " | ".join(cells) + f" | {false} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
