"""One elliptical painted edge located by the model fit of its pixels, with its noise figures.

From points near the edge and a first conic through them, the edge's pixels are fitted
row by row (:mod:`deckpose.detect.edge_profile_fit`), the profiles whose step falls below a
fraction of the median are dropped (occluders, shadows, the bow mark), and a robust conic
(:func:`deckpose.detect.edge_conic.fit_edge_conic`) is fitted to the rest in the undistorted
image, dropping outliers (crossing deck lines, the "H"). The points' distances from that
conic over their Cramér–Rao bounds measure how far the real scatter exceeds the bound: their
RMS (``rms_over_crb``) and the variance factor of their mean for their correlation along the
edge (``correlation``, :func:`correlation_factor`) make the points' sigma
``crb_px * sigma_scale``, ``sigma_scale = rms_over_crb * sqrt(correlation)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.detect.edge_conic import fit_edge_conic, sampson_distance
from deckpose.detect.edge_profile_fit import conic_edge_profiles, fit_edge_profiles
from numpy.typing import NDArray

from deckpose.camera import CameraModel

__all__ = ["MIN_EDGE_POINTS", "ModelEdge", "correlation_factor", "model_edge"]

FloatArray = NDArray[np.float64]

#: Fewest fitted points an edge needs.
MIN_EDGE_POINTS = 12


@dataclass(frozen=True)
class ModelEdge:
    """A fitted edge: its points, their bounds, its conic and its scatter figures.

    Attributes
    ----------
    points_px : (N, 2) array of float
        Edge points kept by the conic fit, image pixels.
    crb_px : (N,) array of float
        Each point's Cramér–Rao bound along the edge normal, pixels.
    conic_px : (3, 3) array of float
        The robust conic, undistorted pixels, negative inside.
    step_dn : (N,) array of float
        Paint minus deck at each point, DN.
    rms_px : float
        RMS distance of the points from the conic, pixels.
    rms_over_crb : float
        RMS of the points' distances over their bounds (1: the bound's scatter).
    correlation : float
        Variance factor of a mean of the normalised distances along the edge (1: independent).
    noise_deck_dn : float
        Robust RMS residual of the deck's pixels beside the edge, DN.
    known_levels_ratio : float
        Median over the points of their bound were the deck's and paint's levels known, over
        ``crb_px`` (at most 1: what the unknown levels cost).
    """

    points_px: FloatArray
    crb_px: FloatArray
    conic_px: FloatArray
    step_dn: FloatArray
    rms_px: float
    rms_over_crb: float
    correlation: float
    noise_deck_dn: float
    known_levels_ratio: float

    @property
    def sigma_scale(self) -> float:
        """The points' sigma over their bound: ``rms_over_crb * sqrt(correlation)``."""
        return self.rms_over_crb * math.sqrt(self.correlation)


def correlation_factor(r: FloatArray, blocks: tuple[int, ...] = (4, 8, 32, 128)) -> float:
    """How much more the mean of residuals ordered along the edge varies than if they were independent.

    Deck texture and shading move neighbouring edge points together, over tens of pixels.
    For consecutive blocks of ``b`` points, ``b var(block means) / var(points)`` is 1 for
    independent points and the variance factor of a mean otherwise (batch means); the
    largest over the block sizes with at least 8 blocks is returned (at least 1).
    """
    r = r - r.mean()
    v = float(np.mean(r * r))
    best = 1.0
    if v <= 0:
        return best
    for b in blocks:
        m = len(r) // b
        if m < 8:
            break
        means = r[:m * b].reshape(m, b).mean(axis=1)
        best = max(best, b * float(np.mean(means ** 2)) / v)
    return best


def model_edge(grey: NDArray[np.float32], camera: CameraModel, anchors_px: FloatArray, conic_und: FloatArray,
               blur_px: float, paint_px: FloatArray, *, paint_outside: bool,
               min_contrast_fraction: float) -> ModelEdge | str:
    """Fit one elliptical edge's pixels (module docstring), or say why it cannot be.

    Parameters
    ----------
    grey : (H, W) array of float32
    camera : CameraModel
    anchors_px : (N, 2) array of float
        Points near the edge (a pixel or so apart along it), image pixels, in order along it.
    conic_und : (3, 3) array of float
        A first conic of the edge, undistorted pixels.
    blur_px : float
        The edge blur sigma (:func:`deckpose.detect.edge_profile_fit.blur_of_edges`).
    paint_px : (N,) array of float
        How far the paint reaches beyond the edge at each anchor, pixels.
    paint_outside : bool, keyword-only
        The paint lies outside the conic (a ring's inner edge) or inside (outer edge, disc).
    min_contrast_fraction : float, keyword-only
        A point counts when its step is at least this fraction of the median step.
    """
    deck_px = max(3.0, 3.0 * blur_px + 2.0)
    rows = conic_edge_profiles(grey, anchors_px, camera.undistort(anchors_px), conic_und,
                               paint_outside=paint_outside, deck_px=deck_px,
                               paint_px=np.minimum(paint_px, deck_px))
    fit = fit_edge_profiles(rows, blur_px)
    ok = fit.valid
    if ok.sum() < MIN_EDGE_POINTS:
        return f"only {int(ok.sum())} edge profiles fit (needs {MIN_EDGE_POINTS})"
    ok &= fit.step_dn >= min_contrast_fraction * float(np.median(fit.step_dn[ok]))
    pts, crb, step, known = fit.points_px[ok], fit.crb_px[ok], fit.step_dn[ok], fit.crb_known_levels_px[ok]
    und = camera.undistort(pts)
    got = fit_edge_conic(und)
    if got is None:
        return "the edge's points admit no ellipse"
    C, keep = got
    if keep.sum() < MIN_EDGE_POINTS:
        return f"only {int(keep.sum())} edge points on the ellipse (needs {MIN_EDGE_POINTS})"
    d = sampson_distance(C, und[keep])
    z = d / crb[keep]
    return ModelEdge(pts[keep], crb[keep], C, step[keep], float(np.sqrt(np.mean(d ** 2))),
                     float(np.sqrt(np.mean(z ** 2))), correlation_factor(z), fit.noise_deck_dn,
                     float(np.median(known[keep] / crb[keep])))
