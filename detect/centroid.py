"""The two classic centroiders: ``binary`` (the baseline) and ``cog``.

* ``binary``: threshold + connected components, centre of the binary blob, as
  most LED trackers do. Every pixel above the threshold counts the same, so
  the centre moves in steps as pixels cross the threshold.
* ``cog``: intensity-weighted centre of gravity of background-subtracted pixels,
  in a soft-edged circular window of ``window_sigma`` spot sigmas re-centred on
  the estimate until it converges (a symmetric window does not bias a
  symmetric spot).
"""

from __future__ import annotations

import math

import numpy as np

from deckpose.detect.candidates import Candidate, measure_candidates
from deckpose.detect.registry import Blobs, DetectorOptions, register
from deckpose.records import Frame

Row = tuple[float, float, np.ndarray, float, float, float]


def truncated_m2_fraction(k: float) -> float:
    """Per-axis second moment of a 2-D Gaussian truncated at radius ``k`` sigma, over sigma^2."""
    e = math.exp(-k * k / 2.0)
    return (1.0 - (1.0 + k * k / 2.0) * e) / (1.0 - e)


def binary_centroid(cand: Candidate) -> Row:
    """Unweighted centre of the blob's mask; covariance adds the mask's quantisation."""
    u, v, sigma = cand.mask_moments()
    flux = float(cand.signal()[cand.mask].sum())
    base = cand.blob(u, v, flux_dn=flux, size_px=sigma)
    area = int(cand.mask.sum())
    quant = 1.0 / (12.0 * math.sqrt(area))  # heuristic: boundary pixels flipping in or out
    return base[:2] + (base[2] + np.eye(2) * quant,) + base[3:]


def cog_centroid(cand: Candidate, window_sigma: float = 3.0, max_iter: int = 20) -> Row | None:
    """Iterated, soft-windowed intensity centroid of one candidate (``None`` if degenerate)."""
    s = cand.signal()
    uu, vv = cand.grid()
    ms = np.where(cand.mask, s, 0.0)
    F = ms.sum()
    if not F > 0:
        return None
    u, v = float((ms * uu).sum() / F), float((ms * vv).sum() / F)
    sigma = cand.mask_moments()[2]
    sigma_max = 0.5 * min(s.shape) / window_sigma + 1.0
    m2_frac = truncated_m2_fraction(window_sigma)
    w = ws = np.zeros_like(s)
    for _ in range(max_iter):
        R = window_sigma * sigma
        d = np.hypot(uu - u, vv - v)
        w = np.clip(R + 0.5 - d, 0.0, 1.0)
        ws = w * s
        F = ws.sum()
        if not F > 0:
            return None
        un, vn = float((ws * uu).sum() / F), float((ws * vv).sum() / F)
        m2 = float((ws * ((uu - un) ** 2 + (vv - vn) ** 2)).sum() / F) / 2.0
        sigma = float(np.clip(math.sqrt(max(m2, 0.0) / m2_frac), 0.5, sigma_max))
        shift = math.hypot(un - u, vn - v)
        u, v = un, vn
        if shift < 1e-5:
            break
    var = cand.variance(s) * w**2
    du, dv = uu - u, vv - v
    cov = np.array([[(var * du * du).sum(), (var * du * dv).sum()],
                    [(var * du * dv).sum(), (var * dv * dv).sum()]]) / F**2
    return cand.blob(u, v, flux_dn=float(F), size_px=sigma, cov_px2=cov)


@register("binary")
def detect_binary(frame: Frame, options: DetectorOptions) -> Blobs:
    """Baseline: adaptive threshold + connected components, binary-blob centre."""
    return measure_candidates(frame, options, binary_centroid)


@register("cog")
def detect_cog(frame: Frame, options: DetectorOptions) -> Blobs:
    """Intensity-weighted centre of gravity in a re-centred window around each blob."""
    return measure_candidates(frame, options, lambda c: cog_centroid(c, options.window_sigma))
