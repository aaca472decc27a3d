"""The emitter's shape: where a beacon's light is centred in the image.

A ``flat`` emitter (a disc in the deck plane, the default) is imaged, to first order,
centred on the projection of its centre, which is the pose truth. Real beacons sit
under domes: a ``dome`` emitter is a hemisphere of the beacon's radius on the deck,
of constant radiance. Its image is the projection of the part of the dome the camera
sees, each surface element as bright as any other, so its light centroid is the
centroid of the projected visible surface: surface points ``p`` with outward normal
``n``, each weighted by the image area of its element, ``fx fy dA max(0, n . (c - p)) / z^3``
(``c`` the camera centre, ``z`` the point's depth; lens distortion, which moves the
element but barely changes its area across a dome, is applied to the positions only),
projected through the full camera model. The visible part leans toward the camera
while its light stands above the deck, and the two nearly cancel: what is left is a
fraction of a pixel, outward from the image centre (0.3 px for a 0.4 m dome 10 m off
the nadir seen from 30 m with a 900 px focal length; ``tests/render/test_realism.py``
checks it against ray casting).

The dome is sampled on a fixed equal-area (Fibonacci) grid of :data:`DOME_SAMPLES`
points, so the centroid is a deterministic function of the geometry; the sampling
error is below 1e-3 of the dome's image radius.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout

#: Points of the equal-area grid on the unit hemisphere.
DOME_SAMPLES = 2000


def _hemisphere_grid(n: int) -> NDArray[np.float64]:
    """(n, 3) unit vectors on the upper hemisphere, equal area each (Fibonacci lattice in z)."""
    k = np.arange(n) + 0.5
    z = 1.0 - k / n  # uniform in z on (0, 1]: equal area on a sphere (Archimedes)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


_GRID = _hemisphere_grid(DOME_SAMPLES)
_GRID.setflags(write=False)


def dome_light_centroids(layout: DeckLayout, T_cam_from_deck: NDArray[np.float64],
                         camera: CameraModel) -> NDArray[np.float64]:
    """Image centroid of each domed beacon's light.

    Parameters
    ----------
    layout : DeckLayout
        Beacon positions and radius (the dome's radius).
    T_cam_from_deck : (4, 4) array of float, or (N, k, 4, 4)
        Deck to camera transform; or beacon ``i``'s own transform at each of ``k``
        sub-poses (the rolling shutter's, :func:`deckpose.render.beacons.splats_under`).
    camera : CameraModel

    Returns
    -------
    (N, 2) or (N, k, 2) array of float
        ``(u, v)`` per beacon id (and sub-pose), pixels; NaN where no part of the dome
        faces the camera or a sample lies behind it.
    """
    T = np.asarray(T_cam_from_deck, float)
    centres = layout.positions_deck_m()
    if T.ndim == 2:
        return np.stack([_dome_centroid(c, layout.beacon_radius_m, T, camera) for c in centres])
    return np.stack([np.stack([_dome_centroid(c, layout.beacon_radius_m, Tj, camera) for Tj in T[i]])
                     for i, c in enumerate(centres)])


def _dome_centroid(centre_deck_m: NDArray[np.float64], radius_m: float, T_cam_from_deck: NDArray[np.float64],
                   camera: CameraModel) -> NDArray[np.float64]:
    """The image centroid ``(u, v)`` of one dome's light under one transform (NaN: not seen)."""
    R, t = T_cam_from_deck[:3, :3], T_cam_from_deck[:3, 3]
    cam_in_deck = -R.T @ t
    p = centre_deck_m + radius_m * _GRID  # (S, 3) deck frame
    facing = np.einsum("ij,ij->i", _GRID, cam_in_deck - p)  # n . (camera - p), metres
    keep = facing > 0
    if not keep.any():
        return np.full(2, np.nan)
    pc = p[keep] @ R.T + t
    if np.any(pc[:, 2] <= 1e-6):
        return np.full(2, np.nan)
    w = facing[keep] / pc[:, 2] ** 3  # image area of the element: fx fy dA n.(c - p) / z^3
    uv = camera.project(pc)
    return np.asarray((w[:, None] * uv).sum(axis=0) / w.sum(), float)
