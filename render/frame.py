"""One frame end to end: rasterise, distort, add beacons, expose; and its exact ground truth.

Motion blur (``motion.exposure_s > 0``) spreads each beacon over the deck poses of the
exposure; the deck and sea raster is drawn once, at mid-exposure (blurring it would
cost one rasterisation per sub-pose). The ground truth is the mid-exposure pose.

Realism on top of the raster, each off by default (:mod:`deckpose.render.config`):
the beacons' light model and unit tolerance (:mod:`deckpose.render.light`), occluders
(:mod:`deckpose.render.occlusion`) and lights that are not beacons
(:mod:`deckpose.render.ship_lights`). Each draws from its own stream,
``SeedSequence([frame seed, stream])``, so switching one on leaves the others' and the
sensor noise's realisations as they were.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from deckpose.render.beacons import beacon_splats
from deckpose.render.bloom import bloom, bloom_sigma_px
from deckpose.render.config import RenderConfig
from deckpose.render.lens import distort, raster_camera
from deckpose.render.light import unit_factors
from deckpose.render.occlusion import OCCLUSION_STREAM, OcclusionRecord, occlude
from deckpose.render.plan import FrameSpec
from deckpose.render.scene import DeckRenderer, radiance_scale
from deckpose.render.sensor import SpotRecord, expose, splat_electrons, spot_record
from deckpose.render.ship_lights import GLINT_STREAM, ShipLight, light_splats, ship_lights

from deckpose.camera import CameraModel
from deckpose.projection import BeaconProjection, project_layout
from deckpose.records import Frame, GroundTruth


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
    cam_pose = spec.camera_pose
    raster = renderer.render(raster_camera(camera), cam_pose, spec.ship, spec.t_s, spec.lighting)
    raster = distort(raster, camera)
    poses = spec.blur_poses or (spec.ship,)
    factors = unit_factors(cfg.layout, cfg.leds, cfg.seed)
    splats = beacon_splats(cfg.layout, poses, cam_pose, camera, cfg.sensor, cfg.leds, factors)
    splats, occlusion = occlude(splats, cfg.occlusion, cfg.layout.n_beacons, _stream(spec.seed, OCCLUSION_STREAM))
    lights = ship_lights(cfg.ship_lights, cfg.deck_half_size_m(), cfg.scene.freeboard_m,
                         _stream(spec.seed, GLINT_STREAM))
    extra, lights_px, lights_in = light_splats(lights, poses, cam_pose, camera, cfg.sensor, cfg.leds, cfg.layout)
    if cfg.scene.bloom_fraction > 0:  # glare around every light, point-symmetric (truth unchanged)
        glare_px = bloom_sigma_px(cfg.scene.bloom_sigma_mrad, camera)
        splats = bloom(splats, cfg.scene.bloom_fraction, glare_px)
        extra = bloom(extra, cfg.scene.bloom_fraction, glare_px)
    flux_e = np.zeros(len(lights))
    for sp in extra:
        flux_e[-1 - sp.beacon_id] = splat_electrons(sp, cfg.sensor)
    rng = np.random.default_rng(spec.seed)
    scale = radiance_scale(spec.lighting, cfg.scene.shading)
    image = expose(raster, scale, splats + extra, cfg.sensor, rng)
    spots = spot_record(raster, scale, splats, cfg.sensor, cfg.layout.n_beacons)
    image.setflags(write=False)  # Frame keeps a read-only array as is (no 200 MB copy at 64 MP)
    proj = project_layout(cfg.layout, spec.ship, cam_pose, camera)
    truth = GroundTruth(spec.ship, cam_pose, proj.points_px, proj.visible, proj.apparent_radius_px,
                        spec.frame_id, spec.stamp_ns, spec.seed)
    frame = Frame(image, camera, spec.frame_id, spec.stamp_ns)
    return RenderedFrame(frame, truth, proj, spec, spots, factors, occlusion, tuple(lights), lights_px,
                         lights_in, flux_e)


def _stream(seed: int, stream: int) -> np.random.Generator:
    """The frame's generator of one realism effect (independent of the sensor noise's)."""
    return np.random.default_rng(np.random.SeedSequence([seed, stream]))


def frame_row(rf: RenderedFrame, image_relpath: str) -> dict[str, Any]:
    """The ``frames.parquet`` row of a rendered frame (dataset contract)."""
    s, t = rf.spec, rf.truth
    tr, tp, ty = s.ship.thesis_angles_rad()
    R = t.camera_pose.R_world_from_cam
    row: dict[str, Any] = {
        "frame_id": s.frame_id, "image": image_relpath, "camera": s.camera_name,
        "stamp_ns": s.stamp_ns, "t_s": s.t_s, "camera_height_m": s.height_m,
        "roll_rad": s.ship.roll_rad, "pitch_rad": s.ship.pitch_rad, "yaw_rad": s.ship.yaw_rad,
        "heave_m": s.ship.heave_m, "surge_m": s.ship.surge_m, "sway_m": s.ship.sway_m,
        "thesis_roll_deg": float(np.degrees(tr)), "thesis_pitch_deg": float(np.degrees(tp)),
        "thesis_yaw_deg": float(np.degrees(ty)), "lighting": s.lighting.value, "seed": s.seed,
        "n_visible": int(np.count_nonzero(t.visible)),
    }
    for i in range(3):
        for j in range(3):
            row[f"r{i}{j}"] = float(R[i, j])
    row["cam_x_m"], row["cam_y_m"], row["cam_z_m"] = (float(x) for x in t.camera_pose.position_world_m)
    return row


def beacon_rows(rf: RenderedFrame) -> list[dict[str, Any]]:
    """The ``beacons.parquet`` rows of a rendered frame, one per beacon id.

    Besides the projection, each row carries the beacon's spot model
    (:class:`~deckpose.render.sensor.SpotRecord`): ``spot_sigma_px``, ``spot_flux_e``,
    ``spot_background_e`` and ``spot_peak_e`` (NaN where the beacon has no spot), which
    the detector benchmark turns into the centroid Cramér–Rao bound; the unit's
    intensity factor (``unit_factor``), and the occluder's ``occluded_fraction`` with the
    centroid of the light left (``light_u_px``, ``light_v_px``).
    """
    p, sp, oc = rf.projection, rf.spots, rf.occlusion
    return [
        {"frame_id": rf.spec.frame_id, "beacon_id": i, "u_px": float(p.points_px[i, 0]),
         "v_px": float(p.points_px[i, 1]), "visible": bool(p.visible[i]), "in_image": bool(p.in_image[i]),
         "facing": bool(p.facing[i]), "apparent_radius_px": float(p.apparent_radius_px[i]),
         "spot_sigma_px": float(sp.sigma_px[i]), "spot_flux_e": float(sp.flux_e[i]),
         "spot_background_e": float(sp.background_e[i]), "spot_peak_e": float(sp.peak_e[i]),
         "unit_factor": float(rf.unit_factors[i]), "occluded_fraction": float(oc.hidden_fraction[i]),
         "light_u_px": float(oc.light_u_px[i]), "light_v_px": float(oc.light_v_px[i])}
        for i in range(p.points_px.shape[0])
    ]


def light_rows(rf: RenderedFrame) -> list[dict[str, Any]]:
    """The ``lights.parquet`` rows of a rendered frame: every non-beacon light, in view or not."""
    return [
        {"frame_id": rf.spec.frame_id, "light_id": j, "kind": light.kind,
         "u_px": float(rf.lights_px[j, 0]), "v_px": float(rf.lights_px[j, 1]),
         "in_image": bool(rf.lights_in_image[j]), "flux_e": float(rf.lights_flux_e[j])}
        for j, light in enumerate(rf.lights)
    ]
