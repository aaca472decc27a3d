"""The ``conic`` estimator for many frames at once (see :mod:`estimate.conic`).

:func:`conic_candidates_batch` is :func:`estimate.conic.conic_candidates` on stacked
frames: one batched ellipse fit, the imaged-centre plane and the eigen planes, the in-plane alignment,
then the Gauss–Newton polish (or, with ``refine``, Levenberg–Marquardt) of the
competing starts. A frame whose unrefined candidates look ambiguous is left to
the single-frame path, which settles it at the converged optima.
"""

from __future__ import annotations

import numpy as np
from deckpose.estimate.conic import ALT_MARGIN_CHI2, MIN_RING_BEACONS
from deckpose.estimate.conic_geometry_batch import (
    circle_planes_batch,
    fit_ellipses,
    imaged_centres,
    in_plane_alignment_batch,
    planes_from_centres,
)
from deckpose.estimate.least_squares_batch import (
    FitBatch,
    FrameObservations,
    chi2_batch,
    covariance_from_information,
    evaluate_fit_batch,
    levenberg_marquardt_batch,
    params_from_relative_batch,
)
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution_batch import BatchCandidates, Extra, pick_batch, scatter_fit

from deckpose.layout import DeckLayout


def polish_batch(fit: FitBatch, obs: FrameObservations, steps: int) -> FitBatch:
    """Up to ``steps`` undamped Gauss–Newton steps per frame, each kept only if chi2 does not rise.

    The batched :func:`estimate.conic._polish`.
    """
    active = np.arange(len(obs))
    params, chi2 = fit.params.copy(), fit.chi2.copy()
    parts = {name: getattr(fit, name).copy() for name in ("information", "whitened", "residuals_px",
                                                          "gradient")}
    for _ in range(steps):
        if not active.size:
            break
        cov, ok = covariance_from_information(parts["information"][active])
        p1 = params[active] - np.einsum("fij,fj->fi", cov, parts["gradient"][active])
        go = ok & np.all(np.isfinite(p1), axis=1)
        rows, p1 = active[go], p1[go]
        f1 = evaluate_fit_batch(p1, obs.take(rows))
        better = f1.chi2 <= chi2[rows]
        rows = rows[better]
        params[rows], chi2[rows] = f1.params[better], f1.chi2[better]
        for name, arr in parts.items():
            arr[rows] = getattr(f1, name)[better]
        active = rows
    return FitBatch(params, chi2, parts["information"], parts["whitened"], parts["residuals_px"],
                    parts["gradient"], fit.iterations, fit.converged)


def _replace_rows(fit: FitBatch, rows: np.ndarray, new: FitBatch) -> FitBatch:
    """``fit`` with frames ``rows`` taken from ``new`` (one row each, in order)."""
    parts = {}
    for name in ("params", "chi2", "information", "whitened", "residuals_px", "gradient", "iterations",
                 "converged"):
        a = getattr(fit, name).copy()
        a[rows] = getattr(new, name)
        parts[name] = a
    return FitBatch(**parts)


def conic_candidates_batch(obs: FrameObservations, layout: DeckLayout,
                           options: EstimateOptions) -> BatchCandidates:
    """Up to two conic solutions per frame, in the single-frame method's order."""
    F = len(obs)
    ring = obs.ids < layout.n_ring
    no = np.ones(F, dtype=bool)
    if int(np.count_nonzero(ring)) < MIN_RING_BEACONS or F == 0:
        return BatchCandidates((), np.zeros((F, 0), dtype=bool), no)
    C, fit_ok = fit_ellipses(obs.xy[:, ring])
    normals, centres, plane_ok = circle_planes_batch(C, layout.radius_m)
    plane_ok &= fit_ok[:, None]
    # With the imaged centre, its polar is the first plane and the eigen plane farthest from it
    # the competitor (estimate.conic.conic_candidates).
    centre_xy, centre_ok, unsure = imaged_centres(obs.xy, obs.points_deck_m, ring, obs.ids == layout.centre_id)
    n_c, X_c, c_ok = planes_from_centres(C, centre_xy, obs.xy[:, ring], layout.radius_m)
    c_ok &= centre_ok & fit_ok
    if np.any(c_ok):
        with np.errstate(invalid="ignore"):
            dist = np.sqrt(np.sum((normals - n_c[:, None, :]) ** 2, axis=2))
        far = np.where(plane_ok[:, 1] & (~plane_ok[:, 0] | (dist[:, 1] > dist[:, 0])), 1, 0)
        ar = np.arange(F)
        rows = np.flatnonzero(c_ok)
        far_n, far_X, far_ok = normals[ar, far], centres[ar, far], np.asarray(plane_ok.any(axis=1))
        normals[rows, 1], centres[rows, 1], plane_ok[rows, 1] = far_n[rows], far_X[rows], far_ok[rows]
        normals[rows, 0], centres[rows, 0], plane_ok[rows, 0] = n_c[rows], X_c[rows], True
    p0 = np.full((F, 2, 6), np.nan)
    start_ok = np.zeros((F, 2), dtype=bool)
    chi0 = np.full((F, 2), np.inf)
    for j in range(2):
        R, t, ok = in_plane_alignment_batch(obs.xy, obs.points_deck_m, normals[:, j], centres[:, j])
        with np.errstate(invalid="ignore"):
            p = params_from_relative_batch(R, t, obs.R_world_from_cam)
        ok &= plane_ok[:, j] & np.all(np.isfinite(p), axis=1)
        rows = np.flatnonzero(ok)
        p0[rows, j] = p[rows]
        start_ok[:, j] = ok
        if rows.size:
            chi0[rows, j] = chi2_batch(p[rows], obs.take(rows))
    # Starts sorted by their chi2 (stable); the second competes only within ALT_MARGIN_CHI2.
    swap = start_ok[:, 1] & (~start_ok[:, 0] | (chi0[:, 1] < chi0[:, 0]))
    first = swap.astype(np.int64)
    second = 1 - first
    ar = np.arange(F)
    has_first = np.asarray(start_ok.any(axis=1))
    has_second = start_ok.all(axis=1) & (chi0[ar, second] < chi0[ar, first] + ALT_MARGIN_CHI2)
    fits = []
    slots = []
    for k, present in ((first, has_first), (second, has_second)):
        if not present.any():
            continue  # no frame has this solution: no slot (the single-frame method lists none)
        rows = np.flatnonzero(present)
        every = rows.size == F  # no gather, no scatter
        sub = obs if every else obs.take(rows)
        starts = p0[rows, k[rows]]
        if options.refine:
            f = levenberg_marquardt_batch(starts, sub)
        else:
            f = polish_batch(evaluate_fit_batch(starts, sub), sub, int(options.conic_polish_steps))
        fits.append(f if every else scatter_fit(F, rows, f))
        slots.append(present)
    centre_used = float(layout.centre_id in obs.ids) if layout.centre_id is not None else 0.0
    valid = np.stack(slots, axis=1) if slots else np.zeros((F, 0), dtype=bool)
    cands = BatchCandidates(
        tuple(fits), valid, ~has_first | unsure,
        (Extra("centre_beacon_used", np.full(F, centre_used)),))
    if options.refine or not fits:
        return cands
    # Unconverged candidates can look ambiguous while they share one minimum: settle those
    # frames at the optima (both solutions iterated to convergence) before the choice.
    unsettled = np.flatnonzero(pick_batch(cands, ambiguity_chi2=options.ambiguity_chi2).unresolved)
    if not unsettled.size:
        return cands
    for k, present in enumerate(slots):
        rows = unsettled[present[unsettled]]
        if rows.size:
            lm = levenberg_marquardt_batch(fits[k].params[rows], obs.take(rows))
            fits[k] = _replace_rows(fits[k], rows, lm)
    return BatchCandidates(tuple(fits), cands.valid, cands.fallback, cands.extras)
