"""Point defects (hot pixels) told from optical spots by their shape and colour.

A hot photosite puts its excess into one pixel; demosaicing spreads it into the
neighbours of that pixel *in one channel only* (bilinear and OpenCV's edge-aware
demosaicing: a 3x3 footprint, nothing in the other two channels). An optical spot
is never narrower than the lens's point-spread function, sigma >= :data:`SIGMA_MIN_PX`
at the pixel pitch (the spot sigmas the detectors claim start there), and a beacon's
light reaches more than one channel. A candidate is a defect when, around its
peak pixel (of the channel sum) and above the local background,

* **shape**: its 8 neighbours hold less than half the light that the sharpest
  possible optical spot puts there relative to its peak pixel
  (:func:`min_neighbour_ratio`: a pixel-integrated Gaussian of sigma
  :data:`SIGMA_MIN_PX` centred on a pixel, the most concentrated case: 1.75 at
  0.6 px; a hot pixel's is 0), by :data:`SHARP_SIGMAS` of that difference's noise
  (a faint spot's peak pixel is a noise spike: no evidence of a defect); or
* **colour** (RGB frames): the two weaker channels hold clearly less light than any
  beacon's would beside the strongest one: each channel's light is measured in the 5x5
  around the peak as its least-squares slope on the strongest channel's profile (with
  an offset, so a level or gradient of the background does not count), and the share
  must lie :data:`COLOUR_SIGMAS` of its own noise below :data:`LEAST_SHARE` (a hot
  photosite under a bilinear or edge-aware demosaic: 0; the red bow of the default
  layout: at least 0.050; a white beacon: 0.54). A faint or broad spot's colour is too
  noisy to judge: it stays a spot.

The shape test sits half way between the two hypotheses' noise-free values. A demosaiced *red or blue* beacon of
sigma < ~1 px centred on its own photosite is, in its channel, a lone sample as a
hot pixel is: only its colour (light in the other channels) keeps it.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from deckpose.detect.background import MAD_TO_SIGMA, noise_floor_dn
from scipy.special import erf

__all__ = ["COLOUR_SIGMAS", "LEAST_SHARE", "SIGMA_MIN_PX", "min_neighbour_ratio", "point_defects"]

#: Narrowest optical spot the detectors claim, Gaussian sigma, pixels (a real lens's PSF at
#: the pixel pitch is sigma >= ~0.6-0.7 px; beacon spots 0.7-3 px).
SIGMA_MIN_PX = 0.6
#: The shape test calls a candidate sharp when its neighbours' deficit exceeds this many of
#: its noise sigmas.
SHARP_SIGMAS = 2.0
#: Colour test: the least share of the strongest channel's light that the two weaker channels
#: of a beacon hold, by its strongest channel (R, G, B), for the default layout's colours on a
#: bilinear- or edge-aware-demosaiced Bayer frame at sigma 0.6 px (the worst sub-pixel
#: position): red, the bow (1, 0.1, 0.05): 0.050 (0.15 in its light, 0.10 at 1 px); green or
#: blue, a ring beacon (1, 1, 0.9): 0.54 (1.9 in its light). A demosaiced hot pixel's is 0.
LEAST_SHARE = (0.050, 0.54, 0.54)
#: A candidate is one colour when its measured share lies this many of its own noise sigmas
#: below :data:`LEAST_SHARE`: a beacon is called a defect at most ~0.6 % of the time (one-sided
#: 2.5 sigma), in its worst case.
COLOUR_SIGMAS = 2.5
#: The colour test judges a candidate only where at least this share of its template's
#: variance (the strongest channel's 5x5 profile) is signal, not noise.
TEMPLATE_SIGNAL = 0.9
#: Half side of the window whose border gives the local background, pixels (a 9x9 window:
#: a sigma-0.6 px spot puts < 1e-8 of its peak there).
BACKGROUND_HALF_PX = 4


@functools.cache
def min_neighbour_ratio(sigma_px: float) -> float:
    """Smallest ``(light in the 8 neighbours) / (light in the peak pixel)`` of an optical spot.

    The spot is a Gaussian of ``sigma_px`` integrated over square pixels (erf), at every
    sub-pixel offset of a 21x21 grid over ``[0, 0.5]^2`` from its peak pixel's centre
    (the peak pixel is the one holding the centre); the minimum is at the centre.

    Parameters
    ----------
    sigma_px : float
        Gaussian sigma, pixels.

    Returns
    -------
    float
        Dimensionless (1.75 at 0.6 px, 2.40 at 0.7 px).
    """
    edges = np.array([-1.5, -0.5, 0.5, 1.5])
    best = math.inf
    for du in np.linspace(0.0, 0.5, 21):
        pu = np.diff(0.5 * (1.0 + erf((edges - du) / (sigma_px * math.sqrt(2.0)))))
        for dv in np.linspace(0.0, 0.5, 21):
            pv = np.diff(0.5 * (1.0 + erf((edges - dv) / (sigma_px * math.sqrt(2.0)))))
            block = np.outer(pv, pu)
            best = min(best, float((block.sum() - block[1, 1]) / block[1, 1]))
    return best


def _gather(image: np.ndarray, rows: np.ndarray, cols: np.ndarray, half: int) -> np.ndarray:
    """``(2 half + 1)``-square windows around each point, reflected at the frame edge.

    Returns (n, k, k) or (n, k, k, C) float64.
    """
    H, W = image.shape[:2]
    off = np.arange(-half, half + 1)

    def reflect(i: np.ndarray, n: int) -> np.ndarray:
        i = np.abs(i)
        return np.where(i > n - 1, 2 * (n - 1) - i, i).clip(0, n - 1)

    rr = reflect(rows[:, None] + off[None, :], H)
    cc = reflect(cols[:, None] + off[None, :], W)
    return np.asarray(image[rr[:, :, None], cc[:, None, :]], np.float64)


def point_defects(image: np.ndarray, centres_px: np.ndarray, search_px: int = 2, *,
                  sparse_counts: bool = False) -> np.ndarray:
    """Which candidates are point defects (hot pixels), by shape and colour.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        The frame, DN.
    centres_px : (n, 2) array of float
        Approximate ``(u, v)`` of each candidate, pixels.
    search_px : int
        The peak pixel (of the channel sum) is sought within this many pixels of each
        centre (a coarse search's block size).
    sparse_counts : bool
        The frame's background is sparse counts (a dark 8-bit frame whose noise does not
        dither the rounding, :func:`~deckpose.detect.search_noise.sparse_count_rate`). The
        tests' least noise is then the rounding's, ``sqrt(C / 12)`` DN, not a whole DN a
        channel (no noise at all there), and a candidate with at most one lit pixel in its
        3x3 is a defect: a lone hot pixel of 10 DN among zeros had passed as a spot. A spot
        of sigma >= 0.6 px mostly lights a neighbour too; a broad one of a few DN can round
        to one lit pixel and is then lost with the hot pixels (about 1 in 20 found beacons
        of 6 DN in all at sigma 1 px, 1 in 120 of 8 DN).

    Returns
    -------
    (n,) array of bool
        True for a defect.
    """
    c = np.asarray(centres_px, float).reshape(-1, 2)
    n = c.shape[0]
    if n == 0:
        return np.zeros(0, bool)
    H, W = image.shape[:2]
    rows = np.clip(np.rint(c[:, 1]).astype(np.intp), 0, H - 1)
    cols = np.clip(np.rint(c[:, 0]).astype(np.intp), 0, W - 1)
    # the channel-sum peak near each centre
    near = _gather(image, rows, cols, search_px)
    s_near = near.sum(axis=3) if near.ndim == 4 else near
    k = 2 * search_px + 1
    arg = s_near.reshape(n, -1).argmax(axis=1)
    rows = np.clip(rows + arg // k - search_px, 0, H - 1)
    cols = np.clip(cols + arg % k - search_px, 0, W - 1)
    h = BACKGROUND_HALF_PX
    win = _gather(image, rows, cols, h)  # (n, 9, 9[, C])
    if win.ndim == 3:
        win = win[..., None]
    border = np.concatenate([win[:, 0], win[:, -1], win[:, 1:-1, 0], win[:, 1:-1, -1]], axis=1)
    excess = win - np.median(border, axis=1)[:, None, None, :]  # (n, 9, 9, C), above background
    core = excess[:, h - 1 : h + 2, h - 1 : h + 2]  # the 3x3 around the peak
    s = core.sum(axis=3)
    peak = s[:, 1, 1]
    neighbours = s.sum(axis=(1, 2)) - peak
    # sharp: the neighbours fall short of half the sharpest spot's share by SHARP_SIGMAS of
    # that difference's noise (the channel sum's pixel noise, from the window border): a
    # faint spot's peak pixel is a noise spike, and its neighbours' deficit is noise too
    half = 0.5 * min_neighbour_ratio(SIGMA_MIN_PX)
    s_border = border.sum(axis=2)
    # at least the thresholds' noise floor (an integer image: 1 DN per channel): on a quantised
    # dark background most border pixels hold the same value, their MAD is 0, and every faint
    # beacon's noisy peak pixel looked sharp (an 8-bit frame of the independent generator lost
    # 3 beacons of 1,900-3,700 e that way)
    n_ch = excess.shape[3]
    floor_dn = math.sqrt(n_ch / 12.0) if sparse_counts else noise_floor_dn(image)
    sigma_s = np.maximum(
        MAD_TO_SIGMA * np.median(np.abs(s_border - np.median(s_border, axis=1, keepdims=True)), axis=1),
        floor_dn)
    sharp = (half * peak - neighbours) > SHARP_SIGMAS * sigma_s * math.sqrt(half**2 + 8.0)
    if sparse_counts:
        sharp |= np.count_nonzero(s > 0.5, axis=(1, 2)) <= 1
    if excess.shape[3] == 1:
        return sharp
    # colour: each channel's light measured with the strongest channel's own profile as the
    # template, over the 5x5 around the peak, with an offset (a least-squares slope of each
    # channel on the template): a level or a gradient left by the background estimate (an
    # edge of the deck through the window) does not count as light, and the noise is about
    # one pixel's, where a sum over the window would add every pixel's noise
    box = excess[:, h - 2 : h + 3, h - 2 : h + 3].reshape(n, 25, -1)  # (n, 25, C)
    strongest = box.sum(axis=1).argmax(axis=1)
    dev = box - box.mean(axis=1, keepdims=True)
    t = dev[np.arange(n), :, strongest]  # (n, 25)
    tt = np.einsum("nk,nk->n", t, t)
    amp = np.einsum("nk,nkc->nc", t, dev) / np.maximum(tt, 1e-300)[:, None]  # own channel: 1
    others = amp.sum(axis=1) - 1.0
    # ... and only where it lies clearly below the least share a beacon of that strongest
    # channel holds: COLOUR_SIGMAS of its own noise (the other channels' pixel noise, from the
    # window border, over the template's norm). A faint or broad spot's colour is too noisy
    # to judge: it stays a spot.
    mad = np.median(np.abs(border - np.median(border, axis=1, keepdims=True)), axis=1)  # (n, C)
    var_c = np.maximum((MAD_TO_SIGMA * mad) ** 2, floor_dn**2 / excess.shape[3])  # the floor per channel
    var_own = var_c[np.arange(n), strongest]
    var_others = var_c.sum(axis=1) - var_own
    # The template is itself noisy, which biases every slope toward 0 (toward "one colour")
    # by the share of noise in it, 24 var_own / tt: the slopes are corrected by it, and only
    # a template at least TEMPLATE_SIGNAL signal is judged (a faint or broad spot's flat,
    # noisy profile is not).
    # (a flat template, a clipped plateau's, has tt = 0: its signal is -inf, never judged)
    with np.errstate(over="ignore"):
        signal = 1.0 - 24.0 * var_own / np.maximum(tt, 1e-300)
        sigma_share = np.sqrt(var_others / np.maximum(tt, 1e-300)) / np.maximum(signal, 1e-12)
    others = others / np.maximum(signal, 1e-12)
    least = np.asarray(LEAST_SHARE)[strongest]
    one_colour = (signal >= TEMPLATE_SIGNAL) & (others + COLOUR_SIGMAS * sigma_share < least)
    return sharp | one_colour
