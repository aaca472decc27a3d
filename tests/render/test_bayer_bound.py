"""The centroid bound behind a colour filter array (render/spot_bound.py, ``sensor.bayer``).

Each photosite of a Bayer sensor collects its own filter's channel only, so a spot's
information is that of the mosaic, not of the full-resolution channel sum the bound took
before (optimistic: the README said so). Checked against a brute-force Fisher information
written here (the mosaic of a Gaussian drawn per channel, derivatives by central
differences, each photosite's variance its own), and against the photon-limited shares of
a wide spot: a white spot's photons split evenly over the channels and a filter passes one
of them, so a photosite collects a third of them, and the bound grows by sqrt(3); a red
spot is seen by the red quarter of the photosites only, and the bound doubles.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from deckpose.render.beacons import spot_splat
from deckpose.render.config import SensorSpec
from deckpose.render.sensor_config import BayerPattern
from deckpose.render.split_kernels import NO_PARTS
from deckpose.render.spot_bound import spot_crb_px

from deckpose.camera import CameraModel

CAM = CameraModel(64, 64, [[100.0, 0, 32.0], [0, 100.0, 32.0], [0, 0, 1]])


def _sensor(pattern: BayerPattern, read_noise_e: float, bit_depth: int = 12) -> SensorSpec:
    return SensorSpec(bit_depth=bit_depth, noise=False, full_well_e=15000.0, read_noise_e=read_noise_e,
                      halo_fraction=0.0, color="rgb", bayer=pattern)


def _bound(centre: tuple[float, float], sigma_px: float, flux: float, rgb: tuple[float, float, float],
           sensor: SensorSpec, background_e: float) -> float:
    base = spot_splat([(np.array(centre), sigma_px**2 * np.eye(2), flux)], rgb, sensor, CAM, 0)
    assert base is not None
    return spot_crb_px(base, NO_PARTS, 1.0, background_e, sensor)


def _sites(pattern: BayerPattern, n: int) -> np.ndarray:
    """Each pixel's filter (0 R, 1 G, 2 B), written out from the pattern's name."""
    names = pattern.value.upper()
    site = np.empty((n, n), int)
    for dy in range(2):
        for dx in range(2):
            site[dy::2, dx::2] = "RGB".index(names[2 * dy + dx])
    return site


def _brute_force_bound(mosaic: Callable[[float, float, float], np.ndarray], centre: tuple[float, float],
                       s: float, flux: float, site: np.ndarray, bg: float) -> float:
    """The centre's per-axis bound from ``mosaic(u, v, sigma)`` (electrons a photosite), derivatives
    by central differences; nuisances: the width, the flux and a background per channel."""
    h = 1e-4
    cu, cv = centre
    spot = mosaic(cu, cv, s)
    grads = [(mosaic(cu + h, cv, s) - mosaic(cu - h, cv, s)) / (2 * h),
             (mosaic(cu, cv + h, s) - mosaic(cu, cv - h, s)) / (2 * h),
             (mosaic(cu, cv, s + h) - mosaic(cu, cv, s - h)) / (2 * h), spot / flux]
    grads += [(site == c).astype(float) for c in range(3)]  # a background per channel
    gain = 4095 / 15000.0
    var = spot + bg / 3 + 4.0**2 + 1 / (12 * gain**2)
    info = np.array([[float(np.sum(gi * gj / var)) for gj in grads] for gi in grads])
    return math.sqrt(np.trace(np.linalg.inv(info)[:2, :2]) / 2)


@pytest.mark.parametrize("pattern", [BayerPattern.RGGB, BayerPattern.GRBG])
@pytest.mark.parametrize("rgb", [(1.0, 1.0, 1.0), (1.0, 0.1, 0.05)])
def test_mosaic_bound_against_brute_force(pattern: BayerPattern, rgb: tuple[float, float, float]) -> None:
    sensor = _sensor(pattern, read_noise_e=4.0)
    centre, s, flux, bg = (30.37, 29.81), 1.3, 0.02, 30.0
    got = _bound(centre, s, flux, rgb, sensor, bg)
    # brute force: the channels' Gaussians sampled at pixel centres (as the renderer draws a
    # spot), each photosite keeping its filter's channel; the filter layout written out from
    # the pattern's name
    n = 64
    site = _sites(pattern, n)
    e = 15000.0  # electrons per unit radiance and channel
    w = np.asarray(rgb)[site]  # the photosite's share of the colour
    yy, xx = np.mgrid[0:n, 0:n].astype(float)

    def mosaic(cu: float, cv: float, ss: float) -> np.ndarray:
        g = np.exp(-0.5 * ((xx - cu) ** 2 + (yy - cv) ** 2) / ss**2) / (2 * math.pi * ss**2)
        return flux * e * w * g

    want = _brute_force_bound(mosaic, centre, s, flux, site, bg)
    # the bound's 6-sigma window against the whole 64 px frame (light beyond 6 sigma: e^-18): 0.1 %
    assert got == pytest.approx(want, rel=1e-3)


def test_photon_limited_shares_of_a_wide_spot() -> None:
    # A wide spot (sigma 3 px: the sub-lattices sample it as finely as the full grid), no
    # background, no read noise, 16-bit quantisation (1e-3 e^2 against 1e4 e a pixel): the
    # information of each channel's photosites is their share of the pixels times the channel's
    # photons, so the bound against the channel sum's is sqrt(3) for a white spot (three equal
    # channels, a third of each reaching a photosite) and 2 for a red one; to 1 %.
    plain = _sensor(BayerPattern.NONE, read_noise_e=0.0, bit_depth=16)
    bayer = dataclasses.replace(plain, bayer=BayerPattern.RGGB)
    for rgb, want in (((1.0, 1.0, 1.0), math.sqrt(3.0)), ((1.0, 0.0, 0.0), 2.0)):
        ratio = (_bound((31.4, 30.8), 3.0, 1.0, rgb, bayer, 0.0)
                 / _bound((31.4, 30.8), 3.0, 1.0, rgb, plain, 0.0))
        assert ratio == pytest.approx(want, rel=1e-2), (rgb, ratio)


def test_without_a_filter_array_the_bound_is_unchanged() -> None:
    # The channel sum's bound, as before (the optics tests hold it against the analytic one):
    # the Bayer path is taken only with a pattern, and it is larger with one.
    plain = _sensor(BayerPattern.NONE, read_noise_e=4.0)
    b0 = _bound((30.2, 29.7), 1.2, 0.02, (1.0, 1.0, 1.0), plain, 30.0)
    b1 = _bound((30.2, 29.7), 1.2, 0.02, (1.0, 1.0, 1.0), dataclasses.replace(plain, bayer=BayerPattern.BGGR), 30.0)
    assert np.isfinite(b0) and b1 > 1.3 * b0


def test_a_bayer_frame_without_optics_records_the_mosaic_bound(egl_renderer_factory) -> None:
    # Without optics a Bayer frame's beacons.parquet carries the mosaic's bound (with the
    # identity lens: no defocus, vignetting 1, every channel at the projection), which the
    # benchmark uses instead of the channel sum's Gaussian bound; an RGB frame without a
    # filter array keeps no bound column, as before.
    import pandas as pd
    from deckpose.detect.benchmark import crb_per_beacon
    from deckpose.detect.synthetic import SensorModel
    from deckpose.render.config import config_from_dict
    from deckpose.render.frame import beacon_rows, render_frame
    from deckpose.render.plan import plan_frames

    from .conftest import tiny_doc

    doc = tiny_doc(heights_m=[30.0], lighting=["night"], cameras=[{"preset": "8mp-square", "size": [320, 180]}],
                   sensor={"bit_depth": 12, "read_noise_e": 4, "full_well_e": 15000, "color": "rgb"})
    plain = config_from_dict(doc)
    bayer = config_from_dict({**doc, "sensor": {**doc["sensor"], "bayer": "rggb"}})
    spec = plan_frames(plain)[0]
    cam = plain.cameras_by_name()[spec.camera_name]
    renderer = egl_renderer_factory(plain)
    a, b = (pd.DataFrame(beacon_rows(render_frame(cfg, spec, cam, renderer))) for cfg in (plain, bayer))
    assert a["spot_crb_px"].isna().all()
    seen = b[b["visible"]]
    assert len(seen) > 3 and (seen["spot_crb_px"] > 0).all()
    assert (seen["defocus_px"] == 0).all() and (seen["vignetting"] == 1).all()
    np.testing.assert_allclose(seen[["u_r_px", "v_r_px"]].to_numpy(), seen[["u_px", "v_px"]].to_numpy())
    # against the channel sum's Gaussian bound of the same spots (what the benchmark used before):
    # larger by about sqrt(3) for the white beacons and 2 for the red bow, the photosites' shares
    # (measured 1.68 and 1.95: the spots' halo and the night sea's background and read noise are
    # not photon-limited, and a spot of sigma ~1 px is sampled coarsely by a sub-lattice: 10 %)
    sensor = SensorModel(gain_dn_per_e=4095 / 15000, read_noise_e=4.0)
    gauss = np.sqrt(crb_per_beacon(seen.drop(columns="spot_crb_px"), sensor))
    ratio = seen["spot_crb_px"].to_numpy() / gauss
    bow = (seen["beacon_id"] == bayer.layout.bow_id).to_numpy()
    assert bow.sum() == 1
    np.testing.assert_allclose(ratio[~bow], math.sqrt(3.0), rtol=0.1)
    np.testing.assert_allclose(ratio[bow], 2.0, rtol=0.1)


@pytest.mark.parametrize("pattern", [BayerPattern.RGGB, BayerPattern.GBRG])
def test_mosaic_bound_through_a_lens_against_brute_force(pattern: BayerPattern) -> None:
    """Through per-channel kernels of odd radius (discs of three sizes, red and blue shifted as
    lateral colour shifts them): each photosite keeps its filter's channel of that channel's
    convolved image, the mosaic's phase taken from the image's own rows and columns."""
    from deckpose.render.psf_kernels import convolve_kernels, disk_kernel, shift_kernel
    from deckpose.render.split_kernels import KernelParts
    from scipy.signal import convolve2d

    sensor = _sensor(pattern, read_noise_e=4.0)
    centre, s, flux, bg, rgb = (40.37, 39.81), 1.3, 0.02, 30.0, (1.0, 0.6, 0.3)
    kernels = (convolve_kernels(disk_kernel(5.0), shift_kernel(np.array([0.4, -0.3]), 2)),
               disk_kernel(7.0),
               convolve_kernels(disk_kernel(9.0), shift_kernel(np.array([-0.4, 0.3]), 2)))
    assert max(k.shape[0] // 2 for k in kernels) % 2 == 1  # an odd radius: a wrong phase would show
    base = spot_splat([(np.array(centre), s**2 * np.eye(2), flux)], rgb, sensor, CAM, 0)
    assert base is not None
    got = spot_crb_px(base, KernelParts.from_kernels(kernels), 1.0, bg, sensor)
    n = 80
    site = _sites(pattern, n)
    e = 15000.0
    yy, xx = np.mgrid[0:n, 0:n].astype(float)

    def mosaic(cu: float, cv: float, ss: float) -> np.ndarray:
        g = np.exp(-0.5 * ((xx - cu) ** 2 + (yy - cv) ** 2) / ss**2) / (2 * math.pi * ss**2)
        out = np.zeros((n, n))
        for c in range(3):  # 'same': the kernel centred on each pixel, image coordinates kept
            out += (site == c) * rgb[c] * convolve2d(g, kernels[c], mode="same")
        return flux * e * out

    want = _brute_force_bound(mosaic, centre, s, flux, site, bg)
    assert got == pytest.approx(want, rel=2e-5)
