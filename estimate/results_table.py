"""Per-frame estimate tables: :class:`PoseEstimate` records to rows and back."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from deckpose.records import POSE_PARAMS, PoseEstimate

#: Columns every estimates table has, in order.
BASE_COLUMNS = ("frame_id", "method", "ok", "reason", "roll_deg", "pitch_deg", "yaw_deg",
                "surge_m", "sway_m", "height_m")
_SIGMA_COLUMNS = ("sigma_roll_deg", "sigma_pitch_deg", "sigma_yaw_deg", "sigma_surge_m",
                  "sigma_sway_m", "sigma_height_m")


def estimate_row(frame_id: int, est: PoseEstimate) -> dict[str, object]:
    """One table row: angles in degrees, NaN (empty in CSV) for what the method does not give."""
    row: dict[str, object] = {
        "frame_id": int(frame_id),
        "method": est.method,
        "ok": bool(est.ok),
        "reason": est.reason,
        "roll_deg": math.degrees(est.roll_rad),
        "pitch_deg": math.degrees(est.pitch_rad),
        "yaw_deg": math.degrees(est.yaw_rad),
        "surge_m": est.surge_m,
        "sway_m": est.sway_m,
        "height_m": est.height_m,
    }
    if est.covariance is not None:
        sig = np.sqrt(np.clip(np.diag(est.covariance), 0.0, None))
        for name, param, s in zip(_SIGMA_COLUMNS, POSE_PARAMS, sig):
            row[name] = math.degrees(s) if param.endswith("_rad") else float(s)
    row.update({k: float(v) for k, v in est.extras.items()})
    return row


def estimates_frame(frame_ids: Sequence[int], estimates: Sequence[PoseEstimate]) -> pd.DataFrame:
    """A table with one row per frame; base columns first, method extras after."""
    rows = [estimate_row(f, e) for f, e in zip(frame_ids, estimates)]
    df = pd.DataFrame(rows)
    if df.empty:
        return pd.DataFrame(columns=list(BASE_COLUMNS))
    extra = [c for c in df.columns if c not in BASE_COLUMNS]
    df = df[list(BASE_COLUMNS) + extra]
    df["ok"] = df["ok"].astype(bool)
    df["reason"] = df["reason"].fillna("").astype(str)
    return df
