"""Predictions falling due: for each frame, what the filter predicted for it a horizon earlier.

A track's predictions table holds, per frame, the deck's roll, pitch and heave predicted
``horizon_s`` ahead of that frame. To compare a prediction with what happened (in a plot
against time, or in a viewer that plays the run), it belongs at the time it was made *for*:
the frame whose capture time is the prediction's frame time plus the horizon. Frames come
at a finite rate, so "plus the horizon" is matched to the nearest frame of the same time
sequence, within half the sequence's median frame interval, and never at the frame the prediction was made at; a
horizon that falls between frames by more than that, under half a frame interval, or beyond
the sequence's end has no prediction due.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["DUE_COLUMNS", "predictions_due"]

#: Columns of :func:`predictions_due`'s table besides the predictions' own value columns.
DUE_COLUMNS = ("frame_id", "horizon_s", "made_at_frame_id", "due_offset_ns")


def predictions_due(tracks: pd.DataFrame, predictions: pd.DataFrame) -> pd.DataFrame:
    """The prediction made for each frame at each horizon.

    Parameters
    ----------
    tracks : DataFrame
        A track's filtered states (``frame_id``, ``sequence``, ``stamp_ns``; ``TRACK_COLUMNS``).
    predictions : DataFrame
        Its predictions (``frame_id`` made at, ``horizon_s``, ``stamp_ns`` predicted for, and the
        predicted values; ``TRACK_PREDICTION_COLUMNS``).

    Returns
    -------
    DataFrame
        One row per (frame, horizon) with a prediction due: ``frame_id`` (the frame it is due
        at), ``horizon_s``, ``made_at_frame_id``, ``due_offset_ns`` (the frame's capture time
        minus the time predicted for, ns; within half a frame interval) and the predictions'
        value columns (``roll_deg``, ``sigma_roll_deg``, ...), sorted by frame then horizon.
    """
    values = [c for c in predictions.columns if c not in ("frame_id", "horizon_s", "stamp_ns")]
    parts: list[pd.DataFrame] = []
    pred = predictions.rename(columns={"frame_id": "made_at_frame_id", "stamp_ns": "for_stamp_ns"})
    seq_of = tracks.set_index("frame_id")["sequence"]
    pred = pred.assign(sequence=pred["made_at_frame_id"].map(seq_of))
    for s, g in tracks.groupby("sequence", sort=True):
        g = g.sort_values("stamp_ns", kind="stable")
        stamps = g["stamp_ns"].to_numpy(np.int64)
        ids = g["frame_id"].to_numpy(np.int64)
        if len(stamps) < 2:
            continue
        half_ns = 0.5 * float(np.median(np.diff(stamps)))
        p = pred[pred["sequence"] == s]
        target = p["for_stamp_ns"].to_numpy(np.int64)
        k = np.clip(np.searchsorted(stamps, target), 1, len(stamps) - 1)
        k = np.where(np.abs(stamps[k - 1] - target) <= np.abs(stamps[k] - target), k - 1, k)
        offset = stamps[k] - target
        made_at = p["made_at_frame_id"].to_numpy(np.int64)
        keep = (np.abs(offset) <= half_ns) & (ids[k] != made_at)   # a prediction is due at a later frame
        parts.append(pd.DataFrame({
            "frame_id": ids[k][keep], "horizon_s": p["horizon_s"].to_numpy(float)[keep],
            "made_at_frame_id": p["made_at_frame_id"].to_numpy(np.int64)[keep],
            "due_offset_ns": offset[keep].astype(np.int64),
            **{c: p[c].to_numpy()[keep] for c in values},
        }))
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype="int64" if c != "horizon_s" else "float64")
                             for c in DUE_COLUMNS} | {c: pd.Series(dtype="float64") for c in values})
    out = pd.concat(parts, ignore_index=True)
    # two predictions due at one frame and horizon (frames closer than the rule's half interval): the nearer
    out = out.assign(_abs=out["due_offset_ns"].abs()).sort_values(["frame_id", "horizon_s", "_abs"], kind="stable")
    out = out.drop_duplicates(["frame_id", "horizon_s"]).drop(columns="_abs")
    return out.reset_index(drop=True)
