"""One frame end to end: rasterise, distort, add beacons, expose; and its exact ground truth.

Motion blur (``motion.exposure_s > 0``) spreads each beacon over the deck poses of the
exposure; the deck and sea raster is drawn once, at mid-exposure (blurring it would
cost one rasterisation per sub-pose). The ground truth is the mid-exposure pose.

Realism on top of the raster, each off by default (:mod:`deckpose.render.config`):
the beacons' light model and unit tolerance (:mod:`deckpose.render.light`), occluders
(:mod:`deckpose.render.occlusion`), lights that are not beacons
(:mod:`deckpose.render.ship_lights`) and the lens beyond a Gaussian (:mod:`deckpose.render.optics`). Each draws from its own stream,
``SeedSequence([frame seed, stream])``, so switching one on leaves the others' and the
sensor noise's realisations as they were. The rolling shutter and the UAV's motion and
vibration (:mod:`deckpose.render.rolling_shutter`) place each beacon at its own row's time;
``u_px, v_px`` are then that truth and ``global_u_px, global_v_px`` the frame-time projection.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from deckpose.render.auto_exposure import metered_exposure
from deckpose.render.beacons import Splat, beacon_splats
from deckpose.render.bloom import bloom, bloom_sigma_px
from deckpose.render.camera_motion import VIBRATION_STREAM, camera_motion
from deckpose.render.compression import jpeg_round_trip
from deckpose.render.config import RenderConfig
from deckpose.render.fixed_pattern import fixed_pattern
from deckpose.render.lens import distort, raster_camera
from deckpose.render.light import unit_factors
from deckpose.render.occlusion import OCCLUSION_STREAM, OcclusionRecord, occlude
from deckpose.render.optics import (
    LensedFrame,
    OpticsRecord,
    lens_record,
    optics_row,
    through_lens,
)
from deckpose.render.optics_config import OpticsSpec
from deckpose.render.painted_ring import (
    RingTruth,
    floodlight_gain,
    paint_splats,
    ring_rows,
    ring_truth,
)
from deckpose.render.plan import FrameSpec
from deckpose.render.rolling_shutter import ShutterFrame, rolling_shutter_beacons
from deckpose.render.scene import SUN_TRAVEL_WORLD, DeckRenderer, radiance_scale
from deckpose.render.sensor import SpotRecord, expose, splat_electrons, spot_record
from deckpose.render.sensor_config import BayerPattern
from deckpose.render.ship_lights import (
    GLINT_STREAM,
    ShipLight,
    light_splats,
    lights_in_camera_m,
    ship_lights,
)
from deckpose.render.split_kernels import NO_PARTS

from deckpose.camera import CameraModel
from deckpose.projection import BeaconProjection, project_layout
from deckpose.records import Frame, GroundTruth
from deckpose.run_folder import frame_truth_row


@dataclass(frozen=True)
class RenderedFrame:
    """A rendered image with its ground truth (never handed to a detector as is)."""

    frame: Frame
    truth: GroundTruth
    projection: BeaconProjection
    spec: FrameSpec
    spots: SpotRecord
    unit_factors: np.ndarray
    occlusion: OcclusionRecord
    lights: tuple[ShipLight, ...] = ()
    lights_px: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))
    lights_in_image: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, bool))
    lights_flux_e: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    global_points_px: np.ndarray | None = None  # frame-time projection (None: projection.points_px)
    #: The exposure the auto-exposure chose (:mod:`deckpose.render.auto_exposure`); None: ``sensor.exposure``.
    exposure: float | None = None
    optics: OpticsRecord | None = None
    #: The painted ring's truth (:mod:`deckpose.render.painted_ring`); None without ``painted_ring``.
    ring: RingTruth | None = None


#: A row gain of the sensor's background, ``f(r0, r1) -> (r1 - r0, W)`` float32.
RowGain = Callable[[int, int], np.ndarray]


def render_frame(cfg: RenderConfig, spec: FrameSpec, camera: CameraModel,
                 renderer: DeckRenderer) -> RenderedFrame:
    """Render one planned frame.

    Parameters
    ----------
    cfg : RenderConfig
    spec : FrameSpec
    camera : CameraModel
        The camera named by ``spec.camera_name``.
    renderer : DeckRenderer
        This process's renderer (its GL context is created on first use).
    """
    factors = unit_factors(cfg.layout, cfg.leds, cfg.seed)
    shutter = _shutter(cfg, spec, camera, factors)
    cam_pose = spec.camera_pose if shutter is None else shutter.camera_pose
    raster = renderer.render(raster_camera(camera), cam_pose, spec.ship, spec.t_s, spec.lighting)
    raster = distort(raster, camera)
    poses = spec.blur_poses or (spec.ship,)
    splats = (beacon_splats(cfg.layout, poses, cam_pose, camera, cfg.sensor, cfg.leds, factors)
              if shutter is None else shutter.splats)
    splats, occlusion = occlude(splats, cfg.occlusion, cfg.layout.n_beacons, _stream(spec.seed, OCCLUSION_STREAM))
    lights = ship_lights(cfg.ship_lights, cfg.deck_half_size_m(), cfg.scene.freeboard_m,
                         _stream(spec.seed, GLINT_STREAM), ship=spec.ship, camera_pose=cam_pose,
                         camera=camera, to_light_world=-SUN_TRAVEL_WORLD, ship_model=cfg.scene.ship)
    extra, lights_px, lights_in = light_splats(lights, poses, cam_pose, camera, cfg.sensor, cfg.leds, cfg.layout)
    proj = project_layout(cfg.layout, spec.ship, cam_pose, camera) if shutter is None else shutter.projection
    scale = radiance_scale(spec.lighting, cfg.scene.shading)
    sensor = cfg.sensor  # with auto-exposure, the exposure this frame's metering chose (and the truth uses)
    if sensor.auto_exposure is not None:  # the controller's, chosen before (exposure_control), or its own
        exposure = (spec.exposure if spec.exposure is not None
                    else metered_exposure(raster, scale, sensor, sensor.auto_exposure))
        sensor = dataclasses.replace(sensor, exposure=exposure)
    if cfg.scene.bloom_fraction > 0:  # glare around every light, point-symmetric (truth unchanged)
        glare_px = bloom_sigma_px(cfg.scene.bloom_sigma_mrad, camera)
        splats = bloom(splats, cfg.scene.bloom_fraction, glare_px)
        extra = bloom(extra, cfg.scene.bloom_fraction, glare_px)
    lens: LensedFrame | None = None
    if cfg.optics.enabled():  # off: today's spots, bit for bit
        depth = lights_in_camera_m(lights, spec.ship, cam_pose)[[-1 - sp.beacon_id for sp in extra], 2]
        lens = through_lens(cfg.optics, camera, sensor, raster, scale, splats, extra, proj.points_px,
                            proj.depth_m, depth)
        splats, extra = lens.beacons, lens.lights
    flux_e = np.zeros(len(lights))
    for sp in extra:
        flux_e[-1 - sp.beacon_id] = splat_electrons(sp, sensor)
    rng = np.random.default_rng(spec.seed)
    spots = lens.spots if lens else spot_record(raster, scale, splats, sensor, cfg.layout.n_beacons)
    record = lens.record if lens else None
    if record is None and sensor.bayer is not BayerPattern.NONE:  # the bound of the mosaic, no lens
        record = lens_record(OpticsSpec(), camera, sensor, splats, [(NO_PARTS, 1.0)] * len(splats), spots,
                             proj.points_px, proj.depth_m)
    pattern = fixed_pattern(sensor, cfg.seed, camera.name, *raster.shape[:2])
    gain = lens.background_gain if lens else None
    paint: list[Splat] = []
    ring: RingTruth | None = None
    if cfg.painted_ring is not None:  # off: today's frames, bit for bit
        flood, flood_rows = floodlight_gain(cfg.painted_ring, spec.lighting, cfg.deck_half_size_m(), spec.ship,
                                            cam_pose, camera)
        paint = paint_splats(raster, scale, cfg.painted_ring, spec.ship, cam_pose, camera, deck_gain=flood)
        gain = _product(gain, flood_rows)
        ring = ring_truth(cfg.painted_ring, spec.ship, cam_pose, camera)
    image = expose(raster, scale, splats + extra + paint, sensor, rng, pattern=pattern, background_gain=gain)
    if sensor.jpeg_quality is not None:
        image = jpeg_round_trip(image, sensor.jpeg_quality)
    image.setflags(write=False)  # Frame keeps a read-only array as is (no 200 MB copy at 64 MP)
    truth = GroundTruth(spec.ship, cam_pose, proj.points_px, proj.visible, proj.apparent_radius_px,
                        spec.frame_id, spec.stamp_ns, spec.seed)
    frame = Frame(image, camera, spec.frame_id, spec.stamp_ns)
    return RenderedFrame(frame, truth, proj, spec, spots, factors, occlusion, tuple(lights), lights_px,
                         lights_in, flux_e,
                         global_points_px=None if shutter is None else shutter.global_points_px,
                         exposure=None if cfg.sensor.auto_exposure is None else sensor.exposure,
                         optics=record, ring=ring)


def _product(a: RowGain | None, b: RowGain | None) -> RowGain | None:
    """The product of two row-gain functions of :func:`~deckpose.render.sensor.expose` (None: 1)."""
    if a is None or b is None:
        return a or b

    def both(r0: int, r1: int) -> np.ndarray:
        return a(r0, r1) * b(r0, r1)

    return both


def _shutter(cfg: RenderConfig, spec: FrameSpec, camera: CameraModel, factors: np.ndarray) -> ShutterFrame | None:
    """The beacons under the rolling shutter and the UAV's motion (None when the section is off)."""
    if not cfg.shutter.enabled or spec.track is None:
        return None
    motion = camera_motion(cfg.shutter, spec.camera_pose, spec.t_s, _stream(spec.seed, VIBRATION_STREAM))
    return rolling_shutter_beacons(cfg.layout, spec.track, spec.ship, motion, camera, cfg.shutter, cfg.motion,
                                   cfg.sensor, cfg.leds, factors)


def _stream(seed: int, stream: int) -> np.random.Generator:
    """The frame's generator of one realism effect (independent of the sensor noise's)."""
    return np.random.default_rng(np.random.SeedSequence([seed, stream]))


def frame_row(rf: RenderedFrame, image_relpath: str) -> dict[str, Any]:
    """The ``frames.parquet`` row of a rendered frame (dataset contract)."""
    s, t = rf.spec, rf.truth
    row = frame_truth_row(s.frame_id, image_relpath, s.camera_name, s.stamp_ns, s.t_s, s.height_m, s.ship,
                          t.camera_pose, s.lighting.value, s.seed, int(np.count_nonzero(t.visible)))
    if rf.exposure is not None:  # the column exists only with sensor.auto_exposure (default tables unchanged)
        row["exposure"] = rf.exposure
    if s.metered_exposure is not None:  # only with the exposure controller (exposure_control)
        row["metered_exposure"] = s.metered_exposure
    return row


def beacon_rows(rf: RenderedFrame) -> list[dict[str, Any]]:
    """The ``beacons.parquet`` rows of a rendered frame, one per beacon id.

    Besides the projection, each row carries the beacon's spot model
    (:class:`~deckpose.render.sensor.SpotRecord`): ``spot_sigma_px``, ``spot_flux_e``,
    ``spot_background_e`` and ``spot_peak_e`` (NaN where the beacon has no spot), which
    the detector benchmark turns into the centroid Cramér–Rao bound; the unit's
    intensity factor (``unit_factor``), and the occluder's ``occluded_fraction`` with the
    centroid of the light left (``light_u_px``, ``light_v_px``); ``global_u_px``,
    ``global_v_px``: the projection at the frame time (``u_px, v_px`` without a rolling shutter),
    and the optics' per-beacon record (:func:`deckpose.render.optics.optics_row`; NaN without optics).
    """
    p, sp, oc = rf.projection, rf.spots, rf.occlusion
    g = p.points_px if rf.global_points_px is None else rf.global_points_px
    return [
        {"frame_id": rf.spec.frame_id, "beacon_id": i, "u_px": float(p.points_px[i, 0]),
         "v_px": float(p.points_px[i, 1]), "visible": bool(p.visible[i]), "in_image": bool(p.in_image[i]),
         "facing": bool(p.facing[i]), "apparent_radius_px": float(p.apparent_radius_px[i]),
         "spot_sigma_px": float(sp.sigma_px[i]), "spot_flux_e": float(sp.flux_e[i]),
         "spot_background_e": float(sp.background_e[i]), "spot_peak_e": float(sp.peak_e[i]),
         "unit_factor": float(rf.unit_factors[i]), "occluded_fraction": float(oc.hidden_fraction[i]),
         "light_u_px": float(oc.light_u_px[i]), "light_v_px": float(oc.light_v_px[i]),
         "global_u_px": float(g[i, 0]), "global_v_px": float(g[i, 1]),
         **optics_row(rf.optics, i)}
        for i in range(p.points_px.shape[0])
    ]


def painted_ring_rows(rf: RenderedFrame) -> list[dict[str, Any]]:
    """The ``painted_ring.parquet`` rows of a rendered frame (none without a painted ring)."""
    return [] if rf.ring is None else ring_rows(rf.spec.frame_id, rf.ring)


def light_rows(rf: RenderedFrame) -> list[dict[str, Any]]:
    """The ``lights.parquet`` rows of a rendered frame: every non-beacon light, in view or not."""
    return [
        {"frame_id": rf.spec.frame_id, "light_id": j, "kind": light.kind,
         "u_px": float(rf.lights_px[j, 0]), "v_px": float(rf.lights_px[j, 1]),
         "in_image": bool(rf.lights_in_image[j]), "flux_e": float(rf.lights_flux_e[j])}
        for j, light in enumerate(rf.lights)
    ]
