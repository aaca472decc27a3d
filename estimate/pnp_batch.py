"""The ``pnp`` estimator for many frames at once (see :mod:`estimate.pnp`).

OpenCV's IPPE and SQPnP run frame by frame (about 20 and 40 µs); everything
after them — the starts' poses, their chi-square, the Levenberg–Marquardt
refinements and the tests that decide which starts compete — is batched, in
the order :func:`estimate.pnp.pnp_candidates` uses.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.estimate.least_squares_batch import (
    RODRIGUES_LOOP_MAX,
    FitBatch,
    FrameObservations,
    chi2_batch,
    levenberg_marquardt_batch,
    params_from_relative_batch,
)
from deckpose.estimate.pnp import (
    ALT_MARGIN_CHI2,
    BASIN_TOL,
    K_NORMALISED,
    MIN_BEACONS,
    SAME_TOL,
    poses_close,
)
from deckpose.estimate.solution_batch import BatchCandidates, Extra, scatter_fit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def rotation_matrices(rvec: FloatArray) -> FloatArray:
    """Rotation matrices (F, 3, 3) of Rodrigues vectors (F, 3), as ``cv2.Rodrigues`` gives them.

    ``R = cos(t) I + (1 - cos(t)) k k^T + sin(t) [k]x`` with ``t = |rvec|``, ``k = rvec / t``
    (the identity for ``t = 0``), written out: a few ufuncs on (F,) columns, no per-call objects;
    up to :data:`RODRIGUES_LOOP_MAX` vectors (a lone frame's three starts) by ``cv2.Rodrigues``
    itself. NaN where a vector is not finite.
    """
    n = rvec.shape[0]
    if n <= RODRIGUES_LOOP_MAX:
        R = np.full((n, 3, 3), np.nan)
        for i, v in enumerate(rvec.tolist()):
            if math.isfinite(v[0] + v[1] + v[2]):
                R[i] = cv2.Rodrigues(np.array(v))[0]
        return R
    x, y, z = rvec[:, 0], rvec[:, 1], rvec[:, 2]
    t = np.sqrt(x * x + y * y + z * z)
    zero = t == 0
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = np.where(zero, 0.0, 1.0 / t)
    kx, ky, kz = x * inv, y * inv, z * inv
    c, s = np.cos(t), np.sin(t)
    c1 = 1.0 - c
    R = np.empty((n, 3, 3))
    R[:, 0, 0] = c + c1 * kx * kx
    R[:, 0, 1] = c1 * kx * ky - s * kz
    R[:, 0, 2] = c1 * kx * kz + s * ky
    R[:, 1, 0] = c1 * ky * kx + s * kz
    R[:, 1, 1] = c + c1 * ky * ky
    R[:, 1, 2] = c1 * ky * kz - s * kx
    R[:, 2, 0] = c1 * kz * kx - s * ky
    R[:, 2, 1] = c1 * kz * ky + s * kx
    R[:, 2, 2] = c + c1 * kz * kz
    return R


def _opencv_starts(obs: FrameObservations) -> tuple[FloatArray, BoolArray, FloatArray, BoolArray]:
    """IPPE's two and SQPnP's solution per frame: rvecs/tvecs (F, 3 slots, 6), present, IPPE errors, failed."""
    F = len(obs)
    obj = np.ascontiguousarray(obs.points_deck_m, dtype=np.float64)
    rt = np.full((F, 3, 6), np.nan)  # slots: SQPnP, IPPE 1, IPPE 2
    present = np.zeros((F, 3), dtype=bool)
    errs = np.full((F, 2), np.nan)
    failed = np.zeros(F, dtype=bool)
    xy = np.ascontiguousarray(obs.xy)
    for i in range(F):
        img = xy[i]
        try:
            n, rvecs, tvecs, e = cv2.solvePnPGeneric(obj, img, K_NORMALISED, None, flags=cv2.SOLVEPNP_IPPE)
            ok, rv, tv = cv2.solvePnP(obj, img, K_NORMALISED, None, flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:
            failed[i] = True
            continue
        k = min(int(n), 2)
        if k:
            rt[i, 1:1 + k, :3] = np.concatenate(rvecs[:k], axis=1).T
            rt[i, 1:1 + k, 3:] = np.concatenate(tvecs[:k], axis=1).T
            present[i, 1:1 + k] = True
        if n >= 2:
            errs[i] = np.asarray(e, dtype=float).ravel()[:2]
        if ok:
            rt[i, 0, :3] = rv.ravel()
            rt[i, 0, 3:] = tv.ravel()
            present[i, 0] = True
    return rt, present, errs, failed


def pnp_candidates_batch(obs: FrameObservations) -> BatchCandidates:
    """SQPnP and both IPPE solutions, refined, in the single-frame method's order."""
    F = len(obs)
    if len(obs.ids) < MIN_BEACONS or F == 0:
        return BatchCandidates((), np.zeros((F, 0), dtype=bool), np.ones(F, dtype=bool))
    rt, present, errs, failed = _opencv_starts(obs)
    R = rotation_matrices(rt[:, :, :3].reshape(-1, 3)).reshape(F, 3, 3, 3)
    Rwc3 = np.repeat(obs.R_world_from_cam, 3, axis=0)
    with np.errstate(invalid="ignore"):
        starts = params_from_relative_batch(R.reshape(-1, 3, 3), rt[:, :, 3:].reshape(-1, 3),
                                            Rwc3).reshape(F, 3, 6)
    starts[~present] = np.nan
    n_ippe2 = present[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(errs[:, 0] > 0, errs[:, 1] / errs[:, 0], np.inf)
    extras = (Extra("ippe_error_ratio", ratio, n_ippe2),
              Extra("ippe_alt_roll_rad", starts[:, 2, 0], n_ippe2),
              Extra("ippe_alt_pitch_rad", starts[:, 2, 1], n_ippe2),
              Extra("ippe_alt_yaw_rad", starts[:, 2, 2], n_ippe2),
              Extra("ippe_alt_height_m", starts[:, 2, 5], n_ippe2))
    # SQPnP joins (in front) unless it repeats an IPPE solution; then non-finite starts drop out.
    # (both IPPE slots against SQPnP's in one call: rows (F, 2) flattened)
    same = poses_close(starts[:, :1], starts[:, 1:], SAME_TOL)  # (F, 2)
    dup = (present[:, 1:] & same).any(axis=1)
    valid = present.copy()
    valid[:, 0] &= ~dup
    valid &= np.isfinite(starts).all(axis=2)
    # Evaluate every valid start, order them by chi2 (stable), refine the best.
    rows_s, slot_s = np.nonzero(valid)
    chi_raw = np.full((F, 3), np.inf)
    chi_raw[rows_s, slot_s] = chi2_batch(starts[rows_s, slot_s], obs.take(rows_s))
    order = np.argsort(np.where(valid, chi_raw, np.inf), axis=1, kind="stable")
    n_valid = valid.sum(axis=1)
    ar = np.arange(F)
    rows0 = np.flatnonzero(n_valid >= 1)
    fit0 = _refine_rows(F, rows0, starts[rows0, order[rows0, 0]], obs)
    fits = [fit0]
    kept = [n_valid >= 1]
    # Which of the second and third starts compete with the refined best (both in one call).
    alt_slots = order[:, 1:]  # (F, 2)
    alt_raw = starts[ar[:, None], alt_slots]  # (F, 2, 6)
    with np.errstate(invalid="ignore"):
        competing = ((n_valid[:, None] > np.array([1, 2]))
                     & ~poses_close(alt_raw, fit0.params[:, None], BASIN_TOL)
                     & (chi_raw[ar[:, None], alt_slots] < (fit0.chi2 + ALT_MARGIN_CHI2)[:, None]))
    for pos in (1, 2):
        compete = competing[:, pos - 1]
        p_raw = alt_raw[:, pos - 1]
        if not compete.any():
            continue  # no frame has a competing start here: no slot (the single-frame method lists none)
        rows = np.flatnonzero(compete)
        f = _refine_rows(F, rows, p_raw[rows], obs)
        new = compete.copy()
        for g, k in zip(fits, kept):
            new &= ~(k & poses_close(f.params, g.params, SAME_TOL))
        fits.append(f)
        kept.append(new)
    return BatchCandidates(tuple(fits), np.stack(kept, axis=1), failed | (n_valid == 0), extras)


def _refine_rows(n_frames: int, rows: NDArray[np.int64], starts: FloatArray, obs: FrameObservations) -> FitBatch:
    """Levenberg–Marquardt from ``starts`` for frames ``rows``, scattered into ``n_frames`` frames."""
    if rows.size == n_frames:  # every frame: no gather, no scatter
        return levenberg_marquardt_batch(starts, obs)
    return scatter_fit(n_frames, rows, levenberg_marquardt_batch(starts, obs.take(rows)))
