"""The painted ring on the deck: its geometry, the config that describes it, and its image conics.

A painted ring (issue 22) is an annulus on the deck plane, centred on the deck centre,
of mid radius ``radius_m`` and line width ``line_width_m``: inner edge ``radius_m -
line_width_m / 2``, outer edge ``radius_m + line_width_m / 2``. A bow mark fixes the
heading, which a circle alone cannot: a ``gap`` of ``gap_deg`` cut out of the ring,
centred on the bow (deck +x), or a ``bar`` of ``bar_length_m`` running from the outer
edge outward along +x, as wide as the line. A ``disc`` of ``centre_radius_m`` may mark
the centre. Positions are in the deck frame (x bow, y port, z up), metres.

The image of a circle on a plane through a pinhole camera is a conic: with the
deck-to-pixel homography ``H = K [r1 r2 t]`` (``r1, r2`` the deck's x and y axes and ``t``
its centre in the camera frame) the circle ``x^2 + y^2 = R^2``, conic ``Q = diag(1, 1,
-R^2)``, images as ``C = H^-T Q H^-1`` (:func:`edge_conics_px`). Under lens distortion
that conic holds in the undistorted image (:meth:`deckpose.camera.CameraModel.undistort`),
not in the distorted one.

This module is shared by the stages: the renderer paints it, the detector looks for it,
the estimator fits it.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["BowMark", "CentreMark", "EllipseParams", "PaintedRing", "boundary_distance_m", "edge_conics_px",
           "ellipse_params",
           "homography_px_from_deck", "paint_mask", "painted_ring_from_dict"]

FloatArray = NDArray[np.float64]


class BowMark(enum.Enum):
    """How the ring shows the bow: a ``gap`` cut out of it, or a ``bar`` outward from it."""

    GAP = "gap"
    BAR = "bar"


class CentreMark(enum.Enum):
    """What marks the ring's centre: nothing, or a painted ``disc``."""

    NONE = "none"
    DISC = "disc"


@dataclass(frozen=True)
class PaintedRing:
    """A painted ring on the deck (the config's ``painted_ring:`` section).

    Attributes
    ----------
    radius_m : float
        Mid radius of the painted line, metres.
    line_width_m : float
        Width of the painted line, metres (inner edge ``radius_m - line_width_m / 2``).
    colour : tuple of 3 float
        The paint's reflectance, RGB in [0, 1] on the scale of the deck texture (the deck's
        non-skid grey is about 0.42, its white markings 0.92).
    contrast : float
        How much of the paint shows, in [0, 1]: the painted value is ``contrast * colour +
        (1 - contrast) * deck`` (1: fresh paint; 0.5: half worn off).
    bow_mark : BowMark
        ``gap`` or ``bar``.
    gap_deg : float
        Angular width of the gap at the bow, degrees (``bow_mark: gap``).
    bar_length_m : float
        Length of the bar beyond the outer edge, metres (``bow_mark: bar``).
    centre_mark : CentreMark
        ``none`` or ``disc``.
    centre_radius_m : float
        Radius of the centre disc, metres.
    floodlight_level : float
        At night, the deck plate's light level under the deck floodlights (the presets'
        scale: night 0.04, dusk 0.25, day 0.85); 0: no floodlights (the deck stays at the
        night level). Not used at dusk and day.
    """

    radius_m: float = 8.0
    line_width_m: float = 0.5
    colour: tuple[float, float, float] = (0.92, 0.92, 0.9)
    contrast: float = 1.0
    bow_mark: BowMark = BowMark.GAP
    gap_deg: float = 20.0
    bar_length_m: float = 1.5
    centre_mark: CentreMark = CentreMark.DISC
    centre_radius_m: float = 0.6
    floodlight_level: float = 0.2

    @property
    def inner_radius_m(self) -> float:
        """Radius of the inner edge, metres."""
        return self.radius_m - 0.5 * self.line_width_m

    @property
    def outer_radius_m(self) -> float:
        """Radius of the outer edge, metres."""
        return self.radius_m + 0.5 * self.line_width_m

    @property
    def edge_radii_m(self) -> tuple[float, float]:
        """``(inner, outer)`` edge radii, metres."""
        return self.inner_radius_m, self.outer_radius_m

    @property
    def extent_m(self) -> float:
        """Distance from the centre to the farthest paint, metres."""
        bar = self.bar_length_m if self.bow_mark is BowMark.BAR else 0.0
        return math.hypot(self.outer_radius_m + bar, 0.5 * self.line_width_m)


def painted_ring_from_dict(doc: object, where: str = "painted_ring") -> PaintedRing:
    """Validate a ``painted_ring:`` mapping (typed loader, then ranges); one-line errors."""
    ring = from_mapping(PaintedRing, doc, where)
    check_range(ring.radius_m, f"{where}.radius_m", low=0, low_open=True, high=1000)
    check_range(ring.line_width_m, f"{where}.line_width_m", low=0, low_open=True)
    if ring.line_width_m >= ring.radius_m:
        raise ConfigError(f"{where}.line_width_m: must be smaller than radius_m ({ring.radius_m:g}) so the "
                          f"ring has a hole, got {ring.line_width_m:g}")
    for i, c in enumerate(ring.colour):
        check_range(c, f"{where}.colour[{i}]", low=0, high=1)
    check_range(ring.contrast, f"{where}.contrast", low=0, high=1)
    check_range(ring.gap_deg, f"{where}.gap_deg", low=0, low_open=True, high=90)
    check_range(ring.bar_length_m, f"{where}.bar_length_m", low=0, low_open=True, high=ring.radius_m)
    check_range(ring.centre_radius_m, f"{where}.centre_radius_m", low=0, low_open=True)
    if ring.centre_mark is CentreMark.DISC and ring.centre_radius_m >= 0.5 * ring.inner_radius_m:
        raise ConfigError(f"{where}.centre_radius_m: the centre disc must stay well inside the ring "
                          f"(below half the inner radius, {0.5 * ring.inner_radius_m:g} m), "
                          f"got {ring.centre_radius_m:g}")
    check_range(ring.floodlight_level, f"{where}.floodlight_level", low=0, high=1)
    return ring


def paint_mask(ring: PaintedRing, x_m: FloatArray, y_m: FloatArray) -> NDArray[np.bool_]:
    """Whether deck points are painted (ring with its bow mark, and the centre mark).

    Parameters
    ----------
    ring : PaintedRing
    x_m, y_m : array of float, any shape, metres
        Deck-frame coordinates.

    Returns
    -------
    array of bool, the shape of ``x_m``
    """
    rho = np.hypot(x_m, y_m)
    inside = (rho >= ring.inner_radius_m) & (rho <= ring.outer_radius_m)
    half_w = 0.5 * ring.line_width_m
    if ring.bow_mark is BowMark.GAP:
        half = 0.5 * math.radians(ring.gap_deg)
        inside &= ~((x_m > 0) & (np.abs(np.arctan2(y_m, x_m)) < half))
    else:
        inside |= (x_m >= ring.radius_m) & (x_m <= ring.outer_radius_m + ring.bar_length_m) & (np.abs(y_m) <= half_w)
    if ring.centre_mark is CentreMark.DISC:
        inside |= rho <= ring.centre_radius_m
    return inside


def boundary_distance_m(ring: PaintedRing, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
    """A lower bound on the distance from deck points to the paint's boundary, metres.

    Every boundary piece (the two edge circles, the gap's two radial cuts or the bar's
    sides and end, the centre disc's edge) contributes the distance to the whole line or
    circle it lies on, so the minimum never exceeds the true distance: a pixel farther
    than its own size from every piece is wholly painted or wholly bare.
    """
    rho = np.hypot(x_m, y_m)
    d = np.minimum(np.abs(rho - ring.inner_radius_m), np.abs(rho - ring.outer_radius_m))
    if ring.bow_mark is BowMark.GAP:
        half = 0.5 * math.radians(ring.gap_deg)
        for s in (1.0, -1.0):  # the cut lines through the centre at +-half
            d = np.minimum(d, np.abs(x_m * math.sin(s * half) - y_m * math.cos(s * half)))
    else:
        half_w = 0.5 * ring.line_width_m
        d = np.minimum(d, np.minimum(np.abs(np.abs(y_m) - half_w),
                                     np.abs(x_m - ring.outer_radius_m - ring.bar_length_m)))
    if ring.centre_mark is CentreMark.DISC:
        d = np.minimum(d, np.abs(rho - ring.centre_radius_m))
    return d


def homography_px_from_deck(T_cam_from_deck: FloatArray, K: FloatArray) -> FloatArray:
    """``H = K [r1 r2 t]``: deck-plane ``(x, y, 1)`` to (undistorted) homogeneous pixels, (3, 3)."""
    T = np.asarray(T_cam_from_deck, dtype=float)
    return np.asarray(K, dtype=float) @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])


def edge_conics_px(ring: PaintedRing, T_cam_from_deck: FloatArray, K: FloatArray) -> FloatArray:
    """Image conics of the inner and outer edge circles, undistorted pixels.

    Parameters
    ----------
    ring : PaintedRing
    T_cam_from_deck : (4, 4) array of float
    K : (3, 3) array of float

    Returns
    -------
    (2, 3, 3) array of float
        ``C[k]`` for edge ``k`` (0 inner, 1 outer): ``[u, v, 1] C [u, v, 1]^T = 0`` on the
        edge, scaled to unit Frobenius norm with ``C[2, 2] < 0`` (negative inside).
    """
    Hinv = np.linalg.inv(homography_px_from_deck(T_cam_from_deck, K))
    out = np.empty((2, 3, 3))
    for k, r in enumerate(ring.edge_radii_m):
        C = Hinv.T @ np.diag([1.0, 1.0, -r * r]) @ Hinv
        C = 0.5 * (C + C.T)
        C /= np.linalg.norm(C)
        out[k] = C if C[2, 2] < 0 else -C
    return out


@dataclass(frozen=True)
class EllipseParams:
    """Centre, semi-axes and orientation of an ellipse, pixels.

    ``angle_rad`` is the major axis's angle from the image +u axis toward +v.
    """

    centre_u_px: float
    centre_v_px: float
    semi_major_px: float
    semi_minor_px: float
    angle_rad: float


def ellipse_params(C: FloatArray) -> EllipseParams | None:
    """The ellipse of conic ``C`` (3, 3), or None when ``C`` is not a real ellipse."""
    C = 0.5 * (np.asarray(C, float) + np.asarray(C, float).T)
    A = C[:2, :2]
    if np.linalg.det(A) <= 0:
        return None
    centre = -np.linalg.solve(A, C[:2, 2])
    k = -(centre @ C[:2, 2] + C[2, 2])  # (p - c)^T A (p - c) = k on the ellipse
    w, V = np.linalg.eigh(A / k) if k != 0 else (np.zeros(2), np.eye(2))
    if not np.all(w > 0):
        return None
    a, b = 1.0 / math.sqrt(w[0]), 1.0 / math.sqrt(w[1])  # w ascending: a is the major semi-axis
    angle = math.atan2(V[1, 0], V[0, 0])
    return EllipseParams(float(centre[0]), float(centre[1]), a, b, (angle + math.pi / 2) % math.pi - math.pi / 2)
