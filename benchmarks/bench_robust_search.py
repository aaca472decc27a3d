"""Frames that need the robust search, this tree against another commit: CPU per frame, interleaved.

Every frame has one or two outliers (a beacon moved by about 20 px), so the batch settles none
and each goes through the robust search (:mod:`deckpose.estimate.robust_search`). For each
variant and tree, in the same process, alternating the trees: ``estimate_batch`` over all the
frames (their searches stacked by beacon set, where the tree does that) and ``run_estimator``
on the first ``--lone`` frames one at a time. Prints the median process CPU per frame of each
and the ratio this/base; and how many records differ between the trees (ok, reason, pose to
1e-9 relative).

Run::

    .venv/bin/python benchmarks/bench_robust_search.py --commit 1779e8c --repeats 5
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
VARIANTS = {"conic": ("conic", {}), "pnp": ("pnp", {}), "thesis+refine": ("thesis", {"refine": True})}


def _frames(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    sys.path.insert(0, str(HERE))
    from bench_estimators import load_attitudes, make_cell

    dets, _, _ = make_cell(0.5, 40.0, "8mp", load_attitudes(None), n, np.random.default_rng(seed), {})
    rng = np.random.default_rng(seed + 1)
    out = []
    for i, d in enumerate(dets):
        pts = np.array(d.points_px)
        for j in rng.choice(len(pts), 1 + i % 2, replace=False):
            pts[j] += rng.normal(0.0, 20.0, 2)
        out.append((pts, np.array(d.beacon_ids), np.array(d.covariance_px2)))
    return out


def _pose(e: object) -> list[float]:
    return [float(getattr(e, k)) for k in ("roll_rad", "pitch_rad", "yaw_rad", "surge_m", "sway_m", "height_m")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", required=True, help="the commit to compare with")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=sorted(VARIANTS))
    ap.add_argument("--frames", type=int, default=400, help="frames of the batch")
    ap.add_argument("--lone", type=int, default=100, help="frames estimated one at a time")
    ap.add_argument("--repeats", type=int, default=5, help="timed passes per tree (trees alternate)")
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from bench_lone_against import import_commit
    from deckpose.estimate import batch, registry

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections

    frames = _frames(args.frames, args.seed)
    with tempfile.TemporaryDirectory(prefix="deckpose-robust-") as tmp:
        base = import_commit(args.commit, Path(tmp))
        trees = {"this": (batch, registry, Detections, preset("8mp"), DeckLayout()),
                 "base": (base["batch"], base["registry"], base["records"].Detections,
                          base["camera"].preset("8mp"), base["layout"].DeckLayout())}
        print(f"# frames needing the robust search (8mp, 40 m, sigma 0.5 px, 1-2 outliers of ~20 px each); "
              f"process CPU, median of {args.repeats} interleaved passes; this tree against {args.commit}; "
              f"1-minute load {os.getloadavg()[0]:.1f}", flush=True)
        print(f"{'variant':>14} {'mode':>6} {'base ms/fr':>10} {'this ms/fr':>10} {'this/base':>9}  differ")
        for v in args.variants:
            name, over = VARIANTS[v]
            for mode, n in (("batch", args.frames), ("lone", args.lone)):
                times: dict[str, list[float]] = {"base": [], "this": []}
                poses: dict[str, list[tuple[bool, str, list[float]]]] = {}
                for rep in range(args.repeats):
                    for t in ("base", "this") if rep % 2 == 0 else ("this", "base"):
                        b, reg, det_cls, cam, layout = trees[t]
                        dets = [det_cls(p, ids, c) for p, ids, c in frames[:n]]
                        opts = dataclasses.replace(reg.EstimateOptions(sigma_px=0.5), **over)
                        t0 = time.process_time()
                        if mode == "batch":
                            ests = b.estimate_batch(name, dets, cam, layout, opts)
                        else:
                            ests = [b.run_estimator(name, d, cam, layout, opts) for d in dets]
                        times[t].append((time.process_time() - t0) / n)
                        poses[t] = [(e.ok, e.reason, _pose(e)) for e in ests]
                differ = sum(
                    a[0] != c[0] or a[1] != c[1]
                    or not np.allclose(a[2], c[2], rtol=1e-9, atol=1e-12, equal_nan=True)
                    for a, c in zip(poses["base"], poses["this"], strict=True))
                tb, tt = statistics.median(times["base"]), statistics.median(times["this"])
                print(f"{v:>14} {mode:>6} {tb * 1e3:10.2f} {tt * 1e3:10.2f} {tt / tb:9.3f}  {differ}/{n}", flush=True)
        print(f"# 1-minute load at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
