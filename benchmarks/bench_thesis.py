"""Speed of the faithful thesis estimator on one core.

Prints poses per second of the vectorised batch form (target: >= 50,000/s, so
the ~15 million estimates of the full thesis tables take minutes) and, as a
peer in the same process, of the per-frame API, with the ratio.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_thesis.py [--frames N]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from deckpose.estimate.thesis import estimate_thesis
from deckpose.estimate.thesis_algorithm import thesis_algorithm
from deckpose.evaluate.thesis_sim import CellSpec, clean_projection, load_thesis_motion

from deckpose.camera import preset
from deckpose.layout import thesis_layout
from deckpose.noise import thesis_uniform
from deckpose.records import Detections


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=198_000, help="frames for the batch form")
    ap.add_argument("--chunk", type=int, default=9_900, help="frames per vectorised call")
    ap.add_argument("--single-frames", type=int, default=2_000, help="frames for the per-frame peer")
    args = ap.parse_args()
    cam = preset("8mp")
    pc, vis, _ = clean_projection(CellSpec("8mp", 8, 20), load_thesis_motion())
    rng = np.random.default_rng(0)
    reps = -(-args.chunk // len(pc))
    base = np.tile(pc, (reps, 1, 1))[: args.chunk]
    mask = np.tile(vis, (reps, 1))[: args.chunk]
    noisy = thesis_uniform(base, 8.0, cam.width_px, cam.height_px, rng)
    thesis_algorithm(noisy, mask, cam.fx, cam.fy, 10.0)  # warm-up
    n_calls = max(1, args.frames // args.chunk)
    t0 = time.perf_counter()
    for _ in range(n_calls):
        res = thesis_algorithm(noisy, mask, cam.fx, cam.fy, 10.0)
    batch_s = time.perf_counter() - t0
    batch_rate = n_calls * args.chunk / batch_s

    layout = thesis_layout()
    dets = []
    for i in range(args.single_frames):
        j = i % args.chunk
        uv = np.column_stack([noisy[j, :, 0] + cam.cx, cam.cy - noisy[j, :, 1]])
        dets.append(Detections(uv, np.arange(12)))
    t0 = time.perf_counter()
    for d in dets:
        estimate_thesis(d, cam, layout)
    single_rate = len(dets) / (time.perf_counter() - t0)

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}, 1 thread")
    print(f"batch thesis estimator : {batch_rate:12,.0f} poses/s  ({n_calls * args.chunk:,} frames, "
          f"{args.chunk} per call, {res.ok.mean() * 100:.1f}% ok)")
    print(f"per-frame API (peer)   : {single_rate:12,.0f} poses/s  ({len(dets):,} frames)")
    print(f"batch / per-frame      : {batch_rate / single_rate:12.1f} x")
    print(f"target >= 50,000 poses/s: {'met' if batch_rate >= 50_000 else 'NOT met'}")
    print(f"full thesis tables (15,097,500 estimates) at this rate on 1 core: {15_097_500 / batch_rate:,.0f} s")


if __name__ == "__main__":
    main()
