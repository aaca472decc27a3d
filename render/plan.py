"""The frame plan: every frame of a dataset as a small frozen record, fixed before rendering.

The plan is a pure function of the config: frame ids enumerate cameras x heights x
lighting x motion samples in that nesting order, and each frame's noise seed is
derived from ``(config seed, frame_id)`` with :class:`numpy.random.SeedSequence`,
so the images do not depend on how frames are spread over workers.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.render.approach import ApproachSpec, approach_camera_pose, approach_times_s
from deckpose.render.config import RenderConfig
from deckpose.render.motion_config import MotionSource, MotionSpec
from deckpose.render.rolling_shutter import ShipTrack
from deckpose.render.scene_config import Lighting

from deckpose.capture_time import epoch_ns, replay_starts_ns
from deckpose.errors import ConfigError, DeckposeError
from deckpose.motion import MotionSeries, read_series
from deckpose.motion.thesis_series import thesis_motion_table
from deckpose.pose import CameraPose, ShipPose
from deckpose.rotation import zyx_from_thesis


@dataclass(frozen=True)
class FrameSpec:
    """What to render for one frame.

    Attributes
    ----------
    frame_id : int
    camera_name : str
    height_m : float
        Camera height above the world origin (the nominal deck centre), metres.
    ship : ShipPose
        Deck pose at mid-exposure (the ground truth).
    blur_poses : tuple of ShipPose
        Deck poses spread over the exposure (empty: no motion blur).
    t_s : float
        Time on the motion time base, seconds.
    lighting : Lighting
    seed : int
        Seed of this frame's noise (from the config seed and the frame id).
    capture_offset_ns : int
        Capture time of motion time 0 for this frame's replay of the motion series,
        nanoseconds since the Unix epoch (:mod:`deckpose.capture_time`); 0 = stamps
        are motion time.
    track : ShipTrack or None
        The deck's motion around ``t_s`` for the rolling shutter and the UAV's motion
        (``shutter`` section; None when it is off).
    camera : CameraPose or None
        The camera's pose where an approach moves it (:mod:`deckpose.render.approach`);
        None: straight down from ``height_m`` above the world origin.
    exposure : float or None
        The exposure the auto-exposure controller chose from the frames before
        (:mod:`deckpose.render.exposure_control`); None: the frame meters itself, or
        ``sensor.exposure`` without auto-exposure.
    metered_exposure : float or None
        The exposure this frame's own metering asks for (with the controller; else None).
    """

    frame_id: int
    camera_name: str
    height_m: float
    ship: ShipPose
    blur_poses: tuple[ShipPose, ...]
    t_s: float
    lighting: Lighting
    seed: int
    capture_offset_ns: int = 0
    track: ShipTrack | None = None
    camera: CameraPose | None = None
    exposure: float | None = None
    metered_exposure: float | None = None

    @property
    def camera_pose(self) -> CameraPose:
        return CameraPose.nadir(self.height_m) if self.camera is None else self.camera

    @property
    def stamp_ns(self) -> int:
        """Capture time, integer nanoseconds since the Unix epoch (motion time when no offset is set)."""
        return self.capture_offset_ns + round(self.t_s * 1e9)


def thesis_series(path: str | Path | None = None) -> MotionSeries:
    """The thesis motion series as a :class:`MotionSeries` (ZYX angles, thesis geometry).

    By default the series is regenerated exactly by
    :func:`deckpose.motion.thesis_series.thesis_motion_table` (no file needed);
    ``path`` reads a file with the same columns instead. The table holds
    THESIS-convention degrees and a heave that the thesis *adds* to the camera
    distance ("camera height = table height + heave"). To render the thesis's
    geometry, our heave (the deck's upward displacement, which brings it closer)
    is ``heave_m = -heave_thesis``. Samples are 0.1 s apart; ``t_s`` runs on
    across the segments.
    """
    if path is None:
        df = thesis_motion_table()
    else:
        p = Path(path)
        try:
            df = pd.read_csv(p)
        except OSError as exc:
            raise ConfigError(f"cannot read the thesis motion series {p}: {exc}") from exc
        need = {"roll_deg", "pitch_deg", "yaw_deg", "heave_m"}
        if not need <= set(df.columns):
            raise ConfigError(f"{p}: thesis series needs columns {sorted(need)}")
    r, pch, y = zyx_from_thesis(*(np.radians(df[f"{a}_deg"].to_numpy(float)) for a in ("roll", "pitch", "yaw")))
    return MotionSeries(t_s=0.1 * np.arange(len(df)), roll_rad=r, pitch_rad=pch, yaw_rad=y,
                        heave_m=-df["heave_m"].to_numpy(float))


def load_motion(spec: MotionSpec) -> MotionSeries:
    """The motion series a config asks for (ConfigError if it cannot be had)."""
    if spec.source is MotionSource.FIXED:
        att = np.array([list(a) + [0.0] * (6 - len(a)) for a in spec.attitudes_deg], dtype=float)
        return MotionSeries(t_s=spec.dt_s * np.arange(len(att)), roll_rad=np.radians(att[:, 0]),
                            pitch_rad=np.radians(att[:, 1]), yaw_rad=np.radians(att[:, 2]),
                            heave_m=att[:, 3], surge_m=att[:, 4], sway_m=att[:, 5])
    if spec.source is MotionSource.THESIS:
        return thesis_series(spec.path)
    if spec.source is MotionSource.FILE:
        try:
            return read_series(spec.path or "", angles=spec.angles)
        except DeckposeError as exc:
            raise ConfigError(f"motion.path: {exc}") from exc
    from deckpose.motion.config import parse_sea_run
    from deckpose.motion.irregular import irregular_series

    run = parse_sea_run(dict(spec.params))
    return irregular_series(run.ship, run.sea, duration_s=run.duration_s, dt_s=run.dt_s,
                            rng=np.random.default_rng(run.seed))


def _interp_pose(series: MotionSeries, t_s: float) -> ShipPose:
    """The ship's pose at ``t_s``: linear between the series' samples, and beyond its ends along
    the first or last step (a frame at the series' first sample blurs over half an exposure
    before it; clamped there, the ship stood still for that half while the truth, at the
    exposure's middle, moved on: the first frame of a rendered approach sat 2-4 sigmas off on
    every outer beacon, a pose 5.1 sigmas off in roll)."""
    chans = ("roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m")
    ts = np.asarray(series.t_s, float)
    vals = []
    for c in chans:
        v = np.asarray(getattr(series, c), float)
        if c.endswith("_rad"):
            v = np.unwrap(v)
        if ts.size >= 2 and t_s < ts[0]:
            x = v[0] + (v[1] - v[0]) * (t_s - ts[0]) / (ts[1] - ts[0])
        elif ts.size >= 2 and t_s > ts[-1]:
            x = v[-1] + (v[-1] - v[-2]) * (t_s - ts[-1]) / (ts[-1] - ts[-2])
        else:
            x = np.interp(t_s, ts, v)
        vals.append(float(x))
    return ShipPose(*vals)


def sample_indices(spec: MotionSpec, n: int) -> list[int]:
    """Indices of the series samples to render."""
    idx = list(range(spec.start, n, spec.every))
    if spec.max_samples is not None:
        idx = idx[: spec.max_samples]
    if not idx:
        raise ConfigError(f"motion: start={spec.start} leaves no samples of a {n}-sample series")
    return idx


def _check_camera_above_deck(cfg: RenderConfig, height_m: float, ship: ShipPose, fid: int,
                             camera: CameraPose | None = None) -> None:
    """Camera must be above the deck plane and clear of the deck plate."""
    n_world = ship.R_world_from_deck[:, 2]
    cam = np.array([0.0, 0.0, height_m]) if camera is None else camera.position_world_m
    dist = float((cam - ship.t_world_from_deck) @ n_world)
    if dist <= 0.5:
        raise ConfigError(
            f"frame {fid}: the camera at height {float(cam[2]):g} m is inside or below the deck (distance "
            f"to the deck plane {dist:.2f} m with heave {ship.heave_m:.2f} m); raise "
            + ("the approach's heights_m" if camera is not None else "heights_m")
        )


def plan_frames(cfg: RenderConfig, series: MotionSeries | None = None) -> list[FrameSpec]:
    """Every frame of the job, in frame-id order.

    Parameters
    ----------
    cfg : RenderConfig
    series : MotionSeries, optional
        Motion to use instead of loading ``cfg.motion`` (tests).
    """
    series = load_motion(cfg.motion) if series is None else series
    if cfg.approach is not None:
        return _plan_approach(cfg, cfg.approach, series)
    idx = sample_indices(cfg.motion, len(series))
    blur = cfg.motion.exposure_s > 0 and cfg.motion.source is not MotionSource.FIXED
    cams = cfg.cameras_by_name()
    names = list(cams)
    frames: list[FrameSpec] = []
    fid = 0
    for cam in names:
        for h in cfg.heights_m:
            for light in cfg.lighting:
                for i in idx:
                    t = float(series.t_s[i])
                    ship = series.pose(i)
                    blur_poses: tuple[ShipPose, ...] = ()
                    if blur:
                        k = cfg.motion.blur_steps
                        ts = t + cfg.motion.exposure_s * ((np.arange(k) + 0.5) / k - 0.5)
                        blur_poses = tuple(_interp_pose(series, float(x)) for x in ts)
                    _check_camera_above_deck(cfg, h, ship, fid)
                    seed = int(np.random.SeedSequence([cfg.seed, fid]).generate_state(1)[0])
                    track = _ship_track(cfg, series, t, ship, cams[cam].height_px) if cfg.shutter.enabled else None
                    frames.append(FrameSpec(fid, cam, float(h), ship, blur_poses, t, light, seed, track=track))
                    fid += 1
    if not frames:
        raise ConfigError("the config yields no frames")
    return _on_capture_time(frames, len(idx), epoch_ns(cfg.capture_epoch))


def _plan_approach(cfg: RenderConfig, spec: ApproachSpec, series: MotionSeries) -> list[FrameSpec]:
    """Frames of an approach: cameras x lighting x the approach's frame times (one time sequence each).

    Frame ``k`` is at motion time ``t0 + k / rate_hz`` (``t0``: the series' sample
    ``motion.start``), its deck pose the series interpolated there, its camera pose
    :func:`~deckpose.render.approach.approach_camera_pose` (over the deck centre there with
    ``follow_deck``); ``height_m`` is the approach's first height (the sequence's nominal
    height in the frames table).
    """
    if cfg.motion.start >= len(series):
        raise ConfigError(f"motion: start={cfg.motion.start} leaves no samples of a {len(series)}-sample series")
    t0 = float(series.t_s[cfg.motion.start])
    times = approach_times_s(spec)
    if t0 + times[-1] > float(series.t_s[-1]) + 1e-9:
        raise ConfigError(f"approach: {spec.duration_s:g} s from motion time {t0:g} s runs past the motion series' "
                          f"end ({float(series.t_s[-1]):g} s); lengthen the series (motion.params.duration_s) or "
                          "shorten the approach")
    blur = cfg.motion.exposure_s > 0
    cams = cfg.cameras_by_name()
    h0 = float(spec.heights_m[0])
    frames: list[FrameSpec] = []
    fid = 0
    for cam in cams:
        for light in cfg.lighting:
            for tau in times:
                t = t0 + float(tau)
                ship = _interp_pose(series, t)
                camera = approach_camera_pose(spec, float(tau), ship.t_world_from_deck)
                blur_poses: tuple[ShipPose, ...] = ()
                if blur:
                    k = cfg.motion.blur_steps
                    ts = t + cfg.motion.exposure_s * ((np.arange(k) + 0.5) / k - 0.5)
                    blur_poses = tuple(_interp_pose(series, float(x)) for x in ts)
                _check_camera_above_deck(cfg, h0, ship, fid, camera)
                seed = int(np.random.SeedSequence([cfg.seed, fid]).generate_state(1)[0])
                track = _ship_track(cfg, series, t, ship, cams[cam].height_px) if cfg.shutter.enabled else None
                frames.append(FrameSpec(fid, cam, h0, ship, blur_poses, t, light, seed, track=track, camera=camera))
                fid += 1
    return _on_capture_time(frames, len(times), epoch_ns(cfg.capture_epoch))


def _ship_track(cfg: RenderConfig, series: MotionSeries, t_s: float, ship: ShipPose, height_px: int) -> ShipTrack:
    """The deck's motion over one frame's readout (one frame height either side) and exposure.

    Knots at the series samples inside the span and at its ends, so linear
    interpolation between them is :func:`_interp_pose` itself; fixed attitudes do not move.
    """
    if cfg.motion.source is MotionSource.FIXED:
        return ShipTrack((t_s,), (ship,))
    half = height_px * cfg.shutter.line_delay_s + 0.5 * cfg.motion.exposure_s
    if half == 0:
        return ShipTrack((t_s,), (ship,))
    ts = np.asarray(series.t_s, float)
    knots = [t_s - half, *(float(x) for x in ts[(ts > t_s - half) & (ts < t_s + half)]), t_s + half]
    return ShipTrack(tuple(knots), tuple(_interp_pose(series, x) for x in knots))


def _on_capture_time(frames: list[FrameSpec], per_replay: int, epoch: int) -> list[FrameSpec]:
    """The frames with their replay's capture offset (replays of ``per_replay`` consecutive frames)."""
    motion_ns = np.array([round(f.t_s * 1e9) for f in frames], np.int64).reshape(-1, per_replay)
    first, last = motion_ns.min(axis=1), motion_ns.max(axis=1)  # (samples need not be in time order)
    offsets = np.repeat(replay_starts_ns(first, last, epoch) - first, per_replay)
    return [dataclasses.replace(f, capture_offset_ns=int(o)) for f, o in zip(frames, offsets)]
