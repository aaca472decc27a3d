"""Channel sums of a frame in square blocks: the significance search's coarse image.

:func:`block_sum` sums a frame's channels over ``f x f`` blocks (``f`` a power of two) by
OpenCV's area resampling, exactly or, for an 8-bit frame, with its block means rounded to
whole DN (the fast path); :func:`block_pair_differences` gives the exact sums of a grid of
neighbouring block pairs without summing the whole frame.
"""

from __future__ import annotations

import math

import cv2
import numpy as np


def block_sum(image: np.ndarray, factor: int, *, exact: bool = True) -> np.ndarray:
    """Channel sum of ``image`` in ``factor x factor`` blocks (as block means x f^2), float32.

    Rows and columns beyond a multiple of ``factor`` are dropped. ``exact=False`` lets an
    8-bit image's block means be rounded to whole DN (OpenCV's fast path, a third of the
    time of the exact sums at 8 MP).
    """
    a = np.asarray(image)
    if a.dtype.type is np.uint8 and factor > 1 and exact:
        # OpenCV's area resampling rounds each block mean to a whole DN: on a dark 8-bit frame
        # (a background of 0.4 DN, its noise mostly the pixels' rounding) that loses a faint
        # spot's light and makes the block sums' noise coarse and non-Gaussian (steps of f^2 a
        # channel). Scaled by f^2 in 16 bits first (255 f^2 fits up to f = 16), every halving's
        # mean is a whole number: the block sums are exact.
        b = a.astype(np.uint16)
        b *= np.uint16(factor * factor)
        return _halve_to_sum(b, factor, np.float32(1.0))
    if a.dtype.type not in (np.uint8, np.uint16, np.float32):
        a = a.astype(np.float32)
    return _halve_to_sum(a, factor, np.float32(factor * factor))


def _halve_to_sum(a: np.ndarray, factor: int, scale: np.float32) -> np.ndarray:
    """``a`` halved ``log2 factor`` times (area means), channels summed, times ``scale``, float32."""
    f = 1
    while f < factor:  # halve at a time: OpenCV's 2x area path is the fast one
        h, w = a.shape[0] // 2, a.shape[1] // 2
        a = cv2.resize(a[: 2 * h, : 2 * w], (w, h), interpolation=cv2.INTER_AREA)
        f *= 2
    a = np.asarray(a)
    # x f^2 in the same pass (a power of two: exact, so the same as scaling the sum after)
    if a.ndim == 3:
        s = cv2.transform(a.astype(np.float32, copy=False), np.full((1, 3), scale, np.float32))
    else:
        # a float32 copy scaled in place: the same values as np.multiply(a, f2,
        # dtype=np.float32), whose mixed-type loop on an integer image costs 3x more
        s = a.astype(np.float32)
        s *= scale
    return np.asarray(s, np.float32).reshape(a.shape[:2])


def block_pair_differences(image: np.ndarray, f: int, samples: int = 60_000) -> np.ndarray:
    """Exact differences of horizontally neighbouring ``f x f`` block channel sums, on a grid, (n,).

    About ``samples`` pairs of :func:`block_sum`'s blocks (``exact=True``), summed in int64
    from the blocks' own pixels: only the sampled rows are copied (``1 / step`` of the
    frame), not the whole frame in 16 bits as the exact block sums take it.
    """
    a = np.asarray(image)
    H, W = a.shape[:2]
    h, w = H // f, W // f
    step = max(1, int(math.sqrt(h * w / samples)))
    n = (w - 1) // step
    if h == 0 or n <= 0:
        return np.zeros(0)
    rows = (np.arange(0, h, step)[:, None] * f + np.arange(f)[None]).ravel()
    left = (np.arange(n) * step)[:, None] * f + np.arange(f)[None]  # (n, f) pixel columns
    band = a[rows]  # (h' f, W[, C])
    sums = []
    for cols in (left, left + f):
        blk = band[:, cols.ravel()].reshape(-1, f, n, f, *a.shape[2:])
        sums.append(blk.sum(axis=tuple(i for i in range(blk.ndim) if i not in (0, 2)), dtype=np.int64))
    return (sums[1] - sums[0]).ravel()
