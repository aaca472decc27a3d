"""Beacons as analytic light spots: a flat emitting disc seen through the lens, plus a glow.

Why analytic
------------
Each beacon is a flat disc of radius ``r`` on the deck plane. Its image, to first
order, is the disc pushed through the local Jacobian ``J`` (2x2, px per metre of
deck) of the full projection -- pose, pinhole and lens distortion -- at the
beacon's projected centre. We draw it as an elliptical Gaussian with covariance
``Sigma = J (r^2/4) J^T + sigma_psf^2 I`` (a uniform disc's second moment is
``r^2/4`` per axis), plus a wider, fainter halo (``halo_scale * sqrt(Sigma)``) for
the glow. The spot is centred exactly on the projected centre that
:func:`deckpose.projection.project_layout` returns, so the ground truth is exact
by construction; point sampling a Gaussian with ``sigma >= 0.5 px`` biases its
centroid by less than 1e-4 px (the aliasing term falls as
``exp(-2 pi^2 sigma^2)``). A flat disc's perspective image is centred on the
projected centre to first order (a sphere's is not), which is why the emitter is
flat. Motion blur averages the spot over the deck poses of the exposure.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from deckpose.render.emitter import dome_light_centroids
from deckpose.render.leds_config import EmitterShape, LedSpec
from deckpose.render.light import beacon_flux
from deckpose.render.sensor_config import SensorSpec
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck


@dataclass(frozen=True)
class Splat:
    """One beacon's light in an image window.

    Attributes
    ----------
    row0, col0 : int
        Image position of ``patch[0, 0]`` (may lie outside the image).
    patch : (h, w) or (h, w, 3) array of float32
        Radiance profile (white = 1 before the colour); (h, w, 3) after the optics
        (:mod:`deckpose.render.optics`), one profile per channel, each times ``rgb[c]``.
    rgb : (3,) array of float32
        Beacon colour.
    beacon_id : int
        Index of the beacon in the layout.
    sigma_px : float
        Gaussian-equivalent standard deviation of the core, pixels: ``det(S)**(1/4)``
        of the core's second-moment matrix ``S`` over the exposure (mean of the
        sub-pose covariances plus the spread of the sub-pose centres).
    core_flux : float
        Radiance summed over the core (white = 1 before the colour), radiance x pixels;
        the halo (``halo_fraction`` of the light) is not included.
    centre_px : (2,) array of float
        Mean centre ``(u, v)`` of the core over the exposure, pixels.
    cov_px2 : (2, 2) array of float
        The core's second-moment matrix over the exposure, px^2 (``sigma_px = det**0.25``).
    """

    row0: int
    col0: int
    patch: NDArray[np.float32]
    rgb: NDArray[np.float32]
    beacon_id: int = -1
    sigma_px: float = float("nan")
    core_flux: float = float("nan")
    centre_px: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    cov_px2: NDArray[np.float64] = field(default_factory=lambda: np.full((2, 2), np.nan))


def _centre_and_jacobian(layout: DeckLayout, ship: ShipPose, camera_pose: CameraPose,
                         camera: CameraModel, emitter: EmitterShape = EmitterShape.FLAT
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Light centres (N,2), Jacobians (N,2,2) px/m of deck (x, y), a usable mask (N,), and
    the beacons' camera-frame positions (N,3) and the deck normal in the camera frame (3,).

    The light centre is the projected centre for a flat emitter and the dome's light
    centroid (:func:`deckpose.render.emitter.dome_light_centroids`) for a domed one.
    """
    T = T_cam_from_deck(ship, camera_pose)
    P = layout.positions_deck_m()
    d = layout.beacon_radius_m
    offsets = np.array([[0, 0, 0], [d, 0, 0], [-d, 0, 0], [0, d, 0], [0, -d, 0]], float)
    pts = (P[:, None, :] + offsets[None]).reshape(-1, 3)
    P_cam = pts @ T[:3, :3].T + T[:3, 3]
    ok = (P_cam[:, 2] > 1e-6).reshape(-1, 5).all(axis=1)
    n_cam = T[:3, 2]
    centres_cam = P @ T[:3, :3].T + T[:3, 3]
    facing = (-centres_cam) @ n_cam > 0.0
    uv = np.full((P_cam.shape[0], 2), np.nan)
    good = np.repeat(ok, 5)
    if good.any():
        uv[good] = camera.project(P_cam[good])
    uv = uv.reshape(-1, 5, 2)
    J = np.stack([(uv[:, 1] - uv[:, 2]) / (2 * d), (uv[:, 3] - uv[:, 4]) / (2 * d)], axis=-1)
    centre = uv[:, 0]
    if emitter is EmitterShape.DOME:
        dome = dome_light_centroids(layout, T, camera)
        ok &= np.isfinite(dome).all(axis=1)
        centre = dome
    return centre, J, ok & facing, np.stack([centres_cam, np.broadcast_to(n_cam, centres_cam.shape)])


def _gaussian_patch(centre: np.ndarray, cov: np.ndarray, flux: float, row0: int, col0: int,
                    h: int, w: int) -> NDArray[np.float32]:
    inv = np.linalg.inv(cov)
    norm = flux / (2 * np.pi * np.sqrt(np.linalg.det(cov)))
    du = (np.arange(col0, col0 + w) - centre[0])[None, :]
    dv = (np.arange(row0, row0 + h) - centre[1])[:, None]
    q = inv[0, 0] * du * du + 2 * inv[0, 1] * du * dv + inv[1, 1] * dv * dv
    return (norm * np.exp(-0.5 * q)).astype(np.float32)


def spot_splat(comps: list[tuple[np.ndarray, np.ndarray, float]], rgb: tuple[float, float, float],
               sensor: SensorSpec, camera: CameraModel, light_id: int = -1) -> Splat | None:
    """The splat of one light from its exposure components, or None when it misses the image.

    Parameters
    ----------
    comps : list of (centre (2,) px, covariance (2, 2) px^2, flux)
        The light's Gaussian core at each sub-pose of the exposure; ``flux`` is radiance
        times pixels (white = 1 before the colour), core and halo together.
    rgb : (3,) floats
        The light's colour.
    sensor : SensorSpec
        Halo fraction and scale.
    camera : CameraModel
        Image size.
    light_id : int
        :attr:`Splat.beacon_id` (a beacon's layout id; -1 for any other light).
    """
    halo_sd = sensor.halo_scale * np.sqrt(max(np.linalg.eigvalsh(cv)[-1] for _, cv, _ in comps))
    centres = np.array([c for c, _, _ in comps])
    half = int(np.ceil(4.0 * halo_sd + np.ptp(centres, axis=0).max() / 2 + 1))
    mid = np.round(centres.mean(axis=0)).astype(int)
    col0, row0 = int(mid[0] - half), int(mid[1] - half)
    if col0 + 2 * half < 0 or row0 + 2 * half < 0 or col0 >= camera.width_px or row0 >= camera.height_px:
        return None
    n = 2 * half + 1
    patch = np.zeros((n, n), np.float32)
    k = len(comps)
    for c, cov, flux in comps:
        core = (1.0 - sensor.halo_fraction) * flux / k
        patch += _gaussian_patch(c, cov, core, row0, col0, n, n)
        if sensor.halo_fraction > 0:
            patch += _gaussian_patch(c, cov * sensor.halo_scale ** 2, sensor.halo_fraction * flux / k,
                                     row0, col0, n, n)
    core_flux = (1.0 - sensor.halo_fraction) * sum(f for _, _, f in comps) / k
    spread = centres - centres.mean(axis=0)
    S = sum(cv for _, cv, _ in comps) / k + spread.T @ spread / k
    sigma = float(np.linalg.det(S)) ** 0.25
    return Splat(row0, col0, patch, np.asarray(rgb, np.float32), light_id, sigma, float(core_flux),
                 centres.mean(axis=0), S)


def beacon_splats(layout: DeckLayout, poses: tuple[ShipPose, ...], camera_pose: CameraPose,
                  camera: CameraModel, sensor: SensorSpec, leds: LedSpec = LedSpec(),
                  unit_factors: np.ndarray | None = None, *,
                  beacon_ids: tuple[int, ...] | None = None) -> list[Splat]:
    """Splats of every beacon the camera can see, averaged over ``poses`` (the exposure).

    Parameters
    ----------
    layout : DeckLayout
    poses : tuple of ShipPose
        One pose (no blur) or the deck poses spread over the exposure.
    camera_pose : CameraPose
    camera : CameraModel
    sensor : SensorSpec
        PSF width, peak radiance and halo.
    leds : LedSpec
        The beacons' light model (:func:`deckpose.render.light.beacon_flux`).
    unit_factors : (N,) array of float, optional
        Each unit's intensity factor (:func:`deckpose.render.light.unit_factors`; default 1).
    beacon_ids : tuple of int, optional
        Only these beacons (default: all); the rolling shutter gives each beacon its own poses.

    Returns
    -------
    list of Splat
        Beacons facing the camera whose window touches the image.
    """
    per_pose = [_centre_and_jacobian(layout, p, camera_pose, camera, leds.emitter) for p in poses]
    r = layout.beacon_radius_m
    s2 = sensor.psf_sigma_px ** 2
    factors = np.ones(layout.n_beacons) if unit_factors is None else np.asarray(unit_factors, float)
    fluxes = [beacon_flux(layout, camera, sensor, leds, J, geo[0], geo[1][0]) * factors
              for _, J, _, geo in per_pose]
    out: list[Splat] = []
    colours = layout.beacon_rgb_all()
    for i in range(layout.n_beacons) if beacon_ids is None else beacon_ids:
        if not all(m[2][i] for m in per_pose):
            continue
        comps = [(c[i], J[i] @ J[i].T * (r * r / 4.0) + s2 * np.eye(2), float(f[i]))
                 for (c, J, _, _), f in zip(per_pose, fluxes)]
        r_, g_, b_ = (float(c) for c in colours[i])
        sp = spot_splat(comps, (r_, g_, b_), sensor, camera, i)
        if sp is not None:
            out.append(sp)
    return out


def add_splats(image: NDArray[np.float32], splats: list[Splat], row_offset: int = 0,
               gain: float = 1.0) -> list[tuple[slice, slice]]:
    """Add ``gain`` x splats into an (h, W, C) strip whose first row is image row ``row_offset``.

    ``C`` is 3 (RGB) or 1 (mono, the colour's mean is used). Modifies ``image`` in place
    (it is a private work buffer of the sensor stage).

    Returns
    -------
    list of (slice, slice)
        The (row, column) windows of ``image`` that received light.
    """
    touched: list[tuple[slice, slice]] = []
    h, W = image.shape[:2]
    mono = image.shape[2] == 1
    for sp in splats:
        r0 = max(sp.row0, row_offset)
        r1 = min(sp.row0 + sp.patch.shape[0], row_offset + h)
        c0 = max(sp.col0, 0)
        c1 = min(sp.col0 + sp.patch.shape[1], W)
        if r0 >= r1 or c0 >= c1:
            continue
        rows = slice(r0 - row_offset, r1 - row_offset)
        if sp.patch.ndim == 3:  # one patch per channel (deckpose.render.optics): patch[..., c] x rgb[c]
            q = sp.patch[r0 - sp.row0: r1 - sp.row0, c0 - sp.col0: c1 - sp.col0] * (sp.rgb * np.float32(gain))
            image[rows, c0:c1] += q.mean(axis=2, keepdims=True) if mono else q
            touched.append((rows, slice(c0, c1)))
            continue
        p = sp.patch[r0 - sp.row0: r1 - sp.row0, c0 - sp.col0: c1 - sp.col0, None]
        col = (sp.rgb.mean(keepdims=True) if mono else sp.rgb) * np.float32(gain)
        image[rows, c0:c1] += p * col
        touched.append((rows, slice(c0, c1)))
    return touched
