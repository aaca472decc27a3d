"""A RENDERED two-ring approach, scored per height band: ok fraction, identification, honesty (issue 21 item 2).

Reads a run folder that ``deckpose pipeline`` made from a two-ring approach config (for
example ``configs/approach_tworing_descent.yaml``: rendered frames, ``cog`` detections,
``pnp`` estimates with identification by the prior) and scores its estimates against the
truth of the frames table, which the estimator never saw: per band of the true camera height
above the deck centre, the fraction ok, how the frames were identified, the beacons used,
ok estimates beyond 5 of their own sigmas in any of the six parameters, the RMS error in
own sigmas (``z``) and the RMS errors. With ``--no-prior-too`` the run's estimates are made
again without the prior (``deckpose estimate --run --no-prior``) in a copy of the run's tables,
and scored the same way, to show what the prior does.

    .venv/bin/deckpose pipeline configs/approach_tworing_descent.yaml RUN --method pnp --track \\
        --detect-at-render --no-images
    .venv/bin/python benchmarks/approach_tworing_rendered.py RUN --no-prior-too
"""

from __future__ import annotations

import argparse
import itertools
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.estimate.pose_model import params_from_relative
from deckpose.estimate.registry import parse_method
from deckpose.estimate.results_table import estimates_from_frame

from deckpose.pose import T_cam_from_deck
from deckpose.records import POSE_PARAMS
from deckpose.rotation import wrap_angle_rad
from deckpose.run_folder import frame_poses, read_estimates, read_frames, run_paths
from deckpose.sequence_run import estimate_run_with_prior

#: Band edges of the true height above the deck centre, metres (those of benchmarks/approach_tworing.py).
BANDS_M = (80.0, 40.0, 20.0, 13.0, 8.0, 4.0, 1.5)


def truth_params(frames: pd.DataFrame) -> np.ndarray:
    """The estimator's six parameters of each frame from the frames table's ship and camera poses, (F, 6)."""
    out = []
    for _, row in frames.iterrows():
        ship, cam = frame_poses(row)
        T = T_cam_from_deck(ship, cam)
        out.append(params_from_relative(T[:3, :3], T[:3, 3], cam.R_world_from_cam))
    return np.array(out)


def scored(frames: pd.DataFrame, estimates: pd.DataFrame) -> pd.DataFrame:
    """One row per frame: truth height, ok, identified_by, beacons used, error / own sigma (max over params)."""
    truth = truth_params(frames)
    by_id = {e.frame_id: e for e in estimates_from_frame(estimates)}
    ident = estimates.set_index("frame_id")["identified_by"]
    n_pts = estimates.set_index("frame_id")["n_points"]
    rows = []
    for k, fid in enumerate(frames["frame_id"].to_numpy(np.int64)):
        e = by_id[int(fid)]
        est = np.array([e.roll_rad, e.pitch_rad, e.yaw_rad, e.surge_m, e.sway_m, e.height_m])
        err = est - truth[k]
        err[:3] = wrap_angle_rad(err[:3])
        sig = np.sqrt(np.diag(e.covariance)) if e.covariance is not None else np.full(6, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.abs(err / sig)
        row: dict[str, object] = {"frame_id": int(fid), "true_height_m": float(truth[k][5]), "ok": bool(e.ok),
                                  "identified_by": ident.get(int(fid)), "n_points": n_pts.get(int(fid)),
                                  "reason": e.reason, "max_z": float(np.nanmax(z)) if np.isfinite(z).any() else math.nan}
        for j, n in enumerate(POSE_PARAMS):
            row[f"err_{n}"], row[f"z_{n}"] = float(err[j]), float(err[j] / sig[j])
        rows.append(row)
    return pd.DataFrame(rows)


def rms(a: pd.Series | np.ndarray) -> float:
    v = np.asarray(a, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else math.nan


def band_table(d: pd.DataFrame) -> pd.DataFrame:
    """Per height band: frames, ok %, by prior %, median beacons used, ok beyond 5 sigma, RMS z and errors."""
    out = []
    for hi, lo in itertools.pairwise(BANDS_M):
        b = d[(d["true_height_m"] <= hi) & (d["true_height_m"] > lo)]
        if not len(b):
            continue
        ok = b[b["ok"]]
        out.append({
            "band_m": f"{lo:g}-{hi:g}", "frames": len(b), "ok_pct": 100 * len(ok) / len(b),
            "by_prior_pct": 100 * float((b["identified_by"] == "prior").mean()),
            "median_used": float(ok["n_points"].median()) if len(ok) else math.nan,
            "ok_beyond_5_sigma": int((ok["max_z"] > 5).sum()),
            "rms_z_roll": rms(ok["z_roll_rad"]), "rms_z_height": rms(ok["z_height_m"]),
            "rms_roll_deg": math.degrees(rms(ok["err_roll_rad"])),
            "rms_pitch_deg": math.degrees(rms(ok["err_pitch_rad"])),
            "rms_height_m": rms(ok["err_height_m"]),
        })
    return pd.DataFrame(out)


def summary(label: str, d: pd.DataFrame) -> list[str]:
    ok = d["ok"].to_numpy(bool)
    lines = [(f"{label}: ok in {100 * ok.mean():.2f} % of {len(d)} frames from {d['true_height_m'].max():.1f} m "
             f"down to {d['true_height_m'].min():.2f} m; ok beyond 5 own sigmas: "
             f"{int((d.loc[ok, 'max_z'] > 5).sum())}; identified by the prior: "
             f"{int((d['identified_by'] == 'prior').sum())}")]
    for r, k in d.loc[~ok, "reason"].value_counts().head(3).items():
        lines.append(f"  not ok x{k}: {r[:300]}")
    return lines


def no_prior_estimates(run: Path, detector: str, method: str) -> pd.DataFrame:
    """The run's estimates made again with ``--no-prior``, in a copy of its tables (the run is not touched)."""
    with tempfile.TemporaryDirectory() as tmp:
        dst = Path(tmp) / "run"
        shutil.copytree(run, dst, ignore=shutil.ignore_patterns("images", "previews", "report", "*.mcap",
                                                                 "tracks", "evaluation"))
        estimate_run_with_prior(dst, parse_method(method), detector=detector, prior=False)
        return read_estimates(run_paths(dst), detector, method)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--detector", default="cog")
    ap.add_argument("--method", default="pnp")
    ap.add_argument("--no-prior-too", action="store_true", help="also score the estimates made without the prior")
    args = ap.parse_args(argv)
    paths = run_paths(args.run)
    frames = read_frames(paths)
    runs = [("with the prior", read_estimates(paths, args.detector, args.method))]
    if args.no_prior_too:
        runs.append(("--no-prior", no_prior_estimates(args.run, args.detector, args.method)))
    for label, est in runs:
        d = scored(frames, est)
        print("\n".join(summary(label, d)))
        with pd.option_context("display.width", 250, "display.max_columns", 30):
            print(band_table(d).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
