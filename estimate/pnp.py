"""The ``pnp`` estimator: OpenCV SQPnP and IPPE on identified beacons, then Levenberg–Marquardt.

The beacons are undistorted and normalised first (so the solvers see an ideal
camera with ``K = I``); SQPnP gives the global minimiser of its algebraic error
and IPPE the two solutions of the planar two-fold ambiguity. Each distinct
solution is refined by minimising the (covariance-weighted) reprojection error;
the better one wins, and the result reports IPPE's second solution, the ratio
of IPPE's two reprojection errors and whether the ambiguity is resolved. EPnP is
not used: it fails on this coplanar layout even without noise.

Batch-first (a lone frame is a batch of one): OpenCV's IPPE and SQPnP run frame
by frame (about 20 and 40 µs); everything after them — the starts' poses, their
chi-square, the Levenberg–Marquardt refinements and the tests that decide which
starts compete — is stacked over the frames that share a beacon set
(:func:`pnp_candidates`). Frames the batch cannot settle (an outlier to remove,
an unresolved ambiguity, any failure) go through the robust search of
:mod:`~estimate.robust_search`, which solves their subsets stacked by beacon set.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from typing import cast

import cv2
import numpy as np
from deckpose.estimate.frames_driver import estimate_frames
from deckpose.estimate.least_squares import Fit, chi2_at, levenberg_marquardt
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_candidates import BatchCandidates, Extra, scatter_fit
from deckpose.estimate.pose_model import RODRIGUES_LOOP_MAX, params_from_relative
from deckpose.estimate.registry import EstimateOptions, register
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import wrap_angle_rad

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

METHOD = "pnp"

#: Identified beacons PnP needs (IPPE's minimum for a planar target).
MIN_BEACONS = 4
#: The camera matrix of normalised image coordinates (PnP runs on undistorted, K-removed points).
K_NORMALISED = np.eye(3)
#: An unrefined alternative solution is refined only if its chi2 is within this of the best.
ALT_MARGIN_CHI2 = 100.0


def params_from_rodrigues(rvec: np.ndarray, tvec: np.ndarray, R_world_from_cam: np.ndarray) -> np.ndarray:
    """Pose parameters (6,) from an OpenCV ``rvec, tvec`` (``T_cam_from_deck``) and the camera attitude.

    A batch of one of the starts of :func:`pnp_candidates` (:func:`rotation_matrices`,
    :func:`~estimate.pose_model.params_from_relative`).
    """
    R = rotation_matrices(np.asarray(rvec, dtype=float).reshape(1, 3))
    t = np.asarray(tvec, dtype=float).reshape(1, 3)
    return params_from_relative(R, t, np.asarray(R_world_from_cam, dtype=float)[None])[0]


#: Two pose solutions are one when every angle, and every translation relative to the height,
#: differs by less than this (radians; fraction of ``1 + |height|``).
SAME_TOL = 1e-6
#: Two starts share a basin of attraction for practical purposes (0.01 rad, 1 % of the height).
BASIN_TOL = 1e-2


def poses_close(a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray:
    """Whether each pair of pose parameters agrees within ``tol`` (:data:`SAME_TOL`, :data:`BASIN_TOL`).

    Parameters
    ----------
    a, b : (..., 6) array of float
        Pose parameters (broadcast against each other); the translation tolerance
        scales with ``1 + |a's height|``.
    tol : float

    Returns
    -------
    (...) array of bool
        False where a value is NaN (comparisons with NaN raise no warning).
    """
    d = np.abs(a - b)
    angles_close = (np.abs(wrap_angle_rad(d[..., :3])) < tol).all(axis=-1)
    return np.logical_and(angles_close, (d[..., 3:] < tol * (1 + np.abs(a[..., 5:6]))).all(axis=-1))


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


#: Columns of :func:`_opencv_starts`' table: three slots (SQPnP, IPPE 1, IPPE 2) of rvec and
#: tvec (18), IPPE's two reprojection errors (2), the number of IPPE solutions (-1: failed).
_N_COLUMNS = 21


def _opencv_starts(obs: Observations, *, raise_errors: bool = False
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """SQPnP's and IPPE's two solutions of each frame.

    Returns
    -------
    rt : (F, 3, 6) array of float
        rvec and tvec of the slots SQPnP, IPPE 1, IPPE 2; NaN where a solver gave none.
    errs : (F, 2) array of float
        IPPE's reprojection errors (NaN unless it gave two solutions).
    n_ippe : (F,) array of float
        IPPE's solutions; -1 where OpenCV raised (or, with ``raise_errors``, the error propagates).
    """
    F = len(obs)
    obj = np.ascontiguousarray(obs.points_deck_m, dtype=np.float64)
    xy = np.ascontiguousarray(obs.xy)
    rows: list[list[float]] = []
    for i in range(F):
        row = [math.nan] * _N_COLUMNS  # (one table row per frame: a lone frame makes no arrays here)
        try:
            n, rvecs, tvecs, e = cv2.solvePnPGeneric(obj, xy[i], K_NORMALISED, None, flags=cv2.SOLVEPNP_IPPE)
            ok, rv, tv = cv2.solvePnP(obj, xy[i], K_NORMALISED, None, flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:
            if raise_errors:
                raise
            row[20] = -1.0
            rows.append(row)
            continue
        for j in range(min(int(n), 2)):
            row[6 + 6 * j:9 + 6 * j] = rvecs[j].ravel().tolist()
            row[9 + 6 * j:12 + 6 * j] = tvecs[j].ravel().tolist()
        if n >= 2:
            row[18:20] = np.asarray(e, dtype=float).ravel()[:2].tolist()
        if ok:
            row[0:3] = rv.ravel().tolist()
            row[3:6] = tv.ravel().tolist()
        row[20] = float(n)
        rows.append(row)
    table = np.array(rows).reshape(F, _N_COLUMNS)
    return table[:, :18].reshape(F, 3, 6), table[:, 18:20], table[:, 20]


#: Rank of the second and third start: a frame has one to compete with only if it has more valid starts.
_ALT_RANKS = np.array([1, 2])


def pnp_candidates(obs: Observations, *, raise_errors: bool = False) -> BatchCandidates:
    """SQPnP and both IPPE solutions of each frame, each refined by weighted least squares.

    Slots in order: the refinement of the start with the lowest chi2, then the others
    that could compete (their unrefined chi2 within :data:`ALT_MARGIN_CHI2` of the best
    refined one, not in its basin, :data:`BASIN_TOL`) and do not converge to a solution
    already listed (:data:`SAME_TOL`). SQPnP's start joins unless it repeats an IPPE one.
    NaN starts and comparisons with NaN are expected: call it under
    ``np.errstate(invalid="ignore")`` (:func:`~estimate.frames_driver.settle_batch` and
    :func:`~estimate.robust_search.estimate_robustly` do).

    Parameters
    ----------
    obs : Observations
        ``F`` frames of one beacon set.
    raise_errors : bool, keyword-only
        Let an OpenCV error propagate instead of marking the frame ``unsolved``.

    Returns
    -------
    BatchCandidates
        With IPPE's error ratio and second solution as extras (where IPPE gave two).
    """
    F = len(obs)
    if len(obs.ids) < MIN_BEACONS or F == 0:
        reason = f"too few identified beacons for PnP: {len(obs.ids)}, need at least {MIN_BEACONS}"
        return BatchCandidates((), np.zeros((F, 0), dtype=bool), np.ones(F, dtype=bool), reasons=(reason,) * F)
    rt, errs, n_ippe = _opencv_starts(obs, raise_errors=raise_errors)
    # The three starts of every frame as 3F rows (NaN where a solver gave none: NaN propagates).
    Rwc3 = np.repeat(obs.R_world_from_cam, 3, axis=0)
    flat = params_from_relative(rotation_matrices(rt[:, :, :3].reshape(-1, 3)), rt[:, :, 3:].reshape(-1, 3),
                                      Rwc3)
    starts = flat.reshape(F, 3, 6)
    n_ippe2 = n_ippe >= 2
    ratio = np.where(errs[:, 0] > 0, errs[:, 1] / errs[:, 0], np.inf)
    extras = (Extra("ippe_error_ratio", ratio, n_ippe2),
              Extra("ippe_alt_roll_rad", starts[:, 2, 0], n_ippe2),
              Extra("ippe_alt_pitch_rad", starts[:, 2, 1], n_ippe2),
              Extra("ippe_alt_yaw_rad", starts[:, 2, 2], n_ippe2),
              Extra("ippe_alt_height_m", starts[:, 2, 5], n_ippe2))
    # Non-finite starts drop out; SQPnP joins (in front) unless it repeats an IPPE solution
    # (both IPPE slots against SQPnP's in one call; an absent slot is NaN and repeats nothing).
    valid = cast(BoolArray, np.isfinite(flat).all(axis=1)).reshape(F, 3)
    valid[:, 0] &= ~poses_close(starts[:, :1], starts[:, 1:], SAME_TOL).any(axis=1)
    # Every start's chi2 in one stacked call (the frames repeated per slot), ordered (stable).
    obs3 = Observations(obs.ids, obs.points_deck_m, np.repeat(obs.xy, 3, axis=0),
                             np.repeat(obs.sqrt_info, 3, axis=0), np.repeat(obs.px_from_norm, 3, axis=0), Rwc3)
    chi_raw = np.where(valid, chi2_at(flat, obs3).reshape(F, 3), np.inf)
    order = np.argsort(chi_raw, axis=1, kind="stable")
    n_valid = valid.sum(axis=1)
    ar = np.arange(F)
    has_start = n_valid >= 1
    rows0 = ar if has_start.all() else np.flatnonzero(has_start)
    fit0 = _refine_rows(F, rows0, starts[rows0, order[rows0, 0]], obs)
    # Which of the second and third starts compete with the refined best (both in one call).
    alt_slots = order[:, 1:]  # (F, 2)
    alt_raw = starts[ar[:, None], alt_slots]  # (F, 2, 6)
    competing = ((n_valid[:, None] > _ALT_RANKS) & ~poses_close(alt_raw, fit0.params[:, None], BASIN_TOL)
                 & (chi_raw[ar[:, None], alt_slots] < (fit0.chi2 + ALT_MARGIN_CHI2)[:, None]))
    failed = (n_ippe < 0) | (n_valid == 0)
    if not competing.any():  # no frame has a start to compete: one slot
        return BatchCandidates((fit0,), has_start[:, None], failed, extras)
    fits = [fit0]
    kept = [has_start]
    for pos in (1, 2):
        compete = competing[:, pos - 1]
        if not compete.any():
            continue  # no frame has a competing start here: no slot (none lists this slot)
        rows = np.flatnonzero(compete)
        f = _refine_rows(F, rows, alt_raw[rows, pos - 1], obs)
        new = compete.copy()
        for g, k in zip(fits, kept):
            new &= ~(k & poses_close(f.params, g.params, SAME_TOL))
        fits.append(f)
        kept.append(new)
    return BatchCandidates(tuple(fits), np.stack(kept, axis=1), failed, extras)


def _refine_rows(n_frames: int, rows: NDArray[np.int64], starts: FloatArray, obs: Observations) -> Fit:
    """Levenberg–Marquardt from ``starts`` for frames ``rows``, scattered into ``n_frames`` frames."""
    if rows.size == n_frames:  # every frame: no gather, no scatter
        return levenberg_marquardt(starts, obs)
    return scatter_fit(n_frames, rows, levenberg_marquardt(starts, obs.take(rows)))


def estimate_pnp_frames(
    detections: Sequence[Detections], camera: CameraModel, layout: DeckLayout, options: EstimateOptions,
    R_world_from_cam: FloatArray,
) -> list[PoseEstimate]:
    """Estimate many frames' deck poses by PnP (see module docstring).

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
        Failures are falsy with a reason. The refinement always weights residuals by the
        detections' covariances (or ``sigma_px``), so each is the maximum-likelihood
        estimate with or without ``options.refine``.
    """
    return estimate_frames(METHOD, pnp_candidates, detections, camera, layout, options, R_world_from_cam,
                           refined=True, min_points=MIN_BEACONS,
                           no_solution="PnP found no pose (degenerate beacon configuration)",
                           subset_candidates=partial(pnp_candidates, raise_errors=True))


@register(METHOD)
def estimate_pnp(
    detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate one frame's deck pose by PnP: a batch of one of :func:`estimate_pnp_frames`.

    Needs at least 4 identified beacons.
    """
    R = np.asarray(options.R_world_from_cam, dtype=float)[None]
    return estimate_pnp_frames([detections], camera, layout, options, R)[0]
