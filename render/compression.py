"""Lossy compression: a frame JPEG-encoded and decoded in memory, as a camera's stream would be.

``sensor.jpeg_quality`` (1..100, 8-bit frames only) passes the quantised frame through
OpenCV's JPEG encoder (libjpeg's baseline coder: 8x8 DCT, the standard quantisation
tables scaled by the quality, 4:2:0 chroma subsampling for colour frames) and back;
the decoded frame is what is stored (lossless PNG of it), so a detector sees the
blocking and ringing of the compression. Beacons' truth is untouched: the compression
only moves the light's DN, not the geometry.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["jpeg_round_trip"]


def jpeg_round_trip(image: NDArray[np.uint8], quality: int) -> NDArray[np.uint8]:
    """The frame after JPEG encoding at ``quality`` and decoding.

    Parameters
    ----------
    image : (H, W, 3) RGB or (H, W) mono array of uint8
    quality : int
        1..100 (``cv2.IMWRITE_JPEG_QUALITY``).

    Returns
    -------
    array of uint8, the shape of ``image``
    """
    if image.dtype != np.uint8:
        raise ValueError(f"jpeg_round_trip: JPEG holds 8-bit images, got {image.dtype}")
    colour = image.ndim == 3
    bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if colour else image
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("jpeg_round_trip: OpenCV could not encode the frame as JPEG")
    out = cv2.imdecode(buf, cv2.IMREAD_COLOR if colour else cv2.IMREAD_GRAYSCALE)
    if out is None:
        raise RuntimeError("jpeg_round_trip: OpenCV could not decode the JPEG it encoded")
    decoded = np.asarray(cv2.cvtColor(out, cv2.COLOR_BGR2RGB) if colour else out, np.uint8)
    return decoded
