"""Monte Carlo efficiency and speed of the estimators against the Cramér–Rao bound.

For every cell (pixel noise sigma x camera height x camera preset) draw attitudes
from the thesis motion series, project the default layout (12-beacon ring of
radius 10 m + centre beacon) exactly into a nadir camera at ``height + heave``,
add isotropic Gaussian pixel noise, and run each estimator. Prints, per cell and
estimator, the RMS error of roll, pitch, yaw and height divided by the
Cramér–Rao bound (root of the mean CRB variance over the same trials), the
number of frames flagged not ok, and the mean time per frame (one process, one
BLAS thread).

Run::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_estimators.py --trials 2000
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import platform
import re
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from deckpose.estimate import registry
from deckpose.estimate.batch import run_estimator
from deckpose.estimate.crb import cramer_rao_bound
from deckpose.estimate.registry import EstimateOptions

from deckpose.atomic_io import atomic_path
from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Detections
from deckpose.rotation import zyx_from_thesis

cv2.setNumThreads(1)

SIGMAS_PX = (0.1, 0.5, 2.0)
HEIGHTS_M = (20.0, 40.0, 80.0)
PRESETS = ("4mp", "8mp", "16mp", "64mp")
#: (label, registry name, options overrides)
VARIANTS = (
    ("conic", "conic", {}),
    ("conic-geom", "conic", {"conic_polish_steps": 0}),
    ("conic+refine", "conic", {"refine": True}),
    ("pnp", "pnp", {}),
    ("thesis", "thesis", {}),
)
QUANTITIES = ("roll_rad", "pitch_rad", "yaw_rad", "height_m")


def load_attitudes(path: Path | None) -> np.ndarray:
    """(M, 4) array: ZYX roll, pitch, yaw (rad) and heave (m) of each motion sample.

    ``path=None`` regenerates the thesis series exactly (deckpose.motion.thesis_series).
    """
    from deckpose.motion.thesis_series import thesis_motion_table

    df = thesis_motion_table() if path is None else pd.read_csv(path)
    r, p, y = zyx_from_thesis(np.radians(df["roll_deg"].to_numpy(float)),
                              np.radians(df["pitch_deg"].to_numpy(float)),
                              np.radians(df["yaw_deg"].to_numpy(float)))
    return np.column_stack([r, p, y, df["heave_m"].to_numpy(float)])


def run_cell(sigma_px: float, height_m: float, cam_name: str, motion: np.ndarray, trials: int,
             variants: list[tuple[str, str, dict]], rng: np.random.Generator,
             crb_cache: dict) -> list[dict]:
    camera = preset(cam_name)
    layout = DeckLayout()
    samples = rng.integers(0, len(motion), trials)
    errs = {v[0]: [] for v in variants}
    crbs = {v[0]: [] for v in variants}
    times = {v[0]: 0.0 for v in variants}
    fails = {v[0]: 0 for v in variants}
    reasons: dict[str, dict[str, int]] = {v[0]: {} for v in variants}
    opts = {lab: dataclasses.replace(EstimateOptions(sigma_px=sigma_px), **over) for lab, _, over in variants}
    for k in samples:
        roll, pitch, yaw, heave = motion[k]
        ship = ShipPose(roll, pitch, yaw)
        cam_pose = CameraPose.nadir(height_m + heave)
        key = (cam_name, height_m, int(k))
        if key not in crb_cache:
            crb_cache[key] = np.diag(cramer_rao_bound(layout, camera, ship, cam_pose, 1.0).covariance)[[0, 1, 2, 5]]
        crb_var = crb_cache[key] * sigma_px**2
        proj = project_layout(layout, ship, cam_pose, camera)
        ids = np.flatnonzero(proj.visible)
        pts = proj.points_px[ids] + rng.normal(0.0, sigma_px, (len(ids), 2))
        det = Detections(pts, ids, np.broadcast_to(np.eye(2) * sigma_px**2, (len(ids), 2, 2)))
        truth = np.array([roll, pitch, yaw, height_m + heave])
        for label, name, _ in variants:
            t0 = time.perf_counter()
            est = run_estimator(name, det, camera, layout, opts[label])
            times[label] += time.perf_counter() - t0
            if not est.ok:
                fails[label] += 1
                key_r = re.sub(r"-?\d+(\.\d+)?", "#", est.reason.split(";")[0])[:70]
                reasons[label][key_r] = reasons[label].get(key_r, 0) + 1
                continue
            e = np.array([est.roll_rad, est.pitch_rad, est.yaw_rad, est.height_m]) - truth
            e[:3] = (e[:3] + np.pi) % (2 * np.pi) - np.pi
            errs[label].append(e)
            crbs[label].append(crb_var)
    rows = []
    for label, _, _ in variants:
        E = np.array(errs[label]).reshape(-1, 4)
        V = np.array(crbs[label]).reshape(-1, 4)
        rms = np.sqrt(np.mean(E**2, axis=0)) if len(E) else np.full(4, np.nan)
        crb = np.sqrt(np.mean(V, axis=0)) if len(V) else np.full(4, np.nan)
        row = {"sigma_px": sigma_px, "height_m": height_m, "camera": cam_name, "estimator": label,
               "trials": trials, "not_ok": fails[label], "us_per_frame": 1e6 * times[label] / trials,
               "not_ok_reasons": "; ".join(f"{r} x{n}" for r, n in reasons[label].items())}
        for q, r_, c_ in zip(QUANTITIES, rms, crb):
            row[f"rms_{q}"] = r_
            row[f"crb_{q}"] = c_
            row[f"ratio_{q.split('_')[0]}"] = r_ / c_
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=2000, help="Monte Carlo trials per cell")
    ap.add_argument("--motion", type=Path, default=None,
                    help="thesis motion series CSV (default: regenerated by deckpose.motion)")
    ap.add_argument("--seed", type=int, default=20260101)
    ap.add_argument("--sigmas", type=float, nargs="+", default=list(SIGMAS_PX))
    ap.add_argument("--heights", type=float, nargs="+", default=list(HEIGHTS_M))
    ap.add_argument("--cameras", nargs="+", default=list(PRESETS))
    ap.add_argument("--estimators", nargs="+", default=[v[0] for v in VARIANTS])
    ap.add_argument("--csv", type=Path, default=None, help="write all rows to this CSV")
    args = ap.parse_args(argv)
    known = set(registry.names())
    variants = [v for v in VARIANTS if v[0] in args.estimators and v[1] in known]
    skipped = [v[0] for v in VARIANTS if v[0] in args.estimators and v[1] not in known]
    if skipped:
        print(f"# not registered, skipped: {', '.join(skipped)}")
    motion = load_attitudes(args.motion)
    rng = np.random.default_rng(args.seed)
    print(f"# {platform.processor() or platform.machine()}, python {sys.version.split()[0]}, "
          f"numpy {np.__version__}, opencv {cv2.__version__}; trials/cell {args.trials}; seed {args.seed}")
    print(f"{'sigma':>5} {'H':>4} {'cam':>5} {'estimator':>13} {'notok':>5} "
          f"{'roll':>6} {'pitch':>6} {'yaw':>6} {'height':>6} {'us/frame':>9}")
    rows: list[dict] = []
    crb_cache: dict = {}
    for s in args.sigmas:
        for h in args.heights:
            for c in args.cameras:
                for row in run_cell(s, h, c, motion, args.trials, variants, rng, crb_cache):
                    rows.append(row)
                    print(f"{s:>5g} {h:>4g} {c:>5} {row['estimator']:>13} {row['not_ok']:>5d} "
                          f"{row['ratio_roll']:>6.3f} {row['ratio_pitch']:>6.3f} {row['ratio_yaw']:>6.3f} "
                          f"{row['ratio_height']:>6.3f} {row['us_per_frame']:>9.0f}", flush=True)
    df = pd.DataFrame(rows)
    print("\n# worst ratio to the Cramér–Rao bound over all cells, and mean us/frame")
    for label, g in df.groupby("estimator", sort=False):
        worst = {q: g[f"ratio_{q}"].max() for q in ("roll", "pitch", "yaw", "height")}
        print(f"{label:>13}: " + "  ".join(f"{q} {v:.3f}" for q, v in worst.items())
              + f"  not_ok {int(g['not_ok'].sum())}/{int(g['trials'].sum())}"
              + f"  {g['us_per_frame'].mean():.0f} us/frame")
    if args.csv:
        with atomic_path(args.csv) as tmp:
            df.to_csv(tmp, index=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
