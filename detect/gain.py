"""Sensor gain (DN per electron) estimated from a frame's own blobs.

Covariances and fit weights need the shot-noise gain. When it is not given,
each blob is modelled as the pixel-integrated Gaussian of its ``cog`` centre,
flux and width; the excess of the squared residuals over the background noise,
pooled over all blobs and divided by the pooled model signal, estimates the gain
(``var = noise**2 + gain * signal``). A spot that is not Gaussian (a rendered
disc) leaves model residuals that only add variance: the estimate then errs on
the conservative side (larger covariances).
"""

from __future__ import annotations

import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.centroid import cog_centroids
from deckpose.detect.synthetic import pixel_fractions

#: Used when no blob constrains the gain.
DEFAULT_GAIN_DN_PER_E = 1.0


def estimate_gain(cands: list[Candidate], window_sigma: float = 3.0, max_blobs: int = 6) -> float:
    """Pooled shot-noise gain of a frame's candidates, DN per electron (clipped to [1e-3, 1e3]).

    Uses the ``max_blobs`` largest blobs (most shot-noise signal; fewer model fits)
    whose cores do not saturate: a clipped core is no Gaussian of its ``cog`` flux.
    """
    num = den = 0.0
    unclipped = [c for c in cands if not c.saturated[c.mask].any()]
    by_size = sorted(unclipped, key=lambda c: -int(c.mask.sum()))
    used = by_size[:max_blobs]
    for c, row in zip(used, cog_centroids(used, window_sigma, above_floor=False, covariance=False)):
        if row is None:
            continue
        u, v, _, flux, sigma_mom, _ = row
        # The moments of a pixel-integrated Gaussian include the pixel's own 1/12 px^2.
        sigma = float(np.sqrt(max(sigma_mom**2 - 1.0 / 12.0, 0.04)))
        h, w = c.pixels.shape
        model = flux * np.outer(
            pixel_fractions(v, sigma, np.arange(h) + c.v0),
            pixel_fractions(u, sigma, np.arange(w) + c.u0),
        )
        uu = np.arange(w, dtype=float)[None, :] + c.u0  # broadcast: Candidate.grid()'s values
        vv = np.arange(h, dtype=float)[:, None] + c.v0
        core = (np.hypot(uu - u, vv - v) <= 2.0 * sigma) & ~c.saturated
        r2 = (c.signal() - model)[core] ** 2
        num += float(np.sum(r2 - c.noise_dn**2))
        den += float(np.sum(np.maximum(model[core], 0.0)))
    if not (den > 0 and num > 0):
        return DEFAULT_GAIN_DN_PER_E
    return float(np.clip(num / den, 1e-3, 1e3))


#: Fewest spots whose fits :func:`fitted_noise_model` pools (fewer: the candidates' model stays).
MIN_FITTED_SPOTS = 3
#: Fewest pixels it pools.
MIN_FITTED_PIXELS = 50


def fitted_noise_model(sq_residual_dn2: np.ndarray, signal_dn: np.ndarray) -> tuple[float, float] | None:
    """Background variance and gain of a frame from the residuals of its spot fits.

    The squared residual of each fitted pixel estimates its variance
    ``a + gain * s`` (background variance ``a``, shot noise of the spot signal
    ``s``); ``a`` and ``gain`` are fitted to them by weighted least squares
    (a squared Gaussian residual has variance ``2 E[r^2]^2``: weights from the
    current fit, four passes, each without the pixels beyond 4 sigma of the last: a
    neighbour or a defect in a window). Unlike :func:`estimate_gain`,
    it does not take the background variance as given: a noise floor (the
    thresholds' 1 DN per channel on an 8-bit frame, 3x the variance there) or the
    quantised difference noise of a 12-bit frame in 16 bits (17 % high) would
    otherwise go into the fit weights and into the gain (on 8-bit frames
    :func:`estimate_gain` fell back to 1 DN/e, 23x the true 0.0425).

    Parameters
    ----------
    sq_residual_dn2 : (M,) array of float
        Squared residuals of the fits' pixels, DN^2, each divided by ``1 - h``
        (``h`` its leverage in the fit), so that it estimates the pixel's variance
        without the share the fitted parameters took.
    signal_dn : (M,) array of float
        The fitted spot signal at those pixels (background excluded), DN.

    Returns
    -------
    (float, float) or None
        ``(background variance DN^2, gain DN per electron)``, the gain clipped to
        [1e-3, 1e3] as :func:`estimate_gain`'s; ``None`` when fewer than
        :data:`MIN_FITTED_PIXELS` pixels are given or the background variance does not come out positive.
    """
    r2 = np.asarray(sq_residual_dn2, float).ravel()
    s = np.maximum(np.asarray(signal_dn, float).ravel(), 0.0)
    if r2.shape != s.shape:
        raise ValueError(f"fitted_noise_model: {r2.shape[0]} residuals but {s.shape[0]} signals; "
                         "give one of each per fitted pixel")
    if r2.size < MIN_FITTED_PIXELS:
        return None
    X = np.column_stack([np.ones_like(s), s])
    # a start that a few wild pixels cannot move: the squared residuals capped at their
    # 99th percentile; then each pass drops the pixels beyond 4 sigma of the last one
    coef = np.linalg.lstsq(X, np.minimum(r2, np.percentile(r2, 99.0)), rcond=None)[0]
    for _ in range(4):
        var = np.maximum(X @ coef, 1e-12)
        w = (r2 < 16.0 * var) / var
        coef = np.linalg.lstsq(X * w[:, None], r2 * w, rcond=None)[0]
    a, gain = float(coef[0]), float(coef[1])
    if not (np.isfinite(a) and np.isfinite(gain) and a > 0):
        return None
    return a, float(np.clip(gain, 1e-3, 1e3))
