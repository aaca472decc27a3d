"""From many frames' candidate fits to :class:`~deckpose.records.PoseEstimate` records.

The batched twin of :mod:`estimate.solution` for the common case: the planar
ambiguity is resolved, no point is an outlier, and the estimate is ok. For those
frames :func:`finish_batch` builds exactly the record that
:func:`estimate.solution.estimate_robustly` builds; every other frame is marked
for :func:`~estimate.solution.estimate_robustly` (which then removes outliers,
reports an unresolved ambiguity, or says why it failed), which solves each of its
subsets as a batch of one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from deckpose.estimate.least_squares import Fit, fit_of_row
from deckpose.estimate.least_squares_batch import (
    FitBatch,
    FrameObservations,
    covariance_from_information,
    relative_from_params_batch,
    rotation_vectors,
    solve_batch,
)
from deckpose.estimate.observations import Observations
from deckpose.estimate.observations_batch import group_observations, stack_detections, stack_one
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution import (
    Candidate,
    ambiguity_resolved,
    covariance_scale,
    estimate_robustly,
    pick_candidate,
    pose_constrained,
)
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import POSE_PARAMS, Detections, PoseEstimate
from deckpose.rotation import wrap_angle_rad

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class Extra:
    """One method-specific extra for every frame of a batch.

    Attributes
    ----------
    name : str
    values : (F,) array of float
    present : (F,) array of bool or None
        Frames whose record carries this extra (None = all).
    """

    name: str
    values: FloatArray
    present: BoolArray | None = None


@dataclass(frozen=True)
class BatchCandidates:
    """The (up to K) solutions of one estimator for ``F`` frames.

    Attributes
    ----------
    fits : tuple of FitBatch
        Slot ``k`` of every frame, in the order the single-frame method lists its fits.
    valid : (F, K) array of bool
        Which slots the single-frame method would list.
    fallback : (F,) array of bool
        Frames the batched method could not settle (they go to the single-frame path).
    extras : tuple of Extra
        Method extras that precede ``n_solutions`` in the record, in order.
    choice : PickBatch or None
        :func:`pick_batch` of these solutions at the options' ``ambiguity_chi2``, where the
        method has made it already (:func:`finish_batch` makes it otherwise).
    reasons : tuple of str or None
        Why each frame has no solution (``""`` where it has one), where the method says;
        None where every frame has one or the method gives no reasons.
    """

    fits: tuple[FitBatch, ...]
    valid: BoolArray
    fallback: BoolArray
    extras: tuple[Extra, ...] = ()
    choice: PickBatch | None = None
    reasons: tuple[str, ...] | None = None


def scatter_fit(n_frames: int, rows: NDArray[np.int64], fit: FitBatch) -> FitBatch:
    """A fit for ``n_frames`` frames holding ``fit`` at ``rows`` and an invalid fit elsewhere."""
    def put(a: np.ndarray, fill: float) -> np.ndarray:
        out = np.full((n_frames,) + a.shape[1:], fill, dtype=a.dtype)
        out[rows] = a
        return out

    return FitBatch(put(fit.params, np.nan), put(fit.chi2, np.inf), put(fit.information, np.nan),
                    put(fit.whitened, np.nan), put(fit.residuals_px, np.nan), put(fit.gradient, np.nan),
                    put(fit.iterations, 0), put(fit.converged, False))


def _take(a: np.ndarray, k: NDArray[np.int64]) -> np.ndarray:
    return a[np.arange(a.shape[0]), k]


def _select(fits: tuple[FitBatch, ...], attr: str, k: NDArray[np.int64]) -> np.ndarray:
    """``getattr(fits[k[f]], attr)[f]`` for every frame ``f`` (read-only: may be ``fits[0]``'s own array)."""
    if len(fits) == 1 or not k.any():
        return getattr(fits[0], attr)
    out = np.array(getattr(fits[0], attr))
    for j in range(1, len(fits)):
        rows = k == j
        if np.any(rows):
            out[rows] = getattr(fits[j], attr)[rows]
    return out


@dataclass(frozen=True)
class PickBatch:
    """Each frame's choice between its solutions (the batched :func:`estimate.solution.pick_candidate`).

    Attributes
    ----------
    best : (F,) array of int
        Slot of the lowest-chi2 valid solution.
    n_good : (F,) array of int
        Valid solutions (finite chi2 and parameters).
    params : (F, 6) array of float
        The best solution.
    covariance : (F, 6, 6) array of float
    covariance_ok : (F,) array of bool
    alt_params : (F, 6) array of float
        The runner-up (NaN without one).
    delta_chi2, mahalanobis : (F,) array of float
        Runner-up minus best chi2; their distance in the best's covariance.
    unresolved : (F,) array of bool
        A runner-up fits almost as well (delta chi2 below the threshold) but differs
        by more than 3 sigma, or the distance could not be computed.
    """

    best: NDArray[np.int64]
    n_good: NDArray[np.int64]
    params: FloatArray
    covariance: FloatArray
    covariance_ok: BoolArray
    alt_params: FloatArray
    delta_chi2: FloatArray
    mahalanobis: FloatArray
    unresolved: BoolArray


def pick_batch(cands: BatchCandidates, *, ambiguity_chi2: float) -> PickBatch:
    """Choose between each frame's solutions: the lowest chi2, and whether the ambiguity is resolved."""
    F, K = cands.valid.shape
    if K == 1:  # one solution per frame: nothing to order
        params, chi2 = cands.fits[0].params[:, None], cands.fits[0].chi2[:, None]
    else:
        params = np.stack([f.params for f in cands.fits], axis=1)  # (F, K, 6)
        chi2 = np.stack([f.chi2 for f in cands.fits], axis=1)
    good = cands.valid & np.isfinite(chi2) & np.isfinite(params).all(axis=2)
    n_good = good.sum(axis=1)
    order = (np.zeros((F, 1), dtype=np.int64) if K == 1
             else np.argsort(np.where(good, chi2, np.inf), axis=1, kind="stable"))
    kb = order[:, 0]
    best_p = cands.fits[0].params if K == 1 else _take(params, kb)
    cov, cov_ok = covariance_from_information(_select(cands.fits, "information", kb))
    unresolved = np.zeros(F, dtype=bool)
    if K < 2:  # no runner-up (one read-only NaN table serves its three fields)
        nan = np.full((F, 6), np.nan)
        return PickBatch(kb, n_good, best_p, cov, cov_ok, nan, nan[:, 0], nan[:, 0], unresolved)
    has_alt = n_good >= 2
    ka = order[:, 1]
    alt_p = _take(params, ka)
    dchi2 = _take(chi2, ka) - _take(chi2, kb)
    delta = alt_p - best_p
    delta[:, :3] = wrap_angle_rad(delta[:, :3])
    testable = has_alt & cov_ok
    if testable.all():  # (every frame: no gathers)
        x, solved = solve_batch(cov, delta)
        maha = np.sqrt(np.sum(delta * x, axis=1))
        unresolved |= ~solved
    else:
        rows = np.flatnonzero(testable)
        maha = np.full(F, np.inf)
        if rows.size:
            x, solved = solve_batch(cov[rows], delta[rows])
            maha[rows] = np.sqrt(np.sum(delta[rows] * x, axis=1))
            unresolved[rows[~solved]] = True
    with np.errstate(invalid="ignore"):
        resolved = ambiguity_resolved(dchi2, maha, ambiguity_chi2)
    unresolved |= has_alt & ~resolved
    return PickBatch(kb, n_good, best_p, cov, cov_ok, alt_p, dchi2, maha, unresolved)


#: The ambiguity's extras, in the order of the record (:func:`estimate.solution.pick_candidate`).
_AMBIGUITY_EXTRAS = ("ambiguity_delta_chi2", "ambiguity_mahalanobis", "alt_roll_rad", "alt_pitch_rad",
                     "alt_yaw_rad", "alt_height_m")
#: The extras after the method's own, in the order of the record (:func:`estimate.solution.make_estimate`).
_TAIL_EXTRAS = (("reprojection_rms_px", "chi2", "dof") + tuple("sigma_" + n for n in POSE_PARAMS)
                + tuple(name for ax in "xyz" for name in (f"rvec_cam_from_deck_{ax}", f"t_cam_from_deck_{ax}_m")))


def finish_batch(
    method: str,
    cands: BatchCandidates,
    obs: FrameObservations,
    n_ignored: NDArray[np.int64],
    *,
    ambiguity_chi2: float,
    outlier_chi2: float,
    max_reprojection_rms_px: float,
    refined: bool,
    pick: bool = True,
) -> list[PoseEstimate | None]:
    """Choose each frame's solution and build its record; None where the single-frame path must decide.

    Frame by frame this is :func:`estimate.solution.pick_candidate`, the first test of
    :func:`estimate.solution.solve_robust` and :func:`estimate.solution.make_estimate`
    for the case where they produce an ok estimate without removing a point.
    ``pick=False`` is for a single solution taken as it is (the refinement): no
    ``n_solutions`` extra. NaN fits are expected: call it under
    ``np.errstate(invalid="ignore")`` (:func:`settle_batch` does).
    """
    F = len(obs)
    M = obs.xy.shape[1]
    choice = cands.choice if cands.choice is not None else pick_batch(cands, ambiguity_chi2=ambiguity_chi2)
    kb, best_p = choice.best, choice.params
    whitened = _select(cands.fits, "whitened", kb)
    res_px = _select(cands.fits, "residuals_px", kb)
    pc = (whitened * whitened).sum(axis=2)
    # solution.make_estimate widens the covariance when the residuals exceed it alike
    scale = covariance_scale(pc)
    rms = np.sqrt((res_px * res_px).sum(axis=(1, 2)) / M)
    cov = choice.covariance * scale[:, None, None]
    sig = np.sqrt(cov.reshape(F, 36)[:, ::7])  # the diagonals (``cov`` is a fresh product)
    # the frames where pick_candidate, solve_robust's first test and make_estimate give an ok
    # estimate without removing a point (pose_constrained: else the single-frame path flags them)
    settled = (choice.n_good > 0) & choice.covariance_ok & (pc.max(axis=1) <= outlier_chi2)
    settled &= np.isfinite(rms) & (rms <= max_reprojection_rms_px) & pose_constrained(best_p, sig)
    settled &= ~(cands.fallback | choice.unresolved)
    settled_list = settled.tolist()
    if not any(settled_list):
        return [None] * F
    # (the frames left to the single-frame path may have no finite pose: zeros keep them quiet)
    p_finite = best_p if all(settled_list) else np.where(np.isfinite(best_p), best_p, 0.0)
    R_cd, t_cd = relative_from_params_batch(p_finite, obs.R_world_from_cam)
    # the tail of every record (_TAIL_EXTRAS) as one (F, 15) table, read back as rows of floats
    tail = np.empty((F, len(_TAIL_EXTRAS)))
    tail[:, 0] = rms
    tail[:, 1] = _select(cands.fits, "chi2", kb)
    tail[:, 2] = 2 * M - 6
    tail[:, 3:9] = sig
    tail[:, 9::2] = rotation_vectors(R_cd)
    tail[:, 10::2] = t_cd
    tail_rows = tail.tolist()
    ids = tuple(obs.ids.tolist())
    head = {"n_points": float(M), "n_ignored": 0.0, "n_outliers_removed": 0.0, "refined": float(refined)}
    pre = [(e.name, e.values.tolist(), None if e.present is None else e.present.tolist())
           for e in cands.extras]
    alt_list = (choice.n_good >= 2).tolist()
    amb_rows = (np.column_stack([choice.delta_chi2, choice.mahalanobis, choice.alt_params[:, :3],
                                 choice.alt_params[:, 5]]).tolist() if any(alt_list) else [])
    n_ign = n_ignored.tolist()
    n_sol = choice.n_good.tolist()
    scale_list = scale.tolist()
    p_list = best_p.tolist()
    out: list[PoseEstimate | None] = []
    for i in range(F):
        if not settled_list[i]:
            out.append(None)
            continue
        ex = dict(head)
        ex["n_ignored"] = float(n_ign[i])
        for name, vals, present in pre:
            if present is None or present[i]:
                ex[name] = vals[i]
        if pick:
            ex["n_solutions"] = float(n_sol[i])
        if alt_list[i]:
            ex.update(zip(_AMBIGUITY_EXTRAS, amb_rows[i]))
        ex.update(zip(_TAIL_EXTRAS, tail_rows[i]))
        if scale_list[i] > 1.0:
            ex["covariance_scale"] = scale_list[i]
        p = p_list[i]
        out.append(PoseEstimate(
            method=method, ok=True, roll_rad=p[0], pitch_rad=p[1], yaw_rad=p[2], height_m=p[5],
            surge_m=p[3], sway_m=p[4], covariance=cov[i], inliers=ids, extras=ex))
    return out


def candidates_of_one(cands: BatchCandidates) -> tuple[list[Fit], dict[str, float]]:
    """The solutions a batch of one frame lists, and its extras, as the robust search takes them.

    Parameters
    ----------
    cands : BatchCandidates
        Of one frame (``F = 1``).

    Returns
    -------
    fits : list of Fit
        The valid slots, in order.
    extras : dict of str to float
        The extras the frame carries, in order.
    """
    fits = [fit_of_row(f, 0) for f, v in zip(cands.fits, cands.valid[0].tolist()) if v]
    extras = {e.name: float(e.values[0]) for e in cands.extras if e.present is None or e.present[0]}
    return fits, extras


#: Solutions of a method for the frames of one beacon set.
CandidatesFn = Callable[[FrameObservations], BatchCandidates]


def settle_batch(
    method: str, candidates: CandidatesFn, detections: Sequence[Detections], camera: CameraModel,
    layout: DeckLayout, options: EstimateOptions, R_world_from_cam: FloatArray, *, refined: bool,
) -> list[PoseEstimate | None]:
    """``method``'s records for the frames the batch settles; None where the frame must be decided alone.

    Parameters
    ----------
    method : str
    candidates : callable
        ``candidates(observations)``: the method's solutions for the frames of one beacon set.
    detections : sequence of F Detections
    camera, layout, options
    R_world_from_cam : (F, 3, 3) array of float
    refined : bool, keyword-only
        The records' ``refined`` extra.

    Returns
    -------
    list of F PoseEstimate or None
    """
    out: list[PoseEstimate | None] = [None] * len(detections)
    groups = group_observations(stack_detections(detections), camera, layout, R_world_from_cam,
                                sigma_px=options.sigma_px,
                                use_detection_covariance=options.use_detection_covariance)
    for g in groups:
        with np.errstate(all="ignore"):
            cands = candidates(g.observations)
            if not len(cands.fits):
                continue
            ests = finish_batch(method, cands, g.observations, g.n_ignored,
                                ambiguity_chi2=options.ambiguity_chi2, outlier_chi2=options.outlier_chi2,
                                max_reprojection_rms_px=options.max_reprojection_rms_px, refined=refined)
        if len(groups) == 1 and g.frames.size == len(detections):
            return ests  # one beacon set (a lone frame, or every beacon seen): the frames in order
        for f, e in zip(g.frames.tolist(), ests):
            out[f] = e
    return out


def estimate_frames(
    method: str, candidates: CandidatesFn, detections: Sequence[Detections], camera: CameraModel,
    layout: DeckLayout, options: EstimateOptions, R_world_from_cam: FloatArray, *, refined: bool,
    min_points: int, no_solution: str, subset_candidates: CandidatesFn | None = None,
) -> list[PoseEstimate]:
    """A batch-first estimator's records for many frames: the one driver of ``conic`` and ``pnp``.

    The batch settles what it can (:func:`settle_batch`); every other frame (an outlier to
    remove, an unresolved ambiguity, a failure) goes through the robust search
    (:func:`~estimate.solution.estimate_robustly`), which solves each subset of the frame's
    points as a batch of one and chooses between its solutions with
    :func:`~estimate.solution.pick_candidate`.

    Parameters
    ----------
    method : str
    candidates : callable
        ``candidates(observations)``: the method's solutions for the frames of one beacon set.
    detections : sequence of F Detections
    camera, layout, options
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude.
    refined : bool, keyword-only
        The records' ``refined`` extra.
    min_points : int, keyword-only
        Fewest points the method solves from.
    no_solution : str, keyword-only
        The failure reason of a subset without a solution where the method gives none
        (:attr:`BatchCandidates.reasons`).
    subset_candidates : callable, optional, keyword-only
        The solutions of one subset, where they differ from ``candidates`` (e.g. letting
        a numerical error propagate to the robust search, which reports it).

    Returns
    -------
    list of F PoseEstimate
        Failures are falsy with a reason.
    """
    got = settle_batch(method, candidates, detections, camera, layout, options, R_world_from_cam,
                       refined=refined)
    alone = subset_candidates or candidates

    def solve_one(obs: Observations, R_wc: FloatArray) -> Candidate | str:
        cands = alone(stack_one(obs, R_wc))
        if cands.fallback[0]:
            return cands.reasons[0] if cands.reasons is not None else no_solution
        fits, extras = candidates_of_one(cands)
        return pick_candidate(fits, ambiguity_chi2=options.ambiguity_chi2,
                              assume_level_deck=options.assume_level_deck, extras=extras)

    out: list[PoseEstimate] = []
    for d, R, e in zip(detections, R_world_from_cam, got, strict=True):
        if e is None:
            e = estimate_robustly(method, solve_one, d, camera, layout, options, R_world_from_cam=R,
                                  min_points=min_points, refined=refined)
        out.append(e)
    return out
