"""A UAV approach: the camera descends over time above the moving deck, one frame every 1/rate s.

A render config's ``approach:`` section replaces its ``heights_m`` grid by one time sequence
per camera and lighting::

    approach:
      times_s:   [0, 10, 70, 90]     # waypoints of the camera's height above the nominal deck centre
      heights_m: [80, 80, 20, 20]    # linear between; equal neighbours: a hover
      rate_hz: 10                    # frame rate, 1-60 Hz
      drift_m: 1.0                   # lateral drift of the UAV, amplitude in x and y (0: none)
      drift_period_s: 30
      wobble_deg: 2.0                # attitude wobble about nadir, amplitude in roll and pitch (0: none)
      wobble_period_s: 4
      follow_deck: false             # true: heights over the moving deck centre (see below)

With ``follow_deck: false`` (the default) the heights are over the deck at rest (world z):
the heave of a rough sea then comes and goes under the camera, and sea-state-6 heave brings
the deck centre to within about 1.2 m of a camera flown at 2 m. With ``follow_deck: true``
the UAV holds its place over the moving deck centre, as a landing UAV does: the deck
centre's surge, sway and heave at the frame time are added to the camera's position, so
``heights_m`` is the camera's height over the deck centre (what the estimators report as
``height_m``) and the drift is relative to the deck centre. The camera holds that position
through the frame's exposure (the deck moves under it, as it does for the motion blur).

Drift and wobble are deterministic sinusoids (x and y, roll and pitch at incommensurate
periods), so the config alone fixes every camera pose. Frame ``k`` is at motion time
``t0 + k / rate_hz`` (``t0`` the series' sample ``motion.start``); the deck pose there is the
motion series interpolated (:func:`deckpose.render.plan.plan_frames`), so the ship and the
UAV move continuously across frames on one time base and the frames table's truth is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError
from deckpose.pose import CameraPose
from deckpose.rotation import R_from_zyx
from deckpose.typed_config import check_range, from_mapping

__all__ = ["ApproachSpec", "approach_camera_pose", "approach_spec", "approach_times_s"]

#: Periods of y drift and pitch wobble relative to x drift and roll wobble (incommensurate).
_Y_PERIOD_RATIO, _PITCH_PERIOD_RATIO = 1.37, 1.29


@dataclass(frozen=True)
class ApproachSpec:
    """A descent (see the module docstring for the keys and their units)."""

    times_s: tuple[float, ...]
    heights_m: tuple[float, ...]
    rate_hz: float = 10.0
    drift_m: float = 0.0
    drift_period_s: float = 30.0
    wobble_deg: float = 0.0
    wobble_period_s: float = 4.0
    follow_deck: bool = False

    @property
    def duration_s(self) -> float:
        return self.times_s[-1] - self.times_s[0]


def approach_spec(doc: object, where: str = "approach") -> ApproachSpec:
    """Validate a config's ``approach:`` mapping."""
    spec = from_mapping(ApproachSpec, doc, where)
    if len(spec.times_s) < 2 or len(spec.times_s) != len(spec.heights_m):
        raise ConfigError(f"{where}: times_s and heights_m must be lists of the same length, at least 2 "
                          f"(waypoints), got {len(spec.times_s)} and {len(spec.heights_m)}")
    if spec.times_s[0] != 0 or any(b <= a for a, b in zip(spec.times_s, spec.times_s[1:])):
        raise ConfigError(f"{where}.times_s: must start at 0 and increase, got {list(spec.times_s)}")
    for i, h in enumerate(spec.heights_m):
        check_range(h, f"{where}.heights_m[{i}]", low=0.5)
    check_range(spec.rate_hz, f"{where}.rate_hz", low=1, high=60)
    check_range(spec.drift_m, f"{where}.drift_m", low=0, high=50)
    check_range(spec.wobble_deg, f"{where}.wobble_deg", low=0, high=30)
    check_range(spec.drift_period_s, f"{where}.drift_period_s", low=0, low_open=True)
    check_range(spec.wobble_period_s, f"{where}.wobble_period_s", low=0, low_open=True)
    return spec


def approach_times_s(spec: ApproachSpec) -> NDArray[np.float64]:
    """Frame times from the approach's start, seconds: ``k / rate_hz`` up to its duration."""
    n = math.floor(spec.duration_s * spec.rate_hz + 1e-9) + 1
    return np.arange(n) / spec.rate_hz


def approach_camera_pose(
    spec: ApproachSpec, t_s: float, deck_centre_world_m: NDArray[np.float64] | None = None
) -> CameraPose:
    """The camera's pose ``t_s`` seconds into the approach (world frame).

    Height from the waypoints (linear), position ``drift_m`` sinusoids in x and y, attitude
    nadir tilted by ``wobble_deg`` sinusoids in roll and pitch (about the world's x and y).
    With ``spec.follow_deck`` the position is relative to the deck centre.

    Parameters
    ----------
    spec : ApproachSpec
    t_s : float
        Seconds from the approach's start.
    deck_centre_world_m : (3,) array of float, optional
        The deck centre's displacement (surge, sway, heave) at that time, metres; needed
        with ``spec.follow_deck``, ignored without.

    Raises
    ------
    ConfigError
        ``spec.follow_deck`` without ``deck_centre_world_m``.
    """
    h = float(np.interp(t_s, spec.times_s, spec.heights_m))
    w = 2 * math.pi / spec.drift_period_s
    x = spec.drift_m * math.sin(w * t_s)
    y = spec.drift_m * math.sin(w / _Y_PERIOD_RATIO * t_s + 1.0)
    a = math.radians(spec.wobble_deg)
    ww = 2 * math.pi / spec.wobble_period_s
    roll, pitch = a * math.sin(ww * t_s), a * math.sin(ww / _PITCH_PERIOD_RATIO * t_s + 0.5)
    nadir = CameraPose.nadir(h, x_m=x, y_m=y)
    R = R_from_zyx(roll, pitch, 0.0) @ nadir.R_world_from_cam
    position = nadir.position_world_m
    if spec.follow_deck:
        if deck_centre_world_m is None:
            raise ConfigError("approach.follow_deck: the camera's pose needs the deck centre's displacement")
        position = position + np.asarray(deck_centre_world_m, float).reshape(3)
    return CameraPose(R, position)
