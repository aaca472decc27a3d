"""Per-frame estimates as the filter's measurements: values, full covariance, and whether usable.

Reads the estimates table's columns (:mod:`deckpose.estimates_schema`): the pose in degrees
and metres, the covariance's upper triangle ``cov_<a>__<b>`` in radians and metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from deckpose.errors import InputDataError
from deckpose.estimates_schema import COVARIANCE_COLUMNS
from deckpose.records import POSE_PARAMS

__all__ = ["Measurements", "measurements_from_estimates"]

#: The estimates table's pose columns in POSE_PARAMS order (degrees for angles).
POSE_COLUMNS = tuple(p[: -len("_rad")] + "_deg" if p.endswith("_rad") else p for p in POSE_PARAMS)


@dataclass(frozen=True)
class Measurements:
    """The filter's measurements of N frames.

    Attributes
    ----------
    z : (N, 6) array of float
        roll, pitch, yaw (rad), surge, sway, height (m); NaN where the frame has no estimate.
    R : (N, 6, 6) array of float
        Covariance of ``z`` (radians and metres); NaN where the estimate gives none.
    usable : (N,) array of bool
        ok, with finite values and a finite, positive-definite covariance.
    """

    z: NDArray[np.float64]
    R: NDArray[np.float64]
    usable: NDArray[np.bool_]


def measurements_from_estimates(estimates: pd.DataFrame, frame_ids: NDArray[np.int64], *,
                                source: str = "estimates") -> Measurements:
    """The estimates of ``frame_ids``, in that order (a frame without a row is not usable).

    Parameters
    ----------
    estimates : DataFrame
        An estimates table (``frame_id, ok``, the pose columns and ``cov_<a>__<b>``).
    frame_ids : (N,) array of int
        The frames wanted, in the filter's order.
    source : str, keyword-only
        How messages name the table.

    Raises
    ------
    InputDataError
        A needed column is missing, or a frame has two rows.
    """
    need = ["frame_id", "ok", *POSE_COLUMNS, *(c for c, _, _ in COVARIANCE_COLUMNS)]
    missing = [c for c in need if c not in estimates.columns]
    if missing:
        raise InputDataError(f"{source}: missing column(s) {missing}; tracking needs an estimates table as "
                             "'deckpose estimate' writes it (with the covariance columns cov_<a>__<b>)")
    dup = estimates["frame_id"].duplicated()
    if dup.any():
        raise InputDataError(f"{source}: frame {int(estimates['frame_id'][dup].iloc[0])} has more than one row; "
                             "track one method's estimates at a time")
    e = estimates.set_index("frame_id").reindex(np.asarray(frame_ids, np.int64))
    z = e[list(POSE_COLUMNS)].to_numpy(float, copy=True)
    z[:, :3] = np.radians(z[:, :3])
    n = len(e)
    R = np.full((n, 6, 6), np.nan)
    for name, i, j in COVARIANCE_COLUMNS:
        v = e[name].to_numpy(float)
        R[:, i, j] = v
        R[:, j, i] = v
    ok = e["ok"].fillna(False).to_numpy(bool)
    finite = np.isfinite(z).all(axis=1) & np.isfinite(R).all(axis=(1, 2))
    usable = ok & finite
    if usable.any():  # positive definite (a Cholesky factor exists)
        Ru = R[usable]
        pd_ok = np.array([_positive_definite(r) for r in Ru])
        idx = np.flatnonzero(usable)
        usable[idx[~pd_ok]] = False
    return Measurements(z, R, usable)


def _positive_definite(r: NDArray[np.float64]) -> bool:
    try:
        np.linalg.cholesky(r)
    except np.linalg.LinAlgError:
        return False
    return True
