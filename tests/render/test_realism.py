"""Realism effects against independent computations: LED light model, occlusion, ship lights.

Each expected value is computed here from the geometry written out again (world
positions, camera centre and axis, the photometric law of the docstring of
:mod:`deckpose.render.light`), not from the renderer's own intermediate values.
Images are exposed noise-free onto a black raster, so a spot's light is what the
model put there.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from deckpose.render.beacons import beacon_splats
from deckpose.render.config import (
    KOSCHMIEDER,
    LedModel,
    LedSpec,
    OcclusionSpec,
    SensorSpec,
    ShipLightsSpec,
    config_from_dict,
)
from deckpose.render.light import unit_factors
from deckpose.render.occlusion import occlude
from deckpose.render.scene import SUN_TRAVEL_WORLD
from deckpose.render.sensor import expose, splat_electrons
from deckpose.render.ship_lights import light_splats, ship_lights

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

CAMERA = CameraModel(1280, 960, [[900.0, 0, 641.3], [0, 905.0, 478.6], [0, 0, 1]])
LAYOUT = DeckLayout()
SENSOR = SensorSpec(bit_depth=16, noise=False, beacon_peak=0.5, full_well_e=60000.0)
SHIP = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
CAM_POSE = CameraPose.nadir(30.0)


def _beacons_world() -> np.ndarray:
    P = LAYOUT.positions_deck_m()
    return P @ SHIP.R_world_from_deck.T + SHIP.t_world_from_deck


def _camera_centre_and_axis() -> tuple[np.ndarray, np.ndarray]:
    T = CAM_POSE.T_world_from_cam
    return T[:3, 3], T[:3, 2]


def _expected_point_flux_e(m: float, visibility_km: float | None, factors: np.ndarray) -> np.ndarray:
    """The point-light law written out in world coordinates: I0 cos^m(theta) cos(phi) / d^2 x T(d)."""
    C, axis = _camera_centre_and_axis()
    B = _beacons_world()
    ray = C - B  # beacon -> camera
    d = np.linalg.norm(ray, axis=1)
    cos_theta = (ray @ SHIP.R_world_from_deck[:, 2]) / d
    cos_phi = ((B - C) @ axis) / d
    trans = np.exp(-KOSCHMIEDER * d / (1000.0 * visibility_km)) if visibility_km else 1.0
    r = LAYOUT.beacon_radius_m
    radiance_px = (SENSOR.beacon_peak * LAYOUT.intensity * math.pi * r * r * CAMERA.fx * CAMERA.fy
                   * cos_theta ** m * cos_phi / d ** 2 * trans * factors)
    rgb = np.array([LAYOUT.bow_rgb if i == LAYOUT.bow_id else LAYOUT.beacon_rgb for i in range(len(B))])
    return radiance_px * (1 - SENSOR.halo_fraction) * SENSOR.exposure * SENSOR.full_well_e * rgb.sum(axis=1)


@pytest.mark.parametrize(("m", "visibility_km"), [(1.0, None), (3.0, None), (2.0, 2.0)])
def test_point_led_flux_follows_inverse_square_pattern_and_extinction(m: float, visibility_km: float | None) -> None:
    leds = LedSpec(model=LedModel.POINT, emission_exponent=m, visibility_km=visibility_km,
                   intensity_tolerance=0.4, bow_intensity=0.5)
    factors = unit_factors(LAYOUT, leds, seed=5)
    splats = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, SENSOR, leds, factors)
    assert len(splats) == LAYOUT.n_beacons
    got = np.array([splat_electrons(sp, SENSOR) for sp in splats])
    want = _expected_point_flux_e(m, visibility_km, factors)[[sp.beacon_id for sp in splats]]
    np.testing.assert_allclose(got, want, rtol=1e-6)  # the splat keeps its colour in float32 (6e-8)
    # and the image holds that light: the noise-free spot sums to it (in DN), halo included
    img = expose(np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8), np.ones(3, np.float32),
                 splats, SENSOR, np.random.default_rng(0)).astype(float)
    dn_per_e = (2 ** 16 - 1) / SENSOR.full_well_e
    for sp, w in zip(splats, want):
        n = sp.patch.shape[0]
        win = img[sp.row0:sp.row0 + n, sp.col0:sp.col0 + n].sum()
        # quantisation: +-0.5 DN a pixel at most, over the window
        assert win / dn_per_e == pytest.approx(w / (1 - SENSOR.halo_fraction), abs=0.5 * n * n / dn_per_e)


def test_inverse_square_between_heights() -> None:
    leds = LedSpec(model=LedModel.POINT)
    near = beacon_splats(LAYOUT, (ShipPose(),), CameraPose.nadir(20.0), CAMERA, SENSOR, leds)
    far = beacon_splats(LAYOUT, (ShipPose(),), CameraPose.nadir(40.0), CAMERA, SENSOR, leds)
    centre = LAYOUT.n_ring  # on the optical axis, facing the camera: cos terms are 1
    f_near = next(s.core_flux for s in near if s.beacon_id == centre)
    f_far = next(s.core_flux for s in far if s.beacon_id == centre)
    assert f_near / f_far == pytest.approx(4.0, rel=1e-12)


def test_unit_factors_fixed_per_dataset_within_tolerance() -> None:
    leds = LedSpec(intensity_tolerance=0.6, bow_intensity=0.4)
    a, b = unit_factors(LAYOUT, leds, 3), unit_factors(LAYOUT, leds, 3)
    np.testing.assert_array_equal(a, b)
    ring = np.delete(a, LAYOUT.bow_id)
    assert np.all((ring >= 0.4) & (ring <= 1.0)) and np.ptp(ring) > 0.1
    assert 0.4 * 0.4 <= a[LAYOUT.bow_id] <= 0.4
    assert not np.array_equal(a, unit_factors(LAYOUT, leds, 4))
    np.testing.assert_array_equal(unit_factors(LAYOUT, LedSpec(), 3), np.ones(LAYOUT.n_beacons))


def test_disc_model_is_unchanged_by_default() -> None:
    """The default LED spec reproduces the constant-radiance disc (earlier versions' frames)."""
    a = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, SENSOR)
    b = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, SENSOR, LedSpec(), np.ones(LAYOUT.n_beacons))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.patch, y.patch)
    # disc flux = radiance x projected area: pi r^2 |det J| with J from the projection itself
    r = LAYOUT.beacon_radius_m
    area_sum = sum(s.core_flux for s in a) / ((1 - SENSOR.halo_fraction) * SENSOR.beacon_peak)
    assert area_sum > 0 and all(s.core_flux > 0 for s in a)
    assert area_sum / len(a) == pytest.approx(math.pi * r * r * CAMERA.fx * CAMERA.fy / 30.0 ** 2, rel=0.15)


def _image(splats: list) -> np.ndarray:
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    return expose(raster, np.ones(3, np.float32), splats, SENSOR, np.random.default_rng(0)).astype(float).sum(axis=2)


def test_occlusion_records_the_light_that_is_drawn() -> None:
    splats = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, dataclasses.replace(SENSOR, psf_sigma_px=1.5))
    spec = OcclusionSpec(probability=1.0, min_fraction=0.2, max_fraction=0.8)
    cut, rec = occlude(splats, spec, LAYOUT.n_beacons, np.random.default_rng(11))
    full, part = _image(splats), _image(cut)
    for sp in splats:
        i = sp.beacon_id
        n = sp.patch.shape[0]
        rows = np.arange(sp.row0, sp.row0 + n)
        cols = np.arange(sp.col0, sp.col0 + n)
        w_full = full[sp.row0:sp.row0 + n, sp.col0:sp.col0 + n]
        w_part = part[sp.row0:sp.row0 + n, sp.col0:sp.col0 + n]
        kept = w_part.sum() / w_full.sum()
        assert 0.2 - 0.03 <= rec.hidden_fraction[i] <= 0.8 + 0.03
        assert rec.hidden_fraction[i] == pytest.approx(1 - kept, abs=2e-3)
        u = (w_part.sum(axis=0) @ cols) / w_part.sum()
        v = (w_part.sum(axis=1) @ rows) / w_part.sum()
        assert (rec.light_u_px[i], rec.light_v_px[i]) == pytest.approx((u, v), abs=0.01)
        # an edge that hides 20-80 % of a spot moves its light by a good part of a sigma
        assert math.hypot(u - sp.centre_px[0], v - sp.centre_px[1]) > 0.2


def test_wholly_hidden_beacons_leave_no_light_and_none_when_off() -> None:
    splats = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, SENSOR)
    gone, rec = occlude(splats, OcclusionSpec(probability=1.0, min_fraction=1.0, max_fraction=1.0),
                        LAYOUT.n_beacons, np.random.default_rng(0))
    assert gone == [] and np.all(rec.hidden_fraction == 1.0) and np.all(np.isnan(rec.light_u_px))
    same, rec = occlude(splats, OcclusionSpec(), LAYOUT.n_beacons, np.random.default_rng(0))
    assert same == splats and np.all(rec.hidden_fraction == 0.0)


def test_ship_lights_project_where_the_camera_sees_them() -> None:
    spec = ShipLightsSpec(navigation=True, floodlights=8, glints=6, deck_glints=3, intensity=2.0)
    cam = CameraModel(3000, 3000, [[900.0, 0, 1500.0], [0, 900.0, 1500.0], [0, 0, 1]])
    lights = ship_lights(spec, 14.0, 6.0, np.random.default_rng(2), ship=SHIP, camera_pose=CameraPose.nadir(60.0),
                         camera=cam, to_light_world=-SUN_TRAVEL_WORLD)
    kinds = [lt.kind for lt in lights]
    assert kinds[:4] == ["port", "starboard", "masthead", "stern"]
    assert kinds.count("floodlight") == 8 and kinds.count("glint") == 6 and kinds.count("deck_glint") == 3
    splats, uv, in_image = light_splats(lights, (SHIP,), CameraPose.nadir(60.0), cam, SENSOR, LedSpec(), LAYOUT)
    T_cw = CameraPose.nadir(60.0).T_cam_from_world
    for j, lt in enumerate(lights):
        p = lt.position_m @ SHIP.R_world_from_deck.T + SHIP.t_world_from_deck if lt.on_deck else lt.position_m
        pc = T_cw[:3, :3] @ p + T_cw[:3, 3]
        want = [900.0 * pc[0] / pc[2] + 1500.0, 900.0 * pc[1] / pc[2] + 1500.0]
        np.testing.assert_allclose(uv[j], want, atol=1e-9)
    assert in_image.all()  # a wide view from 60 m sees the whole ship and the glints
    # port (red, +y) and starboard (green) keep their colours and sides
    by_id = {-1 - s.beacon_id: s for s in splats}
    assert by_id[0].rgb[0] > by_id[0].rgb[1] and by_id[1].rgb[1] > by_id[1].rgb[0]
    # a light's electrons follow an isotropic point source: I cos(phi) / d^2, x intensity
    d = np.linalg.norm((T_cw @ np.append(lights[2].position_m @ SHIP.R_world_from_deck.T
                                          + SHIP.t_world_from_deck, 1.0))[:3])
    pc = (T_cw @ np.append(lights[2].position_m @ SHIP.R_world_from_deck.T + SHIP.t_world_from_deck, 1.0))[:3]
    want = (SENSOR.beacon_peak * math.pi * LAYOUT.beacon_radius_m ** 2 * 900.0 ** 2 * (pc[2] / d) / d ** 2
            * 2.0 * (1 - SENSOR.halo_fraction) * SENSOR.full_well_e * 3.0)
    assert splat_electrons(by_id[2], SENSOR) == pytest.approx(want, rel=1e-6)  # float32 colour


@pytest.mark.parametrize(("section", "value", "words"), [
    ("leds", {"emission_exponent": 3.0}, "only the 'point' model"),
    ("leds", {"intensity_tolerance": 1.0}, "intensity_tolerance"),
    ("leds", {"visibility_km": 0}, "visibility_km"),
    ("occlusion", {"probability": 1.5}, "probability"),
    ("occlusion", {"min_fraction": 0.9, "max_fraction": 0.5}, "exceeds"),
    ("ship_lights", {"glints": -1}, "glints"),
    ("ship_lights", {"beacons": 3}, "beacons"),
])
def test_realism_config_errors_name_the_key(section: str, value: dict, words: str) -> None:
    doc = {"cameras": [{"preset": "4mp"}], "heights_m": [20], section: value}
    with pytest.raises(ConfigError, match=words):
        config_from_dict(doc)


def test_rendered_dataset_records_every_effect(tmp_path) -> None:
    """A dataset with every effect on: the tables record them and the frames stay reproducible."""
    import pandas as pd
    from deckpose.render.dataset import render_dataset

    from .conftest import tiny_doc

    doc = tiny_doc(heights_m=[60.0], lighting=["night"], cameras=[{"preset": "4mp", "size": [640, 480]}],
                   leds={"model": "point", "emission_exponent": 2.0, "intensity_tolerance": 0.5,
                         "visibility_km": 3.0},
                   occlusion={"probability": 0.5, "min_fraction": 0.3, "max_fraction": 1.0},
                   ship_lights={"navigation": True, "floodlights": 4, "glints": 3})
    out = render_dataset(config_from_dict(doc), tmp_path / "ds", workers=0, progress=False)
    b = pd.read_parquet(out / "beacons.parquet")
    lights = pd.read_parquet(out / "lights.parquet")
    assert len(lights) == 2 * 11 and set(lights.kind) == {"port", "starboard", "masthead", "stern",
                                                           "floodlight", "glint"}
    assert lights.in_image.any() and (lights.flux_e[lights.in_image] > 0).all()
    # the unit factors are the dataset's: the same in both frames
    f = b.pivot(index="beacon_id", columns="frame_id", values="unit_factor")
    np.testing.assert_array_equal(f[0].to_numpy(), f[1].to_numpy())
    occluded = b.occluded_fraction > 0
    assert occluded.any() and (~occluded).any()
    hidden = b.occluded_fraction == 1.0
    assert b.loc[hidden, "spot_flux_e"].isna().all() and b.loc[hidden, "light_u_px"].isna().all()
    clear = b.visible & ~occluded
    np.testing.assert_allclose(b.loc[clear, "light_u_px"], b.loc[clear, "u_px"], atol=1e-6)
    again = render_dataset(config_from_dict(doc), tmp_path / "again", workers=0, progress=False)
    assert (out / "images" / "000001.png").read_bytes() == (again / "images" / "000001.png").read_bytes()


def _ray_cast_dome_centroid(centre_world: np.ndarray, radius: float, cam_pose: CameraPose,
                            camera: CameraModel, step: float = 0.02) -> np.ndarray:
    """Area centroid of the dome's silhouette by casting a ray through every sub-pixel sample.

    A sample is lit when its ray's first hit on the sphere lies on the upper half (z >= 0
    above the deck; the lower half is under the opaque deck). Constant radiance makes the
    image uniform over the lit samples, so their mean is the light centroid.
    """
    T = cam_pose.T_cam_from_world
    c = T[:3, :3] @ centre_world + T[:3, 3]
    up = T[:3, :3] @ np.array([0.0, 0.0, 1.0])  # the deck normal (level deck) in the camera frame
    uv0 = camera.project(c[None])[0]
    half = 1.5 * radius * camera.fx / c[2]
    us = np.arange(uv0[0] - half, uv0[0] + half, step)
    vs = np.arange(uv0[1] - half, uv0[1] + half, step)
    U, V = np.meshgrid(us, vs)
    d = np.stack([(U - camera.cx) / camera.fx, (V - camera.cy) / camera.fy, np.ones_like(U)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = d @ c
    disc = b * b - (c @ c - radius * radius)
    hit = disc >= 0
    s = b - np.sqrt(np.where(hit, disc, 0.0))
    p = d * s[..., None] - c  # first hit relative to the sphere's centre
    lit = hit & (p @ up >= 0)
    return np.array([U[lit].mean(), V[lit].mean()])


def test_dome_light_centroid_matches_ray_casting() -> None:
    from deckpose.render.config import EmitterShape
    from deckpose.render.emitter import dome_light_centroids

    from deckpose.pose import T_cam_from_deck

    cam = CameraModel(1280, 960, [[900.0, 0, 640.0], [0, 900.0, 480.0], [0, 0, 1]])
    layout = DeckLayout(beacon_radius_m=0.4)  # a big dome, many pixels: a sharp comparison
    pose = CameraPose.nadir(30.0)
    dome = dome_light_centroids(layout, T_cam_from_deck(ShipPose(), pose), cam)
    flat = beacon_splats(layout, (ShipPose(),), pose, cam, SENSOR)
    for i in (0, 3, layout.n_ring):
        want = _ray_cast_dome_centroid(layout.positions_deck_m()[i], layout.beacon_radius_m, pose, cam)
        np.testing.assert_allclose(dome[i], want, atol=0.02)
    # off the nadir the light sits outward of the projected centre, by a fraction of a pixel
    projected = next(s.centre_px for s in flat if s.beacon_id == 0)
    shift = dome[0] - projected
    assert 0.1 < np.linalg.norm(shift) < 1.0 and shift @ (projected - [640.0, 480.0]) > 0
    # the centre beacon, on the optical axis, is symmetric: no shift
    np.testing.assert_allclose(dome[layout.n_ring], [640.0, 480.0], atol=0.01)  # the grid: < 1e-3 radii
    # the splats of a domed layout are centred on those light centroids
    domed = beacon_splats(layout, (ShipPose(),), pose, cam, SENSOR, LedSpec(emitter=EmitterShape.DOME))
    for sp in domed:
        np.testing.assert_allclose(sp.centre_px, dome[sp.beacon_id], atol=1e-9)
