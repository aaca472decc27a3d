"""Motion of a point away from the centre of gravity (the deck centre is often aft)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from deckpose.errors import ConfigError
from deckpose.motion.series import MotionSeries
from deckpose.rotation import R_from_zyx


def motion_at_offset(series: MotionSeries, offset_deck_m: ArrayLike) -> MotionSeries:
    """The series of a point rigidly attached to the ship, from that of the reference point.

    The attitude is unchanged; the displacement becomes
    ``t_point = t_ref + (R_world_from_deck - I) @ offset_deck_m``. For small
    angles the vertical part is ``heave - x*pitch + y*roll``: a deck centre aft
    of the centre of gravity (x < 0) heaves more in head seas.

    Parameters
    ----------
    series : MotionSeries
        Motion of the reference point (e.g. the centre of gravity).
    offset_deck_m : (3,) array_like of float
        The point relative to the reference point, deck frame (x bow, y port, z up), metres.

    Returns
    -------
    MotionSeries
    """
    p = np.asarray(offset_deck_m, dtype=float).ravel()
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"offset must be 3 finite numbers (x, y, z) in metres, got {offset_deck_m!r}")
    R = R_from_zyx(series.roll_rad, series.pitch_rad, series.yaw_rad)  # (T, 3, 3)
    d = R @ p - p  # (T, 3)
    return MotionSeries(
        t_s=series.t_s,
        roll_rad=series.roll_rad,
        pitch_rad=series.pitch_rad,
        yaw_rad=series.yaw_rad,
        heave_m=series.heave_m + d[:, 2],
        surge_m=series.surge_m + d[:, 0],
        sway_m=series.sway_m + d[:, 1],
    )
