"""Detector benchmark: centroid error, recall, precision, identification and time against truth.

Per detector x camera (resolution) x camera height:

* ``rms_px``: per-axis RMS centroid error, ``sqrt(mean((du^2 + dv^2) / 2))``;
* ``bias_px``: length of the mean error vector; ``p95_px``: 95th percentile of
  the radial error ``|(du, dv)|``;
* ``recall``: matched / visible beacons; ``precision``: matched / detections;
* ``id_accuracy``: matched detections carrying the right beacon id (of the
  frames' matched detections; unassigned counts as wrong);
* ``ms_per_frame``: median detection + identification wall time (image decoding
  excluded); ``cpu_ms_per_frame``: the same work's median CPU time on its thread;
* ``crb_px``: per-axis RMS of the centroid Cramér–Rao bound
  (:mod:`deckpose.detect.crb`) over the matched beacons, and ``rms_over_crb``.
  The bound needs each spot's width and electrons and the sensor model; it is
  computed when the dataset provides them (``spot_sigma_px``, ``spot_flux_e``
  columns in ``beacons.parquet`` and a ``sensor`` block in the manifest, as
  the synthetic datasets and the renderer write them; a per-beacon
  ``spot_background_e`` replaces the sensor's uniform background) and left NaN
  otherwise. The bound assumes unclipped pixels: for a saturated core it is
  optimistic, so ``saturated`` (fraction of the cell's beacons whose core
  reaches the full well, from ``spot_peak_e``) is reported beside it.

A detection matches the nearest visible beacon within
``max(3, 2 * apparent_radius_px)`` pixels, one-to-one, nearest pairs first.
"""

from __future__ import annotations

import dataclasses
import math
from typing import cast

import numpy as np
import pandas as pd
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.synthetic import SensorModel


def match_frame(det: pd.DataFrame, gt: pd.DataFrame) -> pd.DataFrame:
    """Match one frame's detections to its visible beacons.

    Parameters
    ----------
    det : DataFrame
        Rows of ``detections.parquet`` for one frame.
    gt : DataFrame
        Rows of ``beacons.parquet`` for that frame, visible beacons only.

    Returns
    -------
    DataFrame
        ``gt`` plus ``matched, du_px, dv_px, det_beacon_id, size_px``.
    """
    out = gt.copy()
    out["matched"] = False
    out["du_px"] = np.nan
    out["dv_px"] = np.nan
    out["det_beacon_id"] = -1
    out["size_px"] = np.nan
    if len(det) == 0 or len(gt) == 0:
        return out
    P = det[["u_px", "v_px"]].to_numpy(float)
    G = gt[["u_px", "v_px"]].to_numpy(float)
    gate = np.maximum(3.0, 2.0 * np.nan_to_num(gt["apparent_radius_px"].to_numpy(float), nan=1.0))
    d = np.linalg.norm(G[:, None, :] - P[None], axis=2)
    pairs = sorted(
        (d[i, j], i, j) for i in range(len(G)) for j in range(len(P)) if d[i, j] < gate[i]
    )
    used_g, used_d = set(), set()
    names = list(out.columns)
    cols = {c: names.index(c) for c in ("matched", "du_px", "dv_px", "det_beacon_id", "size_px")}
    for _, i, j in pairs:
        if i in used_g or j in used_d:
            continue
        used_g.add(i)
        used_d.add(j)
        out.iat[i, cols["matched"]] = True
        out.iat[i, cols["du_px"]] = P[j, 0] - G[i, 0]
        out.iat[i, cols["dv_px"]] = P[j, 1] - G[i, 1]
        out.iat[i, cols["det_beacon_id"]] = int(det["beacon_id"].iloc[j])
        out.iat[i, cols["size_px"]] = float(det["size_px"].iloc[j])
    return out


def crb_per_beacon(beacons: pd.DataFrame, sensor: SensorModel | None) -> np.ndarray:
    """Per-axis CRB variance (trace / 2, px^2) of each beacon row (NaN where unknown)."""
    out = np.full(len(beacons), np.nan)
    if sensor is None or not {"spot_sigma_px", "spot_flux_e"} <= set(beacons.columns):
        return out
    has_bg = "spot_background_e" in beacons.columns
    for k, r in enumerate(beacons.to_dict("records")):
        if not (r["spot_flux_e"] > 0 and r["spot_sigma_px"] > 0):  # also False for NaN
            continue
        s = sensor
        if has_bg and np.isfinite(r["spot_background_e"]):
            s = dataclasses.replace(sensor, background_e=max(float(r["spot_background_e"]), 0.0))
        crb = centroid_crb_px2(r["u_px"], r["v_px"], r["spot_sigma_px"], r["spot_flux_e"], s)
        out[k] = float(np.trace(crb)) / 2
    return out


def match_run(
    detections: pd.DataFrame, frames_out: pd.DataFrame, beacons: pd.DataFrame, frames: pd.DataFrame
) -> pd.DataFrame:
    """Matched per-beacon rows of a whole run, with camera, height (and lighting) per frame.

    ``frames_out`` is ``detect_frames.parquet``; ``beacons`` and ``frames`` the dataset's tables.
    """
    vis = beacons[beacons["visible"].astype(bool)]
    det_by = {k: g for k, g in detections.groupby("frame_id")}
    parts = []
    empty = detections.iloc[:0]
    for fid, g in vis.groupby("frame_id"):
        parts.append(match_frame(det_by.get(fid, empty), g.reset_index(drop=True)))
    m = pd.concat(parts, ignore_index=True) if parts else vis.iloc[:0]
    cols = ["frame_id", "camera", "camera_height_m"] + (["lighting"] if "lighting" in frames else [])
    return m.merge(frames[cols], on="frame_id", how="left")


def centroid_by_lighting(matches: pd.DataFrame) -> pd.DataFrame:
    """Centroid error against the CRB per detector x camera x height x lighting.

    Empty unless ``matches`` (from :func:`match_run`, with ``detector`` and
    ``crb_var_px2`` columns) holds more than one lighting: the summary pools them,
    and night, dusk and day frames need not share one figure.

    Returns
    -------
    DataFrame
        ``detector, camera, height_m, lighting, beacons, rms_px, crb_px, rms_over_crb``.
    """
    cols = ["detector", "camera", "height_m", "lighting", "beacons", "rms_px", "crb_px", "rms_over_crb"]
    if "lighting" not in matches or matches["lighting"].nunique() < 2:
        return pd.DataFrame(columns=cols)
    m = matches[matches["matched"]]
    rows = []
    keys = ["detector", "camera", "camera_height_m", "lighting"]
    for key, g in m.groupby(keys, sort=True):
        det, cam, h, light = cast("tuple[str, str, float, str]", key)  # the key's columns, in order
        e2 = (g["du_px"].to_numpy(float) ** 2 + g["dv_px"].to_numpy(float) ** 2) / 2
        crb = g["crb_var_px2"].to_numpy(float)
        rms = math.sqrt(float(np.mean(e2)))
        crb_rms = math.sqrt(float(np.mean(crb))) if np.all(np.isfinite(crb)) else math.nan
        rows.append([det, cam, float(h), str(light), len(g), rms, crb_rms,
                     rms / crb_rms if crb_rms > 0 else math.nan])
    return pd.DataFrame(rows, columns=cols)


def summarise(
    detector: str,
    matched: pd.DataFrame,
    detections: pd.DataFrame,
    frames_out: pd.DataFrame,
    frames: pd.DataFrame,
) -> pd.DataFrame:
    """One row per camera x height of the metrics in the module docstring."""
    fo = frames_out.merge(frames[["frame_id", "camera_height_m"]], on="frame_id", how="left")
    nd = detections.groupby("frame_id").size()
    rows = []
    for key, g in matched.groupby(["camera", "camera_height_m"], sort=True):
        cam, h = cast("tuple[str, float]", key)
        fids = set(g["frame_id"])
        f = fo[fo["frame_id"].isin(fids)]
        m = g[g["matched"]]
        du, dv = m["du_px"].to_numpy(float), m["dv_px"].to_numpy(float)
        n_det = int(sum(int(nd.get(i, 0)) for i in fids))
        crb = m["crb_var_px2"].to_numpy(float) if "crb_var_px2" in m else np.full(len(m), np.nan)
        rms = math.sqrt(np.mean((du**2 + dv**2) / 2)) if len(m) else math.nan
        crb_rms = math.sqrt(np.mean(crb)) if len(m) and np.all(np.isfinite(crb)) else math.nan
        sat = g["saturated"].to_numpy(float) if "saturated" in g else np.full(len(g), np.nan)
        rows.append(
            {
                "detector": detector,
                "camera": cam,
                "height_m": float(h),
                "frames": len(fids),
                "beacons": len(g),
                "radius_px": float(g["apparent_radius_px"].mean()),
                "rms_px": rms,
                "bias_px": float(math.hypot(du.mean(), dv.mean())) if len(m) else math.nan,
                "p95_px": float(np.percentile(np.hypot(du, dv), 95)) if len(m) else math.nan,
                "crb_px": crb_rms,
                "rms_over_crb": rms / crb_rms if crb_rms > 0 else math.nan,
                "saturated": float(np.mean(sat))
                if len(g) and np.all(np.isfinite(sat))
                else math.nan,
                "recall": len(m) / len(g) if len(g) else math.nan,
                "precision": len(m) / n_det if n_det else math.nan,
                "id_accuracy": float((m["det_beacon_id"] == m["beacon_id"]).mean())
                if len(m)
                else math.nan,
                "frames_ok": int(f["ok"].sum()),
                "ms_per_frame": 1000.0 * float(f["seconds"].median()) if len(f) else math.nan,
                "cpu_ms_per_frame": 1000.0 * float(f["cpu_seconds"].median())
                if len(f) and "cpu_seconds" in f
                else math.nan,
            }
        )
    return pd.DataFrame(rows)
