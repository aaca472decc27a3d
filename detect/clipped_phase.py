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

The spot's model comes from what the detector measured of it: a round Gaussian of
sigma ``s`` and flux ``N``, pixel-integrated, clipped at ``c``. A Gaussian of peak ``A``
clipped at ``c`` has a plateau of radius ``r_p``, ``r_p^2 = 2 s^2 ln(A / c)`` (area ``n_sat``
saturated pixels: ``r_p^2 = n_sat / pi``), and outside it carries ``2 pi s^2 c`` (the
integral of the Gaussian beyond ``r_p`` is ``2 pi s^2 A exp(-r_p^2 / 2 s^2)``), so the
clipped flux is ``S = c (n_sat + 2 pi s^2)`` and

    s^2 = (S / c - n_sat) / (2 pi),   A = c exp(r_p^2 / (2 s^2)),   N = 2 pi s^2 A.

The excess is evaluated on a grid of ``phases x phases`` sub-pixel positions (the pixels of
the plateau's box only: elsewhere the excess is zero). First order means that the window's
own pull (its soft edge, re-centred on the estimate) is left out: against ``cog``'s actual
errors over the phases of noise-free clipped Gaussians the term is 0.93-1.14x their RMS;
against spots that are no Gaussian (discs through a PSF, 8 bit, noise) ``cog``'s RMS z
with it is 1.1 (tests/detect/test_clipped_phase.py).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

__all__ = ["PHASES", "clipped_phase_cov"]

#: Sub-pixel phases per axis (the grid is ``PHASES x PHASES``, uniform over a pixel).
#: The error is a smooth periodic function of the phase with kinks where a pixel joins
#: the plateau; 8 per axis gave 0.99-1.06x the RMS of a 64 x 64 grid for plateaus of
#: 1-400 px (tests/detect/test_clipped_phase.py).
PHASES = 8

#: The model's peak is at most this many e-folds above the clip level (a plateau wider
#: than its wings suggest: the exponent would overflow, and a spot this hard-edged is no
#: Gaussian anyway).
MAX_LOG_PEAK_OVER_CLIP = 30.0


def clipped_phase_cov(
    clip_dn: np.ndarray,
    n_saturated: np.ndarray,
    flux_dn: np.ndarray,
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
    out = np.zeros((clip.size, 2, 2))
    for k in np.flatnonzero((n_sat > 0) & (clip > 0) & (flux > 0)):
        out[k] = _phase_cov_one(float(clip[k]), float(n_sat[k]), float(flux[k]), phases)
    return out


def _phase_cov_one(c: float, n_sat: float, flux: float, phases: int) -> np.ndarray:
    """:func:`clipped_phase_cov` of one spot, (2, 2) px^2: the phases of its model together."""
    r_p2 = n_sat / math.pi
    # the wings' share of the clipped flux, at least that of the plateau's one-pixel rim
    s2 = max((flux / c - n_sat) / (2.0 * math.pi), 0.25 * r_p2 / MAX_LOG_PEAK_OVER_CLIP, 0.01)
    s = math.sqrt(s2)
    n_total = 2.0 * math.pi * s2 * c * math.exp(min(r_p2 / (2.0 * s2), MAX_LOG_PEAK_OVER_CLIP))
    # Phases p in [-1/2, 1/2) (a pixel's centre at 0). The model is round and centred, so
    # e_u is odd in p_u and even in p_v (e_v alike, axes swapped): e_u^2 and e_v^2 take the
    # same values in each quadrant of the phase grid and e_u e_v averages to zero over it.
    # The quadrant p >= 0 gives the whole grid's mean (a phase at 0, its own mirror, counts half).
    p_all = (np.arange(phases) + 0.5) / phases - 0.5
    p = p_all[p_all >= 0.0]  # (P,)
    w = np.where(p == 0.0, 0.5, 1.0)
    wts = w[:, None] * w[None, :]  # (Pv, Pu)
    half = math.ceil(math.sqrt(r_p2)) + 2  # the plateau's box around the phases
    x = np.arange(-half, half + 1, dtype=float)  # (n,)
    # exact fractions of a unit Gaussian in each pixel, per phase: (P, n)
    frac = ndtr((x[None, :] + 0.5 - p[:, None]) / s) - ndtr((x[None, :] - 0.5 - p[:, None]) / s)
    g = n_total * frac[:, None, :, None] * frac[None, :, None, :]  # (Pv, Pu, rows, cols)
    excess = np.maximum(g - c, 0.0)
    # e_u(pv, pu) = -sum (x - pu) excess / F, and likewise along v
    eu = -(excess.sum(axis=2) * (x[None, None, :] - p[None, :, None])).sum(axis=2) / flux
    ev = -(excess.sum(axis=3) * (x[None, None, :] - p[:, None, None])).sum(axis=2) / flux
    return np.diag([float((wts * eu * eu).sum()), float((wts * ev * ev).sum())]) / float(wts.sum())
