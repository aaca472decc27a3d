"""Bright-spot candidate search: beacons are the brightest compact spots of a frame.

On rendered or real frames, a threshold a few noise sigmas above the background
also passes deck markings, deck texture, the lit sea and edges. Beacons,
however, reach (nearly) the brightest level of the frame in at least one
channel (their cores saturate), while white markings and the lit deck stay
well below it. So candidates are found on the *peak-channel* image (per pixel
the largest channel, which keeps the red bow beacon as bright as the white
ones), thresholded at a fraction ``spot_level`` of the way from the frame's
background to its bright-spot level. Both levels are measured per frame:

* background: median of the peak-channel image (strided sample);
* bright-spot level: the ``BRIGHT_RANK``-th brightest pixel of the frame, so a
  single hot pixel does not set it.

Large frames are searched on a block-*maximum* copy (block means would dilute
small spots below the level), then at full resolution in boxes around it.

All of it is computed once per frame (:func:`spot_search`) and shared by the
box search and the candidate windows. The full frame is read once, by strided
element-wise maxima that keep its integer type (block maxima of the peak channel,
straight from the interleaved RGB pixels); the peak channel itself is made only for
strided samples and small windows, and the bright level is ranked among the
pixels of the brightest blocks only.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import cv2
import numpy as np
from deckpose.detect.background import median
from deckpose.detect.defects import point_defects
from deckpose.detect.registry import DetectorOptions

#: The bright-spot level is the value of this brightest pixel (rank from the top).
BRIGHT_RANK = 20

#: dtypes kept as they are (others become float32).
_CV_DTYPES = (np.uint8, np.uint16, np.int16, np.float32, np.float64)


def coarse_factor(shape: tuple[int, int], coarse_max_px: int) -> int:
    """Integer block size that brings ``H * W`` down to at most ``coarse_max_px``."""
    return max(1, math.ceil(math.sqrt(shape[0] * shape[1] / coarse_max_px)))


def peak_channel(pixels: np.ndarray) -> np.ndarray:
    """Per-pixel largest channel of an (h, w, 3) block, or the block itself; (h, w), dtype kept.

    Integer and float32 images keep their dtype (OpenCV's per-element maximum, no float
    copy of a whole frame); other dtypes become float32.
    """
    a = np.asarray(pixels)
    if a.dtype.type not in _CV_DTYPES:
        a = a.astype(np.float32)
    if a.ndim == 2:
        return a
    # element-wise maximum of the channel views (a reduction over the short last axis,
    # a.max(axis=2), is ~50x slower; cv2.split copies every channel first)
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


def _strided_max(a: np.ndarray, axis: int, step: int, phases: int) -> np.ndarray:
    """Maxima over ``phases`` consecutive entries every ``step`` along ``axis``.

    Entry ``i`` of the result is the maximum of ``a`` at ``i*step + k``, ``k < phases``
    (fewer at the end); ``step`` passes of an element-wise maximum over strided
    views, each a ``1/step`` of the array.
    """
    def sl(start: int, stop: int | None, stride: int | None) -> tuple[slice, ...]:
        return tuple(slice(start, stop, stride) if d == axis else slice(None)
                     for d in range(a.ndim))

    out = a[sl(0, None, step)].copy()
    for k in range(1, min(phases, a.shape[axis])):
        src = a[sl(k, None, step)]
        view = out[sl(0, src.shape[axis], None)]
        np.maximum(view, src, out=view)
    return out


def block_max(pk: np.ndarray, factor: int) -> np.ndarray:
    """Maxima of ``factor x factor`` blocks of an (H, W) image, (ceil(H/f), ceil(W/f)).

    Block ``(i, j)`` covers rows ``i*f .. i*f+f-1`` and columns ``j*f .. j*f+f-1``
    (edge blocks are cut by the image border); the dtype is kept. Rows by
    element-wise maxima of strided views, one pass over the frame (a dilation sampled
    every ``f`` pixels would cost the ``f x f`` maximum at every pixel); then columns
    (:func:`_column_block_max`), on ``1/f`` of it.
    """
    if factor == 1:
        return pk
    rows = _strided_max(np.asarray(pk), 0, factor, factor)
    return _column_block_max(rows, factor)


def _column_block_max(rows: np.ndarray, g: int) -> np.ndarray:
    """Maxima of groups of ``g`` consecutive columns of a 2-D array, (h, ceil(w/g)).

    OpenCV's dilation by a ``1 x g`` row anchored at its first pixel, sampled every ``g``
    columns: in SIMD over contiguous rows, where the strided element-wise maxima of
    :func:`_strided_max` step ``g`` elements at a time (8 MP 8-bit RGB: 3x faster). Past
    the last column the dilation's default border adds nothing. Other dtypes than
    OpenCV's take the strided maxima.
    """
    if rows.dtype.type not in _CV_DTYPES or min(rows.shape) == 0:
        return _strided_max(rows, 1, g, g)
    wide = cv2.dilate(np.ascontiguousarray(rows), np.ones((1, g), np.uint8), anchor=(0, 0))
    return np.asarray(wide)[:, ::g].copy()


def peak_block_max(image: np.ndarray, factor: int) -> np.ndarray:
    """:func:`block_max` of the peak-channel image, without making the peak-channel image.

    An (H, W, 3) frame is reduced as its (H, 3W) interleaved view, its columns in
    groups of ``3f``: each group spans every channel of pixels ``j .. j+f-1``. One
    pass over the frame, no copy of it.
    """
    a = np.asarray(image)
    if a.ndim == 2 or factor == 1:
        return block_max(peak_channel(a), factor)
    H, W, _ = a.shape
    wide = np.ascontiguousarray(a).reshape(H, 3 * W)
    rows = _strided_max(wide, 0, factor, factor)
    return _column_block_max(rows, 3 * factor)


@dataclass(frozen=True)
class SpotSearch:
    """The bright-spot search of one frame, computed once by :func:`spot_search`.

    Attributes
    ----------
    image : (H, W) or (H, W, 3) array
        The frame (not copied).
    small : (ceil(H/f), ceil(W/f)) array
        Block maxima of the peak-channel image (:func:`peak_block_max`).
    factor : int
        Block size ``f``, pixels.
    threshold_dn : float
        Spot threshold: ``spot_level`` of the way from the background to the bright
        level, and at least ``threshold_sigma`` noise sigmas above the background, DN.
    background_dn : float
        Median of the peak-channel image (strided sample), DN.
    bright_dn : float
        Value of the ``BRIGHT_RANK``-th brightest peak-channel pixel, DN.
    noise_dn : float
        Noise of the peak-channel image (pixel differences), DN.
    saturation_dn : float
        Value at which a channel clips (:func:`clip_level`), DN.
    """

    image: np.ndarray
    small: np.ndarray
    factor: int
    threshold_dn: float
    background_dn: float
    bright_dn: float
    noise_dn: float
    saturation_dn: float

    def peak(self, u0: int, v0: int, u1: int, v1: int) -> np.ndarray:
        """Peak-channel pixels of the window ``[v0:v1, u0:u1]``, (v1 - v0, u1 - u0)."""
        return peak_channel(self.image[v0:v1, u0:u1])


def bright_level(
    image: np.ndarray, small: np.ndarray, factor: int, rank: int = BRIGHT_RANK
) -> float:
    """Value of the ``rank``-th brightest peak-channel pixel of ``image``, exactly.

    ``small`` holds the peak-channel maxima of ``factor x factor`` blocks; its own
    ``g x g`` blocks give a still coarser copy. The ``rank`` largest maxima of any
    block grid are ``rank`` distinct pixels, so the answer is at least the
    ``rank``-th largest coarse maximum ``t``, and every pixel at or above ``t`` lies
    in a coarse block whose maximum is at or above ``t``. Only those blocks' pixels
    are ranked.
    """
    g = max(1, math.ceil(math.sqrt(small.size / 16_384)))
    tiny = block_max(small, g)
    flat = tiny.ravel()
    k = min(rank, flat.size)
    t = np.partition(flat, flat.size - k)[flat.size - k]
    ys, xs = np.nonzero(tiny >= t)
    b = factor * g  # coarse block side, full-resolution pixels
    H, W = image.shape[:2]
    if ys.size * b * b > H * W // 8:  # a flat or saturated frame: rank the whole frame
        pk = peak_channel(image)
        vals = pk[pk >= t]
    else:
        vals = np.concatenate(
            [
                peak_channel(image[y * b : (y + 1) * b, x * b : (x + 1) * b]).ravel()
                for y, x in zip(ys, xs)
            ]
        )
        vals = vals[vals >= t]
    k = min(rank, vals.size)
    return float(np.partition(vals, vals.size - k)[vals.size - k])


#: Sensor bit depths whose full scale a uint16 frame may hold (10-, 12- and 14-bit data).
_PACKED_BIT_DEPTHS = (10, 12, 14)


def clip_level(dtype: np.dtype, bright_dn: float) -> float:
    """The value at which a frame's channels clip, DN.

    The dtype maximum of an integer image (inf for float images), except that a
    uint16 frame whose bright level (its ``BRIGHT_RANK``-th brightest peak-channel
    pixel) is exactly the full scale of a 10-, 12- or 14-bit sensor holds a
    saturated plateau of at least ``BRIGHT_RANK`` pixels at that value: the data
    are ``bits``-bit, stored in 16 bits (a 12-bit PNG), and clip there.
    """
    dt = np.dtype(dtype)
    if not np.issubdtype(dt, np.integer):
        return math.inf
    top = float(np.iinfo(dt).max)
    if dt == np.uint16:
        for bits in _PACKED_BIT_DEPTHS:
            if bright_dn == 2**bits - 1:
                return bright_dn
    return top


def spot_search(
    image: np.ndarray, options: DetectorOptions, *, background_dn: float | None = None,
    noise_dn: float | None = None,
) -> SpotSearch:
    """Block maxima and the spot levels of a frame's peak channel (:class:`SpotSearch`).

    The threshold lies ``options.spot_level`` of the way from the background to the
    bright-spot level, and at least ``threshold_sigma`` noise sigmas above the
    background (noise of the peak-channel image from pixel differences). A caller that
    has the peak channel's background (the median of the 30,000-sample strided grid) and
    difference noise (:func:`~deckpose.detect.background.difference_noise`, before any
    floor) passes them as ``background_dn`` and ``noise_dn``: on a mono frame they are the
    frame statistics' own.
    """
    from deckpose.detect.background import MIN_NOISE_DN, difference_noise

    H, W = image.shape[:2]
    f = coarse_factor((H, W), options.coarse_max_px)
    small = peak_block_max(image, f)
    if background_dn is None:
        step = max(1, int(math.sqrt(H * W / 30_000)))
        background_dn = median(peak_channel(image[::step, ::step]))
    bg = background_dn
    bright = bright_level(image, small, f)
    if noise_dn is None:
        noise_dn = difference_noise(image, signal=peak_channel)
    # floor: the quantisation noise of one channel, 1/sqrt(12) DN
    noise = max(noise_dn, MIN_NOISE_DN)
    thr = max(bg + options.spot_level * (bright - bg), bg + options.threshold_sigma * noise)
    return SpotSearch(image, small, f, thr, bg, bright, noise, clip_level(image.dtype, bright))


def tophat_spot_search(image: np.ndarray, options: DetectorOptions) -> SpotSearch:
    """:func:`spot_search` on the peak channel minus its grey opening (a white top-hat).

    For frames whose background is uneven on scales larger than a beacon (a lit,
    textured deck, vignetting): the opening with a disc of
    ``options.background_kernel_px`` pixels keeps every bright structure wider than
    the disc (the deck, its lighting, wide markings) and the top-hat removes it,
    leaving the beacons on a level near zero. The bright-spot criterion then keeps
    only the brightest compact spots (``spot_level``), so deck texture and thin
    markings, which also survive a top-hat, are not candidates. Windows are
    measured on the top-hat; the clip level is the frame's own.
    """
    pk = peak_channel(image)
    k = 2 * (int(options.background_kernel_px) // 2) + 1
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    tophat = cv2.morphologyEx(pk, cv2.MORPH_TOPHAT, disc)
    s = spot_search(tophat, options)
    bright_pk = bright_level(pk, block_max(pk, s.factor), s.factor)
    return dataclasses.replace(s, saturation_dn=clip_level(image.dtype, bright_pk))


def bright_components(mask: np.ndarray, tile_px: int = 16_384) -> np.ndarray:
    """Bounding boxes ``(x, y, w, h)`` of the 8-connected components of a sparse mask, (n, 4).

    The same boxes as ``cv2.connectedComponentsWithStats`` on the whole mask
    (sorted by top row, then left column), but found in two levels: components of a
    ``g x g`` block-max copy with about ``tile_px`` pixels first, then components inside each of
    those. Every component of ``mask`` lies within one component of the coarse
    copy (8-adjacent pixels have equal or 8-adjacent blocks), so labelling the
    pixels of each coarse component apart gives exactly the full labelling; only
    the few bright regions of a frame are labelled at full size.
    """
    m = np.ascontiguousarray(mask, dtype=np.uint8)
    g = max(1, math.ceil(math.sqrt(m.size / tile_px)))
    if g == 1:
        _n, _, st, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        return st[1:, :4].astype(int)
    coarse = block_max(m, g)
    n_c, lab_c, st_c, _ = cv2.connectedComponentsWithStats(coarse, connectivity=8)
    h_m, w_m = m.shape
    boxes = []
    for k in range(1, n_c):
        x, y, w, h, _ = (int(c) for c in st_c[k])
        r0, r1, c0, c1 = y * g, min(h_m, (y + h) * g), x * g, min(w_m, (x + w) * g)
        own = np.repeat(np.repeat(lab_c[y : y + h, x : x + w] == k, g, axis=0), g, axis=1)
        sub = m[r0:r1, c0:c1] * own[: r1 - r0, : c1 - c0]
        _n, _, st, _ = cv2.connectedComponentsWithStats(sub, connectivity=8)
        boxes.extend((int(a) + c0, int(b) + r0, int(cw), int(ch)) for a, b, cw, ch, _ in st[1:])
    boxes.sort(key=lambda b: (b[1], b[0]))
    return np.array(boxes, int).reshape(-1, 4)


def spot_boxes(
    image: np.ndarray, options: DetectorOptions, search: SpotSearch | None = None
) -> tuple[list[tuple[int, int, int, int]], str]:
    """Full-resolution boxes ``(u0, v0, u1, v1)`` around the frame's bright spots.

    Returns the boxes and, when there are none or too many, the reason. ``search``
    is the frame's :func:`spot_search` when the caller has it already.
    """
    s = spot_search(image, options) if search is None else search
    thr, bg, bright, f = s.threshold_dn, s.background_dn, s.bright_dn, s.factor
    stats = bright_components(s.small > thr)
    # point defects (hot pixels) are no spots: a component of at most 2x2 blocks (a hot
    # pixel, spread a pixel by demosaicing, on a block corner) is tested at its peak
    small_c = (stats[:, 2] <= 2) & (stats[:, 3] <= 2)
    if small_c.any():
        centres = np.column_stack([(stats[small_c, 0] + 0.5 * stats[small_c, 2]) * f - 0.5,
                                   (stats[small_c, 1] + 0.5 * stats[small_c, 3]) * f - 0.5])
        drop = np.zeros(stats.shape[0], bool)
        drop[np.flatnonzero(small_c)] = point_defects(s.image, centres, search_px=f + 1)
        stats = stats[~drop]
        if drop.all():
            # the bright level is the hot pixels' (clipped ones, at night): no bright spot,
            # and the significance search looks for the beacons
            return [], ""
    n_spots = stats.shape[0]
    if n_spots > options.max_blobs:
        return [], (
            f"{n_spots} bright spots above {thr:.0f} DN exceed max_blobs={options.max_blobs} "
            f"(background {bg:.0f} DN, bright level {bright:.0f} DN): glare or noise"
        )
    if n_spots == 0:
        return [], (
            f"dark frame: no spot above {thr:.1f} DN (peak channel background {bg:.1f} DN, "
            f"bright level {bright:.0f} DN)"
        )
    H, W = s.image.shape[:2]
    pad = f + 2
    boxes = [
        (
            max(0, x * f - pad),
            max(0, y * f - pad),
            min(W, (x + w) * f + pad),
            min(H, (y + h) * f + pad),
        )
        for x, y, w, h in stats
    ]
    return boxes, ""


#: Angular sectors and percentile of the pedestal around a spot (see :func:`spot_pedestal`).
PEDESTAL_SECTORS = 8
PEDESTAL_PERCENTILE = 75.0


def spot_pedestal(
    pixels: np.ndarray, core: np.ndarray, border_level_dn: float, wings_px: float
) -> float:
    """Level under a bright spot, DN.

    Taken from the window pixels "away" from the core: farther than ``wings_px``
    (at least ``2 r + 2`` px, ``r`` the core's equivalent radius), beyond the spot's
    own wings. It is the highest :data:`PEDESTAL_PERCENTILE` percentile of the
    :data:`PEDESTAL_SECTORS` sectors around the core: a clean spot's glow and noise
    are alike in every sector, while a marking or housing edge the beacon does not
    light raises the sectors it crosses, so it stays below the pedestal. At least
    ``border_level_dn`` (the window border's fitted level).
    """
    r_core = math.sqrt(core.sum() / math.pi)
    r_px = math.ceil(max(wings_px, 2.0 * r_core + 2.0))
    # distance to the core (exact Euclidean): linear time, where a dilation with a disc of
    # radius r_px costs r_px^2 per pixel (minutes for a large bright marking)
    dist = cv2.distanceTransform((~core).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    far = dist > r_px
    if not far.any():
        return border_level_dn
    # Eight sectors around the core: a clean spot's glow and the noise are the same in
    # each; a marking or housing edge raises the upper quartile of the sectors it crosses.
    vv, uu = np.nonzero(core)
    fv, fu = np.nonzero(far)
    ang = np.arctan2(fv - vv.mean(), fu - uu.mean())
    sector = ((ang + np.pi) * (PEDESTAL_SECTORS / (2 * np.pi))).astype(int) % PEDESTAL_SECTORS
    # each sector's percentile, interpolated as np.percentile's default does, by a
    # partial sort of the sector's values (np.percentile's own overhead was most of the
    # time for the 13 windows of a frame)
    vals = np.asarray(pixels[fv, fu], float)
    levels = []
    for k in range(PEDESTAL_SECTORS):
        g = vals[sector == k]
        if g.size == 0:
            continue
        pos = (PEDESTAL_PERCENTILE / 100.0) * (g.size - 1)
        lo = math.floor(pos)
        hi = min(lo + 1, g.size - 1)
        part = np.partition(g, (lo, hi))
        levels.append(part[lo] + (part[hi] - part[lo]) * (pos - lo))
    return max(border_level_dn, float(max(levels)))
