"""Rolling shutter, UAV motion and vibration against computations written out here.

The deck's and the camera's motion are written out again in the test (ZYX angles by
scipy's Euler convention, the turn and the vibration by a matrix exponential of the
skew matrix, a pinhole projection by hand), and each beacon's row time is found by
bisection on ``t - t(v(t)) = 0``, not by the renderer's fixed point. Spots are exposed
noise-free, one at a time, onto a black 16-bit raster, so a window's light is the spot's.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.render.camera_motion import CameraMotion
from deckpose.render.config import (
    LedSpec,
    MotionSpec,
    OcclusionSpec,
    Readout,
    SensorSpec,
    ShutterSpec,
    config_from_dict,
)
from deckpose.render.dataset import render_dataset
from deckpose.render.occlusion import occlude
from deckpose.render.plan import load_motion, plan_frames
from deckpose.render.rolling_shutter import ShipTrack, rolling_shutter_beacons
from deckpose.render.sensor import expose
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

from .conftest import tiny_doc

FX, FY, CX, CY = 600.0, 600.0, 319.5, 239.5
CAMERA = CameraModel(640, 480, [[FX, 0, CX], [0, FY, CY], [0, 0, 1]])
LAYOUT = DeckLayout()
SENSOR = SensorSpec(bit_depth=16, noise=False, beacon_peak=0.5, full_well_e=60000.0)
T0 = 12.3  # frame time, s
BASE = CameraPose.nadir(40.0)
# the deck: a pose at T0 and constant rates (rad/s, m/s) of roll, pitch, yaw, heave, surge, sway
SHIP0 = np.array([math.radians(3.0), math.radians(-2.0), math.radians(25.0), 0.4, 0.3, -0.2])
SHIP_RATE = np.array([math.radians(6.0), math.radians(-4.0), math.radians(3.0), 1.2, 2.5, -1.5])
VELOCITY = np.array([6.0, -4.0, 1.0])  # UAV, world m/s
RATE = np.radians([4.0, -6.0, 8.0])  # UAV turn, camera axes, rad/s
PHASE = np.array([0.3, 2.1, 4.4])


def _ship_at(t: float) -> np.ndarray:
    return SHIP0 + SHIP_RATE * (t - T0)


def _track() -> ShipTrack:
    """The linear deck motion as knots a second either side (linear interpolation is then exact)."""
    knots = (T0 - 1.0, T0, T0 + 1.0)
    return ShipTrack(knots, tuple(ShipPose(*_ship_at(t)) for t in knots))


def _motion(vibration_rms_deg: float = 0.0, hz: float = 80.0) -> CameraMotion:
    return CameraMotion(BASE, T0, VELOCITY, RATE, math.sqrt(2) * math.radians(vibration_rms_deg), hz, PHASE)


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _project(t: float, vibration_rms_deg: float, hz: float = 80.0) -> np.ndarray:
    """Every beacon's pixel (N, 2) at time ``t``, written out from the motion laws."""
    roll, pitch, yaw, heave, surge, sway = _ship_at(t)
    R_deck = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    P_world = LAYOUT.positions_deck_m() @ R_deck.T + np.array([surge, sway, heave])
    dt = t - T0
    jitter = math.sqrt(2) * math.radians(vibration_rms_deg) * np.sin(2 * math.pi * hz * dt + PHASE)
    R_cam = BASE.R_world_from_cam @ expm(_skew(RATE * dt)) @ expm(_skew(jitter))
    C = BASE.position_world_m + VELOCITY * dt
    P_cam = (P_world - C) @ R_cam  # = R_cam^T (P - C), row-wise
    return np.stack([FX * P_cam[:, 0] / P_cam[:, 2] + CX, FY * P_cam[:, 1] / P_cam[:, 2] + CY], axis=1)


def _row_time_by_bisection(i: int, line_delay_s: float, sign: float, vibration_rms_deg: float) -> float:
    """The time at which beacon ``i`` sits on the row being read, by bisection."""
    def g(t: float) -> float:
        return t - (T0 + sign * (_project(t, vibration_rms_deg)[i, 1] - (CAMERA.height_px - 1) / 2) * line_delay_s)

    lo, hi = T0 - CAMERA.height_px * line_delay_s, T0 + CAMERA.height_px * line_delay_s
    assert g(lo) < 0 < g(hi)  # the row lies in the image, so the bracket holds the root
    for _ in range(80):  # 2 x 14 ms / 2**80: far below a float's resolution of T0
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("readout", [Readout.TOP_DOWN, Readout.BOTTOM_UP])
def test_rolling_shutter_truth_is_each_beacon_at_its_own_rows_time(readout: Readout) -> None:
    delay = 3e-5  # 14 ms over 480 rows
    spec = ShutterSpec(line_delay_s=delay, readout=readout)
    rms = 0.05
    out = rolling_shutter_beacons(LAYOUT, _track(), ShipPose(*SHIP0), _motion(rms), CAMERA, spec, MotionSpec(),
                                  SENSOR, LedSpec(), np.ones(LAYOUT.n_beacons))
    sign = 1.0 if readout is Readout.TOP_DOWN else -1.0
    assert out.projection.in_image.all()
    for i in range(LAYOUT.n_beacons):
        t = _row_time_by_bisection(i, delay, sign, rms)
        want = _project(t, rms)[i]
        # both solve the same equation to ~1e-12 px; 1e-6 px leaves room for the ZYX round trip
        np.testing.assert_allclose(out.projection.points_px[i], want, atol=1e-6, rtol=0)
        assert out.row_time_s[i] == pytest.approx(t, abs=1e-9)
    # the frame-time projection is kept apart, and the shutter moved the truth well beyond that tolerance
    np.testing.assert_allclose(out.global_points_px, _project(T0, rms), atol=1e-6, rtol=0)
    assert np.abs(out.projection.points_px - out.global_points_px).max() > 0.5
    assert out.iterations <= 8  # L = line delay x image speed ~ 3e-5 x 1e3 = 0.03: a few steps


def _window_centroid(image: np.ndarray, row0: int, col0: int, n: int) -> tuple[np.ndarray, float]:
    """Centroid (u, v) of an image window and the quantisation bound on it, pixels."""
    w = image[row0:row0 + n, col0:col0 + n].astype(float).sum(axis=2)
    rows, cols = np.arange(row0, row0 + n), np.arange(col0, col0 + n)
    total = w.sum()
    c = np.array([w.sum(axis=0) @ cols / total, w.sum(axis=1) @ rows / total])
    # rounding moves each of the 3 channels' values by <= 0.5 DN: the centroid by at most
    # 0.5 x 3 x sum over the window of |x - c| / total, per axis (the larger axis is used)
    du = np.abs(cols - c[0]).sum() * n
    dv = np.abs(rows - c[1]).sum() * n
    return c, 1.5 * max(du, dv) / total


def _expose_alone(sp) -> np.ndarray:
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    return expose(raster, np.ones(3, np.float32), [sp], SENSOR, np.random.default_rng(0))


def test_spot_light_centroid_sits_on_the_rolling_shutter_truth() -> None:
    spec = ShutterSpec(line_delay_s=3e-5)
    out = rolling_shutter_beacons(LAYOUT, _track(), ShipPose(*SHIP0), _motion(), CAMERA, spec, MotionSpec(),
                                  SENSOR, LedSpec(), np.ones(LAYOUT.n_beacons))
    assert len(out.splats) == LAYOUT.n_beacons
    for sp in out.splats:
        n = sp.patch.shape[0]
        assert 0 <= sp.row0 and sp.row0 + n <= CAMERA.height_px and 0 <= sp.col0 and sp.col0 + n <= CAMERA.width_px
        c, quant = _window_centroid(_expose_alone(sp), sp.row0, sp.col0, n)
        # quantisation bound, plus 1e-3 px for the Gaussians' point sampling (< 1e-4 px at
        # sigma >= 0.5 px) and the halo's tail beyond the window (4 halo sigmas: < 1e-4 px)
        assert np.abs(c - out.projection.points_px[sp.beacon_id]).max() < quant + 1e-3


def test_vibration_light_centroid_is_the_exposed_spots_and_leaves_the_truth() -> None:
    rms, steps = 0.1, 24
    spec = ShutterSpec(line_delay_s=2e-5, vibration_deg_rms=rms, vibration_hz=80.0)
    motion_spec = MotionSpec(exposure_s=0.01, blur_steps=steps)
    out = rolling_shutter_beacons(LAYOUT, _track(), ShipPose(*SHIP0), _motion(rms), CAMERA, spec, motion_spec,
                                  SENSOR, LedSpec(), np.ones(LAYOUT.n_beacons))
    _, rec = occlude(out.splats, OcclusionSpec(), LAYOUT.n_beacons, np.random.default_rng(0))
    light = np.stack([rec.light_u_px, rec.light_v_px], axis=1)  # the beacons.parquet columns
    offsets = 0.01 * ((np.arange(steps) + 0.5) / steps - 0.5)
    bias = []
    for sp in out.splats:
        i = sp.beacon_id
        n = sp.patch.shape[0]
        c, quant = _window_centroid(_expose_alone(sp), sp.row0, sp.col0, n)
        # the recorded light centroid is that of the exposed spot, to quantisation and the
        # halo tail beyond the window (< 1e-4 px)
        assert np.abs(c - light[i]).max() < quant + 1e-3
        # and the mean of the sub-exposure projections written out here: the spot weights
        # each sub-pose by its flux (the disc's projected area), which the 10 ms of motion
        # (< 0.2 deg of view angle, < 0.2 m of range at 40 m) changes by < 0.2 %, over a
        # path < 5 px long: < 0.01 px
        t_i = out.row_time_s[i]
        path = np.array([_project(t_i + o, rms)[i] for o in offsets])
        assert np.ptp(path, axis=0).max() < 5.0
        np.testing.assert_allclose(light[i], path.mean(axis=0), atol=0.01, rtol=0)
        bias.append(np.abs(light[i] - out.projection.points_px[i]).max())
    # the vibration path is not point-symmetric: the light leaves the truth by far more than the tolerances
    assert max(bias) > 0.1


def test_ship_track_interpolates_the_motion_series() -> None:
    doc = tiny_doc(motion={"source": "thesis", "start": 40, "every": 100, "max_samples": 3, "exposure_s": 0.01},
                   heights_m=[30.0], lighting=["night"], shutter={"line_delay_s": 4e-4})
    cfg = config_from_dict(doc)
    series = load_motion(cfg.motion)
    ts = np.asarray(series.t_s)
    for spec in plan_frames(cfg, series):
        assert spec.track is not None
        # readout one frame height either side (240 rows x 0.4 ms) plus half the exposure
        span = 240 * 4e-4 + 0.005
        for t in np.linspace(spec.t_s - span, spec.t_s + span, 9):
            got = spec.track.pose_at(float(t))
            for name in ("roll_rad", "pitch_rad", "yaw_rad", "heave_m"):
                want = np.interp(t, ts, np.unwrap(getattr(series, name)) if name.endswith("_rad")
                                 else getattr(series, name))
                assert getattr(got, name) == pytest.approx(want, abs=1e-12)


def test_fixed_point_refuses_a_line_delay_no_camera_has() -> None:
    # 1 ms a row while the camera turns 700 deg/s: line delay x image speed >> 1 row per row
    spec = ShutterSpec(line_delay_s=1e-3)
    motion = dataclasses.replace(_motion(), rate_rad_per_s=np.radians([700.0, 0.0, 0.0]))
    with pytest.raises(ConfigError, match="do not converge|did not converge"):
        rolling_shutter_beacons(LAYOUT, _track(), ShipPose(*SHIP0), motion, CAMERA, spec, MotionSpec(),
                                SENSOR, LedSpec(), np.ones(LAYOUT.n_beacons))


@pytest.mark.parametrize("workers", [0, 1])
def test_a_shutter_that_cannot_converge_leaves_no_dataset_behind(tmp_path: Path, workers: int) -> None:
    # 1 ms a row while the UAV turns 700 deg/s: the fault shows only when a frame is drawn.
    # A new dataset with no finished frame is removed, so the same folder takes the fixed config.
    doc = tiny_doc(heights_m=[30.0], lighting=["night"], shutter={"line_delay_s": 1e-3,
                   "uav_rate_deg_per_s": [700.0, 0.0, 0.0]})
    out = tmp_path / "ds"
    with pytest.raises(ConfigError, match=r"converge.*\(nothing was kept in .*ds\)"):
        render_dataset(config_from_dict(doc), out, workers=workers, progress=False)
    assert not out.exists() or not any(out.iterdir())
    doc["shutter"] = {"line_delay_s": 1e-5}
    doc["motion"] = {"source": "fixed", "attitudes_deg": [[0, 0, 0]]}
    render_dataset(config_from_dict(doc), out, workers=0, progress=False)
    assert (out / "manifest.json").exists()


@pytest.mark.parametrize(("shutter", "key"), [
    ({"line_delay_s": -1e-5}, "shutter.line_delay_s"),
    ({"line_delay_s": 0.01}, "shutter.line_delay_s"),
    ({"readout": "sideways"}, "shutter.readout"),
    ({"vibration_deg_rms": 10}, "shutter.vibration_deg_rms"),
    ({"vibration_hz": 0}, "shutter.vibration_hz"),
    ({"uav_velocity_m_per_s": [1, 2]}, "shutter.uav_velocity_m_per_s"),
    ({"uav_rate_deg_per_s": [0, 0, 1000]}, "shutter.uav_rate_deg_per_s[2]"),
    ({"line_dealy_s": 1e-5}, "shutter: unknown key"),
])
def test_config_errors_are_one_line(shutter: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        config_from_dict(tiny_doc(shutter=shutter))
    msg = str(err.value)
    assert key in msg and "\n" not in msg


def test_shutter_off_keeps_the_dataset_tables_and_images(tmp_path: Path, egl_renderer_factory) -> None:
    doc = tiny_doc(heights_m=[25.0], lighting=["night", "day"])
    egl_renderer_factory(config_from_dict(doc))  # select EGL in this process
    plain = render_dataset(config_from_dict(doc), tmp_path / "plain", workers=0, progress=False)
    zero = tiny_doc(heights_m=[25.0], lighting=["night", "day"],
                    shutter={"line_delay_s": 0.0, "vibration_deg_rms": 0.0, "readout": "bottom_up"})
    off = render_dataset(config_from_dict(zero), tmp_path / "off", workers=0, progress=False)
    for name in ("frames.parquet", "beacons.parquet"):
        pd.testing.assert_frame_equal(pd.read_parquet(plain / name), pd.read_parquet(off / name))
    for p in sorted((plain / "images").glob("*.png")):
        assert p.read_bytes() == (off / "images" / p.name).read_bytes()
    b = pd.read_parquet(plain / "beacons.parquet")
    # without a rolling shutter the truth is the frame-time projection itself
    np.testing.assert_array_equal(b.global_u_px.to_numpy(), b.u_px.to_numpy())
    np.testing.assert_array_equal(b.global_v_px.to_numpy(), b.v_px.to_numpy())
