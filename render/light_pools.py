"""The beacons' light on the deck around them: pools of light at night and dusk.

Each beacon is a point source of intensity ``I`` (``scene.light_pools_cd``, candela toward
the deck) at the height ``h`` of its light above the deck (the layout's
``beacon_radius_m``: the top of a dome, an assumption for a flush disc). The illuminance it
gives a deck point at distance ``r`` from its foot is the inverse-square law times the
cosine of the incidence on the deck,

    E(r) = I cos(theta) / d^2 = I h / (h^2 + r^2)^(3/2)    lux,   d^2 = h^2 + r^2,

coloured by the beacon's colour and summed over the beacons. The deck's radiance is its
albedo times its illuminance, so the lit deck is the rendered deck times
``1 + E / E_ambient`` per channel, ``E_ambient`` the preset's ambient illuminance
(:data:`AMBIENT_LUX`). That gain is computed once per dataset on a deck-frame texture
(:func:`pool_gain`) and applied per frame to the deck in the raster through the deck
plane's homography (:func:`apply_light_pools`), before the lens distortion; the beacon
spots are added later and are unchanged.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.render.scene_config import Lighting
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck

__all__ = ["AMBIENT_LUX", "POOL_TEXTURE_PX", "apply_light_pools", "pool_gain", "pool_illuminance_lux"]

#: Ambient illuminance on the deck per preset, lux: full moonlight ~0.1 lux (night), a deck in
#: civil twilight ~20 lux (dusk; twilight spans ~3-400 lux), an overcast day ~20,000 lux.
AMBIENT_LUX: dict[Lighting, float] = {Lighting.NIGHT: 0.1, Lighting.DUSK: 20.0, Lighting.DAY: 20000.0}
#: Fixed-point one of the gain in :func:`apply_light_pools` (gains are applied in 1/256 steps).
_GAIN_ONE = 256
#: Regions larger than this many pixels get the gain warped at a lower resolution and enlarged.
_FULL_WARP_PX = 2_000_000
#: Side of the deck-frame gain texture, texels (5.5 cm texels on a 28 m deck; the pools are smooth).
POOL_TEXTURE_PX = 512


def pool_illuminance_lux(sources_m: NDArray[np.float64], intensity_cd: float,
                         points_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Illuminance of point sources on deck points, ``sum_b I h_b / d_b^3``, lux.

    Parameters
    ----------
    sources_m : (N, 3) array of float
        Sources in the deck frame (``z`` > 0: height above the deck), metres.
    intensity_cd : float
        Each source's intensity toward the deck, candela.
    points_m : (M, 2) array of float
        Deck points ``(x, y)``, metres.

    Returns
    -------
    (M, N) array of float
        Lux from each source at each point.
    """
    src = np.asarray(sources_m, float).reshape(-1, 3)
    pts = np.asarray(points_m, float).reshape(-1, 2)
    r2 = ((pts[:, None, :] - src[None, :, :2]) ** 2).sum(axis=2)
    h = src[None, :, 2]
    return intensity_cd * h / (h * h + r2) ** 1.5


def pool_gain(layout: DeckLayout, deck_half_size_m: float, intensity_cd: float, ambient_lux: float,
              size_px: int = POOL_TEXTURE_PX) -> NDArray[np.float32]:
    """The deck's brightening ``1 + E / E_ambient`` per channel on a deck-frame texture.

    Texel ``(row, col)`` is deck point ``x = a - (row + 0.5) / s``, ``y = a - (col + 0.5) / s``
    (``a`` the deck's half side, ``s`` texels per metre): row 0 at the bow, column 0 at
    port, as :func:`deckpose.render.scene.deck_texture`.

    Returns
    -------
    (size_px, size_px, 3) array of float32
    """
    a = deck_half_size_m
    c = a - (np.arange(size_px) + 0.5) * (2.0 * a / size_px)
    xx, yy = np.meshgrid(c, c, indexing="ij")
    src = np.asarray(layout.positions_deck_m(), float).copy()
    src[:, 2] += layout.beacon_radius_m
    lux = pool_illuminance_lux(src, intensity_cd, np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64))
    rgb = np.array(layout.beacon_rgb_all(), float)  # (N, 3)
    gain = 1.0 + (lux @ rgb) / ambient_lux
    return gain.reshape(size_px, size_px, 3).astype(np.float32)


def apply_light_pools(raster: NDArray[np.uint8], gain: NDArray[np.float32], deck_half_size_m: float,
                      camera: CameraModel, camera_pose: CameraPose, ship: ShipPose) -> None:
    """Multiply the deck in a pinhole raster by the gain texture, in place (saturating at 255).

    Parameters
    ----------
    raster : (H, W, 3) array of uint8
        Drawn through ``camera`` (no distortion), modified in place.
    gain : (S, S, 3) array of float32
        From :func:`pool_gain`.
    deck_half_size_m : float
    camera : CameraModel
        The pinhole camera the raster was drawn through.
    camera_pose, ship
        The frame's poses.
    """
    s = gain.shape[0]
    a = deck_half_size_m
    step = 2.0 * a / s
    texel_to_deck = np.array([[0.0, -step, a - 0.5 * step], [-step, 0.0, a - 0.5 * step], [0.0, 0.0, 1.0]])
    T = T_cam_from_deck(ship, camera_pose)
    Hm = camera.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ texel_to_deck  # texel -> pixel
    corners = np.array([[0, 0, 1], [s, 0, 1], [s, s, 1], [0, s, 1]], float) - [0.5, 0.5, 0]
    img = corners @ Hm.T
    H, W = raster.shape[:2]
    if np.all(img[:, 2] > 0):  # the whole deck in front of the camera: warp its bounding box only
        uv = img[:, :2] / img[:, 2:]
        c0, r0 = (max(0, math.floor(v) - 1) for v in uv.min(axis=0))
        c1, r1 = min(W, math.ceil(uv[:, 0].max()) + 2), min(H, math.ceil(uv[:, 1].max()) + 2)
    else:
        c0, r0, c1, r1 = 0, 0, W, H
    if c0 >= c1 or r0 >= r1:
        return
    shift = np.array([[1.0, 0.0, -c0], [0.0, 1.0, -r0], [0.0, 0.0, 1.0]])
    # fixed point, 1/256 steps (gains to 255): 16-bit warp and multiply, rounded and saturated to 8 bits
    gain_q = np.round(np.minimum(gain, 255.0) * _GAIN_ONE).astype(np.uint16)
    w, h = c1 - c0, r1 - r0
    # the gain is smooth (5.5 cm texels): over a large region, warp it at 1/q of the image's
    # resolution (still finer than the texture) and enlarge it, a third of the time at 64 MP
    q = max(1, min(8, math.floor(math.sqrt(w * h / _FULL_WARP_PX))))
    down = np.array([[1.0 / q, 0.0, 0.5 / q - 0.5], [0.0, 1.0 / q, 0.5 / q - 0.5], [0.0, 0.0, 1.0]])
    g = cv2.warpPerspective(gain_q, down @ shift @ Hm, (math.ceil(w / q), math.ceil(h / q)),
                            flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(_GAIN_ONE,) * 3)
    if q > 1:
        g = cv2.resize(g, (math.ceil(w / q) * q, math.ceil(h / q) * q), interpolation=cv2.INTER_LINEAR)[:h, :w]
    region = raster[r0:r1, c0:c1]
    region[...] = cv2.multiply(region.astype(np.uint16), g, scale=1.0 / _GAIN_ONE, dtype=cv2.CV_8U)
