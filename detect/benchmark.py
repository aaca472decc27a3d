"""Detector benchmark: centroid error, recall, precision, identification and time against truth.

Per detector x camera (resolution) x camera height:

* ``rms_px``: per-axis RMS centroid error, ``sqrt(mean((du^2 + dv^2) / 2))``;
* ``bias_px``: length of the mean error vector; ``p95_px``: 95th percentile of
  the radial error ``|(du, dv)|``;
* ``recall``: matched / findable beacons (visible and not wholly occluded);
  ``precision``: matched / detections; ``recall_occluded``: recall of the beacons an
  occluder cuts in part (``occluded_fraction`` in ``beacons.parquet``);
* ``false_per_frame``: detections matched to no beacon, per frame; ``lights_found``:
  the fraction of recorded non-beacon lights in the image (``lights.parquet``:
  navigation lights, floodlights, glints) that drew such a false detection within
  :data:`LIGHT_GATE_PX`;
* ``id_accuracy``: matched detections carrying the right beacon id (of the
  frames' matched detections; unassigned counts as wrong);
* ``rms_geometric_px``: ``rms_px`` against the geometric (green) centre ``u_px, v_px``
  instead of the light's centroid (below): what the lens's lateral colour costs on top;
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
  reaches the full well, from ``spot_peak_e``) is reported beside it. Occluded
  beacons are left out of the centroid error and the bound (a cut spot is no longer
  the Gaussian the bound is for) but counted in the recall.

A detection matches the nearest visible beacon within
``max(3, 2 * apparent_radius_px)`` pixels, one-to-one, nearest pairs first.

**Which truth is scored.** The detectors measure the channel sum of a frame, so a beacon's
error ``du_px, dv_px`` is taken against the centroid of its light in that sum
(:func:`channel_sum_centre_px`): under lateral chromatic aberration the red and blue light
sit at ``u_r_px, v_r_px`` and ``u_b_px, v_b_px``, and the channel sum's centroid is their
flux-weighted mean with the green (geometric) centre, weighted by the per-channel electrons
the renderer recorded (``spot_flux_r_e, spot_flux_g_e, spot_flux_b_e``). Without those
columns (no optics) it is ``u_px, v_px`` exactly. The error against the geometric centre,
what the lens costs on top, is kept as ``du_geo_px, dv_geo_px`` (``rms_geometric_px``). The
bound is consistent with that truth: the recorded ``spot_crb_px`` is the bound on the
position of the spot actually drawn (all channels, with their shifts), and a fixed offset
of the estimated point (light centroid instead of green centre) leaves the Fisher
information of a translation, hence the bound, unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from typing import cast

import numpy as np
import pandas as pd
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.synthetic import SensorModel

#: A false detection within this distance of a recorded non-beacon light was drawn by it, px.
LIGHT_GATE_PX = 4.0

#: ``beacons.parquet``'s per-channel positions and electrons (optics on), red, green, blue.
_CHANNEL_COLUMNS = ((("u_r_px", "v_r_px"), "spot_flux_r_e"), (("u_px", "v_px"), "spot_flux_g_e"),
                    (("u_b_px", "v_b_px"), "spot_flux_b_e"))


def channel_sum_centre_px(beacons: pd.DataFrame) -> np.ndarray:
    """The truth a channel-sum detector sees: the centroid of each beacon's light in the channel sum.

    ``x = x_g + sum_c F_c (x_c - x_g) / sum_c F_c`` over the red, green and blue channels,
    ``x_c`` each channel's true centre and ``F_c`` its electrons (``spot_flux_{r,g,b}_e``),
    ``x_g`` = ``u_px, v_px``. Rows without those columns or with a non-finite value keep
    ``u_px, v_px`` exactly (no optics, or no light).

    Parameters
    ----------
    beacons : DataFrame
        Rows of ``beacons.parquet``.

    Returns
    -------
    (N, 2) array of float
        ``(u, v)`` per row, pixels.
    """
    g = beacons[["u_px", "v_px"]].to_numpy(float)
    names = [c for pair, f in _CHANNEL_COLUMNS for c in (*pair, f)]
    if not set(names) <= set(beacons.columns):
        return g
    x = np.stack([beacons[list(pair)].to_numpy(float) for pair, _ in _CHANNEL_COLUMNS], axis=1)  # (N, 3, 2)
    f = np.stack([beacons[c].to_numpy(float) for _, c in _CHANNEL_COLUMNS], axis=1)  # (N, 3)
    total = f.sum(axis=1)
    ok = np.isfinite(x).all(axis=(1, 2)) & np.isfinite(f).all(axis=1) & (total > 0)
    out = g.copy()
    w = f[ok] / total[ok, None]
    out[ok] = g[ok] + np.einsum("nc,ncd->nd", w, x[ok] - g[ok, None, :])
    return out


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
        ``gt`` plus ``matched, du_px, dv_px`` (the error against the light's centroid in the
        channel sum, :func:`channel_sum_centre_px`, which matching also uses), ``du_geo_px,
        dv_geo_px`` (against the geometric centre ``u_px, v_px``), ``det_beacon_id, size_px``
        and ``det_index`` (the matched detection's row in ``det``; -1 when unmatched).
    """
    out = gt.copy()
    out["matched"] = False
    out["du_px"] = np.nan
    out["dv_px"] = np.nan
    out["du_geo_px"] = np.nan
    out["dv_geo_px"] = np.nan
    out["det_beacon_id"] = -1
    out["size_px"] = np.nan
    out["det_index"] = -1
    if len(det) == 0 or len(gt) == 0:
        return out
    P = det[["u_px", "v_px"]].to_numpy(float)
    G = channel_sum_centre_px(gt)
    G_geo = gt[["u_px", "v_px"]].to_numpy(float)
    gate = np.maximum(3.0, 2.0 * np.nan_to_num(gt["apparent_radius_px"].to_numpy(float), nan=1.0))
    d = np.linalg.norm(G[:, None, :] - P[None], axis=2)
    pairs = sorted(
        (d[i, j], i, j) for i in range(len(G)) for j in range(len(P)) if d[i, j] < gate[i]
    )
    used_g, used_d = set(), set()
    names = list(out.columns)
    cols = {c: names.index(c) for c in ("matched", "du_px", "dv_px", "du_geo_px", "dv_geo_px", "det_beacon_id",
                                        "size_px", "det_index")}
    for _, i, j in pairs:
        if i in used_g or j in used_d:
            continue
        used_g.add(i)
        used_d.add(j)
        out.iat[i, cols["matched"]] = True
        out.iat[i, cols["du_px"]] = P[j, 0] - G[i, 0]
        out.iat[i, cols["dv_px"]] = P[j, 1] - G[i, 1]
        out.iat[i, cols["du_geo_px"]] = P[j, 0] - G_geo[i, 0]
        out.iat[i, cols["dv_geo_px"]] = P[j, 1] - G_geo[i, 1]
        out.iat[i, cols["det_beacon_id"]] = int(det["beacon_id"].iloc[j])
        out.iat[i, cols["size_px"]] = float(det["size_px"].iloc[j])
        out.iat[i, cols["det_index"]] = j
    return out


def crb_per_beacon(beacons: pd.DataFrame, sensor: SensorModel | None) -> np.ndarray:
    """Per-axis CRB variance (trace / 2, px^2) of each beacon row (NaN where unknown).

    Where the dataset recorded the bound of the PSF it drew (``spot_crb_px``, optics on:
    :func:`deckpose.render.optics.spot_crb_px`), that is used; otherwise the Gaussian bound
    of :mod:`deckpose.detect.crb` from the spot model and ``sensor``.
    """
    out = np.full(len(beacons), np.nan)
    recorded = (beacons["spot_crb_px"].to_numpy(float) if "spot_crb_px" in beacons.columns
                else np.full(len(beacons), np.nan))
    if sensor is None or not {"spot_sigma_px", "spot_flux_e"} <= set(beacons.columns):
        sensor = None
    has_bg = "spot_background_e" in beacons.columns
    for k, r in enumerate(beacons.to_dict("records")):
        if r.get("occluded_fraction", 0.0) > 0:  # a cut spot: not the PSF the bound is for
            continue
        if np.isfinite(recorded[k]):
            out[k] = float(recorded[k]) ** 2
            continue
        if sensor is None:
            continue
        if not (r["spot_flux_e"] > 0 and r["spot_sigma_px"] > 0):  # also False for NaN
            continue
        s = sensor
        if has_bg and np.isfinite(r["spot_background_e"]):
            s = dataclasses.replace(sensor, background_e=max(float(r["spot_background_e"]), 0.0))
        crb = centroid_crb_px2(r["u_px"], r["v_px"], r["spot_sigma_px"], r["spot_flux_e"], s)
        out[k] = float(np.trace(crb)) / 2
    return out


def findable(beacons: pd.DataFrame) -> pd.Series:
    """Beacons a detector can find: visible and not wholly hidden by an occluder."""
    ok = beacons["visible"].astype(bool)
    if "occluded_fraction" in beacons:
        ok &= ~(beacons["occluded_fraction"].fillna(0.0) >= 1.0)
    return ok


def match_run(
    detections: pd.DataFrame, frames_out: pd.DataFrame, beacons: pd.DataFrame, frames: pd.DataFrame
) -> pd.DataFrame:
    """Matched per-beacon rows of a whole run, with camera, height (and lighting) per frame.

    ``frames_out`` is ``detect_frames.parquet``; ``beacons`` and ``frames`` the dataset's tables.
    The rows are the findable beacons (:func:`findable`); ``occluded`` marks those an
    occluder cuts in part.
    """
    vis = beacons[findable(beacons)]
    det_by = {k: g for k, g in detections.groupby("frame_id")}
    parts = []
    empty = detections.iloc[:0]
    for fid, g in vis.groupby("frame_id"):
        parts.append(match_frame(det_by.get(fid, empty), g.reset_index(drop=True)))
    m = pd.concat(parts, ignore_index=True) if parts else vis.iloc[:0]
    m["occluded"] = (m["occluded_fraction"].fillna(0.0) > 0).to_numpy() if "occluded_fraction" in m \
        else np.zeros(len(m), bool)
    cols = ["frame_id", "camera", "camera_height_m"] + (["lighting"] if "lighting" in frames else [])
    return m.merge(frames[cols], on="frame_id", how="left")


def false_detections(detections: pd.DataFrame, matches: pd.DataFrame, lights: pd.DataFrame | None,
                     frame_ids: list[int]) -> pd.DataFrame:
    """Per frame: detections matched to no beacon, and the non-beacon lights that drew one.

    Parameters
    ----------
    detections : DataFrame
        One detector's detections.
    matches : DataFrame
        :func:`match_run`'s rows for that detector (``det_index`` per matched beacon).
    lights : DataFrame or None
        The dataset's ``lights.parquet`` (None or empty: no recorded lights).
    frame_ids : list of int
        Every frame of the run.

    Returns
    -------
    DataFrame
        ``frame_id, n_false, n_lights, n_lights_found`` (``n_lights``: recorded lights
        in the image; ``n_lights_found``: of them, those with a false detection within
        :data:`LIGHT_GATE_PX`).
    """
    det_by = {k: g for k, g in detections.groupby("frame_id")}
    used = {k: set(g.loc[g["matched"], "det_index"].astype(int)) for k, g in matches.groupby("frame_id")}
    lit = lights[lights["in_image"].astype(bool)] if lights is not None and len(lights) else None
    light_by = {k: g for k, g in lit.groupby("frame_id")} if lit is not None else {}
    rows = []
    for fid in frame_ids:
        d = det_by.get(fid)
        n = 0 if d is None else len(d)
        free = [j for j in range(n) if j not in used.get(fid, set())]
        lg = light_by.get(fid)
        found = 0
        if lg is not None and free and d is not None:
            P = d[["u_px", "v_px"]].to_numpy(float)[free]
            L = lg[["u_px", "v_px"]].to_numpy(float)
            found = int((np.linalg.norm(L[:, None] - P[None], axis=2).min(axis=1) < LIGHT_GATE_PX).sum())
        rows.append({"frame_id": int(fid), "n_false": len(free), "n_lights": 0 if lg is None else len(lg),
                     "n_lights_found": found})
    return pd.DataFrame(rows, columns=["frame_id", "n_false", "n_lights", "n_lights_found"])


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
    if "occluded" in m:
        m = m[~m["occluded"].astype(bool)]
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
    false: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """One row per camera x height of the metrics in the module docstring.

    ``false`` is :func:`false_detections`' table (None: the false-detection columns are NaN).
    """
    fo = frames_out.merge(frames[["frame_id", "camera_height_m"]], on="frame_id", how="left")
    nd = detections.groupby("frame_id").size()
    occluded = matched["occluded"] if "occluded" in matched else pd.Series(False, index=matched.index)
    rows = []
    for key, g in matched.groupby(["camera", "camera_height_m"], sort=True):
        cam, h = cast("tuple[str, float]", key)
        fids = set(g["frame_id"])
        f = fo[fo["frame_id"].isin(fids)]
        m = g[g["matched"]]
        clear = m[~occluded.loc[m.index]]  # the centroid error and bound: spots no occluder cuts
        du, dv = clear["du_px"].to_numpy(float), clear["dv_px"].to_numpy(float)
        n_det = int(sum(int(nd.get(i, 0)) for i in fids))
        crb = clear["crb_var_px2"].to_numpy(float) if "crb_var_px2" in clear else np.full(len(clear), np.nan)
        rms = math.sqrt(np.mean((du**2 + dv**2) / 2)) if len(clear) else math.nan
        geo = clear[["du_geo_px", "dv_geo_px"]].to_numpy(float) if "du_geo_px" in clear else np.full((0, 2), np.nan)
        rms_geo = math.sqrt(float(np.mean((geo**2).sum(axis=1) / 2))) if len(geo) else math.nan
        crb_rms = math.sqrt(np.mean(crb)) if len(clear) and np.all(np.isfinite(crb)) else math.nan
        sat = g["saturated"].to_numpy(float) if "saturated" in g else np.full(len(g), np.nan)
        occ = g[occluded.loc[g.index]]
        fl = false[false["frame_id"].isin(fids)] if false is not None else None
        rows.append(
            {
                "detector": detector,
                "camera": cam,
                "height_m": float(h),
                "frames": len(fids),
                "beacons": len(g),
                "detections": n_det,
                "radius_px": float(g["apparent_radius_px"].mean()),
                "rms_px": rms,
                "rms_geometric_px": rms_geo,
                "bias_px": float(math.hypot(du.mean(), dv.mean())) if len(clear) else math.nan,
                "p95_px": float(np.percentile(np.hypot(du, dv), 95)) if len(clear) else math.nan,
                "crb_px": crb_rms,
                "rms_over_crb": rms / crb_rms if crb_rms > 0 else math.nan,
                "saturated": float(np.mean(sat))
                if len(g) and np.all(np.isfinite(sat))
                else math.nan,
                "recall": len(m) / len(g) if len(g) else math.nan,
                "recall_occluded": float(occ["matched"].mean()) if len(occ) else math.nan,
                "precision": len(m) / n_det if n_det else math.nan,
                "id_accuracy": float((m["det_beacon_id"] == m["beacon_id"]).mean())
                if len(m)
                else math.nan,
                "false_per_frame": float(fl["n_false"].mean()) if fl is not None and len(fl) else math.nan,
                "lights_found": float(fl["n_lights_found"].sum() / fl["n_lights"].sum())
                if fl is not None and fl["n_lights"].sum() > 0 else math.nan,
                "frames_ok": int(f["ok"].sum()),
                "ms_per_frame": 1000.0 * float(f["seconds"].median()) if len(f) else math.nan,
                "cpu_ms_per_frame": 1000.0 * float(f["cpu_seconds"].median())
                if len(f) and "cpu_seconds" in f
                else math.nan,
            }
        )
    return pd.DataFrame(rows)
