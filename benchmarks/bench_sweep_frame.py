"""CPU per frame of the thesis sweep's lean render in this tree against another, and the sweep it projects.

The full ``configs/thesis_sweep.yaml`` (issue 20: 9,900 frames in 90 minutes on 2 cores)
rendered the lean way: no multisampling (``scene.antialias_samples: 0``), each frame
detected with ``cog`` from memory as it is rendered, no frame image kept (``deckpose
render --detect cog --no-images``; the preview for the log is still made). Two worker
processes, one importing this checkout's ``deckpose`` and one the other tree's
(``--base``, e.g. ``git worktree add --detach /tmp/base main``), each make the frames
:func:`deckpose.render.dataset.encode_frame` makes (render, sensor, detection, preview,
tables; nothing written), one frame per camera at each ``--heights``, in alternating
order, and report the process CPU of each (all threads: llvmpipe draws on its own).

Printed per camera: each tree's median CPU per frame, the median and quartiles of the
per-run ratios, and the projection of the full sweep's render stage: frames per camera
times CPU per frame, summed, over the cores (so perfect use of both cores, no start-up,
no later stages: a lower bound on the wall time, not a measurement of it).

Usage::

    .venv/bin/python benchmarks/bench_sweep_frame.py --base /tmp/base [--repeat 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from speed_against_tree import link_tree  # the benchmarks' own helper


def _lean_config(config: str):  # -> RenderConfig (imported in the worker's tree)
    from deckpose.render.config import load_config

    cfg = load_config(config)
    return dataclasses.replace(cfg, scene=dataclasses.replace(cfg.scene, antialias_samples=0))


def worker(config: str, heights: list[float]) -> None:
    """Build the frames (one per camera and height), warm up, then render the index on each stdin line."""
    from deckpose.render import dataset
    from deckpose.render.dataset import encode_frame, sensor_block
    from deckpose.render.plan import plan_frames
    from deckpose.render.render_detection import RenderDetection, resolve_detection

    cfg = _lean_config(config)
    plan = plan_frames(cfg)
    specs = []
    for cam in cfg.cameras_by_name():
        for h in heights:
            specs.append(next(s for s in plan if s.camera_name == cam and s.height_m == h))
    job = resolve_detection(RenderDetection(detectors=("cog",), keep_images=False), sensor_block(cfg))
    encode_frame(cfg, specs[0], job)  # GL context, imports, caches
    print(f"ready {dataset.__file__} {len(specs)}", flush=True)
    for line in sys.stdin:
        spec = specs[int(line)]
        c0 = time.process_time()
        enc = encode_frame(cfg, spec, job)
        rows = enc.part["detections"]["cog"]["rows"]
        n = sum(1 for b in rows["beacon_id"] if b is not None and b >= 0)  # identified beacons
        print(f"{time.process_time() - c0:.4f} {n} {spec.camera_name}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="checkout of the tree to compare with")
    ap.add_argument("--config", default=str(REPO / "configs" / "thesis_sweep.yaml"))
    ap.add_argument("--heights", default="20,80", help="camera heights, m (comma list; the sweep's)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved runs per frame")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    heights = [float(h) for h in args.heights.split(",")]
    if args.worker:
        worker(args.config, heights)
        return
    from deckpose.render.plan import plan_frames

    cfg = _lean_config(args.config)
    per_camera = {}
    for s in plan_frames(cfg):
        per_camera[s.camera_name] = per_camera.get(s.camera_name, 0) + 1
    with tempfile.TemporaryDirectory() as tmp:
        base_tree = link_tree(Path(args.base), Path(tmp))
        cmd = [sys.executable, __file__, "--worker", "--base", args.base, "--config", args.config,
               "--heights", args.heights]
        procs = []
        for extra in ({"PYTHONPATH": str(base_tree)}, {}):
            p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                 env=dict(os.environ, **extra))
            assert p.stdout is not None
            ready = p.stdout.readline().split()
            print(f"{'base' if extra else 'this'}: {ready[1]}", flush=True)
            n = int(ready[2])
            procs.append(p)

        def run(p: subprocess.Popen[str], i: int) -> tuple[float, int, str]:
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write(f"{i}\n")
            p.stdin.flush()
            cpu, dets, cam = p.stdout.readline().split()
            return float(cpu), int(dets), cam

        loads = [os.getloadavg()[0]]
        cpu = np.zeros((n, 2, args.repeat))
        cams = [""] * n
        dets = np.zeros((n, 2), int)
        for r in range(args.repeat):
            for i in range(n):
                for k in ((0, 1) if r % 2 == 0 else (1, 0)):
                    cpu[i, k, r], dets[i, k], cams[i] = run(procs[k], i)
            loads.append(os.getloadavg()[0])
        for p in procs:
            assert p.stdin is not None
            p.stdin.close()
            p.wait()
    print(f"# {Path(args.config).name}, lean: antialias 0, cog at render time, no images; heights "
          f"{args.heights} m; {args.repeat} interleaved runs per frame; process CPU (all threads); "
          f"1-minute load {min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores")
    print(f"{'camera':18s} {'base s':>7s} {'this s':>7s} {'this/base':>9s} (quartiles)  identified base/this  "
          "frames in the sweep")
    total = {0: 0.0, 1: 0.0}
    for cam, count in per_camera.items():
        idx = [i for i in range(n) if cams[i] == cam]
        med = [float(np.median(cpu[idx, k].mean(axis=0))) for k in (0, 1)]  # mean over heights, median of runs
        ratio = cpu[idx, 1].mean(axis=0) / cpu[idx, 0].mean(axis=0)
        q1, q3 = np.percentile(ratio, [25, 75])
        print(f"{cam:18s} {med[0]:7.2f} {med[1]:7.2f} {np.median(ratio):9.3f} ({q1:.3f}-{q3:.3f})  "
              f"{int(dets[idx, 0].sum())}/{int(dets[idx, 1].sum())}  {count}")
        for k in (0, 1):
            total[k] += count * med[k]
    cores = os.cpu_count() or 1
    for k, name in ((0, "base"), (1, "this")):
        print(f"projected render stage of the full sweep, {name}: {total[k] / 3600:.2f} CPU-hours, "
              f"{total[k] / cores / 60:.0f} min on {cores} cores if both were always busy")


if __name__ == "__main__":
    main()
