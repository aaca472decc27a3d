"""A clipped core's pixel-phase error: the part of a windowed centroid's error that the noise does not hold.

A spot whose core rises above the sensor's clip level (its full well, or the top of the
ADC) is recorded as ``min(g, c)`` per pixel, ``g`` its pixel-integrated intensity and ``c``
the clip level. The centroid of the unclipped ``g`` is exact for any sub-pixel position of
its centre (the pixel-integrated centroid of a spot wider than a pixel errs by
``~exp(-2 pi^2 sigma^2)`` px). Clipping takes the excess ``(g - c)_+`` away from the plateau
pixels, and the centroid of that excess, sampled on the pixel grid, is not the spot's
centre: it depends on where the centre falls within its pixel (its sub-pixel phase ``p``).
With the window centred on the spot (a disc of 3 spot sigmas, whose edge the spot has
left), the clipped centroid's error is, to first order,

    e(p) = -sum_pixels (x - p) (g_p(x) - c)_+ / F,

``F`` the window's (clipped) flux. ``e`` is a deterministic function of ``p``; it averages
to zero over ``p`` for a symmetric spot (``e(-p) = -e(p)``), and the true phase is unknown
and uniform a priori, so its covariance over ``p``, ``E_p[e e^T]``, is the honest second
moment of this error for a spot measured once; it adds to the noise's covariance (the
noise and the phase are independent). On rendered 70 m beacons of the thesis camera
(8 bit, a 7 x 6 px plateau, peaks 8-10x the full well) ``cog``'s centres erred by 0.010 px
RMS against a noise sigma of 0.0025 px; with this term their median sigma is 0.012 px
(RMS z 0.81, largest |z| 2.7, 209 beacons of 11 frames). ``gauss`` needs no term: its
censored fit leaves the plateau out (0.0027 px RMS on the same beacons, RMS z 1.16).

The spot's model comes from what the detector measured of it: an axis-aligned Gaussian of
widths ``s_u`` and ``s_v`` and flux ``N``, pixel-integrated, clipped at ``c``. Its aspect
``s_u / s_v`` is that of the spot's second moments (:func:`spot_aspect`; a clipped
elliptical Gaussian is a clipped round one stretched along the axes, so clipping leaves the
ratio alone): a camera whose pixels are not square, as the thesis's (``fx / fy`` = 4/3),
draws a round light wider along one axis, and a round model puts its phase error on the
wrong axis (noise-free clipped Gaussians 4/3 wide: 0.65-2.3x the RMS per axis). A Gaussian
of peak ``A`` clipped at ``c`` has an elliptical plateau of area ``2 pi s_u s_v ln(A / c)``
(``n_sat`` saturated pixels) and outside it carries ``2 pi s_u s_v c``, so the clipped flux
is ``S = c (n_sat + 2 pi s_u s_v)`` and

    s_u s_v = (S / c - n_sat) / (2 pi),   ln(A / c) = n_sat / (2 pi s_u s_v),   N = 2 pi s_u s_v A.

The count ``n_sat`` is not the plateau's area: the pixels whose centres fall inside an
ellipse differ from its area by the order of the square root of its perimeter (the Gauss
circle problem's lattice-point error), and they move with the phase itself (a 19-pixel
plateau counts 18-21). The phase error, though, swings by 2-5x with one pixel more or less
of plateau (the plateau's edge meets the pixel grid in step or out of it). So the term is
averaged over plateau areas uniform in ``n_sat -/+ sqrt(2 pi r)`` (``r`` the radius of a disc
of ``n_sat`` pixels; midpoint rule, :data:`PLATEAU_SAMPLES` areas), the areas this count
allows; with the count taken as the area, noise-free clipped Gaussians of random width,
aspect and peak had per-axis RMS z of 0.4-3.6 per spot, 1.2-1.4 pooled, and up to 14 at a
phase; averaged, 0.2-1.8 per spot, 0.96-1.00 pooled, at most 5.2 (tests/detect/test_clipped_phase.py).

The excess is evaluated on a grid of ``phases x phases`` sub-pixel positions (the pixels of
the plateau's box only: elsewhere the excess is zero). First order means that the window's
own pull (its soft edge, re-centred on the estimate) is left out: with the spot's own
plateau area, flux and aspect the term is 0.84-1.11x the RMS of ``cog``'s actual errors over
the phases of noise-free clipped Gaussians, round and elliptical (tests/detect/test_clipped_phase.py).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

__all__ = ["MAX_ASPECT", "PHASES", "clipped_phase_cov", "spot_aspect"]

#: Sub-pixel phases per axis (the grid is ``PHASES x PHASES``, uniform over a pixel).
#: The error is a smooth periodic function of the phase with kinks where a pixel joins
#: the plateau; 8 per axis gave 0.99-1.06x the RMS of a 64 x 64 grid for plateaus of
#: 1-400 px (tests/detect/test_clipped_phase.py).
PHASES = 8

#: The model's peak is at most this many e-folds above the clip level (a plateau wider
#: than its wings suggest: the exponent would overflow, and a spot this hard-edged is no
#: Gaussian anyway).
MAX_LOG_PEAK_OVER_CLIP = 30.0

#: Plateau areas the term averages over (:func:`_phase_cov_one`).
PLATEAU_SAMPLES = 5

#: The widest aspect (``u`` width over ``v`` width, or its inverse) the model takes.
MAX_ASPECT = 4.0


def clipped_phase_cov(
    clip_dn: np.ndarray,
    n_saturated: np.ndarray,
    flux_dn: np.ndarray,
    aspect: np.ndarray | None = None,
    *,
    phases: int = PHASES,
) -> np.ndarray:
    """Covariance over the sub-pixel phase of a clipped core's centroid error, (K, 2, 2) px^2.

    Parameters
    ----------
    clip_dn : (K,) array of float
        The clip level in the signal the centroid was measured on (the saturated pixels'
        signal above the pedestal), DN.
    n_saturated : (K,) array of int
        The spot's saturated pixels (its plateau), count.
    flux_dn : (K,) array of float
        The windowed (clipped) flux the centroid divides by, DN.
    aspect : (K,) array of float, optional
        The spot's width along ``u`` over its width along ``v`` (:func:`spot_aspect`; a
        camera whose pixels are not square draws a round spot wider in one axis). Default 1
        (round); clamped to ``[1 / MAX_ASPECT, MAX_ASPECT]``.
    phases : int
        Sub-pixel phases per axis.

    Returns
    -------
    (K, 2, 2) array of float
        ``E_p[e e^T]`` over the phase grid (module docstring); zero where the spot has no
        saturated pixel or no positive clip level or flux.
    """
    clip = np.asarray(clip_dn, float).reshape(-1)
    n_sat = np.asarray(n_saturated, float).reshape(-1)
    flux = np.asarray(flux_dn, float).reshape(-1)
    if not clip.shape == n_sat.shape == flux.shape:
        raise ValueError(f"clip_dn, n_saturated and flux_dn must have one shape (K,), got "
                         f"{clip.shape}, {n_sat.shape} and {flux.shape}")
    if phases < 1:
        raise ValueError(f"phases must be >= 1, got {phases}")
    ratio = np.ones_like(clip) if aspect is None else np.asarray(aspect, float).reshape(-1)
    if ratio.shape != clip.shape:
        raise ValueError(f"aspect must have the shape (K,) of clip_dn, got {ratio.shape} and {clip.shape}")
    ratio = np.clip(np.where(np.isfinite(ratio) & (ratio > 0), ratio, 1.0), 1.0 / MAX_ASPECT, MAX_ASPECT)
    out = np.zeros((clip.size, 2, 2))
    for k in np.flatnonzero((n_sat > 0) & (clip > 0) & (flux > 0)):
        out[k] = _phase_cov_one(float(clip[k]), float(n_sat[k]), float(flux[k]), float(ratio[k]), phases)
    return out


def spot_aspect(signal: np.ndarray, mask: np.ndarray) -> float:
    """A spot's width along ``u`` over its width along ``v``, from its second moments.

    The moments of the signal over the blob's mask, each less the pixel's own ``1/12``
    px^2. A clipped elliptical Gaussian ``min(g, c)`` is a clipped round one stretched along
    the axes, and its mask (a level set of it) is stretched alike, so the ratio of its
    moments is the square of the widths' ratio whatever the clipping. 1 where the
    moments are not positive.

    Parameters
    ----------
    signal : (h, w) array of float
        The spot's signal, DN.
    mask : (h, w) array of bool
        The blob's pixels.
    """
    vv, uu = np.nonzero(mask)
    wts = np.maximum(signal[vv, uu], 0.0)
    total = float(wts.sum())
    if not total > 0:
        return 1.0
    du = uu - float((wts * uu).sum()) / total
    dv = vv - float((wts * vv).sum()) / total
    m_uu = float((wts * du * du).sum()) / total - 1.0 / 12.0
    m_vv = float((wts * dv * dv).sum()) / total - 1.0 / 12.0
    return math.sqrt(m_uu / m_vv) if m_uu > 0 and m_vv > 0 else 1.0


def _phase_cov_one(c: float, n_sat: float, flux: float, aspect: float, phases: int) -> np.ndarray:
    """:func:`clipped_phase_cov` of one spot, (2, 2) px^2: its phases and plateau sizes together."""
    # The plateau's true area is known to about the lattice count's spread (module docstring):
    # uniform over n_sat -/+ sqrt(2 pi r), r the radius of a disc of n_sat pixels, by the
    # midpoint rule on PLATEAU_SAMPLES areas.
    spread = math.sqrt(2.0 * math.pi * math.sqrt(n_sat / math.pi))
    mid = (np.arange(PLATEAU_SAMPLES) + 0.5) / PLATEAU_SAMPLES * 2.0 - 1.0  # (J,) in (-1, 1)
    area = np.maximum(n_sat + spread * mid, 0.0)  # (J,)
    # s_u s_v (the round model's s^2), the wings' share of the clipped flux, at least that of
    # the plateau's one-pixel rim
    s2 = np.maximum.reduce([(flux / c - area) / (2.0 * math.pi),
                            0.25 * area / math.pi / MAX_LOG_PEAK_OVER_CLIP, np.full_like(area, 0.01)])
    log_peak = np.minimum(area / (2.0 * math.pi * s2), MAX_LOG_PEAK_OVER_CLIP)  # ln(A / c)
    n_total = 2.0 * math.pi * s2 * c * np.exp(log_peak)
    s_u, s_v = np.sqrt(s2 * aspect), np.sqrt(s2 / aspect)
    # Phases p in [-1/2, 1/2) (a pixel's centre at 0). The model is an axis-aligned ellipse
    # centred on the pixel, so e_u is odd in p_u and even in p_v (e_v alike, axes swapped):
    # e_u^2 and e_v^2 take the same values in each quadrant of the phase grid and e_u e_v
    # averages to zero over it. The quadrant p >= 0 gives the whole grid's mean (a phase at
    # 0, its own mirror, counts half).
    p_all = (np.arange(phases) + 0.5) / phases - 0.5
    p = p_all[p_all >= 0.0]  # (P,)
    w = np.where(p == 0.0, 0.5, 1.0)
    wts = w[:, None] * w[None, :]  # (Pv, Pu)
    r_p = np.sqrt(2.0 * log_peak)  # the plateaus' semi-axes are r_p s_u and r_p s_v
    x = np.arange(-(math.ceil(float((r_p * s_u).max())) + 2), math.ceil(float((r_p * s_u).max())) + 3.0)
    y = np.arange(-(math.ceil(float((r_p * s_v).max())) + 2), math.ceil(float((r_p * s_v).max())) + 3.0)
    # exact fractions of a unit Gaussian in each pixel, per plateau size and phase: (J, P, n)
    su, sv, pp = s_u[:, None, None], s_v[:, None, None], p[None, :, None]
    fu = ndtr((x[None, None, :] + 0.5 - pp) / su) - ndtr((x[None, None, :] - 0.5 - pp) / su)
    fv = ndtr((y[None, None, :] + 0.5 - pp) / sv) - ndtr((y[None, None, :] - 0.5 - pp) / sv)
    g = n_total[:, None, None, None, None] * fv[:, :, None, :, None] * fu[:, None, :, None, :]  # (J, Pv, Pu, rows, cols)
    excess = np.maximum(g - c, 0.0)
    # e_u(pv, pu) = -sum (x - pu) excess / F, and likewise along v
    eu = -(excess.sum(axis=3) * (x[None, None, None, :] - p[None, None, :, None])).sum(axis=3) / flux
    ev = -(excess.sum(axis=4) * (y[None, None, None, :] - p[None, :, None, None])).sum(axis=3) / flux
    norm = float(wts.sum()) * area.size
    return np.diag([float((wts * eu * eu).sum()), float((wts * ev * ev).sum())]) / norm
