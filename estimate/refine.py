"""Maximum-likelihood refinement of any estimator's result (``--refine``), batch-first.

Starting from an estimate (the thesis's, which has no surge or sway, starts
them at 0: the deck centre under the camera), minimise the reprojection error
of the identified beacons weighted by the detections' covariances, with the
same outlier removal, covariance and flags as the package's own estimators.
:func:`refine_estimates` runs one stacked Levenberg–Marquardt per beacon set; a
lone frame (:func:`refine_estimate`) is a batch of one. Frames the batch cannot
settle (an outlier to remove, any failure) go through the robust search of
:mod:`~estimate.robust_search`, which refines their subsets stacked by beacon set.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from deckpose.estimate.least_squares import levenberg_marquardt
from deckpose.estimate.observations import Observations, group_observations, stack_detections
from deckpose.estimate.pose_candidates import BatchCandidates, Candidate
from deckpose.estimate.pose_records import finish_batch
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.robust_search import estimate_robustly

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
    return arr if np.isfinite(arr).all() and arr[5] > 0 else None


def refine_estimate(
    estimate: PoseEstimate,
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
) -> PoseEstimate:
    """Refine ``estimate`` to the maximum-likelihood pose: a batch of one of :func:`refine_estimates`.

    Parameters
    ----------
    estimate : PoseEstimate
        Any estimator's result; a failed one is returned unchanged.
    detections, camera, layout, options
        As for the estimator that produced it.

    Returns
    -------
    PoseEstimate
        Same ``method``; ``extras["refined"] = 1`` plus the original extras
        (the original values under ``unrefined_*``).
    """
    R = np.asarray(options.R_world_from_cam, dtype=float)[None]
    return refine_estimates([estimate], [detections], camera, layout, options, R)[0]


def _refine_robustly(estimates: Sequence[PoseEstimate], p0: np.ndarray, detections: Sequence[Detections],
                     camera: CameraModel, layout: DeckLayout, options: EstimateOptions,
                     R_world_from_cam: np.ndarray) -> list[PoseEstimate]:
    """The frames the batch left open, through the robust search (their subsets stacked; ``p0`` (F, 6))."""
    def solve(o: Observations, frames: Sequence[int]) -> list[Candidate | str]:
        fit = levenberg_marquardt(p0[list(frames)], o)
        return [Candidate(fit.frame(k)) for k in range(len(frames))]

    prefix = "refinement failed numerically"
    refined = estimate_robustly(estimates[0].method, solve, detections, camera, layout, options, R_world_from_cam,
                                min_points=MIN_BEACONS, refined=True, failure_prefix=prefix)
    # (a failed record carries its own estimate's method)
    return [r.relabelled(e.method, r.extras) if not r.ok and r.reason.startswith(prefix) else _merge(e, r)
            for e, r in zip(estimates, refined, strict=True)]


def _merge(estimate: PoseEstimate, refined: PoseEstimate) -> PoseEstimate:
    """The refined record under the estimate's method, keeping the estimate's extras and values."""
    extras = {k: v for k, v in estimate.extras.items() if k not in refined.extras}
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "height_m", "surge_m", "sway_m"):
        extras["unrefined_" + name] = float(getattr(estimate, name))
    extras.update(refined.extras)
    return refined.relabelled(estimate.method, extras)


def refine_estimates(
    estimates: Sequence[PoseEstimate],
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    R_world_from_cam: np.ndarray,
) -> list[PoseEstimate]:
    """Refine many frames' estimates: one stacked Levenberg–Marquardt per beacon set.

    Parameters
    ----------
    estimates : sequence of PoseEstimate
        Any estimator's results, one per frame.
    detections : sequence of Detections
    camera, layout, options
        As for the estimator that produced them.
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude.

    Returns
    -------
    list of PoseEstimate
        Same ``method`` each; ``extras["refined"] = 1`` plus the original extras (the
        original values under ``unrefined_*``). A failed or already refined estimate
        comes back unchanged.
    """
    out = list(estimates)
    p0: dict[int, np.ndarray] = {}
    for i, e in enumerate(estimates):
        p = initial_params(e) if e.ok and not e.extras.get("refined", 0.0) else None
        if p is not None:
            p0[i] = p
    todo = list(p0)
    if not todo:
        return out
    every = len(todo) == len(estimates)  # (a lone frame): no gathers
    sub = detections if every else [detections[i] for i in todo]
    groups = group_observations(stack_detections(sub), camera, layout,
                                R_world_from_cam if every else R_world_from_cam[todo],
                                sigma_px=options.sigma_px,
                                use_detection_covariance=options.use_detection_covariance)
    done: dict[int, PoseEstimate] = {}
    for g in groups:
        if g.observations.ids.size < MIN_BEACONS:
            continue
        frames = [todo[f] for f in g.frames.tolist()]
        starts = np.array([p0[i] for i in frames])
        with np.errstate(all="ignore"):
            fit = levenberg_marquardt(starts, g.observations)
            F = len(frames)
            cands = BatchCandidates((fit,), np.ones((F, 1), dtype=bool), np.zeros(F, dtype=bool))
            ests = finish_batch("", cands, g.observations, g.n_ignored, ambiguity_chi2=options.ambiguity_chi2,
                                outlier_chi2=options.outlier_chi2,
                                max_reprojection_rms_px=options.max_reprojection_rms_px,
                                refined=True, pick=False)
        for i, e in zip(frames, ests):
            if e is not None:
                done[i] = _merge(estimates[i], e)
    left = []  # an outlier to remove or a failure: the robust search
    for i in todo:
        if i in done:
            out[i] = done[i]
        else:
            left.append(i)
    if left:
        searched = _refine_robustly([estimates[i] for i in left], np.array([p0[i] for i in left]),
                                    [detections[i] for i in left], camera, layout, options,
                                    np.asarray(R_world_from_cam)[left])
        for i, e in zip(left, searched, strict=True):
            out[i] = e
    return out
