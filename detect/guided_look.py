"""Guided second look: the empty ring slots searched again, in the beacon's own colour.

The full-frame significance search (:mod:`~deckpose.detect.significance`) looks at
millions of positions of the channel-sum image, so it needs a high threshold to keep
noise out, and a beacon whose light is in one channel (the red bow) stands lower
there than in its own channel. Once the ring's homography is known
(:class:`~deckpose.detect.identification.Identification` ``ring_homography``, fitted
from the ring beacons found, with or without the bow), every empty ring slot and a
missing centre have a predicted position, and a search of a few pixels around each
can afford a lower threshold and the beacon's colour:

* **Statistic.** For a colour template ``a`` (channel shares of the beacon's light:
  the layout's ``bow_rgb`` or ``beacon_rgb``) the channels are combined with the
  matched weights ``w_c = a_c / sigma_c^2`` (``sigma_c``: the channel's pixel noise, the
  larger of the frame's, :func:`channel_noise`, and that of the window's outer part, where
  a lit or textured deck has more), less each channel's background (a clipped mean of the
  window's outer part, ``N_bg`` pixels), and correlated with the pixel-integrated
  Gaussian ``g`` of the ring's spot size. On noise alone, at each position,

  ``T = sum(g y) / (sigma_y sqrt(|g|^2 + (sum g)^2 / N_bg))``,  ``sigma_y^2 = sum w_c^2 sigma_c^2``,

  is a standard normal (the background's own error counted), a spot of integrated
  SNR ``S`` in that combination gives ``T`` close to ``S``.
* **Threshold.** The search looks at ``n`` positions in all (the integer pixels within
  the search radius of each prediction, once per template). The union bound caps its
  false alarms per frame at ``n Q(t)``; setting that to :data:`FALSE_ALARM_PER_FRAME`
  gives ``t = Q^-1(FALSE_ALARM_PER_FRAME / n)``: for 4 empty slots of 45 positions
  (:func:`search_positions` of 3 px, counted generously) ``t = 4.39``, and 4.54 with two
  templates each (the bow missing). The full-frame search had 1 false detection in 144
  frames of 8 MP (``reports/detectors_independent/frames48``): about 7e-3 per frame,
  so the second look adds at most a seventh of that.
* **Search radius.** The prediction's error is about the ring blobs' RMS residual
  from the homography's predictions, ``r_rms``; the search reaches
  ``3 + 4 r_rms`` px (at most :data:`MAX_SEARCH_RADIUS_PX`).

A spot found becomes a candidate like a significance-search spot
(:func:`~deckpose.detect.candidates.spot_window`, the channel sum above a plane) and is
measured by the detector's own kernel
(:func:`~deckpose.detect.registry.register_kernel`): its centre and covariance are the
detector's, as for every other blob.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.detect.background import clipped_mean, clipped_std_rows, saturation_level
from deckpose.detect.candidates import spot_window, window_candidate
from deckpose.detect.colour import blob_rgb_flux, redness
from deckpose.detect.identification import Identification, IdentifyOptions
from deckpose.detect.registry import BlobRow, Blobs, DetectorOptions, KernelFn
from deckpose.detect.ring_homography import apply_homography
from deckpose.detect.search_noise import clipped_difference_noise
from deckpose.detect.synthetic import pixel_fractions
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray
from scipy.special import ndtri

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout

__all__ = [
    "FALSE_ALARM_PER_FRAME",
    "GuidedSpot",
    "LookResult",
    "channel_noise",
    "guided_threshold",
    "look_again",
    "search_positions",
    "search_windows",
    "slot_predictions",
]

FloatArray = NDArray[np.float64]

#: Largest probability that the second look finds a spot in a frame's empty slots on
#: noise alone (union bound over its positions; see the module docstring).
FALSE_ALARM_PER_FRAME = 1e-3
#: The search radius around a prediction, pixels: at least this ...
MIN_SEARCH_RADIUS_PX = 3.0
#: ... and at most this.
MAX_SEARCH_RADIUS_PX = 10.0
#: Pixel pairs per channel of :func:`channel_noise`: the noise's relative standard error is
#: about ``1 / sqrt(2 x 10,000) = 0.7 %`` (T's scale, a shift of 0.03 sigma at 4.4 sigma).
NOISE_SAMPLES = 10_000
#: A spot found is at most this many times the size (``size_px``) of the ring's largest
#: spot found: the same optics from about the same range (the independent generator draws
#: each beacon's sigma from 0.8-2.5 px, a 3x range, so 2x the largest of 12 draws, about
#: 2.4 px, covers it; a fit's size at SNR 8 errs by up to ~1.7x).
MAX_SIZE_RATIO = 2.0
#: Width of the window's outer part whose clipped mean is the background, pixels.
BACKGROUND_MARGIN_PX = 8


@dataclass(frozen=True)
class GuidedSpot:
    """A significant spot the second look found near a prediction.

    Attributes
    ----------
    u_px, v_px : float
        Its highest matched-filter pixel, distorted pixels.
    z : float
        Its statistic ``T`` there (noise sigmas).
    template : int
        Which colour template found it (an index into the templates searched).
    slot : int
        The ring slot it was predicted for (the homography's numbering), ``-1``: the centre.
    """

    u_px: float
    v_px: float
    z: float
    template: int
    slot: int


@dataclass(frozen=True)
class LookResult:
    """What the second look adds to a frame's blobs.

    Attributes
    ----------
    rows : list of BlobRow
        The new blobs, measured by the detector's kernel.
    note : str
        What it found but did not add (several red spots where one bow is missing); "".
    """

    rows: list[BlobRow]
    note: str = ""


def guided_threshold(n_positions: int, false_alarm: float = FALSE_ALARM_PER_FRAME) -> float:
    """Threshold ``t`` (noise sigmas) with ``n_positions Q(t) = false_alarm``.

    Parameters
    ----------
    n_positions : int
        Positions searched in the frame, all windows and templates together.
    false_alarm : float
        Largest probability of a spot found on noise alone per frame.
    """
    if n_positions < 1 or not 0 < false_alarm < 1:
        raise ValueError(f"need n_positions >= 1 and 0 < false_alarm < 1, got {n_positions}, {false_alarm}")
    return float(-ndtri(false_alarm / n_positions))


def channel_noise(image: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """Each channel's background level and pixel noise, DN, ((C,), (C,)).

    The noise is :func:`~deckpose.detect.search_noise.clipped_difference_noise` of the
    channel (horizontal pixel differences, a clipped standard deviation, which keeps
    the rounding's variance on a quantised frame), and on an integer image at least
    ``sqrt(1/12)`` DN: the variance of rounding to the 1-DN step, which no stored
    integer frame is without (a flat background of a whole DN reads as no noise).
    """
    a = np.asarray(image)
    chans = [a] if a.ndim == 2 else [a[..., c] for c in range(a.shape[2])]
    floor = math.sqrt(1.0 / 12.0) if np.issubdtype(a.dtype, np.integer) else 0.0
    h, w = a.shape[:2]
    step = max(1, int(math.sqrt(h * w / NOISE_SAMPLES)))
    bg = np.array([float(np.median(ch[::step, ::step])) for ch in chans])
    noise = np.array([max(clipped_difference_noise(ch, NOISE_SAMPLES), floor) for ch in chans])
    return bg, noise


def slot_predictions(
    ident: Identification, layout: DeckLayout, camera: CameraModel, points_px: FloatArray
) -> tuple[FloatArray, NDArray[np.int64], float]:
    """Predicted image positions of the empty ring slots and a missing centre.

    Parameters
    ----------
    ident : Identification
        With ``ring_homography`` (one-ring identification that fitted the ring).
    layout : DeckLayout
    camera : CameraModel
    points_px : (N, 2) array of float
        The detections ``ident`` is of, distorted pixels.

    Returns
    -------
    positions_px : (k, 2) array of float
        Distorted pixels, inside the frame.
    slots : (k,) array of int64
        The ring slot of each (``-1``: the centre).
    resid_px : float
        RMS distance of the ring blobs from the homography's predictions, pixels.
    """
    H, slot = ident.ring_homography, ident.ring_slot
    if H is None or slot is None:
        return np.zeros((0, 2)), np.zeros(0, np.int64), math.nan
    n = layout.n_ring
    ang = 2 * np.pi * np.arange(n) / n
    pred = apply_homography(H, np.column_stack([np.cos(ang), np.sin(ang)]))
    on = np.flatnonzero(slot >= 0)
    und = camera.undistort(np.asarray(points_px, float)[on])
    resid = float(np.sqrt(np.mean(np.sum((und - pred[slot[on]]) ** 2, axis=1)))) if on.size else math.nan
    empty = np.setdiff1d(np.arange(n), slot[on])
    want = [pred[empty]]
    slots = list(empty)
    if layout.has_centre and layout.n_ring not in ident.beacon_ids:
        want.append(apply_homography(H, np.zeros((1, 2))))
        slots.append(-1)
    und_pred = np.vstack(want)
    # undistorted pixels back through the lens: the ray of K^-1 (u, v, 1)
    rays = np.column_stack([und_pred, np.ones(und_pred.shape[0])]) @ np.linalg.inv(camera.K).T
    pos = camera.project(rays) if und_pred.shape[0] else np.zeros((0, 2))
    inside = camera.in_image(pos) if pos.shape[0] else np.zeros(0, bool)
    return pos[inside], np.asarray(slots, np.int64)[inside], resid


def _kernel(sigma_px: float) -> FloatArray:
    """Pixel-integrated Gaussian of ``sigma_px`` centred on a pixel, (k, k), sum ~1."""
    half = math.ceil(3.0 * sigma_px)
    x = np.arange(-half, half + 1, dtype=float)
    p = pixel_fractions(0.0, sigma_px, x)
    return np.outer(p, p)


def search_windows(
    image: np.ndarray,
    positions_px: FloatArray,
    radius_px: float,
    sigma_px: float,
    templates: FloatArray,
    noise_dn: FloatArray,
    threshold: float,
) -> list[GuidedSpot]:
    """The spots above ``threshold`` near each position, in each colour template.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array
    positions_px : (k, 2) array of float
        Predicted ``(u, v)``, pixels.
    radius_px : float
        Integer pixels within this distance of a prediction are searched.
    sigma_px : float
        Spot sigma of the matched filter, pixels.
    templates : (m, C) array of float
        Channel shares of each colour searched for (rows need not sum to 1).
    noise_dn : (C,) array of float
        Pixel noise per channel, DN (:func:`channel_noise`); in each window the outer
        part's own (pixel differences), where larger.
    threshold : float
        Noise sigmas of ``T`` (:func:`guided_threshold`).

    Returns
    -------
    list of GuidedSpot
        At most one per position and template: its highest ``T``, when above ``threshold``
        (``slot`` is the position's index here).
    """
    img = np.asarray(image)
    H, W = img.shape[:2]
    C = 1 if img.ndim == 2 else img.shape[2]
    g = _kernel(sigma_px)
    kh = g.shape[0] // 2
    tmpl = np.asarray(templates, float).reshape(-1, C)
    noise = np.asarray(noise_dn, float).reshape(C)
    sum_g, g2 = float(g.sum()), float(np.sum(g**2))
    r_in = radius_px + kh  # the spot's light reaches this far from the prediction
    half = math.ceil(r_in) + BACKGROUND_MARGIN_PX
    out: list[GuidedSpot] = []
    for k, (u, v) in enumerate(np.asarray(positions_px, float).reshape(-1, 2)):
        iu, iv = round(u), round(v)
        u0, v0 = max(0, iu - half), max(0, iv - half)
        u1, v1 = min(W, iu + half + 1), min(H, iv + half + 1)
        block = img[v0:v1, u0:u1].astype(np.float64).reshape(v1 - v0, u1 - u0, C)
        vv, uu = np.mgrid[v0:v1, u0:u1]
        d = np.hypot(uu - u, vv - v)
        outer = d > r_in
        n_bg = int(outer.sum())
        if n_bg < 50:
            continue
        bg = clipped_mean(block[outer])
        # the pixel noise where the window is (a brighter, textured deck has more than the
        # frame's dark sky): the larger of the frame's and the outer part's, per channel
        pair = outer[:, 1:] & outer[:, :-1]
        diffs = (block[:, 1:] - block[:, :-1])[pair]
        local = clipped_std_rows(diffs.T) / math.sqrt(2.0) if pair.sum() >= 50 else np.zeros(C)
        noise_k = np.maximum(noise, local)
        wts = tmpl / noise_k[None, :] ** 2  # (m, C) matched channel weights
        sig_y = np.sqrt((wts**2 * noise_k[None, :] ** 2).sum(axis=1))  # (m,)
        for t in range(tmpl.shape[0]):
            y = ((block - bg[None, None, :]) * wts[t][None, None, :]).sum(axis=2)
            # correlation with g at every pixel whose kernel lies in the block
            sw = sliding_window_view(y, g.shape)
            corr = np.einsum("ijkl,kl->ij", sw, g)
            cu, cv = uu[kh : kh + corr.shape[0], kh : kh + corr.shape[1]], vv[
                kh : kh + corr.shape[0], kh : kh + corr.shape[1]]
            near = np.hypot(cu - u, cv - v) <= radius_px
            if not near.any():
                continue
            z = corr / (sig_y[t] * math.sqrt(g2 + sum_g**2 / n_bg))
            zi = np.where(near, z, -np.inf)
            j = np.unravel_index(int(np.argmax(zi)), zi.shape)
            if zi[j] > threshold:
                out.append(GuidedSpot(float(cu[j]), float(cv[j]), float(zi[j]), t, k))
    return out


def search_positions(radius_px: float) -> int:
    """Integer pixel offsets within ``radius_px`` of a point (at worst; the count searched)."""
    r = math.floor(radius_px)
    x = np.arange(-r - 1, r + 2)
    return int(np.count_nonzero(np.hypot(x[:, None], x[None, :]) <= radius_px + 0.5 * math.sqrt(2)))


def look_again(
    image: np.ndarray,
    camera: CameraModel,
    blobs: Blobs,
    ident: Identification,
    rgb_flux: FloatArray,
    layout: DeckLayout,
    kernel: KernelFn,
    options: DetectorOptions,
    identify_options: IdentifyOptions,
) -> LookResult:
    """The blobs the guided second look adds to a frame (see the module docstring).

    Runs when the identification fitted the ring (``ring_homography``) on a colour
    frame and a ring slot or the centre is empty. When the bow was not identified,
    each empty ring slot is searched in the bow's colour and in the white beacons'; a
    spot whose colour is distinctly red (its red share above the ring blobs' median by
    ``min_red_margin``, as identification asks) is the bow only when it is the only one;
    with several, none is added and the note says so. When the frame was identified,
    white spots alone are added (a red one is no beacon of an empty white slot).

    Parameters
    ----------
    image : (H, W, 3) array
    camera : CameraModel
    blobs : Blobs
        The detector's blobs, ``ident``'s detections.
    ident : Identification
    rgb_flux : (N, 3) array of float
        Per-channel flux of each blob (:func:`~deckpose.detect.colour.blob_rgb_flux`).
    layout : DeckLayout
    kernel : callable
        The detector's candidate kernel.
    options : DetectorOptions
    identify_options : IdentifyOptions
    """
    img = np.asarray(image)
    if img.ndim != 3 or ident.ring_slot is None:
        return LookResult([])
    pos, slots, resid = slot_predictions(ident, layout, camera, blobs.points_px)
    if pos.shape[0] == 0:
        return LookResult([])
    bg, noise = channel_noise(img)
    if float(bg.sum()) < 0.5:
        # as the significance search: a frame whose background is under half a DN has no
        # Gaussian noise to judge significance by
        return LookResult([])
    radius = float(np.clip(MIN_SEARCH_RADIUS_PX + 4.0 * (resid if math.isfinite(resid) else 0.0),
                           MIN_SEARCH_RADIUS_PX, MAX_SEARCH_RADIUS_PX))
    # a prediction that already has a detection near it is not empty
    if len(blobs):
        dmin = np.min(np.linalg.norm(pos[:, None, :] - blobs.points_px[None], axis=2), axis=1)
        pos, slots = pos[dmin > radius + 2.0], slots[dmin > radius + 2.0]
    if pos.shape[0] == 0:
        return LookResult([])
    ring = ident.ring_slot >= 0
    sigma = float(np.clip(np.median(blobs.size_px[ring]) if ring.any() else 1.5, 0.7, 4.0))
    white = np.asarray(layout.beacon_rgb, float)
    red = np.asarray(layout.bow_rgb, float)
    bow_missing = not ident.ok
    templates = np.vstack([white / white.sum(), red / red.sum()]) if bow_missing else (white / white.sum())[None]
    # the centre is searched in white alone
    n_pos = search_positions(radius) * (int(np.count_nonzero(slots >= 0)) * templates.shape[0]
                                        + int(np.count_nonzero(slots < 0)))
    thr = guided_threshold(n_pos)
    spots = search_windows(img, pos, radius, sigma, templates, noise, thr)
    spots = [s for s in spots if not (slots[s.slot] < 0 and s.template > 0)]
    # one candidate per position: its most significant template's peak
    best: dict[int, GuidedSpot] = {}
    for s in spots:
        if s.slot not in best or s.z > best[s.slot].z:
            best[s.slot] = s
    if not best:
        return LookResult([])
    sat = saturation_level(img)
    noise_sum = float(math.sqrt(np.sum(noise**2)))
    gain = blobs.gain_dn_per_e if math.isfinite(blobs.gain_dn_per_e) else (options.gain_dn_per_e or 1.0)
    cands, at = [], []
    for k, s in best.items():
        found = spot_window(img, s.u_px, s.v_px, max(2.0, 2.0 * sigma), noise_sum, sat)
        if found is not None:
            cands.append(window_candidate(found[0], gain, img.shape[:2]))
            at.append(k)
    rows_all = kernel(cands, options) if cands else []
    rows: list[BlobRow] = []
    # A beacon of this ring is seen through the same optics from about the same range as
    # the ring's others: its spot is at most MAX_SIZE_RATIO times the largest of theirs. A
    # broad bump is no beacon (a painted-out beacon's glow on a rendered frame measured
    # 2.4-3.1x the ring's largest spot).
    max_size = MAX_SIZE_RATIO * float(np.max(blobs.size_px[ring])) if ring.any() else math.inf
    for k, r in zip(at, rows_all):
        # the kernel's centre stays near the prediction (a spot's own, not a neighbour's)
        if (r is not None and math.hypot(r[0] - pos[k, 0], r[1] - pos[k, 1]) <= radius + sigma
                and r[4] <= max_size):
            rows.append(r)
    if not rows:
        return LookResult([])
    pts = np.array([[r[0], r[1]] for r in rows])
    rgb_new = blob_rgb_flux(img, pts, np.maximum(2.0, 2.0 * np.array([r[4] for r in rows])))
    ring_red = redness(np.asarray(rgb_flux, float).reshape(-1, 3)[ring])
    base = float(np.nanmedian(ring_red)) if np.isfinite(ring_red).any() else math.nan
    is_red = redness(rgb_new) - base >= identify_options.min_red_margin
    whites = [r for r, red_ in zip(rows, is_red) if not red_]
    reds = [r for r, red_ in zip(rows, is_red) if red_]
    if bow_missing and len(reds) == 1:
        return LookResult(whites + reds)
    note = ""
    if bow_missing and len(reds) > 1:
        note = (f"second look: {len(reds)} red spots in empty ring slots, so none is taken "
                "as the bow")
    return LookResult(whites, note)
