"""Bloom: glare spread around each bright light, point-symmetric so no centroid moves.

A fraction ``f`` (``scene.bloom_fraction``) of each light's spot is scattered into a wide
Gaussian of ``sigma = scene.bloom_sigma_mrad`` milliradians (``sigma_mrad * 1e-3 * f_px``
pixels): the spot's patch ``P`` becomes ``(1 - f) P + f (G * P)`` on a window grown by
``4 sigma`` each side. The kernel ``G`` is symmetric and sums to 1 and the window holds all
of its support, so the patch's total light and its centroid are unchanged exactly (the
convolution of two distributions adds their means, and ``G``'s is zero): the recorded
truth, light centroid included, holds as it was. The splat's recorded core flux is the
``1 - f`` left in the core. Cost: one Gaussian blur per light on its window.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from deckpose.render.beacons import Splat

from deckpose.camera import CameraModel

__all__ = ["bloom", "bloom_sigma_px"]


def bloom_sigma_px(sigma_mrad: float, camera: CameraModel) -> float:
    """The glare's standard deviation in pixels: ``sigma_mrad * 1e-3 * sqrt(fx fy)``."""
    return sigma_mrad * 1e-3 * math.sqrt(camera.fx * camera.fy)


def bloom(splats: list[Splat], fraction: float, sigma_px: float) -> list[Splat]:
    """Each splat with ``fraction`` of its light spread by a Gaussian of ``sigma_px`` (new splats).

    Parameters
    ----------
    splats : list of Splat
    fraction : float
        In [0, 1); 0 returns ``splats`` as they are.
    sigma_px : float
        Glare standard deviation, pixels (> 0).

    Returns
    -------
    list of Splat
        Windows grown by ``ceil(4 sigma_px)`` each side, ``core_flux`` times ``1 - fraction``.
    """
    if fraction <= 0.0:
        return splats
    pad = max(1, math.ceil(4.0 * sigma_px))
    k = 2 * pad + 1
    out = []
    for sp in splats:
        big = cv2.copyMakeBorder(sp.patch.astype(np.float32), pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0.0)
        glare = cv2.GaussianBlur(big, (k, k), sigma_px, sigmaY=sigma_px, borderType=cv2.BORDER_CONSTANT)
        patch = cv2.addWeighted(big, 1.0 - fraction, glare, fraction, 0.0)
        out.append(dataclasses.replace(sp, row0=sp.row0 - pad, col0=sp.col0 - pad, patch=patch,
                                       core_flux=(1.0 - fraction) * sp.core_flux))
    return out
