"""Rolling shutter: each beacon imaged where it is when its own row is exposed.

Row timing
----------
Row ``v`` (pixel centres at integers, continuous ``v`` for a spot's centre) is exposed
around

    ``t(v) = t_frame + s (v - (H - 1) / 2) * line_delay_s``

with ``s = +1`` for a ``top_down`` readout and ``-1`` for ``bottom_up``: the frame time
``t_frame`` (the plan's ``t_s``, the ship pose of ``frames.parquet``) is the middle of
the readout, the first row is read ``(H - 1) / 2 * line_delay_s`` before it. With an
exposure ``motion.exposure_s > 0`` each row integrates over ``t(v) +- exposure_s / 2``.

Each beacon's row solves the fixed point ``v = v_proj(t(v))``, where ``v_proj(t)`` is the
beacon's projected row with the deck at ``t`` (:class:`ShipTrack`) seen from the camera
at ``t`` (:class:`~deckpose.render.camera_motion.CameraMotion`). Iterating
``v_{k+1} = v_proj(t(v_k))`` from the global-shutter row contracts with ratio
``L = line_delay_s * |dv/dt|`` (rows per row): for an 8 MP sensor read in 21.6 ms
(10 µs a row) and an image speed of 1000 px/s (a UAV at 10 m/s, 30 m up), ``L = 0.01``,
so the 1e-9 px tolerance is met in about five iterations; the error after the last
step is at most ``L / (1 - L)`` times that step. An iteration whose step does not shrink
by half raises a :class:`~deckpose.errors.ConfigError` (``L >= 0.5``: a line delay or a
motion no camera has). Times are kept within one frame height of readout of
``t_frame``; only beacons far outside the image reach that bound.

What is drawn and recorded
--------------------------
The spot is drawn as a whole at its centre row's time (its own rows are read
``line_delay_s`` apart: microseconds across a spot, far below any motion blur); with
an exposure, its blur sub-poses (``motion.blur_steps``) are centred on that time, and
the camera's motion and vibration move it along the path of the sub-exposure poses.
The truth (``u_px, v_px`` and the rest of the projection) is each beacon at its own row
time; the global-shutter projection at ``t_frame`` is kept as ``global_u_px,
global_v_px``. A vibration path is not point-symmetric, so the spot's light centroid
(``light_u_px, light_v_px``: the centroid of the drawn patch, core and halo) can leave
the truth; both are recorded. The deck and sea raster and the non-beacon lights stay
at ``t_frame`` (background).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from deckpose.render.beacons import Splat, splats_under
from deckpose.render.camera_motion import CameraMotion
from deckpose.render.leds_config import LedSpec
from deckpose.render.motion_config import MotionSpec
from deckpose.render.sensor_config import SensorSpec
from deckpose.render.shutter_config import Readout, ShutterSpec
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import BeaconProjection, project_layout
from deckpose.rotation import R_from_zyx

__all__ = ["ROW_TOLERANCE_PX", "ShipTrack", "ShutterFrame", "rolling_shutter_beacons", "row_time_s"]

#: The fixed point's stopping step, pixels.
ROW_TOLERANCE_PX = 1e-9
_MAX_ITERATIONS = 60
_CHANNELS = ("roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m")


@dataclass(frozen=True)
class ShipTrack:
    """The deck's pose over a short span of motion time: linear between knots.

    Attributes
    ----------
    t_s : tuple of float
        Knot times, increasing, seconds (one knot: a deck that does not move).
    poses : tuple of ShipPose
        The deck pose at each knot (angles unwrapped along the track).
    """

    t_s: tuple[float, ...]
    poses: tuple[ShipPose, ...]

    def __post_init__(self) -> None:
        if not self.t_s or len(self.t_s) != len(self.poses):
            raise ValueError(f"ShipTrack: {len(self.t_s)} knot times for {len(self.poses)} poses (need >= 1, equal)")
        if any(b <= a for a, b in zip(self.t_s, self.t_s[1:])):
            raise ValueError("ShipTrack: knot times must increase")

    def pose_at(self, t_s: float) -> ShipPose:
        """The deck pose at ``t_s`` (held at the end knots outside the track)."""
        return ShipPose(*(float(x) for x in self.values_at(np.array([float(t_s)]))[0]))

    def values_at(self, t_s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Roll, pitch, yaw (rad), heave, surge, sway (m) at times ``t_s`` (M,): an (M, 6) array."""
        knots = np.asarray(self.t_s, float)
        return np.stack([np.interp(t_s, knots, [getattr(p, c) for p in self.poses]) for c in _CHANNELS], axis=-1)


@dataclass(frozen=True)
class ShutterFrame:
    """The beacons of one frame under the rolling shutter and the camera's motion.

    Attributes
    ----------
    splats : list of Splat
        Each beacon's spot drawn around its own row time; ``centre_px`` is the light
        centroid of its patch.
    projection : BeaconProjection
        The truth: each beacon projected at its own row time.
    global_points_px : (N, 2) array of float
        Each beacon projected at the frame time (global shutter), pixels.
    row_time_s : (N,) array of float
        Each beacon's row time, motion time base, seconds.
    camera_pose : CameraPose
        The camera at the frame time (with its vibration then): the raster's and the
        recorded camera pose.
    iterations : int
        Fixed-point iterations used.
    """

    splats: list[Splat]
    projection: BeaconProjection
    global_points_px: NDArray[np.float64]
    row_time_s: NDArray[np.float64]
    camera_pose: CameraPose
    iterations: int


def row_time_s(v_px: NDArray[np.float64], height_px: int, t_frame_s: float, spec: ShutterSpec) -> NDArray[np.float64]:
    """The exposure time of image rows ``v_px`` (N,), seconds on the motion time base."""
    sign = 1.0 if spec.readout is Readout.TOP_DOWN else -1.0
    return t_frame_s + sign * (np.asarray(v_px, float) - 0.5 * (height_px - 1)) * spec.line_delay_s


def _cam_from_deck(track: ShipTrack, motion: CameraMotion,
                   t_s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``R_cam_from_deck`` (M, 3, 3) and ``t_cam_from_deck`` (M, 3), metres, at times ``t_s`` (M,)."""
    v = track.values_at(t_s)
    R_deck = R_from_zyx(v[:, 0], v[:, 1], v[:, 2])
    R_cam, C = motion.matrices_at(t_s)
    R_cam_T = np.swapaxes(R_cam, 1, 2)
    return R_cam_T @ R_deck, np.einsum("mij,mj->mi", R_cam_T, v[:, [4, 5, 3]] - C)


def _patch_centroid(sp: Splat) -> NDArray[np.float64]:
    """Light centroid ``(u, v)`` of a splat's patch (core and halo), pixels."""
    p = sp.patch.astype(np.float64)
    total = p.sum()
    u = p.sum(axis=0) @ np.arange(sp.col0, sp.col0 + p.shape[1]) / total
    v = p.sum(axis=1) @ np.arange(sp.row0, sp.row0 + p.shape[0]) / total
    return np.array([u, v])


def _solve_rows(layout: DeckLayout, track: ShipTrack, motion: CameraMotion, camera: CameraModel,
                spec: ShutterSpec, v0_px: NDArray[np.float64]) -> tuple[NDArray[np.float64], list[BeaconProjection], int]:
    """Row times (N,) solving ``v = v_proj(t(v))``, each beacon's projection at its time, iterations."""
    n = layout.n_beacons
    t0 = motion.t_frame_s
    span = camera.height_px * spec.line_delay_s
    v = np.asarray(v0_px, float)
    last_step = math.inf
    P_deck = layout.positions_deck_m()
    for it in range(1, _MAX_ITERATIONS + 1):
        t = np.clip(row_time_s(np.nan_to_num(v, nan=0.5 * (camera.height_px - 1)), camera.height_px, t0, spec),
                    t0 - span, t0 + span)
        R, tr = _cam_from_deck(track, motion, t)
        P_cam = np.einsum("nij,nj->ni", R, P_deck) + tr  # beacon i at its own time
        v_new = np.full(n, np.nan)
        front = P_cam[:, 2] > 1e-9
        if front.any():
            v_new[front] = camera.project(P_cam[front])[:, 1]
        moved = np.abs(v_new - v)[np.isfinite(v_new) & np.isfinite(v)]
        step = float(moved.max()) if moved.size else 0.0
        v = v_new
        if step < ROW_TOLERANCE_PX:
            projs = [project_layout(layout, track.pose_at(float(t[i])), motion.pose_at(float(t[i])), camera)
                     for i in range(n)]
            return t, projs, it
        if it > 2 and step > 0.5 * last_step:
            raise ConfigError(f"shutter.line_delay_s: the rolling-shutter rows do not converge (step {step:.3g} px "
                              f"after {last_step:.3g} px): line delay x image speed is near 1 row per row; "
                              "lower line_delay_s or the motion")
        last_step = step
    raise ConfigError(f"shutter.line_delay_s: the rolling-shutter rows did not converge in {_MAX_ITERATIONS} "
                      "iterations; lower line_delay_s or the motion")


def rolling_shutter_beacons(layout: DeckLayout, track: ShipTrack, ship_frame: ShipPose, motion: CameraMotion,
                            camera: CameraModel, spec: ShutterSpec, motion_spec: MotionSpec, sensor: SensorSpec,
                            leds: LedSpec, unit_factors: NDArray[np.float64]) -> ShutterFrame:
    """The beacons' splats and truth of one frame under the rolling shutter and the camera's motion.

    Parameters
    ----------
    layout : DeckLayout
    track : ShipTrack
        The deck's motion around the frame time.
    ship_frame : ShipPose
        The deck at the frame time (the recorded ship pose).
    motion : CameraMotion
        The camera's trajectory (:func:`deckpose.render.camera_motion.camera_motion`).
    camera : CameraModel
    spec : ShutterSpec
    motion_spec : MotionSpec
        ``exposure_s`` (0: no blur) and ``blur_steps``, the sub-poses of each beacon's exposure.
    sensor, leds : SensorSpec, LedSpec
        As for :func:`deckpose.render.beacons.beacon_splats`.
    unit_factors : (N,) array of float
        Each unit's intensity factor.
    """
    t0 = motion.t_frame_s
    cam0 = motion.pose_at(t0)
    glob = project_layout(layout, ship_frame, cam0, camera)
    t, projs, iterations = _solve_rows(layout, track, motion, camera, spec, glob.points_px[:, 1])
    n = layout.n_beacons
    projection = BeaconProjection(
        np.array([projs[i].points_px[i] for i in range(n)]), np.array([projs[i].depth_m[i] for i in range(n)]),
        np.array([projs[i].in_image[i] for i in range(n)]), np.array([projs[i].facing[i] for i in range(n)]),
        np.array([projs[i].apparent_radius_px[i] for i in range(n)]))
    k = motion_spec.blur_steps if motion_spec.exposure_s > 0 else 1
    offsets = motion_spec.exposure_s * ((np.arange(k) + 0.5) / k - 0.5)
    # beacon i's sub-poses over its own rows' exposure: the deck-to-camera transforms of the moving
    # camera at those times (the splats are drawn in the frame's pixels, whatever cam0 is)
    R, tr = _cam_from_deck(track, motion, (t[:, None] + offsets[None, :]).ravel())
    T = np.zeros((n * k, 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, tr, 1.0
    splats = [dataclasses.replace(sp, centre_px=_patch_centroid(sp))
              for sp in splats_under(layout, T.reshape(n, k, 4, 4), camera, sensor, leds, unit_factors)]
    return ShutterFrame(splats, projection, glob.points_px, t, cam0, iterations)
