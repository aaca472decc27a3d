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
from deckpose.render.sensor_config import SensorSpec
from numpy.typing import NDArray

from deckpose.camera import CameraModel

__all__ = ["BLOOM_MAX_PAD_PX", "bloom_column", "bloom_splats"]

def bloom_column(charge_e: NDArray[np.float64], full_well_e: float) -> NDArray[np.float64]:
    """Charge above the full well spilled along each column; (h, w) in, (h, w) out.

    Repeatedly the fullest pixel of a column keeps ``full_well_e`` and sends half its
    excess up and half down; on the way each pixel fills to the well and passes the rest
    on (a pixel already over the well passes its own excess too). Charge that reaches the
    window's end is lost (it would drain off the sensor); inside, the total is kept.

    Every column over the well is worked at once: a round takes each one's fullest pixel,
    and a walk's end is found from the running sum of the room along its path
    (:func:`_spill`) instead of pixel by pixel, so a round is a few array operations.
    The result is the pixel-by-pixel walk's to round-off (``tests/render/test_realism_finish.py``
    keeps that walk as the reference).
    """
    out = np.array(charge_e, dtype=np.float64)
    cap = float(full_well_e)
    cols = np.flatnonzero((out > cap).any(axis=0))
    while cols.size:
        sub = out[:, cols]
        i = np.argmax(sub, axis=0)
        m = np.arange(cols.size)
        excess = sub[i, m] - cap
        sub[i, m] = cap
        h = sub.shape[0]
        _spill(sub, i, 0.5 * excess, cap)  # down the column
        flipped = sub[::-1]
        _spill(flipped, h - 1 - i, 0.5 * excess, cap)  # up: the same walk on the rows reversed
        sub = flipped[::-1]
        out[:, cols] = sub
        cols = cols[(sub > cap).any(axis=0)]
    return out


def _spill(sub: NDArray[np.float64], start: NDArray[np.intp], charge: NDArray[np.float64], cap: float) -> None:
    """Walk ``charge`` (m,) down each column of ``sub`` (h, m) from below row ``start``, in place.

    Past row ``start``, the charge left after row ``k`` is ``R_k = charge - sum (cap - x)``
    over the rows walked; the walk ends at the first ``k`` with ``R_k <= 0``, which holds
    ``cap + R_k``; the rows before it are full, and with no such row the rest leaves the window.
    """
    h = sub.shape[0]
    rows = np.arange(h)[:, None]
    past = rows > start[None, :]
    room = np.where(past, cap - sub, 0.0)
    left = charge[None, :] - np.cumsum(room, axis=0)  # R_k (rows before the start: the charge)
    ends = past & (left <= 0)
    has_end = ends.any(axis=0)
    end = np.where(has_end, np.argmax(ends, axis=0), h)
    full = past & (rows < end[None, :])
    sub[full] = cap
    k = np.flatnonzero(has_end)
    sub[end[k], k] = cap + left[end[k], k]


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
    in rows only (it is no longer square). Only the range of columns holding charge above
    the well is bloomed (the others keep their light as it was), and a splat whose light plus
    the window's brightest background stays under the well is passed over before any
    background is computed.

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
    H, W = raster.shape[:2]
    out: list[Splat] = []
    for sp in splats:
        rgb = sp.rgb.astype(np.float64)
        light = sp.patch.astype(np.float64) * rgb * e_per_rad  # (n, n, 3) electrons
        if mono:
            light = light.mean(axis=2, keepdims=True)
        n = sp.patch.shape[0]
        # a bound first (the raster's brightest value in the window, unvignetted): most spots fill no pixel
        r0, r1, c0, c1 = max(sp.row0, 0), min(sp.row0 + n, H), max(sp.col0, 0), min(sp.col0 + n, W)
        bg_top = float(raster[r0:r1, c0:c1].max()) * float(scale.max()) if r0 < r1 and c0 < c1 else 0.0
        if float(light.max()) + bg_top <= cap:
            out.append(sp)
            continue
        bg = _window_background(sp.row0, sp.col0, n, raster, scale, mono, vignetting)
        over = np.maximum(light + bg - cap, 0.0).sum(axis=0)
        if not over.any():
            out.append(sp)
            continue
        pad = min(math.ceil(float(over.max()) / max(cap - float(bg.max()), 0.1 * cap)) + 2, BLOOM_MAX_PAD_PX)
        # only the columns that hold charge above the well change: bloom those (a contiguous range)
        hot = np.flatnonzero(over.any(axis=1))
        a, b = int(hot[0]), int(hot[-1]) + 1
        lit = np.pad(light[:, a:b], ((pad, pad), (0, 0), (0, 0)))
        bgc = np.concatenate([_window_background(sp.row0 - pad, sp.col0 + a, pad, raster, scale, mono, vignetting,
                                                 b - a),
                              bg[:, a:b],
                              _window_background(sp.row0 + n, sp.col0 + a, pad, raster, scale, mono, vignetting,
                                                 b - a)])
        bloomed = np.stack([bloom_column(lit[..., c] + bgc[..., c], cap) - bgc[..., c]
                            for c in range(lit.shape[2])], axis=-1)
        if mono:
            cols = np.repeat(bloomed / (e_per_rad * rgb.mean()), 3, axis=2)
        else:
            cols = np.divide(bloomed, rgb * e_per_rad, out=np.zeros_like(bloomed), where=rgb > 0)
        patch = np.zeros((n + 2 * pad, n, 3), np.float32)
        patch[pad:pad + n] = sp.patch if sp.patch.ndim == 3 else sp.patch[..., None]
        patch[:, a:b] = cols
        out.append(replace(sp, row0=sp.row0 - pad, patch=patch))
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
