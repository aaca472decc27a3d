"""Monte Carlo efficiency and speed of the estimators against the Cramér–Rao bound.

For every cell (pixel noise sigma x camera height x camera preset) draw attitudes
from the thesis motion series, project the default layout (12-beacon ring of
radius 10 m + centre beacon) exactly into a nadir camera at ``height + heave``,
add isotropic Gaussian pixel noise, and run each estimator. Prints, per cell and
estimator, the RMS error of roll, pitch, yaw and height divided by the
Cramér–Rao bound (root of the mean CRB variance over the same trials), the
number of frames flagged not ok, and the CPU time per frame (one process, one
BLAS thread, one OpenCV thread) two ways: one ``run_estimator`` call per frame,
and the whole cell in one ``estimate_batch`` call; their ratio; and how many
frames the two disagree on (ok flag, reason, or a pose by more than 2e-3 sigma).
The errors are those of the batched estimates.

``pnp+mean`` and ``conic+mean`` report the posterior mean under a uniform prior
(``EstimateOptions.posterior_mean``) instead of the maximum-likelihood pose of
``pnp`` and ``conic+refine``: a biased estimator, whose error the bound (which
holds for unbiased ones) does not limit.

``thesis`` is the faithful thesis estimator: its own angles (``R = Rx Ry Rz``)
are converted to our ZYX convention by the estimator itself, so its errors are
compared with the same bound. It gives no surge or sway (it assumes the deck
centre under the camera, which holds here), so its roll and pitch can sit below
the 6-DoF bound.

Run::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_estimators.py --trials 2000
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_estimators.py --speed 2000
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import math
import platform
import re
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from deckpose.estimate import registry
from deckpose.estimate.batch import estimate_batch, run_estimator
from deckpose.estimate.crb import cramer_rao_bound
from deckpose.estimate.registry import EstimateOptions

from deckpose.atomic_io import atomic_path
from deckpose.camera import CameraModel, preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import POSE_PARAMS, Detections, PoseEstimate
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
    ("conic+mean", "conic", {"posterior_mean": True}),
    ("pnp+mean", "pnp", {"posterior_mean": True}),
    ("thesis", "thesis", {}),
)
#: The issue's targets: RMS / CRB at most this in every cell.
TARGETS = {"pnp": 1.05, "conic+refine": 1.05, "conic": 3.0, "pnp+mean": 1.05, "conic+mean": 1.05}
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


def make_cell(sigma_px: float, height_m: float, cam_name: str, motion: np.ndarray, trials: int,
              rng: np.random.Generator, crb_cache: dict) -> tuple[list[Detections], np.ndarray, np.ndarray]:
    """One cell's noisy detections, true (roll, pitch, yaw, height) and CRB variances, both (trials, 4)."""
    camera = preset(cam_name)
    layout = DeckLayout()
    samples = rng.integers(0, len(motion), trials)
    dets, truth, crb = [], [], []
    for k in samples:
        roll, pitch, yaw, heave = motion[k]
        ship = ShipPose(roll, pitch, yaw)
        cam_pose = CameraPose.nadir(height_m + heave)
        key = (cam_name, height_m, int(k))
        if key not in crb_cache:
            crb_cache[key] = np.diag(cramer_rao_bound(layout, camera, ship, cam_pose, 1.0).covariance)[[0, 1, 2, 5]]
        crb.append(crb_cache[key] * sigma_px**2)
        proj = project_layout(layout, ship, cam_pose, camera)
        ids = np.flatnonzero(proj.visible)
        pts = proj.points_px[ids] + rng.normal(0.0, sigma_px, (len(ids), 2))
        dets.append(Detections(pts, ids, np.broadcast_to(np.eye(2) * sigma_px**2, (len(ids), 2, 2))))
        truth.append([roll, pitch, yaw, height_m + heave])
    return dets, np.array(truth), np.array(crb)


def time_variant(name: str, dets: list[Detections], camera: CameraModel, layout: DeckLayout,
                 opts: EstimateOptions, *, single: bool = True
                 ) -> tuple[list[PoseEstimate], float, list[PoseEstimate] | None, float]:
    """Batched estimates and CPU seconds; the single-frame calls' estimates and seconds (if ``single``)."""
    t0 = time.process_time()
    batched = estimate_batch(name, dets, camera, layout, opts)
    t_batch = time.process_time() - t0
    if not single:
        return batched, t_batch, None, math.nan
    t0 = time.process_time()
    singles = [run_estimator(name, d, camera, layout, opts) for d in dets]
    return batched, t_batch, singles, time.process_time() - t0


def disagreements(batched: list[PoseEstimate], singles: list[PoseEstimate]) -> int:
    """Frames where batch and single-frame calls differ: ok flag, or a pose by more than 2e-3 sigma."""
    n = 0
    for b, s in zip(batched, singles):
        if b.ok != s.ok or b.reason != s.reason:
            n += 1
        elif s.ok:
            pb = np.array([getattr(b, q) for q in POSE_PARAMS])
            ps = np.array([getattr(s, q) for q in POSE_PARAMS])
            if s.covariance is not None:
                tol = 2e-3 * np.sqrt(np.diag(s.covariance))
            else:
                tol = 1e-9 * (1.0 + np.abs(ps))
            with np.errstate(invalid="ignore"):
                bad = ~(np.abs(pb - ps) <= tol) & ~(np.isnan(pb) & np.isnan(ps))
            n += int(np.any(bad))
    return n


def run_cell(sigma_px: float, height_m: float, cam_name: str, motion: np.ndarray, trials: int,
             variants: list[tuple[str, str, dict]], rng: np.random.Generator,
             crb_cache: dict, *, single: bool = True) -> list[dict]:
    camera = preset(cam_name)
    layout = DeckLayout()
    dets, truth, crb_var = make_cell(sigma_px, height_m, cam_name, motion, trials, rng, crb_cache)
    rows = []
    for label, name, over in variants:
        opts = dataclasses.replace(EstimateOptions(sigma_px=sigma_px), **over)
        ests, t_batch, singles, t_single = time_variant(name, dets, camera, layout, opts, single=single)
        ok = np.array([e.ok for e in ests])
        reasons: dict[str, int] = {}
        for e in ests:
            if not e.ok:
                key_r = re.sub(r"-?\d+(\.\d+)?", "#", e.reason.split(";")[0])[:70]
                reasons[key_r] = reasons.get(key_r, 0) + 1
        E = np.array([[e.roll_rad, e.pitch_rad, e.yaw_rad, e.height_m] for e in ests]).reshape(-1, 4)[ok] - truth[ok]
        E[:, :3] = (E[:, :3] + np.pi) % (2 * np.pi) - np.pi
        V = crb_var[ok]
        rms = np.sqrt(np.mean(E**2, axis=0)) if len(E) else np.full(4, np.nan)
        crb = np.sqrt(np.mean(V, axis=0)) if len(V) else np.full(4, np.nan)
        row = {"sigma_px": sigma_px, "height_m": height_m, "camera": cam_name, "estimator": label,
               "trials": trials, "not_ok": int((~ok).sum()),
               "us_per_frame": 1e6 * t_single / trials, "us_per_frame_batch": 1e6 * t_batch / trials,
               "batch_disagreements": disagreements(ests, singles) if singles is not None else -1,
               "not_ok_reasons": "; ".join(f"{r} x{n}" for r, n in reasons.items())}
        for q, r_, c_ in zip(QUANTITIES, rms, crb):
            row[f"rms_{q}"] = r_
            row[f"crb_{q}"] = c_
            row[f"ratio_{q.split('_')[0]}"] = r_ / c_
        rows.append(row)
    return rows


def speed_table(variants: list[tuple[str, str, dict]], frames: int, repeats: int, seed: int) -> None:
    """Per-frame CPU time of single-frame calls and of one batch: 8 MP, 30 m, sigma 0.5 px, best of ``repeats``."""
    camera, layout = preset("8mp"), DeckLayout()
    rng = np.random.default_rng(seed)
    motion = load_attitudes(None)
    dets, _, _ = make_cell(0.5, 30.0, "8mp", motion, frames, rng, {})
    print(f"# speed: {frames} frames, 8mp, 30 m, sigma 0.5 px, CPU time of one process "
          f"(1 BLAS thread, cv2 1 thread), best of {repeats}")
    print(f"{'estimator':>13} {'single us/frame':>16} {'batch us/frame':>15} {'ratio':>6}")
    for label, name, over in variants:
        opts = dataclasses.replace(EstimateOptions(sigma_px=0.5), **over)
        t_b, t_s = math.inf, math.inf
        for _ in range(repeats):
            _, tb, _, ts = time_variant(name, dets, camera, layout, opts)
            t_b, t_s = min(t_b, tb), min(t_s, ts)
        print(f"{label:>13} {1e6 * t_s / frames:>16.1f} {1e6 * t_b / frames:>15.1f} {t_s / t_b:>6.1f}", flush=True)


def markdown_tables(df: pd.DataFrame, targets: dict[str, float]) -> str:
    """Per-cell Markdown tables (ratio RMS / CRB, bold above the estimator's target) of a results CSV."""
    out = []
    for label, g in df.groupby("estimator", sort=False):
        limit = targets.get(label, math.inf)
        out += [f"### `{label}`", "",
                "| σ px | H m | camera | roll | pitch | yaw | height | not ok | µs/frame single | µs/frame batch |",
                "|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
        for _, r in g.iterrows():
            cells = [f"**{r[f'ratio_{q}']:.3f}**" if r[f"ratio_{q}"] > limit else f"{r[f'ratio_{q}']:.3f}"
                     for q in ("roll", "pitch", "yaw", "height")]
            out.append(f"| {r.sigma_px:g} | {r.height_m:g} | {r.camera} | " + " | ".join(cells)
                       + f" | {int(r.not_ok)} | {r.us_per_frame:.0f} | {r.us_per_frame_batch:.0f} |")
        out.append("")
    return "\n".join(out)


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
    ap.add_argument("--no-single", action="store_true",
                    help="time only the batch (skip the single-frame calls and the agreement check)")
    ap.add_argument("--speed", type=int, default=0, metavar="FRAMES",
                    help="only the speed table: FRAMES frames at 8mp, 30 m, sigma 0.5 px, best of 3")
    ap.add_argument("--tables-from", type=Path, default=None, metavar="CSV",
                    help="only print the per-cell Markdown tables of a CSV this script wrote")
    args = ap.parse_args(argv)
    if args.tables_from is not None:
        print(markdown_tables(pd.read_csv(args.tables_from),
                              TARGETS))
        return 0
    known = set(registry.names())
    variants = [v for v in VARIANTS if v[0] in args.estimators and v[1] in known]
    skipped = [v[0] for v in VARIANTS if v[0] in args.estimators and v[1] not in known]
    if skipped:
        print(f"# not registered, skipped: {', '.join(skipped)}")
    if args.speed:
        speed_table(variants, args.speed, 3, args.seed)
        return 0
    motion = load_attitudes(args.motion)
    rng = np.random.default_rng(args.seed)
    print(f"# {platform.processor() or platform.machine()}, python {sys.version.split()[0]}, "
          f"numpy {np.__version__}, opencv {cv2.__version__}; trials/cell {args.trials}; seed {args.seed}")
    print(f"{'sigma':>5} {'H':>4} {'cam':>5} {'estimator':>13} {'notok':>5} "
          f"{'roll':>6} {'pitch':>6} {'yaw':>6} {'height':>6} {'us/frame':>9} {'batch':>6} {'ratio':>6} "
          f"{'differ':>6}")
    rows: list[dict] = []
    crb_cache: dict = {}
    for s in args.sigmas:
        for h in args.heights:
            for c in args.cameras:
                for row in run_cell(s, h, c, motion, args.trials, variants, rng, crb_cache,
                                    single=not args.no_single):
                    rows.append(row)
                    print(f"{s:>5g} {h:>4g} {c:>5} {row['estimator']:>13} {row['not_ok']:>5d} "
                          f"{row['ratio_roll']:>6.3f} {row['ratio_pitch']:>6.3f} {row['ratio_yaw']:>6.3f} "
                          f"{row['ratio_height']:>6.3f} {row['us_per_frame']:>9.0f} "
                          f"{row['us_per_frame_batch']:>6.0f} "
                          f"{row['us_per_frame'] / row['us_per_frame_batch']:>6.1f} "
                          f"{row['batch_disagreements']:>6d}", flush=True)
    df = pd.DataFrame(rows)
    print("\n# worst ratio to the Cramér–Rao bound over all cells; mean CPU us/frame of single-frame calls "
          "and of the batch, their ratio; frames where batch and single-frame calls differ")
    for label, g in df.groupby("estimator", sort=False):
        worst = {q: g[f"ratio_{q}"].max() for q in ("roll", "pitch", "yaw", "height")}
        print(f"{label:>13}: " + "  ".join(f"{q} {v:.3f}" for q, v in worst.items())
              + f"  not_ok {int(g['not_ok'].sum())}/{int(g['trials'].sum())}"
              + f"  {g['us_per_frame'].mean():.0f} us/frame single, {g['us_per_frame_batch'].mean():.0f} batch"
              + f" ({g['us_per_frame'].mean() / g['us_per_frame_batch'].mean():.1f}x)"
              + f"  differ {int(g['batch_disagreements'].sum())}")
    if args.csv:
        with atomic_path(args.csv) as tmp:
            df.to_csv(tmp, index=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
