"""Multisampling of the deck raster: what it costs to draw, and what it changes (issue 20 item 4).

pyrender draws the deck and sea with 4x multisample anti-aliasing; ``scene.antialias_samples: 0``
turns it off. The beacons are drawn analytically on top of the raster, so their truth
cannot change; what can change is the background around them (the edges of markings)
and so the detectors' error. This benchmark prints both:

1. **Draw time** of the deck raster (``DeckRenderer.render``, GL draw and read-back) at
   8 MP and 64 MP with 4 and 0 samples, in one process, interleaved, median of
   ``--repeat`` runs; process CPU time (llvmpipe draws on every core) and wall time.
2. **What it changes**: a small 8 MP dataset (``--frames`` attitudes x 3 heights x night,
   dusk, day) rendered with 4 and with 0 samples from the same seed, detected at render
   time with ``cog`` and ``gauss``: the share of pixels that differ, whether the beacon
   truth tables are equal, and each detector's RMS centroid error against the truth and
   its recall with each setting.

Usage::

    .venv/bin/python benchmarks/bench_antialias.py [--repeat 5] [--frames 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

DETECTORS = ("cog", "gauss")


def _config(samples: int, n_attitudes: int) -> dict[str, object]:
    attitudes = [[0, 0, 0], [4.5, 2.1, 10.0], [-3.0, 5.0, 25.0], [2.0, -4.0, 40.0]][:n_attitudes]
    return {"name": f"antialias{samples}", "seed": 11, "backend": "egl",
            "cameras": [{"preset": "8mp-square"}], "heights_m": [20.0, 40.0, 80.0],
            "lighting": ["night", "dusk", "day"], "motion": {"source": "fixed", "attitudes_deg": attitudes},
            "sensor": {"bit_depth": 12, "read_noise_e": 4, "full_well_e": 15000},
            "scene": {"shading": "flat", "antialias_samples": samples}}


def draw_times(repeat: int) -> None:
    from deckpose.render.config import Lighting, config_from_dict
    from deckpose.render.scene import DeckRenderer

    from deckpose.pose import CameraPose, ShipPose

    print(f"1. deck raster draw, DeckRenderer.render, median of {repeat} interleaved; "
          f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for preset in ("8mp-square", "64mp"):
        renderers = {}
        for s in (4, 0):
            cfg = config_from_dict({"cameras": [{"preset": preset}], "heights_m": [30.0],
                                    "scene": {"shading": "flat", "antialias_samples": s}})
            renderers[s] = (DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend),
                            cfg.cameras[0].model())
        args = (CameraPose.nadir(30.0), ShipPose(0.02, -0.01, 0.3), 0.0, Lighting.DUSK)
        cpu: dict[int, list[float]] = {4: [], 0: []}
        wall: dict[int, list[float]] = {4: [], 0: []}
        for s, (r, cam) in renderers.items():
            r.render(cam, *args)  # warm: buffers and textures
        for _ in range(repeat):
            for s, (r, cam) in renderers.items():
                c0, t0 = time.process_time(), time.perf_counter()
                r.render(cam, *args)
                cpu[s].append(time.process_time() - c0)
                wall[s].append(time.perf_counter() - t0)
        c4, c0_ = float(np.median(cpu[4])), float(np.median(cpu[0]))
        print(f"  {preset:11s} 4 samples CPU {c4:6.3f} s (wall {np.median(wall[4]):.3f}), "
              f"0 samples CPU {c0_:6.3f} s (wall {np.median(wall[0]):.3f}): {c4 / c0_:.2f}x")


def what_changes(n_attitudes: int) -> None:
    from deckpose.detect.benchmark import match_run
    from deckpose.render.config import config_from_dict
    from deckpose.render.dataset import render_dataset
    from deckpose.render.render_detection import RenderDetection

    from deckpose.image_store import decode_image
    from deckpose.run_folder import RunPaths

    print(f"\n2. what 0 samples changes: 8 MP, {n_attitudes} attitudes x 20/40/80 m x night/dusk/day, "
          f"seed 11, detected at render time; load {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        runs = {}
        for s in (4, 0):
            out = Path(tmp) / f"aa{s}"
            t0 = time.perf_counter()
            render_dataset(config_from_dict(_config(s, n_attitudes)), out, workers=1, progress=False,
                           detection=RenderDetection(detectors=DETECTORS))
            runs[s] = RunPaths(out)
            print(f"  rendered and detected with {s} samples in {time.perf_counter() - t0:.0f} s")
        b4 = pd.read_parquet(runs[4].beacons)
        b0 = pd.read_parquet(runs[0].beacons)
        print(f"  beacon truth tables equal: {b4.equals(b0)}")
        frames = pd.read_parquet(runs[4].frames)
        differ, big = [], []
        for name in frames["image"]:
            a = decode_image((runs[4].root / name).read_bytes()).astype(np.int32)
            b = decode_image((runs[0].root / name).read_bytes()).astype(np.int32)
            d = np.abs(a - b).max(axis=2) if a.ndim == 3 else np.abs(a - b)
            differ.append(float(np.mean(d > 0)))
            big.append(float(np.mean(d > 100)))
        print(f"  pixels that differ: {100 * np.mean(differ):.2f} % (more than 100 DN: {100 * np.mean(big):.3f} %)")
        for det in DETECTORS:
            row = []
            for s in (4, 0):
                m = match_run(pd.read_parquet(runs[s].detections(det)), pd.read_parquet(runs[s].detect_frames(det)),
                              pd.read_parquet(runs[s].beacons), frames)
                found = m["matched"].to_numpy(bool)
                err = np.hypot(m.loc[found, "du_px"], m.loc[found, "dv_px"]).to_numpy(float)
                rms = float(np.sqrt(np.mean(err**2))) if err.size else float("nan")
                row.append(f"{s} samples: RMS {rms:.4f} px, recall {float(found.mean()):.3f}")
            print(f"  {det:6s} " + "; ".join(row))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="interleaved draws per setting (default 5)")
    ap.add_argument("--frames", type=int, default=2, choices=range(1, 5),
                    help="attitudes per height and lighting in part 2 (1-4, default 2)")
    args = ap.parse_args()
    draw_times(args.repeat)
    what_changes(args.frames)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
