"""Painted circle against beacons (issue 22 item 4): pose error, failure rate and time per frame.

For each resolution, one dataset is rendered with the painted ring *and* the beacons on the
same deck (``painted_ring:`` on; the beacons are always drawn), for every height and lighting
and a few seeded attitudes; both pipelines run on the same frames:

* painted ring: ``deckpose painted-ring`` (:func:`deckpose.painted_ring_run.painted_ring_run`);
* beacons: ``deckpose detect --detector cog`` then ``deckpose estimate --method conic``.

Errors are estimate minus truth (:func:`deckpose.evaluate.errors.frame_errors`), RMS over the
frames each method called ok; the failure rate counts the frames it did not. Times are CPU
seconds of this process's thread per frame (detection plus estimation; rendering excluded).
Writes ``OUT/README.md`` (tables, verdicts, the command, machine and load), ``OUT/results.csv``
(one row per frame x target) and ``OUT/errors_by_height.png``.

    python benchmarks/painted_circle.py --work /tmp/painted_circle --out reports/painted_circle
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from deckpose.atomic_io import atomic_open

#: Cameras of the comparison: the same 75 x 60 degree field, two resolutions.
CAMERAS = {
    "1mp": {"preset": "4mp-square", "size": [1156, 867], "name": "1mp"},
    "8mp": {"preset": "16mp-square", "size": [3264, 2448], "name": "8mp"},
}
PARAMS = ("roll", "pitch", "yaw")


def _config(camera: str, heights: list[float], attitudes: int, seed: int,
            texture_seed: int | None = None) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    att = [[float(rng.uniform(-4, 4)), float(rng.uniform(-4, 4)), float(rng.uniform(-40, 40)),
            float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-1.0, 1.0)), float(rng.uniform(-1.0, 1.0))]
           for _ in range(attitudes)]
    return {
        "name": f"painted-circle-{camera}", "seed": seed, "backend": "egl",
        "cameras": [CAMERAS[camera]], "heights_m": heights, "lighting": ["day", "dusk", "night"],
        "motion": {"source": "fixed", "attitudes_deg": att},
        "sensor": {"bit_depth": 8, "read_noise_e": 5},
        "scene": {"shading": "flat", "texture_px": "auto",
                  **({} if texture_seed is None else {"texture_seed": texture_seed})},
        "layout": {"n_ring": 12, "radius_m": 10.0, "has_centre": True},
        "painted_ring": {"radius_m": 8.0, "line_width_m": 0.5, "bow_mark": "gap"},
    }


def _run_one(camera: str, work: Path, heights: list[float], attitudes: int, seed: int, workers: int,
             texture_seed: int | None = None) -> pd.DataFrame:
    from deckpose.detect.run import detect_run
    from deckpose.estimate.registry import parse_method
    from deckpose.estimate.run import estimate_run
    from deckpose.evaluate.errors import frame_errors
    from deckpose.render.config import config_from_dict
    from deckpose.render.dataset import render_dataset

    from deckpose.painted_ring_run import painted_ring_run, read_bounds
    from deckpose.run_folder import RunPaths, read_frames
    from deckpose.tables import read_table

    ds = work / camera
    cfg = config_from_dict(_config(camera, heights, attitudes, seed, texture_seed), f"painted circle {camera}")
    render_dataset(cfg, ds, workers=workers, resume=ds.exists(), progress=True)
    run = RunPaths(ds)
    frames = read_frames(run)
    ring = painted_ring_run(ds, progress=True)
    ring_err = frame_errors(frames, read_table(ring.estimates, "estimates"))
    det = read_table(ring.detections, "ring detections").set_index("frame_id")
    bnd = read_bounds(run).set_index("frame_id")
    ring_err["seconds"] = (det["seconds"] + bnd["seconds"]).reindex(ring_err["frame_id"]).to_numpy()
    for p in ("roll", "pitch", "yaw"):
        ring_err[f"bound_{p}_deg"] = bnd[f"bound_{p}_deg"].reindex(ring_err["frame_id"]).to_numpy()
    for p in ("height", "surge", "sway"):
        ring_err[f"bound_{p}_m"] = bnd[f"bound_{p}_m"].reindex(ring_err["frame_id"]).to_numpy()
    for p, u in (("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("height", "m")):
        for kind in ("known_levels", "correlated"):
            ring_err[f"bound_{kind}_{p}_{u}"] = bnd[f"bound_{kind}_{p}_{u}"].reindex(ring_err["frame_id"]).to_numpy()
    ring_err["target"] = "painted ring"
    t0 = time.thread_time()
    d = detect_run(ds, "cog", progress=True, workers=0)
    est = estimate_run(ds, parse_method("conic"), detector="cog")
    t_est = (time.thread_time() - t0 - float(d.frames["cpu_seconds"].sum())) / max(1, len(frames))
    beacon_err = frame_errors(frames, read_table(est.path, "estimates"))
    cpu = d.frames.set_index("frame_id")["cpu_seconds"]
    beacon_err["seconds"] = cpu.reindex(beacon_err["frame_id"]).to_numpy() + t_est
    beacon_err["target"] = "beacons"
    out = pd.concat([ring_err, beacon_err], ignore_index=True)
    f = frames.set_index("frame_id")
    out["lighting"] = f["lighting"].reindex(out["frame_id"]).to_numpy()
    out["resolution"] = camera
    out["camera_height_m"] = out["table_height_m"]
    return out


def _rms(x: pd.Series) -> float:
    v = x.dropna().to_numpy(float)
    return float(np.sqrt(np.mean(v ** 2))) if v.size else math.nan


def summary(df: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """RMS errors, failure rate and time per group and target."""
    rows = []
    for key, g in df.groupby([*by, "target"], sort=True):
        ok = g["ok"].astype(bool)
        tilt = np.sqrt(0.5 * (g.loc[ok, "roll_err_deg"] ** 2 + g.loc[ok, "pitch_err_deg"] ** 2))
        horiz = np.hypot(g.loc[ok, "surge_err_m"], g.loc[ok, "sway_err_m"])
        rows.append({**dict(zip([*by, "target"], key if isinstance(key, tuple) else (key,))),
                     "frames": len(g), "failed": float(1 - ok.mean()),
                     "tilt_rms_deg": _rms(tilt), "yaw_rms_deg": _rms(g.loc[ok, "yaw_err_deg"]),
                     "height_rms_m": _rms(g.loc[ok, "height_err_m"]), "horizontal_rms_m": _rms(horiz),
                     "ms_per_frame": 1e3 * float(g["seconds"].median())})
    return pd.DataFrame(rows)


def bound_ratios(df: pd.DataFrame) -> pd.DataFrame:
    """Painted ring per resolution and lighting: RMS error over the estimate's own sigma and over its bounds.

    Per parameter, RMS over the ok frames of error / sigma, error / the white-noise bound and
    error / the correlated-noise bound; ``tilt_*`` pools roll and pitch; ``max_abs_err/sigma``
    is the largest ``|error| / sigma`` of roll, pitch, yaw and height.
    """
    g = df[(df["target"] == "painted ring") & df["ok"].astype(bool)]
    rows = []
    for (res, light), h in g.groupby(["resolution", "lighting"], sort=True):
        row: dict[str, Any] = {"resolution": res, "lighting": light, "frames": len(h)}
        z_all = []
        for p, unit in (("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("height", "m")):
            err = h[f"{p}_err_{unit}"]
            sig = h[f"sigma_{p}_{unit}"] if f"sigma_{p}_{unit}" in h else pd.Series(np.nan, index=h.index)
            row[f"{p}_err/sigma"] = _rms(err / sig)
            row[f"{p}_err/bound"] = _rms(err / h[f"bound_{p}_{unit}"])
            corr = f"bound_correlated_{p}_{unit}"
            row[f"{p}_err/bound_corr"] = _rms(err / h[corr]) if corr in h else math.nan
            z_all.append((err / sig).abs().to_numpy(float))
        for name, col in (("sigma", "sigma_{p}_deg"), ("bound", "bound_{p}_deg"),
                          ("bound_corr", "bound_correlated_{p}_deg")):
            z = [h[f"{p}_err_deg"] / h[col.format(p=p)] for p in ("roll", "pitch") if col.format(p=p) in h]
            row[f"tilt_err/{name}"] = _rms(pd.concat(z)) if z else math.nan
        row["max_abs_err/sigma"] = float(np.nanmax(np.concatenate(z_all))) if len(h) else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def verdicts(s: pd.DataFrame) -> pd.DataFrame:
    """Per resolution and lighting: the target with fewer failures, then the smaller tilt error."""
    rows = []
    for (res, light), g in s.groupby(["resolution", "lighting"], sort=False):
        g = g.assign(score=g["failed"] * 1e6 + g["tilt_rms_deg"].fillna(np.inf))
        best = g.loc[g["score"].idxmin()]
        other = g.loc[g["score"].idxmax()]
        rows.append({"resolution": res, "lighting": light, "better": best["target"],
                     "tilt_rms_deg (better / other)": f"{best['tilt_rms_deg']:.4f} / {other['tilt_rms_deg']:.4f}",
                     "failed (better / other)": f"{best['failed']:.2f} / {other['failed']:.2f}"})
    return pd.DataFrame(rows)


def _figure(s: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res_list = list(dict.fromkeys(s["resolution"]))
    fig, axes = plt.subplots(len(res_list), 3, figsize=(12, 3.2 * len(res_list)), squeeze=False, sharey=True)
    for i, res in enumerate(res_list):
        for j, light in enumerate(("day", "dusk", "night")):
            ax = axes[i][j]
            for target, style in (("painted ring", "o-"), ("beacons", "s--")):
                g = s[(s["resolution"] == res) & (s["lighting"] == light) & (s["target"] == target)]
                ax.semilogy(g["camera_height_m"], g["tilt_rms_deg"], style, label=target)
            ax.set_title(f"{res}, {light}")
            ax.set_xlabel("camera height, m")
            ax.grid(True, which="both", alpha=0.3)
            if j == 0:
                ax.set_ylabel("tilt error RMS, deg")
    axes[0][0].legend()
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=90)
    os.replace(tmp, path)
    plt.close(fig)


def markdown_table(t: pd.DataFrame) -> str:
    """A pipe table of a frame's values as they print (floats to 3 significant figures)."""
    def cell(x: object) -> str:
        return f"{x:.3g}" if isinstance(x, float) else str(x)

    lines = ["| " + " | ".join(map(str, t.columns)) + " |", "|" + "---|" * len(t.columns)]
    lines += ["| " + " | ".join(cell(x) for x in row) + " |" for row in t.itertuples(index=False)]
    return "\n".join(lines)


def _markdown(df: pd.DataFrame, command: str, load_before: str, load_after: str, seconds: float) -> str:
    s_all = summary(df, ["resolution", "lighting"])
    s_h = summary(df, ["resolution", "lighting", "camera_height_m"])
    v = verdicts(s_all)
    b = bound_ratios(df)
    fmt = {"failed": "{:.2f}", "tilt_rms_deg": "{:.4f}", "yaw_rms_deg": "{:.4f}", "height_rms_m": "{:.4f}",
           "horizontal_rms_m": "{:.4f}", "ms_per_frame": "{:.0f}"}

    def table(t: pd.DataFrame) -> str:
        t = t.copy()
        for c, f in fmt.items():
            if c in t:
                t[c] = t[c].map(lambda x, f=f: "-" if pd.isna(x) else f.format(x))
        return markdown_table(t)

    fails = df[~df["ok"].astype(bool)].groupby(["target", "reason"]).size().reset_index(name="frames")
    return "\n".join([
        "# Painted circle against beacons (issue 22)",
        "",
        "Made by:",
        "",
        f"    {command}",
        "",
        (f"Machine: {platform.machine()}, {os.cpu_count()} CPUs shared with other jobs; 1-minute load "
         f"{load_before} before and {load_after} after; {seconds / 60:.0f} min in all."),
        "",
        ("Each resolution is one dataset with the painted ring (mid radius 8 m, line 0.5 m, white, bow gap "
        "20 deg, centre disc) and the 12 beacons (radius 10 m, centre beacon) on the same deck, so both "
        "targets are scored on the same frames: heights x day/dusk/night (floodlit deck at night, level "
        "0.2) x seeded attitudes (roll, pitch U(-4, 4) deg, yaw U(-40, 40) deg, offsets up to 1 m). "
        "Cameras: 75 x 60 deg field, 1156 x 867 (1 MP) and 3264 x 2448 (8 MP), 8-bit RGB. Beacons: "
        "`cog` detector, `conic` estimator; painted ring: `deckpose painted-ring`. Errors are RMS over "
        "the frames a method called ok (tilt: RMS of roll and pitch); `failed` counts the others; "
        "time is the median CPU time per frame of detection plus estimation (rendering excluded)."),
        "",
        "## Which target gives the better pose",
        "",
        "Fewer failures first, then the smaller tilt error:",
        "",
        table(v),
        "",
        "## Per resolution and lighting",
        "",
        table(s_all),
        "",
        "## Per resolution, lighting and height",
        "",
        table(s_h),
        "",
        "## Painted ring: error against its sigma and its bounds",
        "",
        ("Per resolution and lighting, RMS over the frames the ring called ok of error / sigma (the estimate's "
         "own: the measured edge-point scatter, its correlation along each edge in a Newey-West sandwich), of "
         "error / bound (the white-noise Cramér-Rao bound: each edge point at its own bound from the model fit "
         "of its pixels under white noise of the measured level, the deck's level and slope and the paint's "
         "level beside it unknown) and of error / bound_corr (the correlated-noise bound: each point at the same "
         "bound, correlated along its edge as the residuals are). `tilt_*` pools roll and pitch; "
         "`max_abs_err/sigma` is the largest |error| / sigma of roll, pitch, yaw and height."),
        "",
        table(b),
        "",
        "## Failures",
        "",
        table(fails) if len(fails) else "None.",
        "",
        "![tilt error against height](errors_by_height.png)",
        "",
    ])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True, help="folder for the datasets (kept; --resume-able)")
    ap.add_argument("--out", default="reports/painted_circle", help="report folder")
    ap.add_argument("--resolutions", default="1mp,8mp", help=f"comma-separated, of {sorted(CAMERAS)}")
    ap.add_argument("--heights", default="20,40,80", help="camera heights, m")
    ap.add_argument("--attitudes", type=int, default=4, help="attitudes per height and lighting")
    ap.add_argument("--seed", type=int, default=22)
    ap.add_argument("--workers", type=int, default=2, help="render worker processes")
    ap.add_argument("--texture-seed", type=int, default=None,
                    help="the deck texture's seed (scene.texture_seed; default: the renderer's): the ring's "
                         "fixed edge errors follow the texture, so a few seeds sample them")
    args = ap.parse_args(argv)
    command = "python benchmarks/painted_circle.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    load_before = f"{os.getloadavg()[0]:.1f}"
    t0 = time.perf_counter()
    work, out = Path(args.work), Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    heights = [float(h) for h in args.heights.split(",")]
    parts = [_run_one(r, work, heights, args.attitudes, args.seed, args.workers, args.texture_seed)
             for r in args.resolutions.split(",")]
    df = pd.concat(parts, ignore_index=True)
    with atomic_open(out / "results.csv", "w") as fh:
        df.to_csv(fh, index=False)
    _figure(summary(df, ["resolution", "lighting", "camera_height_m"]), out / "errors_by_height.png")
    text = _markdown(df, command, load_before, f"{os.getloadavg()[0]:.1f}", time.perf_counter() - t0)
    with atomic_open(out / "README.md", "w") as fh:
        fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
