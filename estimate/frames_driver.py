"""The one driver of the batch-first estimators: settle what the batch can, search the rest.

:func:`settle_batch` groups the frames by beacon set, asks the method for its candidate
poses of each group at once and makes the ok records of the frames it settles
(:func:`~estimate.pose_records.finish_batch`); :func:`estimate_frames` sends every other
frame (an outlier to remove, an unresolved ambiguity, a failure) through the robust search
(:func:`~estimate.robust_search.estimate_robustly`), all of them together.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import cast

import numpy as np
from deckpose.estimate.observations import Observations, group_observations, stack_detections
from deckpose.estimate.pose_candidates import BatchCandidates, Candidate, pick_candidates
from deckpose.estimate.pose_records import finish_batch
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.robust_search import estimate_robustly
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

FloatArray = NDArray[np.float64]


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
    (:func:`~estimate.robust_search.estimate_robustly`), which solves the subsets of all those
    frames stacked by beacon set and chooses between each frame's solutions with
    :func:`~estimate.pose_candidates.pick_candidates`.

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
    left = [f for f, e in enumerate(got) if e is None]
    if not left:
        return cast("list[PoseEstimate]", got)
    subsets = subset_candidates or candidates

    def solve(obs: Observations, frames: Sequence[int]) -> list[Candidate | str]:
        return pick_candidates(subsets(obs), ambiguity_chi2=options.ambiguity_chi2,
                               assume_level_deck=options.assume_level_deck, no_solution=no_solution)

    every = len(left) == len(detections)
    searched = estimate_robustly(method, solve, detections if every else [detections[f] for f in left], camera,
                                 layout, options, R_world_from_cam if every else R_world_from_cam[left],
                                 min_points=min_points, refined=refined)
    for f, e in zip(left, searched, strict=True):
        got[f] = e
    return cast("list[PoseEstimate]", got)
