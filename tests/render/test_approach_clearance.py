"""``approach.follow_deck``: heights over the moving deck centre, so heave cannot bring the deck to the camera.

A sea-state-6 series (Hs 5 m, as ``configs/approach_tworing.yaml``) under a descent to 2 m.
The deck centre's displacement is interpolated here from the series' own samples
(``np.interp``), the deck normal written out from the ZYX angles, and the heights from the
waypoints: none of the plan's code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.render.config import config_from_dict, config_to_dict
from deckpose.render.plan import load_motion, plan_frames

TIMES_S, HEIGHTS_M = [0, 4, 6], [8, 2, 2]


def _doc(**approach: object) -> dict:
    return {
        "cameras": [{"preset": "8mp-square", "size": [640, 480], "name": "small"}],
        "lighting": ["night"],
        "motion": {"source": "sea_state", "params": {
            "sea": {"sea_state": 6, "hs_m": 5.0, "tp_s": 12.4, "heading_deg": 135, "speed_kn": 15},
            "duration_s": 40, "dt_s": 0.1, "seed": 1}, "start": 150},
        "sensor": {"bit_depth": 8, "read_noise_e": 5},
        "scene": {"shading": "flat", "texture_px": 256},
        "approach": {"times_s": TIMES_S, "heights_m": HEIGHTS_M, "rate_hz": 5, "drift_m": 0.3,
                     "wobble_deg": 2.0, **approach},
    }


def _deck_normal(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Third column of Rz(yaw) Ry(pitch) Rx(roll): the deck's up axis in the world."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    return np.array([cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr])


def _clearances(plan, series) -> tuple[np.ndarray, np.ndarray]:
    """Camera height over the deck centre (world z) and distance to the deck plane, per frame, metres."""
    t = np.asarray(series.t_s, float)
    over, plane = [], []
    for f in plan:
        centre = np.array([np.interp(f.t_s, t, series.surge_m), np.interp(f.t_s, t, series.sway_m),
                           np.interp(f.t_s, t, series.heave_m)])
        n = _deck_normal(f.ship.roll_rad, f.ship.pitch_rad, f.ship.yaw_rad)
        cam = f.camera_pose.position_world_m
        over.append(cam[2] - centre[2])
        plane.append(float((cam - centre) @ n))
    return np.array(over), np.array(plane)


def test_follow_deck_flies_the_heights_over_the_moving_deck_centre():
    cfg = config_from_dict(_doc(follow_deck=True), "t")
    series = load_motion(cfg.motion)
    plan = plan_frames(cfg, series)
    over, plane = _clearances(plan, series)
    want = np.interp([f.t_s - plan[0].t_s for f in plan], TIMES_S, HEIGHTS_M)
    # the plan interpolates the same samples linearly: equal to rounding (metres, 1e-9 of 10 m)
    np.testing.assert_allclose(over, want, atol=1e-9)
    # the deck's tilt (a few degrees) and 0.3 m of drift cost at most a few cm of the 2 m
    assert plane.min() > 1.9


def test_without_it_the_heave_brings_the_deck_close_and_the_config_round_trips():
    cfg = config_from_dict(_doc(), "t")
    series = load_motion(cfg.motion)
    plan = plan_frames(cfg, series)
    over, _plane = _clearances(plan, series)
    want = np.interp([f.t_s - plan[0].t_s for f in plan], TIMES_S, HEIGHTS_M)
    heave = np.array([np.interp(f.t_s, series.t_s, series.heave_m) for f in plan])
    np.testing.assert_allclose(over, want - heave, atol=1e-9)  # heights over the deck at rest
    assert np.abs(heave).max() > 0.3  # a rough sea: the heave matters at 2 m
    follow = config_from_dict(_doc(follow_deck=True), "t")
    assert config_to_dict(follow)["approach"]["follow_deck"] is True
    assert config_from_dict(config_to_dict(follow), "t").approach == follow.approach


def test_follow_deck_takes_a_boolean_only():
    from deckpose.errors import ConfigError

    with pytest.raises(ConfigError, match="follow_deck"):
        config_from_dict(_doc(follow_deck="yes"), "t")
