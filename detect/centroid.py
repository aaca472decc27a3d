"""The two classic centroiders, one candidate at a time: ``binary`` (the baseline) and ``cog``.

The detectors of those names (:mod:`~deckpose.detect.binary`, :mod:`~deckpose.detect.cog`)
run them on every candidate of a frame; ``gauss``, ``log`` and the gain estimate start
from :func:`cog_centroid`.

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
from deckpose.detect.candidate import Candidate

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


#: An unclipped spot's floor-based window may grow to at most this many times the
#: pedestal-based spot sigma (see :func:`cog_centroid`).
FLOOR_SIGMA_GROWTH = 1.3


def cog_centroid(
    cand: Candidate,
    window_sigma: float = 3.0,
    max_iter: int = 30,
    tol_px: float = 1e-4,
    *,
    above_floor: bool = True,
) -> Row | None:
    """Iterated, soft-windowed intensity centroid of one candidate (``None`` if degenerate).

    The window is a disc of radius ``window_sigma * sigma`` whose edge pixels are
    weighted by their approximate coverage; ``sigma`` is re-estimated from the
    windowed second moment (corrected for the truncation) at each iteration.

    The signal is first the candidate's own (:meth:`Candidate.signal`: above its
    pedestal for a bright spot). A bright spot whose core is not clipped
    (``clip_signal`` and no saturated core pixel) is then measured again from that
    result, above its floor (:meth:`Candidate.above_floor`: the level its wings fall
    to, such as the beacon's dark housing), so its wings count: above the deck's
    pedestal, the wings of a rendered 80 m beacon at dusk were cut and cog was
    1.50x the centroid CRB (1.14x above the floor, reports/detectors_crb/). In this
    second pass the spot sigma may grow to at most :data:`FLOOR_SIGMA_GROWTH` times
    the first pass's, so lit deck reaching into a window around a small housing
    cannot widen the window without end. ``above_floor=False`` keeps the first pass.
    """
    s_full = cand.signal()
    unclipped = not cand.saturated[cand.mask].any()
    if not cand.clip_signal and unclipped:
        return _matched_centroid(cand, s_full)
    ms = np.where(cand.mask, s_full, 0.0)
    F = ms.sum()
    if not F > 0:
        return None
    vv0, uu0 = np.nonzero(cand.mask)
    wts = ms[vv0, uu0]
    u = float((wts * uu0).sum() / F) + cand.u0
    v = float((wts * vv0).sum() / F) + cand.v0
    h, w = s_full.shape
    sigma_max = 0.5 * min(h, w) / window_sigma + 1.0
    row = _windowed_centroid(
        cand, s_full, u, v, cand.mask_moments()[2], window_sigma, sigma_max, max_iter, tol_px
    )
    if row is None or not above_floor or not cand.clip_signal or not unclipped:
        return row
    u, v, _, _, sigma, _ = row
    s_floor = np.maximum(cand.above_floor(u, v, window_sigma * sigma + 2.0)[0], 0.0)
    grown = min(sigma_max, FLOOR_SIGMA_GROWTH * sigma)
    return _windowed_centroid(cand, s_floor, u, v, sigma, window_sigma, grown, max_iter, tol_px)


def _matched_centroid(cand: Candidate, s_full: np.ndarray) -> Row | None:
    """Gaussian-windowed centroid of an unclipped spot found by its significance.

    The window's sigma starts from the blob's half-maximum region (of the window
    smoothed by a 1 px Gaussian: radius ``1.177 sqrt(sigma^2 + 1)``) and is refined
    twice from the windowed second moment (a Gaussian spot of sigma ``s`` seen through
    a Gaussian window of sigma ``w`` has moment ``s^2 w^2 / (s^2 + w^2)``), within
    0.7-1.4x its start so noise cannot run it away.
    """
    vv, uu = np.nonzero(cand.mask)
    wts = np.maximum(s_full[vv, uu], 0.0)
    if not wts.sum() > 0:
        return None
    u = float((wts * uu).sum() / wts.sum()) + cand.u0
    v = float((wts * vv).sum() / wts.sum()) + cand.v0
    r_half = math.sqrt(vv.size / math.pi)
    sigma0 = math.sqrt(max((r_half / 1.1774) ** 2 - 1.0, 0.25))
    sigma_w = sigma0
    row = None
    for _ in range(3):
        row = gaussian_window_centroid(cand, s_full, u, v, sigma_w)
        if row is None:
            return None
        u, v = row[0], row[1]
        m2 = _window_moment(cand, s_full, u, v, sigma_w)
        if not (0.0 < m2 < sigma_w * sigma_w):
            break
        s2 = m2 * sigma_w * sigma_w / (sigma_w * sigma_w - m2) - 1.0 / 12.0
        sigma_w = float(np.clip(math.sqrt(max(s2, 0.0)), 0.7 * sigma0, 1.4 * sigma0))
    return row


def _window_moment(cand: Candidate, s_full: np.ndarray, u: float, v: float, sw: float) -> float:
    """Per-axis second moment of the signal through a Gaussian window at ``(u, v)``, px^2."""
    h, w = s_full.shape
    R = 4.0 * sw
    c0, c1 = max(0, int(u - cand.u0 - R)), min(w, int(u - cand.u0 + R) + 2)
    r0, r1 = max(0, int(v - cand.v0 - R)), min(h, int(v - cand.v0 + R) + 2)
    du = (np.arange(c0, c1, dtype=float) + cand.u0 - u)[None, :]
    dv = (np.arange(r0, r1, dtype=float) + cand.v0 - v)[:, None]
    ws = np.exp(-(du * du + dv * dv) / (2 * sw * sw)) * s_full[r0:r1, c0:c1]
    F = float(ws.sum())
    return float((ws * (du * du + dv * dv)).sum()) / (2.0 * F) if F > 0 else math.nan


def _windowed_centroid(
    cand: Candidate,
    s_full: np.ndarray,
    u: float,
    v: float,
    sigma: float,
    window_sigma: float,
    sigma_max: float,
    max_iter: int,
    tol_px: float,
) -> Row | None:
    """The iteration of :func:`cog_centroid` on the signal ``s_full`` (DN), from ``(u, v, sigma)``."""
    h, w = s_full.shape
    m2_frac = truncated_m2_fraction(window_sigma)
    for it in range(max_iter + 1):
        R = window_sigma * sigma
        edge = cand.edge_distance_px(u, v)
        if R > edge:
            # The frame edge cuts the disc on one side: shrink it to the largest disc
            # inside the frame, which stays symmetric about the spot (and keep sigma,
            # which a truncated moment would shrink). Less than one sigma of it: the
            # spot cannot be measured without a bias.
            if edge < sigma:
                return None
            R = edge
        # Work on the square around the current window only.
        c0 = max(0, int(np.floor(u - cand.u0 - R - 1)))
        c1 = min(w, int(np.ceil(u - cand.u0 + R + 2)))
        r0 = max(0, int(np.floor(v - cand.v0 - R - 1)))
        r1 = min(h, int(np.ceil(v - cand.v0 + R + 2)))
        if c1 <= c0 or r1 <= r0:  # the estimate left the candidate's window: degenerate
            return None
        s = s_full[r0:r1, c0:c1]
        du = (np.arange(c0, c1, dtype=float) + cand.u0 - u)[None, :]
        dv = (np.arange(r0, r1, dtype=float) + cand.v0 - v)[:, None]
        d2 = du * du + dv * dv
        # np.clip's value by two ufuncs (np.clip's dispatch costs more than the work here)
        win = np.minimum(np.maximum(R + 0.5 - np.sqrt(d2), 0.0), 1.0)
        ws = win * s
        F = ws.sum()
        if not F > 0:
            return None
        su, sv = float((ws * du).sum() / F), float((ws * dv).sum() / F)
        if it == max_iter or math.hypot(su, sv) < tol_px:
            break
        if R == window_sigma * sigma:  # a whole disc (not one cut to the frame edge)
            m2 = float((ws * d2).sum() / F) / 2.0 - (su * su + sv * sv) / 2.0
            sigma = float(np.clip(math.sqrt(max(m2, 0.0) / m2_frac), 0.5, sigma_max))
        u, v = u + su, v + sv
    else:  # only an empty loop ends without a break (the last iteration breaks)
        raise ValueError(f"max_iter must be >= 0, got {max_iter}")
    u, v = u + su, v + sv
    du, dv = du - su, dv - sv
    var = cand.variance(s) * win**2
    cov = (
        np.array(
            [
                [(var * du * du).sum(), (var * du * dv).sum()],
                [(var * du * dv).sum(), (var * dv * dv).sum()],
            ]
        )
        / F**2
    )
    # the surround's tilt left in the signal (a bright spot above its flat pedestal)
    cov = cov + cand.surround_tilt_cov(win, s, du, dv, float(F))
    return cand.blob(u, v, flux_dn=float(F), size_px=sigma, cov_px2=cov)


#: Largest step of one :func:`gaussian_window_centroid` iteration, in window sigmas.
MAX_STEP_SIGMA = 1.0


def gaussian_window_centroid(
    cand: Candidate,
    s_full: np.ndarray,
    u_px: float,
    v_px: float,
    sigma_w_px: float,
    max_iter: int = 30,
    tol_px: float = 1e-4,
) -> Row | None:
    """Gaussian-windowed centroid of an unclipped spot (the windowed position of SExtractor).

    Iterates ``c <- c + 2 sum(w I (x - c)) / sum(w I)`` with the window
    ``w = exp(-|x - c|^2 / (2 sigma_w^2))`` over the square of pixels within 4 ``sigma_w``
    of ``c`` (or, where the frame edge is nearer, within the edge distance, so the
    window stays symmetric about the spot and the edge does not pull it inward) and ``I`` the signal above the candidate's background (not clipped, so noise
    does not bias it). For a Gaussian spot of sigma ``sigma_w`` the fixed point is
    its centre and the estimate is the matched-filter centroid, close to the
    Cramér–Rao bound where the background dominates; a disc window of 3 sigma
    weighs the noisy wings as much as the core (1.5-2.7x the bound on dim spots).
    ``s_full`` is the candidate's signal, DN (h, w). ``None`` when the window's flux
    is not positive or the estimate runs away.
    """
    h, w = s_full.shape
    u, v = u_px, v_px
    inv2s2 = 1.0 / (2.0 * sigma_w_px**2)
    for it in range(max_iter + 1):
        # Pixels within 4 window sigmas, or (where the frame edge is nearer) within the
        # edge distance, so the window stays symmetric about the spot.
        R = min(4.0 * sigma_w_px, cand.edge_distance_px(u, v))
        if R < sigma_w_px:
            return None
        c0 = max(0, int(np.floor(u - cand.u0 - R)))
        c1 = min(w, int(np.ceil(u - cand.u0 + R)) + 1)
        r0 = max(0, int(np.floor(v - cand.v0 - R)))
        r1 = min(h, int(np.ceil(v - cand.v0 + R)) + 1)
        if c1 - c0 < 3 or r1 - r0 < 3:
            return None
        s = s_full[r0:r1, c0:c1]
        du = (np.arange(c0, c1, dtype=float) + cand.u0 - u)[None, :]
        dv = (np.arange(r0, r1, dtype=float) + cand.v0 - v)[:, None]
        win = np.exp(-(du * du) * inv2s2) * np.exp(-(dv * dv) * inv2s2)
        ws = win * s
        F = float(ws.sum())
        if not F > 0:
            return None
        su = 2.0 * float((ws * du).sum()) / F
        sv = 2.0 * float((ws * dv).sum()) / F
        step = math.hypot(su, sv)
        if step > MAX_STEP_SIGMA * sigma_w_px:
            su, sv = su * MAX_STEP_SIGMA * sigma_w_px / step, sv * MAX_STEP_SIGMA * sigma_w_px / step
        u, v = u + su, v + sv
        if math.hypot(u - u_px, v - v_px) > 2.0 * sigma_w_px + 1.0:
            return None
        if step < tol_px or it == max_iter:
            break
    else:  # only an empty loop ends without a break (the last iteration breaks)
        raise ValueError(f"max_iter must be >= 0, got {max_iter}")
    du = np.arange(c0, c1, dtype=float)[None, :] + cand.u0 - u
    dv = np.arange(r0, r1, dtype=float)[:, None] + cand.v0 - v
    win = np.exp(-(du * du + dv * dv) * inv2s2)
    var = cand.variance(s) * win**2
    F = float((win * s).sum())
    if not F > 0:
        return None
    cov = 4.0 * np.array(
        [
            [(var * du * du).sum(), (var * du * dv).sum()],
            [(var * du * dv).sum(), (var * dv * dv).sum()],
        ]
    ) / F**2
    # flux: the window's flux over the Gaussian window's own weight of a sigma_w spot
    return cand.blob(u, v, flux_dn=2.0 * F, size_px=sigma_w_px, cov_px2=cov)
