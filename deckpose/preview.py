"""The downscaled 8-bit preview of a frame that viewers show (one rule for render and the log).

A frame of up to 64 MP is shrunk so that its long side is at most ``preview_px``
(OpenCV ``INTER_AREA``) and a 16-bit frame keeps its top 8 bits. The render stage
writes this preview next to each frame (``previews/<frame_id>.png``,
:func:`deckpose.run_folder.preview_relpath`), so the MCAP log does not decode the
full frame again; a log with another ``preview_px`` makes its own from the frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: The preview's long side, pixels, that the render stage writes (and the log's default).
PREVIEW_PX = 1920


def preview_scale(width_px: int, height_px: int, preview_px: int) -> float:
    """Downscale factor (<= 1) that brings the long side of a ``width_px x height_px`` frame to ``preview_px``."""
    return min(1.0, preview_px / max(width_px, height_px))


def preview_size(width_px: int, height_px: int, preview_px: int) -> tuple[int, int]:
    """``(width, height)`` of the preview, pixels."""
    s = preview_scale(width_px, height_px, preview_px)
    if s >= 1.0:
        return width_px, height_px
    return max(1, round(width_px * s)), max(1, round(height_px * s))


def make_preview(image: NDArray[np.generic], preview_px: int) -> NDArray[np.uint8]:
    """The 8-bit preview of an image (H, W) or (H, W, C), 8- or 16-bit, channel order kept.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array of uint8 or uint16
    preview_px : int
        Long side of the preview, pixels.

    Returns
    -------
    (h, w) or (h, w, C) array of uint8
        ``(w, h)`` is :func:`preview_size`.
    """
    import cv2

    if image.ndim == 3 and image.strides[2] < 0:  # a channel-reversed view (RGB <-> BGR) of a frame:
        # shrink the frame as stored and reverse the small result's channels (each channel is
        # shrunk alone, so the pixels are the same); OpenCV would copy the whole view first
        return np.ascontiguousarray(make_preview(image[..., ::-1], preview_px)[..., ::-1])
    img = np.right_shift(image, 8).astype(np.uint8) if image.dtype == np.uint16 else np.asarray(image, np.uint8)
    w, h = preview_size(img.shape[1], img.shape[0], preview_px)
    if (w, h) != (img.shape[1], img.shape[0]):
        img = np.asarray(cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA), dtype=np.uint8)
    return img
