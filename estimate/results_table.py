"""Per-frame estimate tables: :class:`PoseEstimate` records to rows and back.

A table has exactly the columns of :data:`~deckpose.estimates_schema.ESTIMATE_COLUMNS`,
in order and with their types, whatever the method (null where a method gives no
value): the pose (angles in degrees), its standard deviations (``sigma_*``, degrees and
metres), the full 6x6 covariance as its 21 upper-triangle entries ``cov_<a>__<b>`` in
the units of :data:`~deckpose.records.POSE_PARAMS` (radians and metres), every built-in
estimator's extras in typed columns (counts and ids integer, flags boolean, angles in
degrees) and a plugin estimator's other extras as JSON in ``extras_json``. So
:func:`estimates_from_frame` gives back the records as they were, covariance and all.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from deckpose.estimates_schema import (
    COVARIANCE_COLUMNS,
    ESTIMATE_COLUMNS,
    EXTRAS_JSON,
    SIGMA_COLUMNS,
)
from deckpose.records import POSE_PARAMS, PoseEstimate
from deckpose.table_schemas import Column, pandas_dtype

__all__ = ["BASE_COLUMNS", "COLUMN_NAMES", "COVARIANCE_COLUMNS", "estimate_row", "estimates_frame",
           "estimates_from_frame"]

#: Every estimates table's columns, in order.
COLUMN_NAMES = tuple(c.name for c in ESTIMATE_COLUMNS)
#: The columns of the record's own fields (the pose), first in every table.
BASE_COLUMNS = COLUMN_NAMES[:10]
#: Extras key -> the column that holds it.
_BY_EXTRA: dict[str, Column] = {c.extra: c for c in ESTIMATE_COLUMNS if c.extra}
_SIGMA_EXTRAS = tuple("sigma_" + p for p in POSE_PARAMS)


def _in_table(extra: str, col: Column, value: float) -> float:
    """An extra's value as its column holds it: an angle the record holds in radians, in degrees."""
    return math.degrees(value) if col.unit == "deg" and extra.endswith("_rad") else float(value)


def _in_record(col: Column, value: float) -> float:
    return math.radians(value) if col.unit == "deg" and col.extra.endswith("_rad") else float(value)


def _sigma_in_table(param: str, s: float) -> float:
    return math.degrees(s) if param.endswith("_rad") else float(s)


def estimate_row(est: PoseEstimate) -> dict[str, object]:
    """One table row (the schema's columns this record gives; the others are null).

    Extras no column holds (a plugin estimator's) go into ``extras_json``, non-finite
    values as null. The records' ``sigma_<param>`` extras are the covariance's diagonal,
    which the table holds in full; without a covariance they fill the ``sigma_*`` columns.
    """
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
        for name, param, s in zip(SIGMA_COLUMNS, POSE_PARAMS, sig):
            row[name] = _sigma_in_table(param, float(s))
        for name, i, j in COVARIANCE_COLUMNS:
            row[name] = float(est.covariance[i, j])
    other: dict[str, float | None] = {}
    for key, value in est.extras.items():
        if key in _SIGMA_EXTRAS:
            if est.covariance is None:
                k = _SIGMA_EXTRAS.index(key)
                row[SIGMA_COLUMNS[k]] = _sigma_in_table(POSE_PARAMS[k], float(value))
        elif key in _BY_EXTRA:
            col = _BY_EXTRA[key]
            row[col.name] = _in_table(key, col, float(value))
        else:
            other[key] = float(value) if math.isfinite(value) else None
    if other:
        row[EXTRAS_JSON] = json.dumps(other, sort_keys=True, allow_nan=False)
    return row


def _typed(values: pd.Series, col: Column) -> pd.Series:
    """A column in its schema's pandas dtype (raises where a count or flag is not one)."""
    if col.dtype == "string":
        out = values.astype(object).where(values.notna(), None)
        return out.fillna("") if not col.nullable else out
    if col.dtype in ("int64", "bool") and values.dtype == object:
        values = pd.to_numeric(values)  # ints, bools and NaN mixed in one column
    return values.astype(pandas_dtype(col))


def estimates_frame(estimates: Sequence[PoseEstimate]) -> pd.DataFrame:
    """A table with one row per estimate (its ``frame_id``): exactly the schema's columns and types."""
    df = pd.DataFrame([estimate_row(e) for e in estimates], columns=list(COLUMN_NAMES))
    return pd.DataFrame({c.name: _typed(df[c.name], c) for c in ESTIMATE_COLUMNS}, index=df.index)


def _missing(value: object) -> bool:
    return value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value))


def _extras_of(row: Mapping[str, object], others: Sequence[str]) -> dict[str, float]:
    """The record's extras in a row: typed columns, unknown columns (older tables), ``extras_json``."""
    extras: dict[str, float] = {}
    for col in ESTIMATE_COLUMNS:
        value = row.get(col.name)
        if col.extra and not _missing(value):
            extras[col.extra] = _in_record(col, float(value))  # type: ignore[arg-type]
    for name in others:
        if not _missing(row[name]):
            extras[name] = float(row[name])  # type: ignore[arg-type]
    raw = row.get(EXTRAS_JSON)
    if isinstance(raw, str) and raw:
        extras.update({k: math.nan if v is None else float(v) for k, v in json.loads(raw).items()})
    return extras


def estimates_from_frame(df: pd.DataFrame) -> list[PoseEstimate]:
    """The records of an estimates table (the inverse of :func:`estimates_frame`).

    Extras come back under their record names (``ml_roll_rad`` from ``ml_roll_deg``, in
    radians); a null extra, as where a frame's record lacked it, comes back absent, and a
    plugin's non-finite extra comes back NaN. The ``sigma_<param>`` extras come back from
    the covariance (or the ``sigma_*`` columns where a row has none). Columns the schema
    does not know (a table of an older layout) come back as extras of their names.
    ``inliers`` are not stored in the table and come back empty.
    """
    cov_cols = [c for c, _, _ in COVARIANCE_COLUMNS]
    has_cov = all(c in df.columns for c in cov_cols)
    others = [str(c) for c in df.columns if c not in COLUMN_NAMES]
    out = []
    for row in df.to_dict("records"):
        row = {str(k): v for k, v in row.items()}
        cov = None
        if has_cov and all(not _missing(row[c]) and np.isfinite(float(row[c])) for c in cov_cols):
            cov = np.zeros((6, 6))
            for name, i, j in COVARIANCE_COLUMNS:
                cov[i, j] = cov[j, i] = float(row[name])
        extras = _extras_of(row, others)
        if cov is not None:
            extras.update({"sigma_" + p: float(np.sqrt(cov[k, k])) for k, p in enumerate(POSE_PARAMS)})
        else:
            for name, p in zip(SIGMA_COLUMNS, POSE_PARAMS):
                if not _missing(row.get(name)):
                    s = float(row[name])  # type: ignore[arg-type]
                    extras["sigma_" + p] = math.radians(s) if p.endswith("_rad") else s
        est = PoseEstimate(
            method=str(row["method"]), ok=bool(row["ok"]),
            reason="" if _missing(row["reason"]) else str(row["reason"]),
            roll_rad=math.radians(float(row["roll_deg"])), pitch_rad=math.radians(float(row["pitch_deg"])),
            yaw_rad=math.radians(float(row["yaw_deg"])), surge_m=float(row["surge_m"]),
            sway_m=float(row["sway_m"]), height_m=float(row["height_m"]), covariance=cov, extras=extras,
            frame_id=int(row["frame_id"]),
        )
        out.append(est)
    return out
