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
        uu, vv = c.grid()
        core = (np.hypot(uu - u, vv - v) <= 2.0 * sigma) & ~c.saturated
        r2 = (c.signal() - model)[core] ** 2
        num += float(np.sum(r2 - c.noise_dn**2))
        den += float(np.sum(np.maximum(model[core], 0.0)))
    if not (den > 0 and num > 0):
        return DEFAULT_GAIN_DN_PER_E
    return float(np.clip(num / den, 1e-3, 1e3))
