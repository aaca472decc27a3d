"""The robust search of one frame: outliers removed by leave-one-out, the result made a record.

For the frames an estimator's batch does not settle (:mod:`~estimate.frames_driver`): a
spurious point or a wrong id shows in its Mahalanobis reprojection residual, and the
search removes, one at a time, the point whose removal fits best
(:func:`solve_robust`); :func:`estimate_robustly` builds the frame's observations (a
batch of one), runs the search and makes the record
(:func:`~estimate.pose_records.make_estimate`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import cv2
import numpy as np
from deckpose.estimate.least_squares import levenberg_marquardt
from deckpose.estimate.observations import Observations, observe_frame
from deckpose.estimate.pose_candidates import Candidate
from deckpose.estimate.pose_records import covariance_scale, make_estimate

from deckpose.records import PoseEstimate

if TYPE_CHECKING:
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections


#: ``solve(observations) -> Candidate or failure reason`` for the observations of one frame.
SolveFn = Callable[[Observations], "Candidate | str"]


#: A fit accepted under the widened outlier threshold must have a reprojection RMS of at most
#: this: a larger residual is no centroid error a covariance understates but wrong points.
SCALED_MAX_RMS_PX = 1.0


#: Levenberg-Marquardt iterations of a leave-one-out trial (:func:`solve_robust`): a trial
#: only ranks which point to drop, from the current fit's pose.
TRIAL_ITERATIONS = 8


#: ``(observations of one frame, params (6,)) -> chi2 of each leave-one-out subset`` (n,).
RefitFn = Callable[[Observations, np.ndarray], np.ndarray]



def solve_robust(
    obs: Observations, solve: SolveFn, *, min_points: int, outlier_chi2: float, max_outliers: int,
    refit: RefitFn | None = None,
) -> tuple[Candidate | str, Observations, list[int]]:
    """Solve, and while a point's residual is an outlier remove the point whose removal fits best.

    A point is an outlier when its squared Mahalanobis residual exceeds ``outlier_chi2``.
    When that leaves residuals too large after ``max_outliers`` removals, and the first
    fit's :func:`covariance_scale` says the detections' covariances understate every
    residual alike (a clipped spot's centroid, say) while its reprojection RMS is at most
    :data:`SCALED_MAX_RMS_PX`, the search's fits are taken again at the threshold times that
    scale (the search at that threshold would remove the same points, only stop sooner). The
    plain search runs first because a least-squares fit smears a wrong id's residual over
    every point and would hide it in the scale.

    ``refit(observations, params) -> chi2 of each subset without one point`` ranks the
    leave-one-out trials from the current fit's pose (:data:`TRIAL_ITERATIONS` iterations,
    all subsets as one batch) instead of a full ``solve`` of each; the subset chosen is then
    solved in full. On garbage (19 points, three outliers allowed,
    both thresholds) the full trials took 62 solves and up to 0.3 s a frame.

    Returns
    -------
    (Candidate or failure reason, observations used, ids removed)
    """
    first = solve(obs) if obs.n_points >= min_points else _too_few(obs, min_points)
    states: list[tuple[Candidate, Observations, list[int]]] = []
    result, used, removed, residual_failure = _remove_outliers(
        obs, solve, first, min_points=min_points, threshold=outlier_chi2, max_outliers=max_outliers,
        refit=refit, states=states)
    if not (residual_failure and isinstance(result, Candidate)):
        return result, used, removed
    # The scale from the fit without the worst points, where a wrong point no longer smears.
    pc = result.fit.point_chi2()[0]
    scale = float(covariance_scale(pc)) if np.all(np.isfinite(pc)) else 1.0
    if scale <= 1.0:
        return result, used, removed
    # The search at the scaled threshold removes the same points in the same order (which
    # point to drop does not depend on the threshold); it only stops sooner: at the first
    # state of the search above whose residuals all lie within the scaled threshold. None
    # does: it gives up where the search above did.
    for c, c_obs, c_removed in states:
        c_pc = c.fit.point_chi2()[0]
        if c_pc.size == 0 or float(np.max(c_pc)) <= outlier_chi2 * scale:
            if float(c.fit.rms_px[0]) <= SCALED_MAX_RMS_PX:
                return c, c_obs, c_removed
            break
    return result, used, removed



def _remove_outliers(
    obs: Observations, solve: SolveFn, result: Candidate | str, *, min_points: int, threshold: float,
    max_outliers: int, refit: RefitFn | None = None,
    states: list[tuple[Candidate, Observations, list[int]]] | None = None,
) -> tuple[Candidate | str, Observations, list[int], bool]:
    """The leave-one-out search of :func:`solve_robust` at one threshold; the flag says
    whether it gave up with a residual above the threshold. ``states`` (when given) collects
    every fit the search went through, with its observations and the ids removed so far."""
    removed: list[int] = []
    while isinstance(result, Candidate):
        if states is not None:
            states.append((result, obs, list(removed)))
        pc = result.fit.point_chi2()[0]
        if pc.size == 0 or float(np.max(pc)) <= threshold:
            return result, obs, removed, False
        if len(removed) >= max_outliers or obs.n_points - 1 < min_points:
            worst = int(obs.ids[int(np.argmax(pc))])
            return Candidate(result.fit, result.extras, (
                f"reprojection residual of beacon {worst} is {math.sqrt(float(np.max(pc))):.1f} sigma "
                f"after removing {len(removed)} outlier(s): spurious point, wrong id, or sigma_px too small"
            )), obs, removed, True
        best: tuple[float, int, Candidate | None] = (math.inf, -1, None)
        if refit is not None:  # all trials in one batch; the chosen subset is solved below
            chi2 = np.asarray(refit(obs, result.fit.params[0]), float)
            chi2 = np.where(np.isfinite(chi2), chi2, np.inf)
            if chi2.size and np.isfinite(chi2.min()):
                best = (float(chi2.min()), int(np.argmin(chi2)), None)
        else:
            for i in range(obs.n_points):
                keep = np.ones(obs.n_points, dtype=bool)
                keep[i] = False
                r = solve(obs.points(keep))
                if isinstance(r, Candidate) and float(r.fit.chi2[0]) < best[0]:
                    best = (float(r.fit.chi2[0]), i, r)
        if best[1] < 0:
            return result, obs, removed, False
        keep = np.ones(obs.n_points, dtype=bool)
        keep[best[1]] = False
        chosen = best[2] if best[2] is not None else solve(obs.points(keep))
        if not isinstance(chosen, Candidate):
            return result, obs, removed, False
        removed.append(int(obs.ids[best[1]]))
        obs = obs.points(keep)
        result = chosen
    return result, obs, removed, False



def _too_few(obs: Observations, min_points: int) -> str:
    return f"too few identified beacons: {obs.n_points} usable, this method needs at least {min_points}"



def _trial_chi2(obs: Observations, params: np.ndarray) -> np.ndarray:
    """chi2 of each subset of one frame's ``obs`` without one point, (n,), after
    :data:`TRIAL_ITERATIONS` LM iterations from ``params`` (6,): all subsets as one batch, the
    left-out point given zero weight (it must still lie in front of the camera)."""
    n = obs.n_points
    sqrt_info = np.repeat(np.broadcast_to(obs.sqrt_info, (1, n, 2, 2)), n, axis=0)
    sqrt_info[np.arange(n), np.arange(n)] = 0.0
    rows = np.zeros(n, dtype=np.int64)
    stacked = Observations(obs.ids, obs.points_deck_m, obs.xy[rows], sqrt_info, obs.px_from_norm[rows],
                           obs.R_world_from_cam[rows])
    fit = levenberg_marquardt(np.repeat(np.asarray(params, float)[None], n, axis=0), stacked,
                              max_iterations=TRIAL_ITERATIONS)
    return np.where(np.isfinite(fit.chi2), fit.chi2, np.inf)



def estimate_robustly(
    method: str,
    solve: SolveFn,
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    *,
    min_points: int,
    refined: bool,
    failure_prefix: str = "numerical failure",
    R_world_from_cam: np.ndarray | None = None,
) -> PoseEstimate:
    """The shared frame of every least-squares estimator here.

    Builds the frame's observations (a batch of one), runs ``solve(observations)`` under
    :func:`solve_robust` (outlier removal), and turns the result into a
    :class:`PoseEstimate`; a numerical exception becomes a failed estimate whose
    reason starts with ``failure_prefix``. ``R_world_from_cam`` (3, 3), when given, is the
    frame's camera attitude instead of ``options.R_world_from_cam``.
    """
    R_wc = np.asarray(options.R_world_from_cam if R_world_from_cam is None else R_world_from_cam, dtype=float)
    with np.errstate(all="ignore"):
        try:
            group = observe_frame(detections, camera, layout, R_wc, sigma_px=options.sigma_px,
                                  use_detection_covariance=options.use_detection_covariance)
            result, used, removed = solve_robust(
                group.observations, solve, min_points=min_points,
                outlier_chi2=options.outlier_chi2, max_outliers=options.max_outliers, refit=_trial_chi2)
            return make_estimate(method, result, used, int(group.n_ignored[0]), removed,
                                 max_reprojection_rms_px=options.max_reprojection_rms_px,
                                 refined=refined)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, cv2.error) as exc:
            return PoseEstimate.failed(method, f"{failure_prefix}: {exc}")
