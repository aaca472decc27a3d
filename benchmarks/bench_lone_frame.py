"""A lone frame against a big batch: CPU time per frame of every estimator variant.

For each variant three ways of estimating the same 8 MP frames (30 m, sigma 0.5 px,
attitudes from the thesis motion series, every beacon visible):

* ``lone``: :func:`~deckpose.estimate.batch.run_estimator` on one frame at a time;
* ``of-one``: :func:`~deckpose.estimate.batch.estimate_batch` on a list of one frame;
* ``batch``: one :func:`~deckpose.estimate.batch.estimate_batch` call on all frames.

The three are interleaved (lone, of-one, batch, lone, ...) ``--repeats`` times and
each prints the median per-frame thread CPU time (``time.thread_time``, one BLAS and
one OpenCV thread), with the machine's load average before and after. A noisy shared
machine moves the absolute figures; the ratios of interleaved medians move less.

``--save FILE`` writes every variant's batched results (ok, reason, the six pose
values, their sigmas) and its lone results (``run_estimator`` on the ``--lone`` frames)
as ``.npz``; ``--compare FILE`` checks the current tree's results against such a file
and prints, per variant, how many frames differ (ok, reason, or a value by more than
``--rtol``, default 1e-9, relative) and the largest change of a pose value in units of
its sigma, for the batch and (``lone differ``) for the frames alone — to show a refactoring left the estimates as they were
(Levenberg–Marquardt stops at 1e-3 sigma, so a start that moves by rounding can move
the optimum by up to that much).

Run::

    .venv/bin/python benchmarks/bench_lone_frame.py --frames 1000 --lone 200 --repeats 5
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_estimators import load_attitudes, make_cell
from deckpose.estimate.batch import estimate_batch, run_estimator
from deckpose.estimate.registry import EstimateOptions

from deckpose.atomic_io import atomic_path
from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.records import POSE_PARAMS, PoseEstimate

cv2.setNumThreads(1)

#: (label, registry name, options overrides): every estimator and its variants.
VARIANTS = (
    ("thesis", "thesis", {}),
    ("thesis+refine", "thesis", {"refine": True}),
    ("conic", "conic", {}),
    ("conic-geom", "conic", {"conic_polish_steps": 0}),
    ("conic+refine", "conic", {"refine": True}),
    ("pnp", "pnp", {}),
    ("pnp+mean", "pnp", {"posterior_mean": True}),
)


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _fingerprint(ests: list[PoseEstimate]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ok = np.array([e.ok for e in ests])
    reason = np.array([e.reason for e in ests])
    vals = np.array([[getattr(e, q) for q in POSE_PARAMS]
                     + [e.extras.get("sigma_" + q, np.nan) for q in POSE_PARAMS] for e in ests])
    return ok, reason, vals


def _differ(ok: np.ndarray, reason: np.ndarray, vals: np.ndarray, r_ok: np.ndarray, r_reason: np.ndarray,
            r_vals: np.ndarray, what: str, rtol: float) -> str:
    """How many frames differ from the reference (ok, reason, a value by ``rtol`` relative), as printed."""
    with np.errstate(invalid="ignore"):
        close = (np.abs(vals - r_vals) <= rtol * (1 + np.abs(r_vals))) | (np.isnan(vals) & np.isnan(r_vals))
    differ = (ok != r_ok) | (reason != r_reason) | ~close.all(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        in_sigmas = np.abs(vals[:, :6] - r_vals[:, :6]) / r_vals[:, 6:]
    worst = float(np.nanmax(in_sigmas, initial=0.0))
    return (f"  {what}: {int(differ.sum())}/{len(ok)} "
            f"(ok or reason: {int(((ok != r_ok) | (reason != r_reason)).sum())}; "
            f"largest pose change {worst:.1g} of its sigma)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000, help="frames of the big batch")
    ap.add_argument("--lone", type=int, default=200, help="frames timed one at a time (the first ones)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=20261203)
    ap.add_argument("--variants", nargs="+", default=[v[0] for v in VARIANTS])
    ap.add_argument("--save", type=Path, default=None, help="write the batched results to this .npz")
    ap.add_argument("--compare", type=Path, default=None, help="compare the batched results with this .npz")
    ap.add_argument("--rtol", type=float, default=1e-9,
                    help="a value differs when it moves by more than this, relative (default 1e-9)")
    args = ap.parse_args(argv)
    camera, layout = preset("8mp"), DeckLayout()
    dets, _, _ = make_cell(0.5, 30.0, "8mp", load_attitudes(None), args.frames,
                           np.random.default_rng(args.seed), {})
    lone = dets[:args.lone]
    print(f"# {args.frames} frames (lone: first {len(lone)}), 8mp, 30 m, sigma 0.5 px; thread CPU us/frame, "
          f"median of {args.repeats} interleaved; load before {_load()}")
    print(f"{'variant':>14} {'lone':>8} {'of-one':>8} {'batch':>8} {'of-one/lone':>12} {'lone/batch':>11}")
    saved: dict[str, np.ndarray] = {}
    ref = np.load(args.compare, allow_pickle=False) if args.compare else None
    for label, name, over in VARIANTS:
        if label not in args.variants:
            continue
        opts = dataclasses.replace(EstimateOptions(sigma_px=0.5), **over)
        t: dict[str, list[float]] = {"lone": [], "one": [], "batch": []}
        ests: list[PoseEstimate] = []
        lone_ests: list[PoseEstimate] = []
        for _ in range(args.repeats):
            t0 = time.thread_time()
            lone_ests = [run_estimator(name, d, camera, layout, opts) for d in lone]
            t["lone"].append((time.thread_time() - t0) / len(lone))
            t0 = time.thread_time()
            for d in lone:
                estimate_batch(name, [d], camera, layout, opts)
            t["one"].append((time.thread_time() - t0) / len(lone))
            t0 = time.thread_time()
            ests = estimate_batch(name, dets, camera, layout, opts)
            t["batch"].append((time.thread_time() - t0) / len(dets))
        m = {k: 1e6 * statistics.median(v) for k, v in t.items()}
        line = (f"{label:>14} {m['lone']:>8.0f} {m['one']:>8.0f} {m['batch']:>8.1f} "
                f"{m['one'] / m['lone']:>12.2f} {m['lone'] / m['batch']:>11.1f}")
        for tag, got in (("", ests), ("lone_", lone_ests)):
            ok, reason, vals = _fingerprint(got)
            saved.update({f"{label}/{tag}ok": ok, f"{label}/{tag}reason": reason, f"{label}/{tag}vals": vals})
            if ref is not None and f"{label}/{tag}ok" in ref:
                line += _differ(ok, reason, vals, ref[f"{label}/{tag}ok"], ref[f"{label}/{tag}reason"],
                                ref[f"{label}/{tag}vals"], "lone differ" if tag else "differ from reference",
                                args.rtol)
        print(line, flush=True)
    print(f"# load after {_load()}")
    if args.save:
        with atomic_path(args.save) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **saved)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
