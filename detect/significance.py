"""Significance search: every compact spot that stands out of its own surroundings.

The bright-spot search (:mod:`deckpose.detect.spots`) keeps the spots near the
frame's brightest level, which drops a beacon much dimmer than the brightest
one (LED tolerance, viewing angle, a red bow on a mono sensor). This search
finds spots by their significance instead, whatever their brightness:

1. The channel-sum image is block-summed by a power of two ``f`` (so that at most
   :data:`SEARCH_MAX_PX` pixels remain; OpenCV area resampling, which keeps every
   photon) and smoothed with a small Gaussian: together, close to a matched filter
   for a spot of 1.5-3 px sigma. Its noise ``sigma_G`` follows from the block sums'
   pixel-difference noise and the Gaussian's norm. On a dark 8-bit frame whose
   background is sparse single-DN counts (the noise does not dither the rounding),
   ``sigma_G`` is instead the noise whose ``significance_sigma`` multiple is the
   counts' own threshold at the same tail probability
   (:func:`~deckpose.detect.search_noise.count_threshold`).
2. Candidates are local maxima of the smoothed image at least ``significance_sigma``
   of its noise above the frame's background.
3. Each candidate is tested against its own surroundings: on rings of
   :data:`RING_RADII` coarse pixels, the *highest* of :data:`RING_SAMPLES` samples is
   its pedestal, and the candidate must exceed that pedestal by ``significance_sigma``
   local noise sigmas on at least one ring (the local noise is the larger of
   ``sigma_G`` and the robust spread of the ring's samples, so deck texture counts as
   noise). A line or an edge through the candidate raises the pedestal to its own
   level, so markings, the deck's edge and glare gradients are not spots; a spot on
   a line still stands above it. A short bar passes a ring wider than it, so the
   ring inside that one must be round too (:data:`MAX_RING_ASYMMETRY`).

Point defects (hot pixels, :mod:`deckpose.detect.defects`) pass these tests too (a
demosaiced one is a compact bump); they are dropped by their shape and colour before
the spots are counted. The result is a full-resolution centre per spot and the radius
of the ring it passed on.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.background import MIN_NOISE_DN, median, neighbour_differences, row_median
from deckpose.detect.block_sums import block_pair_differences, block_sum
from deckpose.detect.defects import point_defects
from deckpose.detect.search_noise import (
    SPARSE_MAX_FRACTION,
    clipped_difference_noise,
    codec_block_step,
    count_threshold,
    gaussian_norm,
    noise_skewness,
    skew_threshold,
    smoothed_skew_factor,
    sparse_count_rate,
)
from deckpose.detect.tile_texture import TileTextures
from scipy.special import log_ndtr

#: The coarse image has at most this many pixels (block size a power of two).
SEARCH_MAX_PX = 4_200_000
#: Radii (coarse pixels) of the rings a candidate is compared with.
RING_RADII = (2.0, 3.5, 6.0, 10.0, 16.0)
#: Fewest samples per ring; larger rings have one every :data:`RING_SPACING_PX` coarse
#: pixels, so a thin line crossing the ring cannot slip between two samples.
RING_SAMPLES = 16
RING_SPACING_PX = 1.5
#: Smoothings of the coarse image, full-resolution pixels (Gaussian sigma): each, with the
#: block sums, a matched filter for spots of about its size; the n-th starts at the n-th
#: ring. A second of 3 px raised the recall of sigma-3 px spots at integrated SNR 10 from
#: 0.74 to 0.97, but it also found broad sea-texture bumps on rendered frames (9 of 78
#: frames instead of 3) and cost 50 % more: one smoothing, for now.
SMOOTH_PX: tuple[float, ...] = (1.5,)
#: A spot is round: on the ring inside the one it passed on, the highest sample rises
#: at most this fraction of the way from the ring's median to the centre's level.
MAX_RING_ASYMMETRY = 0.5
#: The whole-image prefilter asks this fraction of the ring test's threshold.
PREFILTER_FRACTION = 0.8
#: Samples per ring (about) of the ring test's first, cheap pass.
PASS0_SAMPLES = 8
#: On a frame whose fluctuations are a lossy codec's block steps
#: (:func:`~deckpose.detect.search_noise.codec_block_step`), a spot rises at least this many
#: steps above its surroundings: one raised block rises one, two coinciding quanta two.
CODEC_STEPS = 2.0
#: More local maxima above the prefilter than this fail the frame (a flat noise field).
MAX_PEAKS = 200_000


def search_factor(shape: tuple[int, int]) -> int:
    """Power-of-two block size that brings ``H * W`` to at most :data:`SEARCH_MAX_PX`."""
    f = 1
    while shape[0] * shape[1] / (f * f) > SEARCH_MAX_PX:
        f *= 2
    return f


def box_means(G: np.ndarray, ys: np.ndarray, xs: np.ndarray, half: int) -> np.ndarray:
    """Mean of ``G`` over the ``(2 half + 1)``-square box around each point, (n,).

    A box that would cross the frame's edge is shifted inside it. For a few points
    the boxes are summed directly; for many, from the integral image (whose 8-byte
    copy of the frame costs more than a thousand boxes).
    """
    h, w = G.shape
    k = 2 * half + 1
    if k > h or k > w:
        return np.full(ys.size, float(np.mean(G)))
    y0 = np.clip(ys - half, 0, h - k)
    x0 = np.clip(xs - half, 0, w - k)
    if ys.size <= 1000:
        win = np.lib.stride_tricks.sliding_window_view(G, (k, k))[y0, x0]
        return win.sum(axis=(1, 2), dtype=np.float64) / (k * k)
    integ = cv2.integral(G, sdepth=cv2.CV_64F)
    # corners by flat index (one take each; a 2-D fancy index costs 2-3x more)
    flat, wi = integ.ravel(), integ.shape[1]
    a, b = y0 * wi + x0, (y0 + k) * wi + x0
    return (flat.take(b + k) - flat.take(a + k) - flat.take(b) + flat.take(a)) / (k * k)


def significant_spots(
    image: np.ndarray, significance_sigma: float, max_spots: int, *, screen: bool = True
) -> tuple[np.ndarray, np.ndarray, str, str]:
    """Centres and sizes of the frame's significant compact spots.

    Point defects (hot pixels, :func:`deckpose.detect.defects.point_defects`) are no
    spots: they are dropped before the count. When more than ``max_spots`` spots remain
    (a lit sea, glare), the ``max_spots`` most significant are kept (their smoothed
    peaks above the background, in the frame's noise) and the note says so; whether the
    beacons are among them is for identification to decide.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
    significance_sigma : float
        Threshold, in local noise sigmas of the smoothed coarse image.
    max_spots : int
        At most this many spots are returned.
    screen : bool
        Narrow the peaks by the cheap necessary conditions first (:func:`_ring_screen`).
        ``False`` runs every ring's full test on every local maximum: the same spots
        (the screen is a bound), slowly on a lit sea; the reference the screen is
        tested against.

    Returns
    -------
    centres_px : (n, 2) array of float
        Approximate full-resolution ``(u, v)`` of each spot (its coarse pixel's centre),
        most significant first.
    radius_px : (n,) array of float
        Full-resolution radius of the ring the spot passed on (its size, roughly).
    reason : str
        Why the frame failed (more than :data:`MAX_PEAKS` local maxima); "" when it did not.
    note : str
        That spots were left out (more than ``max_spots``); "" otherwise.
    """
    f = search_factor(image.shape[:2])
    S, noise_S, sparse_rate = _search_image(image, f)
    # a lossy codec's block steps (JPEG's 8-bit frames), where they are the frame's fluctuations:
    # a spot must rise CODEC_STEPS such steps above its surroundings (a block raised by one
    # quantum rises one step, which the smoothing barely lowers: it covers whole coarse
    # pixels); 0 elsewhere (codec_block_step)
    codec_G = CODEC_STEPS * codec_block_step(S, f) if image.dtype.type is np.uint8 else 0.0
    skew_S = noise_skewness(S, noise_S) if sparse_rate is None else 0.0
    pts_all: list[np.ndarray] = []
    rad_all: list[float] = []
    val_all: list[float] = []
    for n_scale, smooth_px in enumerate(SMOOTH_PX):
        sigma_c = max(0.5, smooth_px / f)
        k_sigma = skew_threshold(significance_sigma, skew_S * smoothed_skew_factor(sigma_c))
        noise_scale = noise_S
        if sparse_rate is not None:
            # the noise for which k_sigma of it, smoothed, is the counts' threshold (above
            # their mean, which the background median is at most below)
            log_tail = float(log_ndtr(-significance_sigma))
            level = count_threshold(sparse_rate, sigma_c, log_tail) + sparse_rate
            noise_scale = level / (k_sigma * gaussian_norm(sigma_c)[1])
        if codec_G > 0:  # the threshold, k_sigma of the smoothed noise, at least codec_G
            noise_scale = max(noise_scale, codec_G / (k_sigma * gaussian_norm(sigma_c)[1]))
        found = _spots_at_scale(S, sigma_c, noise_scale, k_sigma, RING_RADII[n_scale:], screen=screen)
        if isinstance(found, str):
            return np.zeros((0, 2)), np.zeros(0), found, ""
        pts, rad, val = found
        # a spot the finer smoothing found is not found again (within `near` on both axes)
        near = max(2.0, 0.5 * min(RING_RADII[n_scale:]))
        if pts_all:
            prev = np.array(pts_all, float)
            close = ((np.abs(pts[:, None, 0] - prev[None, :, 0]) <= near)
                     & (np.abs(pts[:, None, 1] - prev[None, :, 1]) <= near)).any(axis=1)
            pts, rad, val = pts[~close], rad[~close], val[~close]
        pts_all.extend(pts)
        rad_all.extend(rad.tolist())
        val_all.extend(val.tolist())
    if not pts_all:
        return np.zeros((0, 2)), np.zeros(0), "", ""
    centres = (np.array(pts_all, float) + 0.5) * f - 0.5
    radii = np.array(rad_all, float) * f
    order = np.argsort(-np.array(val_all), kind="stable")
    centres, radii = centres[order], radii[order]
    real = ~point_defects(image, centres, search_px=f + 1, sparse_counts=sparse_rate is not None)
    n_defects = int(np.count_nonzero(~real))
    centres, radii = centres[real], radii[real]
    note = ""
    if centres.shape[0] > max_spots:
        note = (f"{centres.shape[0]} significant spots (besides {n_defects} hot pixels), more than "
                f"max_blobs={max_spots}: kept the {max_spots} most significant (glare, noise or "
                "texture?)")
        centres, radii = centres[:max_spots], radii[:max_spots]
    return centres, radii, "", note


def _search_image(image: np.ndarray, f: int) -> tuple[np.ndarray, float, float | None]:
    """The search's coarse image (channel sums in ``f x f`` blocks) and its pixel noise.

    Returns the block sums, their noise (floored as below) and, on an 8-bit frame of
    sparse counts, the counts' rate per block (:func:`~deckpose.detect.search_noise.sparse_count_rate`;
    ``None`` elsewhere), for which the threshold is the counts' own.
    """
    S = block_sum(image, f, exact=False)
    # On an integer image the noise is never below the rounding's (1/12 DN^2 a channel and
    # pixel). It was floored at 1 DN a channel (3.5x a dark 8-bit frame's 0.3 DN), because
    # the few pixels at 1 DN of a background of a fraction of a DN are counts, not Gaussian
    # noise, and chance clusters of them counted as spots (over 200 on 8-bit RGB with a 0.6 DN
    # background). Two faults made them: block means rounded to whole DN (block_sum now
    # sums exactly) and a threshold blind to the counts' skew (skew_threshold now keeps the
    # Gaussian tail probability). The floor had cost the dimmest beacons of such frames
    # (1,600 e among 30,000 e beacons: 6 of 156, benchmarks/bench_independent.py rgb8_dark).
    n_ch = image.shape[2] if image.ndim == 3 else 1
    noise_S = clipped_difference_noise(S)
    sparse_rate: float | None = None
    if np.issubdtype(image.dtype, np.integer):
        # Noise at least the rounding's dithers it, and the rounding's variance is the floor;
        # below that the rounding is not noise but the scene's own steps (a night sea's flat
        # patches one DN apart, tests/detect/test_significance_steps.py), and the smallest
        # step that counts is a whole DN a channel. Where the noise dithers the rounding, an
        # 8-bit frame's block means rounded to whole DN lose a faint spot's light: its block
        # sums are taken again, exactly (judged on the rounded sums, whose noise is larger).
        rounding = f * math.sqrt(n_ch / 12.0)
        dithered = noise_S >= rounding
        if dithered and image.dtype.type is np.uint8 and f > 1:
            S = block_sum(image, f)
            noise_S = clipped_difference_noise(S)
        elif not dithered and image.dtype.type is np.uint8:
            # A darker frame still (a 15 e background at 78 e a DN): the level is flat and the
            # noise is rare single-DN counts, whose light the rounded block means drop. Where
            # the exact sums' background is such sparse counts, the threshold is the counts'
            # own (count_threshold); the whole-DN floor below asked a dim beacon for some 20
            # DN at its centre where 2-3 are beyond chance (recall 0.31-0.94 on the
            # independent generator's frames 2-4x darker than rgb8_dark). Sparseness is
            # judged on sampled block pairs, summed exactly (the whole frame's exact sums, a
            # 16-bit copy of it, only where it is sparse), and not even those where more than
            # the sparse fraction of the frame's own pixel pairs differ: a block holds f^2
            # pixels' counts, so its pairs differ more often still.
            px = neighbour_differences(image, samples=30_000)
            if np.count_nonzero(px) <= SPARSE_MAX_FRACTION * px.size:
                sparse_rate = sparse_count_rate(block_pair_differences(image, f))
            if sparse_rate is not None and f > 1:
                S = block_sum(image, f)
        noise_S = max(noise_S, rounding if dithered else f * math.sqrt(n_ch))
    else:
        noise_S = max(noise_S, MIN_NOISE_DN)
    return S, noise_S, sparse_rate


def _spots_at_scale(
    S: np.ndarray, sigma_c: float, noise_S: float, significance_sigma: float,
    radii: tuple[float, ...], *, screen: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | str:
    """The significant spots of block sums ``S`` smoothed by a Gaussian of ``sigma_c`` px.

    Returns coarse ``(x, y)`` per spot (n, 2), the radius of the ring it passed on (n,)
    and its height above the frame's background in ``sigma_G`` (n,), brightest first; or
    why the frame fails.
    """
    k, norm = gaussian_norm(sigma_c)
    G = cv2.GaussianBlur(S, (k, k), sigma_c, borderType=cv2.BORDER_REFLECT)
    sigma_G = noise_S * norm
    h, w = G.shape
    step = max(1, int(math.sqrt(h * w / 30_000)))
    bg = median(G[::step, ::step])
    ys, xs = _local_maxima(G, bg + significance_sigma * sigma_G)
    # A spot is a local maximum above the frame's background that passes (a) the prefilter:
    # above the local mean of a box as wide as the largest ring by PREFILTER_FRACTION of the
    # threshold in the frame's noise, then in its tile's small-scale texture noise; and (b)
    # the ring test on some ring k: it stands significance_sigma above the ring's highest
    # sample in the largest of three noises (the pixel noise sigma_G, the spread of the
    # ring's samples, the tile's texture at the ring's scale) and the ring inside (k - 1) is
    # round. Every test is a necessary condition, so the order they run in does not change
    # which peaks pass: the cheapest and most selective run first, on all the peaks (the
    # screen, _ring_screen: a few samples per ring against the pixel noise, then the same
    # few against the tile's texture, which a lit sea's ~20,000 bumps fail), and the dear
    # ones (the prefilter's box means and the full rings' statistics) on the few left.
    # The frame fails when more than MAX_PEAKS maxima pass the prefilter: that count needs
    # the prefilter on every maximum, which only a frame with more maxima than that runs.
    thr = PREFILTER_FRACTION * significance_sigma
    textures = TileTextures(G, sigma_G)
    if ys.size > MAX_PEAKS:
        # flat steps (a night sea on a low-noise 8-bit sensor) give plateaus of equal maxima:
        # each plateau is one peak before the count (frames below the count keep all of them)
        ys, xs = one_per_plateau(ys, xs, G.shape)
        keep = _prefilter(G, ys, xs, thr, sigma_G, int(radii[-1]), textures)
        ys, xs = ys[keep], xs[keep]
        if ys.size > MAX_PEAKS:
            return (
                f"{ys.size} local maxima above the significance threshold: "
                "a flat bright or noisy frame (glare?)"
            )
    if ys.size == 0:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0)
    rings = [_ring_offsets(r) for r in radii]
    gp = G[ys, xs].astype(np.float64)
    if screen:
        pass0 = _ring_screen(G, ys, xs, gp, rings, radii, significance_sigma, sigma_G, textures)
    else:
        pass0 = np.ones((len(rings), ys.size), bool)
    sel = np.flatnonzero(pass0.any(axis=0))
    ys, xs, gp, pass0 = ys[sel], xs[sel], gp[sel], pass0[:, sel]
    if ys.size:
        keep = _prefilter(G, ys, xs, thr, sigma_G, int(radii[-1]), textures)
        ys, xs, gp, pass0 = ys[keep], xs[keep], gp[keep], pass0[:, keep]
    # Pass 1: each ring in full where the screen let it pass: its highest sample against
    # sigma_G; then, where that holds, the ring's spread (median absolute deviation of
    # RING_SAMPLES of its samples) and the roundness of the ring inside it (whose samples
    # are gathered for those peaks alone).
    s_thr = significance_sigma * sigma_G
    n_r = len(radii)
    rise = np.full((n_r, ys.size), -np.inf)  # centre minus the ring's highest sample
    for k, (dy, dx) in enumerate(rings):
        at = np.flatnonzero(pass0[k])
        if at.size:
            rise[k, at] = gp[at] - ring_samples(G, ys[at], xs[at], dy, dx).max(axis=1)
    may = rise > s_thr
    spreads = np.zeros((n_r, ys.size))
    for k in range(n_r):
        at = np.flatnonzero(may[k])
        if at.size == 0:
            continue
        _top, _med, spread = _ring_stats(G, ys[at], xs[at], rings[k])
        # the same division as pass 2's by a smaller divisor: a peak that passes there
        # passes here
        ok = rise[k, at] / np.maximum(spread, sigma_G) > significance_sigma
        if k > 0:
            # round: no sample of the ring inside near the centre's level unless all are (a
            # bar or a line through the centre reaches it on two sides and leaves the rest
            # dark)
            top_in, med_in, _spread = _ring_stats(G, ys[at], xs[at], rings[k - 1])
            ok &= (top_in - med_in) < MAX_RING_ASYMMETRY * np.maximum(gp[at] - med_in, 1e-12)
        may[k, at] = ok
        spreads[k, at] = spread
    # Pass 2: the texture on each ring's scale (pixel pairs r apart), in the peak's tile; the
    # smallest ring passed is the spot's radius.
    radius = np.zeros(ys.size)
    for k, r in enumerate(radii):
        at = np.flatnonzero(may[k] & (radius == 0))
        if at.size == 0:
            continue
        floor = np.maximum(sigma_G, textures.at(_texture_step(r), ys[at], xs[at]))
        z = rise[k, at] / np.maximum(spreads[k, at], floor)
        radius[at[z > significance_sigma]] = r
    ok = radius > 0
    # plateaus (a saturated core) give several equal maxima: keep one per 2 coarse px
    pts = np.column_stack([xs[ok], ys[ok]]).astype(np.float64)
    rad, val = radius[ok], gp[ok]
    order = np.argsort(-val)
    kept: list[int] = []
    taken = np.zeros((h + 4, w + 4), bool)  # coarse pixels within 2 of a kept spot
    for i in order:
        x, y = int(pts[i, 0]), int(pts[i, 1])
        if taken[y + 2, x + 2]:
            continue
        kept.append(int(i))
        taken[y : y + 5, x : x + 5] = True
    kept_a = np.array(kept, np.intp)
    return pts[kept_a], rad[kept_a], (val[kept_a] - bg) / sigma_G


def _local_maxima(G: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the pixels of ``G`` above ``level`` that are 3x3 local maxima.

    A pixel equal to its largest neighbour counts (a plateau gives several). Row-major
    order. Where more than a sixteenth of the pixels are above the level (a lit sea), one
    dilation of the whole image beats gathering the neighbours of each.
    """
    h, w = G.shape
    flat_g = G.ravel()
    above = flat_g > level
    if np.count_nonzero(above) > h * w // 16:
        is_max = cv2.compare(G, cv2.dilate(G, np.ones((3, 3), np.uint8)), cv2.CMP_GE)
        idx = np.flatnonzero(above & (is_max.ravel() != 0))
    else:
        idx = np.flatnonzero(above)
        ys, xs = np.divmod(idx, w)
        top = np.full(idx.size, -np.inf, np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy or dx:
                    yy = np.clip(ys + dy, 0, h - 1)
                    xx = np.clip(xs + dx, 0, w - 1)
                    np.maximum(top, G[yy, xx], out=top)
        idx = idx[flat_g[idx] >= top]
    ys, xs = np.divmod(idx, w)
    return ys, xs


def one_per_plateau(ys: np.ndarray, xs: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """One local maximum per plateau: the one nearest the plateau's centroid.

    Two 3x3 local maxima that touch (8-connected) are equal (each is at least the other),
    so the connected groups of maxima are plateaus. Of each, the member nearest the
    group's centroid is kept (the first in row-major order on a tie); a lone maximum is
    its own group. Row-major order is kept.

    Parameters
    ----------
    ys, xs : (n,) arrays of int
        Rows and columns of local maxima of an image of ``shape``.
    """
    if ys.size == 0:
        return ys, xs
    mask = np.zeros(shape, np.uint8)
    mask[ys, xs] = 1
    _n, labels, _stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    labels, centroids = np.asarray(labels, np.intp), np.asarray(centroids, np.float64)
    lab = labels[ys, xs]
    d2 = (xs - centroids[lab, 0]) ** 2 + (ys - centroids[lab, 1]) ** 2
    order = np.lexsort((np.arange(ys.size), d2, lab))  # by group, nearest first, then row-major
    first = np.ones(order.size, bool)
    first[1:] = lab[order][1:] != lab[order][:-1]
    kept = np.sort(order[first])
    return ys[kept], xs[kept]


def _prefilter(
    G: np.ndarray, ys: np.ndarray, xs: np.ndarray, thr: float, sigma_G: float, half: int,
    textures: TileTextures,
) -> np.ndarray:
    """Which peaks rise ``thr`` noise sigmas above the mean of their ``2 half + 1`` box, (n,) bool.

    In the frame's noise ``sigma_G`` and in the tile's texture noise at a 2-px scale.
    """
    keep = np.zeros(ys.size, bool)
    if ys.size:
        rise = G[ys, xs] - box_means(G, ys, xs, half)
        at = np.flatnonzero(rise > thr * sigma_G)
        if at.size:
            tex2 = textures.at(2, ys[at], xs[at])
            keep[at[rise[at] > thr * np.maximum(sigma_G, tex2)]] = True
    return keep


def _texture_step(radius: float) -> int:
    """Pixel-pair distance of the texture noise a ring of ``radius`` coarse px is judged in."""
    return max(2, round(radius))


def _ring_offsets(radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets of a ring's samples, (m,) each, int.

    :data:`RING_SAMPLES` samples at least, one every :data:`RING_SPACING_PX` coarse px of
    the circle, rounded to the pixel grid.
    """
    n_s = max(RING_SAMPLES, math.ceil(2 * math.pi * radius / RING_SPACING_PX))
    ang = 2 * np.pi * np.arange(n_s) / n_s
    return (np.rint(radius * np.sin(ang)).astype(np.intp),
            np.rint(radius * np.cos(ang)).astype(np.intp))


def _screen_offsets(dy: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The :data:`PASS0_SAMPLES` (about) evenly spaced samples of a ring the screen uses."""
    few = slice(None, None, max(1, dy.size // PASS0_SAMPLES))
    return dy[few], dx[few]


def _ring_screen(
    G: np.ndarray, ys: np.ndarray, xs: np.ndarray, gp: np.ndarray,
    rings: list[tuple[np.ndarray, np.ndarray]], radii: tuple[float, ...],
    significance_sigma: float, sigma_G: float, textures: TileTextures,
) -> np.ndarray:
    """Which peaks may pass which ring, (n_rings, n) bool: a bound, no peak that passes is lost.

    A peak can pass ring k only if it stands ``significance_sigma`` above the ring's highest
    sample in ``sigma_G`` (pass 1) and in ``max(sigma_G, texture_k)`` (pass 2 divides by at
    least that), and the ring's highest sample is at least that of any subset of its
    samples. So it must stand that far above each of a few samples
    (:func:`_screen_offsets`), tested sample by sample on the peaks left: a lit sea's
    ~20,000 bumps, whose tile texture is several sigma_G, fail on the first one or two,
    and only a few peaks cost a sample per ring. The texture threshold is lowered by 1e-9
    of itself, so that rounding cannot make this product test stricter than pass 2's
    quotient.
    """
    h, w = G.shape
    flat = G.ravel()
    s_thr = significance_sigma * sigma_G
    out = np.zeros((len(rings), ys.size), bool)
    reach = max(int(max(np.abs(dy).max(), np.abs(dx).max())) for dy, dx in rings)
    inner = (ys >= reach) & (ys < h - reach) & (xs >= reach) & (xs < w - reach)
    i_in, i_out = np.flatnonzero(inner), np.flatnonzero(~inner)
    base_in, gp_in = ys[i_in] * w + xs[i_in], gp[i_in]
    tile = textures.tile_of(ys, xs)
    tiles = np.flatnonzero(np.bincount(tile))
    tile_in = tile[i_in]
    for k, (dy, dx) in enumerate(rings):
        fy, fx = _screen_offsets(dy, dx)
        tex = textures.of_tiles(_texture_step(radii[k]), tiles)  # per tile
        need = np.maximum(s_thr, (significance_sigma * (1.0 - 1e-9)) * np.maximum(sigma_G, tex))
        # peaks inside the frame by the ring's reach: one flat gather per sample, of the
        # peaks still standing (ndarray.take: G[index]'s values, 5x faster on a 1-D array)
        at, b, g, t = i_in, base_in, gp_in, need.take(tile_in)
        for off in fy * w + fx:
            keep = (g - flat.take(b + off)) > t
            at, b, g, t = at[keep], b[keep], g[keep], t[keep]
            if at.size == 0:
                break
        out[k, at] = True
        if i_out.size:  # the few at the frame's edge: clipped coordinates
            top = ring_samples(G, ys[i_out], xs[i_out], fy, fx).max(axis=1)
            out[k, i_out[(gp[i_out] - top) > need[tile[i_out]]]] = True
    return out


def _ring_stats(
    G: np.ndarray, ys: np.ndarray, xs: np.ndarray, ring: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Highest sample, and median and spread of :data:`RING_SAMPLES` samples, of one ring per peak.

    ``ring`` holds the ring's row and column offsets (:func:`_ring_offsets`). The spread is
    ``1.4826`` times the median absolute deviation. Returns three (n,) arrays of float.
    """
    dy, dx = ring
    few = slice(None, None, max(1, dy.size // RING_SAMPLES))
    sub = ring_samples(G, ys, xs, dy[few], dx[few]).astype(np.float64)
    med = row_median(sub)
    spread = 1.4826 * row_median(np.abs(sub - med[:, None]))
    top = ring_samples(G, ys, xs, dy, dx).max(axis=1).astype(np.float64)
    return top, med, spread


def ring_samples(
    G: np.ndarray, ys: np.ndarray, xs: np.ndarray, dy: np.ndarray, dx: np.ndarray
) -> np.ndarray:
    """Values of ``G`` at ``(ys + dy, xs + dx)`` for each point and offset, (n, m), ``G``'s dtype.

    Coordinates beyond the image are clipped to it (the replicated border). Points at
    least the largest offset inside the image are gathered by flat index, the others
    (few) by clipped coordinates; no padded copy of the image is made.
    """
    h, w = G.shape
    out = np.empty((ys.size, dy.size), G.dtype)
    if ys.size == 0 or dy.size == 0:
        return out
    r = int(max(np.abs(dy).max(), np.abs(dx).max()))
    inner = (ys >= r) & (ys < h - r) & (xs >= r) & (xs < w - r)
    i_in = np.flatnonzero(inner)
    if i_in.size:
        base = ys[i_in] * w + xs[i_in]
        out[i_in] = G.ravel().take(base[:, None] + (dy * w + dx)[None, :])
    i_out = np.flatnonzero(~inner)
    if i_out.size:
        yy = np.clip(ys[i_out, None] + dy[None, :], 0, h - 1)
        xx = np.clip(xs[i_out, None] + dx[None, :], 0, w - 1)
        out[i_out] = G.ravel().take(yy * w + xx)
    return out
