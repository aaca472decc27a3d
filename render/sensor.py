"""The sensor after the lens: distortion, beacon light, exposure, noise, saturation, bit depth.

Order of operations for one frame:

1. the rasterised pinhole image is warped to the distorted image by
   :func:`deckpose.render.lens.distort` (for every distorted pixel, the raster at its ray);
2. beacon splats are added at their *distorted* projected centres (so ground
   truth and image agree, see :mod:`deckpose.render.beacons`);
3. radiance is turned into electrons (``exposure * full_well_e`` for white),
   photon shot noise and read noise are added as one Gaussian of variance
   ``signal + read_noise^2`` (the Poisson law's normal limit; exact enough above
   a few electrons), the well saturates, and the result is quantised to
   ``bit_depth`` bits.

Sensor effects, off by default: with ``sensor.bayer`` each pixel keeps its filter's
channel before the noise and the quantised mosaic is demosaiced
(:mod:`deckpose.render.bayer`); a camera's fixed pattern (:mod:`deckpose.render.fixed_pattern`)
changes each pixel's mean before the noise. Auto-exposure and JPEG act around
:func:`expose` (:mod:`deckpose.render.frame`).

The work is done in horizontal strips of about :data:`STRIP_ELEMENTS` values, so the
float32 work buffers stay in the CPU cache and main memory sees the frame twice: one
read of the raster, one write of the image. A value's mean is its raster value times
its channel's DN per raster unit (one vectorised multiply: 0.32 ns a value of RGB
here against 0.85 ns for the per-channel 256-entry ``cv2.LUT`` it replaced, a gather).
Normal deviates are Box-Muller pairs from OpenCV's uniform generator (``cv2.randu``;
2.4-2.7 ns a value here, 1.5-1.7 of them the uniforms, against 2.7-2.9 ns for
``cv2.randn`` and 10-12 ns for numpy's float32 ``standard_normal`` with SFC64 or PCG64;
SFC64's raw bits made into the same two uniforms save nothing measurable in the strip), seeded once per frame from the frame's
:class:`numpy.random.Generator` and drawn strip after strip, so a frame is a function
of that generator's state and the frame's shape only (not of the number of workers).
OpenCV's generator state is per thread. Since issue 20 the realisation differs from
earlier versions for the same seed; the law (mean and variance at every signal level)
is the same.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from deckpose.render.bayer import demosaic, select_mosaic
from deckpose.render.beacons import Splat, add_splats
from deckpose.render.fixed_pattern import FixedPattern, apply_fixed_pattern
from deckpose.render.sensor_config import BayerPattern, SensorSpec
from numpy.typing import NDArray

#: Float32 values per processing strip: each of its three work buffers (1 MiB) stays in cache.
STRIP_ELEMENTS = 2 ** 18
_LUMA = np.array([0.299, 0.587, 0.114], np.float32)
# cv2.randu bounds as (1,) arrays (OpenCV's stubs take arrays; a scalar works the same)
_U_LOW, _U_HIGH = np.array([-1.0]), np.array([1.0])
_ANGLE_LOW, _ANGLE_HIGH = np.array([0.0]), np.array([2.0 * math.pi])


def _dn_per_raster_unit(scale_e: np.ndarray, dn_per_e: float, width_px: int) -> NDArray[np.float32]:
    """Mean DN per raster unit of each value of a row: (W * C,) float32, channels interleaved."""
    return np.tile((scale_e * dn_per_e).astype(np.float32), width_px)


def strip_rows(width_px: int, channels: int) -> int:
    """Rows per strip of a ``width_px`` x ``channels`` frame (~ :data:`STRIP_ELEMENTS` values)."""
    return max(1, STRIP_ELEMENTS // max(1, width_px * channels))


def _splats_by_strip(splats: list[Splat], rows: int) -> dict[int, list[Splat]]:
    """The splats that reach each strip of ``rows`` rows, keyed by strip index."""
    by_strip: dict[int, list[Splat]] = {}
    for sp in splats:
        first = max(sp.row0, 0) // rows
        last = max(sp.row0 + sp.patch.shape[0] - 1, 0) // rows
        for k in range(first, last + 1):
            by_strip.setdefault(k, []).append(sp)
    return by_strip


def _fill_standard_normal(out: NDArray[np.float32], radius: NDArray[np.float32],
                          angle: NDArray[np.float32]) -> None:
    """Fill ``out`` (2 * n values) with standard normal deviates from OpenCV's uniform stream.

    Box-Muller: ``(r cos t, r sin t)`` with ``r = sqrt(-ln u**2)``, ``|u|`` uniform on
    (0, 1] and ``t`` uniform on [0, 2 pi). ``u`` comes from ``cv2.randu`` on [-1, 1) (an
    int32 times 2**-31), so its square resolves 2**-62 and the radius reaches 6.6 sigma;
    2**-64 is added so that u = 0 (probability 2**-32) gives a finite radius. ``radius``
    and ``angle`` are (1, n) float32 work buffers. Faster than ``cv2.randn`` here: 1.2-1.6
    ns a value against 2.1-2.9 ns at load 4; 2.64 against 2.95 ns, interleaved, at load 6.
    """
    n = radius.shape[1]
    cv2.randu(radius, _U_LOW, _U_HIGH)
    cv2.multiply(radius, radius, dst=radius)
    cv2.addWeighted(radius, 1.0, radius, 0.0, 2.0 ** -64, dst=radius)  # u = 0 reads 2**-64
    cv2.log(radius, dst=radius)
    cv2.addWeighted(radius, -1.0, radius, 0.0, 0.0, dst=radius)
    cv2.sqrt(radius, dst=radius)
    cv2.randu(angle, _ANGLE_LOW, _ANGLE_HIGH)
    cv2.polarToCart(radius, angle, out[:n].reshape(1, n), out[n:2 * n].reshape(1, n))


def expose(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], splats: list[Splat],
           sensor: SensorSpec, rng: np.random.Generator, *, pattern: FixedPattern | None = None,
           background_gain: Callable[[int, int], NDArray[np.float32]] | None = None) -> np.ndarray:
    """Raster plus beacons to a quantised sensor image.

    A pixel (per channel) of mean ``m`` DN reads ``clip(round(m + sigma z), 0, 2**bit_depth - 1)``
    with ``z`` standard normal and ``sigma**2 = g m + (g r)**2`` (shot plus read noise; ``g``
    DN per electron, ``r = read_noise_e``); 12-bit values are clamped at 4095. The
    background's mean is its 8-bit raster value times its channel's DN per raster unit;
    beacon light is added to it in the splat windows, and sigma follows the sum.

    The frame is worked in strips of about :data:`STRIP_ELEMENTS` values whose float32
    buffers stay in the CPU cache: main memory sees the raster read once and the image
    written once. In the strip, each value gets its mean (one multiply), its normal
    deviate (:func:`_fill_standard_normal`, seven OpenCV calls on half a strip each plus
    the cos/sin that writes both halves), its variance (``cv2.addWeighted``) and sigma
    (``cv2.sqrt``), deviate times sigma, and mean plus that, rounded and saturated into
    the output type (``cv2.add(..., dtype=)``).

    Passes over a strip's values (a call over half of them counts 1/2), per path:

    - default (noise on, no optional effect), 8- or 16-bit RGB: 9.5 (13 calls);
    - mono: the same over one value a pixel, plus the grey conversion of the raster strip;
    - 12 bits: + 1 (the clamp at 4095);
    - beacons: the splat windows only (:func:`deckpose.render.beacons.add_splats`);
    - ``background_gain``: + 1; Bayer: + 1 (the mosaic's selection), the noise passes over
      one value a pixel, and the demosaicing of the image; fixed pattern: + 1 (gain),
      + 2 (dark signal and the clamp at 0), RGB + 1 each (the map merged over channels);
    - noise off: 2 (mean, rounded conversion).

    Issue 20 asked for five; the five-pass model (sigma from a per-channel ``cv2.LUT`` of
    the raster value, ``cv2.randn``, ``cv2.accumulateProduct``, conversion) measured 20 %
    slower (reports/throughput/sensor.txt, 2026-12-07): a 3-channel table gather costs
    twice ``addWeighted`` + ``sqrt``, and ``cv2.randn`` more than the Box-Muller deviate.

    Parameters
    ----------
    raster : (H, W, 3) array of uint8
        Rasterised (and distorted) deck and sea.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    splats : list of Splat
        Beacon light, radiance.
    sensor : SensorSpec
    rng : numpy.random.Generator
        The frame's noise generator (unused when ``sensor.noise`` is false). One
        31-bit seed is drawn from it to seed OpenCV's uniform stream, so a frame
        depends on the generator's state and the frame's shape only.
    pattern : FixedPattern, optional
        The camera's fixed-pattern noise, applied to the mean before the noise
        (:mod:`deckpose.render.fixed_pattern`). With ``sensor.bayer`` set, each pixel keeps
        its filter's channel before the pattern and the noise, and the quantised mosaic
        is demosaiced (:mod:`deckpose.render.bayer`).
    background_gain : callable, optional
        ``f(r0, r1) -> (r1 - r0, W)`` float32 gain of the raster's rows (vignetting,
        :func:`deckpose.render.optics.vignetting_rows`), applied before the beacon light.

    Returns
    -------
    (H, W, 3) or (H, W) array of uint8 (8-bit) or uint16 (12/16-bit)
        RGB, or mono when ``sensor.color == "mono"``; DN.
    """
    H, W = raster.shape[:2]
    mono = sensor.color == "mono"
    dn_max = float(2 ** sensor.bit_depth - 1)
    dn_per_e = dn_max / sensor.full_well_e
    e_per_rad = sensor.exposure * sensor.full_well_e
    scale = np.asarray(scale_rgb, np.float64) * e_per_rad  # electrons per raster unit
    if mono:
        scale = np.array([scale @ _LUMA])
    C = 1 if mono else 3
    dn_per_unit = _dn_per_raster_unit(scale, dn_per_e, W)
    bayer = sensor.bayer is not BayerPattern.NONE
    Cn = 1 if bayer else C  # values per pixel that get noise (a Bayer photosite has one)
    depth = cv2.CV_8U if sensor.bit_depth == 8 else cv2.CV_16U
    out = np.empty((H, W) if mono or bayer else (H, W, C), np.uint8 if sensor.bit_depth == 8 else np.uint16)
    rows = strip_rows(W, C)
    by_strip = _splats_by_strip(splats, rows)
    # work buffers of one strip, 2-D (rows, W * C): one OpenCV channel, all of it
    mean_buf = np.empty((rows, W * C), np.float32)
    mosaic_buf = np.empty((rows, W), np.float32) if bayer else mean_buf
    half = (rows * W * Cn + 1) // 2  # Box-Muller pairs per strip
    noise_buf = np.empty(2 * half if sensor.noise else 0, np.float32)
    sigma_buf = np.empty_like(mosaic_buf) if sensor.noise else mosaic_buf  # (unused without noise)
    radius_buf = np.empty((1, half if sensor.noise else 0), np.float32)
    angle_buf = np.empty_like(radius_buf)
    # variance in DN^2 of a pixel of mean m DN: g m + (g r)^2 (shot + read noise, g = DN/e)
    read_var_dn2 = (dn_per_e * sensor.read_noise_e) ** 2
    if sensor.noise:  # OpenCV's uniform stream (thread-local), seeded from the frame's rng
        cv2.setRNGSeed(int(rng.integers(2**31 - 1)))
    for k, r0 in enumerate(range(0, H, rows)):
        r1 = min(H, r0 + rows)
        h = r1 - r0
        block = cv2.cvtColor(raster[r0:r1], cv2.COLOR_RGB2GRAY) if mono else raster[r0:r1]
        dst = out[r0:r1].reshape(h, W * Cn)
        mean = mean_buf[:h]
        np.multiply(block.reshape(h, W * C), dn_per_unit, out=mean)
        if background_gain is not None:
            m3 = mean.reshape(h, W, C)
            m3 *= background_gain(r0, r1)[:, :, None]
        if k in by_strip:
            add_splats(mean.reshape(h, W, C), by_strip[k], r0, gain=e_per_rad * dn_per_e)
        if bayer:
            select_mosaic(mean.reshape(h, W, C), sensor.bayer, r0, mosaic_buf[:h])
            mean = mosaic_buf[:h]
        if pattern is not None:
            apply_fixed_pattern(mean.reshape(h, W, Cn), pattern, r0, dn_per_e)
        if sensor.noise:
            pairs = (h * W * Cn + 1) // 2
            _fill_standard_normal(noise_buf, radius_buf[:, :pairs], angle_buf[:, :pairs])
            noise, sigma = noise_buf[:h * W * Cn].reshape(h, W * Cn), sigma_buf[:h]
            cv2.addWeighted(mean, dn_per_e, mean, 0.0, read_var_dn2, dst=sigma)
            cv2.sqrt(sigma, dst=sigma)
            cv2.multiply(noise, sigma, dst=noise)
            cv2.add(mean, noise, dst=dst, dtype=depth)
        else:
            cv2.addWeighted(mean, 1.0, mean, 0.0, 0.0, dst=dst, dtype=depth)  # round, saturate
        if sensor.bit_depth == 12:
            np.minimum(dst, np.uint16(dn_max), out=dst)
    return demosaic(out, sensor.bayer) if bayer else out


@dataclass(frozen=True)
class SpotRecord:
    """Per-beacon spot model in electrons: what the centroid Cramér–Rao bound needs.

    All arrays are (N,) over the layout's beacons; NaN for a beacon with no splat.
    Electrons are summed over the image's channels (RGB: R + G + B; mono: the one
    channel), matching a detector that measures the channel sum.

    Attributes
    ----------
    sigma_px : (N,) array of float
        Gaussian-equivalent standard deviation of the core, pixels (point-sampled
        Gaussian, :attr:`deckpose.render.beacons.Splat.sigma_px`).
    flux_e : (N,) array of float
        Electrons in the core (halo excluded), summed over channels.
    background_e : (N,) array of float
        Mean background electrons per pixel within 2 sigma of the centre (the
        rendered deck or sea under the beacon), summed over channels.
    peak_e : (N,) array of float
        Expected electrons of the brightest pixel in the brightest channel, beacon
        light (core + halo) plus background; at or above the full well the core saturates.
    """

    sigma_px: np.ndarray
    flux_e: np.ndarray
    background_e: np.ndarray
    peak_e: np.ndarray

    def __post_init__(self) -> None:
        n = np.shape(self.sigma_px)
        for name in ("sigma_px", "flux_e", "background_e", "peak_e"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.ndim != 1 or arr.shape != n:
                raise ValueError(f"SpotRecord.{name}: expected shape {n}, got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


def splat_electrons(sp: Splat, sensor: SensorSpec) -> float:
    """Electrons in a splat's core (halo excluded), summed over the image's channels.

    RGB: the core's radiance times each channel's colour, summed; mono: times the
    colour's mean (the grey the sensor sees, :func:`deckpose.render.beacons.add_splats`).
    """
    rgb = sp.rgb.astype(np.float64)
    weight = float(rgb.mean()) if sensor.color == "mono" else float(rgb.sum())
    return sp.core_flux * (sensor.exposure * sensor.full_well_e) * weight


def spot_record(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], splats: list[Splat],
                sensor: SensorSpec, n_beacons: int) -> SpotRecord:
    """The :class:`SpotRecord` of a frame's splats, under the same exposure as :func:`expose`.

    Parameters
    ----------
    raster : (H, W, 3) array of uint8
        The distorted raster passed to :func:`expose`.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    splats : list of Splat
    sensor : SensorSpec
    n_beacons : int
        Number of beacons in the layout (length of the arrays).
    """
    e_per_rad = sensor.exposure * sensor.full_well_e
    scale = np.asarray(scale_rgb, np.float64) * e_per_rad  # electrons per raster unit, per channel
    mono = sensor.color == "mono"
    out = {k: np.full(n_beacons, np.nan) for k in ("sigma_px", "flux_e", "background_e", "peak_e")}
    H, W = raster.shape[:2]
    for sp in splats:
        if sp.beacon_id < 0:  # a light that is not a beacon (lights.parquet records it)
            continue
        rgb = sp.rgb.astype(np.float64)
        weights = np.array([rgb.mean()]) if mono else rgb
        n = sp.patch.shape[0]
        rc = sp.row0 + n // 2
        cc = sp.col0 + n // 2
        h = math.ceil(2.0 * sp.sigma_px)
        r0, r1 = max(0, rc - h), min(H, rc + h + 1)
        c0, c1 = max(0, cc - h), min(W, cc + h + 1)
        mean_raster = np.zeros(3)
        if r0 < r1 and c0 < c1:
            vv, uu = np.mgrid[r0:r1, c0:c1]
            disc = (vv - rc) ** 2 + (uu - cc) ** 2 <= h * h
            if disc.any():
                mean_raster = raster[r0:r1, c0:c1][disc].reshape(-1, 3).mean(axis=0)
        # expose(): mono frames are the grey raster (luma) times the luma-weighted scale
        if mono:
            bg = np.array([float(mean_raster @ _LUMA) * float(scale @ _LUMA)])
        else:
            bg = mean_raster * scale
        i = sp.beacon_id
        out["sigma_px"][i] = sp.sigma_px
        out["flux_e"][i] = splat_electrons(sp, sensor)
        out["background_e"][i] = float(bg.sum())
        # per-channel patches (optics): each channel's own peak, the grey's as their weighted mean
        # (rows first, then columns: numpy's reduction over a 3-wide trailing axis is 50x slower)
        peak = (sp.patch.max(axis=0).max(axis=0).astype(np.float64) if sp.patch.ndim == 3
                else float(sp.patch.max()))
        if sp.patch.ndim == 3 and mono:
            peak = float(np.max(sp.patch.astype(np.float64) @ rgb) / 3.0) / float(rgb.mean())
        out["peak_e"][i] = float(np.max(peak * e_per_rad * weights + bg))
    return SpotRecord(**out)
