"""Specular glints: where a rough water surface shows the camera the sun (or the moon).

A glint is a small facet of water tilted so that it mirrors the light source into the
camera. For a facet with unit normal ``n`` lit from the unit direction ``s`` (surface
toward the light), the mirrored ray leaves along ``r = 2 (s . n) n - s``; the camera at
``C`` sees it at the point ``X = C - t r`` where that ray meets the water's mean plane
(``t > 0``). So a glint's place follows from its facet's slope, and drawing the slopes
from the surface's slope distribution draws the glitter pattern itself: centred on the
mirror point of the mean plane, spread by the roughness, denser where the slopes are
likely. This is Cox and Munk's model of sun glitter (C. Cox, W. Munk, "Measurement of the
roughness of the sea surface from photographs of the sun's glitter", J. Opt. Soc. Am. 44,
838-850, 1954): a Gaussian slope distribution of mean square slope
``0.003 + 5.12e-3 U`` for a wind of ``U`` m/s (clean surface, both axes together; here
isotropic, half of it per axis).

Two surfaces carry glints (:mod:`deckpose.render.ship_lights` draws them as lights):

* the sea, whose mean plane is the world's ``z = -freeboard``; the facets are world-fixed
  for the frame;
* a wet deck: the deck plate's plane (deck ``z = 0``, moving with the ship), a film of
  water over the non-skid grain whose facets tilt by ``deck_slope_deg`` RMS per axis
  (default 10 degrees, an assumption: a smooth film of 2 degrees mirrors the sun only
  where its mirror point falls on the plate, which for this sun and a camera above the
  deck it rarely does); only points on the plate count.

:func:`glint_points` keeps facets whose point lies in the image (and, for the deck, on the
plate) and whose mirrored ray reaches the camera past the ship (the deck plate, and the hull
and superstructure where the scene has them: a sea glint under the deck is not seen),
drawing in batches until it has the number asked for or has tried ``MAX_TRIES_PER_GLINT``
times as many: a light behind the camera's view gives fewer glints, or none, as it would.
The sunlight's own way to a facet is not tested against the ship's shadow: for this sun,
54.5 degrees up, that would hide 0-1 of 256 glints at 30-80 m.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.pose import CameraPose

__all__ = ["MAX_TRIES_PER_GLINT", "cox_munk_slope_sigma", "facet_mirror_points", "glint_points"]

#: Facets drawn per glint asked for before :func:`glint_points` gives up on the rest.
MAX_TRIES_PER_GLINT = 200


def cox_munk_slope_sigma(wind_m_per_s: float) -> float:
    """RMS sea-surface slope per axis for a wind speed (Cox and Munk 1954, clean surface).

    Parameters
    ----------
    wind_m_per_s : float
        Wind speed, m/s (Cox and Munk's at 12.5 m above the sea).

    Returns
    -------
    float
        ``sqrt((0.003 + 5.12e-3 U) / 2)``: the mean square slope of both axes, split evenly.
    """
    return math.sqrt((0.003 + 5.12e-3 * wind_m_per_s) / 2.0)


def facet_mirror_points(slopes: NDArray[np.float64], R_world_from_plane: NDArray[np.float64],
                        plane_point_world_m: NDArray[np.float64], to_light_world: NDArray[np.float64],
                        camera_centre_world_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Where facets of given slopes must lie on a plane to mirror the light into the camera.

    Parameters
    ----------
    slopes : (N, 2) array of float
        Each facet's slopes ``(dz/dx, dz/dy)`` in the plane's frame (its z axis the normal).
    R_world_from_plane : (3, 3) array of float
        The plane's frame in the world.
    plane_point_world_m : (3,) array of float
        A point of the plane, metres.
    to_light_world : (3,) array of float
        Unit direction from the surface toward the light.
    camera_centre_world_m : (3,) array of float
        The camera's centre, metres.

    Returns
    -------
    (N, 3) array of float
        Each facet's point in the world, metres; NaN where the light is not above the plane,
        the facet faces away from it, or its mirrored ray does not rise from the plane toward
        the camera.
    """
    s = np.asarray(slopes, float).reshape(-1, 2)
    n_plane = np.column_stack([-s[:, 0], -s[:, 1], np.ones(len(s))])
    n = (n_plane / np.linalg.norm(n_plane, axis=1, keepdims=True)) @ np.asarray(R_world_from_plane).T
    light = np.asarray(to_light_world, float)
    cos_i = n @ light
    r = 2.0 * cos_i[:, None] * n - light
    normal = np.asarray(R_world_from_plane)[:, 2]
    height = float((np.asarray(camera_centre_world_m) - plane_point_world_m) @ normal)
    rise = r @ normal
    ok = (cos_i > 0) & (rise > 1e-9) & (height > 0) & (float(light @ normal) > 0)
    t = np.where(ok, height / np.where(ok, rise, 1.0), np.nan)
    return np.asarray(camera_centre_world_m)[None, :] - t[:, None] * r


def glint_points(n_glints: int, slope_sigma: float, R_world_from_plane: NDArray[np.float64],
                 plane_point_world_m: NDArray[np.float64], to_light_world: NDArray[np.float64],
                 camera_pose: CameraPose, camera: CameraModel, rng: np.random.Generator,
                 half_extent_m: float | None = None, occluder_world: trimesh.Trimesh | None = None
                 ) -> NDArray[np.float64]:
    """Up to ``n_glints`` glints in the image, drawn from the surface's glitter pattern.

    Parameters
    ----------
    n_glints : int
        Glints asked for.
    slope_sigma : float
        RMS facet slope per axis (dimensionless; :func:`cox_munk_slope_sigma` for the sea).
    R_world_from_plane, plane_point_world_m, to_light_world
        As for :func:`facet_mirror_points`.
    camera_pose : CameraPose
    camera : CameraModel
    rng : numpy.random.Generator
        The frame's glint stream.
    half_extent_m : float, optional
        Keep only points within this distance of ``plane_point_world_m`` along both of the
        plane's in-plane axes (the deck plate); None: the plane is unbounded (the sea).
    occluder_world : trimesh.Trimesh, optional
        What may stand between a glint and the camera (the ship, world frame, metres).

    Returns
    -------
    (K, 3) array of float
        World points of the glints, ``K <= n_glints``, in the order drawn.
    """
    if n_glints <= 0:
        return np.zeros((0, 3))
    R = np.asarray(R_world_from_plane, float)
    P0 = np.asarray(plane_point_world_m, float)
    C = camera_pose.position_world_m
    T = camera_pose.T_cam_from_world
    kept: list[NDArray[np.float64]] = []
    batch = max(64, 4 * n_glints)
    drawn = n_kept = 0
    while n_kept < n_glints and drawn < MAX_TRIES_PER_GLINT * n_glints:
        X = facet_mirror_points(rng.normal(0.0, slope_sigma, (batch, 2)), R, P0, to_light_world, C)
        drawn += batch
        X = X[np.isfinite(X).all(axis=1)]
        if half_extent_m is not None:
            local = (X - P0) @ R
            X = X[np.all(np.abs(local[:, :2]) <= half_extent_m, axis=1)]
        pc = X @ T[:3, :3].T + T[:3, 3]
        X, pc = X[pc[:, 2] > 1e-6], pc[pc[:, 2] > 1e-6]
        if len(X):
            X = X[camera.in_image(camera.project(pc))]
        if len(X) and occluder_world is not None:
            X = X[~_hidden(X, C, occluder_world)]
        kept.append(X)
        n_kept += len(X)
    return np.concatenate(kept)[:n_glints]


def _hidden(X: NDArray[np.float64], camera_centre_world_m: NDArray[np.float64], occluder: trimesh.Trimesh
            ) -> NDArray[np.bool_]:
    """Whether the segment from each point to the camera crosses a triangle of the occluder; (N,) bool.

    Moller-Trumbore for every segment and triangle at once (the ship has a few dozen
    triangles); a hit within 1 mm of the point is the surface the point lies on, not an occluder.
    """
    seg = camera_centre_world_m[None, :] - X  # (N, 3), parameter t in [0, 1] along it
    tri = np.asarray(occluder.triangles, float)  # (T, 3, 3)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    pvec = np.cross(seg[:, None, :], e2[None])  # (N, T, 3)
    det = np.einsum("ntk,tk->nt", pvec, e1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = X[:, None, :] - tri[None, :, 0]
    u = np.einsum("ntk,ntk->nt", tvec, pvec) * inv
    qvec = np.cross(tvec, e1[None])
    v = np.einsum("nk,ntk->nt", seg, qvec) * inv
    t = np.einsum("tk,ntk->nt", e2, qvec) * inv
    eps_t = 1e-3 / np.linalg.norm(seg, axis=1)[:, None]
    return np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps_t) & (t < 1.0 - eps_t), axis=1)
