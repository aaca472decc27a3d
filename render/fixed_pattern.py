"""Fixed-pattern noise: photo-response and dark-signal non-uniformity, and hot pixels.

Each is a property of one camera's sensor, so it is the same in every frame of that
camera: the maps are drawn from the config seed and the camera's name (not from the
frame's seed), each from its own stream, and cached per camera in the worker process.
The pattern acts on a pixel's mean before the noise (:func:`deckpose.render.sensor.expose`)::

    mean_e = signal_e * (1 + prnu * z1) + dsnu_e * z2 + hot_pixel_e * [pixel is hot]

with ``z1``, ``z2`` standard normal per photosite (a Bayer pixel, or a whole RGB or mono
pixel: all its channels share the gain and the dark signal), clamped at 0 (a camera
whose black level is subtracted and clamped), and the shot and read noise follow
that mean as in the documented law. The dark signal is electrons per frame at any
exposure (a dark current growing with exposure time is not modelled).

Hot pixels are recorded per camera (``cameras/<name>_hot_pixels.parquet``,
:func:`hot_pixel_table`) so a benchmark can count false detections on them.
"""

from __future__ import annotations

import functools
import zlib
from dataclasses import dataclass

import cv2
import numpy as np
from deckpose.render.sensor_config import SensorSpec
from numpy.typing import NDArray

__all__ = ["FIXED_PATTERN_STREAM", "FixedPattern", "apply_fixed_pattern", "fixed_pattern", "hot_pixel_table"]

#: Stream id of the fixed pattern (with the config seed and the camera name's CRC-32).
FIXED_PATTERN_STREAM = 23_04
_GAIN, _DARK, _HOT = 0, 1, 2  # sub-streams: switching one effect on leaves the others' maps unchanged


@dataclass(frozen=True)
class FixedPattern:
    """One camera's fixed pattern; arrays read-only.

    Attributes
    ----------
    gain : (H, W) array of float32 or None
        Relative photo-response of each photosite, ``1 + prnu * z`` (None: PRNU off).
    dark_e : (H, W) array of float32 or None
        Dark signal of each photosite, electrons: DSNU plus the hot pixels' excess
        (None: both off).
    hot_rows, hot_cols : (K,) array of int
        Hot pixels, row and column, sorted by ``row * W + col``.
    """

    gain: NDArray[np.float32] | None
    dark_e: NDArray[np.float32] | None
    hot_rows: NDArray[np.int64]
    hot_cols: NDArray[np.int64]

    def __post_init__(self) -> None:
        for name in ("gain", "dark_e", "hot_rows", "hot_cols"):
            arr = getattr(self, name)
            if arr is not None:
                arr.setflags(write=False)
        if self.hot_rows.shape != self.hot_cols.shape:
            raise ValueError(f"FixedPattern: hot_rows {self.hot_rows.shape} and hot_cols "
                             f"{self.hot_cols.shape} differ in shape")


def _rng(seed: int, camera: str, sub: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(
        [seed, FIXED_PATTERN_STREAM, zlib.crc32(camera.encode()), sub]))


def hot_pixels(seed: int, camera: str, height_px: int, width_px: int,
               fraction: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Rows and columns of the camera's hot pixels: ``round(fraction * H * W)`` distinct pixels."""
    n = round(fraction * height_px * width_px)
    idx = np.sort(_rng(seed, camera, _HOT).choice(height_px * width_px, size=n, replace=False))
    return (idx // width_px).astype(np.int64), (idx % width_px).astype(np.int64)


@functools.lru_cache(maxsize=2)
def _cached_pattern(seed: int, camera: str, height_px: int, width_px: int, prnu: float, dsnu_e: float,
                    hot_fraction: float, hot_e: float) -> FixedPattern:
    shape = (height_px, width_px)
    gain = None
    if prnu > 0:
        gain = _rng(seed, camera, _GAIN).standard_normal(shape, dtype=np.float32)
        gain *= np.float32(prnu)
        gain += np.float32(1.0)
    rows, cols = hot_pixels(seed, camera, height_px, width_px, hot_fraction)
    dark = None
    if dsnu_e > 0 or rows.size:
        if dsnu_e > 0:
            dark = _rng(seed, camera, _DARK).standard_normal(shape, dtype=np.float32)
            dark *= np.float32(dsnu_e)
        else:
            dark = np.zeros(shape, np.float32)
        dark[rows, cols] += np.float32(hot_e)
    return FixedPattern(gain, dark, rows, cols)


def fixed_pattern(sensor: SensorSpec, seed: int, camera: str, height_px: int,
                  width_px: int) -> FixedPattern | None:
    """The fixed pattern of camera ``camera`` (None when PRNU, DSNU and hot pixels are all off).

    Cached for the last two cameras of the process: a 64 MP camera's maps take
    256 MB each (float32).
    """
    if sensor.prnu == 0 and sensor.dsnu_e == 0 and sensor.hot_pixel_fraction == 0:
        return None
    return _cached_pattern(seed, camera, height_px, width_px, sensor.prnu, sensor.dsnu_e,
                           sensor.hot_pixel_fraction, sensor.hot_pixel_e)


def apply_fixed_pattern(mean_dn: NDArray[np.float32], pattern: FixedPattern, row0: int,
                        dn_per_e: float) -> None:
    """Apply the pattern to rows ``row0 ..`` of a frame's mean, in place, and clamp it at 0.

    OpenCV on contiguous single-channel views: an RGB strip gets the photosite map
    replicated over its channels (``cv2.merge`` into a scratch buffer), about 4x faster
    than numpy's broadcasting over a last axis of 3.

    Parameters
    ----------
    mean_dn : (h, W, C) array of float32, C-contiguous
        Mean DN per pixel and channel (C = 1 for mono and Bayer mosaics, 3 for RGB).
    pattern : FixedPattern
    row0 : int
        Image row of ``mean_dn[0]``.
    dn_per_e : float
        Gain, DN per electron.
    """
    h, W, C = mean_dn.shape
    flat = mean_dn.reshape(h, W * C)

    def per_value(m: NDArray[np.float32]) -> NDArray[np.float32]:
        rows = m[row0:row0 + h]
        return rows if C == 1 else cv2.merge([rows] * C).reshape(h, W * C)

    if pattern.gain is not None:
        cv2.multiply(flat, per_value(pattern.gain), dst=flat)
    if pattern.dark_e is not None:
        cv2.scaleAdd(per_value(pattern.dark_e), dn_per_e, flat, dst=flat)
        cv2.max(flat, 0.0, dst=flat)


def hot_pixel_table(sensor: SensorSpec, seed: int, camera: str, height_px: int,
                    width_px: int) -> dict[str, NDArray[np.generic]]:
    """Columns of ``cameras/<camera>_hot_pixels.parquet``: ``u_px``, ``v_px``, ``excess_e``.

    Drawn without the maps (cheap at 64 MP); the same pixels :func:`fixed_pattern` makes hot.
    """
    rows, cols = hot_pixels(seed, camera, height_px, width_px, sensor.hot_pixel_fraction)
    return {"u_px": cols, "v_px": rows, "excess_e": np.full(rows.size, sensor.hot_pixel_e)}
