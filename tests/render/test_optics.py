"""Optics beyond a Gaussian (:mod:`deckpose.render.optics`) against independent computations.

Each expected value is computed here again from its law: the thin-lens blur from the lens
equation and similar triangles, the Airy profile from ``scipy.special.j1`` integrated
over pixels on a finer grid, chromatic aberration from the magnification written out,
vignetting from the angle between the optical axis and the pixel's ray, blooming from
charge bookkeeping, the Cramér–Rao bound from images built and differentiated by brute
force. Spots are exposed noise-free onto a black raster, so the image is the model's light.
"""

from __future__ import annotations

import dataclasses
import math
from typing import cast

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.benchmark import crb_per_beacon
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.synthetic import SensorModel
from deckpose.render.beacons import Splat, add_splats, beacon_splats, spot_splat
from deckpose.render.blooming import bloom_column, bloom_splats
from deckpose.render.config import OpticsSpec, SensorSpec, config_from_dict
from deckpose.render.optics import (
    apply_optics,
    ca_centres_px,
    defocus_diameter_px,
    optics_block,
    vignetting_gain,
    vignetting_rows,
)
from deckpose.render.psf_kernels import airy_first_zero_px, airy_kernel, disk_kernel
from deckpose.render.sensor import expose
from deckpose.render.split_kernels import NO_PARTS, KernelParts
from deckpose.render.spot_bound import spot_crb_px
from scipy.special import j1, jn_zeros

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.spot_fisher import centre_crb_px2

from .conftest import tiny_doc

CAMERA = CameraModel(640, 480, [[600.0, 0, 321.3], [0, 600.0, 238.6], [0, 0, 1]])
LAYOUT = DeckLayout()
SENSOR = SensorSpec(bit_depth=16, noise=False, beacon_peak=0.6, full_well_e=1e6)  # peak ~ 60000 DN: no clipping
SHIP = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
CAM_POSE = CameraPose.nadir(40.0)  # the ring (10 m) 150 px from the centre: every spot whole


def _splats(optics: OpticsSpec, sensor: SensorSpec = SENSOR) -> tuple[list[Splat], list[Splat], np.ndarray]:
    """The beacons' splats before and after the optics, and the true centres (N, 2)."""
    base = beacon_splats(LAYOUT, (SHIP,), CAM_POSE, CAMERA, sensor)
    proj = project_layout(LAYOUT, SHIP, CAM_POSE, CAMERA)
    lensed, _ = apply_optics(base, proj.depth_m[[sp.beacon_id for sp in base]], optics, CAMERA)
    return base, lensed, proj.points_px


def _image(splats: list[Splat], sensor: SensorSpec = SENSOR) -> np.ndarray:
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    img = expose(raster, np.ones(3, np.float32), splats, sensor, np.random.default_rng(0))
    return img.astype(np.float64)


def _light(splats: list[Splat]) -> np.ndarray:
    """The spots' light as the sensor adds it (float, before noise and rounding), (H, W, 3) radiance."""
    img = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.float32)
    add_splats(img, splats)
    return img.astype(np.float64)


def _centroid(img: np.ndarray) -> np.ndarray:
    """Intensity centroid ``(u, v)`` of an image, pixels."""
    v, u = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    return np.array([(img * u).sum(), (img * v).sum()]) / img.sum()


def test_defocus_diameter_follows_the_lens_equation() -> None:
    optics = OpticsSpec(f_number=2.0, focus_distance_m=12.0, pixel_pitch_um=3.45)
    s = np.array([5.0, 12.0, 30.0, 80.0])
    f = CAMERA.fx * 3.45e-6
    image = 1.0 / (1.0 / f - 1.0 / s)  # where each depth focuses (1/f = 1/s + 1/v)
    sensor_at = 1.0 / (1.0 / f - 1.0 / 12.0)  # the sensor sits where 12 m focuses
    aperture = f / 2.0
    want_px = aperture * np.abs(image - sensor_at) / image / 3.45e-6  # similar triangles: cone cut by the sensor
    np.testing.assert_allclose(defocus_diameter_px(s, CAMERA, optics), want_px, rtol=1e-9, atol=1e-12)
    assert defocus_diameter_px(np.array([12.0]), CAMERA, optics)[0] == 0.0


def test_airy_kernel_is_the_pixel_integrated_airy_pattern() -> None:
    optics = OpticsSpec(f_number=4.0, pixel_pitch_um=1.2, diffraction=True)
    k = airy_kernel(540.0, optics)
    r = k.shape[0] // 2
    # (2 J1(x)/x)^2, x = pi r / (lambda N), averaged over 21 x 21 points per pixel (the kernel uses 7 x 7)
    sub = (np.arange(21) + 0.5) / 21 - 0.5
    x = (np.arange(-r, r + 1)[:, None] + sub[None, :]).ravel()
    rr = np.hypot(x[None, :], x[:, None]) * 1.2e-6
    arg = math.pi * rr / (540e-9 * 4.0)
    prof = np.where(arg > 0, (2 * j1(np.maximum(arg, 1e-300)) / np.maximum(arg, 1e-300)) ** 2, 1.0)
    want = prof.reshape(2 * r + 1, 21, 2 * r + 1, 21).mean(axis=(1, 3))
    want /= want.sum()
    # 7 against 21 sub-samples: the midpoint rule's error on this smooth profile, < 0.5 % of the peak
    np.testing.assert_allclose(k, want, atol=5e-3 * want.max())
    # the first dark ring: J1's first zero, x = 3.8317, i.e. r = 3.8317 / pi lambda N (= 1.2197 lambda N;
    # the module's 1.22 is 2.7e-4 off)
    want_px = jn_zeros(1, 1)[0] / math.pi * 540e-9 * 4.0 / 1.2e-6
    assert airy_first_zero_px(540.0, optics) == pytest.approx(want_px, rel=3e-4)


@pytest.mark.parametrize("optics", [
    OpticsSpec(focus_distance_m=1.0, f_number=1.4, pixel_pitch_um=6.0),  # a 1.5 px disc at 40 m
    OpticsSpec(diffraction=True, f_number=8.0, pixel_pitch_um=1.0),
    OpticsSpec(glare_fraction=0.1, glare_radius_px=3.0),
    OpticsSpec(spike_fraction=0.1, spike_blades=5),
    OpticsSpec(field_blur_px=2.0),
], ids=["defocus", "diffraction", "glare", "spikes", "field_blur"])
def test_point_symmetric_kernels_keep_the_centroid_and_the_flux(optics: OpticsSpec) -> None:
    base, lensed, truth = _splats(optics)
    for sp, sl in zip(base, lensed):
        c = truth[sp.beacon_id]
        img, ref = _light([sl]).sum(axis=2), _light([sp]).sum(axis=2)  # one spot alone: no neighbour's wings
        # the sampled Gaussian core is centred to < 1e-4 px (render/beacons.py), float32 sums add
        # ~1e-5 px: 1e-3 px is the bound
        np.testing.assert_allclose(_centroid(img), c, atol=1e-3)
        # flux: the kernels sum to 1 (float32 accumulation: ~1e-6)
        assert abs(img.sum() / ref.sum() - 1) < 1e-5
        # and the quantised noise-free exposure keeps both too, to its rounding (light spread thin over
        # spikes and glare rounds to 0 DN: up to ~1e-3 px and 0.5 % of the flux here)
        q, q_ref = _image([sl]).sum(axis=2), _image([sp]).sum(axis=2)
        np.testing.assert_allclose(_centroid(q), c, atol=3e-3)
        assert abs(q.sum() / q_ref.sum() - 1) < 5e-3


def test_lateral_ca_moves_each_channel_to_its_recorded_centre() -> None:
    optics = OpticsSpec(lateral_ca_ppm=(1500.0, -1200.0))
    base, lensed, truth = _splats(optics)
    centres = ca_centres_px(truth, CAMERA, optics)
    # the radial magnification written out: x0 + m (x - x0), m = 1 + ppm / 1e6, green unmoved
    x0 = np.array([CAMERA.cx, CAMERA.cy])
    np.testing.assert_allclose(centres[:, 0], x0 + 1.0015 * (truth - x0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(centres[:, 1], truth, rtol=0, atol=1e-12)
    np.testing.assert_allclose(centres[:, 2], x0 + 0.9988 * (truth - x0), rtol=0, atol=1e-9)
    assert np.abs(centres[:, 0] - truth).max() > 0.2  # the shifts are a fifth of a pixel at the ring
    for sp, sl in zip(base, lensed):
        light = _light([sl])
        for ch in range(3):
            if sl.rgb[ch] > 0:  # the bow beacon is red only
                # the bilinear shift kernel's centroid is the shift exactly; the core's < 1e-4 px
                np.testing.assert_allclose(_centroid(light[..., ch]), centres[sp.beacon_id, ch], atol=1e-3)


def test_vignetting_is_cos4_of_the_ray_angle_on_spots_and_raster() -> None:
    optics = OpticsSpec(vignetting_exponent=4.0)
    base, lensed, truth = _splats(optics)
    rays = np.linalg.solve(CAMERA.K, np.c_[truth, np.ones(len(truth))].T).T  # pinhole rays (no distortion)
    theta = np.arccos(rays[:, 2] / np.linalg.norm(rays, axis=1))
    want = np.cos(theta) ** 4
    np.testing.assert_allclose(vignetting_gain(truth, CAMERA, 4.0), want, rtol=1e-12)
    assert want.min() < 0.95  # the ring is far enough out for the law to show
    for sp, sl in zip(base, lensed):
        # the spot's light and its recorded flux are dimmed by the law at its centre (float32 sums: 1e-6)
        assert _light([sl]).sum() / _light([sp]).sum() == pytest.approx(want[sp.beacon_id], rel=1e-5)
        assert sl.core_flux / sp.core_flux == pytest.approx(want[sp.beacon_id], rel=1e-12)
    # the raster: a uniform half-well scene exposed with the vignetting rows
    raster = np.full((CAMERA.height_px, CAMERA.width_px, 3), 200, np.uint8)
    scale = np.full(3, 0.5 / 200, np.float32)  # 200 -> half the well
    img = expose(raster, scale, [], SENSOR, np.random.default_rng(0),
                 background_gain=vignetting_rows(CAMERA, 4.0)).astype(float)
    v, u = np.mgrid[0:CAMERA.height_px:37, 0:CAMERA.width_px:41]
    r = np.stack([(u - CAMERA.cx) / CAMERA.fx, (v - CAMERA.cy) / CAMERA.fy, np.ones(u.shape)], axis=-1)
    cos_t = r[..., 2] / np.linalg.norm(r, axis=-1)
    want_dn = 0.5 * 65535 * cos_t ** 4
    np.testing.assert_allclose(img[v, u, 1], want_dn, atol=0.51)  # rounding to whole DN (+ float32 1e-3)


def test_bloom_column_fills_the_neighbours_and_conserves_charge() -> None:
    cap = 1000.0
    col = np.zeros((21, 3))
    col[10, 1] = 5 * cap  # five wells' charge in one pixel: two full pixels above and two below it
    want = np.zeros_like(col)
    want[8:13, 1] = cap
    np.testing.assert_allclose(bloom_column(col, cap), want)
    col[10, 1] = 5.5 * cap  # 4.5 wells spill, 2.25 each way: two full pixels and a quarter well per side
    want[7, 1] = want[13, 1] = 0.25 * cap
    np.testing.assert_allclose(bloom_column(col, cap), want)
    col[10, 1] = 30 * cap  # more than the column holds: what leaves the window is lost, none is made
    out = bloom_column(col, cap)
    assert out.max() <= cap and out.sum() == pytest.approx(21 * cap)


def test_bloom_splats_spill_along_columns_only_and_keep_the_charge() -> None:
    sensor = dataclasses.replace(SENSOR, exposure=20.0, full_well_e=15000.0, bit_depth=12)  # ~15 wells at peak
    _, lensed, _ = _splats(OpticsSpec(bloom=True), sensor)
    raster = np.full((CAMERA.height_px, CAMERA.width_px, 3), 10, np.uint8)
    e = sensor.exposure * sensor.full_well_e
    scale = np.full(3, 0.2 * sensor.full_well_e / (10 * e), np.float32)  # a background of 0.2 wells
    bloomed = bloom_splats(lensed, raster, scale, sensor)
    bg = 10 * float(scale[0]) * e
    for before, after in zip(lensed, bloomed):
        a = before.patch.astype(np.float64) * before.rgb * e  # electrons per channel
        b = after.patch.astype(np.float64) * after.rgb * e
        assert (a + bg).max() > 5 * sensor.full_well_e  # it does saturate
        assert (b + bg).max() <= sensor.full_well_e * (1 + 1e-6)  # no pixel above the well after
        pad = before.row0 - after.row0
        assert pad > 0 and before.col0 == after.col0  # the window grows in rows
        a_cols = a.sum(axis=0)
        # each column keeps its charge (float32 patches: 1e-6 of the spot's light)
        np.testing.assert_allclose(b.sum(axis=0), a_cols, rtol=0, atol=1e-6 * a.sum())
        lit = (b.sum(axis=2) > 1e-3 * sensor.full_well_e)
        rows, cols = np.flatnonzero(lit.any(axis=1)), np.flatnonzero(lit.any(axis=0))
        assert np.ptp(rows) > np.ptp(cols)  # the spot streaks along its columns


def _fisher(mu: np.ndarray, grads: list[np.ndarray], extra: float) -> np.ndarray:
    """The Fisher information of independent pixels of variance mu + extra, written out."""
    info = np.zeros((len(grads), len(grads)))
    for i, gi in enumerate(grads):
        for j, gj in enumerate(grads):
            info[i, j] = float(np.sum(gi * gj / (mu + extra)))
    return info


def test_numeric_crb_of_a_gaussian_is_the_analytic_bound() -> None:
    u, v, s, flux, bg = 10.3, 9.8, 1.1, 5000.0, 40.0
    sensor = SensorModel(gain_dn_per_e=0.25, read_noise_e=4.0, background_e=bg)
    sub = (np.arange(15) + 0.5) / 15 - 0.5

    def image(u: float, v: float, s: float) -> np.ndarray:
        """The Gaussian integrated over 21 x 21 pixels by 15 x 15 point samples each."""
        x = (np.arange(21)[:, None] + sub[None, :]).ravel()
        gx = np.exp(-0.5 * ((x - u) / s) ** 2)
        gy = np.exp(-0.5 * ((x - v) / s) ** 2)
        g = np.outer(gy, gx) / (2 * math.pi * s * s) / 225
        return flux * g.reshape(21, 15, 21, 15).sum(axis=(1, 3))

    h = 1e-4  # central differences: O(h^2) = 1e-8 relative
    grads = np.stack([(image(u + h, v, s) - image(u - h, v, s)) / (2 * h),
                      (image(u, v + h, s) - image(u, v - h, s)) / (2 * h),
                      (image(u, v, s + h) - image(u, v, s - h)) / (2 * h),
                      image(u, v, s) / flux, np.ones((21, 21))])
    got = centre_crb_px2(bg + image(u, v, s), grads, sensor.extra_variance_e2)
    want = centroid_crb_px2(u, v, s, flux, sensor)
    # 15-point midpoint quadrature of a sigma = 1.1 px Gaussian (~1e-4) and the 21 px window against
    # the analytic 8 sigma + 2 (light beyond 9 sigma: nil): 0.5 %
    np.testing.assert_allclose(got, want, rtol=5e-3, atol=1e-6 * float(want[0, 0]))


def test_numeric_crb_of_a_defocused_spot_against_brute_force() -> None:
    sensor = SensorSpec(bit_depth=12, noise=False, full_well_e=15000.0, read_noise_e=4.0, halo_fraction=0.0)
    centre, s, flux = np.array([30.37, 29.81]), 1.0, 0.02  # flux in radiance x px: 0.02 x 15000 x 3 = 900 e
    cam = CameraModel(64, 64, [[100.0, 0, 32.0], [0, 100.0, 32.0], [0, 0, 1]])
    base = spot_splat([(centre, s * s * np.eye(2), flux)], (1.0, 1.0, 1.0), sensor, cam, 0)
    assert base is not None
    d = 3.0
    disk = disk_kernel(d)
    bg = 30.0
    got = spot_crb_px(base, KernelParts.from_kernels((disk, disk, disk)), 1.0, bg, sensor)
    # brute force: the Gaussian sampled at pixel centres (as the renderer draws it) convolved with a
    # uniform disc integrated over each pixel on a 41 x 41 grid (the renderer's kernel: 7 x 7)
    sub = (np.arange(41) + 0.5) / 41 - 0.5
    R = 2
    off = np.arange(-R, R + 1)
    x = (off[:, None] + sub[None, :]).ravel()
    inside = (x[None, :] ** 2 + x[:, None] ** 2 <= (d / 2) ** 2).reshape(2 * R + 1, 41, 2 * R + 1, 41)
    K = inside.mean(axis=(1, 3))
    K /= K.sum()
    n = 64
    e = 15000.0 * 3  # electrons per unit radiance, summed over three white channels

    def image(cu: float, cv: float, ss: float) -> np.ndarray:
        yy, xx = np.mgrid[0:n, 0:n].astype(float)
        g = np.exp(-0.5 * ((xx - cu) ** 2 + (yy - cv) ** 2) / ss ** 2) / (2 * math.pi * ss ** 2)
        out = np.zeros_like(g)
        for i, dy in enumerate(off):  # the convolution written out
            for j, dx in enumerate(off):
                out += K[i, j] * np.roll(np.roll(g, dy, axis=0), dx, axis=1)
        return flux * e * out

    h = 1e-4
    cu, cv = centre
    spot = image(cu, cv, s)
    grads = [(image(cu + h, cv, s) - image(cu - h, cv, s)) / (2 * h),
             (image(cu, cv + h, s) - image(cu, cv - h, s)) / (2 * h),
             (image(cu, cv, s + h) - image(cu, cv, s - h)) / (2 * h), spot / flux, np.ones_like(spot)]
    gain = 4095 / 15000.0
    info = _fisher(bg + spot, grads, 4.0 ** 2 + 1 / (12 * gain ** 2))
    want = math.sqrt(np.trace(np.linalg.inv(info)[:2, :2]) / 2)
    # the disc's pixel weights at 7 x 7 against 41 x 41 sub-samples differ by a few % at its rim, which
    # moves the bound by 0.25 % here: 1 %
    assert got == pytest.approx(want, rel=1e-2)
    # and the disc matters: the bound of the plain Gaussian is clearly smaller
    plain = spot_crb_px(base, NO_PARTS, 1.0, bg, sensor)
    assert plain < 0.8 * got


def test_benchmark_uses_the_recorded_bound_when_present() -> None:
    sensor = SensorModel(gain_dn_per_e=0.27, read_noise_e=4.0, background_e=0.0)
    rows = pd.DataFrame({"u_px": [100.2, 200.7, 300.1], "v_px": [50.3, 60.1, 70.9],
                         "spot_sigma_px": [1.2, 1.2, 1.2], "spot_flux_e": [3000.0, 3000.0, 3000.0],
                         "spot_background_e": [20.0, 20.0, 20.0], "spot_crb_px": [0.031, np.nan, 0.05],
                         "occluded_fraction": [0.0, 0.0, 0.5]})
    got = crb_per_beacon(rows, sensor)
    assert got[0] == pytest.approx(0.031 ** 2)  # recorded (optics on)
    analytic = centroid_crb_px2(200.7, 60.1, 1.2, 3000.0, dataclasses.replace(sensor, background_e=20.0))
    assert got[1] == pytest.approx(np.trace(analytic) / 2)  # not recorded: the Gaussian bound
    assert np.isnan(got[2])  # occluded: no bound


@pytest.mark.parametrize(("optics", "needle"), [
    ({"f_number": 0.1}, "optics.f_number"),
    ({"glare_fraction": 0.6, "spike_fraction": 0.5}, "glare_fraction + spike_fraction"),
    ({"lateral_ca_ppm": [1.0, 2.0, 3.0]}, "optics.lateral_ca_ppm"),
    ({"bloom": "yes"}, "optics.bloom"),
    ({"focus_m": 3.0}, "focus_distance_m"),  # an unknown key: the valid ones are listed
    ({"focus_distance_m": 0.0001}, "focal length"),  # 0.1 mm: inside the lens (f ~ 0.3 mm here)
    ({"spike_blades": 2}, "optics.spike_blades"),
    ({"wavelength_nm": [610.0, 540.0, 100.0]}, "optics.wavelength_nm[2]"),
])
def test_optics_config_errors_are_one_line(optics: dict[str, object], needle: str) -> None:
    with pytest.raises(ConfigError) as err:
        config_from_dict(tiny_doc(optics=optics))
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_frames_bit_for_bit_with_optics_off_and_recorded_with_it_on(egl_renderer_factory) -> None:
    from deckpose.render.frame import beacon_rows, render_frame
    from deckpose.render.plan import plan_frames

    doc = tiny_doc(heights_m=[30.0], lighting=["night"], cameras=[{"preset": "8mp-square", "size": [320, 180]}],
                   sensor={"bit_depth": 12, "read_noise_e": 4, "full_well_e": 15000},
                   ship_lights={"navigation": True, "floodlights": 2, "glints": 2})
    plain = config_from_dict(doc)
    off = config_from_dict({**doc, "optics": {"f_number": 4.0, "pixel_pitch_um": 3.0}})  # every effect off
    on = config_from_dict({**doc, "optics": {"focus_distance_m": 2.0, "diffraction": True, "glare_fraction": 0.03,
                                             "spike_fraction": 0.02, "bloom": True, "vignetting_exponent": 4.0,
                                             "lateral_ca_ppm": [800.0, -800.0], "field_blur_px": 1.0}})
    spec = plan_frames(plain)[0]
    cam = plain.cameras_by_name()[spec.camera_name]
    renderer = egl_renderer_factory(plain)
    a, b, c = (render_frame(cfg, spec, cam, renderer) for cfg in (plain, off, on))
    np.testing.assert_array_equal(a.frame.image, b.frame.image)
    pd.testing.assert_frame_equal(pd.DataFrame(beacon_rows(a)), pd.DataFrame(beacon_rows(b)))
    assert pd.DataFrame(beacon_rows(a))["spot_crb_px"].isna().all()
    assert not np.array_equal(a.frame.image, c.frame.image)
    np.testing.assert_array_equal(a.lights_flux_e, b.lights_flux_e)
    seen_lights = a.lights_flux_e > 0
    assert seen_lights.any()  # the other lights went through the lens too, dimmed by the vignetting
    assert np.all(c.lights_flux_e[seen_lights] < a.lights_flux_e[seen_lights])
    rows = pd.DataFrame(beacon_rows(c))
    seen = rows[rows["visible"]]
    assert len(seen) > 3 and (seen["spot_crb_px"] > 0).all()
    np.testing.assert_allclose(rows["defocus_px"], defocus_diameter_px(c.projection.depth_m, cam, on.optics))
    np.testing.assert_allclose(rows["vignetting"], vignetting_gain(c.projection.points_px, cam, 4.0))
    ca = ca_centres_px(c.projection.points_px, cam, on.optics)
    np.testing.assert_allclose(rows[["u_r_px", "v_r_px"]].to_numpy(), ca[:, 0])
    # the spot's flux carries the vignetting: the same beacon's flux with and without the optics
    ratio = (rows["spot_flux_e"] / pd.DataFrame(beacon_rows(a))["spot_flux_e"])[rows["visible"]]
    np.testing.assert_allclose(ratio, seen["vignetting"], rtol=1e-9)


def test_manifest_block_holds_the_fixed_kernels_and_each_camera_lens() -> None:
    optics = OpticsSpec(diffraction=True, f_number=2.0, pixel_pitch_um=2.0, glare_fraction=0.02)
    block = optics_block(optics, {"cam": CAMERA})
    lens = cast("dict[str, dict[str, float]]", block["cameras"])["cam"]
    assert lens["focal_length_mm"] == pytest.approx(600.0 * 2.0e-3)  # fx x pitch
    assert lens["aperture_mm"] == pytest.approx(600.0 * 2.0e-3 / 2.0)  # f / N
    kernels = cast("list[list[list[float]]]", block["airy_kernels"])
    assert len(kernels) == 3
    for k, w in zip(kernels, optics.wavelength_nm):
        np.testing.assert_allclose(np.array(k), airy_kernel(w, optics), atol=1e-9)  # stored rounded to 1e-9
    assert block["glare_kernel_size_px"] == 2 * math.ceil(8 * optics.glare_radius_px) + 1


def test_a_mono_sensor_sees_the_channels_mean_of_the_optical_spot() -> None:
    optics = OpticsSpec(diffraction=True, f_number=8.0, pixel_pitch_um=1.0, lateral_ca_ppm=(1500.0, -1200.0))
    _, lensed, _ = _splats(optics)
    rgb_light = _light(lensed)
    grey = np.zeros((CAMERA.height_px, CAMERA.width_px, 1), np.float32)
    add_splats(grey, lensed)
    # the grey pixel is the mean of the three channels' light (as for a plain splat, rgb.mean() x patch)
    np.testing.assert_allclose(grey[..., 0], rgb_light.mean(axis=2), rtol=1e-5, atol=1e-7 * rgb_light.max())
