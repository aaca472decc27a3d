"""Coarse-to-fine candidate search, shared by the detectors.

1. Block-average the frame to at most ``coarse_max_px`` pixels (OpenCV area
   resampling) and threshold it at its own background + ``k`` sigma.
2. Each connected component of the coarse mask gives a full-resolution window;
   in it, pixels above the full-resolution threshold form blobs (connected
   components, 8-connectivity).
3. Each blob becomes a :class:`Candidate`: a full-resolution window around it,
   its mask, local background and the frame noise, which a detector measures.

Thresholds adapt to the frame: background and noise are measured per frame
(:mod:`deckpose.detect.background`), never fixed constants.

By default (``DetectorOptions.spot_level`` > 0) steps 1-2 are replaced by the
bright-spot search of :mod:`deckpose.detect.spots`: candidates are the cores
that approach the frame's brightest level in their largest channel (rendered
and real beacons saturate; deck markings, texture and the lit sea do not), and
each is measured on the peak channel, above its pedestal where a marking or
the beacon's housing surrounds it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import cv2
import numpy as np
from deckpose.detect.background import (
    border_noise,
    channel_sum_noise,
    difference_noise,
    frame_problem,
    frame_stats,
    mono,
    noise_floor_dn,
    robust_stats,
    row_median,
    tile_stats,
)
from deckpose.detect.candidate import Candidate
from deckpose.detect.gain import estimate_gain
from deckpose.detect.registry import Blobs, DetectorOptions
from deckpose.detect.significance import significant_spots
from deckpose.detect.spots import (
    SpotSearch,
    coarse_factor,
    spot_boxes,
    spot_pedestal,
    spot_search,
    tophat_spot_search,
)

from deckpose.records import Frame

#: A frame narrower than this has no room for a beacon and its background (and no noise
#: estimate: a 1x1 frame gave "noise nan DN").
MIN_FRAME_SIDE_PX = 8

#: A blob covering more than this fraction of the frame is no beacon (glare, a lit patch). The
#: largest beacon image comes at the bottom of a landing: a beacon of radius r seen from height
#: h by a camera of horizontal field F covers pi r^2 / (4 h^2 tan^2(F/2)) x W/H of the frame, 4 %
#: for the 0.15 m beacon from 1 m with the 75-degree thesis camera (1 % from 2 m, where a limit
#: of 1 % once dropped most of them); a 64 MP frame at 20 m: 0.01 %.
MAX_SPOT_AREA_FRACTION = 0.05


MeasureFn = Callable[[Candidate], "tuple[float, float, np.ndarray, float, float, float] | None"]
BatchMeasureFn = Callable[
    [list[Candidate]], "list[tuple[float, float, np.ndarray, float, float, float] | None]"
]


def coarse_image(image: np.ndarray, factor: int) -> np.ndarray:
    """Block means of ``factor x factor`` pixels (mono), float32."""
    if factor == 1:
        return mono(image).astype(np.float32)
    H, W = image.shape[:2]
    h, w = H // factor, W // factor
    small = cv2.resize(image[: h * factor, : w * factor], (w, h), interpolation=cv2.INTER_AREA)
    if small.ndim == 3:
        return small.sum(axis=2, dtype=np.float32)
    return small.astype(np.float32)


def coarse_boxes(
    image: np.ndarray, options: DetectorOptions, search: SpotSearch | None = None
) -> tuple[list[tuple[int, int, int, int]], str]:
    """Full-resolution boxes ``(u0, v0, u1, v1)`` (exclusive ends) around coarse detections.

    Returns the boxes and, when there are none or too many, the reason. With the
    frame's bright-spot search (``search``, see :mod:`deckpose.detect.spots`) the boxes
    are its bright spots (:func:`~deckpose.detect.spots.spot_boxes`); otherwise blobs
    ``threshold_sigma`` noise sigmas above the block-averaged frame's background.
    """
    if search is not None:
        return spot_boxes(image, options, search)
    f = coarse_factor(image.shape[:2], options.coarse_max_px)
    small = coarse_image(image, f)
    step = max(1, int(math.sqrt(small.size / 30_000)))
    if options.background_kernel_px > 0:
        # Uneven background (a lit, textured deck): subtract a grey opening, which keeps
        # structures wider than the kernel and removes the beacons.
        k = 2 * max(1, round(options.background_kernel_px / (2 * f))) + 1
        small = small - cv2.morphologyEx(
            small, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
        )
        # ... and its noise varies with the background (shot noise): local statistics.
        bg_map, noise_map = tile_stats(small)
        noise_map = np.maximum(noise_map, noise_floor_dn(image))
        mask = (small > bg_map + options.threshold_sigma * noise_map).astype(np.uint8)
    else:
        bg, _ = robust_stats(small[::step, ::step])
        noise = max(difference_noise(small), noise_floor_dn(image))
        mask = (small > bg + options.threshold_sigma * noise).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n - 1 > options.max_blobs:
        return [], (
            f"{n - 1} candidate blobs exceed max_blobs={options.max_blobs}: "
            "glare, noise or the wrong threshold"
        )
    H, W = image.shape[:2]
    pad = f + 2
    boxes = []
    for x, y, w, h, _area in stats[1:]:
        boxes.append(
            (
                max(0, x * f - pad),
                max(0, y * f - pad),
                min(W, (x + w) * f + pad),
                min(H, (y + h) * f + pad),
            )
        )
    return boxes, ""


def _saturated(image: np.ndarray, box: tuple[int, int, int, int], sat: float) -> np.ndarray:
    """Pixels of the window with any channel at or above ``sat``, (h, w) bool."""
    u0, v0, u1, v1 = box
    block = image[v0:v1, u0:u1]
    if block.ndim == 3 and block.shape[2] == 3 and np.issubdtype(block.dtype, np.integer):
        # any channel at sat is the largest one at sat (element-wise maxima of the channels:
        # a reduction over the short channel axis costs several times more)
        top = np.maximum(np.maximum(block[..., 0], block[..., 1]), block[..., 2])
        return np.asarray(top >= sat)
    return np.asarray((block >= sat).any(axis=2) if block.ndim == 3 else block >= sat)


def _window(
    image: np.ndarray, box: tuple[int, int, int, int], sat: float
) -> tuple[np.ndarray, np.ndarray]:
    u0, v0, u1, v1 = box
    return mono(image[v0:v1, u0:u1]), _saturated(image, box, sat)


def border_plane(pixels: np.ndarray) -> tuple[float, float, float]:
    """Plane ``(value at the centre, d/du, d/dv)`` fitted to a window's border pixels.

    Two passes: a least-squares fit, then a refit without border pixels more than
    3 robust sigmas off it (a neighbouring blob touching the border).
    """
    h, w = pixels.shape
    # the border clockwise from the top-left corner: top row, right column, bottom row,
    # left column (each corner once)
    cu, cv = (w - 1) / 2, (h - 1) / 2
    cols, rows = np.arange(w, dtype=float) - cu, np.arange(h, dtype=float) - cv
    if h < 2 or w < 2:
        z = np.asarray(pixels, float).ravel()
        uu_b, vv_b = np.broadcast_to(cols[None, :], (h, w)).ravel(), np.broadcast_to(
            rows[:, None], (h, w)).ravel()
    else:
        z = np.concatenate([pixels[0], pixels[1:, -1], pixels[-1, -2::-1], pixels[-2:0:-1, 0]])
        uu_b = np.concatenate([cols, np.full(h - 1, cols[-1]), cols[-2::-1], np.full(h - 2, cols[0])])
        vv_b = np.concatenate([np.full(w, rows[0]), rows[1:], np.full(w - 1, rows[-1]), rows[-2:0:-1]])
    z = np.asarray(z, float)
    A = np.column_stack([np.ones(z.size), uu_b, vv_b])
    keep = np.ones(z.size, bool)
    # medians by a sort (row_median: np.median's value, a fifth of its overhead)
    coef = np.array([float(row_median(z[None])[0]), 0.0, 0.0])
    for _ in range(2):
        if keep.sum() < 6:
            break
        coef = np.linalg.lstsq(A[keep], z[keep], rcond=None)[0]
        r = z - A @ coef
        dev = np.abs(r - row_median(r[None])[0])
        mad = 1.4826 * float(row_median(dev[None])[0]) + 1e-9
        keep = np.abs(r) < 3 * mad + 1e-6
    return float(coef[0]), float(coef[1]), float(coef[2])


def border_spread_px2(shape: tuple[int, ...]) -> float:
    """Sum over a window's border pixels of the squared column offset from the centre, px^2.

    The same holds for the rows with ``h`` and ``w`` swapped; the smaller of the two is
    returned. A least-squares slope fitted to the border (:func:`border_plane`) on white
    noise of sd ``n`` has sd ``n / sqrt(this)`` (the plane's three columns are orthogonal
    on the border, which is symmetric about the centre).
    """
    h, w = int(shape[0]), int(shape[1])
    if h < 3 or w < 3:
        return float(max(h * w, 1))

    def spread(a: int, b: int) -> float:  # offsets along the side of length a
        rows = 2.0 * a * (a * a - 1) / 12.0  # the two full sides of length a
        cols = 2.0 * (b - 2) * ((a - 1) / 2.0) ** 2  # the two short sides, at the ends
        return rows + cols

    return min(spread(w, h), spread(h, w))


def _border_median(pixels: np.ndarray) -> float:
    return float(
        np.median(np.concatenate([pixels[0], pixels[-1], pixels[1:-1, 0], pixels[1:-1, -1]]))
    )


BoxesFn = Callable[
    [np.ndarray, DetectorOptions, "SpotSearch | None"],
    "tuple[list[tuple[int, int, int, int]], str]",
]


#: A candidate window before the gain is known: pixels, blob mask, saturated pixels,
#: corner (u0, v0), background plane, threshold, noise, whether its signal is clipped, and
#: the surround's tilt left in it with its noise sd (du, dv, sd; see Candidate.surround_grad).
RawWindow = tuple[
    np.ndarray, np.ndarray, np.ndarray, int, int, tuple[float, float, float], float, float, bool,
    tuple[float, float, float],
]


def find_candidates(
    frame: Frame, options: DetectorOptions, *, boxes_fn: BoxesFn = coarse_boxes
) -> tuple[list[Candidate], str]:
    """All blobs of a frame as :class:`Candidate` windows, or ``([], reason)``.

    See :func:`search_candidates`, which also returns the search's note.
    """
    cands, reason, _note = search_candidates(frame, options, boxes_fn=boxes_fn)
    return cands, reason


def search_candidates(
    frame: Frame, options: DetectorOptions, *, boxes_fn: BoxesFn = coarse_boxes
) -> tuple[list[Candidate], str, str]:
    """All blobs of a frame as :class:`Candidate` windows, the failure reason and a note.

    The note says what the search left out of an ok frame (significant spots beyond
    ``max_blobs``, :func:`~deckpose.detect.significance.significant_spots`).

    Parameters
    ----------
    frame : Frame
    options : DetectorOptions
    boxes_fn : callable, optional
        ``(image, options, search) -> (boxes, reason)``: where to look at full
        resolution; ``search`` is the frame's :class:`~deckpose.detect.spots.SpotSearch`
        (``None`` when the bright-spot search is off); default :func:`coarse_boxes`.
    """
    image = frame.image
    if min(image.shape[:2]) < MIN_FRAME_SIDE_PX:
        return [], (f"image is {image.shape[1]}x{image.shape[0]} px: too small to find beacons in "
                    f"(each side at least {MIN_FRAME_SIDE_PX} px)"), ""
    # On an integer mono frame the channel sum is the peak channel, value for value: the
    # frame statistics' background and difference noise are the bright-spot search's too
    # (one estimate of each; a float32 frame's peak-channel median is taken in float32)
    mono_int = image.ndim == 2 and image.dtype.type in (np.uint8, np.uint16, np.int16)
    shared_noise = difference_noise(image) if mono_int else None
    st = frame_stats(image, difference_noise_dn=shared_noise)
    problem = frame_problem(st)
    if problem:
        return [], problem, ""
    search = None
    spot_thr = spot_noise = 0.0
    if options.spot_level > 0:
        # One bright-spot search per frame: levels, peak channel and block maxima are
        # shared by the box search and every candidate window; on an uneven background
        # (background_kernel_px) the search runs on the frame minus its grey opening.
        if options.background_kernel_px > 0:
            search = tophat_spot_search(image, options)
        else:
            search = spot_search(image, options, noise_dn=shared_noise,
                                 background_dn=st.background_dn if mono_int else None)
        spot_thr, spot_noise = search.threshold_dn, search.noise_dn
    # a 12-bit frame stored in 16 bits clips at 4095, not at the dtype maximum
    sat_dn = st.saturation_dn if search is None else search.saturation_dn
    boxes, reason = boxes_fn(image, options, search)
    if reason:
        return [], reason, ""
    thr = st.background_dn + options.threshold_sigma * st.noise_dn
    k_noise = options.threshold_sigma * st.noise_dn
    H, W = image.shape[:2]
    raw: list[RawWindow] = []
    seen: set[tuple[int, int]] = set()
    # the channel sum's noise as it is (unfloored: it enters covariances, the gain estimate and
    # the recorded snr, never a threshold), for the windows measured on the channel sum: the
    # bright spots' unclipped cores and every significance window
    sum_noise = channel_sum_noise(image) if search is not None else math.nan
    for box in boxes:
        if search is not None:
            # Bright-spot search: the blob is the spot's bright core (peak channel); its
            # threshold and noise are the spot's own, set below.
            above = search.peak(*box) > spot_thr
            pix = None
            thr_box = noise_box = math.nan
        else:
            pix, _ = _window(image, box, sat_dn)
            # The threshold follows the local background (the box border) where it is
            # brighter; with an uneven background, the local noise too.
            if options.background_kernel_px > 0:
                noise_box = max(border_noise(pix), noise_floor_dn(image))
                thr_box = _border_median(pix) + options.threshold_sigma * noise_box
            else:
                noise_box = st.noise_dn
                thr_box = max(thr, _border_median(pix) + k_noise)
            above = pix > thr_box
        n, labels, cstats, _ = cv2.connectedComponentsWithStats(
            above.astype(np.uint8), connectivity=8
        )
        for lab in range(1, n):
            x, y, w, h, area = (int(c) for c in cstats[lab])
            if area < options.min_area_px or area > MAX_SPOT_AREA_FRACTION * H * W:
                continue  # noise, or an extended light (glare, a lit patch): no beacon
            comp = labels[y : y + h, x : x + w] == lab
            # the component's brightest pixel (of the channel sum) names the blob
            block = (pix[y : y + h, x : x + w] if pix is not None else
                     mono(image[box[1] + y : box[1] + y + h, box[0] + x : box[0] + x + w]))
            peak = np.unravel_index(
                np.argmax(np.where(comp, block, -np.inf)), comp.shape
            )
            key = (box[1] + y + int(peak[0]), box[0] + x + int(peak[1]))
            if key in seen:  # the same blob reached from two overlapping coarse boxes
                continue
            seen.add(key)
            r_eq = math.sqrt(area / math.pi)
            if search is not None:
                # The core is the spot above spot_level of its peak: its radius is
                # sqrt(2 ln(1/spot_level)) sigma of a Gaussian spot (0.67 sigma at 0.8; a
                # clipped core is wider, which only widens the window). The window reaches
                # window_sigma sigma for the measurement plus 1.5 sigma beyond the wings
                # for the pedestal.
                sigma_core = max(r_eq, 1.0) / math.sqrt(2.0 * math.log(1.0 / options.spot_level))
                pad = math.ceil((options.window_sigma + 1.5) * sigma_core) + 3
            else:
                sigma_core = math.nan  # no core: the blob's own size sets the window
                pad = math.ceil(options.window_sigma * max(r_eq, 1.0)) + 3
            gu0, gv0 = box[0] + x, box[1] + y
            wb = (
                max(0, gu0 - pad),
                max(0, gv0 - pad),
                min(W, gu0 + w + pad),
                min(H, gv0 + h + pad),
            )
            if search is not None:
                # A clipped core is measured on the peak channel, whose clip level is one
                # number (core_fit censors it); an unclipped one on the channel sum, where
                # the photons (and the centroid's Cramer-Rao bound) are.
                wsat = _saturated(image, wb, sat_dn)
                core = wsat[gv0 - wb[1] : gv0 - wb[1] + h, gu0 - wb[0] : gu0 - wb[0] + w]
                on_peak = bool(core[comp].any()) or image.ndim == 2
                if on_peak:
                    wpix = search.peak(*wb).astype(np.float64)
                else:
                    wpix = mono(image[wb[1] : wb[3], wb[0] : wb[2]])
            else:
                wpix, wsat = _window(image, wb, sat_dn)
                on_peak = False
            mask = np.zeros(wpix.shape, bool)
            surround = (0.0, 0.0, 0.0)
            mask[gv0 - wb[1] : gv0 - wb[1] + h, gu0 - wb[0] : gu0 - wb[0] + w] = comp
            plane = border_plane(wpix)
            if search is not None:
                # Every bright spot is measured above its pedestal (spot_pedestal: the level
                # around the core, beyond its wings: a marking, a housing or its own glow). A
                # plane through the window border did worse even where the pedestal was
                # within the noise: a small core's window border lies in its glow, and the
                # plane's tilt moved the centre (rendered 80 m beacons: gauss 2.0x the CRB
                # with the border plane, 1.06x above the pedestal; analytic spots on a flat
                # background lose at most 0.14x, benchmarks/bench_detectors.py).
                ped = spot_pedestal(wpix, mask, plane[0],
                                    options.window_sigma * sigma_core - r_eq)
                # the noise of what the window holds: the peak channel's where the core is
                # measured on it, else the channel sum's
                noise_box = spot_noise if on_peak else sum_noise
                # the border's tilt stays in the signal; it bounds the centre's bias instead
                # (Candidate.surround_tilt_cov)
                surround = (plane[1], plane[2], noise_box / math.sqrt(border_spread_px2(wpix.shape)))
                plane = (ped, 0.0, 0.0)
                # half the core's height above the background, peak-channel DN
                thr_box = plane[0] + 0.5 * (float(wpix[mask].max()) - plane[0])
            raw.append((wpix, mask, wsat, wb[0], wb[1], plane, thr_box, noise_box, search is not None,
                        surround))
    # Every frame gets the significance search, a dark one too (median pixel 0 DN): until
    # session 22 it was skipped there, because its rare 1-DN pixels had once clustered into
    # "spots" by chance (105 on a 64 MP 8-bit frame with a 0.02 DN background, before the
    # search's ring screen and tile textures); on the independent generator's dark 8-bit
    # frames that left two beacons in three unfound and no frame identified.
    note = ""
    if search is not None and options.significance_sigma > 0:
        raw, reason, note = _significant_windows(image, options, sat_dn, raw, sum_noise)
        if reason:
            return [], reason, ""
    if not raw:
        return [], (
            f"dark frame: no blob above {thr:.1f} DN (background {st.background_dn:.1f} DN, "
            f"noise {st.noise_dn:.2f} DN, brightest pixel {float(np.max(image)):.0f} DN)"
        ), ""
    gain0 = options.gain_dn_per_e or 1.0
    cands = [window_candidate(win, gain0, (H, W)) for win in raw]
    if options.gain_dn_per_e is None:
        gain = estimate_gain(cands, options.window_sigma)
        cands = [dataclasses.replace(c, gain_dn_per_e=gain) for c in cands]
    return cands, "", note


def _significant_windows(
    image: np.ndarray,
    options: DetectorOptions,
    sat_dn: float,
    bright: list[RawWindow],
    sum_noise_dn: float,
) -> tuple[list[RawWindow], str, str]:
    """The bright-spot windows that are spots, and windows of the other significant spots.

    The significant spots are those of :mod:`deckpose.detect.significance`. A
    bright-spot window whose core is not clipped is kept only when a significant
    spot lies on its core (a noise peak on a bright patch or glare is not one); a
    clipped core (a saturated beacon, whose plateau no ring test sees) is kept. Each
    significant spot outside the kept windows gets a window of its own, measured
    on the channel sum above a plane fitted to its border; its blob is the spot's
    half-maximum region (of the window smoothed by a 1 px Gaussian) around its peak, and
    its noise the channel sum's as it is (``sum_noise_dn``, :func:`channel_sum_noise`:
    unfloored, as a bright spot's measured on the channel sum; the thresholds' noise,
    floored at 1 DN a channel, overstated a dark 8-bit frame's spots' covariances 3x), or
    the window border's where larger.

    Returns the windows, the reason when the frame fails, and the search's note.
    """
    centres, radii, reason, note = significant_spots(
        image, options.significance_sigma, options.max_blobs
    )
    if reason:
        return [], reason, ""
    taken: list[tuple[float, float, float, float]] = []
    out: list[RawWindow] = []
    for win in bright:
        _p, m, sat, u0, v0 = win[:5]
        rows, cols = np.nonzero(m)
        box = (u0 + cols.min(), v0 + rows.min(), u0 + cols.max(), v0 + rows.max())
        hit = any(box[0] - r - 2 <= uc <= box[2] + r + 2 and box[1] - r - 2 <= vc <= box[3] + r + 2
                  for (uc, vc), r in zip(centres, radii))
        if hit or sat[m].any():
            out.append(win)
            taken.append(box)
    for (uc, vc), r in zip(centres, radii):
        near_px = r + 2.0
        if any(a - near_px <= uc <= c + near_px and b - near_px <= vc <= d + near_px
               for a, b, c, d in taken):
            continue
        found = spot_window(image, float(uc), float(vc), float(r), sum_noise_dn, sat_dn)
        if found is None:
            continue
        win, (pu_px, pv_px) = found
        out.append(win)
        taken.append((pu_px - 1.0, pv_px - 1.0, pu_px + 1.0, pv_px + 1.0))
    return out, "", note


def spot_window(
    image: np.ndarray, uc: float, vc: float, r: float, noise_dn: float, sat_dn: float
) -> tuple[RawWindow, tuple[int, int]] | None:
    """The window of a spot a search found near ``(uc, vc)``, measured on the channel sum.

    The window reaches ``1.5 r + 4`` px around the spot, its background is a plane fitted
    to its border, and its blob is the half-maximum region (of the window smoothed by a
    1 px Gaussian, above the plane) around the highest point within ``max(r, 2)`` px of
    ``(uc, vc)``.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
    uc, vc : float
        Where the search found the spot, full-resolution pixels.
    r : float
        Its size: the radius it was found on, pixels.
    noise_dn : float
        The frame's noise of the channel sum, DN (the window border's, where larger).
    sat_dn : float
        Saturation level, DN.

    Returns
    -------
    (RawWindow, (u, v)) or None
        The window and its peak pixel; ``None`` when the window is smaller than 5 px a
        side or nothing rises above its plane there.
    """
    H, W = image.shape[:2]
    half = math.ceil(1.5 * r) + 4
    wb = (max(0, int(uc) - half), max(0, int(vc) - half),
          min(W, int(uc) + half + 1), min(H, int(vc) + half + 1))
    if wb[2] - wb[0] < 5 or wb[3] - wb[1] < 5:
        return None
    wpix = mono(image[wb[1] : wb[3], wb[0] : wb[2]])
    plane = border_plane(wpix)
    h, w = wpix.shape
    tilt = (np.arange(h)[:, None] - (h - 1) / 2) * plane[2] + (
        np.arange(w)[None, :] - (w - 1) / 2
    ) * plane[1]
    smooth = cv2.GaussianBlur(wpix - plane[0] - tilt, (0, 0), 1.0)
    # the peak nearest the search's centre, within the ring it passed on
    vv, uu = np.mgrid[0:h, 0:w]
    near = np.hypot(uu + wb[0] - uc, vv + wb[1] - vc) <= max(r, 2.0)
    pv, pu = np.unravel_index(np.argmax(np.where(near, smooth, -np.inf)), smooth.shape)
    top = float(smooth[pv, pu])
    if not top > 0:
        return None
    _n, labels = cv2.connectedComponents((smooth > 0.5 * top).astype(np.uint8), connectivity=8)
    mask = labels == labels[pv, pu]
    noise = max(noise_dn, border_noise(wpix))
    win: RawWindow = (wpix, mask, _saturated(image, wb, sat_dn), wb[0], wb[1], plane,
                      plane[0] + 0.5 * top, noise, False, (0.0, 0.0, 0.0))
    return win, (wb[0] + int(pu), wb[1] + int(pv))


def window_candidate(win: RawWindow, gain_dn_per_e: float, frame_shape: tuple[int, int]) -> Candidate:
    """The :class:`Candidate` of a window (:data:`RawWindow`) at a known gain, DN per electron."""
    p, m, s, u0, v0, bg, t, nz, clip, sg = win
    return Candidate(p, m, s, u0, v0, bg[0], (bg[1], bg[2]), nz, gain_dn_per_e, t, clip_signal=clip,
                     frame_shape=frame_shape, surround_grad=(sg[0], sg[1]), surround_grad_sd=sg[2])


def measure_candidates(
    frame: Frame, options: DetectorOptions, measure: MeasureFn, *, boxes_fn: BoxesFn = coarse_boxes
) -> Blobs:
    """Run ``measure`` on every candidate of ``frame``; ``None`` results are dropped.

    One candidate at a time: :func:`measure_candidate_batch` with ``measure`` mapped
    over the frame's candidates.
    """
    return measure_candidate_batch(frame, options, lambda cands: [measure(c) for c in cands],
                                   boxes_fn=boxes_fn)


def measure_candidate_batch(
    frame: Frame, options: DetectorOptions, measure: BatchMeasureFn, *,
    boxes_fn: BoxesFn = coarse_boxes,
) -> Blobs:
    """Run ``measure`` on all the candidates of ``frame`` at once; ``None`` results are dropped.

    ``measure`` takes the frame's candidates and returns one row (or ``None``) per
    candidate, in their order. A blob measured twice (reached from two coarse boxes,
    e.g. a faint spot whose coarse footprint fell apart) is kept once: of two centres
    closer than the larger spot sigma (at least 1 px), the one with more flux stays.
    """
    cands, reason, note = search_candidates(frame, options, boxes_fn=boxes_fn)
    if reason:
        return Blobs.empty(reason)
    rows = [r for r in measure(cands) if r is not None]
    if not rows:
        return Blobs.empty("no candidate could be measured")
    kept: list[tuple[float, float, np.ndarray, float, float, float]] = []
    for r in sorted(rows, key=lambda r: -r[3]):
        if all(math.hypot(r[0] - k[0], r[1] - k[1]) >= max(1.0, r[4], k[4]) for k in kept):
            kept.append(r)
    return Blobs.stack(kept, note=note, gain_dn_per_e=cands[0].gain_dn_per_e)
