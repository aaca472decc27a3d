"""Approach scenarios: a descending, drifting, wobbling camera over the moving deck, one time sequence."""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.render.approach import approach_camera_pose
from deckpose.render.config import config_from_dict, config_to_dict, default_config
from deckpose.render.plan import load_motion, plan_frames

from deckpose.errors import ConfigError
from deckpose.pose import ShipPose
from deckpose.projection import project_layout
from deckpose.run_folder import frame_poses, read_beacons, read_frames, run_paths
from deckpose.tracking.run import sequence_ids

#: The beacons table's centres against project_layout at the poses the frames table records: the
#: same projection, apart from the camera rotation's round trip through the r00..r22 columns
#: (float64, exact to ~1e-16) and the wobble's trigonometry: far below 1e-6 px.
TRUTH_PX = 1e-6


def _doc(**approach: object) -> dict:
    return {
        "cameras": [{"preset": "8mp-square", "size": [640, 480], "name": "small"}],
        "lighting": ["night"],
        "motion": {"source": "sea_state", "params": {"duration_s": 12, "dt_s": 0.1, "seed": 3}},
        "sensor": {"bit_depth": 8, "read_noise_e": 5},
        "scene": {"shading": "flat", "texture_px": 256},
        "approach": {"times_s": [0, 1, 3, 4], "heights_m": [40, 40, 30, 30], "rate_hz": 10, "drift_m": 1.0,
                     "wobble_deg": 2.0, **approach},
    }


def test_an_approach_plans_one_sequence_on_one_time_base():
    cfg = config_from_dict(_doc(), "t")
    assert cfg.heights_m == (40.0,)
    plan = plan_frames(cfg)
    assert len(plan) == 41
    stamps = np.array([f.stamp_ns for f in plan])
    assert np.all(np.diff(stamps) == 100_000_000)          # 10 Hz exactly
    series = load_motion(cfg.motion)
    for f in plan[::7]:
        # the deck: the motion series interpolated at the frame time (here on its samples: exact)
        i = round(f.t_s / 0.1)
        np.testing.assert_allclose([f.ship.roll_rad, f.ship.heave_m], [series.roll_rad[i], series.heave_m[i]],
                                   atol=1e-12)
        # the camera: waypoints linear in time, drift and wobble
        tau = f.t_s - plan[0].t_s
        want_h = np.interp(tau, [0, 1, 3, 4], [40, 40, 30, 30])
        assert f.camera_pose.position_world_m[2] == pytest.approx(want_h, abs=1e-9)
        R = f.camera_pose.R_world_from_cam
        tilt = math.degrees(math.acos(-R[2, 2]))           # optical axis away from straight down
        assert tilt <= 2.0 * math.sqrt(2) + 1e-9
    xy = np.array([f.camera_pose.position_world_m[:2] for f in plan])
    assert np.abs(xy).max() <= 1.0 + 1e-12 and np.abs(np.diff(xy, axis=0)).max() < 0.05   # continuous drift


def test_the_first_frame_blurs_symmetrically_about_its_truth():
    # A frame at the series' first sample blurs over half an exposure before it. The sub-poses
    # there follow the series' first step (not the first sample, clamped: the ship stood still
    # for half the exposure, and the first rendered approach frame's outer beacons sat 2-4
    # sigmas off their truth). Along the first step's line the sub-poses are symmetric about the
    # frame's time, so their mean is the frame's own pose (the truth, at the exposure's middle)
    # to rounding; and the sub-poses themselves against that line, written out.
    doc = _doc()
    doc["motion"] = {**doc["motion"], "exposure_s": 0.02}
    plan = plan_frames(config_from_dict(doc, "t"))
    series = load_motion(config_from_dict(doc, "t").motion)
    rate = (series.roll_rad[1] - series.roll_rad[0]) / (series.t_s[1] - series.t_s[0])
    first = plan[0]
    assert first.t_s == series.t_s[0] and len(first.blur_poses) > 1
    assert np.mean([p.roll_rad for p in first.blur_poses]) == pytest.approx(first.ship.roll_rad, abs=1e-12)
    assert np.mean([p.heave_m for p in first.blur_poses]) == pytest.approx(first.ship.heave_m, abs=1e-12)
    k = len(first.blur_poses)
    ts = first.t_s + 0.02 * ((np.arange(k) + 0.5) / k - 0.5)
    np.testing.assert_allclose([p.roll_rad for p in first.blur_poses],
                               series.roll_rad[0] + rate * (ts - series.t_s[0]), atol=1e-12)


def test_the_resolved_config_reads_back_and_the_grid_configs_are_unchanged():
    cfg = config_from_dict(_doc(), "t")
    again = config_from_dict(config_to_dict(cfg), "again")
    assert again == cfg
    assert "approach" not in config_to_dict(default_config())   # grid manifests as before


@pytest.mark.parametrize("change,match", [
    ({"heights_m": [30]}, "heights_m or approach, not both"),
    ({"motion": {"source": "fixed"}}, "needs a motion series"),
    ({"motion": {"source": "sea_state", "every": 2}}, "do not apply to an approach"),
    ({"approach": {"times_s": [1, 2], "heights_m": [30, 20]}}, "must start at 0"),
    ({"approach": {"times_s": [0, 2], "heights_m": [30, 20], "rate_hz": 100}}, "rate_hz"),
    ({"approach": {"times_s": [0, 2, 3], "heights_m": [30, 20]}}, "same length"),
])
def test_bad_approaches_are_one_line_errors(change, match):
    doc = {**_doc(), **change}
    with pytest.raises(ConfigError, match=match):
        config_from_dict(doc, "t")


def test_an_approach_past_the_series_end_is_refused():
    cfg = config_from_dict(_doc(times_s=[0, 20], heights_m=[40, 30]), "t")
    with pytest.raises(ConfigError, match="runs past the motion series"):
        plan_frames(cfg)


def test_camera_pose_is_continuous_and_exact_at_the_waypoints():
    cfg = config_from_dict(_doc(drift_m=0.0, wobble_deg=0.0), "t")
    assert cfg.approach is not None
    for tau, h in ((0.0, 40.0), (1.0, 40.0), (2.0, 35.0), (4.0, 30.0)):
        p = approach_camera_pose(cfg.approach, tau)
        np.testing.assert_allclose(p.position_world_m, [0, 0, h], atol=1e-12)


def test_a_rendered_approach_has_exact_truth_and_tracks_as_one_sequence(tmp_path):
    from deckpose.render.dataset import render_dataset

    doc = _doc(times_s=[0, 0.5], heights_m=[40, 38], rate_hz=4)
    out = render_dataset(config_from_dict(doc, "t"), tmp_path / "run", progress=False)
    run = run_paths(out)
    frames, beacons = read_frames(run), read_beacons(run)
    assert len(frames) == 3 and frames["camera_height_m"].eq(40.0).all()
    assert np.allclose(np.diff(frames["stamp_ns"]), 250_000_000)
    assert frames["cam_z_m"].tolist() == pytest.approx([40.0, 39.0, 38.0])
    cfg = config_from_dict(doc, "t")
    cam = cfg.cameras_by_name()["small"]
    for _, row in frames.iterrows():
        ship, camera = frame_poses(row)
        assert isinstance(ship, ShipPose)
        proj = project_layout(cfg.layout, ship, camera, cam)
        b = beacons[beacons["frame_id"] == row["frame_id"]].sort_values("beacon_id")
        np.testing.assert_allclose(b[["u_px", "v_px"]].to_numpy(), proj.points_px, atol=TRUTH_PX)
    # one time sequence for the tracker (one camera x nominal height x lighting)
    assert len(set(sequence_ids(frames, frames["stamp_ns"].to_numpy()))) == 1
