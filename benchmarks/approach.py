"""A sea-state-6 approach: per-frame estimates, the tracking filter and its prediction against the truth.

The frames are those ``deckpose render`` plans for an approach config (default
``configs/approach_ss6.yaml``: sea state 6, 80 m down to 25 m over 90 s at 10 Hz, 8 MP, UAV
drift and attitude wobble): the same deck and camera poses, on one time base. Detections are
SYNTHESISED, not rendered: each frame's visible beacons are projected exactly
(``deckpose.projection.project_layout``) and given independent Gaussian noise of ``--sigma-px``
per axis (default 0.2 px: a centroid Cramér-Rao level for bright, unsaturated night spots; the
detections carry that covariance), with their true ids. The estimator is told each frame's
camera attitude (the IMU's), as the render stage tells it. Per-frame estimates are ``pnp``
(``deckpose.estimate.estimate_batch``); the tracker is ``deckpose track``'s ``wave-bank`` filter
(``deckpose.tracking.track_table``) with ``--track-config`` (default
``configs/track/sea_state_6.yaml``: the tracker is told the sea state, heading, speed and ship,
and fits its oscillator bank to that sea's response spectra; it never sees the truth or the
random draw of the sea). One default was changed after looking at this benchmark: the UAV's
vertical acceleration intensity, 0.2 -> 1.0 m/s^2/sqrt(Hz), as 0.2 lagged the descent's
climb-rate steps by up to 6.8 of the filter's own sigmas. The bank's grid and damping
(24 periods 4-26 s, damping 0.02) were chosen on seed 6 of sea state 6 among four grids;
the other seeds and sea state 4 check them.

The filtered error is compared with the least any causal filter can reach
(``deckpose.tracking.filter_bound``): the Kolmogorov-Szego bound for the sea's roll and
pitch spectra (of the render config's sea, evaluation side only) in white noise of each
frame's own estimate variance.

Prints the issue's targets and writes, with ``--out DIR``, ``README.md`` (command, machine,
load, tables), ``frames.csv`` (per-frame truth, estimate, filtered and 1 s-predicted roll,
pitch, height) and ``error_vs_time.png``.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/approach.py --out reports/approach_ss6``
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pandas as pd
from deckpose.estimate import EstimateOptions, estimate_batch
from deckpose.render.config import load_config
from deckpose.render.plan import plan_frames

from deckpose.estimates_schema import COVARIANCE_COLUMNS
from deckpose.projection import project_layout
from deckpose.records import Detections
from deckpose.tracking.config import TrackConfig, load_track_config
from deckpose.tracking.deck_motion_model import discretise, measurement_matrix, prior, state_size
from deckpose.tracking.filter_bound import optimal_filtered_variance
from deckpose.tracking.kalman import kalman_predict, kalman_update
from deckpose.tracking.landing_window import (
    LandingLimits,
    landing_window_go,
    truth_window_calm,
)
from deckpose.tracking.measurements import measurements_from_estimates
from deckpose.tracking.run import track_table
from deckpose.tracking.sea_prior import SeaPrior, encounter_spectra
from deckpose.tracking.sequence_filter import ANGLE_ROWS, FilterTrack, filter_sequence, gate_nis

HORIZONS_S = (0.5, 1.0, 2.0, 5.0)


def synthesise(args: argparse.Namespace) -> tuple[pd.DataFrame, pd.DataFrame, list[Detections], np.ndarray]:
    """Truth frames, per-frame pnp estimates, the detections and each frame's camera attitude.

    The frames are the render plan of ``args.config`` (an ``approach:`` config): the deck and
    camera poses ``deckpose render`` would draw, at mid-exposure.
    """
    cfg = load_config(args.config)
    if cfg.approach is None or len(cfg.cameras) != 1:
        raise SystemExit(f"{args.config}: give a render config with an approach: section and one camera")
    if getattr(args, "motion_seed", None) is not None:   # another draw of the same sea
        params = tuple((k, args.motion_seed if k == "seed" else v) for k, v in cfg.motion.params)
        cfg = dataclasses.replace(cfg, motion=dataclasses.replace(cfg.motion, params=params))
    args.motion_seed_used = dict(cfg.motion.params).get("seed")
    plan = plan_frames(cfg)
    (name, cam), = cfg.cameras_by_name().items()
    rng = np.random.default_rng(args.seed)
    dets, R_wc, rows = [], [], []
    for f in plan:
        cp = f.camera_pose
        proj = project_layout(cfg.layout, f.ship, cp, cam)
        ids = np.flatnonzero(proj.visible)
        pts = proj.points_px[ids] + rng.normal(0.0, args.sigma_px, (len(ids), 2))
        cov = np.broadcast_to(np.eye(2) * args.sigma_px ** 2, (len(ids), 2, 2))
        dets.append(Detections(pts, ids, cov, frame_id=f.frame_id))
        R_wc.append(cp.R_world_from_cam)
        x, y, z = cp.position_world_m
        rows.append({"frame_id": f.frame_id, "camera": name, "camera_height_m": f.height_m,
                     "lighting": f.lighting.value, "stamp_ns": f.stamp_ns, "t_s": f.t_s - plan[0].t_s,
                     "roll_rad": f.ship.roll_rad, "pitch_rad": f.ship.pitch_rad, "yaw_rad": f.ship.yaw_rad,
                     "heave_m": f.ship.heave_m, "true_surge_m": f.ship.surge_m - x, "true_sway_m": f.ship.sway_m - y,
                     "true_height_m": z - f.ship.heave_m, "uav_height_m": z, "n_visible": len(ids)})
    frames = pd.DataFrame(rows)
    R = np.array(R_wc)
    res = estimate_batch("pnp", dets, cam, cfg.layout, EstimateOptions(sigma_px=args.sigma_px),
                         R_world_from_cam=R)
    args.rate_hz, args.camera, args.layout = cfg.approach.rate_hz, name, cfg.layout
    args.duration_s = cfg.approach.duration_s
    args.sea = dict(dict(cfg.motion.params).get("sea") or {})
    return frames, estimates_table(res), dets, R


def estimates_table(results: list) -> pd.DataFrame:
    """The estimates-table columns the tracker reads, from the estimator's records."""
    rows = []
    for r in results:
        row = {"frame_id": r.frame_id, "method": r.method, "ok": bool(r.ok), "reason": r.reason,
               "roll_deg": math.degrees(r.roll_rad), "pitch_deg": math.degrees(r.pitch_rad),
               "yaw_deg": math.degrees(r.yaw_rad), "surge_m": r.surge_m, "sway_m": r.sway_m,
               "height_m": r.height_m}
        cov = r.covariance if r.covariance is not None else np.full((6, 6), np.nan)
        row.update({name: cov[i, j] for name, i, j in COVARIANCE_COLUMNS})
        rows.append(row)
    return pd.DataFrame(rows)


def time_one_frame(args: argparse.Namespace, dets: list[Detections], R: np.ndarray, estimates: pd.DataFrame,
                   config: TrackConfig) -> tuple[float, float]:
    """Median thread CPU time of one frame's estimate alone and of one filter step (predict + update), ms."""
    cam = load_config(args.config).cameras_by_name()[args.camera]
    layout, opts = args.layout, EstimateOptions(sigma_px=args.sigma_px)
    idx = np.linspace(0, len(dets) - 1, min(200, len(dets))).astype(int)
    est_ms = []
    for i in idx:
        t0 = time.thread_time()
        estimate_batch("pnp", [dets[i]], cam, layout, opts, R_world_from_cam=R[i:i + 1])
        est_ms.append(1e3 * (time.thread_time() - t0))
    m = measurements_from_estimates(estimates, estimates["frame_id"].to_numpy())
    model = config.model
    H = measurement_matrix(model)
    d = discretise(model, 1.0 / args.rate_hz)
    gate = gate_nis(config.gate_probability)
    filt_ms = []
    x, P = prior(model)
    for i in range(len(m.z)):
        t0 = time.thread_time()
        x, P = kalman_predict(x, P, d.F, d.Q)
        if m.usable[i]:
            up = kalman_update(x, P, m.z[i], m.R[i], H, gate_nis=gate if i else math.inf, angle_rows=ANGLE_ROWS)
            if up.accepted:
                x, P = up.x, up.P
        filt_ms.append(1e3 * (time.thread_time() - t0))
    return float(np.median(est_ms)), float(np.median(filt_ms))


def rms(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a * a))) if a.size else math.nan


def evaluate(args: argparse.Namespace, frames: pd.DataFrame, est: pd.DataFrame, tracks: pd.DataFrame,
             preds: pd.DataFrame, config: TrackConfig) -> tuple[dict[str, object], pd.DataFrame]:
    f = frames.set_index("frame_id")
    e = est.set_index("frame_id").loc[f.index]
    tr = tracks.set_index("frame_id").loc[f.index]
    ok = e["ok"].to_numpy(bool)
    truth_deg = {q: np.degrees(f[f"{q}_rad"].to_numpy()) for q in ("roll", "pitch")}
    out: dict[str, object] = {"n_frames": len(f), "ok_fraction": float(ok.mean())}
    warm = f["t_s"].to_numpy() >= args.warmup_s
    above = f["true_height_m"].to_numpy() > 20.0
    sel = warm & above
    table = pd.DataFrame({"t_s": f["t_s"], "true_height_m": f["true_height_m"], "ok": ok})
    for q in ("roll", "pitch"):
        raw = np.where(ok, e[f"{q}_deg"].to_numpy() - truth_deg[q], np.nan)
        filt = tr[f"{q}_deg"].to_numpy() - truth_deg[q]
        out[f"{q}_raw_rms_deg"], out[f"{q}_filt_rms_deg"] = rms(raw[sel]), rms(filt[sel])
        out[f"{q}_ratio"] = out[f"{q}_filt_rms_deg"] / out[f"{q}_raw_rms_deg"]  # type: ignore[operator]
        table[f"{q}_err_estimate_deg"], table[f"{q}_err_filtered_deg"] = raw, filt
    # the least any causal filter can reach on this sea with these frames' own estimate noise
    spectra = sea_spectra(args)
    for q in ("roll", "pitch"):
        var = e[f"cov_{q}_rad__{q}_rad"].to_numpy()[sel & ok]
        e_opt = bound_variance(spectra, q, var, 1.0 / args.rate_hz)
        out[f"{q}_bound_rms_deg"] = math.degrees(math.sqrt(float(np.mean(e_opt))))
        out[f"{q}_bound_ratio"] = out[f"{q}_bound_rms_deg"] / out[f"{q}_raw_rms_deg"]  # type: ignore[operator]
    h_raw = np.where(ok, e["height_m"].to_numpy() - f["true_height_m"].to_numpy(), np.nan)
    h_filt = tr["height_m"].to_numpy() - f["true_height_m"].to_numpy()
    out["height_raw_rms_m"], out["height_filt_rms_m"] = rms(h_raw[sel]), rms(h_filt[sel])
    table["height_err_estimate_m"], table["height_err_filtered_m"] = h_raw, h_filt
    # an ok per-frame estimate beyond 5 of its own sigmas (roll, pitch or height)
    bad = np.zeros(len(f), bool)
    for q, err in (("roll_rad", np.radians(table["roll_err_estimate_deg"].to_numpy())),
                   ("pitch_rad", np.radians(table["pitch_err_estimate_deg"].to_numpy())),
                   ("height_m", h_raw)):
        bad |= np.abs(err) > 5 * np.sqrt(e[f"cov_{q}__{q}"].to_numpy())
    out["ok_beyond_5_sigma"] = int((bad & ok).sum())
    # honesty: errors in units of their own sigmas
    for name, err, sig in (("estimate roll", np.radians(table["roll_err_estimate_deg"]),
                            np.sqrt(e["cov_roll_rad__roll_rad"].to_numpy())),
                           ("filtered roll", np.radians(table["roll_err_filtered_deg"]),
                            np.sqrt(tr["cov_roll_rad__roll_rad"].to_numpy())),
                           ("filtered pitch", np.radians(table["pitch_err_filtered_deg"]),
                            np.sqrt(tr["cov_pitch_rad__pitch_rad"].to_numpy())),
                           ("filtered height", h_filt, tr["sigma_height_m"].to_numpy())):
        z = np.abs(np.asarray(err) / sig)[warm]
        z = z[np.isfinite(z)]
        out[f"{name} > 5 sigma"] = int((z > 5).sum())
        out[f"{name} rms z"] = rms(z)
    # prediction against holding the last estimate (the last ok one), per horizon
    t = f["t_s"].to_numpy()
    held = e[["roll_deg", "pitch_deg", "height_m"]].where(np.repeat(ok[:, None], 3, axis=1)).ffill()
    pred_rows = []
    for h in config.horizons_s:
        k = round(h * args.rate_hz)
        i = np.flatnonzero(warm[: len(t) - k])
        p = preds[preds["horizon_s"] == h].set_index("frame_id").loc[f.index[i]]
        row: dict[str, object] = {"horizon_s": h}
        for q, truth in (("roll_deg", truth_deg["roll"]), ("pitch_deg", truth_deg["pitch"]),
                         ("height_m", f["true_height_m"].to_numpy())):
            pe = p[q].to_numpy() - truth[i + k]
            he = held[q].to_numpy()[i] - truth[i + k]
            row[f"{q} pred"], row[f"{q} hold"], row[f"{q} ratio"] = rms(pe), rms(he), rms(pe) / rms(he)
            row[f"{q} z"] = rms(pe / p[f"sigma_{q}"].to_numpy())
        true_rate = np.gradient(f["heave_m"].to_numpy(), t)
        row["heave_rate_m_per_s pred"] = rms(p["heave_rate_m_per_s"].to_numpy() - true_rate[i + k])
        row["heave_rate_m_per_s hold"] = rms(tr["heave_rate_m_per_s"].to_numpy()[i] - true_rate[i + k])
        row["heave_rate_m_per_s z"] = rms((p["heave_rate_m_per_s"].to_numpy() - true_rate[i + k])
                                          / p["sigma_heave_rate_m_per_s"].to_numpy())
        pred_rows.append(row)
        if h == 1.0:
            for col, err in (("roll_err_predicted_1s_deg", p["roll_deg"].to_numpy() - truth_deg["roll"][i + k]),
                             ("roll_err_hold_1s_deg", held["roll_deg"].to_numpy()[i] - truth_deg["roll"][i + k])):
                table[col] = np.nan
                table.iloc[i + k, table.columns.get_loc(col)] = err
    out["prediction"] = pd.DataFrame(pred_rows)
    bins = [0.0, 20.0, 40.0, 60.0, 100.0]
    hb = pd.cut(table["true_height_m"], bins)
    by_h = []
    for b, g in table[warm].groupby(hb[warm], observed=True):
        by_h.append({"true height (m)": f"{b.left:g}-{b.right:g}", "frames": len(g),
                     "roll per-frame": rms(g["roll_err_estimate_deg"].to_numpy()),
                     "roll filtered": rms(g["roll_err_filtered_deg"].to_numpy()),
                     "pitch per-frame": rms(g["pitch_err_estimate_deg"].to_numpy()),
                     "pitch filtered": rms(g["pitch_err_filtered_deg"].to_numpy()),
                     "height per-frame": rms(g["height_err_estimate_m"].to_numpy()),
                     "height filtered": rms(g["height_err_filtered_m"].to_numpy())})
    out["by_height"] = pd.DataFrame(by_h)
    # landing window: how often "go" when the truth leaves the limits within the window
    true_rate = np.gradient(f["heave_m"].to_numpy(), t)
    win_rows = []
    state = tracks_state(frames, est, config)
    for lim in scored_limits(config):
        calm = truth_window_calm(t, f["roll_rad"].to_numpy(), f["pitch_rad"].to_numpy(), true_rate, lim)
        go = landing_window_go(state.x, state.P, config.model, lim)
        if lim == config.landing and not np.array_equal(go, tr["landing_go"].to_numpy(bool)):
            raise RuntimeError("the track table's landing_go differs from the filter state's indicator")
        scored = np.isfinite(calm) & warm
        n_go = int((go & scored).sum())
        false_go = int((go & scored & (calm == 0)).sum())
        n_calm = int((scored & (calm == 1)).sum())
        win_rows.append({"limits": f"roll < {lim.roll_deg:g} deg, pitch < {lim.pitch_deg:g} deg, heave rate < "
                                   f"{lim.heave_rate_m_per_s:g} m/s for {lim.window_s:g} s, "
                                   f"confidence {lim.confidence:g}",
                         "frames scored": int(scored.sum()), "truly calm": n_calm, "go": n_go,
                         "false go": false_go, "false-go rate": false_go / n_go if n_go else math.nan,
                         "calm frames found": int((go & scored & (calm == 1)).sum()) / n_calm if n_calm else math.nan})
    out["landing"] = pd.DataFrame(win_rows)
    return out, table


def scored_limits(config: TrackConfig) -> tuple[LandingLimits, ...]:
    """The limits the landing window is scored at: the config's, then wider and narrower ones."""
    return (config.landing,
            LandingLimits(roll_deg=3.0, pitch_deg=2.0, heave_rate_m_per_s=1.0),
            LandingLimits(roll_deg=5.0, pitch_deg=3.0, heave_rate_m_per_s=1.0),
            LandingLimits(roll_deg=3.0, pitch_deg=2.0, heave_rate_m_per_s=1.5),
            LandingLimits(roll_deg=5.0, pitch_deg=3.0, heave_rate_m_per_s=1.5),
            LandingLimits(roll_deg=5.0, pitch_deg=3.0, heave_rate_m_per_s=1.5, confidence=0.99),
            LandingLimits(roll_deg=8.0, pitch_deg=4.0, heave_rate_m_per_s=1.5),
            LandingLimits(roll_deg=5.0, pitch_deg=3.0, heave_rate_m_per_s=1.5, window_s=6.0))


def sea_spectra(args: argparse.Namespace) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The render config's sea (the truth's generator, used on the evaluation side only): roll/pitch spectra."""
    sea = args.sea
    prior = SeaPrior(**{k: sea[k] for k in ("sea_state", "hs_m", "tp_s", "heading_deg", "speed_kn", "spectrum")
                        if k in sea})
    omega = np.linspace(0.005, 12.0, 6000)
    return omega, encounter_spectra(prior, omega)


def bound_variance(spectra: tuple[np.ndarray, dict[str, np.ndarray]], channel: str, noise_var: np.ndarray,
                   dt_s: float) -> np.ndarray:
    """Least causal-filter error variance for each frame's noise variance (interpolated on a log grid of 40)."""
    omega, dens = spectra
    grid = np.geomspace(float(noise_var.min()), float(noise_var.max()) * 1.0001, 40)
    e = optimal_filtered_variance(omega, dens[channel], grid, dt_s)
    return np.interp(np.log(noise_var), np.log(grid), e)


def tracks_state(frames: pd.DataFrame, est: pd.DataFrame, config: TrackConfig) -> FilterTrack:
    """The filter's full states over the approach (one sequence), as ``track_table`` runs it."""
    m = measurements_from_estimates(est, frames["frame_id"].to_numpy())
    t = (frames["stamp_ns"].to_numpy() - frames["stamp_ns"].iloc[0]) / 1e9
    return filter_sequence(t, m.z, m.R, m.usable, config.model, gate_probability=config.gate_probability,
                           reacquire_after=config.reacquire_after)


def plot(table: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    t = table["t_s"]
    ax[0].plot(t, table["true_height_m"], "k-")
    ax[0].set_ylabel("camera above deck (m)")
    ax[0].axhline(20, color="0.6", lw=0.8, ls="--")
    for k, q in ((1, "roll"), (2, "pitch")):
        ax[k].plot(t, table[f"{q}_err_estimate_deg"], ".", ms=2, color="0.6", label="per-frame estimate")
        ax[k].plot(t, table[f"{q}_err_filtered_deg"], "-", lw=1, color="C0", label="filtered")
        ax[k].set_ylabel(f"{q} error (deg)")
        ax[k].legend(loc="upper right", fontsize=8)
    ax[3].plot(t, table["roll_err_hold_1s_deg"], "-", lw=0.8, color="0.5", label="last estimate held 1 s")
    ax[3].plot(t, table["roll_err_predicted_1s_deg"], "-", lw=0.8, color="C3", label="predicted 1 s ahead")
    ax[3].set_ylabel("roll error 1 s ahead (deg)")
    ax[3].legend(loc="upper right", fontsize=8)
    ax[3].set_xlabel("time (s)")
    fig.suptitle("Sea-state-6 approach: error against time")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", type=Path, default=Path("configs/approach_ss6.yaml"),
                    help="render config with an approach: section (its frames' poses are used)")
    ap.add_argument("--sigma-px", type=float, default=0.2, help="detection noise per axis, px")
    ap.add_argument("--warmup-s", type=float, default=5.0, help="filter warm-up left out of the scores")
    ap.add_argument("--seed", type=int, default=6, help="seed of the detection noise")
    ap.add_argument("--sweep-sigma-px", type=float, nargs="*", default=[0.5, 1.0],
                    help="also report the filtered/per-frame ratio at these detection noises (px)")
    ap.add_argument("--track-config", type=Path, default=Path("configs/track/sea_state_6.yaml"),
                    help="the tracker's config (deckpose track --config)")
    ap.add_argument("--more-seeds", type=int, nargs="*", default=[7, 8],
                    help="also score these detection-noise seeds (summary table)")
    ap.add_argument("--other", nargs=2, action="append", metavar=("CONFIG", "TRACK_CONFIG"),
                    default=None, help="also score this render config with this tracker config, at every seed "
                    "(default: configs/approach_ss4.yaml with configs/track/sea_state_4.yaml)")
    ap.add_argument("--out", type=Path, default=None, help="write README.md, frames.csv, error_vs_time.png here")
    args = ap.parse_args()
    others = args.other if args.other is not None else [["configs/approach_ss4.yaml",
                                                         "configs/track/sea_state_4.yaml"]]
    config = dataclasses.replace(load_track_config(args.track_config), horizons_s=HORIZONS_S)
    c0 = time.process_time()
    frames, est, dets, R = synthesise(args)
    tracks, preds = track_table(frames, est, config)
    res, table = evaluate(args, frames, est, tracks, preds, config)
    est_ms, filt_ms = time_one_frame(args, dets, R, est, config)
    sweep = []
    for sig in args.sweep_sigma_px:
        a2 = argparse.Namespace(**{**vars(args), "sigma_px": sig})
        f2, e2, _, _ = synthesise(a2)
        t2, p2 = track_table(f2, e2, config)
        r2, _ = evaluate(a2, f2, e2, t2, p2, config)
        sweep.append((sig, r2))
    summary = [summary_row(args, config, str(args.track_config), res)]
    default_cfg = TrackConfig(horizons_s=HORIZONS_S)
    t_d, p_d = track_table(frames, est, default_cfg)
    summary.append(summary_row(args, default_cfg, "defaults (not told the sea)",
                               evaluate(args, frames, est, t_d, p_d, default_cfg)[0]))
    # more seeds: each a new draw of the detection noise AND of the sea (the motion series' seed)
    runs = [(args.config, args.track_config, config, s, s) for s in args.more_seeds]
    for cfg_path, tc_path in others:
        tc = dataclasses.replace(load_track_config(Path(tc_path)), horizons_s=HORIZONS_S)
        runs += [(Path(cfg_path), Path(tc_path), tc, s, m) for s, m in [(args.seed, None),
                                                                          *((s, s) for s in args.more_seeds)]]
    for cfg_path, tc_path, tc, seed, motion_seed in runs:
        a2 = argparse.Namespace(**{**vars(args), "config": cfg_path, "seed": seed, "motion_seed": motion_seed})
        f2, e2, _, _ = synthesise(a2)
        t2, p2 = track_table(f2, e2, tc)
        summary.append(summary_row(a2, tc, str(tc_path), evaluate(a2, f2, e2, t2, p2, tc)[0]))
    cpu_s = time.process_time() - c0
    load = os.getloadavg()
    a = load_config(args.config).approach
    assert a is not None
    approach_text = (f"heights {list(a.heights_m)} m at {list(a.times_s)} s, {a.rate_hz:g} Hz, drift {a.drift_m:g} m, "
                     f"wobble {a.wobble_deg:g} deg")
    lines = [(f"# Approach: tracking and prediction ({args.config}: {args.duration_s:g} s at {args.rate_hz:g} Hz, "
             f"{args.camera})"), "",
             "Made by (from the repository root):", "",
             f"    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/approach.py {' '.join(sys.argv[1:])}", "",
             (f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
             f"1/5/15-min load at the end {load[0]:.1f}/{load[1]:.1f}/{load[2]:.1f}; "
             f"{cpu_s:.0f} s CPU in all; commit {_commit()}."), "",
             ("Detections are synthesised (exact projection + Gaussian noise of "
             f"{args.sigma_px:g} px per axis), not rendered, on the render plan's poses of {args.config} "
             f"(approach: {approach_text}); see the benchmark's docstring. The estimator is told each frame's "
             f"camera attitude. Scores leave out the first {args.warmup_s:g} s (filter warm-up)."), "",
             (f"Per-frame estimates ok: {res['ok_fraction']:.1%} of {res['n_frames']} frames (true heights "
             f"{frames['true_height_m'].min():.1f}-{frames['true_height_m'].max():.1f} m); ok with roll, pitch or "
             f"height beyond 5 of its own sigmas: {res['ok_beyond_5_sigma']}."), "",
             "## The issue's targets, as measured here", "", *_targets(res, est_ms + filt_ms), "",
             "## Filtered against per-frame error, true height above 20 m", "",
             ("| quantity | per-frame RMS | filtered RMS | ratio (target <= 0.5) | least any causal filter can "
              "reach: RMS, ratio |"), "|---|---|---|---|---|"]
    for q in ("roll", "pitch"):
        lines.append(f"| {q} (deg) | {res[f'{q}_raw_rms_deg']:.4f} | {res[f'{q}_filt_rms_deg']:.4f} | "
                     f"{res[f'{q}_ratio']:.2f} | {res[f'{q}_bound_rms_deg']:.4f}, {res[f'{q}_bound_ratio']:.2f} |")
    lines.append(f"| height (m) | {res['height_raw_rms_m']:.4f} | {res['height_filt_rms_m']:.4f} | "
                 f"{res['height_filt_rms_m'] / res['height_raw_rms_m']:.2f} | (not computed: the UAV's climb and the deck's heave "
                 "are told apart only by their dynamics) |")
    for sig, r2 in sweep:
        lines.append(f"| at {sig:g} px: roll / pitch (deg) | {r2['roll_raw_rms_deg']:.4f} / {r2['pitch_raw_rms_deg']:.4f} "
                     f"| {r2['roll_filt_rms_deg']:.4f} / {r2['pitch_filt_rms_deg']:.4f} | {r2['roll_ratio']:.2f} / "
                     f"{r2['pitch_ratio']:.2f} | {r2['roll_bound_ratio']:.2f} / {r2['pitch_bound_ratio']:.2f} |")
    lines += ["", "By true height (RMS error after warm-up; deg, deg, m):", "",
              ("| true height (m) | frames | roll per-frame | roll filtered | pitch per-frame | pitch filtered | "
              "height per-frame | height filtered |"), "|---|---|---|---|---|---|---|---|"]
    for _, r in res["by_height"].iterrows():  # type: ignore[union-attr]
        lines.append(f"| {r['true height (m)']} | {r['frames']} | {r['roll per-frame']:.4f} | {r['roll filtered']:.4f} | "
                     f"{r['pitch per-frame']:.4f} | {r['pitch filtered']:.4f} | {r['height per-frame']:.4f} | "
                     f"{r['height filtered']:.4f} |")
    lines += ["", "Errors in their own sigmas (after warm-up, all heights): "
              + "; ".join(f"{k.replace(' > 5 sigma', '')}: {res[k]} beyond 5 sigma, RMS z "
                          f"{res[k.replace(' > 5 sigma', ' rms z')]:.2f}" for k in res if k.endswith("> 5 sigma")),
              "", "## Prediction against holding the last estimate (RMS error)", "",
              ("| horizon (s) | roll pred / hold (deg) | ratio | pitch pred / hold (deg) | ratio | "
              "height pred / hold (m) | ratio | heave rate pred / hold-filtered (m/s) | RMS z: roll, pitch, height, "
              "heave rate |"), "|---|---|---|---|---|---|---|---|---|"]
    for _, r in res["prediction"].iterrows():  # type: ignore[union-attr]
        lines.append(f"| {r['horizon_s']:g} | {r['roll_deg pred']:.3f} / {r['roll_deg hold']:.3f} | "
                     f"{r['roll_deg ratio']:.2f} | {r['pitch_deg pred']:.3f} / {r['pitch_deg hold']:.3f} | "
                     f"{r['pitch_deg ratio']:.2f} | {r['height_m pred']:.3f} / {r['height_m hold']:.3f} | "
                     f"{r['height_m ratio']:.2f} | {r['heave_rate_m_per_s pred']:.3f} / "
                     f"{r['heave_rate_m_per_s hold']:.3f} | {r['roll_deg z']:.2f}, {r['pitch_deg z']:.2f}, "
                     f"{r['height_m z']:.2f}, {r['heave_rate_m_per_s z']:.2f} |")
    lines += ["", ("Targets: ratio <= 0.5 at 1 s and 2 s. RMS z: the prediction's error in its own predicted "
              "sigmas (1 = calibrated)."), "", "## Landing window against the truth", "",
              "| limits | frames scored | truly calm | go | false go | false-go rate | calm frames found |",
              "|---|---|---|---|---|---|---|"]
    for _, r in res["landing"].iterrows():  # type: ignore[union-attr]
        lines.append(f"| {r['limits']} | {r['frames scored']} | {r['truly calm']} | {r['go']} | {r['false go']} | "
                     f"{r['false-go rate']:.3f} | {r['calm frames found']:.2f} |")
    lines += ["", "## Time per frame (one core, thread CPU time, median)", "",
              (f"pnp estimate of one frame alone: {est_ms:.2f} ms; filter predict + update ({state_size(config.model)} "
              f"states): {filt_ms:.3f} ms; together {est_ms + filt_ms:.2f} ms (target <= 2 ms); the estimate is "
              f"{est_ms / (est_ms + filt_ms):.0%} of it."), "",
              "## Seeds, sea states and trackers", "",
              ("Filtered/per-frame RMS above 20 m (bound: the least any causal filter can reach on the sea's spectrum "
               "with these estimates' noise), filtered errors in their own sigmas (RMS z, count beyond 5), prediction "
               "against holding the last estimate, and the landing window (roll < 5 deg, pitch < 3 deg, heave rate "
               "< 1.5 m/s for 3 s at 0.95)."), "",
              ("| sea (render config) | tracker config | noise / sea seed | roll ratio (bound) | pitch ratio (bound) | "
               "filtered roll / pitch RMS z (> 5) | pred / hold 1 s roll, pitch | 2 s roll, pitch | "
               "landing: calm, go, false go, found |"),
              "|---|---|---|---|---|---|---|---|---|"]
    for r in summary:
        lines.append(f"| {r['sea']} | {r['tracker']} | {r['seed']} | {r['roll']:.2f} ({r['roll_b']:.2f}) | "
                     f"{r['pitch']:.2f} ({r['pitch_b']:.2f}) | {r['zr']:.2f} / {r['zp']:.2f} ({r['n5']}) | "
                     f"{r['p1r']:.2f}, {r['p1p']:.2f} | {r['p2r']:.2f}, {r['p2p']:.2f} | {r['land']} |")
    lines += ["",
              "![error against time](error_vs_time.png)", ""]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "README.md").write_text(text)
        table.round(6).to_csv(args.out / "frames.csv", index=False)
        plot(table, args.out / "error_vs_time.png")


def summary_row(args: argparse.Namespace, config: TrackConfig, tracker: str, res: dict[str, object]) -> dict[str, object]:
    """One row of the seeds / sea states / trackers table."""
    pr = res["prediction"]
    land = res["landing"]
    assert isinstance(pr, pd.DataFrame) and isinstance(land, pd.DataFrame)
    r1, r2 = (pr[pr["horizon_s"] == h].iloc[0] for h in (1.0, 2.0))
    key = next(i for i, lim in enumerate(scored_limits(config))
               if (lim.roll_deg, lim.pitch_deg, lim.heave_rate_m_per_s, lim.window_s, lim.confidence)
               == (5.0, 3.0, 1.5, 3.0, 0.95))
    lr = land.iloc[key]
    sea = args.sea
    return {"sea": f"SS{sea.get('sea_state', '?')} ({args.config})", "tracker": tracker,
            "seed": f"{args.seed} / {args.motion_seed_used}",
            "roll": res["roll_ratio"], "roll_b": res["roll_bound_ratio"], "pitch": res["pitch_ratio"],
            "pitch_b": res["pitch_bound_ratio"], "zr": res["filtered roll rms z"], "zp": res["filtered pitch rms z"],
            "n5": int(res["filtered roll > 5 sigma"]) + int(res["filtered pitch > 5 sigma"]),  # type: ignore[call-overload]
            "p1r": r1["roll_deg ratio"], "p1p": r1["pitch_deg ratio"], "p2r": r2["roll_deg ratio"],
            "p2p": r2["pitch_deg ratio"],
            "land": f"{lr['truly calm']}, {lr['go']}, {lr['false go']}, {lr['calm frames found']:.2f}"}


def _targets(res: dict[str, object], frame_ms: float) -> list[str]:
    """One line per target of issue 21 this benchmark measures: met or not, with the number."""
    def yes(cond: bool) -> str:
        return "met" if cond else "NOT met"

    pr = res["prediction"]
    assert isinstance(pr, pd.DataFrame)
    lines = [(f"- Filtered roll and pitch RMS <= 0.5x per-frame above 20 m: roll {res['roll_ratio']:.2f}, pitch "
             f"{res['pitch_ratio']:.2f}: {yes(max(res['roll_ratio'], res['pitch_ratio']) <= 0.5)} "  # type: ignore[call-overload]
             f"(the least any causal filter can reach here: roll {res['roll_bound_ratio']:.2f}, pitch "
             f"{res['pitch_bound_ratio']:.2f}).")]
    for h in (1.0, 2.0):
        r = pr[pr["horizon_s"] == h].iloc[0]
        worst = max(r["roll_deg ratio"], r["pitch_deg ratio"])
        lines.append(f"- Prediction RMS at {h:g} s <= 0.5x holding the last estimate: roll {r['roll_deg ratio']:.2f}, "
                     f"pitch {r['pitch_deg ratio']:.2f}: {yes(worst <= 0.5)}.")
    lines.append(f"- ok in >= 99 % of frames: {res['ok_fraction']:.1%} ({yes(res['ok_fraction'] >= 0.99)} over the "  # type: ignore[operator]
                 "heights flown here; below the ring's ~13 m the two-ring layout is needed, not part of this work).")
    lines.append(f"- No ok estimate beyond 5 of its own sigmas: {res['ok_beyond_5_sigma']} "
                 f"({yes(res['ok_beyond_5_sigma'] == 0)}).")
    lines.append(f"- Estimate + filter update <= 2 ms on one core: {frame_ms:.2f} ms ({yes(frame_ms <= 2.0)}; "
                 "see the load above).")
    land = res["landing"]
    assert isinstance(land, pd.DataFrame)
    for _, r in land.iterrows():
        lines.append(f"- Landing window, {r['limits']}: go in {r['go']} frames, {r['false go']} of them with the truth "
                     f"outside the limits (false-go rate {r['false-go rate']:.3f}); {r['calm frames found']:.0%} of the "
                     f"{r['truly calm']} truly calm frames found.")
    return lines


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


if __name__ == "__main__":
    main()
