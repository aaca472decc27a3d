"""The ring's ellipse in the image: RANSAC over 5-point conics, and ring positions from angles on it.

The largest set of detections on one ellipse is the ring (glints, reflections and the
centre beacon lie off it). Ordered by angle in the ellipse's normalised frame, the
angular gaps (in units of ``2 pi / n``) give relative ring positions, leaving room for
missing beacons.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np
from deckpose.detect import conic as cn
from deckpose.detect.identification import IdentifyOptions
from numpy.typing import NDArray

__all__ = ["MIN_RANSAC_SAMPLES", "flux_groups", "ransac_ellipse", "relative_positions", "ring_angles"]

FloatArray = NDArray[np.float64]


def _ellipse_inliers(
    c: FloatArray, points: FloatArray, opts: IdentifyOptions
) -> tuple[NDArray[np.bool_] | None, FloatArray, float]:
    axes = cn.ellipse_semi_axes(c) if c[1] ** 2 - 4 * c[0] * c[2] < 0 else None
    if axes is None:
        return None, np.zeros(0), 0.0
    if opts.max_axis_ratio is not None and not max(axes) <= opts.max_axis_ratio * min(axes):
        return None, np.zeros(0), 0.0
    tol = max(opts.inlier_tol_px, opts.inlier_tol_frac * 0.5 * sum(axes))
    d = cn.sampson_distance(c, points)
    return d < tol, d, tol


#: Fewest RANSAC samples before the adaptive stop (which needs a 99.9 % chance of one
#: all-inlier sample given the best inlier ratio so far).
MIN_RANSAC_SAMPLES = 8


def flux_groups(flux: FloatArray, size: int) -> tuple[NDArray[np.intp], ...]:
    """Blobs of like brightness: windows of ``size`` consecutive blobs by flux, brightest first,
    half a window apart (the last one ending with the dimmest); one window when there are few.

    Parameters
    ----------
    flux : (N,) array of float
        Each blob's flux (any unit).
    size : int
        Blobs a window (the ring's count and a spare or two).

    Returns
    -------
    tuple of arrays of int
        Indices into ``flux``.
    """
    order = np.argsort(-np.asarray(flux, float), kind="stable")
    n = order.size
    if n <= size:
        return (order,)
    starts = sorted(set(range(0, n - size, max(1, size // 2))) | {n - size})
    return tuple(order[s:s + size] for s in starts)


def _ring_support(points: FloatArray, inliers: NDArray[np.bool_], ring_size: int) -> int:
    """How many of the inliers sit in whole ring steps round their ellipse (:func:`relative_positions`); 0: none."""
    conic = cn.fit_conic(points[inliers])
    ang = ring_angles(points[inliers], conic)
    found = None if ang is None else relative_positions(ang, ring_size)
    return 0 if found is None else int(found[1].sum())


def ransac_ellipse(
    points: FloatArray, opts: IdentifyOptions, max_inliers: int, ring_size: int | None = None,
    min_support: int = 5, prefer: tuple[NDArray[np.intp], ...] | None = None,
) -> NDArray[np.bool_]:
    """Largest set of points (at most ``max_inliers``) on one ellipse (boolean mask).

    With ``ring_size``, a set of which at least ``min_support`` points sit in whole steps
    of ``2 pi / ring_size`` round the ellipse (:func:`relative_positions`, spurious points
    dropped) ranks above any set that does not, and among such sets the most points so
    kept win: a cluster of glints on the sea lies on many small ellipses, often more
    points than the ring has, but not evenly round them. Under strong perspective the
    ring's own angles are uneven (the test is affine) and the largest set wins as before;
    ``min_support`` (the fewest ring blobs identification accepts) keeps a small chance
    set of evenly spaced points from outranking it there.

    ``prefer`` (groups of point indices likeliest to hold the ring together, e.g. blobs of
    like brightness): when there are more points than ``max_inliers``, each uniform sample
    is followed by one drawn from a group alone, the groups in turn (from a stream of its
    own). Among 33 blobs of which 12 are the ring, one uniform sample in 300 is all ring, and
    1,000 samples missed it in 4 % of frames (among 44, in half); the uniform samples are
    today's, so a ring in no group is found as often as before (at most twice
    ``opts.max_ransac`` samples in all).

    The samples' conics are fitted a chunk at a time (:func:`~deckpose.detect.conic.fit_conics`,
    each as alone), and the samples are then taken in their order, as one at a time: the
    adaptive stop ends the search at the same sample, and the random stream is the same
    (the chunk's samples past the stop are drawn and not used).
    """
    n = points.shape[0]
    best = np.zeros(n, bool)
    best_rank: tuple[int, float] = (0, math.inf)
    exhaustive = math.comb(n, 5) <= 100
    needed = opts.max_ransac
    tried = 0
    # The local optimisation's result (and the ring steps' support) is a function of the
    # inlier set alone: most samples of a ring share one, whose refit is made once.
    refits: dict[bytes, tuple[NDArray[np.bool_] | None, FloatArray, float, int]] = {}
    groups = tuple(g for g in prefer or () if len(g) >= 5) if n > max_inliers else ()
    preferred = groups or None
    for chunk in _sample_chunks(n, opts, exhaustive, preferred):
        for c in cn.fit_conics(points[chunk]):
            inl, d, tol = _ellipse_inliers(c, points, opts)
            if inl is None or inl.sum() <= 5:
                continue
            # Local optimisation: refit on the inliers and count again, so a conic that
            # only passes near points by the first-order distance does not win.
            key = inl.tobytes()
            if key not in refits:
                r_inl, r_d, r_tol = _ellipse_inliers(cn.fit_conic(points[inl]), points, opts)
                support = (_ring_support(points, r_inl, ring_size)
                           if ring_size is not None and r_inl is not None and min_support <= r_inl.sum() <= max_inliers
                           else 0)
                support = support if support >= min_support else 0
                refits[key] = (r_inl, r_d, r_tol, support)
            inl, d, tol, support = refits[key]
            if inl is None:
                continue
            k = int(inl.sum())
            if k < 5 or k > max_inliers:
                continue
            rank = (-support, -k + float(np.sum(np.minimum(d, tol))) / (tol * (n + 1)))
            if rank < best_rank:
                best, best_rank = inl, rank
                # Adaptive stopping: samples needed to draw one all-inlier 5-set with 99.9 %
                # (with preferred groups, every other sample is a group's, with odds of its own).
                w5 = ((support or k) / n) ** 5
                if preferred is not None:
                    w5 = 0.5 * w5 + 0.5 * float(np.mean([(int(inl[g].sum()) / len(g)) ** 5 for g in preferred]))
                needed = math.ceil(math.log(1e-3) / math.log1p(-w5)) if w5 < 1 else 1
            tried += 1
            if not exhaustive and tried >= max(needed, MIN_RANSAC_SAMPLES):
                return best
    return best


#: Samples in the first chunk of :func:`_sample_chunks`; each next chunk doubles, to
#: :data:`_MAX_CHUNK`. (A clean ring stops after 8-15 samples; a ring among other lights
#: can take hundreds.)
_FIRST_CHUNK = 16
_MAX_CHUNK = 128


def _sample_chunks(n: int, opts: IdentifyOptions, exhaustive: bool,
                   prefer: tuple[NDArray[np.intp], ...] | None = None) -> Iterator[NDArray[np.intp]]:
    """The RANSAC samples of 5 point indices, (m, 5) a chunk: every 5-set, or ``opts.max_ransac`` drawn.

    Drawn samples come from ``default_rng(opts.seed)``, one ``choice`` each, in order; with
    ``prefer``, each is followed by one drawn from a group alone (the groups in turn), by
    ``default_rng([opts.seed, 1])`` (chunks twice as long).
    """
    if exhaustive:
        combos = np.array(list(itertools.combinations(range(n), 5)), np.intp).reshape(-1, 5)
        if combos.size:
            yield combos
        return
    rng = np.random.default_rng(opts.seed)
    prefer_rng = np.random.default_rng([opts.seed, 1])
    drawn, size = 0, _FIRST_CHUNK
    while drawn < opts.max_ransac:
        m = min(size, opts.max_ransac - drawn)
        uniform = [rng.choice(n, 5, replace=False) for _ in range(m)]
        if prefer is None:
            yield np.array(uniform, np.intp)
        else:
            rows = []
            for j, u in enumerate(uniform):
                g = prefer[(drawn + j) % len(prefer)]
                rows += [u, g[prefer_rng.choice(len(g), 5, replace=False)]]
            yield np.array(rows, np.intp)
        drawn += m
        size = min(2 * size, _MAX_CHUNK)


def ring_angles(pts: FloatArray, conic: FloatArray) -> FloatArray | None:
    """Angle of each point in the ellipse's normalised (circular) frame, ccw as displayed.

    Parameters
    ----------
    pts : (K, 2) array of float
        Undistorted pixels.
    conic : (6,) array of float
        The ellipse's conic coefficients (:func:`deckpose.detect.conic.fit_conic`).

    Returns
    -------
    (K,) array of float, radians, or None
        None when the conic is no ellipse.
    """
    M = cn.ellipse_shape(conic)
    if M is None:
        return None
    w, V = np.linalg.eigh(M)
    L = V @ np.diag(np.sqrt(w)) @ V.T
    d = (pts - cn.ellipse_centre(conic)) @ L.T
    return np.arctan2(-d[:, 1], d[:, 0])  # v points down


def _gap_misfit(ang: FloatArray, n: int) -> tuple[float, NDArray[np.int64], NDArray[np.int64]]:
    """Worst non-integer part of the angular gaps (ring steps), the order, the rounded steps."""
    order = np.argsort(ang)
    gaps = np.diff(np.append(ang[order], ang[order[0]] + 2 * np.pi)) / (2 * np.pi / n)
    steps = np.rint(gaps).astype(np.int64)
    misfit = float(np.max(np.abs(gaps - steps)))
    if np.any(steps < 1) or steps.sum() != n:
        misfit = max(misfit, 0.5)
    return misfit, order, steps


def relative_positions(
    ang: FloatArray, n: int, *, max_misfit: float = 0.3, max_drop: int = 3
) -> tuple[NDArray[np.int64], NDArray[np.bool_]] | None:
    """Ring positions (relative to the first kept point) from angles, dropping spurious points.

    Gaps between consecutive angles must be whole ring steps (``2 pi / n``);
    while they are not, the point whose removal fits best is dropped (a glint
    that happens to lie on the ring ellipse), at most ``max_drop`` times.

    Returns ``(rel, keep)``, ``rel`` valid where ``keep``; ``None`` if no fit.
    """
    keep = np.ones(ang.size, bool)
    for _ in range(max_drop + 1):
        idx = np.flatnonzero(keep)
        misfit, order, steps = _gap_misfit(ang[idx], n)
        if misfit <= max_misfit:
            rel = np.full(ang.size, -1, np.int64)
            rel[idx[order]] = np.concatenate([[0], np.cumsum(steps[:-1])])
            return rel, keep
        if idx.size <= 5:
            return None
        trials = [(_gap_misfit(np.delete(ang[idx], j), n)[0], j) for j in range(idx.size)]
        keep[idx[min(trials)[1]]] = False
    return None

