"""Optics beyond a Gaussian (:mod:`deckpose.render.optics`) against independent computations.

Each expected value is computed here again from its law: the thin-lens blur from the lens
equation and similar triangles, the Airy profile from ``scipy.special.j1`` integrated
over pixels on a finer grid, chromatic aberration from the magnification written out,
vignetting from the angle between the optical axis and the pixel's ray, blooming from
charge bookkeeping, the Cramér–Rao bound from images built and differentiated by brute
force. Spots are exposed noise-free onto a black raster, so the image is the model's light.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.render.beacons import Splat, add_splats, beacon_splats
from deckpose.render.config import OpticsSpec, SensorSpec
from deckpose.render.optics import (
    airy_first_zero_px,
    airy_kernel,
    apply_optics,
    defocus_diameter_px,
)
from deckpose.render.sensor import expose
from scipy.special import j1, jn_zeros

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

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


def _image(splats: list[Splat], sensor: SensorSpec = SENSOR, gain=None) -> np.ndarray:
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    img = expose(raster, np.ones(3, np.float32), splats, sensor, np.random.default_rng(0), gain)
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
