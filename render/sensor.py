"""The sensor after the lens: distortion, beacon light, exposure, noise, saturation, bit depth.

Order of operations for one frame:

1. the rasterised pinhole image is warped to the distorted image with
   ``cv2.remap`` (map from :func:`cv2.initInverseRectificationMap`: for every
   distorted pixel, where it comes from in the pinhole image);
2. beacon splats are added at their *distorted* projected centres (so ground
   truth and image agree, see :mod:`deckpose.render.beacons`);
3. radiance is turned into electrons (``exposure * full_well_e`` for white),
   photon shot noise and read noise are added as one Gaussian of variance
   ``signal + read_noise^2`` (the Poisson law's normal limit; exact enough above
   a few electrons), the well saturates, and the result is quantised to
   ``bit_depth`` bits.

The work is done in horizontal strips so a 64 MP frame never holds more than one
float copy of a strip; the noise of strip ``k`` comes from the frame's generator
in strip order, so results are identical for any number of workers.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.render.beacons import Splat, add_splats
from deckpose.render.config import SensorSpec

#: Rows per processing strip.
STRIP_ROWS = 256
_LUMA = np.array([0.299, 0.587, 0.114], np.float32)

_MAP_CACHE: dict[tuple[object, ...], tuple[np.ndarray, np.ndarray]] = {}


def distortion_maps(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` from the pinhole image to the distorted image (cached per camera)."""
    key = (camera.width_px, camera.height_px, camera.K.tobytes(), camera.dist_coeffs.tobytes())
    if key not in _MAP_CACHE:
        _MAP_CACHE.clear()
        _MAP_CACHE[key] = cv2.initInverseRectificationMap(
            camera.K, camera.dist_coeffs, np.eye(3), camera.K, (camera.width_px, camera.height_px),
            cv2.CV_16SC2)
    return _MAP_CACHE[key]


def distort(raster: NDArray[np.uint8], camera: CameraModel) -> NDArray[np.uint8]:
    """Warp a pinhole raster into the camera's distorted image (identity without distortion)."""
    if not camera.has_distortion:
        return raster
    m1, m2 = distortion_maps(camera)
    return cv2.remap(raster, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def expose(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], splats: list[Splat],
           sensor: SensorSpec, rng: np.random.Generator) -> np.ndarray:
    """Raster plus beacons to a quantised sensor image.

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
        The frame's noise generator (unused when ``sensor.noise`` is false).

    Returns
    -------
    (H, W, 3) or (H, W) array of uint8 (8-bit) or uint16 (12/16-bit)
        RGB, or mono when ``sensor.color == "mono"``.
    """
    H, W = raster.shape[:2]
    mono = sensor.color == "mono"
    C = 1 if mono else 3
    dn_max = float(2 ** sensor.bit_depth - 1)
    out = np.empty((H, W, C), np.uint8 if sensor.bit_depth == 8 else np.uint16)
    e_per_rad = np.float32(sensor.exposure * sensor.full_well_e)
    dn_per_e = np.float32(dn_max / sensor.full_well_e)
    scale = (scale_rgb @ _LUMA).reshape(1) if mono else scale_rgb
    scale = (scale * e_per_rad).astype(np.float32)
    for r0 in range(0, H, STRIP_ROWS):
        r1 = min(H, r0 + STRIP_ROWS)
        if mono:
            strip = (raster[r0:r1].astype(np.float32) @ _LUMA)[..., None] * scale
        else:
            strip = raster[r0:r1].astype(np.float32) * scale
        add_splats(strip, splats, r0, gain=float(e_per_rad))
        if sensor.noise:
            noise = rng.standard_normal(strip.shape, dtype=np.float32)
            var = np.maximum(strip, 0.0)
            var += np.float32(sensor.read_noise_e ** 2)
            np.sqrt(var, out=var)
            noise *= var
            strip += noise
        np.clip(strip, 0.0, sensor.full_well_e, out=strip)
        strip *= dn_per_e
        np.rint(strip, out=strip)
        out[r0:r1] = strip
    return out[..., 0] if mono else out
