"""Recall on dark 8-bit frames of sparse counts, against what the rounding leaves to find (prints a table).

Frames from :mod:`independent_spots` (8 MP RGB 8-bit, uneven beacons x U(0.4, 1), 2,000-30,000 e),
darker than ``bench_independent.py``'s ``rgb8_dark``: backgrounds of 1-30 e at 78-157 e a DN,
where the noise does not dither the rounding and the background is a flat 0 DN with rare
single-DN counts. A detector cannot find light the rounding took: each beacon's expected DN above
the background after rounding (Poisson + read noise as a normal variable, rounded to whole DN,
summed over its pixels and channels: ``independent_spots.visible_dn``), independent of ``detect/``, and the
table gives the recall of the beacons with at least ``--visible-dn`` of it besides the plain
recall. *false*: detections on no beacon.

Usage::

    .venv/bin/python benchmarks/sparse_dark_recall.py [--frames 4] [--detector cog]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_spots as gen
from deckpose.detect.frame_detection import detect_frame

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame

#: (background e, read noise e, full well e) per setting; rgb8_dark's first.
SETTINGS = ((30.0, 5.0, 20_000.0), (15.0, 5.0, 20_000.0), (8.0, 3.0, 20_000.0), (3.0, 2.0, 20_000.0),
            (1.0, 1.0, 20_000.0), (30.0, 5.0, 40_000.0), (10.0, 2.0, 40_000.0))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=4, help="frames per setting (default 4)")
    ap.add_argument("--detector", default="cog")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--visible-dn", type=float, default=8.0,
                    help="expected DN above the background a beacon needs to count as visible")
    args = ap.parse_args(argv)
    base = replace(gen.SpotFrameSpec(), bits=8, uneven=(0.4, 1.0))
    t0 = time.time()
    print(f"# {args.detector}, {args.frames} frames a setting, 3840x2160 RGB 8-bit, seed {args.seed}; "
          f"1-minute load {os.getloadavg()[0]:.1f}")
    print(f"{'bg e':>5} {'read e':>6} {'well e':>7} {'bg DN/ch':>8} {'recall':>7} {'visible':>8} "
          f"{'recall visible':>14} {'false':>5}  {'missed: most DN any had':>24}")
    for bg_e, read_e, well_e in SETTINGS:
        spec = replace(base, background_e=bg_e, read_noise_e=read_e, full_well_e=well_e)
        rng = np.random.default_rng([args.seed, int(bg_e), int(read_e), int(well_e)])
        found = n = n_vis = found_vis = false = 0
        missed_dn = 0.0
        for _ in range(args.frames):
            t = gen.make_frame(spec, rng)
            cam = CameraModel(t.image.shape[1], t.image.shape[0], t.K)
            res = detect_frame(Frame(t.image, cam, 0), args.detector, DeckLayout())
            idx, _ = gen.match(res.detections.points_px, t)
            vis = gen.visible_dn(t, spec)
            hit = idx >= 0
            n += idx.size
            found += int(hit.sum())
            n_vis += int((vis >= args.visible_dn).sum())
            found_vis += int((hit & (vis >= args.visible_dn)).sum())
            false += len(res.detections.points_px) - int(hit.sum())
            if (~hit).any():
                missed_dn = max(missed_dn, float(vis[~hit].max()))
        print(f"{bg_e:5.0f} {read_e:6.0f} {well_e:7.0f} {bg_e * 255 / well_e:8.2f} {found / n:7.3f} "
              f"{n_vis:8d} {found_vis / max(n_vis, 1):14.3f} {false:5d}  {missed_dn:24.1f}", flush=True)
    print(f"# {time.time() - t0:.0f} s; 1-minute load {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
