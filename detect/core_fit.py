"""Censored least-squares fit of a spot's core: a Gaussian through a saturated or framed spot.

A beacon whose core saturates keeps its position in the wings just outside the
clipped plateau. This fit uses exactly those pixels:

* the model is an elliptical, rotated 2-D Gaussian on a constant background,
  ``b + F * |P|**0.5 / (2 pi) * exp(-d^T P d / 2)`` with ``d = (u - u_c, v - v_c)``
  and precision matrix ``P = L L^T``, ``L = [[p, 0], [q, r]]`` (positive
  definite for any ``p, q, r``), sampled at pixel centres: seven parameters;
* the data are the pixels within the measuring window, connected to the blob,
  whose signal above the floor the core rises from (20th percentile of the
  window) is at least ``CORE_FRACTION`` of the clip level (a clipped core) or
  ``UNCLIPPED_CORE_FRACTION`` of the brightest pixel (an unclipped one), so the
  faint halo, a dark housing or a marking around the core do not enter;
* saturated pixels are *censored*: they only say that the true value is at or
  above the clip level, so their residual is ``min(model - data, 0)`` (no cost
  while the model reaches the clip level) and their rows of the Jacobian vanish
  there;
* weights are the inverse modelled noise variance (background noise plus shot
  noise of the model), updated once from the first fit.

The centre covariance is the ``(u, v)`` block of ``inv(J^T W J)`` over the
unsaturated pixels (censored pixels above the clip carry no information at the
solution), scaled by the reduced chi-square of the fit, so a gain estimated
poorly from saturated blobs, or a core that is not quite Gaussian, widens it
rather than leaving it overconfident.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.registry import BlobRow
from scipy.optimize import least_squares

#: Pixels of a clipped core whose signal reaches this fraction of the clip level enter the
#: fit. Lower values reach into the halo and the housing edge of rendered beacons (0.05-0.1
#: doubled the error at 50-80 m by day), higher ones leave small cores too few pixels (0.7
#: failed most 80 m beacons); measured on rendered detector-benchmark frames.
CORE_FRACTION = 0.35
#: The same for an unclipped core, as a fraction of its brightest pixel (2.8 sigma out):
#: the wings hold much of the position information (0.35 lost ~70 % of it; measured on
#: configs/detector_crb.yaml renders, 0.02 and 0.05 alike).
UNCLIPPED_CORE_FRACTION = 0.02


def elliptical_gaussian(
    params: np.ndarray, u_px: np.ndarray, v_px: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Model and Jacobian of the point-sampled elliptical Gaussian, (M,) and (M, 7).

    Parameters
    ----------
    params : (7,) array of float
        ``(u_c, v_c, p, q, r, F, b)``: centre (px), Cholesky factor of the precision
        matrix (1/px), flux (signal summed over the spot, DN) and background (DN).
    u_px, v_px : (M,) array of float
        Pixel centres.
    """
    u, v, p, q, r, F, b = (float(x) for x in params)
    du, dv = u_px - u, v_px - v
    a, c_, e = p * p, p * q, q * q + r * r  # P = [[a, c_], [c_, e]]
    quad = a * du * du + 2.0 * c_ * du * dv + e * dv * dv
    norm = abs(p * r) / (2.0 * math.pi)  # sqrt(det P) / (2 pi)
    g = np.exp(-0.5 * np.minimum(quad, 1400.0))
    s = F * norm * g  # spot signal per pixel
    J = np.empty((u_px.size, 7))
    J[:, 0] = s * (a * du + c_ * dv)
    J[:, 1] = s * (c_ * du + e * dv)
    # d quad / d(p, q, r) and d log(norm) / d(p, q, r)
    J[:, 2] = s * (-(p * du * du + q * du * dv) + 1.0 / p)
    J[:, 3] = s * (-(p * du * dv + q * dv * dv))
    J[:, 4] = s * (-r * dv * dv + 1.0 / r)
    J[:, 5] = norm * g
    J[:, 6] = 1.0
    return b + s, J


def core_fit(cand: Candidate, start: BlobRow, window_sigma: float = 3.0) -> BlobRow | None:
    """Censored elliptical-Gaussian fit of one candidate's core (module docstring).

    Parameters
    ----------
    cand : Candidate
    start : BlobRow
        The ``cog`` measurement of the candidate (start point and window size).
    window_sigma : float
        Radius of the window searched for core pixels, in ``cog`` spot sigmas.

    Returns
    -------
    BlobRow or None
        ``None`` when too few unsaturated core pixels remain or the fit fails.
    """
    fit = core_fit_residuals(cand, start, window_sigma)
    return None if fit is None else fit[0]


def core_fit_residuals(cand: Candidate, start: BlobRow, window_sigma: float = 3.0
                       ) -> tuple[BlobRow, np.ndarray, np.ndarray] | None:
    """:func:`core_fit`, with what its unsaturated pixels say of the noise.

    Returns
    -------
    (BlobRow, (M,) array of float, (M,) array of float) or None
        The row; per unsaturated fitted pixel its squared residual over ``1 - h``
        (``h``: its leverage in the weighted fit), DN^2, and the fitted spot signal
        there, DN: the inputs of :func:`~deckpose.detect.gain.fitted_noise_model`.
        ``None`` where :func:`core_fit` gives None.
    """
    u0, v0, _, F0, s0, _ = start
    # Above the level the core rises from: the darker part of the window (a beacon's
    # housing, the deck), not the candidate's pedestal, which may be a bright marking nearby.
    signal, near = cand.above_floor(u0, v0, window_sigma * s0 + 2.0)
    uu, vv = cand.grid()
    sat_all = cand.saturated & near
    top = float(signal[sat_all].min()) if sat_all.any() else float(signal[near].max())
    if not top > 0:
        return None
    frac = CORE_FRACTION if sat_all.any() else UNCLIPPED_CORE_FRACTION
    sel = near & ((signal >= frac * top) | sat_all)
    # only the core's own pixels: the part of the selection connected to the blob
    _n_lab, labels = cv2.connectedComponents(sel.astype(np.uint8), connectivity=8)
    own = np.unique(labels[cand.mask & sel])
    sel &= np.isin(labels, own[own > 0])
    sat = sat_all[sel]
    data, U, V = signal[sel], uu[sel], vv[sel]
    n_free = int((~sat).sum())
    if n_free < 12:
        return None
    inv_s = 1.0 / max(s0, 0.3)
    # start: the cog centre, a round spot of the cog width, and a flux that reaches the top
    flux0 = max(F0, 2.0 * math.pi * s0 * s0 * top)
    p = np.array([u0, v0, inv_s, 0.0, inv_s, flux0, 0.0])  # background relative to floor
    # bounds keep the model finite: centre within the window, widths 0.2-50 px, flux >= 0
    reach = window_sigma * s0 + 2.0
    bounds = (
        [u0 - reach, v0 - reach, 0.02, -5.0, 0.02, 0.0, -np.inf],
        [u0 + reach, v0 + reach, 5.0, 5.0, 5.0, np.inf, np.inf],
    )
    p[2] = p[4] = min(max(inv_s, 0.03), 4.9)
    for _ in range(2):  # weights from the current model, then once more from the fit
        m, _ = elliptical_gaussian(p, U, V)
        wts = 1.0 / np.sqrt(cand.noise_dn**2 + cand.gain_dn_per_e * np.maximum(m - p[6], 0.0))

        def fun(x: np.ndarray, wts: np.ndarray = wts) -> np.ndarray:
            r = elliptical_gaussian(x, U, V)[0] - data
            r[sat] = np.minimum(r[sat], 0.0)
            return r * wts

        def jac(x: np.ndarray, wts: np.ndarray = wts) -> np.ndarray:
            m, J = elliptical_gaussian(x, U, V)
            J = J * wts[:, None]
            J[sat & (m >= data)] = 0.0
            return J

        try:
            # scipy has no types: pyright takes jac's type (str) from its default
            res = least_squares(fun, p, jac=jac,  # pyright: ignore[reportArgumentType]
                                bounds=bounds, method="trf", x_scale="jac", max_nfev=100)
        except (ValueError, np.linalg.LinAlgError):
            return None
        p = res.x
    u, v, pp, qq, rr, F, b = (float(x) for x in p)
    if not (np.all(np.isfinite(p)) and F > 0 and abs(pp * rr) > 0):
        return None
    if math.hypot(u - u0, v - v0) > max(1.0, s0):  # far from the windowed centroid
        return None
    if sat.any():  # a clipped plateau's centre lies within it
        Us, Vs = U[sat], V[sat]
        if not (Us.min() <= u <= Us.max() and Vs.min() <= v <= Vs.max()):
            return None
    P = np.array([[pp * pp, pp * qq], [pp * qq, qq * qq + rr * rr]])
    size = float(np.linalg.det(np.linalg.inv(P)) ** 0.25)  # Gaussian-equivalent sigma
    if not 0.2 < size < 4.0 * (window_sigma * s0 + 2.0):
        return None
    m, J = elliptical_gaussian(p, U, V)
    free = ~sat
    var = cand.noise_dn**2 + cand.gain_dn_per_e * np.maximum(m[free] - b, 0.0)
    Jf = J[free]
    chi2 = float(np.sum((m[free] - data[free]) ** 2 / var))
    scale = chi2 / max(n_free - 7, 1)
    try:
        n_inv = np.linalg.inv((Jf / var[:, None]).T @ Jf)
    except np.linalg.LinAlgError:
        return None
    cov = n_inv[:2, :2] * scale
    # The surround's tilt left in the signal (the floor is flat): a tilt t (DN/px) along u
    # adds t (U - u) to the data and moves the fit by N^-1 J^T W (U - u) t, to first order
    # (the flat background b takes the constant part). Its bound on the centre goes in as
    # the windowed centroid's does (Candidate.surround_bias_cov).
    if cand.surround_tilt2() > 0.0:
        ramps = np.column_stack([U[free] - u, V[free] - v])
        response = (n_inv @ ((Jf / var[:, None]).T @ ramps))[:2]  # px per DN/px, (2, 2)
        cov = cov + cand.surround_bias_cov(float(np.linalg.norm(response, axis=0).max()))
    if not np.all(np.isfinite(cov)):
        return None
    # leverage of each free pixel in the weighted fit: diag(W^1/2 J N^-1 J^T W^1/2)
    lev = np.einsum("ij,jk,ik->i", Jf, n_inv, Jf) / var
    sq_res = (data[free] - m[free]) ** 2 / np.maximum(1.0 - lev, 0.05)
    row = cand.blob(u, v, flux_dn=F, size_px=size, cov_px2=cov)
    return row, sq_res, np.maximum(m[free] - b, 0.0)
