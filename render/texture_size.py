"""The deck texture's size from the cameras' ground sampling distance (``scene.texture_px: auto``).

A nadir pinhole camera ``h`` metres above the deck sees ``f / h`` pixels per metre of deck
at the image centre (``f`` the focal length in pixels), its finest ground sampling. A
deck texture of side ``2 a`` metres (``a`` = ``deck_half_size_m``) is not stretched when it
has at least ``2 a f / h`` texels a side at the lowest height. The 2,048 px default is
2.7x short of that for a 64 MP camera at 30 m over a 14 m deck; the size is capped at
:data:`MAX_TEXTURE_PX` (an 8,192 px RGB texture takes 200 MB, 270 MB with mip maps).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from deckpose.camera import CameraModel

__all__ = ["MAX_TEXTURE_PX", "deck_texture_px", "texels_needed"]

#: Largest auto-sized deck texture, texels a side.
MAX_TEXTURE_PX = 8192
#: Auto sizes are rounded up to a multiple of this many texels.
TEXTURE_STEP_PX = 256


def texels_needed(focal_px: float, height_m: float, deck_half_size_m: float) -> float:
    """Texels a side for one texel per image pixel under a nadir camera, ``2 a f / h``.

    Parameters
    ----------
    focal_px : float
        Focal length, pixels.
    height_m : float
        Camera height above the deck, metres.
    deck_half_size_m : float
        Half the side of the square deck, metres.
    """
    return 2.0 * deck_half_size_m * focal_px / height_m


def deck_texture_px(cameras: Sequence[CameraModel], min_height_m: float, deck_half_size_m: float) -> int:
    """The auto deck texture side, texels: :func:`texels_needed` for the sharpest camera at the
    lowest height, rounded up to a multiple of :data:`TEXTURE_STEP_PX`, within [256, 8192]."""
    focal_px = max(max(c.fx, c.fy) for c in cameras)
    need = texels_needed(focal_px, min_height_m, deck_half_size_m)
    return int(min(MAX_TEXTURE_PX, max(TEXTURE_STEP_PX, math.ceil(need / TEXTURE_STEP_PX) * TEXTURE_STEP_PX)))
