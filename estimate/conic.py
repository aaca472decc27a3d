"""The ``conic`` estimator: the thesis's ring-ellipse idea done right for a physical camera.

1. Undistort the detections and remove ``K`` (any fx, fy, skew, principal point).
2. Fit the ring beacons' ellipse in float64 (direct, normalised least squares).
3. Recover the deck plane from the conic (:mod:`~deckpose.estimate.conic_geometry`):
   when the image of the deck centre is known — from the centre beacon and the
   lines through diametrically opposite ring beacons, which all pass through it —
   the plane's normal is the centre's polar (the vanishing line), a single
   solution; otherwise the conic's eigen-decomposition gives two candidates.
4. For each candidate, align the layout in the plane with every identified
   beacon (2-D Procrustes: yaw about the normal from the bow beacon's id and all
   others, and the centre offset).
5. Keep the candidate that reprojects the identified beacons best. Without the
   imaged centre the ring ids decide, or — if that fails and
   ``assume_level_deck`` is set — the more level deck (stated in the extras).

Full pose (roll, pitch, yaw, height, surge, sway) in the world frame via the
known camera attitude ``options.R_world_from_cam``. The imaged-centre route
makes the closed-form tilt first-order in the image measurements, so the pure
geometric solution stays within about 1.6x the Cramér–Rao bound
(``benchmarks/bench_estimators.py``); the eigen route alone, whose tilt comes
from the ellipse's eccentricity, is several times above it near nadir.
By default one Gauss–Newton step on all identified beacons follows
(``options.conic_polish_steps``; 0 = pure geometry): the reported covariance
assumes an efficient estimate, and with few, noisy beacons far away the pure
geometric solution can sit several of those sigmas off. With
``options.refine`` each candidate is refined to the maximum-likelihood optimum
before the choice.

Batch-first (a lone frame is a batch of one): :func:`conic_candidates` runs every step
above as stacked array operations over the frames that share a beacon set. Frames the
batch cannot settle (an outlier to remove, an unresolved ambiguity, any failure) go
through the robust search of :mod:`~estimate.robust_search`, which solves their subsets
stacked by beacon set.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import numpy as np
from deckpose.estimate.conic_geometry import (
    circle_planes,
    fit_ellipses,
    imaged_centres,
    in_plane_alignment,
    planes_from_centres,
)
from deckpose.estimate.frames_driver import estimate_frames
from deckpose.estimate.least_squares import (
    Fit,
    chi2_at,
    covariance_from_information,
    evaluate_fit,
    levenberg_marquardt,
)
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_candidates import BatchCandidates, Extra, pick_batch, scatter_fit
from deckpose.estimate.pose_model import params_from_relative
from deckpose.estimate.registry import EstimateOptions, register
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

FloatArray = NDArray[np.float64]

METHOD = "conic"

#: Ring beacons the ellipse fit needs (5 determine a conic).
MIN_RING_BEACONS = 5
#: The second candidate plane is kept only if its closed-form chi2 is within this of the first's.
ALT_MARGIN_CHI2 = 1000.0


def polish(fit: Fit, obs: Observations, steps: int) -> Fit:
    """Up to ``steps`` undamped Gauss–Newton steps per frame, each kept only if chi2 does not rise."""
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
        go = ok & np.isfinite(p1).all(axis=1)
        rows = active
        if not go.all():
            rows, p1 = active[go], p1[go]
        whole = rows.size == F
        f1 = evaluate_fit(p1, obs if whole else obs.take(rows))
        better = f1.chi2 <= (cur.chi2 if whole else cur.chi2[rows])
        if not better.all():
            rows = rows[better]
            f1 = f1.take(better)
        if rows.size == F:  # every frame took its step
            cur = f1
        elif rows.size:
            cur = _replace_rows(cur, rows, f1)
        active = rows
    return Fit(cur.params, cur.chi2, cur.information, cur.whitened, cur.residuals_px, cur.gradient,
                    fit.iterations, fit.converged)


def _eigen_rows(normals: FloatArray, centres: FloatArray, plane_ok: NDArray[np.bool_]
                ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Both eigen planes of every frame as 2F rows, plane-major."""
    F = normals.shape[0]
    return (normals.transpose(1, 0, 2).reshape(2 * F, 3), centres.transpose(1, 0, 2).reshape(2 * F, 3),
            plane_ok.T.reshape(2 * F))


#: The fields of :class:`Fit`, in order.
_FIELDS = ("params", "chi2", "information", "whitened", "residuals_px", "gradient", "iterations", "converged")


def _replace_rows(fit: Fit, rows: np.ndarray, new: Fit) -> Fit:
    """``fit`` with frames ``rows`` taken from ``new`` (one row each, in order)."""
    parts = {}
    for name in _FIELDS:
        a = getattr(fit, name).copy()
        a[rows] = getattr(new, name)
        parts[name] = a
    return Fit(**parts)


def conic_candidates(obs: Observations, layout: DeckLayout,
                     options: EstimateOptions) -> BatchCandidates:
    """Up to two conic solutions per frame (see the module docstring).

    Slots in order: the start that reprojects best (the imaged-centre plane's, where the
    centre is imaged, else an eigen plane's), then the other plane's start if its
    closed-form chi2 is within :data:`ALT_MARGIN_CHI2`; each polished by
    ``options.conic_polish_steps`` Gauss-Newton steps, or with ``options.refine``
    refined by Levenberg-Marquardt. Frames whose polished solutions look ambiguous have
    both refined to convergence before the choice (unconverged candidates can look
    ambiguous while they share one minimum). NaN and inf are expected in frames without
    a solution: call it under ``np.errstate(all="ignore")``
    (:func:`~estimate.frames_driver.settle_batch` and
    :func:`~estimate.robust_search.estimate_robustly` do).

    Parameters
    ----------
    obs : Observations
        ``F`` frames of one beacon set.
    layout : DeckLayout
    options : EstimateOptions

    Returns
    -------
    BatchCandidates
        With ``centre_beacon_used`` as an extra, and each frame's failure reason where it
        has no solution.
    """
    F = len(obs)
    ring = obs.ids < layout.n_ring
    n_ring = int(np.count_nonzero(ring))
    if n_ring < MIN_RING_BEACONS or F == 0:
        reason = (f"too few ring beacons for the ellipse fit: {n_ring}, need at least {MIN_RING_BEACONS}")
        return BatchCandidates((), np.zeros((F, 0), dtype=bool), np.ones(F, dtype=bool), reasons=(reason,) * F)
    ring_xy = obs.xy[:, ring]
    C, fit_ok = fit_ellipses(ring_xy)
    normals, centres, plane_ok = circle_planes(C, layout.radius_m)
    plane_ok &= fit_ok[:, None]
    # With the imaged centre, its polar is the first plane and the eigen plane farthest from it
    # the competitor, so a real two-fold ambiguity is still tested.
    centre_xy, centre_ok = imaged_centres(obs.xy, obs.points_deck_m, ring, obs.ids == layout.centre_id)
    n_c, X_c, c_ok = planes_from_centres(C, centre_xy, ring_xy, layout.radius_m)
    c_ok &= centre_ok & fit_ok
    # Both planes of every frame as 2F rows (plane-major): one alignment, one chi2 call.
    if c_ok.any():
        dist = np.sqrt(((normals - n_c[:, None, :]) ** 2).sum(axis=2))
        far = np.where(plane_ok[:, 1] & (~plane_ok[:, 0] | (dist[:, 1] > dist[:, 0])), 1, 0)
        ar = np.arange(F)
        far_n, far_X, far_ok = normals[ar, far], centres[ar, far], np.asarray(plane_ok.any(axis=1))
        if c_ok.all():  # (the usual case, with a centre beacon or two diameters: no eigen rows made)
            n2, X2 = np.concatenate([n_c, far_n]), np.concatenate([X_c, far_X])
            ok2 = np.concatenate([c_ok, far_ok])
        else:
            n2, X2, ok2 = _eigen_rows(normals, centres, plane_ok)
            rows = np.flatnonzero(c_ok)
            n2[rows], X2[rows], ok2[rows] = n_c[rows], X_c[rows], True
            n2[F + rows], X2[F + rows], ok2[F + rows] = far_n[rows], far_X[rows], far_ok[rows]
    else:
        n2, X2, ok2 = _eigen_rows(normals, centres, plane_ok)
    # every frame twice (plane-major), as obs.take(np.r_[ar, ar]) would give it
    obs2 = Observations(obs.ids, obs.points_deck_m, np.concatenate([obs.xy, obs.xy]),
                             np.concatenate([obs.sqrt_info, obs.sqrt_info]),
                             np.concatenate([obs.px_from_norm, obs.px_from_norm]),
                             np.concatenate([obs.R_world_from_cam, obs.R_world_from_cam]))
    R, t, ok = in_plane_alignment(obs2.xy, obs.points_deck_m, n2, X2)
    p = params_from_relative(R, t, obs2.R_world_from_cam)
    ok &= ok2 & np.isfinite(p).all(axis=1)
    if ok.all():  # (the usual case: no gathers)
        chi = chi2_at(p, obs2)
    else:
        rows = np.flatnonzero(ok)
        chi = np.full(2 * F, np.inf)
        if rows.size:
            chi[rows] = chi2_at(p[rows], obs.take(rows % F))
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
    slot_rows = [ar if present.all() else np.flatnonzero(present) for present in slots]
    every = [rows.size == F for rows in slot_rows]
    rows_all = np.concatenate(slot_rows) if len(slot_rows) > 1 else slot_rows[0] if slot_rows else ar[:0]
    fits: list[Fit] = []
    if rows_all.size:
        which = np.concatenate([first[slot_rows[0]], second[slot_rows[1]]]) if len(slot_rows) > 1 else (
            first if every[0] else first[rows_all])
        starts = p0[rows_all, which]
        sub = (obs if rows_all.size == F and every[0] else obs2 if len(every) == 2 and all(every)
               else obs.take(rows_all))
        if options.refine:
            f = levenberg_marquardt(starts, sub)
        else:
            f = polish(evaluate_fit(starts, sub), sub, int(options.conic_polish_steps))
        lo = 0
        for rows, all_rows in zip(slot_rows, every):
            part = f if len(slot_rows) == 1 else f.take(slice(lo, lo + rows.size))
            fits.append(part if all_rows else scatter_fit(F, rows, part))
            lo += rows.size
    centre_used = float(layout.centre_id in obs.ids) if layout.centre_id is not None else 0.0
    valid = (slots[0][:, None] if len(slots) == 1 else np.stack(slots, axis=1) if slots
             else np.zeros((F, 0), dtype=bool))
    reasons = None if has_first.all() else tuple(
        "" if has else "the ring beacons do not fit an ellipse (collinear or degenerate points)" if not fit
        else "the fitted conic is not the image of a circle in front of the camera" if not plane
        else "no candidate plane gives a valid pose (rays parallel to the deck)"
        for has, fit, plane in zip(has_first.tolist(), fit_ok.tolist(), (plane_ok.any(axis=1) | c_ok).tolist()))
    cands = BatchCandidates(
        tuple(fits), valid, ~has_first,
        (Extra("centre_beacon_used", np.full(F, centre_used)),), reasons=reasons)
    if options.refine or len(fits) < 2 or not cands.valid.all(axis=1).any():
        return cands  # (an ambiguity needs two solutions)
    # Unconverged candidates can look ambiguous while they share one minimum: settle those
    # frames at the optima (both solutions iterated to convergence) before the choice.
    choice = pick_batch(cands, ambiguity_chi2=options.ambiguity_chi2)
    unsettled = np.flatnonzero(choice.unresolved)
    if not unsettled.size:  # the choice stands (finish_batch need not make it again)
        return BatchCandidates(cands.fits, cands.valid, cands.unsolved, cands.extras, choice, cands.reasons)
    for k, present in enumerate(slots):
        rows = unsettled[present[unsettled]]
        if rows.size:
            lm = levenberg_marquardt(fits[k].params[rows], obs.take(rows))
            fits[k] = _replace_rows(fits[k], rows, lm)
    return BatchCandidates(tuple(fits), cands.valid, cands.unsolved, cands.extras, reasons=cands.reasons)


def estimate_conic_frames(
    detections: Sequence[Detections], camera: CameraModel, layout: DeckLayout, options: EstimateOptions,
    R_world_from_cam: FloatArray,
) -> list[PoseEstimate]:
    """Estimate many frames' deck poses from the ring's image conic (see module docstring).

    Parameters
    ----------
    detections : sequence of F Detections
    camera : CameraModel
    layout : DeckLayout
    options : EstimateOptions
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude (instead of ``options.R_world_from_cam``).

    Returns
    -------
    list of F PoseEstimate
        Failures are falsy with a reason; ``extras["refined"]`` is ``options.refine``.
    """
    return estimate_frames(METHOD, partial(conic_candidates, layout=layout, options=options), detections, camera,
                           layout, options, R_world_from_cam, refined=options.refine,
                           min_points=MIN_RING_BEACONS, no_solution="no conic solution")


@register(METHOD)
def estimate_conic(
    detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate one frame's deck pose from the ring's image conic: a batch of one of
    :func:`estimate_conic_frames`.

    Needs at least 5 identified ring beacons; the centre beacon, when detected,
    resolves the two-fold ambiguity. Never raises on bad detections: failures come
    back as a falsy estimate with a reason.
    """
    R = np.asarray(options.R_world_from_cam, dtype=float)[None]
    return estimate_conic_frames([detections], camera, layout, options, R)[0]
