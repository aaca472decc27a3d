"""Bright-spot candidate search: beacons are the brightest compact spots of a frame.

On rendered or real frames, a threshold a few noise sigmas above the background
also passes deck markings, deck texture, the lit sea and edges. Beacons,
however, reach (nearly) the brightest level of the frame in at least one
channel (their cores saturate), while white markings and the lit deck stay
well below it. So candidates are found on the *peak-channel* image (per pixel
the largest channel, which keeps the red bow beacon as bright as the white
ones), thresholded at a fraction ``spot_level`` of the way from the frame's
background to its bright-spot level. Both levels are measured per frame:

* background: median of the peak-channel image (strided sample);
* bright-spot level: the ``BRIGHT_RANK``-th brightest pixel of the frame, so a
  single hot pixel does not set it.

Large frames are searched on a block-*maximum* copy (block means would dilute
small spots below the level), then at full resolution in boxes around it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from deckpose.detect.registry import DetectorOptions

#: The bright-spot level is the value of this brightest pixel (rank from the top).
BRIGHT_RANK = 20


def peak_channel(pixels: np.ndarray) -> np.ndarray:
    """Per-pixel largest channel of an (h, w, 3) block, or the block itself; float32."""
    a = np.asarray(pixels)
    if a.ndim == 3:
        return a.max(axis=2).astype(np.float32)
    return a.astype(np.float32)


def spot_threshold(
    image: np.ndarray, options: DetectorOptions
) -> tuple[float, float, float, float]:
    """``(threshold, background, bright level, noise)`` of the peak-channel image, DN.

    The threshold lies ``options.spot_level`` of the way from the background to
    the bright-spot level, and at least ``threshold_sigma`` noise sigmas above
    the background (noise of the peak-channel image from pixel differences).
    """
    from deckpose.detect.background import difference_noise, noise_floor_dn

    pk = peak_channel(image)
    H, W = pk.shape
    step = max(1, int(math.sqrt(H * W / 30_000)))
    bg = float(np.median(pk[::step, ::step]))
    flat = pk.ravel()
    k = min(BRIGHT_RANK, flat.size)
    bright = float(np.partition(flat, flat.size - k)[flat.size - k])
    noise = max(difference_noise(pk), noise_floor_dn(pk))
    thr = max(bg + options.spot_level * (bright - bg), bg + options.threshold_sigma * noise)
    return thr, bg, bright, noise


def block_max(pk: np.ndarray, factor: int) -> np.ndarray:
    """Maxima of ``factor x factor`` blocks (edge blocks padded), (ceil(H/f), ceil(W/f))."""
    if factor == 1:
        return pk
    H, W = pk.shape
    h, w = -(-H // factor), -(-W // factor)
    pad = np.full((h * factor, w * factor), -np.inf, np.float32)
    pad[:H, :W] = pk
    return pad.reshape(h, factor, w, factor).max(axis=(1, 3))


def spot_boxes(
    image: np.ndarray, options: DetectorOptions
) -> tuple[list[tuple[int, int, int, int]], str]:
    """Full-resolution boxes ``(u0, v0, u1, v1)`` around the frame's bright spots.

    Returns the boxes and, when there are none or too many, the reason.
    """
    from deckpose.detect.candidates import coarse_factor

    thr, bg, bright, _ = spot_threshold(image, options)
    pk = peak_channel(image)
    f = coarse_factor(pk.shape, options.coarse_max_px)
    small = block_max(pk, f)
    mask = (small > thr).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n - 1 > options.max_blobs:
        return [], (
            f"{n - 1} bright spots above {thr:.0f} DN exceed max_blobs={options.max_blobs} "
            f"(background {bg:.0f} DN, bright level {bright:.0f} DN): glare or noise"
        )
    if n == 1:
        return [], (
            f"dark frame: no spot above {thr:.1f} DN (peak channel background {bg:.1f} DN, "
            f"bright level {bright:.0f} DN)"
        )
    H, W = pk.shape
    pad = f + 2
    boxes = [
        (
            max(0, x * f - pad),
            max(0, y * f - pad),
            min(W, (x + w) * f + pad),
            min(H, (y + h) * f + pad),
        )
        for x, y, w, h, _a in stats[1:]
    ]
    return boxes, ""


def spot_pedestal(pixels: np.ndarray, core: np.ndarray, border_level_dn: float) -> float:
    """Level under a bright spot: the brightest window pixel away from its core, DN.

    "Away" is farther than ``2 r + 2`` px from the core, ``r`` the core's
    equivalent radius, beyond the spot's own wings. At least ``border_level_dn``
    (the window border's fitted level). Pixels the beacon does not light (a
    white marking it sits on) stay below it.
    """
    r_px = int(math.ceil(2.0 * math.sqrt(core.sum() / math.pi) + 2.0))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r_px + 1, 2 * r_px + 1))
    near = cv2.dilate(core.astype(np.uint8), disc).astype(bool)
    away = pixels[~near]
    return max(border_level_dn, float(away.max())) if away.size else border_level_dn
