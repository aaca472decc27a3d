"""Auto-exposure: the exposure of each frame chosen from a metering of its noise-free image.

A real camera meters the frames before the one it takes; that controller, switched on by
``auto_exposure.time_constant_s`` or ``max_step_stops``, runs over each time sequence
before the frames render (:mod:`deckpose.render.exposure_control`, with this metering).
Without it each frame meters itself: the noise-free,
clipped background (the rasterised deck and sea through the sensor's mean table,
without the beacons and other lights, which cover well under 0.1 % of a frame) at a
trial exposure ``E``, in full-scale units, is ``min(E * a, 1)`` per pixel and channel
with ``a = scale_rgb[c] * v`` for raster value ``v`` (mono: the grey raster times the
luma-weighted scale), so the metering is exact from a 256-bin histogram per channel:

* ``percentile: null``: the mean of the clipped values equals ``target`` (bisection on
  ``log E``; the mean is continuous and non-decreasing in ``E``);
* ``percentile: p``: the ``p``-th percentile of the values (the smallest value with at
  least ``p`` % of the values at or below it) equals ``target``: ``E = target / a_p``.

``E`` is clamped to ``[min_exposure, max_exposure]``: a night frame whose deck is
dark takes the longest exposure and its beacons saturate, a bright day frame a short
one and its beacons come out dim. The exposure used is recorded per frame
(``exposure`` in ``frames.parquet``) and the spot model of ``beacons.parquet`` is
computed under it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.render.sensor_config import AutoExposureSpec, SensorSpec
from numpy.typing import NDArray

__all__ = ["metered_exposure", "raster_levels"]

_LUMA = np.array([0.299, 0.587, 0.114])


def raster_levels(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32],
                  mono: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The background's values at exposure 1, full-scale units, as a weighted histogram.

    Returns
    -------
    levels : (256 * C,) array of float
        ``scale_rgb[c] * v`` for every raster value ``v`` and channel ``c`` (mono: ``C = 1``).
    counts : (256 * C,) array of float
        Pixels (times channels) at each level.
    """
    scale = np.asarray(scale_rgb, np.float64)
    v = np.arange(256, dtype=np.float64)
    if mono:
        grey = cv2.cvtColor(raster, cv2.COLOR_RGB2GRAY)
        hist = cv2.calcHist([grey], [0], None, [256], [0, 256]).ravel()
        return v * float(scale @ _LUMA), hist.astype(np.float64)
    hists = [cv2.calcHist([raster], [c], None, [256], [0, 256]).ravel() for c in range(3)]
    levels = np.concatenate([v * scale[c] for c in range(3)])
    return levels, np.concatenate(hists).astype(np.float64)


def _mean_at(exposure: float, levels: NDArray[np.float64], weights: NDArray[np.float64]) -> float:
    return float(weights @ np.minimum(exposure * levels, 1.0))


def metered_exposure(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], sensor: SensorSpec,
                     ae: AutoExposureSpec) -> float:
    """The exposure that brings the metered statistic of the frame's background to ``ae.target``.

    Parameters
    ----------
    raster : (H, W, 3) array of uint8
        The distorted raster :func:`deckpose.render.sensor.expose` receives.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    sensor : SensorSpec
        Its ``color`` picks RGB or grey metering.
    ae : AutoExposureSpec

    Returns
    -------
    float
        The exposure (unit of ``sensor.exposure``), within ``[ae.min_exposure, ae.max_exposure]``.
    """
    levels, counts = raster_levels(raster, scale_rgb, sensor.color == "mono")
    keep = counts > 0
    levels, weights = levels[keep], counts[keep] / counts.sum()
    lo, hi = ae.min_exposure, ae.max_exposure
    if ae.percentile is not None:
        order = np.argsort(levels, kind="stable")
        cdf = np.cumsum(weights[order])
        k = min(int(np.searchsorted(cdf, ae.percentile / 100.0 - 1e-12)), order.size - 1)
        a_p = float(levels[order[k]])
        return hi if a_p <= 0 else min(hi, max(lo, ae.target / a_p))
    if _mean_at(hi, levels, weights) <= ae.target:
        return hi
    if _mean_at(lo, levels, weights) >= ae.target:
        return lo
    a, b = math.log(lo), math.log(hi)
    for _ in range(60):  # the bracket shrinks 2**60-fold: exact to float precision
        m = 0.5 * (a + b)
        if _mean_at(math.exp(m), levels, weights) < ae.target:
            a = m
        else:
            b = m
    return math.exp(0.5 * (a + b))
