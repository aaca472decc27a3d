"""Sub-pixel ground truth: a noise-free beacon's intensity-weighted centroid lies on its projection.

The centroid is measured on the final quantised image (beacons minus the same frame
rendered without beacons), and compared with :func:`deckpose.projection.project_layout`,
an independent computation. Requirement: within 0.02 px.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from deckpose.render.beacons import beacon_splats
from deckpose.render.config import Lighting, SensorSpec
from deckpose.render.lens import distort, raster_camera
from deckpose.render.scene import radiance_scale
from deckpose.render.sensor import expose

from deckpose.camera import CameraModel
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

from .conftest import tiny_config

#: Required accuracy of a rendered beacon's centroid, px (issue requirement).
CENTROID_PX = 0.02


def _centroids(diff: np.ndarray, points_px: np.ndarray, half: int) -> np.ndarray:
    out = np.full_like(points_px, np.nan)
    H, W = diff.shape
    for i, (u, v) in enumerate(points_px):
        c0, r0 = round(u) - half, round(v) - half
        if c0 < 0 or r0 < 0 or c0 + 2 * half >= W or r0 + 2 * half >= H:
            continue
        win = diff[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1]
        vv, uu = np.mgrid[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1]
        out[i] = [(win * uu).sum() / win.sum(), (win * vv).sum() / win.sum()]
    return out


#: (bit depth, beacon peak radiance, tolerance px). Unsaturated 16-bit isolates the renderer's
#: anti-aliasing: the issue's 0.02 px applies. A saturated core (the default peak 6, or 40x full
#: well) has a clipped plateau whose sharp rim aliases, and the deck texture under it differs
#: left/right; 8-bit quantisation adds its own share. Those are sensor effects, measured
#: (0.02-0.04 px here) and bounded more loosely so a regression still fails.
CASES = [(16, 0.5, CENTROID_PX), (16, 6.0, 0.04), (8, 6.0, 0.05), (16, 40.0, 0.04)]


@pytest.mark.parametrize(("bit_depth", "peak", "tol"), CASES)
@pytest.mark.parametrize("distorted", [False, True])
def test_noise_free_centroid_matches_projection(egl_renderer_factory, bit_depth: int, peak: float,
                                                tol: float, distorted: bool) -> None:
    cfg = tiny_config()
    base = CameraModel(640, 480, [[520.0, 0, 317.3], [0, 515.0, 242.6], [0, 0, 1]],
                       [-0.15, 0.04, 0.001, -0.0007, 0.0] if distorted else [])
    sensor = dataclasses.replace(cfg.sensor, noise=False, bit_depth=bit_depth, beacon_peak=peak)
    renderer = egl_renderer_factory(cfg)
    errors = []
    for ship in (ShipPose(0.07, -0.05, 0.4, 0.3, 0.4, -0.6), ShipPose(-0.1, 0.08, -1.0, -0.5, -1.2, 0.9)):
        cam_pose = CameraPose.nadir(30.0)
        raster = distort(renderer.render(raster_camera(base), cam_pose, ship, 0.0, Lighting.NIGHT), base)
        scale = radiance_scale(Lighting.NIGHT, cfg.scene.shading)
        splats = beacon_splats(cfg.layout, (ship,), cam_pose, base, sensor)
        rng = np.random.default_rng(0)
        with_b = expose(raster, scale, splats, sensor, rng).astype(float).sum(axis=2)
        without = expose(raster, scale, [], sensor, rng).astype(float).sum(axis=2)
        proj = project_layout(cfg.layout, ship, cam_pose, base)
        c = _centroids(with_b - without, proj.points_px, half=40)
        ok = proj.visible & np.isfinite(c[:, 0])
        assert ok.sum() >= 10
        errors.append(np.linalg.norm(c[ok] - proj.points_px[ok], axis=1))
    err = np.concatenate(errors)
    print(f"\ncentroid error ({bit_depth}-bit, peak {peak}, distorted={distorted}): max {err.max():.4f} px, "
          f"rms {np.sqrt((err ** 2).mean()):.4f} px over {err.size} beacons")
    assert err.max() < tol


@pytest.mark.parametrize("color", ["rgb", "mono"])
def test_spot_record_matches_the_rendered_spot(egl_renderer_factory, color: str) -> None:
    """Flux, width, background and peak recorded per beacon agree with the pixels themselves.

    Measured independently on a noise-free, unsaturated 16-bit frame without halo: the
    beacon's electrons are (frame with beacons - frame without) / gain summed over a
    window and the channels; its width is det(second-moment matrix)**(1/4) of that
    difference (point-sampled Gaussian: no pixel term); the background is the frame
    without beacons near the centre.
    """
    from deckpose.render.sensor import spot_record

    cfg = tiny_config()
    cam = CameraModel(640, 480, [[520.0, 0, 317.3], [0, 515.0, 242.6], [0, 0, 1]])
    sensor = dataclasses.replace(cfg.sensor, noise=False, bit_depth=16, beacon_peak=0.3,
                                 halo_fraction=0.0, color=color)
    renderer = egl_renderer_factory(cfg)
    ship, cam_pose = ShipPose(0.07, -0.05, 0.4), CameraPose.nadir(30.0)
    raster = renderer.render(cam, cam_pose, ship, 0.0, Lighting.NIGHT)
    scale = radiance_scale(Lighting.NIGHT, cfg.scene.shading)
    splats = beacon_splats(cfg.layout, (ship,), cam_pose, cam, sensor)
    rng = np.random.default_rng(0)
    with_b = expose(raster, scale, splats, sensor, rng).astype(float)
    without = expose(raster, scale, [], sensor, rng).astype(float)
    if color == "mono":
        with_b, without = with_b[..., None], without[..., None]
    gain = (2 ** 16 - 1) / sensor.full_well_e
    rec = spot_record(raster, scale, splats, sensor, cfg.layout.n_beacons)
    proj = project_layout(cfg.layout, ship, cam_pose, cam)
    assert np.all(rec.peak_e[proj.visible] < sensor.full_well_e)  # unsaturated, as the test needs
    checked = 0
    for i in np.flatnonzero(proj.visible):
        u, v = proj.points_px[i]
        c0, r0, half = round(u) - 25, round(v) - 25, 25
        if c0 < 0 or r0 < 0 or c0 + 2 * half >= 640 or r0 + 2 * half >= 480:
            continue
        win = np.s_[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1]
        diff = (with_b[win] - without[win]) / gain
        d = diff.sum(axis=2)
        vv, uu = np.mgrid[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1]
        du, dv = uu - u, vv - v
        m = np.array([[(d * du * du).sum(), (d * du * dv).sum()],
                      [(d * du * dv).sum(), (d * dv * dv).sum()]]) / d.sum()
        assert d.sum() == pytest.approx(rec.flux_e[i], rel=2e-3)
        assert np.linalg.det(m) ** 0.25 == pytest.approx(rec.sigma_px[i], rel=5e-3)
        near = np.hypot(du, dv) <= 2 * rec.sigma_px[i]
        assert (without[win].sum(axis=2) / gain)[near].mean() == pytest.approx(
            rec.background_e[i], rel=0.05, abs=2.0)
        assert with_b[win].max() / gain == pytest.approx(rec.peak_e[i], rel=5e-3, abs=2.0)
        checked += 1
    assert checked >= 8


def test_splat_peak_flux_scales_with_disc_area() -> None:
    """A disc twice as far away delivers a quarter of the flux (inverse-square through J)."""
    cfg = tiny_config()
    cam = CameraModel(640, 480, [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    sensor = SensorSpec(halo_fraction=0.0)
    f20 = [s.patch.sum() for s in beacon_splats(cfg.layout, (ShipPose(),), CameraPose.nadir(20.0), cam, sensor)]
    f40 = [s.patch.sum() for s in beacon_splats(cfg.layout, (ShipPose(),), CameraPose.nadir(40.0), cam, sensor)]
    np.testing.assert_allclose(np.array(f20) / np.array(f40), 4.0, rtol=1e-3)




@pytest.mark.parametrize(("bit_depth", "color"), [(8, "rgb"), (12, "mono"), (16, "rgb")])
def test_sensor_noise_statistics(bit_depth: int, color: str) -> None:
    """Flat grey field: mean and variance in DN follow signal and shot + read noise; saturation clips."""
    from deckpose.render.sensor import expose

    sensor = SensorSpec(bit_depth=bit_depth, color=color, full_well_e=10000.0, read_noise_e=20.0)
    raster = np.full((200, 300, 3), 100, np.uint8)
    scale = np.full(3, 1.0 / 255.0, np.float32)
    img = expose(raster, scale, [], sensor, np.random.default_rng(5)).astype(float)
    assert img.shape == ((200, 300) if color == "mono" else (200, 300, 3))
    dn_max = 2 ** bit_depth - 1
    e = 100 / 255 * 10000.0
    want_mean = e / 10000.0 * dn_max
    want_sd = np.sqrt(e + 400.0) / 10000.0 * dn_max
    assert img.mean() == pytest.approx(want_mean, rel=2e-3)
    if bit_depth > 8:  # 8-bit quantisation (1 DN) dominates sigma there
        assert img.std() == pytest.approx(want_sd, rel=0.03)
    bright = expose(np.full((10, 10, 3), 255, np.uint8), scale * 2, [], sensor, np.random.default_rng(0))
    assert bright.max() == dn_max and bright.min() > 0.9 * dn_max
