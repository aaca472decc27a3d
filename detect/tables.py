"""Detection tables on disk: ``detections.parquet`` and ``detect_frames.parquet``.

``detections.parquet``: one row per frame x detection: ``frame_id, beacon_id``
(-1 = unassigned), ``u_px, v_px, cov_uu, cov_uv, cov_vv`` (px^2), ``flux`` (DN),
``size_px``, ``score``, ``detector``.

``detect_frames.parquet``: one row per frame: ``frame_id, ok, reason,
n_detections, seconds`` plus ``n_identified, camera, stamp_ns, image``.
"""

from __future__ import annotations

import os
from typing import cast

import numpy as np
import pandas as pd
from deckpose.detect.frame_detection import FrameDetections

from deckpose.errors import InputDataError
from deckpose.records import Detections
from deckpose.table_schemas import DETECTION_COLUMNS as DETECTION_SCHEMA
from deckpose.table_schemas import upgrade_legacy_columns
from deckpose.tables import write_table

#: ``detections.parquet``'s columns, in order (their schema: :data:`deckpose.table_schemas.DETECTION_COLUMNS`).
DETECTION_COLUMNS: tuple[str, ...] = tuple(c.name for c in DETECTION_SCHEMA)
FRAME_COLUMNS = ("frame_id", "ok", "reason", "n_detections", "seconds")


def detection_rows(fd: FrameDetections) -> pd.DataFrame:
    """The ``detections.parquet`` rows of one frame."""
    d = fd.detections
    n = len(d)
    return pd.DataFrame(
        {
            "frame_id": np.full(n, d.frame_id, np.int64),
            "beacon_id": np.asarray(d.beacon_ids, np.int64),
            "u_px": d.points_px[:, 0],
            "v_px": d.points_px[:, 1],
            "cov_uu": d.covariance_px2[:, 0, 0],
            "cov_uv": d.covariance_px2[:, 0, 1],
            "cov_vv": d.covariance_px2[:, 1, 1],
            "flux_dn": np.asarray(fd.flux_dn, float),
            "size_px": np.asarray(fd.size_px, float),
            "snr": np.asarray(d.score, float),
            "detector": pd.Series([fd.detector] * n, dtype=str),
        },
        columns=list(DETECTION_COLUMNS),
    )


def write_tables(
    detections_path: str | os.PathLike[str],
    frames_path: str | os.PathLike[str],
    detections: pd.DataFrame,
    frames: pd.DataFrame,
) -> None:
    """Write both tables atomically."""
    write_table(detections, detections_path, "detections")
    write_table(frames, frames_path, "detect frames")


def read_detections(path: str | os.PathLike[str]) -> dict[int, Detections]:
    """Read ``detections.parquet`` into one :class:`Detections` per frame id."""
    try:
        df = upgrade_legacy_columns(pd.read_parquet(path), "detections")
    except Exception as exc:
        raise InputDataError(f"cannot read detections table {path}: {exc}") from exc
    missing = set(DETECTION_COLUMNS) - set(df.columns)
    if missing:
        raise InputDataError(f"{path}: missing columns {sorted(missing)}")
    out = {}
    for key, g in df.groupby("frame_id", sort=True):
        fid = int(cast(int, key))  # a frame id (pandas' stubs type a group key as any scalar)
        cov = np.stack([g.cov_uu, g.cov_uv, g.cov_uv, g.cov_vv], axis=1).reshape(-1, 2, 2)
        out[fid] = Detections(
            g[["u_px", "v_px"]].to_numpy(float),
            g.beacon_id.to_numpy(np.int64),
            cov,
            g.snr.to_numpy(float),
            frame_id=fid,
        )
    return out
