"""Per-frame errors: ground truth joined with detections and estimates.

Pure functions on tables (pandas DataFrames in the run-folder formats of
:mod:`deckpose.run_folder`). Angle errors are wrapped to [-180, 180)
degrees; the true height is the camera's height above the deck centre along
world z; surge and sway are relative to the point under the camera.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from deckpose.rotation import wrap_angle_deg

#: Error columns of the per-frame error table, in report order.
POSE_ERRORS = ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m", "surge_err_m", "sway_err_m")



def centroid_errors(beacons: pd.DataFrame, detections: pd.DataFrame) -> pd.DataFrame:
    """Per-detection centroid errors of identified detections against the projected truth.

    Parameters
    ----------
    beacons : DataFrame
        ``frame_id, beacon_id, u_px, v_px, visible, apparent_radius_px`` (truth).
    detections : DataFrame
        ``frame_id, beacon_id, u_px, v_px`` (beacon_id -1 = unassigned).

    Returns
    -------
    DataFrame
        One row per identified detection of a visible beacon: ``frame_id, beacon_id,
        du_px, dv_px, err_px, apparent_radius_px``.
    """
    det = detections[detections["beacon_id"] >= 0][["frame_id", "beacon_id", "u_px", "v_px"]]
    truth = beacons[beacons["visible"].astype(bool)][["frame_id", "beacon_id", "u_px", "v_px", "apparent_radius_px"]]
    m = det.merge(truth, on=["frame_id", "beacon_id"], suffixes=("", "_true"))
    m["du_px"] = m["u_px"] - m["u_px_true"]
    m["dv_px"] = m["v_px"] - m["v_px_true"]
    m["err_px"] = np.hypot(m["du_px"], m["dv_px"])
    return m[["frame_id", "beacon_id", "du_px", "dv_px", "err_px", "apparent_radius_px"]]


def frame_centroid_stats(beacons: pd.DataFrame, detections: pd.DataFrame) -> pd.DataFrame:
    """Per-frame centroid RMS (px), identified count, recall and mean apparent radius."""
    ce = centroid_errors(beacons, detections)
    g = ce.groupby("frame_id")
    stats = pd.DataFrame({
        "centroid_rms_px": g["err_px"].apply(lambda e: float(np.sqrt(np.mean(np.square(e))))),
        "n_identified": g.size(),
        "apparent_radius_px": g["apparent_radius_px"].mean(),
    })
    n_vis = beacons[beacons["visible"].astype(bool)].groupby("frame_id").size().rename("n_visible_true")
    out = pd.DataFrame({"frame_id": beacons["frame_id"].unique()}).set_index("frame_id")
    out = out.join(n_vis).join(stats)
    out["n_visible_true"] = out["n_visible_true"].fillna(0).astype(int)
    out["n_identified"] = out["n_identified"].fillna(0).astype(int)
    out["recall"] = np.where(out["n_visible_true"] > 0, out["n_identified"] / out["n_visible_true"].clip(lower=1), np.nan)
    return out.reset_index()


def frame_errors(frames: pd.DataFrame, estimates: pd.DataFrame) -> pd.DataFrame:
    """Pose errors per frame (estimate minus truth) with the estimate's flags and sigmas.

    Parameters
    ----------
    frames : DataFrame
        The dataset's frames table (truth): ``roll_deg, pitch_deg, yaw_deg, heave_m,
        surge_m, sway_m, cam_x_m, cam_y_m, cam_z_m, thesis_*_deg, camera, camera_height_m``.
    estimates : DataFrame
        An estimates table (``deckpose estimate`` output).
    """
    t = frames.set_index("frame_id")
    e = estimates.set_index("frame_id")
    idx = e.index.intersection(t.index)
    t, e = t.loc[idx], e.loc[idx]
    out = pd.DataFrame(index=idx)
    out["camera"] = t["camera"]
    out["table_height_m"] = t["camera_height_m"]
    out["method"] = e["method"]
    out["ok"] = e["ok"].astype(bool)
    out["reason"] = e["reason"].fillna("").astype(str)
    for name in ("roll", "pitch", "yaw"):
        out[f"{name}_err_deg"] = wrap_angle_deg(e[f"{name}_deg"].to_numpy(float) - t[f"{name}_deg"].to_numpy(float))
    true_height = t["cam_z_m"].to_numpy(float) - t["heave_m"].to_numpy(float)
    out["true_height_m"] = true_height
    out["height_err_m"] = e["height_m"].to_numpy(float) - true_height
    out["surge_err_m"] = e["surge_m"].to_numpy(float) - (t["surge_m"] - t["cam_x_m"]).to_numpy(float)
    out["sway_err_m"] = e["sway_m"].to_numpy(float) - (t["sway_m"] - t["cam_y_m"]).to_numpy(float)
    if "thesis_roll_deg" in e.columns and e["thesis_roll_deg"].notna().any():  # (null for other methods)
        for q in ("roll", "pitch", "yaw"):
            out[f"thesis_{q}_err_deg"] = wrap_angle_deg(e[f"thesis_{q}_deg"].to_numpy(float) - t[f"thesis_{q}_deg"].to_numpy(float))
    for c in e.columns:
        if c.startswith("sigma_"):
            out[c] = e[c]
    # An estimate flagged not ok carries no numbers worth scoring.
    out.loc[~out["ok"], [c for c in out.columns if c.endswith(("_err_deg", "_err_m"))]] = np.nan
    return out.reset_index()


def run_errors(frames: pd.DataFrame, beacons: pd.DataFrame, detections: pd.DataFrame,
               estimates: pd.DataFrame, detector: str) -> pd.DataFrame:
    """Pose and centroid errors of one (detector, method) pair, one row per frame."""
    fe = frame_errors(frames, estimates)
    cs = frame_centroid_stats(beacons[beacons["frame_id"].isin(fe["frame_id"])], detections)
    out = fe.merge(cs, on="frame_id", how="left")
    out.insert(1, "detector", detector)
    return out
