"""How a run stores its frames: lossless PNG (the default) or Zstandard-compressed arrays.

Measured by ``benchmarks/bench_image_store.py`` on rendered thesis-sweep frames (one core,
``reports/throughput/image_store.txt``): encoding plus decoding a 64 MP 8-bit RGB frame
takes 2.7 s as PNG (level 1, SUB filter) and 0.9 s as a Zstandard (level 1) array, at
1.1x the PNG's size; uncompressed TIFF is faster still but 7x larger; TIFF with Deflate
and WebP lossless are 3.6x and 10x slower. PNG stays the default because every tool
reads it; ``image_format: zstd`` in a render config stores ``images/<id>.zst`` instead:

    b"DKPZ" | version u8 | dtype code u8 (1 = uint8, 2 = uint16, little-endian) | ndim u8 |
    reserved u8 | shape as ndim little-endian u32 | Zstandard frame of the C-order pixels

with colour channels in OpenCV's order (BGR), as a decoded PNG has them, so every
reader of this module handles both alike. numpy and ``zstandard`` (``pip install
zstandard``) read it in five lines; :func:`decode_image` is the reference.
"""

from __future__ import annotations

import enum
import struct
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import InputDataError

#: A frame's pixels: 8- or 16-bit, (H, W) or (H, W, 3).
Pixels = NDArray[np.unsignedinteger[Any]]


class ImageFormat(enum.Enum):
    """How frames are stored in a run's ``images/`` folder."""

    PNG = "png"
    ZSTD = "zstd"

    @property
    def suffix(self) -> str:
        """The image files' suffix: ``.png`` or ``.zst``."""
        return ".png" if self is ImageFormat.PNG else ".zst"


#: Zstandard level of ``.zst`` frames: level 1 (level 3 is 30 % slower for 1 % less).
ZSTD_LEVEL = 1

_MAGIC = b"DKPZ"
_VERSION = 1
_DTYPES = {1: np.dtype("<u1"), 2: np.dtype("<u2")}
_CODES = {np.dtype("uint8"): 1, np.dtype("uint16"): 2}


def _png_params() -> list[int]:
    """PNG encoder settings: the SUB filter at OpenCV's default level 1 (``bench_image_store``)."""
    import cv2

    return [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_SUB]


def encode_image(image_bgr: Pixels, fmt: ImageFormat) -> bytes:
    """A frame's file contents.

    Parameters
    ----------
    image_bgr : (H, W) or (H, W, 3) array of uint8 or uint16
        Colour in OpenCV's channel order (BGR).
    fmt : ImageFormat

    Returns
    -------
    bytes
    """
    img = np.ascontiguousarray(image_bgr)
    if fmt is ImageFormat.PNG:
        import cv2

        ok, buf = cv2.imencode(".png", img, _png_params())
        if not ok:
            raise OSError("OpenCV could not encode the frame as PNG")
        return buf.tobytes()
    import zstandard

    code = _CODES.get(img.dtype)
    if code is None:
        raise ValueError(f"frames are 8- or 16-bit, got {img.dtype}")
    head = _MAGIC + struct.pack("<BBBB", _VERSION, code, img.ndim, 0) + struct.pack(f"<{img.ndim}I", *img.shape)
    return head + zstandard.ZstdCompressor(level=ZSTD_LEVEL).compress(img.astype(_DTYPES[code], copy=False).tobytes())


def decode_image(data: bytes, name: str = "image") -> Pixels:
    """Pixels of a PNG (or any image OpenCV reads) or a ``.zst`` frame, colour in BGR order.

    Grey stays grey (H, W), colour is (H, W, 3) (an alpha channel is dropped), 8 or 16
    bits as stored; a JPEG's EXIF orientation is applied, as OpenCV's ``imread`` does.

    Raises
    ------
    InputDataError
        Empty, truncated or not an image; ``name`` names the file in the message.
    """
    if data[:4] == _MAGIC:
        try:
            import zstandard
        except ImportError:
            raise InputDataError(f"{name} is a Zstandard frame; install zstandard (pip install zstandard)") from None
        try:
            version, code, ndim, _ = struct.unpack("<BBBB", data[4:8])
            if version != _VERSION or code not in _DTYPES or ndim not in (2, 3):
                raise ValueError(f"version {version}, dtype code {code}, {ndim} dimensions")
            shape = struct.unpack(f"<{ndim}I", data[8:8 + 4 * ndim])
            raw = zstandard.ZstdDecompressor().decompress(data[8 + 4 * ndim:])
            return cast(Pixels, np.frombuffer(raw, _DTYPES[code]).reshape(shape))  # read-only, as frames are
        except (ValueError, struct.error, zstandard.ZstdError) as exc:
            raise InputDataError(f"cannot decode {name}: a damaged .zst frame ({exc})") from None
    import cv2

    buf = np.frombuffer(data, np.uint8)
    # any depth and colour as stored (16 bits stay 16, grey stays grey, an alpha channel is
    # dropped), turned as an EXIF orientation tag says, as OpenCV's default imread and every
    # viewer show it (IMREAD_UNCHANGED would keep a rotated JPEG's pixels as the sensor wrote them)
    img = cv2.imdecode(buf, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR) if buf.size else None
    if img is None:
        raise InputDataError(f"cannot decode image {name}: empty, truncated or not an image")
    if img.dtype.kind != "u":
        raise InputDataError(f"image {name} has pixel type {img.dtype}; use 8- or 16-bit images")
    return cast(Pixels, img)
