"""The :class:`MotionSeries` record and its CSV/Parquet file form.

File columns: ``t_s, roll_deg, pitch_deg, yaw_deg, heave_m`` and optionally
``surge_m, sway_m`` (ZYX angles of ``R_world_from_deck``). With
``angles="rad"`` the angle columns are ``roll_rad, pitch_rad, yaw_rad``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from deckpose.errors import InputDataError
from deckpose.pose import ShipPose
from deckpose.tables import read_table, write_table

FloatArray = NDArray[np.float64]
_CHANNELS = ("roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m")


@dataclass(frozen=True, init=False)
class MotionSeries:
    """Deck pose over time.

    Attributes
    ----------
    t_s : (T,) array of float
        Strictly increasing times, seconds.
    roll_rad, pitch_rad, yaw_rad : (T,) array of float
        ZYX attitude of the deck.
    heave_m, surge_m, sway_m : (T,) array of float
        Deck-centre displacement, metres.

    ``surge_m`` and ``sway_m`` may be left out (None: zeros); the series always holds
    arrays, hence its own ``__init__``.
    """

    t_s: FloatArray
    roll_rad: FloatArray
    pitch_rad: FloatArray
    yaw_rad: FloatArray
    heave_m: FloatArray
    surge_m: FloatArray
    sway_m: FloatArray

    def __init__(
        self,
        t_s: ArrayLike,
        roll_rad: ArrayLike,
        pitch_rad: ArrayLike,
        yaw_rad: ArrayLike,
        heave_m: ArrayLike,
        surge_m: ArrayLike | None = None,
        sway_m: ArrayLike | None = None,
    ) -> None:
        t = np.array(t_s, dtype=float).ravel()
        if t.size == 0:
            raise InputDataError("a motion series needs at least one sample")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise InputDataError("motion time t_s must be finite and strictly increasing")
        object.__setattr__(self, "t_s", t)
        t.setflags(write=False)
        given = {"roll_rad": roll_rad, "pitch_rad": pitch_rad, "yaw_rad": yaw_rad,
                 "heave_m": heave_m, "surge_m": surge_m, "sway_m": sway_m}
        for name in _CHANNELS:
            v = given[name]
            arr = np.zeros_like(t) if v is None else np.array(v, dtype=float).ravel()
            if arr.shape != t.shape:
                raise InputDataError(f"motion channel {name} has {arr.size} samples, t_s has {t.size}")
            if not np.all(np.isfinite(arr)):
                raise InputDataError(f"motion channel {name} has non-finite values")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.t_s.size)

    def pose(self, i: int) -> ShipPose:
        """The ship pose at sample ``i``."""
        return ShipPose(*(float(getattr(self, c)[i]) for c in _CHANNELS))

    def to_frame(self, *, angles: str = "deg") -> pd.DataFrame:
        """As a table with the file columns (``angles`` ``"deg"`` or ``"rad"``)."""
        df = pd.DataFrame({"t_s": self.t_s})
        for c in ("roll", "pitch", "yaw"):
            v = getattr(self, f"{c}_rad")
            df[f"{c}_{angles}"] = np.degrees(v) if angles == "deg" else v
        for c in ("heave_m", "surge_m", "sway_m"):
            df[c] = getattr(self, c)
        return df


def read_series(path: str | os.PathLike[str], *, angles: str = "deg") -> MotionSeries:
    """Read a motion series from CSV or Parquet (by extension).

    Parameters
    ----------
    path : path-like
    angles : {"deg", "rad"}
        Unit of the angle columns (``roll_deg`` ... or ``roll_rad`` ...).
    """
    if angles not in ("deg", "rad"):
        raise InputDataError(f"angles must be 'deg' or 'rad', got {angles!r}")
    p = Path(path)
    df = read_table(p, "motion series")
    need = ["t_s", f"roll_{angles}", f"pitch_{angles}", f"yaw_{angles}", "heave_m"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        hint = " (angles in radians? pass angles='rad' / --radians)" if angles == "deg" and "roll_rad" in df else ""
        raise InputDataError(f"{p}: missing column(s) {missing}; need {need} [+ surge_m, sway_m]{hint}")
    conv = np.radians if angles == "deg" else (lambda x: x)
    try:
        return MotionSeries(
            t_s=df["t_s"].to_numpy(float),
            roll_rad=conv(df[f"roll_{angles}"].to_numpy(float)),
            pitch_rad=conv(df[f"pitch_{angles}"].to_numpy(float)),
            yaw_rad=conv(df[f"yaw_{angles}"].to_numpy(float)),
            heave_m=df["heave_m"].to_numpy(float),
            surge_m=df["surge_m"].to_numpy(float) if "surge_m" in df else None,
            sway_m=df["sway_m"].to_numpy(float) if "sway_m" in df else None,
        )
    except InputDataError as exc:
        raise InputDataError(f"{p}: {exc}") from None


def write_series(series: MotionSeries, path: str | os.PathLike[str], *, angles: str = "deg") -> None:
    """Write a motion series as CSV or Parquet (by extension), atomically."""
    write_table(series.to_frame(angles=angles), path, "motion series")
