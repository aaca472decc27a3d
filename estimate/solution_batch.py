"""From many frames' candidate fits to :class:`~deckpose.records.PoseEstimate` records.

The common case at once: the planar ambiguity is resolved, no point is an outlier,
and the estimate is ok. For those frames :func:`finish_batch` builds exactly the
record that :func:`estimate.solution.estimate_robustly` builds; every other frame
goes to :func:`~estimate.solution.estimate_robustly` (which then removes outliers,
reports an unresolved ambiguity, or says why it failed), which solves each of its
subsets as a batch of one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from deckpose.estimate.observations import Observations, group_observations, stack_detections
from deckpose.estimate.pose_candidates import (
    AMBIGUITY_EXTRAS,
    BatchCandidates,
    Candidate,
    pick_batch,
    pick_candidate,
    slot_values,
)
from deckpose.estimate.pose_model import relative_from_params, rotation_vectors
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution import covariance_scale, estimate_robustly, pose_constrained
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import POSE_PARAMS, Detections, PoseEstimate

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


#: The extras after the method's own, in the order of the record (:func:`estimate.solution.make_estimate`).
_TAIL_EXTRAS = (("reprojection_rms_px", "chi2", "dof") + tuple("sigma_" + n for n in POSE_PARAMS)
                + tuple(name for ax in "xyz" for name in (f"rvec_cam_from_deck_{ax}", f"t_cam_from_deck_{ax}_m")))


def finish_batch(
    method: str,
    cands: BatchCandidates,
    obs: Observations,
    n_ignored: NDArray[np.int64],
    *,
    ambiguity_chi2: float,
    outlier_chi2: float,
    max_reprojection_rms_px: float,
    refined: bool,
    pick: bool = True,
) -> list[PoseEstimate | None]:
    """Choose each frame's solution and build its record; None where the single-frame path must decide.

    Frame by frame this is :func:`~estimate.pose_candidates.pick_candidate`, the first test of
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
    whitened = slot_values(cands.fits, "whitened", kb)
    res_px = slot_values(cands.fits, "residuals_px", kb)
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
    R_cd, t_cd = relative_from_params(p_finite, obs.R_world_from_cam)
    # the tail of every record (_TAIL_EXTRAS) as one (F, 15) table, read back as rows of floats
    tail = np.empty((F, len(_TAIL_EXTRAS)))
    tail[:, 0] = rms
    tail[:, 1] = slot_values(cands.fits, "chi2", kb)
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
            ex.update(zip(AMBIGUITY_EXTRAS, amb_rows[i]))
        ex.update(zip(_TAIL_EXTRAS, tail_rows[i]))
        if scale_list[i] > 1.0:
            ex["covariance_scale"] = scale_list[i]
        p = p_list[i]
        out.append(PoseEstimate(
            method=method, ok=True, roll_rad=p[0], pitch_rad=p[1], yaw_rad=p[2], height_m=p[5],
            surge_m=p[3], sway_m=p[4], covariance=cov[i], inliers=ids, extras=ex))
    return out


#: Solutions of a method for the frames of one beacon set.
CandidatesFn = Callable[[Observations], BatchCandidates]


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
    :func:`~estimate.pose_candidates.pick_candidate`.

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

    def solve_one(obs: Observations) -> Candidate | str:
        cands = alone(obs)
        if cands.fallback[0]:
            return cands.reasons[0] if cands.reasons is not None else no_solution
        return pick_candidate(cands, ambiguity_chi2=options.ambiguity_chi2,
                              assume_level_deck=options.assume_level_deck)

    out: list[PoseEstimate] = []
    for d, R, e in zip(detections, R_world_from_cam, got, strict=True):
        if e is None:
            e = estimate_robustly(method, solve_one, d, camera, layout, options, R_world_from_cam=R,
                                  min_points=min_points, refined=refined)
        out.append(e)
    return out
