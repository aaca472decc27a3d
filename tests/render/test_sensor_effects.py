"""Sensor effects against independent computations: Bayer, JPEG, fixed pattern, auto-exposure.

Each expected value is computed here from the effect's definition written out again
(the colour filter layout letter by letter, the JPEG quantisation tables of the
standard, the sample statistics of a Gaussian map, the clipped mean of a histogram
done with numpy on the image itself), not from the renderer's intermediate values.
Images are exposed noise-free at 16 bits where a law is checked, so that rounding
(+-0.5 DN) is the only other error.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from deckpose.render.auto_exposure import metered_exposure
from deckpose.render.bayer import demosaic, filter_channels, select_mosaic
from deckpose.render.beacons import beacon_splats
from deckpose.render.compression import jpeg_round_trip
from deckpose.render.config import AutoExposureSpec, BayerPattern, SensorSpec, config_from_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.fixed_pattern import _cached_pattern, fixed_pattern, hot_pixel_table
from deckpose.render.frame import frame_row, render_frame
from deckpose.render.plan import plan_frames
from deckpose.render.sensor import expose

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

from .conftest import tiny_doc

FLAT16 = SensorSpec(bit_depth=16, noise=False, full_well_e=60000.0)
LAYOUTS = {"rggb": "RGGB", "bggr": "BGGR", "grbg": "GRBG", "gbrg": "GBRG"}  # top-left 2x2, row by row
CH = {"R": 0, "G": 1, "B": 2}


def _written_mosaic(rgb: np.ndarray, layout: str) -> np.ndarray:
    """Keep each pixel's channel by the layout's letters: (even, even) = layout[0], (even, odd) = [1] ..."""
    out = np.empty(rgb.shape[:2], rgb.dtype)
    for r in range(rgb.shape[0]):
        for c in range(rgb.shape[1]):
            out[r, c] = rgb[r, c, CH[layout[2 * (r % 2) + c % 2]]]
    return out


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_filter_channel_per_pixel_is_the_layout_written_out(name: str) -> None:
    pattern = BayerPattern(name)
    rgb = np.random.default_rng(1).random((7, 9, 3)).astype(np.float32)
    want = _written_mosaic(rgb, LAYOUTS[name])
    got = np.empty((7, 9), np.float32)
    select_mosaic(rgb, pattern, 0, got)
    np.testing.assert_array_equal(got, want)
    # a strip starting on an odd image row takes the pattern's second row first
    got_odd = np.empty((6, 9), np.float32)
    select_mosaic(rgb[1:], pattern, 1, got_odd)
    np.testing.assert_array_equal(got_odd, want[1:])
    ch = filter_channels(pattern, 7, 9)
    np.testing.assert_array_equal(np.take_along_axis(rgb, ch[..., None], axis=2)[..., 0], want)


@pytest.mark.parametrize("name", list(LAYOUTS))
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_demosaic_of_a_flat_field_written_out_returns_it(name: str, dtype: type) -> None:
    """OpenCV's Bayer names are shifted by a pixel: the code chosen for each layout restores a flat colour."""
    colour = np.array([200, 100, 50], dtype)
    mosaic = _written_mosaic(np.broadcast_to(colour, (10, 12, 3)), LAYOUTS[name])
    out = demosaic(mosaic, BayerPattern(name))
    assert out.dtype == dtype and out.shape == (10, 12, 3)
    np.testing.assert_array_equal(out, np.broadcast_to(colour, out.shape))  # borders included


def test_bayer_expose_is_the_written_mosaic_demosaiced_and_a_flat_field_comes_back() -> None:
    """expose() with a Bayer sensor equals: mean image (raster x scale x exposure, in DN), keep the
    layout's channel, round, demosaic. 1000 px wide: 87-row strips, so strips start on odd rows too."""
    H, W = 200, 1000
    raster = np.random.default_rng(2).integers(0, 256, (H, W, 3), dtype=np.uint8)
    scale = np.array([0.9, 0.7, 0.5], np.float32) / 255.0
    sensor = dataclasses.replace(FLAT16, exposure=1.3, bayer=BayerPattern.GRBG)
    got = expose(raster, scale, [], sensor, np.random.default_rng(0))
    mean_dn = raster * (scale.astype(np.float64) * 1.3 * 65535.0)  # e- x DN/e = exposure x full scale
    mosaic = np.clip(np.rint(_written_mosaic(mean_dn, "GRBG")), 0, 65535).astype(np.uint16)
    diff = np.abs(got.astype(np.int64) - cv2.cvtColor(mosaic, cv2.COLOR_BayerGB2RGB))
    # expose's float32 mean (the DN per raster unit rounded to float32, then the product: two
    # roundings) is off by <= 2**-23 of at most 255 x 0.9 x 1.3 x 65535 / 255 = 76 676 DN, i.e.
    # 0.0092 DN: a value within that of a half DN may round the other way, by 1 DN; with the
    # fractional parts spread evenly that is at most 2 x 0.0092 = 1.8 % of the values
    assert diff.max() <= 1 and diff.mean() < 0.02
    flat = np.full((H, W, 3), (180, 90, 30), np.uint8)
    for name in LAYOUTS:
        bayer = expose(flat, scale, [], dataclasses.replace(FLAT16, bayer=BayerPattern(name)),
                       np.random.default_rng(0))
        np.testing.assert_array_equal(bayer, expose(flat, scale, [], FLAT16, np.random.default_rng(0)))


def _centroid(img: np.ndarray) -> np.ndarray:
    vv, uu = np.mgrid[: img.shape[0], : img.shape[1]]
    return np.array([(img * uu).sum(), (img * vv).sum()]) / img.sum()


@pytest.mark.parametrize(("height_m", "psf_sigma_px"), [(30.0, 0.8), (80.0, 0.6)])
def test_red_bow_centroid_after_bayer_and_demosaic(height_m: float, psf_sigma_px: float) -> None:
    """Bilinear demosaicing convolves each channel's samples with a symmetric kernel of sum
    1/density, so the channel-sum centroid is that of the samples weighted by 1/density
    (computed here from the splat's patch on each lattice); that differs from the true centre
    by the aliasing of a Gaussian of sigma s on the 2-px red lattice, at most
    (4 pi s^2 / 2) exp(-pi^2 s^2 / 2) per axis (Poisson summation, first harmonic)."""
    cam = CameraModel(1280, 960, [[900.0, 0, 640.3], [0, 900.0, 480.6], [0, 0, 1]])
    sensor = dataclasses.replace(FLAT16, beacon_peak=0.3, psf_sigma_px=psf_sigma_px, halo_fraction=0.0)
    layout = DeckLayout()
    ship = ShipPose(0.03, -0.02, 0.4, 0, 0, 0)
    splats = beacon_splats(layout, (ship,), CameraPose.nadir(height_m), cam, sensor)
    bow = next(sp for sp in splats if sp.beacon_id == layout.bow_id)
    black = np.zeros((cam.height_px, cam.width_px, 3), np.uint8)
    img = expose(black, np.ones(3, np.float32), [bow], dataclasses.replace(sensor, bayer=BayerPattern.RGGB),
                 np.random.default_rng(0)).astype(float)
    assert img.max() < 65535  # unsaturated
    n = bow.patch.shape[0]
    r0, c0 = bow.row0 - 2, bow.col0 - 2  # the demosaic kernel reaches one pixel beyond the patch
    win = img[r0:r0 + n + 4, c0:c0 + n + 4].sum(axis=2)
    got = _centroid(win) + (c0, r0)
    # the samples: patch x colour on each channel's lattice, weighted by 1 / density (R, B: 4; G: 2)
    rows, cols = np.mgrid[bow.row0:bow.row0 + n, bow.col0:bow.col0 + n]
    letter = np.array(list("RGGB"))[2 * (rows % 2) + cols % 2]
    weight = np.where(letter == "G", 2.0, 4.0) * np.array([float(bow.rgb[CH[x]]) for x in letter.ravel()]).reshape(n, n)
    samples = bow.patch * weight
    want = _centroid(samples) + (bow.col0, bow.row0)
    # 16-bit rounding: +-0.5 DN a pixel over a spot of >= 1e4 DN moves the centroid < 1e-3 px
    np.testing.assert_allclose(got, want, atol=1e-3)
    s = math.sqrt(np.linalg.eigvalsh(bow.cov_px2)[0])
    bound = 4 * math.pi * s * s / 2 * math.exp(-math.pi ** 2 * s * s / 2)
    err = np.abs(got - bow.centre_px)
    assert np.all(err <= bound + 1e-3), (err, bound, s)


def _ijg_quant_table(quality: int) -> np.ndarray:
    """The standard's luminance table (ITU T.81 Annex K) scaled as libjpeg scales it for ``quality``."""
    t = np.array([16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
                  14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
                  92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99], float)
    scale = 5000.0 / quality if quality < 50 else 200.0 - 2.0 * quality
    return np.clip(np.floor((t * scale + 50.0) / 100.0), 1, 255)


@pytest.mark.parametrize("quality", [30, 75, 95])
def test_jpeg_error_per_block_within_the_quantisation_bound(quality: int) -> None:
    """Each DCT coefficient is rounded to a multiple of its table entry Q (error <= Q/2); the DCT is
    orthonormal, so a block's RMS pixel error is at most sqrt(mean(Q^2))/2, plus 1 DN for the
    integer DCT/IDCT and the final rounding. A grey frame has no chroma subsampling."""
    rng = np.random.default_rng(4)
    yy, xx = np.mgrid[:240, :320]
    grey = np.clip(60 + 0.4 * xx + 30 * np.sin(yy / 9.0) + rng.normal(0, 12, (240, 320)), 0, 255).astype(np.uint8)
    out = jpeg_round_trip(grey, quality)
    assert out.dtype == np.uint8 and out.shape == grey.shape
    err = (out.astype(float) - grey).reshape(30, 8, 40, 8).transpose(0, 2, 1, 3).reshape(30, 40, 64)
    rms = np.sqrt((err ** 2).mean(axis=2))
    bound = math.sqrt((_ijg_quant_table(quality) ** 2).mean()) / 2 + 1.0
    assert rms.max() <= bound, (rms.max(), bound)
    assert rms.mean() > 0.1  # and it is lossy: the noise texture cannot pass unchanged
    rgb = np.dstack([grey, grey[::-1], grey[:, ::-1]])
    out_rgb = jpeg_round_trip(rgb, quality)
    assert out_rgb.dtype == np.uint8 and out_rgb.shape == rgb.shape
    # channel order kept: each channel's error is far below the difference between channels
    for c in range(3):
        assert np.abs(out_rgb[..., c].astype(float) - rgb[..., c]).mean() < 0.5 * np.abs(
            rgb[..., c].astype(float) - rgb[..., (c + 1) % 3]).mean()


def _flat(level: int = 128, shape: tuple[int, int] = (480, 640)) -> np.ndarray:
    return np.full((*shape, 3), level, np.uint8)


def test_prnu_is_fixed_per_camera_and_has_the_configured_sigma() -> None:
    """Two frames of a camera (different frame seeds, noise on) share their pixel-to-pixel
    pattern; another camera's is uncorrelated. Noise-free, the relative deviation's sample std is
    prnu within 5 standard errors (sigma / sqrt(2 N)) plus rounding (0.3 DN on 3e4 DN: 1e-5)."""
    H, W, prnu = 480, 640, 0.05
    sensor = dataclasses.replace(SensorSpec(bit_depth=16, full_well_e=60000.0, read_noise_e=3.0), prnu=prnu)
    scale = np.full(3, 1 / 255, np.float32)
    a = fixed_pattern(sensor, 7, "cam-a", H, W)
    _cached_pattern.cache_clear()
    assert a is not None and a.gain is not None
    a2 = fixed_pattern(sensor, 7, "cam-a", H, W)
    b = fixed_pattern(sensor, 7, "cam-b", H, W)
    assert a2 is not None and a2.gain is not None and b is not None and b.gain is not None
    np.testing.assert_array_equal(a.gain, a2.gain)  # drawn again from the seed and the name
    flat = _flat()
    base = expose(flat, scale, [], dataclasses.replace(sensor, noise=False, prnu=0.0), np.random.default_rng(0))
    resid = [expose(flat, scale, [], sensor, np.random.default_rng(s), pattern=p)[..., 1].astype(float)
             - base[..., 1] for s, p in ((1, a), (2, a2), (3, b))]
    n = H * W
    # PRNU 5 % against shot noise sqrt(3e4 e)/3e4 = 0.6 %: same pattern -> corr ~ 0.99
    assert np.corrcoef(resid[0].ravel(), resid[1].ravel())[0, 1] > 0.95
    assert abs(np.corrcoef(resid[0].ravel(), resid[2].ravel())[0, 1]) < 5 / math.sqrt(n)
    quiet = expose(flat, scale, [], dataclasses.replace(sensor, noise=False), np.random.default_rng(0), pattern=a)
    rel = quiet.astype(float) / base - 1.0
    assert np.all(rel[..., 0] == rel[..., 2])  # the channels of a pixel share its gain (to rounding)
    assert np.std(rel[..., 1]) == pytest.approx(prnu, rel=5 / math.sqrt(2 * n) + 1e-3)


def test_dsnu_has_the_configured_sigma_in_electrons() -> None:
    H, W, dsnu = 480, 640, 40.0
    sensor = dataclasses.replace(FLAT16, dsnu_e=dsnu)
    scale = np.full(3, 1 / 255, np.float32)
    p = fixed_pattern(sensor, 3, "cam", H, W)
    assert p is not None and p.gain is None and p.dark_e is not None
    flat = _flat()  # ~3e4 e: the dark map never drives a pixel below 0
    on = expose(flat, scale, [], sensor, np.random.default_rng(0), pattern=p)
    off = expose(flat, scale, [], FLAT16, np.random.default_rng(0))
    dark_e = (on.astype(float) - off)[..., 0] / (65535 / 60000.0)
    # sample std within 5 standard errors; rounding adds 0.27 e RMS (negligible against 40 e)
    assert np.std(dark_e) == pytest.approx(dsnu, rel=5 / math.sqrt(2 * H * W) + 1e-3)
    assert abs(dark_e.mean()) < 5 * dsnu / math.sqrt(H * W)


def test_hot_pixels_lie_at_the_recorded_positions() -> None:
    H, W = 480, 640
    sensor = dataclasses.replace(FLAT16, hot_pixel_fraction=1e-3, hot_pixel_e=5000.0)
    table = hot_pixel_table(sensor, 11, "cam", H, W)
    assert table["u_px"].size == round(1e-3 * H * W)
    p = fixed_pattern(sensor, 11, "cam", H, W)
    assert p is not None
    img = expose(np.zeros((H, W, 3), np.uint8), np.ones(3, np.float32), [], sensor, np.random.default_rng(0),
                 pattern=p)
    rows, cols = np.nonzero(img[..., 0])
    assert set(zip(cols.tolist(), rows.tolist())) == set(zip(table["u_px"].tolist(), table["v_px"].tolist()))
    assert np.all(img[rows, cols] == round(5000.0 * 65535 / 60000.0))
    other = hot_pixel_table(sensor, 11, "cam-2", H, W)
    assert not np.array_equal(other["u_px"], table["u_px"])


def _day_raster() -> np.ndarray:
    """A deck-like raster: a dim textured half and a bright half that clips at high exposures."""
    rng = np.random.default_rng(5)
    r = rng.integers(20, 90, (240, 320, 3), dtype=np.uint8)
    r[:, 200:] = rng.integers(200, 256, (240, 120, 3), dtype=np.uint8)
    return r


@pytest.mark.parametrize("color", ["rgb", "mono"])
@pytest.mark.parametrize(("target", "percentile"), [(0.18, None), (0.6, None), (0.8, 99.0), (0.3, 50.0)])
def test_auto_exposure_brings_the_metered_statistic_to_the_target(color: str, target: float,
                                                                  percentile: float | None) -> None:
    """The noise-free 16-bit image exposed at the chosen exposure: its mean (clipped values
    included) or its percentile (inverted CDF), over full scale, is the target to rounding
    (0.5 DN / 65535 for the mean; one raster step x scale x exposure for a percentile)."""
    raster = _day_raster()
    scale = np.array([1.0, 0.95, 0.85], np.float32) / 255.0
    ae = AutoExposureSpec(target=target, percentile=percentile, min_exposure=0.01, max_exposure=100.0)
    sensor = dataclasses.replace(FLAT16, color=color)
    e = metered_exposure(raster, scale, sensor, ae)
    img = expose(raster, scale, [], dataclasses.replace(sensor, exposure=e), np.random.default_rng(0)) / 65535.0
    if percentile is None:
        assert img.mean() == pytest.approx(target, abs=1e-5)
        assert (img >= 1.0).any() == (target > 0.5)  # the brighter target clips the bright half
    else:
        assert np.percentile(img, percentile, method="inverted_cdf") == pytest.approx(target, abs=1e-4)


def test_auto_exposure_is_clamped_to_its_limits() -> None:
    scale = np.full(3, 1 / 255, np.float32)
    ae = AutoExposureSpec(target=0.18, min_exposure=0.5, max_exposure=8.0)
    assert metered_exposure(np.zeros((48, 64, 3), np.uint8), scale, FLAT16, ae) == 8.0  # night: longest
    dim = np.full((48, 64, 3), 2, np.uint8)  # 2/255 x 8 = 0.06 < 0.18: still the longest
    assert metered_exposure(dim, scale, FLAT16, ae) == 8.0
    assert metered_exposure(_flat(255, (48, 64)), scale, FLAT16, ae) == 0.5  # would need 0.18
    ae_p = dataclasses.replace(ae, percentile=99.0)
    assert metered_exposure(np.zeros((48, 64, 3), np.uint8), scale, FLAT16, ae_p) == 8.0
    assert metered_exposure(_flat(255, (48, 64)), scale, FLAT16, ae_p) == 0.5


def _sensor_doc(**sensor: object) -> dict[str, object]:
    return tiny_doc(sensor={"bit_depth": 8, "read_noise_e": 5, **sensor})


def test_frame_with_every_effect_is_the_fixed_exposure_frame_compressed(egl_renderer_factory) -> None:
    """With auto-exposure the frame equals the frame rendered at the recorded exposure (same noise,
    same fixed pattern), then JPEG-compressed; the spot model is that of the recorded exposure."""
    effects = {"bayer": "rggb", "prnu": 0.01, "dsnu_e": 5.0, "hot_pixel_fraction": 1e-3}
    cfg = config_from_dict(_sensor_doc(**effects, jpeg_quality=85, auto_exposure={"target": 0.18}))
    spec = plan_frames(cfg)[0]
    cam = cfg.cameras_by_name()[spec.camera_name]
    auto = render_frame(cfg, spec, cam, egl_renderer_factory(cfg))
    assert auto.exposure is not None
    fixed_cfg = config_from_dict(_sensor_doc(**effects, exposure=auto.exposure))
    fixed = render_frame(fixed_cfg, spec, cam, egl_renderer_factory(fixed_cfg))
    np.testing.assert_array_equal(auto.frame.image, jpeg_round_trip(fixed.frame.image, 85))
    np.testing.assert_array_equal(auto.spots.flux_e, fixed.spots.flux_e)
    np.testing.assert_array_equal(auto.spots.peak_e, fixed.spots.peak_e)
    assert frame_row(auto, "x.png")["exposure"] == auto.exposure and "exposure" not in frame_row(fixed, "x.png")


def test_dataset_records_hot_pixels_and_exposures(tmp_path: Path, egl_renderer_factory) -> None:
    doc = _sensor_doc(hot_pixel_fraction=2e-3, hot_pixel_e=15000.0, auto_exposure={"target": 0.2})
    doc.update(heights_m=[25.0], lighting=["night", "day"], motion={"source": "fixed", "attitudes_deg": [[0, 0, 0]]})
    cfg = config_from_dict(doc)
    egl_renderer_factory(cfg)  # this process's GL platform
    out = render_dataset(cfg, tmp_path / "ds", workers=0, progress=False)
    cam = next(iter(cfg.cameras_by_name()))
    hot = pd.read_parquet(out / "cameras" / f"{cam}_hot_pixels.parquet")
    assert len(hot) == round(2e-3 * 320 * 240) and list(hot.columns) == ["u_px", "v_px", "excess_e"]
    frames = pd.read_parquet(out / "frames.parquet")
    night, day = frames.set_index("lighting")["exposure"][["night", "day"]]
    assert night > day  # a dark frame takes a longer exposure
    img = cv2.imread(str(out / frames.set_index("lighting")["image"]["night"]), cv2.IMREAD_UNCHANGED)
    # a hot pixel's 15000 e at 255/20000 DN/e saturates the 8-bit frame where the deck is dark
    assert np.median(img[hot["v_px"], hot["u_px"]].max(axis=1)) == 255


@pytest.mark.parametrize(("sensor", "key"), [
    ({"color": "mono", "bayer": "rggb"}, "sensor.bayer"),
    ({"bayer": "rgbg"}, "sensor.bayer"),
    ({"bit_depth": 12, "jpeg_quality": 80}, "sensor.jpeg_quality"),
    ({"jpeg_quality": 0}, "sensor.jpeg_quality"),
    ({"prnu": 0.8}, "sensor.prnu"),
    ({"dsnu_e": -1.0}, "sensor.dsnu_e"),
    ({"hot_pixel_fraction": 0.5}, "sensor.hot_pixel_fraction"),
    ({"auto_exposure": {"target": 1.5}}, "sensor.auto_exposure.target"),
    ({"auto_exposure": {"min_exposure": 2.0, "max_exposure": 1.0}}, "sensor.auto_exposure"),
    ({"auto_exposure": {"percentile": 101}}, "sensor.auto_exposure.percentile"),
    ({"auto_exposure": {"smoothing": 0.5}}, "sensor.auto_exposure"),
])
def test_config_errors_are_one_line_naming_the_key(sensor: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as info:
        config_from_dict(_sensor_doc(**sensor))
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"config: {key}"), msg  # the file, then the key


def test_effects_are_off_by_default() -> None:
    s = config_from_dict(tiny_doc()).sensor
    assert (s.bayer, s.jpeg_quality, s.prnu, s.dsnu_e, s.hot_pixel_fraction, s.auto_exposure) == (
        BayerPattern.NONE, None, 0.0, 0.0, 0.0, None)
    assert fixed_pattern(s, 0, "cam", 4, 4) is None
