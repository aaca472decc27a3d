"""The thesis-format tables measured on rendered frames, per detector x estimator x resolution.

Rows per table height: maximum absolute error of roll, pitch, yaw (deg) and
height, the centroid RMS error mean and sigma over frames (the real pixelation
effect), sigma of each error (like Table 4.15), the failure rate, and the
Cramer-Rao bound where the errors table carries it (``crb_*`` columns).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

_Q = (("roll", "roll_err_deg"), ("pitch", "pitch_err_deg"), ("yaw", "yaw_err_deg"), ("height", "height_err_m"))
GROUP = ["detector", "method", "camera", "table_height_m"]


def _maxabs(s: pd.Series) -> float:
    v = np.abs(s.to_numpy(float))
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else float("nan")


def _std(s: pd.Series) -> float:
    v = s.to_numpy(float)
    v = v[np.isfinite(v)]
    return float(v.std(ddof=1)) if v.size > 1 else float("nan")


def resolution_table(errors: pd.DataFrame) -> pd.DataFrame:
    """Aggregate a per-frame errors table into one row per (detector, method, camera, height)."""
    rows = []
    for key, g in errors.groupby(GROUP, sort=True):
        row = dict(zip(GROUP, key))
        row["n_frames"] = len(g)
        row["failure_rate"] = float(1.0 - g["ok"].mean())
        for name, col in _Q:
            row[f"max_{name}"] = _maxabs(g[col])
        for name, col in _Q:
            row[f"sigma_{name}"] = _std(g[col])
        c = g["centroid_rms_px"].to_numpy(float) if "centroid_rms_px" in g else np.array([])
        c = c[np.isfinite(c)]
        row["centroid_rms_mean_px"] = float(c.mean()) if c.size else float("nan")
        row["centroid_rms_sigma_px"] = float(c.std(ddof=1)) if c.size > 1 else float("nan")
        row["apparent_radius_px"] = float(g["apparent_radius_px"].mean()) if "apparent_radius_px" in g else float("nan")
        for name, _ in _Q:
            col = f"crb_{name}" + ("_m" if name == "height" else "_deg")
            if col in g:  # NaN where no frame has a bound (none detected), without numpy's warning
                v = g[col].to_numpy(float)
                v = v[np.isfinite(v)]
                row[f"crb_{name}"] = float(v.mean()) if v.size else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


def _f(v: float, d: int) -> str:
    return "-" if not np.isfinite(v) else f"{v:.{d}f}"


def resolution_markdown(table: pd.DataFrame) -> str:
    """Markdown: a thesis-style table per detector x method x camera, plus a sigma table."""
    lines = ["# Resolution tables measured on rendered frames", "",
             ("Per detector, estimator and camera: rows per table height (camera height above the "
             "world origin). Max = maximum absolute error over the frames of the cell; sigma = standard "
             "deviation of the error; centroid RMS = per-frame RMS distance between identified detections "
             "and projected beacon centres (mean and sigma over frames); fail = share of frames whose "
             "estimate was flagged not ok (excluded from the error statistics)."), ""]
    has_crb = any(c.startswith("crb_") for c in table.columns)
    for (det, method, cam), g in table.groupby(["detector", "method", "camera"], sort=True):
        lines += [f"## {det} + {method}, camera {cam}", "",
                  ("| Height | Roll max [deg] | Pitch max [deg] | Yaw max [deg] | Height max [m] | "
                  "centroid RMS [px] | sigma [px] | fail | frames |"),
                  "|---|---|---|---|---|---|---|---|---|"]
        for _, r in g.sort_values("table_height_m").iterrows():
            lines.append(
                f"| {r.table_height_m:g} | {_f(r.max_roll, 4)} | {_f(r.max_pitch, 4)} | {_f(r.max_yaw, 4)} | "
                f"{_f(r.max_height, 4)} | {_f(r.centroid_rms_mean_px, 3)} | {_f(r.centroid_rms_sigma_px, 3)} | "
                f"{r.failure_rate:.1%} | {r.n_frames} |")
        lines += ["", "| Height | Roll sigma [deg] | Pitch sigma [deg] | Yaw sigma [deg] | Height sigma [m] |"
                  + (" CRB roll [deg] | CRB pitch [deg] | CRB yaw [deg] | CRB height [m] |" if has_crb else ""),
                  "|---|---|---|---|---|" + ("---|---|---|---|" if has_crb else "")]
        for _, r in g.sort_values("table_height_m").iterrows():
            line = (f"| {r.table_height_m:g} | {_f(r.sigma_roll, 4)} | {_f(r.sigma_pitch, 4)} | "
                    f"{_f(r.sigma_yaw, 4)} | {_f(r.sigma_height, 4)} |")
            if has_crb:
                line += "".join(f" {_f(r.get(f'crb_{q}', np.nan), 4)} |" for q in ("roll", "pitch", "yaw", "height"))
            lines.append(line)
        lines.append("")
    return "\n".join(lines)
