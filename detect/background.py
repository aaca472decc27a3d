"""Per-frame background level, noise and saturation: the numbers every threshold adapts to.

All statistics are robust (median, MAD) and computed on a strided subsample of
the frame, so a few bright beacons do not move them and a 64 MP frame costs a
few milliseconds. Colour frames are measured on the sum of their channels, the
mono signal the detectors work on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Noise floor, DN: integer images hold at least quantisation noise (1/sqrt(12) DN).
MIN_NOISE_DN = 1.0 / math.sqrt(12.0)
#: Scale from median absolute deviation to standard deviation for Gaussian noise.
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class FrameStats:
    """Robust statistics of one frame (mono = sum of channels).

    Attributes
    ----------
    background_dn : float
        Median pixel value, DN.
    noise_dn : float
        Robust noise standard deviation (:func:`difference_noise`), at least
        :func:`noise_floor_dn`, DN.
    saturation_dn : float
        Value at which a single channel saturates (dtype maximum), DN.
    saturated_fraction : float
        Fraction of sampled pixels with a channel at ``saturation_dn``.
    max_dn : float
        Brightest sampled mono value, DN.
    """

    background_dn: float
    noise_dn: float
    saturation_dn: float
    saturated_fraction: float
    max_dn: float


def noise_floor_dn(image: np.ndarray) -> float:
    """Smallest noise the thresholds assume, DN of the mono (channel-sum) signal.

    Integer images: 1 DN per channel. Noise-free renders and heavily quantised
    dark backgrounds would otherwise put the threshold a single quantum above
    the background, where antialiasing and dither make false blobs.
    """
    if not np.issubdtype(image.dtype, np.integer):
        return MIN_NOISE_DN
    return math.sqrt(image.shape[2] if image.ndim == 3 else 1)


def saturation_level(image: np.ndarray) -> float:
    """The dtype maximum of an integer image (inf for float images)."""
    if np.issubdtype(image.dtype, np.integer):
        return float(np.iinfo(image.dtype).max)
    return math.inf


def mono(pixels: np.ndarray) -> np.ndarray:
    """Float64 mono signal of an (h, w) or (h, w, 3) block: the sum of its channels."""
    a = np.asarray(pixels)
    if a.ndim == 3 and a.shape[2] == 3:
        # the channels added in order, as a.sum(axis=2) adds three (a reduction over the
        # short last axis costs several times more)
        return a[..., 0].astype(np.float64) + a[..., 1] + a[..., 2]
    if a.ndim == 3:
        return a.sum(axis=2, dtype=np.float64)
    return a.astype(np.float64)


#: Shortest rows that :func:`row_median` counts rather than sorts (below it a sort is as fast).
COUNTED_MEDIAN_MIN = 4096


def row_median(a: np.ndarray) -> np.ndarray:
    """Median of each row of a finite (n, m) array, (n,): ``np.median(a, axis=1)``, exactly.

    By a sort of the rows (the mean of the two middle values for even ``m``, as
    ``np.median`` takes it): for short rows 5-10x faster than ``np.median``'s partition
    (and a 1-D median of a few hundred values, ``row_median(a[None])[0]``, 5x). Long
    float rows of whole or half DN (a frame's pixel differences, block sums and their
    deviations from a median) are counted instead (:func:`_counted_row_median`), the
    same values in 0.2-0.6 ms where a sort of 60,000 takes 1.2 ms.
    """
    m = a.shape[1]
    if m >= COUNTED_MEDIAN_MIN and a.dtype == np.float64:
        counted = _counted_row_median(a)
        if counted is not None:
            return counted
    s = np.sort(a, axis=1)
    if m % 2:
        return s[:, m // 2]
    return (s[:, m // 2 - 1] + s[:, m // 2]) / 2


def _counted_row_median(a: np.ndarray) -> np.ndarray | None:
    """:func:`row_median` of float64 rows whose values are all multiples of 1/2 within a
    range of a few times the row length, by counting them (``np.bincount``); else None.

    Twice a value is then an exact integer (checked on the values themselves, each of
    magnitude below 2^50, so that doubling and the differences below are exact), the two
    middle ranks' values are read off the cumulative counts exactly, and their mean is the
    sort's. Besides the counts (``n x (8 m + 1)`` at most), two temporaries of the rows'
    size are made: each new one costs its page faults.
    """
    n, m = a.shape
    if n == 0:
        return None
    lo, hi = a.min(axis=1), a.max(axis=1)
    if not (max(-lo.min(), hi.max()) < 2.0**50 and 2.0 * (hi - lo).max() <= 8 * m):  # (NaN fails it)
        return None
    doubled = a * 2.0  # exact: a power of two
    idx = doubled.astype(np.int64)  # exact where doubled is whole (below 2^51)
    doubled -= idx
    if doubled.any():  # a value not a multiple of 1/2
        return None
    lo = 2.0 * lo  # whole now, as every doubled value
    idx -= lo.astype(np.int64)[:, None]
    bins = int((2.0 * hi - lo).max()) + 1
    if n > 1:
        idx += (np.arange(n) * bins)[:, None]
    counts = np.bincount(idx.ravel(), minlength=n * bins)
    below = np.cumsum(counts.reshape(n, bins), axis=1)
    # the value of 0-based rank r is the first bin whose cumulative count exceeds r
    upper = ((below <= m // 2).sum(axis=1) + lo) / 2.0
    if m % 2:
        return upper
    lower = ((below <= m // 2 - 1).sum(axis=1) + lo) / 2.0
    return (lower + upper) / 2


def median(values: np.ndarray) -> float:
    """``float(np.median(values))``, exactly, by a sort where every value is finite.

    ``np.median`` partitions, which is slow where many values tie (a frame's integer
    DN and its block sums: 30,000-80,000 samples of a few hundred distinct values take
    4-5x a sort); a NaN or an empty array is left to ``np.median``.

    Parameters
    ----------
    values : array
        Any shape; flattened.
    """
    v = np.asarray(values).ravel()
    if v.size == 0 or (v.dtype.kind == "f" and not np.isfinite(v).all()):
        return float(np.median(v))
    if v.dtype.kind != "f":  # the mean of the two middle values in float64, as np.median's
        v = v.astype(np.float64)
    return float(row_median(v[None])[0])


def percentile(values: np.ndarray, q: float) -> float:
    """``float(np.percentile(values, q))`` of the values as float64 (its linear method), exactly, by one partition.

    ``np.percentile``'s own overhead is most of its time on the few hundred values of a
    spot's surroundings; this takes its steps (the virtual index ``(n - 1) q / 100``, the
    two values around it, numpy's two-sided interpolation) without it. A NaN or an empty
    array is left to ``np.percentile``.

    Parameters
    ----------
    values : array
        Any shape; flattened.
    q : float
        Percentile, 0-100.
    """
    if not 0.0 <= q <= 100.0:
        raise ValueError(f"percentile: q must be within [0, 100], got {q}")
    v = np.asarray(values, np.float64).ravel()
    if v.size == 0 or not np.isfinite(v).all():
        return float(np.percentile(v, q))
    at = (v.size - 1) * (q / 100.0)
    lo = math.floor(at)
    hi = min(lo + 1, v.size - 1)
    part = np.partition(v, (lo, hi))
    a, b = part[lo], part[hi]
    t = at - lo
    d = b - a
    # numpy's _lerp: from the nearer end, so that t = 1 gives b exactly
    return float(b - d * (1 - t)) if t >= 0.5 else float(a + d * t)


def clipped_mean(values: np.ndarray, k_sigma: float = 3.0, passes: int = 3) -> np.ndarray:
    """Mean of each column of ``values`` within ``k_sigma`` standard deviations, (m,).

    ``values`` is (n, m) (or (n,), giving one value). Three passes drop a neighbouring
    spot's light. A mean, not a median: on a quantised frame whose background is a DN or
    two, the median is a whole DN, up to half a DN off the level (summed over a
    spot's aperture, a bias of many DN).
    """
    x = np.asarray(values, dtype=np.float64)
    # column-major work, (m, n): numpy's inner loops run along a row, and a row of three
    # channels made every operation here 10-40x slower than on a contiguous column
    xt = np.ascontiguousarray(x.reshape(x.shape[0], -1).T)
    keep = np.ones(xt.shape, bool)
    m = xt.mean(axis=1)
    for _ in range(passes):
        n = keep.sum(axis=1)
        if (n < 3).any():
            break
        m = np.where(keep, xt, 0.0).sum(axis=1) / n
        dev = xt - m[:, None]
        sd = np.sqrt(np.where(keep, dev * dev, 0.0).sum(axis=1) / n)
        keep = np.abs(dev) <= k_sigma * sd[:, None] + 1e-12
    return m if x.ndim > 1 else m.reshape(())


def clipped_std_rows(d: np.ndarray, sd0: np.ndarray | None = None, *, clip: float = 4.0,
                     passes: int = 3, min_kept: int = 10) -> np.ndarray:
    """Each row's standard deviation within ``clip`` sigma of its centre, (n,).

    Starts from the row's median and a first sigma, then ``passes`` times keeps the
    values within ``clip`` of the current sigma of the current centre and takes their
    mean and standard deviation; a row that would keep fewer than ``min_kept`` values
    keeps its previous figures. The first sigma is ``sd0`` when given, else ``1.4826 MAD``
    (the standard deviation where the MAD is 0). A median absolute deviation alone is
    quantised with the data: on an 8-bit frame it overstated the noise by 40 %; the
    clipped standard deviation keeps the quantisation's true variance and drops spots and
    edges (beyond ``clip`` sigma).

    Parameters
    ----------
    d : (n, m) array of float
        Finite values (pixel differences), one sample per row.
    sd0 : (n,) array of float, optional
        First sigma of each row.
    """
    d = np.asarray(d, np.float64)
    med = row_median(d)
    if sd0 is not None:
        sd = np.asarray(sd0, np.float64).copy()
    else:
        sd = MAD_TO_SIGMA * row_median(np.abs(d - med[:, None]))
        flat = ~(sd > 0)
        if flat.any():
            sd[flat] = d[flat].std(axis=1)
    for _ in range(passes):
        keep = np.abs(d - med[:, None]) < clip * np.maximum(sd, 1e-12)[:, None]
        n = keep.sum(axis=1)
        ok = n >= min_kept
        if not ok.any():
            break
        nn = np.maximum(n, 1)
        mean = np.where(keep, d, 0.0).sum(axis=1) / nn
        var = np.where(keep, (d - mean[:, None]) ** 2, 0.0).sum(axis=1) / nn
        med = np.where(ok, mean, med)
        sd = np.where(ok, np.sqrt(var), sd)
    return sd


def robust_stats(values: np.ndarray) -> tuple[float, float]:
    """Median and MAD-based standard deviation (floored at :data:`MIN_NOISE_DN`)."""
    v = np.asarray(values, dtype=np.float64).ravel()
    med = median(v)
    sigma = MAD_TO_SIGMA * median(np.abs(v - med))
    if sigma < MIN_NOISE_DN:
        # Heavily quantised noise: the MAD can be 0; fall back to the standard deviation
        # of the central 80 % of the distribution.
        lo, hi = np.percentile(v, [10, 90])
        core = v[(v >= lo) & (v <= hi)]
        sigma = max(float(core.std()) if core.size else 0.0, MIN_NOISE_DN)
    return med, sigma


def difference_noise(
    image: np.ndarray,
    *,
    samples: int = 30_000,
    signal: Callable[[np.ndarray], np.ndarray] | None = None,
) -> float:
    """Noise standard deviation from differences of horizontally adjacent pixels, DN.

    Smooth background structure (a lit deck, vignetting) cancels in the
    differences, so unlike the spread of pixel values this measures the noise
    alone: ``sigma = 1.4826 * MAD(d) / sqrt(2)`` over strided pixel pairs.
    ``signal`` turns sampled pixels into the signal measured (default :func:`mono`,
    the channel sum); only the samples are converted, never the whole frame.
    """
    _, s = robust_stats(neighbour_differences(image, samples=samples, signal=signal))
    return max(s / math.sqrt(2.0), MIN_NOISE_DN)


def neighbour_differences(
    image: np.ndarray,
    *,
    samples: int = 30_000,
    signal: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Differences of about ``samples`` strided pairs of horizontally adjacent pixels, DN, (n,).

    ``signal`` turns sampled pixels into the signal measured (default :func:`mono`, the
    channel sum); only the samples are converted, never the whole frame.
    """
    to_signal = mono if signal is None else signal
    H, W = image.shape[:2]
    step = max(1, int(math.sqrt(H * W / samples)))
    a = np.asarray(to_signal(image[::step, 0 : W - 1 : step]), np.float64)
    b = np.asarray(to_signal(image[::step, 1::step]), np.float64)
    n = min(a.shape[1], b.shape[1])
    return (b[:, :n] - a[:, :n]).ravel()


def channel_sum_noise(image: np.ndarray, *, samples: int = 30_000) -> float:
    """The noise of the channel sum as it is, unfloored: for covariances, not thresholds, DN.

    A 4-sigma-clipped standard deviation (:func:`clipped_std_rows`) of the channel sums'
    :func:`neighbour_differences`, over ``sqrt 2``. Unlike
    :func:`difference_noise` (a MAD, quantised with the data) it keeps a quantised frame's
    true variance, and unlike the thresholds' noise it is not floored at 1 DN a channel: an
    8-bit frame whose noise is mostly its rounding reads about ``sqrt(C / 12)`` DN, and that is
    its floor on an integer frame (no stored integer frame is without the rounding's variance).
    """
    d = neighbour_differences(image, samples=samples)
    d = d[np.isfinite(d)]
    n_ch = image.shape[2] if image.ndim == 3 else 1
    floor = math.sqrt(n_ch / 12.0) if np.issubdtype(image.dtype, np.integer) else MIN_NOISE_DN
    if d.size < 10:
        return floor
    return max(float(clipped_std_rows(d[None])[0]) / math.sqrt(2.0), floor)


def frame_stats(
    image: np.ndarray, *, samples: int = 30_000, difference_noise_dn: float | None = None
) -> FrameStats:
    """Background, noise and saturation of a frame from a strided subsample.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
    samples : int
        About how many pixels to sample.
    difference_noise_dn : float, optional
        ``difference_noise(image, samples=samples)`` when the caller has it already, DN.

    Returns
    -------
    FrameStats
    """
    H, W = image.shape[:2]
    step = max(1, int(math.sqrt(H * W / samples)))
    sub = image[::step, ::step]
    sat = saturation_level(image)
    m = mono(sub)
    saturated = (sub >= sat).any(axis=2) if sub.ndim == 3 else sub >= sat
    bg, _ = robust_stats(m)
    if difference_noise_dn is None:
        difference_noise_dn = difference_noise(image, samples=samples)
    noise = max(difference_noise_dn, noise_floor_dn(image))
    return FrameStats(bg, noise, sat, float(saturated.mean()), float(m.max()))


def frame_problem(stats: FrameStats, *, max_saturated_fraction: float = 0.25) -> str:
    """Why a frame cannot be measured at all ("" when it can)."""
    if stats.saturated_fraction > max_saturated_fraction:
        return (
            f"saturated frame: {100 * stats.saturated_fraction:.0f}% of pixels at the maximum "
            f"value {stats.saturation_dn:g} DN; reduce exposure or gain"
        )
    return ""


def tile_stats(image: np.ndarray, tile: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Local background level and noise maps of a mono image, from ``tile x tile`` tiles.

    Level: per-tile median; noise: per-tile :func:`difference_noise` estimate
    (MAD of horizontal differences). Both maps have the image's shape (constant
    per tile). For frames whose noise varies with the background (shot noise of
    a lit deck).
    """
    img = np.asarray(image, dtype=np.float32)
    h, w = img.shape
    th, tw = -(-h // tile), -(-w // tile)
    pad = np.full((th * tile, tw * tile + 1), np.nan, np.float32)
    pad[:h, :w] = img
    tiles = pad[:, :-1].reshape(th, tile, tw, tile).transpose(0, 2, 1, 3).reshape(th, tw, -1)
    diffs = (
        np.diff(pad, axis=1).reshape(th, tile, tw, tile).transpose(0, 2, 1, 3).reshape(th, tw, -1)
    )
    level = np.nanmedian(tiles, axis=2)
    dmed = np.nanmedian(diffs, axis=2)
    noise = MAD_TO_SIGMA * np.nanmedian(np.abs(diffs - dmed[..., None]), axis=2) / math.sqrt(2.0)
    noise = np.maximum(np.nan_to_num(noise, nan=MIN_NOISE_DN), MIN_NOISE_DN)
    up = np.ones((tile, tile), np.float32)
    return np.kron(level, up)[:h, :w], np.kron(noise, up)[:h, :w]


def border_noise(pixels: np.ndarray) -> float:
    """Noise of a window from differences along its outer two-pixel frame, DN."""
    p = np.asarray(pixels, dtype=np.float64)
    if min(p.shape) < 6:
        return MIN_NOISE_DN
    d = np.concatenate(
        [
            np.diff(p[:2], axis=1).ravel(),
            np.diff(p[-2:], axis=1).ravel(),
            np.diff(p[:, :2], axis=0).ravel(),
            np.diff(p[:, -2:], axis=0).ravel(),
        ]
    )
    med = median(d)
    return max(MAD_TO_SIGMA * median(np.abs(d - med)) / math.sqrt(2.0), MIN_NOISE_DN)
