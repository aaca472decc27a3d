"""The noise of the significance search's image: its pixel noise, its skew, the threshold.

The significance search (:mod:`deckpose.detect.significance`) asks a spot to stand a
number of noise sigmas above its surroundings. The noise is measured on the search's own
image (block sums of the frame's channel sum) from pairs of horizontal neighbours, where
the scene cancels: their difference gives the pixel noise
(:func:`clipped_difference_noise`) and, with their sum, the noise's skewness
(:func:`noise_skewness`), for which the threshold is raised so that it keeps the
Gaussian tail probability (:func:`skew_threshold`). The smoothing's kernel carries both
through (:func:`gaussian_norm`, :func:`smoothed_skew_factor`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.background import MIN_NOISE_DN, clipped_std_rows, median


def _neighbour_pairs(S: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """About ``samples`` horizontal neighbours of ``S`` on a regular grid: ``(left, right)`` views, (h', w')."""
    h, w = S.shape
    step = max(1, int(math.sqrt(h * w / samples)))
    n = (w - 1) // step
    return S[::step, 0 : w - 1 : step][:, :n], S[::step, 1::step][:, :n]


def clipped_difference_noise(S: np.ndarray, samples: int = 60_000) -> float:
    """Noise of an image from horizontal pixel differences: a 4-sigma-clipped std, DN.

    :func:`clipped_std_rows` of about ``samples`` differences of neighbours, over
    ``sqrt 2`` (the noise of one pixel). ``S`` may be an integer image (one channel of a
    frame).
    """
    left, right = _neighbour_pairs(S, samples)
    if np.issubdtype(S.dtype, np.integer):  # no wrap-around below 0 (exact in float32 to 2^24)
        right = right.astype(np.float32)
    d = right - left
    d = np.asarray(d, np.float64).ravel()
    d = d[np.isfinite(d)]
    if d.size < 10:
        return MIN_NOISE_DN
    return float(clipped_std_rows(d[None])[0]) / math.sqrt(2.0)


def noise_skewness(S: np.ndarray, noise: float, samples: int = 60_000) -> float:
    """Skewness of an image's pixel noise from pairs of horizontal neighbours, unitless.

    For two neighbours ``a = t + n_a`` and ``b = t + n_b`` on a smooth scene ``t`` with
    independent noise, ``E[(a - b)^2 (a + b - E[a + b])] = 2 k3``, the noise's third
    cumulant: the scene cancels in the difference and averages out of the sum, so deck
    texture and gradients do not count as skew (a plain third moment of the pixels would
    take a bright marking for it). Pairs more than 4 noise sigmas apart or whose sum lies
    more than 8 sigmas from the median sum (a spot, an edge) are left out. Returns
    ``k3 / noise^3``; 0 where too few pairs remain.

    Parameters
    ----------
    S : (h, w) array
        The image (block sums of a frame).
    noise : float
        Its pixel noise (:func:`clipped_difference_noise`, floored), same units as ``S``.
    """
    left, right = _neighbour_pairs(S, samples)
    a, b = np.asarray(left, np.float64).ravel(), np.asarray(right, np.float64).ravel()
    d, t = a - b, a + b
    ok = np.isfinite(d) & np.isfinite(t)
    d, t = d[ok], t[ok]
    if d.size < 100 or not noise > 0:
        return 0.0
    keep = (np.abs(d) < 4.0 * math.sqrt(2.0) * noise) & (
        np.abs(t - median(t)) < 8.0 * math.sqrt(2.0) * noise)
    if np.count_nonzero(keep) < 100:
        return 0.0
    d, t = d[keep], t[keep]
    return float(np.mean(d * d * (t - t.mean()))) / 2.0 / noise**3


def skew_threshold(k_sigma: float, skew: float) -> float:
    """The threshold, in noise sigmas, with the tail probability of ``k_sigma`` on Gaussian noise.

    Cornish-Fisher to first order: ``k + skew (k^2 - 1) / 6`` for noise of that skewness
    (never below ``k``: a negative estimate leaves it). Counting noise is skewed: on a dark
    8-bit frame a channel's pixels are 0 DN or, one in ten, 1 DN, and a 5-sigma threshold
    on their smoothed sums is passed by chance clusters of 1-DN pixels some 100 times as
    often as by Gaussian noise.
    """
    return k_sigma + max(skew, 0.0) * (k_sigma * k_sigma - 1.0) / 6.0


def _gaussian_kernel(sigma: float) -> np.ndarray:
    """The search's 1-D smoothing kernel of ``sigma`` px, (k,), ``k = 2 ceil(3 sigma) + 1``."""
    return cv2.getGaussianKernel(2 * math.ceil(3.0 * sigma) + 1, sigma).ravel()


def gaussian_norm(sigma: float) -> tuple[int, float]:
    """Size ``k`` of the smoothing kernel of ``sigma`` px and its 2-D L2 norm squared (the noise's gain)."""
    g = _gaussian_kernel(sigma)
    return g.size, float(np.sum(g**2))  # the 2-D kernel's L2 norm is the 1-D one's squared


def smoothed_skew_factor(sigma: float) -> float:
    """``sum w^3 / (sum w^2)^1.5`` of the 2-D Gaussian kernel of ``sigma`` px (separable).

    The skewness of white noise smoothed by the kernel is the pixels' skewness times this.
    """
    g = _gaussian_kernel(sigma)
    return float(np.sum(g**3) ** 2 / np.sum(g**2) ** 3)
