"""Maximum-likelihood refinement of any estimator's result (``--refine``).

Starting from an estimate (the thesis's, which has no surge or sway, starts
them at 0: the deck centre under the camera), minimise the reprojection error
of the identified beacons weighted by the detections' covariances, with the
same outlier removal, covariance and flags as the package's own estimators.

Batch-first (:func:`refine_estimates`): one stacked Levenberg–Marquardt per beacon
set; a lone estimate is a batch of one. A frame whose refined fit leaves an outlier
to remove or fails goes through the robust protocol
(:func:`~estimate.solution.estimate_robustly`), whose fit is the same batched
Levenberg–Marquardt on that frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Sequence

import numpy as np
from deckpose.estimate.least_squares import fit_of_row, frame_observations_of
from deckpose.estimate.least_squares_batch import levenberg_marquardt_batch
from deckpose.estimate.observations import Observations
from deckpose.estimate.observations_batch import group_observations, stack_detections
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution import Candidate, estimate_robustly
from deckpose.estimate.solution_batch import BatchCandidates, finish_batch

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

#: Identified beacons the refinement needs (6 parameters, 2 residuals per beacon, plus margin).
MIN_BEACONS = 4


def initial_params(estimate: PoseEstimate) -> np.ndarray | None:
    """The 6 pose parameters of an estimate; surge and sway default to 0. None if unusable."""
    p = [estimate.roll_rad, estimate.pitch_rad, estimate.yaw_rad,
         0.0 if math.isnan(estimate.surge_m) else estimate.surge_m,
         0.0 if math.isnan(estimate.sway_m) else estimate.sway_m, estimate.height_m]
    arr = np.array(p, dtype=float)
    return arr if np.all(np.isfinite(arr)) and arr[5] > 0 else None


def _merge(estimate: PoseEstimate, refined: PoseEstimate) -> PoseEstimate:
    """The refined record under the estimate's method, keeping the estimate's extras and values."""
    extras = {k: v for k, v in estimate.extras.items() if k not in refined.extras}
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "height_m", "surge_m", "sway_m"):
        extras["unrefined_" + name] = float(getattr(estimate, name))
    extras.update(refined.extras)
    return dataclasses.replace(refined, method=estimate.method, extras=extras)


#: The reason of a refinement that failed numerically starts with this (the estimate is not merged).
FAILURE_PREFIX = "refinement failed numerically"


def _refine_robustly(estimate: PoseEstimate, p0: np.ndarray, detections: Detections, camera: CameraModel,
                     layout: DeckLayout, options: EstimateOptions, R_world_from_cam: np.ndarray) -> PoseEstimate:
    """One frame through the robust protocol (outlier removal, failure reasons) from ``p0``."""
    def solve(o: Observations, R_wc: np.ndarray) -> Candidate | str:
        fit = levenberg_marquardt_batch(p0[None], frame_observations_of(o, R_wc))
        return Candidate(fit_of_row(fit, 0))

    refined = estimate_robustly(estimate.method, solve, detections, camera, layout, options,
                                min_points=MIN_BEACONS, refined=True, failure_prefix=FAILURE_PREFIX,
                                R_world_from_cam=R_world_from_cam)
    if not refined.ok and refined.reason.startswith(FAILURE_PREFIX):
        return refined
    return _merge(estimate, refined)


def refine_estimates(
    estimates: Sequence[PoseEstimate],
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    R_world_from_cam: np.ndarray,
    *,
    skip: Collection[int] = (),
) -> list[PoseEstimate]:
    """Refine each estimate to the maximum-likelihood pose: one stacked Levenberg–Marquardt per beacon set.

    Parameters
    ----------
    estimates : sequence of PoseEstimate
        Any estimator's results, one per frame; a failed one, or one already refined
        (``extras["refined"]``), is returned unchanged.
    detections : sequence of Detections
        The frames' detections, as for the estimator that produced them.
    camera, layout, options
        As for that estimator.
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude.
    skip : collection of int, keyword-only
        Frames returned unchanged.

    Returns
    -------
    list of PoseEstimate
        Same ``method``; ``extras["refined"] = 1`` plus the original extras (the
        original values under ``unrefined_*``).
    """
    out = list(estimates)
    todo = [i for i, e in enumerate(estimates)
            if i not in skip and e.ok and not e.extras.get("refined", 0.0)]
    p0 = {i: initial_params(estimates[i]) for i in todo}
    todo = [i for i in todo if p0[i] is not None]
    if not todo:
        return out
    sub = [detections[i] for i in todo]
    groups = group_observations(stack_detections(sub), camera, layout, R_world_from_cam[todo],
                                sigma_px=options.sigma_px,
                                use_detection_covariance=options.use_detection_covariance)
    done: dict[int, PoseEstimate] = {}
    for g in groups:
        if g.observations.ids.size < MIN_BEACONS:
            continue
        frames = [todo[f] for f in g.frames.tolist()]
        starts = np.array([p0[i] for i in frames])
        with np.errstate(all="ignore"):
            fit = levenberg_marquardt_batch(starts, g.observations)
            F = len(frames)
            cands = BatchCandidates((fit,), np.ones((F, 1), dtype=bool), np.zeros(F, dtype=bool))
            ests = finish_batch("", cands, g.observations, g.n_ignored, ambiguity_chi2=options.ambiguity_chi2,
                                outlier_chi2=options.outlier_chi2,
                                max_reprojection_rms_px=options.max_reprojection_rms_px,
                                refined=True, pick=False)
        for i, e in zip(frames, ests):
            if e is not None:
                done[i] = _merge(estimates[i], e)
    for i in todo:
        p = p0[i]
        if i in done:
            out[i] = done[i]
        elif p is not None:  # an outlier to remove, too few beacons or a failure
            out[i] = _refine_robustly(estimates[i], p, detections[i], camera, layout, options,
                                      R_world_from_cam[i])
    return out
