"""What the ring-edge detector hands the painted-ring estimator (detect -> estimate).

One :class:`RingDetection` per frame: the sub-pixel points of the painted ring's inner and
outer edges, their fitted ellipses, the bow mark, and what the image says about how well
an edge can be located (contrast, noise, blur), from which the estimator derives its bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["RingDetection"]

FloatArray = NDArray[np.float64]


def _frozen(a: object, shape: tuple[int | None, ...], name: str) -> FloatArray:
    arr = np.array(a, dtype=float)
    if arr.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, arr.shape)):
        raise ValueError(f"RingDetection.{name}: expected shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class RingDetection:
    """The painted ring found in one frame.

    A failed detection is falsy and carries a ``reason``.

    Attributes
    ----------
    ok : bool
    reason : str
        Empty when ``ok``.
    inner_px, outer_px : (N, 2) array of float
        Sub-pixel edge points kept by the ellipse fits (distorted image, pixels).
    conics_px : (2, 3, 3) array of float
        Fitted inner and outer edge conics in undistorted pixels (NaN when not fitted).
    rms_px : (2,) array of float
        RMS distance of each edge's points from its fitted ellipse, pixels.
    bow_ends_px : (2, 2) array of float
        The two ends of the bow mark along the ring's mid line (the gap's ends, or the
        bar's sides), distorted image pixels (NaN when not found).
    bow_sigma_px : float
        Standard deviation of each end's position along the ring, pixels.
    spacing_px : (2,) array of float
        Length of edge each point stands for, pixels (the arc between profiles).
    contrast_dn : float
        Median step across the edges, paint minus deck, DN (channel sum).
    noise_dn : float
        Robust noise of one pixel next to the edges, DN (channel sum).
    blur_px : float
        Gaussian-equivalent sigma of the edge profile, pixels.
    edge_crb_px : float
        Cramér–Rao bound of an edge's position over one pixel of its length from
        ``contrast_dn``, ``noise_dn`` and ``blur_px`` (a Gaussian-blurred step).
    residual_scale : (2,) array of float
        Variance factor of each edge's point residuals for their correlation along the
        edge (batch means over blocks of 8, 32 and 128 points; 1: independent).
    inner_crb_px, outer_crb_px : (N,) array of float
        Each edge point's Cramér–Rao bound along the edge normal, pixels (the model fit of
        its pixels: :mod:`deckpose.detect.edge_profile_fit`); empty when not measured.
    crb_ratio : (2,) array of float
        RMS of each edge's point distances from its ellipse over their bounds.
    known_levels_ratio : float
        An edge point's bound were the deck's and paint's levels known, over its bound (the
        white-noise bound of the position alone; median over the points).
    disc_px : (M, 2) array of float
        Edge points of the centre disc, image pixels; empty when it is not used.
    disc_crb_px : (M,) array of float
        Their Cramér–Rao bounds along the normal, pixels.
    disc_conic_px : (3, 3) array of float
        The disc edge's conic, undistorted pixels (NaN without a disc).
    disc_sigma_scale : float
        The disc points' sigma over their bound (RMS ratio times the root of the correlation factor).
    frame_id : int
    """

    ok: bool
    reason: str = ""
    inner_px: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    outer_px: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    conics_px: FloatArray = field(default_factory=lambda: np.full((2, 3, 3), np.nan))
    rms_px: FloatArray = field(default_factory=lambda: np.full(2, np.nan))
    bow_ends_px: FloatArray = field(default_factory=lambda: np.full((2, 2), np.nan))
    bow_sigma_px: float = math.nan
    spacing_px: FloatArray = field(default_factory=lambda: np.full(2, np.nan))
    contrast_dn: float = math.nan
    noise_dn: float = math.nan
    blur_px: float = math.nan
    edge_crb_px: float = math.nan
    residual_scale: FloatArray = field(default_factory=lambda: np.ones(2))
    inner_crb_px: FloatArray = field(default_factory=lambda: np.zeros(0))
    outer_crb_px: FloatArray = field(default_factory=lambda: np.zeros(0))
    crb_ratio: FloatArray = field(default_factory=lambda: np.full(2, np.nan))
    known_levels_ratio: float = math.nan
    disc_px: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    disc_crb_px: FloatArray = field(default_factory=lambda: np.zeros(0))
    disc_conic_px: FloatArray = field(default_factory=lambda: np.full((3, 3), np.nan))
    disc_sigma_scale: float = math.nan
    frame_id: int = 0

    def __post_init__(self) -> None:
        if self.ok and self.reason:
            raise ValueError("an ok RingDetection cannot carry a failure reason")
        if not self.ok and not self.reason:
            raise ValueError("a failed RingDetection needs a reason")
        for name, shape in (("inner_px", (None, 2)), ("outer_px", (None, 2)), ("conics_px", (2, 3, 3)),
                            ("rms_px", (2,)), ("bow_ends_px", (2, 2)), ("spacing_px", (2,)),
                            ("residual_scale", (2,)), ("inner_crb_px", (None,)), ("outer_crb_px", (None,)),
                            ("crb_ratio", (2,)), ("disc_px", (None, 2)), ("disc_crb_px", (None,)),
                            ("disc_conic_px", (3, 3))):
            object.__setattr__(self, name, _frozen(getattr(self, name), shape, name))
        for name, points in (("inner_crb_px", self.inner_px), ("outer_crb_px", self.outer_px),
                             ("disc_crb_px", self.disc_px)):
            n = len(getattr(self, name))
            if n and n != len(points):
                raise ValueError(f"RingDetection.{name}: one bound per point ({len(points)}), got {n}")
        if len(self.disc_crb_px) != len(self.disc_px):
            raise ValueError(f"RingDetection.disc_crb_px: one bound per disc point ({len(self.disc_px)}), "
                             f"got {len(self.disc_crb_px)}")

    def __bool__(self) -> bool:
        return self.ok

    @property
    def has_point_bounds(self) -> bool:
        """Whether each ring edge point carries its own Cramér–Rao bound."""
        return len(self.inner_crb_px) == len(self.inner_px) > 0 and len(self.outer_crb_px) == len(self.outer_px) > 0

    @property
    def edges_px(self) -> tuple[FloatArray, FloatArray]:
        """``(inner_px, outer_px)``."""
        return self.inner_px, self.outer_px
