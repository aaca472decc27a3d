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
from scipy.optimize import minimize_scalar


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


#: A frame's background is sparse counts where at most this fraction of its neighbour pairs
#: differ (:func:`sparse_count_rate`).
SPARSE_MAX_FRACTION = 0.05
#: Pair differences larger than this (whole DN of the block sums) are a spot's or an edge's,
#: not the background's counts.
SPARSE_MAX_STEP = 3.0


def sparse_count_rate(d: np.ndarray) -> float | None:
    """Rate of chance counts per pixel of an exact-integer image whose background is sparse.

    A dark 8-bit frame whose noise does not dither the rounding is a flat level with rare
    single-DN counts above it (a 15 e background at 78 e a DN: one channel-pixel in some
    thousands). Its pixel noise is then no Gaussian's: the clipped difference noise reads 0
    and the counts' skew is beyond a Cornish-Fisher correction. Where at most
    :data:`SPARSE_MAX_FRACTION` of the image's horizontal neighbour pairs differ, the counts
    are modelled as Poisson with the rate ``mean(d^2) / 2`` of their differences ``d`` (pairs
    more than :data:`SPARSE_MAX_STEP` apart left out: a spot or an edge), at least ``3 / n``
    of the ``n`` pairs (none counted in ``n`` pairs would bound it at that, 95 %, were the
    pairs' blocks shared; they are not, so the floor is conservative by up to 2x).

    Parameters
    ----------
    d : (n,) array
        Differences of neighbouring pixels of the image (exact sums of whole DN, e.g. block
        sums of an 8-bit frame), DN.

    Returns
    -------
    float or None
        Counts (DN) per pixel of the image; ``None`` where its background is not sparse.
    """
    d = np.asarray(d, np.float64).ravel()
    d = d[np.isfinite(d)]
    if d.size < 100 or np.count_nonzero(d) > SPARSE_MAX_FRACTION * d.size:
        return None
    d = d[np.abs(d) <= SPARSE_MAX_STEP]
    return max(float(np.mean(d * d)) / 2.0, 3.0 / max(d.size, 1))


def count_threshold(rate: float, sigma: float, log_tail_probability: float) -> float:
    """Level of a Gaussian-smoothed image of Poisson counts passed with at most a given probability.

    The smoothed value is ``G = sum_j w_j X_j`` with the kernel's weights ``w_j``
    (:func:`gaussian_norm`'s kernel, 2-D) and independent counts ``X_j`` of mean ``rate``. By
    Chernoff's bound, ``P(G - E G >= T) <= exp(rate sum_j (e^(t w_j) - 1 - t w_j) - t T)`` for
    every ``t > 0``; the threshold returned is the smallest ``T`` whose bound, minimised over
    ``t``, is the tail probability (given as its logarithm: a 40-sigma Gaussian tail is
    below the smallest float). On dense counts it approaches the Gaussian threshold (about
    ``sqrt(2 ln(1/p))`` sigmas, a little above the quantile); on sparse ones it asks for the
    few counts together that chance does not give.

    Parameters
    ----------
    rate : float
        Mean count per pixel of the unsmoothed image, > 0.
    sigma : float
        The smoothing's sigma, pixels.
    log_tail_probability : float
        Natural logarithm of the tail probability, < 0.

    Returns
    -------
    float
        ``T``, above the smoothed image's mean, in its units.
    """
    g = _gaussian_kernel(sigma)
    w = np.outer(g, g).ravel()
    log_p = float(log_tail_probability)
    if not log_p < 0:
        raise ValueError(f"count_threshold: log_tail_probability must be < 0, got {log_p}")

    def level(t: float) -> float:
        return (rate * float(np.sum(np.expm1(t * w) - t * w)) - log_p) / t

    # T(t) is convex-like in t: bracket its minimum on a log scale, then refine
    ts = np.geomspace(1e-3, 200.0 / float(w.max()), 80)
    vals = np.array([level(float(t)) for t in ts])
    i = int(np.argmin(vals))
    lo, hi = ts[max(i - 1, 0)], ts[min(i + 1, ts.size - 1)]
    res = minimize_scalar(level, bounds=(float(lo), float(hi)), method="bounded", options={"xatol": 1e-6})
    return float(min(res.fun, vals[i]))


#: A lossy codec's block (JPEG's DCT and its chroma MCUs are multiples of it), px.
CODEC_BLOCK_PX = 8
#: Fewest differing pairs across block edges for the blocks to be judged at all.
CODEC_MIN_STEPS = 30
#: Block edges must differ at least this many times as often as the pairs at any one phase
#: inside the blocks. A raised block (one DCT term) differs from its neighbours at its two
#: edges in every row and at most once at each inner phase, so lone codec blocks give 2 (more
#: where some inner pairs stay equal: 1.9-5.3 on JPEGs of qualities 50-80); white noise 1; any
#: 2- or 4-pixel pattern (a Bayer mosaic's) also 1, as its pairs at the edges' phase
#: (``bk + 3 | bk + 4`` and ``bk + 7 | bk + 8`` are the same phase of it) differ as often.
CODEC_EDGE_RATIO = 1.6
#: Fewest distinct block edges (grid lines across the sampled direction) whose steps count:
#: a codec's raised blocks lie all over the frame, a panel lying on the grid has two edges.
CODEC_MIN_EDGES = 8
#: Where more than this fraction of the sampled pairs differ, the noise was not flattened (a
#: flattened frame's: under 5 %); the frame is not judged further.
CODEC_MAX_INNER_FRACTION = 0.25
#: A step this many times the median of the sampled steps is a spot's or an edge's, not the codec's.
CODEC_LARGE_STEP = 4.0


def codec_block_step(S: np.ndarray, factor: int, max_rows: int = 300) -> float:
    """The step between a lossy codec's blocks where they, not the noise, vary the frame (0 if not).

    A JPEG at moderate quality of a frame whose noise is a DN or two flattens each 8 x 8
    block to a few DCT terms: the noise is gone, and what is left are whole blocks raised by
    one quantum of their DC term (or one AC term's pattern), tens of pixels in step. Each is
    a compact bump that no per-pixel noise model explains (thousands of sigmas of the zero
    pixel noise a flattened frame shows), and the significance search took them for spots
    (24-160 on a 2 MP frame at qualities 50-80, and identification failed). The sign of
    such a frame: neighbours across a block's edge differ far more often than those at any
    one phase inside the blocks (:data:`CODEC_EDGE_RATIO`), along the rows and along the
    columns alike, which noise, a Bayer mosaic's or any 2- or 4-pixel pattern cannot make,
    nor a scene's edge that happens to lie on the grid (it lies along one axis). There, the
    median size of the edge steps is a step the codec makes out of nothing: a spot must
    stand out of it as out of noise.

    Judged on the search's image (channel sums in ``factor x factor`` blocks, whose grid
    the codec's 8 px blocks fit for ``factor`` 1, 2 and 4), one row in each row of blocks
    and one column in each column of blocks (all of them, so that even a few raised blocks
    in a frame are seen; at most ``max_rows`` of each, evenly spaced in whole blocks).

    Parameters
    ----------
    S : (h, w) array
        The search image, DN (channel sums of ``factor x factor`` blocks).
    factor : int
        Its block size, px.

    Returns
    -------
    float
        The median absolute step across the codec's block edges, in ``S``'s DN, where on
        both axes the edges differ at least :data:`CODEC_MIN_STEPS` times and
        :data:`CODEC_EDGE_RATIO` times as often as the pairs at any inner phase; else 0.
    """
    if factor < 1 or CODEC_BLOCK_PX % factor or CODEC_BLOCK_PX // factor < 2:
        return 0.0
    b = CODEC_BLOCK_PX // factor  # the codec's block in S's pixels
    across = _edge_steps(np.asarray(S), b, max_rows)  # pairs along the rows: columns' edges
    if across is None:
        return 0.0
    down = _edge_steps(np.asarray(S).T, b, max_rows)  # and along the columns: rows' edges
    if down is None:  # (a vertical step edge in a clean frame shows on one axis only)
        return 0.0
    return median(np.concatenate([across, down]))


def _edge_steps(S: np.ndarray, b: int, max_rows: int) -> np.ndarray | None:
    """The absolute steps across the block edges of ``b`` px along ``S``'s rows, where those
    edges stand out as a codec's do (:func:`codec_block_step`); else None."""
    h, w = S.shape
    n_blocks = (w - 1) // b  # blocks with a right neighbour
    block_rows = h // b
    if n_blocks < 1 or block_rows < 1:
        return None
    every = -(-block_rows // max_rows)  # whole block rows between two sampled rows
    rows = np.arange(block_rows)[::every] * b + b // 2
    d = np.diff(S[rows, : b * n_blocks + 1], axis=1).ravel()  # pair (bk+p, bk+p+1) at p = index % b
    lit = d != 0
    if np.count_nonzero(lit) > CODEC_MAX_INNER_FRACTION * d.size:
        return None  # the noise differs inside the blocks: the codec did not flatten it
    at = np.flatnonzero(lit)
    if at.size < CODEC_MIN_STEPS:
        return None
    step = np.abs(d[at])
    block = at // b
    # blocks a spot or an edge crosses (a step far above the typical one) are left out: their
    # gradients differ at every phase and would hide the codec's pattern
    calm = ~np.isin(block, block[step > CODEC_LARGE_STEP * median(step)])
    differing = np.bincount(at[calm] % b, minlength=b)  # (b,) differing pairs at each phase
    n_edge = int(differing[b - 1])
    if n_edge < CODEC_MIN_STEPS or n_edge < CODEC_EDGE_RATIO * max(int(differing[: b - 1].max()), 1):
        return None
    on_edge = calm & (at % b == b - 1)
    # scattered over the frame, as a codec's blocks are: not the few edges of one panel or band
    # lying on the grid
    if np.unique(block[on_edge] % n_blocks).size < CODEC_MIN_EDGES:
        return None
    return step[on_edge]
