"""Colour filter array: a Bayer mosaic (each photosite keeps one channel) and its demosaicing.

A sensor with ``sensor.bayer`` set records, at each pixel, only the channel of its
filter; :func:`deckpose.render.sensor.expose` draws the noise on that one value and
quantises the mosaic, and :func:`demosaic` turns it back into RGB with OpenCV's
bilinear demosaicing (``cv2.COLOR_Bayer**2RGB``).

Why bilinear: it is linear and, for each channel, a convolution of that channel's
samples with a point-symmetric kernel (red and blue: weights 1, 1/2, 1/4 over the 3x3
neighbourhood, summing to 4; green: 1 and four 1/4, summing to 2). So each channel's
demosaiced spot has the centroid of its samples and the total light of the
full-resolution channel (to the aliasing of the 2-pixel lattice), which keeps the
beacons' truth analysable. The edge-aware (``_EA``) variant chooses its green
interpolation direction from the data (non-linear) and VNG is non-linear, 8-bit only
and several times slower.

OpenCV names a pattern by the 2x2 block starting at the *second* row and column, so
the sensor layout RGGB is ``COLOR_BayerBG2RGB`` (``tests/render/test_sensor_effects.py``
checks every code on a synthetic mosaic).
"""

from __future__ import annotations

import cv2
import numpy as np
from deckpose.render.sensor_config import BayerPattern
from numpy.typing import NDArray

__all__ = ["CHANNEL_INDEX", "demosaic", "filter_channels", "select_mosaic"]

#: Channel index (R 0, G 1, B 2) of each pattern's top-left 2x2 block, row by row.
CHANNEL_INDEX: dict[BayerPattern, tuple[int, int, int, int]] = {
    BayerPattern.RGGB: (0, 1, 1, 2),
    BayerPattern.BGGR: (2, 1, 1, 0),
    BayerPattern.GRBG: (1, 0, 2, 1),
    BayerPattern.GBRG: (1, 2, 0, 1),
}

#: OpenCV's bilinear demosaicing code for each sensor layout (OpenCV's names are shifted by one pixel).
_CV_CODE: dict[BayerPattern, int] = {
    BayerPattern.RGGB: cv2.COLOR_BayerBG2RGB,
    BayerPattern.BGGR: cv2.COLOR_BayerRG2RGB,
    BayerPattern.GRBG: cv2.COLOR_BayerGB2RGB,
    BayerPattern.GBRG: cv2.COLOR_BayerGR2RGB,
}


def filter_channels(pattern: BayerPattern, height_px: int, width_px: int, row0: int = 0,
                    col0: int = 0) -> NDArray[np.intp]:
    """The filter channel (0 R, 1 G, 2 B) of every pixel of rows ``row0 ..`` and columns ``col0 ..``.

    Returns
    -------
    (height_px, width_px) array of int
    """
    block = np.array(CHANNEL_INDEX[pattern], np.intp).reshape(2, 2)
    rows = (np.arange(height_px) + row0) % 2
    cols = (np.arange(width_px) + col0) % 2
    return block[rows[:, None], cols[None, :]]


def select_mosaic(rgb: NDArray[np.float32], pattern: BayerPattern, row0: int,
                  out: NDArray[np.float32]) -> None:
    """Keep each pixel's filter channel: ``out[r, c] = rgb[r, c, channel(row0 + r, c)]``.

    Parameters
    ----------
    rgb : (h, W, 3) array of float32
        Rows ``row0 ..`` of the full-resolution image (any unit).
    pattern : BayerPattern
        Not ``NONE``.
    row0 : int
        Image row of ``rgb[0]`` (its parity picks the pattern's row).
    out : (h, W) array of float32
        Written in place.
    """
    ch = CHANNEL_INDEX[pattern]
    for dy in range(2):
        for dx in range(2):
            k = ch[2 * ((row0 + dy) % 2) + dx]
            out[dy::2, dx::2] = rgb[dy::2, dx::2, k]


def demosaic(mosaic: np.ndarray, pattern: BayerPattern) -> np.ndarray:
    """Bilinear demosaicing of a quantised mosaic into RGB (OpenCV).

    Parameters
    ----------
    mosaic : (H, W) array of uint8 or uint16
        DN; ``H`` and ``W`` at least 2.
    pattern : BayerPattern
        The sensor's layout (not ``NONE``).

    Returns
    -------
    (H, W, 3) array of the mosaic's dtype
        RGB, DN.
    """
    if mosaic.ndim != 2:
        raise ValueError(f"demosaic: expected an (H, W) mosaic, got shape {mosaic.shape}")
    return cv2.cvtColor(mosaic, _CV_CODE[pattern])
