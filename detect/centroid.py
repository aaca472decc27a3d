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
  symmetric spot); a bright unclipped spot's last pass weighs the window's pixels
  by their noise (:func:`noise_weight`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.clipped_phase import clipped_phase_cov, spot_aspect
from deckpose.detect.gaussian_window import matched_centroid
from deckpose.detect.registry import BlobRow


def truncated_m2_fraction(k: float) -> float:
    """Per-axis second moment of a 2-D Gaussian truncated at radius ``k`` sigma, over sigma^2."""
    e = math.exp(-k * k / 2.0)
    return (1.0 - (1.0 + k * k / 2.0) * e) / (1.0 - e)


def binary_centroid(cand: Candidate) -> BlobRow:
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
) -> BlobRow | None:
    """Iterated, soft-windowed intensity centroid of one candidate (``None`` if degenerate).

    A batch of one of :func:`cog_centroids`, which has the method. Measuring a frame's
    candidates one at a time this way costs 2-3x one call with all of them (each batch
    carries its iteration's bookkeeping; a bright 8 MP spot: ~1.9 against ~0.5 ms).
    """
    return cog_centroids([cand], window_sigma, max_iter, tol_px, above_floor=above_floor)[0]


def cog_centroids(
    cands: Sequence[Candidate],
    window_sigma: float = 3.0,
    max_iter: int = 30,
    tol_px: float = 1e-4,
    *,
    above_floor: bool = True,
    covariance: bool = True,
) -> list[BlobRow | None]:
    """Iterated, soft-windowed intensity centroid of each candidate, (K,) rows (``None`` if degenerate).

    The window is a disc of radius ``window_sigma * sigma`` whose edge pixels are
    weighted by their approximate coverage; ``sigma`` is re-estimated from the
    windowed second moment (corrected for the truncation) at each iteration. The
    iterations of all the candidates run together (:func:`_windowed_centroids`: one
    set of array operations per iteration for the frame, not one per candidate).

    The signal is first the candidate's own (:meth:`Candidate.signal`: above its
    pedestal for a bright spot). A bright spot whose core is not clipped
    (``clip_signal`` and no saturated core pixel) is then measured again from that
    result, above its floor (:meth:`Candidate.above_floor`: the level its wings fall
    to, such as the beacon's dark housing), so its wings count: above the deck's
    pedestal, the wings of a rendered 80 m beacon at dusk were cut and cog was
    1.50x the centroid CRB (1.14x above the floor, reports/detectors_crb/). In this
    second pass the spot sigma may grow to at most :data:`FLOOR_SIGMA_GROWTH` times
    the first pass's, so lit deck reaching into a window around a small housing
    cannot widen the window without end. Its centre is then measured once more through
    that disc with each pixel weighed by its noise (:func:`noise_weight`: the spot's
    expected signal over its variance, for a Gaussian of the floor pass's flux and
    sigma), so that wings below the noise (read noise, the background's shot noise, the
    rounding) count as little as they tell: a 3-sigma disc weighs them by their offset,
    and on 8-bit RGB frames whose 30 e background rounds to 0 DN cog was 1.32x the
    bound there (0.96x weighed; benchmarks/bench_independent.py, rgb8_dark). Where
    photons dominate the disc the weights are near 1 and the centre is the disc's; the
    flux and size stay the disc's. ``above_floor=False`` keeps the first pass.
    An unclipped spot found by its significance (not ``clip_signal``) is measured
    through a Gaussian window instead (:func:`~deckpose.detect.gaussian_window.matched_centroid`). ``covariance=False``
    leaves the rows' covariances NaN (for a caller that reads the centres, fluxes and
    sizes alone: they are the same either way).

    A clipped core's covariance also holds its pixel-phase error
    (:func:`~deckpose.detect.clipped_phase.clipped_phase_cov`, from its saturated pixels,
    their signal and the window's flux): a deterministic error of the centroid of a
    clipped plateau that the noise's covariance does not hold. A spot without a
    saturated pixel in its blob pays nothing and its covariance is unchanged.
    """
    if max_iter < 0:
        raise ValueError(f"max_iter must be >= 0, got {max_iter}")
    rows: list[BlobRow | None] = [None] * len(cands)
    disc: list[int] = []
    signals: list[np.ndarray] = []
    starts: list[tuple[float, float, float, float]] = []
    for i, cand in enumerate(cands):
        s_full = cand.signal()
        if not cand.clip_signal and not cand.saturated[cand.mask].any():
            rows[i] = matched_centroid(cand, s_full, covariance)
            continue
        ms = np.where(cand.mask, s_full, 0.0)
        F = ms.sum()
        if not F > 0:
            continue
        vv0, uu0 = np.nonzero(cand.mask)
        wts = ms[vv0, uu0]
        u = float((wts * uu0).sum() / F) + cand.u0
        v = float((wts * vv0).sum() / F) + cand.v0
        h, w = s_full.shape
        sigma_max = 0.5 * min(h, w) / window_sigma + 1.0
        disc.append(i)
        signals.append(s_full)
        starts.append((u, v, cand.mask_sigma(), sigma_max))
    if not disc:
        return rows
    # a bright spot whose core is not clipped is measured again above its floor (below), so its
    # first pass needs no covariance
    measured_again = np.array([above_floor and cands[i].clip_signal and not cands[i].saturated[cands[i].mask].any()
                               for i in disc])
    first = _windowed_centroids([cands[i] for i in disc], signals, np.array(starts),
                                window_sigma, max_iter, tol_px, cov_of=covariance & ~measured_again)
    again: list[int] = []
    floors: list[np.ndarray] = []
    restarts: list[tuple[float, float, float, float]] = []
    for k, i in enumerate(disc):
        row = rows[i] = first[k]
        cand = cands[i]
        if row is None or not measured_again[k]:
            continue
        u, v, _, _, sigma, _ = row
        floors.append(np.maximum(cand.above_floor(u, v, window_sigma * sigma + 2.0)[0], 0.0))
        restarts.append((u, v, sigma, min(starts[k][3], FLOOR_SIGMA_GROWTH * sigma)))
        again.append(i)
    if again:
        # the disc's covariance only where the noise-weighed pass fails (below)
        second = _windowed_centroids([cands[i] for i in again], floors, np.array(restarts),
                                     window_sigma, max_iter, tol_px, cov_of=np.zeros(len(again), bool))
        for i, row in zip(again, second):
            rows[i] = row
        kept = _weigh_by_noise(cands, again, floors, rows, window_sigma, max_iter, tol_px, covariance)
        if covariance and kept:
            redo = _windowed_centroids([cands[again[k]] for k in kept], [floors[k] for k in kept],
                                       np.array([restarts[k] for k in kept]), window_sigma, max_iter, tol_px)
            for k, row in zip(kept, redo):
                rows[again[k]] = row
    if covariance:
        _add_clipped_phase_cov(cands, signals, disc, rows)
    return rows


def _weigh_by_noise(
    cands: Sequence[Candidate], again: Sequence[int], floors: Sequence[np.ndarray],
    rows: list[BlobRow | None], window_sigma: float, max_iter: int, tol_px: float, covariance: bool,
) -> list[int]:
    """Re-measure the centres of the floor pass through its disc weighed by each pixel's noise, in place.

    The floor pass's centre, sigma and flux give each spot's model (a Gaussian of that flux
    and sigma), and :func:`noise_weight` its pixels' weights within the disc; the flux and
    size stay the disc's. Where photons dominate the whole disc (a bright 16-bit spot) the
    weights are near 1 and the centre is the disc's. Returns the positions in ``again``
    whose floor-pass row is kept (this pass degenerate: the step ran off the frame).
    """
    done = [(k, i, disc) for k, i in enumerate(again) if (disc := rows[i]) is not None]
    if not done:
        return []
    starts = np.array([(d[0], d[1], d[4], d[4]) for _, _, d in done])
    amplitude = np.array([d[3] for _, _, d in done]) / (2.0 * math.pi * starts[:, 2] ** 2)
    weighed = _windowed_centroids([cands[i] for _, i, _ in done], [floors[k] for k, _, _ in done], starts,
                                  window_sigma, max_iter, tol_px, cov_of=np.full(len(done), covariance),
                                  amplitude_dn=amplitude)
    kept = []
    for (k, i, disc), row in zip(done, weighed):
        if row is not None:
            rows[i] = (row[0], row[1], row[2], disc[3], disc[4], disc[5])
        else:
            kept.append(k)
    return kept


def _add_clipped_phase_cov(
    cands: Sequence[Candidate], signals: Sequence[np.ndarray], disc: Sequence[int],
    rows: list[BlobRow | None],
) -> None:
    """Add the clipped cores' pixel-phase covariance to their rows, in place (all of them at once).

    ``disc`` are the candidates measured through the disc window and ``signals`` their
    signals (the first pass's, which a clipped core keeps: it is not measured again above
    its floor). The clip level is the median signal of the blob's saturated pixels, the
    spot's aspect that of its signal's second moments over the blob (:func:`spot_aspect`).
    """
    clipped: list[tuple[int, BlobRow]] = []
    clip, n_sat, aspect = [], [], []
    for k, i in enumerate(disc):
        row = rows[i]
        sat = cands[i].saturated & cands[i].mask
        if row is None or not sat.any():
            continue
        clipped.append((i, row))
        clip.append(float(np.median(signals[k][sat])))
        n_sat.append(int(np.count_nonzero(sat)))
        aspect.append(spot_aspect(signals[k], cands[i].mask))
    if not clipped:
        return
    terms = clipped_phase_cov(np.array(clip), np.array(n_sat), np.array([r[3] for _, r in clipped]),
                              np.array(aspect))
    for (i, (u, v, cov, f, size, score)), term in zip(clipped, terms):
        rows[i] = (u, v, cov + term, f, size, score)


def _windowed_centroids(
    cands: Sequence[Candidate],
    signals: Sequence[np.ndarray],
    starts: np.ndarray,
    window_sigma: float,
    max_iter: int,
    tol_px: float,
    *,
    cov_of: np.ndarray | None = None,
    amplitude_dn: np.ndarray | None = None,
) -> list[BlobRow | None]:
    """The iteration of :func:`cog_centroids` on the signal of each candidate, all together.

    Parameters
    ----------
    cands : sequence of K Candidate
    signals : sequence of K arrays of float, each its candidate's window shape
        The signal to measure, DN.
    starts : (K, 4) array of float
        Start ``u, v`` (pixels), start spot sigma and the largest sigma, pixels.
    window_sigma, max_iter, tol_px
        As :func:`cog_centroids`.
    cov_of : (K,) array of bool, optional
        The candidates whose covariance is computed (default all); the others' are NaN (the
        centres, fluxes and sizes do not depend on them).
    amplitude_dn : (K,) array of float, optional
        Weigh the disc by each pixel's noise (:func:`noise_weight`) for a Gaussian spot of this
        peak, DN, and the start sigma, which then stays fixed; the centre moves by Newton steps
        of the weighted centroid's equation, whose slope also scales the covariance. Default:
        the disc alone, its sigma re-estimated at each iteration.

    Returns
    -------
    list of K BlobRow or None
        ``None`` where the candidate is degenerate (no flux in its window, or the frame
        edge cuts it within a sigma).

    Notes
    -----
    The windows are stacked, zero-padded, and each iteration gathers, for every
    candidate still iterating, the square around its current disc (the pixels
    of its own window there; the padding's zeros beyond), so its sums are those of
    one candidate alone, added in another order.
    """
    K = len(cands)
    hs = np.array([s.shape[0] for s in signals])
    ws = np.array([s.shape[1] for s in signals])
    Hp, Wp = int(hs.max()) + 1, int(ws.max()) + 1  # one zero row and column past every window
    stack = np.zeros((K, Hp, Wp))
    for k, s in enumerate(signals):
        stack[k, : s.shape[0], : s.shape[1]] = s
    flat = stack.ravel()
    u0 = np.array([c.u0 for c in cands], float)
    v0 = np.array([c.v0 for c in cands], float)
    shape = np.array([c.frame_shape if c.frame_shape is not None else (np.inf, np.inf)
                      for c in cands], float)
    u, v, sigma, sigma_max = (np.array(starts[:, j], float) for j in range(4))
    m2_frac = truncated_m2_fraction(window_sigma)
    # the noise weight's level: where a pixel's signal variance equals its noise's, DN (a zero
    # gain: inf, no weight, a degenerate row)
    k_dn = np.zeros(K)
    if amplitude_dn is not None:
        with np.errstate(divide="ignore"):
            k_dn = np.array([c.noise_dn**2 for c in cands]) / np.array([c.gain_dn_per_e for c in cands])
    rows: list[BlobRow | None] = [None] * K
    act = np.arange(K)
    for it in range(max_iter + 1):
        ua, va, sa = u[act], v[act], sigma[act]
        R = window_sigma * sa
        # Candidate.edge_distance_px: where the frame edge cuts the disc on one side, shrink
        # it to the largest disc inside the frame, which stays symmetric about the spot (and
        # keep sigma, which a truncated moment would shrink). Less than one sigma of it: the
        # spot cannot be measured without a bias.
        fh, fw = shape[act, 0], shape[act, 1]
        with np.errstate(invalid="ignore"):  # inf - inf where the frame shape is not known
            edge = np.minimum(np.minimum(ua + 0.5, va + 0.5), np.minimum(fw - 0.5 - ua, fh - 0.5 - va))
        edge = np.where(np.isfinite(fh), edge, np.inf)
        cut = R > edge
        R = np.where(cut, edge, R)
        # the square around the current window, within the candidate's own window
        c0 = np.maximum(0, np.floor(ua - u0[act] - R - 1)).astype(np.intp)
        c1 = np.minimum(ws[act], np.ceil(ua - u0[act] + R + 2)).astype(np.intp)
        r0 = np.maximum(0, np.floor(va - v0[act] - R - 1)).astype(np.intp)
        r1 = np.minimum(hs[act], np.ceil(va - v0[act] + R + 2)).astype(np.intp)
        # degenerate: cut within a sigma, or the estimate left the candidate's window
        ok = ~(cut & (edge < sa)) & (c1 > c0) & (r1 > r0)
        if not ok.all():
            act, ua, va, sa, R, c0, c1, r0, r1 = (a[ok] for a in (act, ua, va, sa, R, c0, c1, r0, r1))
            cut = cut[ok]
        if act.size == 0:
            break
        cols = c0[:, None] + np.arange(int((c1 - c0).max()))
        rws = r0[:, None] + np.arange(int((r1 - r0).max()))
        c_in, r_in = cols < c1[:, None], rws < r1[:, None]
        at = ((act[:, None, None] * Hp + np.where(r_in, rws, Hp - 1)[:, :, None]) * Wp
              + np.where(c_in, cols, Wp - 1)[:, None, :])
        s = flat[at]  # (n, rows, cols); the padding's zeros outside each square
        du1 = cols + u0[act][:, None] - ua[:, None]  # (n, cols)
        dv1 = rws + v0[act][:, None] - va[:, None]  # (n, rows)
        du, dv = du1[:, None, :], dv1[:, :, None]
        d2 = du * du + dv * dv
        r = np.sqrt(d2)
        win = np.minimum(np.maximum(R[:, None, None] + 0.5 - r, 0.0), 1.0)
        wn = None if amplitude_dn is None else noise_weight(d2, amplitude_dn[act], k_dn[act], sa)
        if wn is not None:
            win = win * wn
        wsig = win * s
        # the moments from the windowed signal's column and row sums (two passes over the
        # squares instead of one per moment)
        by_col, by_row = wsig.sum(axis=1), wsig.sum(axis=2)  # (n, cols), (n, rows)
        F = by_col.sum(axis=1)
        good = F > 0  # no flux in the window: degenerate
        # the slope of the centroid's equation: F for the disc (its moving edge neglected)
        D_u, D_v = (F, F) if wn is None else _weighted_slopes(wsig, wn, s, r, R, du1, dv1, sa, F)
        with np.errstate(divide="ignore", invalid="ignore"):
            su = (by_col * du1).sum(axis=1) / D_u
            sv = (by_row * dv1).sum(axis=1) / D_v
        if amplitude_dn is not None:  # a Newton step of at most a sigma
            step = np.hypot(su, sv)
            shrink = np.minimum(1.0, sa / np.where(step > 0, step, 1.0))
            su, sv = su * shrink, sv * shrink
        done = good & ((np.hypot(su, sv) < tol_px) | (it == max_iter))
        for j in np.flatnonzero(done):
            cand = cands[act[j]]
            if cov_of is not None and not cov_of[act[j]]:
                rows[act[j]] = cand.blob(ua[j] + su[j], va[j] + sv[j], flux_dn=float(F[j]),
                                         size_px=float(sa[j]), cov_px2=np.full((2, 2), np.nan))
                continue
            inside = r_in[j][:, None] & c_in[j][None, :]
            duj, dvj = du[j] - su[j], dv[j] - sv[j]
            var = cand.variance(s[j]) * win[j] ** 2 * inside
            Du, Dv = float(D_u[j]), float(D_v[j])
            cov = np.array([[(var * duj * duj).sum() / Du**2, (var * duj * dvj).sum() / (Du * Dv)],
                            [(var * duj * dvj).sum() / (Du * Dv), (var * dvj * dvj).sum() / Dv**2]])
            # the surround's tilt left in the signal (a bright spot above its flat pedestal)
            if amplitude_dn is None:
                cov = cov + cand.surround_tilt_cov(win[j] * inside, s[j], duj, dvj, float(F[j]))
            else:  # the slopes hold the disc edge's term already
                r2 = duj * duj + dvj * dvj
                m2 = 0.5 * float((win[j] * inside * (s[j] > 0) * r2).sum())
                cov = cov + cand.surround_bias_cov(m2 / (0.5 * (Du + Dv)))
            rows[act[j]] = cand.blob(ua[j] + su[j], va[j] + sv[j], flux_dn=float(F[j]),
                                     size_px=float(sa[j]), cov_px2=cov)
        more = good & ~done
        if not more.any():
            break
        # the spot sigma from the windowed second moment, where the disc is whole (not cut
        # by the frame edge)
        m = np.flatnonzero(more)
        act = act[m]
        if amplitude_dn is None:
            d2sum = (by_col[m] * du1[m] ** 2).sum(axis=1) + (by_row[m] * dv1[m] ** 2).sum(axis=1)
            m2 = d2sum / F[m] / 2.0 - (su[m] ** 2 + sv[m] ** 2) / 2.0
            s_new = np.clip(np.sqrt(np.maximum(m2, 0.0) / m2_frac), 0.5, sigma_max[act])
            sigma[act] = np.where(cut[m], sa[m], s_new)
        u[act] = ua[m] + su[m]
        v[act] = va[m] + sv[m]
    return rows


def noise_weight(d2_px2: np.ndarray, amplitude_dn: np.ndarray, k_dn: np.ndarray,
                 sigma_px: np.ndarray) -> np.ndarray:
    """Each pixel's weight in a centroid of a Gaussian spot under shot and even noise, (n, h, w) in [0, 1).

    The centroid that is efficient to first order (the score of the spot's centre) weighs a
    pixel of expected signal ``mu`` and variance ``V = n0^2 + g mu`` by ``mu / V``, up to a
    constant: ``mu / (mu + k)`` with ``k = n0^2 / g``. Where photons dominate (``mu >> k``)
    every pixel counts the same, as in a disc; where the even noise does (the wings, and
    every pixel of a spot whose signal is below its noise: read noise, the background's shot
    noise, the rounding's 1/12 DN^2 a channel) the weight falls as the spot, a Gaussian
    window matched to it. A disc of 3 sigma weighs those wings by their offset instead: on
    8-bit RGB frames whose background rounds to 0 DN it was 1.35-1.8x the Cramér–Rao bound.

    Parameters
    ----------
    d2_px2 : (n, h, w) array of float
        Squared distance of each pixel from the spot's centre, px^2.
    amplitude_dn, k_dn, sigma_px : (n,) arrays of float
        The spot's peak ``mu(0)`` (DN), the level ``k`` (DN) and its sigma (px, the pixels'
        width included).
    """
    mu = amplitude_dn[:, None, None] * np.exp(-d2_px2 / (2.0 * sigma_px[:, None, None] ** 2))
    with np.errstate(invalid="ignore"):
        return np.where(mu > 0, mu / (mu + k_dn[:, None, None]), 0.0)


def _weighted_slopes(
    wsig: np.ndarray, wn: np.ndarray, s: np.ndarray, r: np.ndarray, R: np.ndarray,
    du1: np.ndarray, dv1: np.ndarray, sigma: np.ndarray, F: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes ``-dG/dc`` along u and v of the noise-weighted centroid's equation ``G = sum(w s (x - c)) = 0``, (n,) each.

    ``w`` is the disc (soft edge) times :func:`noise_weight`; the weight's fall gives
    ``sum(w s (1 - wn) du^2) / sigma^2`` and the disc's edge following the centre
    ``sum_edge(wn s du^2 / r)``, both less than the windowed flux ``F``. The slope is held
    to ``[F / 4, F]`` (a Gaussian window matched to its spot: ``F / 2``) so a spot far from
    the model cannot make the step or the covariance run away.
    """
    t = wsig * (1.0 - wn)
    edge = np.where(np.abs(r - R[:, None, None]) < 0.5, wn * s / np.maximum(r, 0.5), 0.0)
    inv_s2 = 1.0 / sigma**2
    D_u = F - (t.sum(axis=1) * du1**2).sum(axis=1) * inv_s2 - (edge.sum(axis=1) * du1**2).sum(axis=1)
    D_v = F - (t.sum(axis=2) * dv1**2).sum(axis=1) * inv_s2 - (edge.sum(axis=2) * dv1**2).sum(axis=1)
    return np.clip(D_u, 0.25 * F, F), np.clip(D_v, 0.25 * F, F)
