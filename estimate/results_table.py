"""Per-frame estimate tables: :class:`PoseEstimate` records to rows and back.

A row holds the pose (angles in degrees), its standard deviations (``sigma_*``, degrees
and metres) and the full 6x6 covariance as its 21 upper-triangle entries
``cov_<a>__<b>`` in the units of :data:`~deckpose.records.POSE_PARAMS` (radians and
metres; ``cov_roll_rad__pitch_rad`` is in rad^2, ``cov_roll_rad__height_m`` in rad m),
so :func:`estimates_from_frame` gives back the records as they were, covariance and all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import combinations_with_replacement

import numpy as np
import pandas as pd

from deckpose.records import POSE_PARAMS, PoseEstimate

#: Columns every estimates table has, in order.
BASE_COLUMNS = ("frame_id", "method", "ok", "reason", "roll_deg", "pitch_deg", "yaw_deg",
                "surge_m", "sway_m", "height_m")
_SIGMA_COLUMNS = ("sigma_roll_deg", "sigma_pitch_deg", "sigma_yaw_deg", "sigma_surge_m",
                  "sigma_sway_m", "sigma_height_m")
#: The covariance's upper triangle: ``(column, row index, column index)`` over POSE_PARAMS.
COVARIANCE_COLUMNS: tuple[tuple[str, int, int], ...] = tuple(
    (f"cov_{POSE_PARAMS[i]}__{POSE_PARAMS[j]}", i, j)
    for i, j in combinations_with_replacement(range(len(POSE_PARAMS)), 2)
)
#: Extras that are counts or beacon ids (integer columns, null where a frame has none) and
#: yes/no flags (boolean columns); the records hold every extra as a float.
INTEGER_EXTRAS = ("n_points", "n_ignored", "n_outliers_removed", "n_solutions", "dof",
                  "outlier_id_0", "outlier_id_1", "outlier_id_2")
FLAG_EXTRAS = ("refined", "posterior_mean", "centre_beacon_used", "assumed_level_deck")
_SIGMA_EXTRAS = frozenset("sigma_" + p for p in POSE_PARAMS)
_TABLE_ONLY = {*BASE_COLUMNS, *_SIGMA_COLUMNS, *(c for c, _, _ in COVARIANCE_COLUMNS)}


def estimate_row(est: PoseEstimate) -> dict[str, object]:
    """One table row: angles in degrees, NaN (empty in CSV) for what the method does not give."""
    row: dict[str, object] = {
        "frame_id": int(est.frame_id),
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
        for name, i, j in COVARIANCE_COLUMNS:
            row[name] = float(est.covariance[i, j])
    # the records' sigma_<param> extras (radians, metres) are the covariance's diagonal,
    # which the table holds in full: one unit per quantity
    row.update({k: float(v) for k, v in est.extras.items() if k not in _SIGMA_EXTRAS})
    return row


def estimates_from_frame(df: pd.DataFrame) -> list[PoseEstimate]:
    """The records of an estimates table (the inverse of :func:`estimates_frame`).

    Columns other than the pose, its sigmas and its covariance come back as extras (an
    extra that is NaN in the table, as where a frame's record lacked it, comes back
    absent); the records' ``sigma_<param>`` extras come back from the covariance.
    ``inliers`` are not stored in the table and come back empty.
    """
    cov_cols = [c for c, _, _ in COVARIANCE_COLUMNS]
    has_cov = all(c in df.columns for c in cov_cols)
    extra_cols = [c for c in df.columns if c not in _TABLE_ONLY]
    out = []
    for row in df.to_dict("records"):
        cov = None
        if has_cov and all(np.isfinite(float(row[c])) for c in cov_cols):
            cov = np.zeros((6, 6))
            for name, i, j in COVARIANCE_COLUMNS:
                cov[i, j] = cov[j, i] = float(row[name])
        extras = {c: float(row[c]) for c in extra_cols if not _missing(row[c])}
        if cov is not None:
            extras.update({"sigma_" + p: float(np.sqrt(cov[k, k])) for k, p in enumerate(POSE_PARAMS)})
        est = PoseEstimate(
            method=str(row["method"]), ok=bool(row["ok"]), reason=str(row["reason"] or ""),
            roll_rad=math.radians(float(row["roll_deg"])), pitch_rad=math.radians(float(row["pitch_deg"])),
            yaw_rad=math.radians(float(row["yaw_deg"])), surge_m=float(row["surge_m"]),
            sway_m=float(row["sway_m"]), height_m=float(row["height_m"]), covariance=cov, extras=extras,
            frame_id=int(row["frame_id"]),
        )
        out.append(est)
    return out


def _missing(value: object) -> bool:
    return value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value))


def estimates_frame(estimates: Sequence[PoseEstimate]) -> pd.DataFrame:
    """A table with one row per estimate (its ``frame_id``); base columns first, method extras after."""
    rows = [estimate_row(e) for e in estimates]
    df = pd.DataFrame(rows)
    if df.empty:
        return pd.DataFrame(columns=list(BASE_COLUMNS))
    extra = [c for c in df.columns if c not in BASE_COLUMNS]
    df = df[list(BASE_COLUMNS) + extra]
    df["ok"] = df["ok"].astype(bool)
    df["reason"] = df["reason"].fillna("").astype(str)
    for c in INTEGER_EXTRAS:
        if c in df.columns:
            df[c] = df[c].astype("Int64")
    for c in FLAG_EXTRAS:
        if c in df.columns:
            df[c] = df[c].astype("boolean")
    return df
