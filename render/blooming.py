"""Blooming: the charge a pixel collects above its full well spills along its column.

Deterministic and charge-conserving (:func:`bloom_column`); applied to the light spots'
windows with the background under them (:func:`bloom_splats`), by
:mod:`deckpose.render.optics` when ``optics.bloom`` is on.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
from deckpose.render.beacons import Splat
from deckpose.render.config import SensorSpec
from numpy.typing import NDArray

from deckpose.camera import CameraModel

__all__ = ["BLOOM_MAX_PAD_PX", "bloom_column", "bloom_splats"]

def bloom_column(charge_e: NDArray[np.float64], full_well_e: float) -> NDArray[np.float64]:
    """Charge above the full well spilled along each column; (h, w) in, (h, w) out.

    Repeatedly the fullest pixel of a column keeps ``full_well_e`` and sends half its
    excess up and half down; on the way each pixel fills to the well and passes the rest
    on (a pixel already over the well passes its own excess too). Charge that reaches the
    window's end is lost (it would drain off the sensor); inside, the total is kept.
    """
    out = np.array(charge_e, dtype=np.float64)
    h = out.shape[0]
    cap = full_well_e
    for j in np.flatnonzero((out > cap).any(axis=0)):
        col = out[:, j]
        while True:
            i = int(np.argmax(col))
            if col[i] <= cap:
                break
            excess = col[i] - cap
            col[i] = cap
            for step in (-1, 1):
                e, k = 0.5 * excess, i + step
                while e > 0 and 0 <= k < h:
                    total = col[k] + e
                    col[k], e = (total, 0.0) if total <= cap else (cap, total - cap)
                    k += step
    return out


_LUMA = np.array([0.299, 0.587, 0.114])
#: The most rows blooming adds above and below a spot's window; charge spilled farther is dropped.
BLOOM_MAX_PAD_PX = 256


def bloom_splats(splats: list[Splat], raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32],
                 sensor: SensorSpec, vignetting: tuple[CameraModel, float] | None = None) -> list[Splat]:
    """The splats with the charge their light and the background put above the full well spilled.

    Per channel (mono: the grey pixel) the expected electrons of light plus background in
    the splat's window are bloomed along columns (:func:`bloom_column`, the window padded
    so the charge stays in it, by at most :data:`BLOOM_MAX_PAD_PX` rows) and the background
    taken off again; a splat that fills no pixel is returned as it is. The window grows
    in rows only (it is no longer square).

    Parameters
    ----------
    splats : list of Splat
        Optical splats (``(h, w, 3)`` patches, :func:`apply_optics`).
    raster : (H, W, 3) array of uint8
        The distorted raster (the background), as :func:`deckpose.render.sensor.expose` takes it.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    sensor : SensorSpec
    vignetting : (CameraModel, float), optional
        The camera and ``vignetting_exponent`` of the raster's vignetting (:func:`vignetting_gain`).
    """
    e_per_rad = sensor.exposure * sensor.full_well_e
    cap = sensor.full_well_e
    scale = np.asarray(scale_rgb, np.float64) * e_per_rad
    mono = sensor.color == "mono"
    out: list[Splat] = []
    for sp in splats:
        rgb = sp.rgb.astype(np.float64)
        light = sp.patch.astype(np.float64) * rgb * e_per_rad  # (n, n, 3) electrons
        if mono:
            light = light.mean(axis=2, keepdims=True)
        bg = _window_background(sp.row0, sp.col0, sp.patch.shape[0], raster, scale, mono, vignetting)
        over = np.maximum(light + bg - cap, 0.0).sum(axis=0)
        if not over.any():
            out.append(sp)
            continue
        n = sp.patch.shape[0]
        pad = min(math.ceil(float(over.max()) / max(cap - float(bg.max()), 0.1 * cap)) + 2, BLOOM_MAX_PAD_PX)
        light = np.pad(light, ((pad, pad), (0, 0), (0, 0)))
        bg = np.concatenate([_window_background(sp.row0 - pad, sp.col0, pad, raster, scale, mono, vignetting, n),
                             bg, _window_background(sp.row0 + n, sp.col0, pad, raster, scale, mono, vignetting, n)])
        bloomed = np.stack([bloom_column(light[..., c] + bg[..., c], cap) - bg[..., c]
                            for c in range(light.shape[2])], axis=-1)
        if mono:
            patch = np.repeat(bloomed / (e_per_rad * rgb.mean()), 3, axis=2)
        else:
            patch = np.divide(bloomed, rgb * e_per_rad, out=np.zeros_like(bloomed), where=rgb > 0)
        out.append(replace(sp, row0=sp.row0 - pad, patch=patch.astype(np.float32)))
    return out


def _window_background(row0: int, col0: int, n: int, raster: NDArray[np.uint8], scale_e: NDArray[np.float64],
                       mono: bool, vignetting: tuple[CameraModel, float] | None,
                       width: int | None = None) -> NDArray[np.float64]:
    """Expected background electrons of an ``n`` x ``width`` (default ``n``) window, (n, width, C); 0 off the image."""
    H, W = raster.shape[:2]
    C = 1 if mono else 3
    w = n if width is None else width
    out = np.zeros((n, w, C))
    r0, r1, c0, c1 = max(row0, 0), min(row0 + n, H), max(col0, 0), min(col0 + w, W)
    if r0 >= r1 or c0 >= c1:
        return out
    block = raster[r0:r1, c0:c1]
    if mono:  # expose(): the grey raster (OpenCV's rounding) times the luma-weighted scale
        vals = cv2.cvtColor(np.ascontiguousarray(block), cv2.COLOR_RGB2GRAY)[..., None] * float(scale_e @ _LUMA)
    else:
        vals = block * scale_e
    if vignetting is not None:  # vignetting_gain() on the window's grid, by broadcasting
        cam, n_exp = vignetting
        tx2 = ((np.arange(c0, c1) - cam.cx) / cam.fx) ** 2
        ty2 = ((np.arange(r0, r1) - cam.cy) / cam.fy) ** 2
        vals = vals * ((1.0 + ty2[:, None] + tx2[None, :]) ** (-0.5 * n_exp))[..., None]
    out[r0 - row0:r1 - row0, c0 - col0:c1 - col0] = vals
    return out
