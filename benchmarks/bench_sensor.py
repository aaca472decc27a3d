"""Sensor-model benchmark: CPU per frame of :func:`deckpose.render.sensor.expose`, this tree against another.

Two worker processes, one importing this checkout's ``deckpose`` and one the other
tree's (``--base``, a checkout of the commit to compare with, e.g. ``git worktree add
--detach /tmp/base main``; laid out as installed by ``speed_against_tree.link_tree``), so
the model before is reachable only here, as it was committed. Both get the same inputs,
made once in this process and pickled: an (H, W, 3) uint8 raster (random values, which
cost what a real one costs: every step is element-wise or a table look-up), the night
radiance scale and the beacon splats of the default layout seen from 30 m, the sensor of
``configs/thesis_sweep.yaml`` (8-bit RGB, read noise 5 e-) unless told otherwise. Each
worker times ``expose`` (CPU time of its thread with one OpenCV thread; ``--cv-threads
0``: OpenCV's default pool and the process's CPU time, all threads, as the sweep runs),
the two in alternating order call by call (``base, this, this, base, ...``) so a change of
the machine's load hits both. Printed per size: each tree's median and fastest CPU time,
ns per value, the median and quartiles of the per-call ratios base / this, the 1-minute
load before and after; and how many values of the first call's two images (same seed)
differ, with the largest difference.

Usage::

    .venv/bin/python benchmarks/bench_sensor.py --base /tmp/base [--sizes 8mp 64mp]
        [--repeats 9] [--bit-depth 8] [--color rgb] [--cv-threads 1]
"""

from __future__ import annotations

import argparse
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from speed_against_tree import link_tree  # the benchmarks' own helper

REPO = Path(__file__).resolve().parents[1]


def make_inputs(size: str, bit_depth: int, color: str, folder: Path, seed: int = 1) -> Path:
    """Raster, radiance scale, splats and sensor of one ``size`` frame, pickled for the workers."""
    from deckpose.render.beacons import beacon_splats
    from deckpose.render.config import SensorSpec
    from deckpose.render.scene import Lighting, Shading, radiance_scale

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.pose import CameraPose, ShipPose

    sensor = SensorSpec(bit_depth=bit_depth, read_noise_e=5.0, color=color)
    cam = preset(f"{size}-thesis")
    raster = np.random.default_rng(seed).integers(0, 256, (cam.height_px, cam.width_px, 3), np.uint8)
    splats = beacon_splats(DeckLayout(), (ShipPose(),), CameraPose.nadir(30.0), cam, sensor)
    path = folder / f"{size}.pkl"
    with open(path, "wb") as f:
        pickle.dump((raster, radiance_scale(Lighting.NIGHT, Shading.FLAT), splats, sensor), f)
    return path


def worker(paths: list[str], cv_threads: int, out_dir: str) -> None:
    """Load the inputs, warm up (saving the first image), then time ``expose`` per stdin line ``i seed``."""
    import cv2
    from deckpose.render import sensor as sensor_module

    if cv_threads > 0:
        cv2.setNumThreads(cv_threads)
    clock = time.thread_time if cv_threads == 1 else time.process_time
    inputs = []
    for i, p in enumerate(paths):
        with open(p, "rb") as f:
            raster, scale, splats, sensor = pickle.load(f)
        img = sensor_module.expose(raster, scale, splats, sensor, np.random.default_rng(0))
        np.save(Path(out_dir) / f"{i}.npy", img)
        inputs.append((raster, scale, splats, sensor))
    print(f"ready {sensor_module.__file__}", flush=True)
    for line in sys.stdin:
        i, seed = (int(x) for x in line.split())
        raster, scale, splats, sensor = inputs[i]
        c0 = clock()
        sensor_module.expose(raster, scale, splats, sensor, np.random.default_rng(seed))
        print(f"{clock() - c0:.6f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="checkout of the tree to compare with")
    ap.add_argument("--sizes", nargs="+", default=["8mp", "64mp"])
    ap.add_argument("--repeats", type=int, default=9, help="interleaved calls of each tree per size")
    ap.add_argument("--bit-depth", type=int, default=8, choices=(8, 12, 16))
    ap.add_argument("--color", default="rgb", choices=("rgb", "mono"))
    ap.add_argument("--cv-threads", type=int, default=1,
                    help="OpenCV threads (1: thread CPU time; 0: OpenCV's default, process CPU time)")
    ap.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker, args.cv_threads, args.out)
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = [make_inputs(s, args.bit_depth, args.color, folder) for s in args.sizes]
        base_tree = link_tree(Path(args.base), folder)
        procs, outs = [], []
        for name, extra in (("base", {"PYTHONPATH": str(base_tree)}), ("this", {})):
            out = folder / name
            out.mkdir()
            cmd = [sys.executable, __file__, "--base", args.base, "--cv-threads", str(args.cv_threads),
                   "--out", str(out), "--worker", *map(str, paths)]
            p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                 env=dict(os.environ, **extra))
            assert p.stdout is not None
            print(f"{name}: {p.stdout.readline().split()[-1]}", flush=True)
            procs.append(p)
            outs.append(out)

        def run(p: subprocess.Popen[str], i: int, seed: int) -> float:
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write(f"{i} {seed}\n")
            p.stdin.flush()
            return float(p.stdout.readline())

        clock = "thread CPU, 1 OpenCV thread" if args.cv_threads == 1 else (
            f"process CPU, OpenCV threads {args.cv_threads or 'default'}")
        print(f"sensor: {args.bit_depth}-bit {args.color}, read noise 5 e-, noise on; {args.repeats} "
              f"interleaved calls per tree and size; {clock}; {os.cpu_count()} CPUs", flush=True)
        print(f"{'size':>5} {'values':>11} {'base ms':>8} {'this ms':>8} {'base min':>8} {'this min':>8} "
              f"{'base ns/v':>9} {'this ns/v':>9} {'base/this (quartiles)':>24} {'load':>9} "
              f"{'values differing (max |diff|)':>30}")
        for i, size in enumerate(args.sizes):
            a = np.load(outs[0] / f"{i}.npy", mmap_mode="r")
            b = np.load(outs[1] / f"{i}.npy", mmap_mode="r")
            differ = int(np.count_nonzero(a != b))
            max_diff = int(np.max(np.abs(a.astype(np.int32) - b.astype(np.int32)))) if differ else 0
            n_values = a.size
            del a, b
            load0 = os.getloadavg()[0]
            t = np.zeros((2, args.repeats))
            for r in range(args.repeats):
                for k in ((0, 1) if r % 2 == 0 else (1, 0)):
                    t[k, r] = run(procs[k], i, 100 + r)
            load1 = os.getloadavg()[0]
            ratios = t[0] / t[1]
            q1, q3 = np.quantile(ratios, [0.25, 0.75])
            print(f"{size:>5} {n_values:>11,} {statistics.median(t[0]) * 1e3:8.0f} "
                  f"{statistics.median(t[1]) * 1e3:8.0f} {t[0].min() * 1e3:8.0f} {t[1].min() * 1e3:8.0f} "
                  f"{statistics.median(t[0]) / n_values * 1e9:9.2f} "
                  f"{statistics.median(t[1]) / n_values * 1e9:9.2f} "
                  f"{statistics.median(ratios):10.3f} ({q1:.3f}-{q3:.3f}) {load0:4.1f}-{load1:<4.1f} "
                  f"{differ:>19,} ({max_diff})", flush=True)
        for p in procs:
            assert p.stdin is not None
            p.stdin.close()
            p.wait()


if __name__ == "__main__":
    main()
