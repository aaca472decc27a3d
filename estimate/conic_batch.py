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
    F = len(obs)
    cur = fit
    active = np.arange(F)
    for _ in range(steps):
        if not active.size:
            break
        every = active.size == F  # (then ``active`` is every frame in order: no gathers)
        H, params, grad = ((cur.information, cur.params, cur.gradient) if every else
                           (cur.information[active], cur.params[active], cur.gradient[active]))
        cov, ok = covariance_from_information(H)
        p1 = params - np.einsum("fij,fj->fi", cov, grad)
        go = ok & np.all(np.isfinite(p1), axis=1)
        rows, p1 = active[go], p1[go]
        f1 = evaluate_fit_batch(p1, obs if rows.size == F else obs.take(rows))
        better = f1.chi2 <= cur.chi2[rows]
        rows = rows[better]
        if rows.size == F:  # every frame took its step
            cur = f1
        elif rows.size:
            cur = _replace_rows(cur, rows, FitBatch(*(getattr(f1, name)[better] for name in _FIELDS)))
        active = rows
    return FitBatch(cur.params, cur.chi2, cur.information, cur.whitened, cur.residuals_px, cur.gradient,
                    fit.iterations, fit.converged)


#: The fields of :class:`FitBatch`, in order.
_FIELDS = ("params", "chi2", "information", "whitened", "residuals_px", "gradient", "iterations", "converged")


def _fit_rows(fit: FitBatch, rows: slice) -> FitBatch:
    """The frames ``rows`` of ``fit`` (views)."""
    return FitBatch(*(getattr(fit, name)[rows] for name in _FIELDS))


def _replace_rows(fit: FitBatch, rows: np.ndarray, new: FitBatch) -> FitBatch:
    """``fit`` with frames ``rows`` taken from ``new`` (one row each, in order)."""
    parts = {}
    for name in _FIELDS:
        a = getattr(fit, name).copy()
        a[rows] = getattr(new, name)
        parts[name] = a
    return FitBatch(**parts)


def conic_candidates_batch(obs: FrameObservations, layout: DeckLayout,
                           options: EstimateOptions) -> BatchCandidates:
    """Up to two conic solutions per frame, in the single-frame method's order.

    NaN and inf are expected in frames without a solution: call it under
    ``np.errstate(all="ignore")`` (:func:`~estimate.solution_batch.settle_batch` does).
    """
    F = len(obs)
    ring = obs.ids < layout.n_ring
    if int(np.count_nonzero(ring)) < MIN_RING_BEACONS or F == 0:
        return BatchCandidates((), np.zeros((F, 0), dtype=bool), np.ones(F, dtype=bool))
    C, fit_ok = fit_ellipses(obs.xy[:, ring])
    normals, centres, plane_ok = circle_planes_batch(C, layout.radius_m)
    plane_ok &= fit_ok[:, None]
    # With the imaged centre, its polar is the first plane and the eigen plane farthest from it
    # the competitor (estimate.conic.conic_candidates).
    centre_xy, centre_ok, unsure = imaged_centres(obs.xy, obs.points_deck_m, ring, obs.ids == layout.centre_id)
    n_c, X_c, c_ok = planes_from_centres(C, centre_xy, obs.xy[:, ring], layout.radius_m)
    c_ok &= centre_ok & fit_ok
    # Both planes of every frame as 2F rows (plane-major): one alignment, one chi2 call.
    n2, X2 = normals.transpose(1, 0, 2).reshape(2 * F, 3), centres.transpose(1, 0, 2).reshape(2 * F, 3)
    ok2 = plane_ok.T.reshape(2 * F)
    if c_ok.any():
        dist = np.sqrt(np.sum((normals - n_c[:, None, :]) ** 2, axis=2))
        far = np.where(plane_ok[:, 1] & (~plane_ok[:, 0] | (dist[:, 1] > dist[:, 0])), 1, 0)
        ar = np.arange(F)
        far_n, far_X, far_ok = normals[ar, far], centres[ar, far], np.asarray(plane_ok.any(axis=1))
        if c_ok.all():
            n2, X2 = np.concatenate([n_c, far_n]), np.concatenate([X_c, far_X])
            ok2 = np.concatenate([c_ok, far_ok])
        else:
            rows = np.flatnonzero(c_ok)
            n2[rows], X2[rows], ok2[rows] = n_c[rows], X_c[rows], True
            n2[F + rows], X2[F + rows], ok2[F + rows] = far_n[rows], far_X[rows], far_ok[rows]
    xy2 = np.concatenate([obs.xy, obs.xy])
    R2 = np.concatenate([obs.R_world_from_cam, obs.R_world_from_cam])
    R, t, ok = in_plane_alignment_batch(xy2, obs.points_deck_m, n2, X2)
    p = params_from_relative_batch(R, t, R2)
    ok &= ok2 & np.isfinite(p).all(axis=1)
    rows = np.flatnonzero(ok)
    chi = np.full(2 * F, np.inf)
    if rows.size:
        chi[rows] = chi2_batch(p[rows], obs.take(rows % F))
    p0 = np.where(ok[:, None], p, np.nan).reshape(2, F, 6).transpose(1, 0, 2)
    start_ok = ok.reshape(2, F).T
    chi0 = chi.reshape(2, F).T
    # Starts sorted by their chi2 (stable); the second competes only within ALT_MARGIN_CHI2.
    swap = start_ok[:, 1] & (~start_ok[:, 0] | (chi0[:, 1] < chi0[:, 0]))
    first = swap.astype(np.int64)
    second = 1 - first
    ar = np.arange(F)
    has_first = np.asarray(start_ok.any(axis=1))
    has_second = start_ok.all(axis=1) & (chi0[ar, second] < chi0[ar, first] + ALT_MARGIN_CHI2)
    # Both slots' starts solved in one stacked call (slot-major rows), then split into slots;
    # a slot no frame has is not listed.
    slots = [present for present in (has_first, has_second) if present.any()]
    slot_rows = [np.flatnonzero(present) for present in slots]
    every = [rows.size == F for rows in slot_rows]
    rows_all = np.concatenate(slot_rows) if len(slot_rows) > 1 else slot_rows[0] if slot_rows else ar[:0]
    fits: list[FitBatch] = []
    if rows_all.size:
        which = np.concatenate([first[slot_rows[0]], second[slot_rows[1]]]) if len(slot_rows) > 1 else (
            first if every[0] else first[rows_all])
        starts = p0[rows_all, which]
        sub = obs if rows_all.size == F and every[0] else obs.take(rows_all)
        if options.refine:
            f = levenberg_marquardt_batch(starts, sub)
        else:
            f = polish_batch(evaluate_fit_batch(starts, sub), sub, int(options.conic_polish_steps))
        lo = 0
        for rows, all_rows in zip(slot_rows, every):
            part = f if len(slot_rows) == 1 else _fit_rows(f, slice(lo, lo + rows.size))
            fits.append(part if all_rows else scatter_fit(F, rows, part))
            lo += rows.size
    centre_used = float(layout.centre_id in obs.ids) if layout.centre_id is not None else 0.0
    valid = np.stack(slots, axis=1) if slots else np.zeros((F, 0), dtype=bool)
    cands = BatchCandidates(
        tuple(fits), valid, ~has_first | unsure,
        (Extra("centre_beacon_used", np.full(F, centre_used)),))
    if options.refine or len(fits) < 2 or not cands.valid.all(axis=1).any():
        return cands  # (an ambiguity needs two solutions)
    # Unconverged candidates can look ambiguous while they share one minimum: settle those
    # frames at the optima (both solutions iterated to convergence) before the choice.
    choice = pick_batch(cands, ambiguity_chi2=options.ambiguity_chi2)
    unsettled = np.flatnonzero(choice.unresolved)
    if not unsettled.size:  # the choice stands (finish_batch need not make it again)
        return BatchCandidates(cands.fits, cands.valid, cands.fallback, cands.extras, choice)
    for k, present in enumerate(slots):
        rows = unsettled[present[unsettled]]
        if rows.size:
            lm = levenberg_marquardt_batch(fits[k].params[rows], obs.take(rows))
            fits[k] = _replace_rows(fits[k], rows, lm)
    return BatchCandidates(tuple(fits), cands.valid, cands.fallback, cands.extras)
