"""Colour of each blob: tells the red bow beacon from the white ones."""

from __future__ import annotations

import math

import numpy as np
from deckpose.detect.background import clipped_mean
from numpy.typing import NDArray

from deckpose.errors import check_shape

FloatArray = NDArray[np.float64]


def blob_rgb_flux(image: np.ndarray, points_px: FloatArray, radii_px: FloatArray) -> FloatArray:
    """Background-subtracted flux per channel of each blob.

    Parameters
    ----------
    image : (H, W, 3) array
        RGB frame.
    points_px : (N, 2) array of float
        Blob centres ``(u, v)``.
    radii_px : (N,) array of float
        Aperture radius per blob, pixels; the background is the per-channel
        clipped mean (:func:`~deckpose.detect.background.clipped_mean`) of an annulus
        from 1.5 to 2.5 aperture radii: a median of a quantised 8-bit background is a
        whole DN, and its bias summed over the aperture washed a dim red bow out to
        white (a red share of 0.44 for 0.90).

    Returns
    -------
    (N, 3) array of float, DN
        NaN for a blob whose aperture lies outside the image.

    Notes
    -----
    A light's flux is positive. Where the channel sum comes out zero or negative, the
    aperture took in surroundings darker than its annulus (by day, a beacon's dark
    fitting on a bright deck, under an aperture a detector's wide fitted size made), and
    the blob is measured again in half the radius, down to :data:`MIN_APERTURE_PX`
    (a ``gauss`` size of 23 px for a clipped red bow gave a 46 px aperture, a negative
    flux and no bow on 12 of 15 day frames of the detector ladder's ``real`` rung).
    """
    img = np.asarray(image)
    check_shape("image", img, (None, None, 3))
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    out = np.zeros((pts.shape[0], 3))
    for i, ((u, v), r) in enumerate(zip(pts, np.broadcast_to(radii_px, (pts.shape[0],)))):
        if not (np.isfinite(u) and np.isfinite(v) and np.isfinite(r)):
            out[i] = np.nan
            continue
        out[i] = _aperture_flux(img, float(u), float(v), float(r))
        while out[i].sum() <= 0 and r > MIN_APERTURE_PX:  # darker surroundings in the aperture
            r = max(MIN_APERTURE_PX, 0.5 * r)
            out[i] = _aperture_flux(img, float(u), float(v), float(r))
    return out


#: Smallest aperture radius a blob's colour is measured in again, pixels.
MIN_APERTURE_PX = 2.0


def _aperture_flux(img: np.ndarray, u: float, v: float, r: float) -> FloatArray:
    """Per-channel flux in the disc of radius ``r`` about ``(u, v)`` less its annulus's level, (3,) DN."""
    H, W = img.shape[:2]
    R = 2.5 * r + 1.0
    u0, u1 = max(0, math.floor(u - R)), min(W, math.ceil(u + R) + 1)
    v0, v1 = max(0, math.floor(v - R)), min(H, math.ceil(v + R) + 1)
    if u1 <= u0 or v1 <= v0:  # a centre outside the image: no colour to measure
        return np.full(3, np.nan)
    # channel-major, (3, h, w): each channel's pixels contiguous (numpy's inner loops
    # over a pixel's three channels cost 10-40x more than over a channel's pixels)
    block = np.moveaxis(img[v0:v1, u0:u1], 2, 0).astype(np.float64, order="C")
    vv, uu = np.ogrid[v0:v1, u0:u1]  # broadcast: the same distances as a full grid's
    d = np.hypot(uu - u, vv - v)
    ap, ann = d <= r, (d >= 1.5 * r) & (d <= R)
    bg = clipped_mean(block[:, ann].T) if ann.sum() >= 3 else np.zeros(3)
    return (block[:, ap] - bg[:, None]).sum(axis=1)


def redness(rgb_flux: FloatArray) -> FloatArray:
    """Share of red in each blob's flux, ``R / (R + G + B)`` (NaN for non-positive flux), (N,)."""
    f = np.clip(np.asarray(rgb_flux, dtype=float), 0.0, None)
    tot = f.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tot > 0, f[:, 0] / tot, np.nan)

