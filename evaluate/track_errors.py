"""Errors of a track (``deckpose track``) against the truth: filtered against per frame, predicted against held.

Pure functions on tables in the run-folder formats. The per-frame and the filtered pose are
scored by one rule, :func:`deckpose.evaluate.errors.frame_errors` (the filtered states are
an estimates table whose every row is ok). A prediction is scored at the frame it was made
for (:func:`deckpose.tracking.due_predictions.predictions_due`), against the truth there;
its peer is holding the last ok per-frame estimate of its sequence as of the frame the
prediction was made at.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from deckpose.evaluate.errors import frame_errors

from deckpose.rotation import wrap_angle_deg
from deckpose.tracking.due_predictions import predictions_due

__all__ = ["HEIGHT_BANDS_M", "filtered_by_height", "markdown_table", "predicted_roll_errors", "prediction_errors",
           "track_frame_errors"]

#: Bands of the true height for :func:`filtered_by_height`, metres.
HEIGHT_BANDS_M = (0.0, 20.0, 40.0, 60.0, 100.0, np.inf)
_SCORED = ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m")


def _rms(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(np.square(a)))) if a.size else float("nan")


def track_frame_errors(frames: pd.DataFrame, estimates: pd.DataFrame, tracks: pd.DataFrame) -> pd.DataFrame:
    """Per frame: the per-frame estimate's and the filtered pose's errors, and the filtered error in its sigmas.

    Parameters
    ----------
    frames : DataFrame
        The frames table (truth).
    estimates : DataFrame
        The estimates table the track filtered.
    tracks : DataFrame
        The track (``TRACK_COLUMNS``).

    Returns
    -------
    DataFrame
        One row per frame of the track: ``frame_id, sequence, status, t_s, true_height_m``, the
        per-frame errors ``<q>_err_<unit>_estimate`` (NaN where the estimate is not ok), the
        filtered errors ``<q>_err_<unit>_filtered`` and ``<q>_z_filtered`` (error / the filtered
        sigma) for roll, pitch, yaw and height.
    """
    pseudo = tracks.assign(method="track", ok=True, reason="")
    filt = frame_errors(frames, pseudo).set_index("frame_id")
    per = frame_errors(frames, estimates).set_index("frame_id").reindex(filt.index)
    out = pd.DataFrame(index=filt.index)
    t = tracks.set_index("frame_id")
    out["sequence"] = t["sequence"]
    out["status"] = t["status"].astype(str)
    out["t_s"] = frames.set_index("frame_id")["t_s"].reindex(filt.index)
    out["true_height_m"] = filt["true_height_m"]
    for q in _SCORED:
        out[f"{q}_estimate"] = per[q]
        out[f"{q}_filtered"] = filt[q]
        sigma = filt[f"sigma_{q.replace('_err', '')}"]
        out[f"{q.rsplit('_err', 1)[0]}_z_filtered"] = filt[q] / sigma
    return out.reset_index()


def filtered_by_height(errors: pd.DataFrame) -> pd.DataFrame:
    """RMS of the per-frame and filtered errors in bands of the true height (:data:`HEIGHT_BANDS_M`).

    Parameters
    ----------
    errors : DataFrame
        :func:`track_frame_errors`'s table.

    Returns
    -------
    DataFrame
        Per band with frames: ``height_band_m``, ``frames``, ``estimates_ok`` (share of frames with an
        ok estimate), and for roll, pitch and height the RMS per frame and filtered on the same
        frames (those with an ok estimate), their ratio, and the filtered RMS on every frame of the
        band (``<q>_rms_filtered_all``: frames without an estimate are the filter's predictions).
    """
    bands = pd.cut(errors["true_height_m"], list(HEIGHT_BANDS_M), right=False)
    rows = []
    for band, g in errors.groupby(bands, observed=True):
        row: dict[str, object] = {"height_band_m": f"{band.left:g}-{band.right:g}", "frames": len(g),
                                  "estimates_ok": float(g["roll_err_deg_estimate"].notna().mean())}
        for q in ("roll_err_deg", "pitch_err_deg", "height_err_m"):
            scored = g[f"{q}_estimate"].notna().to_numpy()  # one set of frames for both
            per = _rms(g[f"{q}_estimate"].to_numpy()[scored])
            filt = _rms(g[f"{q}_filtered"].to_numpy()[scored])
            row[f"{q}_rms_estimate"], row[f"{q}_rms_filtered"] = per, filt
            row[f"{q}_ratio"] = filt / per if per > 0 else float("nan")
            row[f"{q}_rms_filtered_all"] = _rms(g[f"{q}_filtered"].to_numpy())
        rows.append(row)
    return pd.DataFrame(rows)


def prediction_errors(frames: pd.DataFrame, estimates: pd.DataFrame, tracks: pd.DataFrame,
                      predictions: pd.DataFrame) -> pd.DataFrame:
    """RMS error of the predictions per horizon, beside holding the last ok estimate as long.

    Parameters
    ----------
    frames, estimates, tracks, predictions : DataFrame
        The run's truth, the estimates the track filtered, the track and its predictions.

    Returns
    -------
    DataFrame
        Per horizon: ``horizon_s``, ``scored`` (predictions due at a frame, with a held estimate to
        compare), and for roll (deg), pitch (deg) and height (m): ``<q>_rms_predicted``,
        ``<q>_rms_held``, ``<q>_ratio`` (predicted over held) and ``<q>_z_rms`` (RMS of the
        prediction's error in its own sigmas: 1 for an honest prediction).
    """
    due = predictions_due(tracks, predictions)
    truth = frames.set_index("frame_id")
    true_height = truth["cam_z_m"] - truth["heave_m"]
    # the last ok estimate of each frame's sequence, as of that frame
    est = estimates.set_index("frame_id").reindex(tracks["frame_id"])
    order = tracks.sort_values(["sequence", "stamp_ns"], kind="stable")
    ok = est["ok"].fillna(False).astype(bool).reindex(order["frame_id"]).to_numpy()
    held = est.loc[order["frame_id"], ["roll_deg", "pitch_deg", "height_m"]].where(np.repeat(ok[:, None], 3, axis=1))
    held = held.groupby(order["sequence"].to_numpy()).ffill()
    held.index = order["frame_id"].to_numpy()
    rows = []
    for h, g in due.groupby("horizon_s", sort=True):
        h = float(np.asarray(h, float))
        made, at = g["made_at_frame_id"].to_numpy(), g["frame_id"].to_numpy()
        row: dict[str, object] = {"horizon_s": h}
        truth_at = {"roll_deg": truth.loc[at, "roll_deg"].to_numpy(float),
                    "pitch_deg": truth.loc[at, "pitch_deg"].to_numpy(float),
                    "height_m": true_height.loc[at].to_numpy(float)}
        keep = np.isfinite(held.loc[made, "roll_deg"].to_numpy(float))
        row["scored"] = int(keep.sum())
        for q, t in truth_at.items():
            pe = g[q].to_numpy(float) - t
            he = held.loc[made, q].to_numpy(float) - t
            if q != "height_m":
                pe, he = wrap_angle_deg(pe), wrap_angle_deg(he)
            pred_rms, held_rms = _rms(pe[keep]), _rms(he[keep])
            row[f"{q}_rms_predicted"], row[f"{q}_rms_held"] = pred_rms, held_rms
            row[f"{q}_ratio"] = pred_rms / held_rms if held_rms > 0 else float("nan")
            row[f"{q}_z_rms"] = _rms((pe / g[f"sigma_{q}"].to_numpy(float))[keep])
        rows.append(row)
    # a track shorter than every horizon has no prediction due: no rows, the same columns
    columns = ["horizon_s", "scored", *(f"{q}_{k}" for q in ("roll_deg", "pitch_deg", "height_m")
                                        for k in ("rms_predicted", "rms_held", "ratio", "z_rms"))]
    return pd.DataFrame(rows, columns=columns)


def predicted_roll_errors(frames: pd.DataFrame, tracks: pd.DataFrame, predictions: pd.DataFrame,
                          horizon_s: float) -> pd.DataFrame:
    """The roll error of the prediction due at each frame for one horizon, in time order.

    Returns
    -------
    DataFrame
        ``frame_id, t_s, roll_err_deg`` (the prediction made ``horizon_s`` earlier minus the
        truth at the frame, wrapped to [-180, 180) deg), with ``attrs["horizon_s"]``.
    """
    due = predictions_due(tracks, predictions[predictions["horizon_s"] == horizon_s])
    truth = frames.set_index("frame_id").loc[due["frame_id"]]
    err = wrap_angle_deg(due["roll_deg"].to_numpy(float) - truth["roll_deg"].to_numpy(float))
    out = pd.DataFrame({"frame_id": due["frame_id"].to_numpy(), "t_s": truth["t_s"].to_numpy(float),
                        "roll_err_deg": err}).sort_values("t_s", kind="stable").reset_index(drop=True)
    out.attrs["horizon_s"] = float(horizon_s)
    return out


def markdown_table(table: pd.DataFrame, digits: int = 3) -> list[str]:
    """A table as Markdown lines; floats to ``digits`` significant digits."""
    def cell(v: object) -> str:
        if isinstance(v, (float, np.floating)):
            return "" if not np.isfinite(v) else f"{float(v):.{digits}g}"
        return str(v)

    lines = ["| " + " | ".join(map(str, table.columns)) + " |", "|" + "---|" * len(table.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return lines
