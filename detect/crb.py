"""Cramér–Rao bound of a beacon centroid: the best any unbiased detector can do.

The spot is the pixel-integrated circular Gaussian of :mod:`deckpose.detect.synthetic`
with unknown centre ``(u, v)``, width ``sigma``, flux ``N`` and background ``b``
(all five estimated, so the bound on the centre includes the cost of not knowing
the other three). Pixel ``k`` has expected electrons
``mu_k = b + N * Ex_k(u, sigma) * Ey_k(v, sigma)`` and variance
``mu_k + read_noise**2 + 1 / (12 * gain**2)``: Poisson shot noise plus read and
quantisation noise, with the usual shifted-Poisson approximation of the
Poisson+Gaussian likelihood (Huang et al., Nat. Methods 2013), under which the
Fisher information is ``I = sum_k grad(mu_k) grad(mu_k)^T / var_k``.
Saturation is not modelled (the bound assumes unclipped pixels).
"""

from __future__ import annotations

import math

import numpy as np
from deckpose.detect.synthetic import SensorModel
from numpy.typing import NDArray
from scipy.special import erf

from deckpose.errors import ConfigError

FloatArray = NDArray[np.float64]

_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


def gaussian_pixel_terms(
    centre: float, sigma: float, x: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``E``, ``dE/dcentre``, ``dE/dsigma`` of a 1-D Gaussian over unit pixels ``x``, each (M,)."""
    a_hi = (x + 0.5 - centre) / sigma
    a_lo = (x - 0.5 - centre) / sigma
    E = 0.5 * (erf(a_hi / math.sqrt(2.0)) - erf(a_lo / math.sqrt(2.0)))
    p_hi = _INV_SQRT_2PI * np.exp(-0.5 * a_hi**2)
    p_lo = _INV_SQRT_2PI * np.exp(-0.5 * a_lo**2)
    dE_dc = -(p_hi - p_lo) / sigma
    dE_ds = -(p_hi * a_hi - p_lo * a_lo) / sigma
    return E, dE_dc, dE_ds


def centroid_fisher(
    u_px: float, v_px: float, sigma_px: float, flux_e: float, sensor: SensorModel
) -> FloatArray:
    """Fisher information of ``(u, v, sigma, flux, background)`` for one spot.

    Parameters
    ----------
    u_px, v_px : float
        True spot centre, pixels.
    sigma_px : float
        Spot standard deviation, pixels (> 0).
    flux_e : float
        Spot electrons (> 0).
    sensor : SensorModel
        Background, read noise and gain.

    Returns
    -------
    (5, 5) array of float
    """
    if not (sigma_px > 0 and flux_e > 0):
        raise ConfigError(f"CRB needs sigma_px > 0 and flux_e > 0, got {sigma_px}, {flux_e}")
    h = math.ceil(8.0 * sigma_px + 2.0)
    xs = np.arange(round(u_px) - h, round(u_px) + h + 1, dtype=float)
    ys = np.arange(round(v_px) - h, round(v_px) + h + 1, dtype=float)
    Ex, dEx, sEx = gaussian_pixel_terms(u_px, sigma_px, xs)
    Ey, dEy, sEy = gaussian_pixel_terms(v_px, sigma_px, ys)
    mu = sensor.background_e + flux_e * np.outer(Ey, Ex)
    var = mu + sensor.extra_variance_e2
    grads = np.stack(
        [
            flux_e * np.outer(Ey, dEx),
            flux_e * np.outer(dEy, Ex),
            flux_e * (np.outer(Ey, sEx) + np.outer(sEy, Ex)),
            np.outer(Ey, Ex),
            np.ones_like(mu),
        ]
    ).reshape(5, -1)
    w = 1.0 / var.ravel()
    return (grads * w) @ grads.T


def centroid_crb_px2(
    u_px: float, v_px: float, sigma_px: float, flux_e: float, sensor: SensorModel
) -> FloatArray:
    """Cramér–Rao lower bound on the covariance of an unbiased centre estimate.

    Parameters
    ----------
    u_px, v_px, sigma_px, flux_e, sensor
        As :func:`centroid_fisher`.

    Returns
    -------
    (2, 2) array of float, px^2
        The ``(u, v)`` block of the inverse Fisher information (nuisance
        parameters sigma, flux and background unknown).
    """
    info = centroid_fisher(u_px, v_px, sigma_px, flux_e, sensor)
    return np.asarray(np.linalg.inv(info)[:2, :2], dtype=np.float64)

