"""The painted ring's centre disc: its edge, to sub-pixel accuracy, once the ring is found.

The disc (:attr:`deckpose.painted_ring.PaintedRing.centre_radius_m`) is a circle concentric
with the ring: its image is near the ring's ellipse scaled about its centre by the radius
ratio (the two ellipses' centres differ by the perspective, a few percent of the disc's
size). Rays from that predicted centre, one per pixel of the predicted edge, are sampled
every 0.25 px from 0.4 to 1.8 predicted radii; the disc's edge is the largest fall (paint to
deck) along each, a first conic is fitted to those points, and the edge's pixels are then
fitted row by row (:func:`deckpose.detect.model_edge.model_edge`, paint inside).

Why it matters: the image of the deck centre and a circle's conic fix the deck plane's
vanishing line (the centre's polar), so the disc makes the tilt first order where the ring
alone gives it only through the ellipse's shape (second order near nadir). Only the disc's
edge is used (a circle of known radius about the deck centre), as the ring's edges are.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.edge_conic import fit_edge_conic
from deckpose.detect.model_edge import MIN_EDGE_POINTS, ModelEdge, model_edge
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from deckpose.camera import CameraModel
from deckpose.painted_ring import PaintedRing, ellipse_params

__all__ = ["find_centre_disc"]

FloatArray = NDArray[np.float64]

#: Smallest predicted disc radius looked for, pixels (smaller discs are not fitted).
MIN_RADIUS_PX = 4.0


def _distort(camera: CameraModel, und_px: FloatArray) -> FloatArray:
    if not camera.has_distortion:
        return und_px
    y = (und_px[:, 1] - camera.cy) / camera.fy
    x = (und_px[:, 0] - camera.cx - camera.K[0, 1] * y) / camera.fx
    return camera.project(np.column_stack([x, y, np.ones_like(x)]))


def find_centre_disc(grey: NDArray[np.float32], camera: CameraModel, ring: PaintedRing, inner_conic_und: FloatArray,
                     outer_conic_und: FloatArray, blur_px: float, *, min_contrast_fraction: float = 0.5
                     ) -> ModelEdge | None:
    """The centre disc's edge (module docstring), or None when it is not found.

    Parameters
    ----------
    grey : (H, W) array of float32
    camera : CameraModel
    ring : PaintedRing
    inner_conic_und, outer_conic_und : (3, 3) array of float
        The ring's fitted edge conics, undistorted pixels.
    blur_px : float
        The edges' blur sigma, pixels.
    min_contrast_fraction : float, keyword-only
        See :func:`deckpose.detect.model_edge.model_edge`.

    Returns
    -------
    ModelEdge or None
        None when the disc is too small, hidden or not where the ring puts it (the ring's
        pose is then estimated without it).
    """
    ei, eo = ellipse_params(inner_conic_und), ellipse_params(outer_conic_und)
    if ei is None or eo is None:
        return None
    scale = ring.centre_radius_m / ring.radius_m
    a = scale * 0.5 * (ei.semi_major_px + eo.semi_major_px)
    b = scale * 0.5 * (ei.semi_minor_px + eo.semi_minor_px)
    if b < MIN_RADIUS_PX:
        return None
    centre_und = np.array([0.5 * (ei.centre_u_px + eo.centre_u_px), 0.5 * (ei.centre_v_px + eo.centre_v_px)])
    perimeter = math.pi * (3 * (a + b) - math.sqrt((3 * a + b) * (a + 3 * b)))
    n = max(64, round(perimeter))
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    c, s = math.cos(eo.angle_rad), math.sin(eo.angle_rad)
    edge = np.column_stack([a * np.cos(t), b * np.sin(t)]) @ np.array([[c, s], [-s, c]])
    radius = np.linalg.norm(edge, axis=1)
    direction = edge / radius[:, None]
    step = 0.25
    f = np.arange(0.4, 1.8, step / max(b, 1.0))
    pts_und = centre_und + (radius[:, None, None] * f[None, :, None]) * direction[:, None, :]
    pts = _distort(camera, pts_und.reshape(-1, 2)).reshape(pts_und.shape)
    mx = np.ascontiguousarray(pts[..., 0], np.float32)
    my = np.ascontiguousarray(pts[..., 1], np.float32)
    prof = cv2.remap(grey, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan).astype(float)
    inside = np.all(np.isfinite(prof), axis=1)
    if inside.mean() < 0.5:
        return None
    prof = gaussian_filter1d(np.where(np.isfinite(prof), prof, 0.0), 1.0 / step, axis=1, mode="nearest")
    k = np.argmin(np.diff(prof, axis=1), axis=1)  # the largest fall outward
    hit = pts[np.arange(n), k] + 0.5 * (pts[np.arange(n), k + 1] - pts[np.arange(n), k])
    hit = hit[inside & (k > 0) & (k < len(f) - 2)]
    if len(hit) < MIN_EDGE_POINTS:
        return None
    got = fit_edge_conic(camera.undistort(hit))
    if got is None:
        return None
    conic, keep = got
    e = ellipse_params(conic)
    # the first conic must be the disc: its size within 30 % of the prediction
    if e is None or abs(math.sqrt(e.semi_major_px * e.semi_minor_px) / math.sqrt(a * b) - 1) > 0.3:
        return None
    anchors = hit[keep]
    reach = np.full(len(anchors), 0.5 * math.sqrt(e.semi_major_px * e.semi_minor_px))
    got_edge = model_edge(grey, camera, anchors, conic, blur_px, reach, paint_outside=False,
                          min_contrast_fraction=min_contrast_fraction)
    return None if isinstance(got_edge, str) else got_edge
