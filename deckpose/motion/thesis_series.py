"""The thesis's 495-sample motion series, regenerated from the closed-form model.

Four regular-wave segments of periods ``75/v16, 90/v16, 75/v11, 90/v11`` s
(v16, v11 = 16 and 11 knots in m/s), each sampled every 0.1 s from 0 to its
period, for the thesis ship with a 2.5 m wave at heading 45 deg and zero speed.
The thesis's "yaw" is the synthetic ``heave_m * sin(t_s)`` used as degrees.

:func:`thesis_motion_table` returns the series exactly as
``deckpose/data/thesis_motion_series.csv`` (thesis X-Y-Z angles in degrees);
:func:`thesis_motion_series` returns it as a :class:`MotionSeries` of ZYX angles
on one continuous time axis.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from deckpose.motion.closed_form import KNOTS_PER_M_S, RegularWave, thesis_regular_response
from deckpose.motion.series import MotionSeries
from deckpose.motion.ship import thesis_ship
from deckpose.rotation import zyx_from_thesis

#: Thesis wave: amplitude (m), heading (deg), ship speed (m/s), sample step (s).
THESIS_WAVE_AMPLITUDE_M = 2.5
THESIS_HEADING_DEG = 45.0
THESIS_SPEED_M_S = 0.0
THESIS_STEP_S = 0.1
#: Columns of the thesis table, as in the reference CSV.
THESIS_COLUMNS = ("sample_index", "segment", "t_in_segment_s", "roll_deg", "pitch_deg", "yaw_deg", "heave_m")


def thesis_wave_periods_s() -> tuple[float, float, float, float]:
    """The four wave periods, ``75/v16, 90/v16, 75/v11, 90/v11`` seconds."""
    v16, v11 = 16.0 / KNOTS_PER_M_S, 11.0 / KNOTS_PER_M_S
    return (75.0 / v16, 90.0 / v16, 75.0 / v11, 90.0 / v11)


def thesis_motion_table() -> pd.DataFrame:
    """The thesis motion series, column for column as the reference CSV.

    Returns
    -------
    pandas.DataFrame
        495 rows; columns ``sample_index`` (1-based), ``segment`` (1..4),
        ``t_in_segment_s``, ``roll_deg``, ``pitch_deg``, ``yaw_deg`` (thesis
        X-Y-Z angles, degrees; "yaw" is the synthetic ``heave * sin(t)``) and
        ``heave_m``.
    """
    ship = thesis_ship()
    parts = []
    for segment, period_s in enumerate(thesis_wave_periods_s(), start=1):
        n = math.floor(period_s / THESIS_STEP_S + 1e-9) + 1
        t = np.arange(n) * THESIS_STEP_S
        wave = RegularWave(THESIS_WAVE_AMPLITUDE_M, period_s, math.radians(THESIS_HEADING_DEG),
                           THESIS_SPEED_M_S)
        r = thesis_regular_response(ship, wave, t)
        parts.append(pd.DataFrame({
            "segment": segment,
            "t_in_segment_s": t,
            "roll_deg": np.degrees(r.roll_rad),
            "pitch_deg": np.degrees(r.pitch_rad),
            "yaw_deg": r.heave_m * np.sin(t),
            "heave_m": r.heave_m,
        }))
    df = pd.concat(parts, ignore_index=True)
    df.insert(0, "sample_index", np.arange(1, len(df) + 1))
    return df[list(THESIS_COLUMNS)]


def thesis_motion_series() -> MotionSeries:
    """The thesis series as a :class:`MotionSeries` (ZYX angles, continuous time).

    Samples are 0.1 s apart throughout (segments are joined end to end; the
    motion jumps at the joins, as in the thesis). Angles are converted from the
    thesis X-Y-Z convention with :func:`deckpose.rotation.zyx_from_thesis`;
    surge and sway are zero.
    """
    df = thesis_motion_table()
    roll, pitch, yaw = zyx_from_thesis(
        np.radians(df["roll_deg"].to_numpy()),
        np.radians(df["pitch_deg"].to_numpy()),
        np.radians(df["yaw_deg"].to_numpy()),
    )
    return MotionSeries(
        t_s=np.arange(len(df), dtype=float) * THESIS_STEP_S,
        roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw,
        heave_m=df["heave_m"].to_numpy(),
    )
