"""Ship look (issue 23 item 8) against independent computations: hull and superstructure
geometry and lines of sight (trimesh ray casting), the wave sea's formula, the sky it reflects against Fresnel's
equations, the light pools' inverse-square and cosine law, the deck texture's size from the GSD, bloom's centroid and
energy, and the default frame left as it was."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trimesh
from deckpose.render.beacons import Splat
from deckpose.render.bloom import bloom
from deckpose.render.config import Lighting, SeaSpec, config_from_dict
from deckpose.render.frame import render_frame
from deckpose.render.light_pools import AMBIENT_LUX, pool_illuminance_lux
from deckpose.render.plan import FrameSpec
from deckpose.render.sea import (
    WATER_F0,
    WATER_RGB,
    Waves,
    sea_colour,
    sea_grid_m,
    sea_grid_surface,
    sea_height_m,
    sea_normals,
    sea_waves,
)
from deckpose.render.ship_model import hull_mesh, superstructure_mesh
from deckpose.render.texture_size import deck_texture_px

from deckpose.camera import preset
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

from .conftest import tiny_config, tiny_doc

A_M, FREEBOARD_M = 14.0, 6.0


def _hits(mesh: trimesh.Trimesh, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Whether each segment origin -> target crosses a triangle of the mesh (Moller-Trumbore,
    brute force over every ray and triangle)."""
    tri = mesh.triangles  # (T, 3, 3)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d = targets - origins  # (R, 3); a hit at 0 < t < 1 lies on the segment
    p = np.cross(d[:, None, :], e2[None])  # (R, T, 3)
    det = np.einsum("rtk,tk->rt", p, e1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins[:, None, :] - tri[None, :, 0]
    u = np.einsum("rtk,rtk->rt", s, p) * inv
    q = np.cross(s, e1[None])
    v = np.einsum("rk,rtk->rt", d, q) * inv
    t = np.einsum("tk,rtk->rt", e2, q) * inv
    return (ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9) & (t < 1 - 1e-9)).any(axis=1)


def test_hull_runs_from_the_deck_to_the_waterline_with_a_bow() -> None:
    hull = hull_mesh(A_M, FREEBOARD_M)
    assert hull.is_watertight
    (x0, y0, z0), (x1, y1, z1) = hull.bounds
    assert z0 == pytest.approx(-FREEBOARD_M) and -0.05 < z1 <= 0.0  # just under the plate (no depth fight)
    assert x0 == pytest.approx(-A_M) and y0 == pytest.approx(-A_M) and y1 == pytest.approx(A_M)  # transom, beam
    # every deck point has the hull under it: a ray straight down from above the deck hits its top
    g = np.linspace(-0.99 * A_M, 0.99 * A_M, 7)
    xy = np.array([(x, y) for x in g for y in g])
    down = _hits(hull, np.column_stack([xy, np.full(len(xy), 1.0)]), np.column_stack([xy, np.full(len(xy), -1.0)]))
    assert down.all()
    # a bow: the hull narrows forward of the deck to a point at the tip
    def beam_at(x: float) -> float:
        ys = np.linspace(-A_M - 1, A_M + 1, 561)
        hit = _hits(hull, np.column_stack([np.full(len(ys), x), ys, np.full(len(ys), 1.0)]),
                    np.column_stack([np.full(len(ys), x), ys, np.full(len(ys), -1.0)]))
        return float(np.ptp(ys[hit])) if hit.any() else 0.0
    assert beam_at(0.0) > beam_at(x1 - 10.0) > beam_at(x1 - 1.0) > 0.0


@pytest.mark.parametrize("height_m", [10.0, 20.0, 30.0, 50.0, 80.0, 120.0, 200.0])
def test_superstructure_hides_no_beacon_from_a_nadir_camera(height_m: float) -> None:
    """Ray casting from every beacon (dome top) to nadir cameras over a rolling, pitching deck."""
    layout = DeckLayout(n_ring=12, radius_m=10.0, has_centre=True)
    ship_mesh = trimesh.util.concatenate([superstructure_mesh(A_M), hull_mesh(A_M, FREEBOARD_M)])
    beacons = layout.positions_deck_m() + [0.0, 0.0, 0.01]
    for roll, pitch, yaw in [(0, 0, 0), (8, 8, 30), (-8, -8, -30), (8, -8, 90)]:
        ship = ShipPose(math.radians(roll), math.radians(pitch), math.radians(yaw), 1.0, 0.5, -0.5)
        cam_world = CameraPose.nadir(height_m).T_world_from_cam[:3, 3]
        T = np.linalg.inv(ship.T_world_from_deck)
        cam_deck = T[:3, :3] @ cam_world + T[:3, 3]
        assert not _hits(ship_mesh, beacons, np.tile(cam_deck, (len(beacons), 1))).any()
    # the check can fail: a camera low over the bow sees the bow beacon through the bridge
    low = np.array([[A_M + 40.0, 0.0, 7.0]])
    assert _hits(ship_mesh, beacons[:1], low).all()


def test_sea_height_follows_its_formula_and_is_a_function_of_time() -> None:
    spec = SeaSpec(waves=5, height_m=2.0, wavelength_m=50.0, direction_deg=30.0, seed=4)
    waves, _ = sea_waves(spec)
    rng = np.random.default_rng(0)
    xy = rng.uniform(-300, 300, (40, 2))
    for t in (0.0, 3.7):
        want = np.zeros(len(xy))
        for A, (kx, ky), phi in zip(waves.amplitude_m, waves.k_per_m, waves.phase_rad, strict=True):
            omega = math.sqrt(9.81 * math.hypot(kx, ky))  # deep-water dispersion
            want += A * np.sin(kx * xy[:, 0] + ky * xy[:, 1] - omega * t + phi)
        np.testing.assert_allclose(sea_height_m(waves, xy, t), want, atol=1e-12)
    # significant height 4 sqrt(m0), m0 = sum A^2 / 2; wavelengths within an octave of the peak
    assert 4.0 * math.sqrt(float((waves.amplitude_m ** 2).sum()) / 2.0) == pytest.approx(2.0)
    lam = 2 * math.pi / np.linalg.norm(waves.k_per_m, axis=1)
    assert lam.min() == pytest.approx(25.0) and lam.max() == pytest.approx(100.0)
    # deterministic in t_s and the seed; moving in time; another seed another sea
    again, _ = sea_waves(spec)
    np.testing.assert_array_equal(sea_height_m(again, xy, 1.5), sea_height_m(waves, xy, 1.5))
    assert not np.allclose(sea_height_m(waves, xy, 1.5), sea_height_m(waves, xy, 2.5))
    other, _ = sea_waves(dataclasses.replace(spec, seed=5))
    assert not np.allclose(sea_height_m(other, xy, 1.5), sea_height_m(waves, xy, 1.5))


def test_sea_normals_are_the_surface_gradient() -> None:
    waves, ripples = sea_waves(SeaSpec(waves=4, seed=2))
    still = Waves(np.zeros(len(ripples.amplitude_m)), ripples.k_per_m, ripples.omega_rad_per_s, ripples.phase_rad)
    xy = np.random.default_rng(1).uniform(-100, 100, (20, 2))
    h = 1e-4  # central differences: error ~ h^2 eta''' ~ 1e-9
    dx = (sea_height_m(waves, xy + [h, 0], 2.0) - sea_height_m(waves, xy - [h, 0], 2.0)) / (2 * h)
    dy = (sea_height_m(waves, xy + [0, h], 2.0) - sea_height_m(waves, xy - [0, h], 2.0)) / (2 * h)
    want = np.column_stack([-dx, -dy, np.ones(len(xy))])
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    np.testing.assert_allclose(sea_normals(waves, still, xy, 2.0), want, atol=1e-7)


def test_rendered_sea_grid_is_the_formula_at_its_vertices() -> None:
    """The renderer's fast grid (angle-sum outer products) against the per-point formula."""
    waves, ripples = sea_waves(SeaSpec(waves=5, seed=7))
    g = sea_grid_m(500.0, inner_half_m=30.0, step_m=3.0)
    xy = np.column_stack([np.repeat(g, len(g)), np.tile(g, len(g))])  # x index first
    eta, normals = sea_grid_surface(waves, ripples, g, 12.5)
    np.testing.assert_allclose(eta, sea_height_m(waves, xy, 12.5), atol=1e-10)  # float64 rounding
    np.testing.assert_allclose(normals, sea_normals(waves, ripples, xy, 12.5), atol=1e-10)


def _fresnel_unpolarised(cos_i: np.ndarray, n: float = 1.333) -> np.ndarray:
    """Reflectance of still water (refractive index ``n``) for unpolarised light, Fresnel's equations."""
    cos_t = np.sqrt(1.0 - (1.0 - cos_i ** 2) / n ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    return (rs + rp) / 2


def test_sea_reflects_the_sky_by_fresnel() -> None:
    """The sea's colour mixes water and sky by the reflectance at the view angle: Schlick's
    approximation of Fresnel's equations for water, which it follows within 0.06 (its largest
    error for n = 1.333, at 84 degrees; 0.002 at normal incidence)."""
    view_deg = np.linspace(0.0, 89.0, 90)
    normals = np.tile([0.0, 0.0, 1.0], (view_deg.size, 1))
    to_cam = np.stack([np.sin(np.radians(view_deg)), np.zeros(view_deg.size), np.cos(np.radians(view_deg))], axis=1)
    sky = np.array([0.55, 0.65, 0.8])
    colour = sea_colour(normals, to_cam, sky, None)
    water = np.asarray(WATER_RGB)
    reflectance = (colour - water) / (sky - water)  # the share of sky, per channel
    np.testing.assert_allclose(reflectance, np.repeat(reflectance[:, :1], 3, axis=1), atol=1e-12)
    exact = _fresnel_unpolarised(np.cos(np.radians(view_deg)))
    assert abs(WATER_F0 - exact[0]) < 0.002
    np.testing.assert_allclose(reflectance[:, 0], exact, atol=0.06)
    assert np.all(np.diff(reflectance[:, 0]) >= 0)  # more sky toward grazing
    # flat shading: the water (not the sky) is lit by Lambert's term toward the sun
    sun = np.array([0.0, 0.0, 1.0])
    lit = sea_colour(normals[:1], to_cam[:1], sky, sun)
    f0 = reflectance[0, 0]
    np.testing.assert_allclose(lit[0], (1 - f0) * water * (0.6 + 0.8) + f0 * sky, rtol=1e-12)


def test_light_pool_illuminance_is_inverse_square_times_cosine() -> None:
    src = np.array([[1.0, 2.0, 0.15], [-3.0, 0.5, 0.3]])
    pts = np.array([[1.0, 2.0], [2.0, 2.0], [4.0, -1.0], [-3.0, 3.5]])
    got = pool_illuminance_lux(src, 5.0, pts)
    for j, s in enumerate(src):
        for i, p in enumerate(pts):
            d = math.dist((*p, 0.0), s)
            cos_incidence = s[2] / d
            assert got[i, j] == pytest.approx(5.0 / d ** 2 * cos_incidence, rel=1e-12)


def test_light_pools_brighten_the_rendered_deck_by_the_law(egl_renderer_factory) -> None:
    """Deck pixels, pools on over pools off, against 1 + E rgb / E_ambient written out per beacon."""
    intensity_cd = 2.0
    base = tiny_config(cameras=[{"preset": "4mp-square", "size": [640, 480]}])
    lit = tiny_config(cameras=[{"preset": "4mp-square", "size": [640, 480]}],
                      scene={"shading": "flat", "texture_px": 256, "light_pools_cd": intensity_cd})
    cam = base.cameras_by_name()["4mp-square-640x480"]
    pose, ship = CameraPose.nadir(25.0), ShipPose()
    off = egl_renderer_factory(base).render(cam, pose, ship, 0.0, Lighting.NIGHT).astype(float)
    on = egl_renderer_factory(lit).render(cam, pose, ship, 0.0, Lighting.NIGHT).astype(float)
    layout = base.layout
    P = layout.positions_deck_m()
    rgb = np.array([layout.bow_rgb if i == layout.bow_id else layout.beacon_rgb for i in range(len(P))])
    checked = 0
    for x, y in [(10.0, 2.0), (7.5, -6.0), (-4.0, 8.0), (0.0, -7.2), (3.0, 3.0)]:
        lux = np.zeros(3)
        for b, c in zip(P, rgb, strict=True):
            h = layout.beacon_radius_m
            d2 = (x - b[0]) ** 2 + (y - b[1]) ** 2 + h * h
            lux += intensity_cd * h / d2 ** 1.5 * c
        gain = 1.0 + lux / AMBIENT_LUX[Lighting.NIGHT]
        u, v = cam.fx * -y / 25.0 + cam.cx, cam.fy * -x / 25.0 + cam.cy  # nadir: image up = bow, left = port
        win = (slice(round(v) - 1, round(v) + 2), slice(round(u) - 1, round(u) + 2))
        if on[win].max() >= 250:  # saturated: the law cannot show
            continue
        ratio = on[win].mean(axis=(0, 1)) / off[win].mean(axis=(0, 1))
        # rounding to 8 bits (0.5/~100 per pixel) and the 5.5 cm pool texels over a 3x3 window: 3 %
        np.testing.assert_allclose(ratio, gain, rtol=0.03)
        checked += 1
    assert checked >= 3


def test_auto_texture_size_follows_the_gsd() -> None:
    cam = preset("64mp-square")
    want = 2 * A_M * cam.fx / 30.0  # texels a side for one texel a pixel at 30 m
    got = deck_texture_px([cam, preset("8mp-square")], 30.0, A_M)
    assert want <= got < want + 256 and got % 256 == 0
    assert want / 2048 == pytest.approx(2.75, abs=0.05)  # the "stretched about 2.7x"
    assert deck_texture_px([cam], 5.0, A_M) == 8192  # capped
    cfg = config_from_dict(tiny_doc(cameras=[{"preset": "64mp-square"}, {"preset": "8mp-square"}],
                                    heights_m=[50.0, 30.0], scene={"texture_px": "auto"}))
    assert cfg.scene.texture_px == got


def test_bloom_keeps_each_spot_centroid_and_light() -> None:
    rng = np.random.default_rng(3)
    patch = rng.uniform(0, 1, (15, 13)).astype(np.float32) ** 4  # lopsided: centroid off the window centre
    sp = Splat(100, 200, patch, np.array([1.0, 0.1, 0.05], np.float32), 0, 1.0, 5.0)
    f, sigma = 0.2, 6.0
    (out,) = bloom([sp], f, sigma)

    def moments(s: Splat) -> tuple[float, np.ndarray, np.ndarray]:
        vv, uu = np.mgrid[: s.patch.shape[0], : s.patch.shape[1]]
        w = s.patch.astype(float)
        m = w.sum()
        c = np.array([(w * (uu + s.col0)).sum(), (w * (vv + s.row0)).sum()]) / m
        var = np.array([(w * (uu + s.col0 - c[0]) ** 2).sum(), (w * (vv + s.row0 - c[1]) ** 2).sum()]) / m
        return m, c, var

    m0, c0, v0 = moments(sp)
    m1, c1, v1 = moments(out)
    assert m1 == pytest.approx(m0, rel=1e-5)  # float32 sums
    np.testing.assert_allclose(c1, c0, atol=1e-4)  # px; the kernel is symmetric
    # a mixture (1 - f) P + f (G * P): variance grows by f sigma^2 (G's truncation at 4 sigma: 0.03 %)
    np.testing.assert_allclose(v1, v0 + f * sigma ** 2, rtol=0.01)
    assert out.core_flux == pytest.approx((1 - f) * sp.core_flux)


def test_frame_truth_and_spots_unchanged_by_the_ship_look(egl_renderer_factory) -> None:
    """Everything on: the same beacon truth and light centroids; the default frame is what it was
    with every key written out as off."""
    on_scene = {"shading": "flat", "texture_px": 256, "ship": {"hull": True, "superstructure": True},
                "sea": {"waves": 3}, "light_pools_cd": 2.0, "bloom_fraction": 0.05, "bloom_sigma_mrad": 3.0}
    off_scene = {"shading": "flat", "texture_px": 256, "ship": {"hull": False, "superstructure": False},
                 "sea": {"waves": 0}, "light_pools_cd": 0.0, "bloom_fraction": 0.0, "shadows": False}
    base, on, off = tiny_config(), tiny_config(scene=on_scene), tiny_config(scene=off_scene)
    cam = base.cameras_by_name()["4mp-320x240"]
    spec = FrameSpec(0, cam.name, 30.0, ShipPose(0.05, -0.03, 0.2), (), 1.0, Lighting.NIGHT, 5)
    a = render_frame(base, spec, cam, egl_renderer_factory(base))
    b = render_frame(on, spec, cam, egl_renderer_factory(on))
    c = render_frame(off, spec, cam, egl_renderer_factory(off))
    np.testing.assert_array_equal(a.frame.image, c.frame.image)
    np.testing.assert_array_equal(a.truth.points_px, b.truth.points_px)
    np.testing.assert_array_equal(a.occlusion.light_u_px, b.occlusion.light_u_px)
    np.testing.assert_allclose(b.spots.flux_e, 0.95 * a.spots.flux_e, rtol=1e-6)  # 5 % gone to glare
    assert not np.array_equal(a.frame.image, b.frame.image)


@pytest.mark.parametrize(("scene", "message"), [
    ({"texture_px": "big"}, r"scene\.texture_px: an integer \(64-8192\) or auto, got 'big'"),
    ({"ship": {"hull": True, "mast": True}}, r"scene\.ship: unknown key\(s\) \['mast'\]"),
    ({"sea": {"waves": 4, "height_m": 4.0}}, r"scene\.sea\.height_m"),
    ({"bloom_fraction": 1.0}, r"scene\.bloom_fraction"),
    ({"light_pools_cd": -1.0}, r"scene\.light_pools_cd"),
])
def test_ship_look_keys_are_checked(scene: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        config_from_dict(tiny_doc(scene=scene))
    assert "\n" not in str(err.value)  # one line
