"""The painted ring in a frame: painted analytically onto the raster, and its exact truth.

The ring (:class:`deckpose.painted_ring.PaintedRing`) is not a texture: every pixel near
it gets its exact coverage by the paint, so its edges are sharp and unbiased at any
resolution. Each pixel centre of the ring's bounding box is cast onto the deck plane
through the camera (:meth:`~deckpose.camera.CameraModel.undistort`, then the inverse of
the deck's homography), so the paint follows the same lens as the beacons and the raster.
Pixels farther than 1.5 pixel footprints from every boundary of the paint (edge circles,
bow mark, centre disc: :func:`deckpose.painted_ring.boundary_distance_m`) are wholly
painted or bare; the others are supersampled on a ``samples x samples`` grid of
sub-pixel points (area coverage of a box pixel).

A painted pixel's raster value ``v`` becomes ``(1 - a) v + a p``, ``a`` its coverage and
``p = contrast * 255 colour + (1 - contrast) v`` the paint, under the same light
(:func:`deckpose.render.scene.radiance_scale`): the change is handed to the sensor as
additive light (:class:`~deckpose.render.beacons.Splat` tiles of 64 x 64 pixels), so
the sensor model (noise, saturation, Bayer, fixed pattern, JPEG) acts on it as on the
rest of the frame. At night the deck floodlights light the deck plate to
``floodlight_level`` (:func:`floodlight_gain`), through the sensor's background gain.
The ring is drawn at the frame's (mid-exposure) pose: motion blur and the rolling shutter
move the beacons, not the paint. Flat shading only (``pbr`` lights the deck with a sun
the paint does not see; :mod:`deckpose.render.config` refuses the pair). Mono frames
take the mean of the paint's channels (the background takes the luma): exact for grey
paint on the grey deck.

Truth (:func:`ring_truth`): the inner and outer edges' image conics through ``K``, exact
in the undistorted image (under distortion the edge in the image is not an ellipse),
their ellipse parameters, the imaged deck centre and bow point (distortion-aware), and
the fraction of each edge inside the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from deckpose.render.beacons import Splat
from deckpose.render.scene import PRESETS
from deckpose.render.scene_config import Lighting
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.painted_ring import (
    PaintedRing,
    boundary_distance_m,
    edge_conics_px,
    ellipse_params,
    paint_mask,
)
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck

__all__ = ["RingTruth", "floodlight_gain", "paint_coverage", "paint_splats", "ring_rows", "ring_truth"]

FloatArray = NDArray[np.float64]

#: Side of the square tiles the paint is handed to the sensor in, pixels.
TILE_PX = 64
#: Image rows cast onto the deck at a time (bounded memory at 64 MP).
_ROWS = 256
#: Pixels within this many footprints of a boundary are supersampled.
_NEAR_FOOTPRINTS = 1.5
#: Sub-pixel samples per side of a frame's pixels near the paint's boundary: coverage steps of
#: 1 / 256, so an edge pixel's value places the edge to ~1/64 px where the edge runs along a pixel
#: axis (4 a side gave steps of 1/4 px there: 0.07 px RMS per edge point, a renderer artefact as
#: large as the pixel noise's edge error in daylight).
PAINT_SAMPLES = 16
#: Points per edge circle for the bounding box and the in-image fraction.
_EDGE_SAMPLES = 720


def _normalised_rays(camera: CameraModel, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Undistorted normalised ``(x/z, y/z)`` of pixels (NaN where none), shapes of ``u``."""
    if camera.has_distortion:
        und = camera.undistort(np.column_stack([u.ravel(), v.ravel()]))
        u, v = und[:, 0].reshape(u.shape), und[:, 1].reshape(u.shape)
    y = (v - camera.cy) / camera.fy
    x = (u - camera.cx - camera.K[0, 1] * y) / camera.fx
    return x, y


def _deck_points(Hn_inv: FloatArray, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Deck ``(x, y)`` metres where normalised rays meet the deck plane (NaN behind the camera)."""
    X = Hn_inv[0, 0] * x + Hn_inv[0, 1] * y + Hn_inv[0, 2]
    Y = Hn_inv[1, 0] * x + Hn_inv[1, 1] * y + Hn_inv[1, 2]
    W = Hn_inv[2, 0] * x + Hn_inv[2, 1] * y + Hn_inv[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = W > 0  # the deck point lies in front of the camera
        return np.where(ok, X / W, np.nan), np.where(ok, Y / W, np.nan)


def _deck_inverse(T: FloatArray) -> FloatArray:
    """Inverse of the normalised homography ``[r1 r2 t]`` scaled so W > 0 in front of the camera."""
    Hn = np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])
    Hinv = np.linalg.inv(Hn)
    # the deck centre's ray (x, y, 1) = t / t_z must map to W > 0
    c = T[:3, 3] / T[2, 3]
    return np.asarray(Hinv if (Hinv[2] @ c) > 0 else -Hinv, dtype=np.float64)


def _bbox(ring: PaintedRing, T: FloatArray, camera: CameraModel) -> tuple[int, int, int, int] | None:
    """Pixel rows and columns ``(r0, r1, c0, c1)`` that may see paint, or None."""
    ang = np.linspace(0.0, 2 * math.pi, _EDGE_SAMPLES, endpoint=False)
    P = np.column_stack([ring.extent_m * np.cos(ang), ring.extent_m * np.sin(ang), np.zeros_like(ang)])
    Pc = P @ T[:3, :3].T + T[:3, 3]
    if np.any(Pc[:, 2] <= 0):  # part of the ring behind the camera: cast every pixel
        return 0, camera.height_px, 0, camera.width_px
    uv = camera.project(Pc)
    if not np.all(np.isfinite(uv)):
        return 0, camera.height_px, 0, camera.width_px
    lo, hi = np.floor(uv.min(axis=0)) - 2, np.ceil(uv.max(axis=0)) + 3
    c0, r0 = max(0, int(lo[0])), max(0, int(lo[1]))
    c1, r1 = min(camera.width_px, int(hi[0])), min(camera.height_px, int(hi[1]))
    return (r0, r1, c0, c1) if r0 < r1 and c0 < c1 else None


def paint_coverage(ring: PaintedRing, ship: ShipPose, camera_pose: CameraPose, camera: CameraModel,
                   *, samples: int = 4) -> tuple[int, int, NDArray[np.float32]] | None:
    """Each pixel's area fraction covered by paint, over the ring's bounding box.

    Parameters
    ----------
    ring : PaintedRing
    ship : ShipPose
    camera_pose : CameraPose
    camera : CameraModel
    samples : int, keyword-only
        Sub-pixel samples per side in pixels near a boundary (coverage steps of
        ``1 / samples**2``).

    Returns
    -------
    (row0, col0, coverage) or None
        ``coverage`` (h, w) float32 in [0, 1] for image rows ``row0..row0+h`` and columns
        ``col0..col0+w``; None when no paint can be in view.
    """
    T = T_cam_from_deck(ship, camera_pose)
    box = _bbox(ring, T, camera)
    if box is None:
        return None
    r0, r1, c0, c1 = box
    Hinv = _deck_inverse(T)
    cov = np.zeros((r1 - r0, c1 - c0), np.float32)
    offs = (np.arange(samples) + 0.5) / samples - 0.5
    for a in range(r0, r1, _ROWS):
        b = min(r1, a + _ROWS)
        # one extra row and column to difference the footprint
        vv, uu = np.meshgrid(np.arange(a, b + 1, dtype=float), np.arange(c0, c1 + 1, dtype=float), indexing="ij")
        X, Y = _deck_points(Hinv, *_normalised_rays(camera, uu, vv))
        fp = np.maximum(np.hypot(np.diff(X, axis=1)[:-1], np.diff(Y, axis=1)[:-1]),
                        np.hypot(np.diff(X, axis=0)[:, :-1], np.diff(Y, axis=0)[:, :-1]))
        X, Y = X[:-1, :-1], Y[:-1, :-1]
        with np.errstate(invalid="ignore"):
            block = paint_mask(ring, X, Y).astype(np.float32)
            near = ~(boundary_distance_m(ring, X, Y) > _NEAR_FOOTPRINTS * fp)  # NaN (no deck): sampled too
        rows, cols = np.nonzero(near)
        if rows.size:
            su = (cols[:, None, None] + c0 + offs[None, None, :]) + 0 * offs[None, :, None]
            sv = (rows[:, None, None] + a + offs[None, :, None]) + 0 * offs[None, None, :]
            sx, sy = _deck_points(Hinv, *_normalised_rays(camera, su, sv))
            with np.errstate(invalid="ignore"):
                hit = paint_mask(ring, sx, sy)
            block[rows, cols] = hit.reshape(rows.size, -1).mean(axis=1)
        cov[a - r0:b - r0] = block
    return r0, c0, cov


def paint_splats(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], ring: PaintedRing,
                 ship: ShipPose, camera_pose: CameraPose, camera: CameraModel, *,
                 deck_gain: float = 1.0, samples: int = PAINT_SAMPLES) -> list[Splat]:
    """The paint as additive light tiles for :func:`deckpose.render.sensor.expose`.

    Parameters
    ----------
    raster : (H, W, 3) array of uint8
        The distorted raster the frame is exposed from.
    scale_rgb : (3,) array of float32
        Raster value to radiance (:func:`deckpose.render.scene.radiance_scale`).
    ring, ship, camera_pose, camera
        The paint and the frame's geometry.
    deck_gain : float, keyword-only
        The background gain on the deck (the floodlights' :func:`floodlight_gain`; 1: none).
    samples : int, keyword-only
        See :func:`paint_coverage` (default :data:`PAINT_SAMPLES`).

    Returns
    -------
    list of Splat
        Tiles of at most :data:`TILE_PX` square with ``patch`` (h, w, 3) radiance: coverage x
        ``contrast * (255 colour - v) * scale * deck_gain``; ``rgb`` ones; ``beacon_id`` -1.
    """
    got = paint_coverage(ring, ship, camera_pose, camera, samples=samples)
    if got is None:
        return []
    r0, c0, cov = got
    paint = 255.0 * np.asarray(ring.colour, np.float32)
    unit = (np.asarray(scale_rgb, np.float32) * np.float32(ring.contrast * deck_gain))
    ones = np.ones(3, np.float32)
    out: list[Splat] = []
    h, w = cov.shape
    for i in range(0, h, TILE_PX):
        for j in range(0, w, TILE_PX):
            a = cov[i:i + TILE_PX, j:j + TILE_PX]
            if not a.any():
                continue
            v = raster[r0 + i:r0 + i + a.shape[0], c0 + j:c0 + j + a.shape[1]].astype(np.float32)
            patch = (a[..., None] * (paint - v) * unit).astype(np.float32)
            out.append(Splat(r0 + i, c0 + j, patch, ones))
    return out


def floodlight_gain(ring: PaintedRing, lighting: Lighting, deck_half_size_m: float, ship: ShipPose,
                    camera_pose: CameraPose, camera: CameraModel) -> tuple[float, Any]:
    """The deck floodlights at night: the gain on the deck plate and the sensor's row-gain function.

    Returns
    -------
    gain : float
        ``floodlight_level / night level`` at night with floodlights, else 1.
    rows : callable or None
        ``f(r0, r1) -> (r1 - r0, W)`` float32: ``gain`` where a pixel sees the deck plate, 1
        elsewhere (the sea, the sky); None when ``gain`` is 1.
    """
    if lighting is not Lighting.NIGHT or ring.floodlight_level <= 0:
        return 1.0, None
    gain = ring.floodlight_level / PRESETS[Lighting.NIGHT].level
    Hinv = _deck_inverse(T_cam_from_deck(ship, camera_pose))
    W = camera.width_px

    def rows(r0: int, r1: int) -> NDArray[np.float32]:
        vv, uu = np.meshgrid(np.arange(r0, r1, dtype=float), np.arange(W, dtype=float), indexing="ij")
        X, Y = _deck_points(Hinv, *_normalised_rays(camera, uu, vv))
        with np.errstate(invalid="ignore"):
            on = (np.abs(X) <= deck_half_size_m) & (np.abs(Y) <= deck_half_size_m)
        return np.where(on, np.float32(gain), np.float32(1.0)).astype(np.float32)

    return gain, rows


@dataclass(frozen=True)
class RingTruth:
    """The painted ring's exact image geometry in one frame (render -> evaluate only).

    Attributes
    ----------
    conics_px : (2, 3, 3) array of float
        Inner and outer edge conics in undistorted pixels (:func:`deckpose.painted_ring.edge_conics_px`).
    centre_px : (2,) array of float
        The deck centre's image, pixels (distortion-aware; not the ellipses' centres).
    bow_px : (2,) array of float
        The image of the ring's mid line at the bow, deck ``(radius_m, 0)``, pixels.
    in_image_fraction : (2,) array of float
        Fraction of each edge circle (720 points) that projects inside the image.
    distorted : bool
        The camera has lens distortion: the conics hold after undistortion only.
    """

    conics_px: FloatArray
    centre_px: FloatArray
    bow_px: FloatArray
    in_image_fraction: FloatArray
    distorted: bool

    def __post_init__(self) -> None:
        for name, shape in (("conics_px", (2, 3, 3)), ("centre_px", (2,)), ("bow_px", (2,)),
                            ("in_image_fraction", (2,))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape:
                raise ValueError(f"RingTruth.{name}: expected shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)


def ring_truth(ring: PaintedRing, ship: ShipPose, camera_pose: CameraPose, camera: CameraModel) -> RingTruth:
    """The painted ring's exact image geometry for one frame (see :class:`RingTruth`)."""
    T = T_cam_from_deck(ship, camera_pose)
    C = edge_conics_px(ring, T, camera.K)
    pts = np.array([[0.0, 0.0, 0.0], [ring.radius_m, 0.0, 0.0]]) @ T[:3, :3].T + T[:3, 3]
    cb = camera.project(pts)
    ang = np.linspace(0.0, 2 * math.pi, _EDGE_SAMPLES, endpoint=False)
    frac = np.zeros(2)
    for k, r in enumerate(ring.edge_radii_m):
        P = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(ang)]) @ T[:3, :3].T + T[:3, 3]
        front = P[:, 2] > 0
        uv = camera.project(np.where(front[:, None], P, 1.0))
        frac[k] = float(np.mean(front & camera.in_image(uv)))
    return RingTruth(C, cb[0], cb[1], frac, camera.has_distortion)


def ring_rows(frame_id: int, truth: RingTruth) -> list[dict[str, Any]]:
    """The ``painted_ring.parquet`` rows of a frame: one per edge (``inner``, ``outer``)."""
    rows = []
    for k, edge in enumerate(("inner", "outer")):
        e = ellipse_params(truth.conics_px[k])
        nan = math.nan
        row: dict[str, Any] = {
            "frame_id": frame_id, "edge": edge,
            "ellipse_u_px": e.centre_u_px if e else nan, "ellipse_v_px": e.centre_v_px if e else nan,
            "semi_major_px": e.semi_major_px if e else nan, "semi_minor_px": e.semi_minor_px if e else nan,
            "angle_deg": math.degrees(e.angle_rad) if e else nan,
            "centre_u_px": float(truth.centre_px[0]), "centre_v_px": float(truth.centre_px[1]),
            "bow_u_px": float(truth.bow_px[0]), "bow_v_px": float(truth.bow_px[1]),
            "in_image_fraction": float(truth.in_image_fraction[k]), "distorted": truth.distorted,
        }
        for i in range(3):
            for j in range(3):
                row[f"conic_px_{i}{j}"] = float(truth.conics_px[k, i, j])
        rows.append(row)
    return rows
