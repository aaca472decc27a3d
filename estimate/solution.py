"""From one frame's candidate fits to an honest :class:`~deckpose.records.PoseEstimate`.

Shared by every estimator of this package, for the frames their batches do not
settle (:mod:`~estimate.solution_batch`); each works on a batch of one frame:

* :func:`solve_robust` — detect spurious points and wrong ids by their
  Mahalanobis reprojection residual and remove them (leave-one-out);
* :func:`make_estimate` — covariance ``(J^T Sigma^-1 J)^-1``, per-parameter sigma,
  reprojection RMS and the ``ok`` flag with its reason.
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
from deckpose.estimate.pose_model import relative_from_params

from deckpose.estimates_schema import MAX_OUTLIER_IDS
from deckpose.records import POSE_PARAMS, PoseEstimate

if TYPE_CHECKING:
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections


#: ``solve(observations) -> Candidate or failure reason`` for the observations of one frame.
SolveFn = Callable[[Observations], "Candidate | str"]

#: Median of a chi-square variable with 2 degrees of freedom (a point's squared Mahalanobis residual).
_MEDIAN_CHI2_2 = 2.0 * math.log(2.0)
#: Fewest points for which the residuals say anything about the detections' covariance scale.
MIN_POINTS_FOR_SCALE = 7
#: The detections' covariances are taken as underestimated when the robust scale exceeds this.
SCALE_TRIGGER = 2.0
#: A fit accepted under the widened outlier threshold must have a reprojection RMS of at most
#: this: a larger residual is no centroid error a covariance understates but wrong points.
SCALED_MAX_RMS_PX = 1.0


def covariance_scale(point_chi2: np.ndarray) -> np.ndarray:
    """Robust factor by which the detections' covariances understate the residuals.

    ``median(point chi2) / (ln 4 (N - 3) / N)``: the median of the squared Mahalanobis
    residuals over its expectation for a six-parameter fit to ``N`` points with correct
    covariances. The median is untouched by a few spurious points or wrong ids, so a
    detector that understates every point's covariance alike (a clipped spot's centroid
    is worse than its photon noise says) is told apart from an outlier. Factors up to
    :data:`SCALE_TRIGGER` (chance with correct covariances) and fits to fewer than
    :data:`MIN_POINTS_FOR_SCALE` points give 1.

    Parameters
    ----------
    point_chi2 : ndarray, shape (..., N)
        Each point's squared Mahalanobis reprojection residual (NaN for a missing point
        is not allowed; pass the points used).

    Returns
    -------
    ndarray, shape (...)
        The factor (>= 1) to multiply the covariances and the outlier threshold by.
    """
    pc = np.asarray(point_chi2, dtype=float)
    n = pc.shape[-1]
    if n < MIN_POINTS_FOR_SCALE:
        return np.ones(pc.shape[:-1])
    # (no errstate: NaN and inf here only propagate or compare, which numpy does without a warning;
    # the values are squares, so no inf - inf arises)
    # the median through one sort (np.median's dispatch costs more than the sort of a few points)
    srt = np.sort(pc, axis=-1)
    h = n // 2
    med = srt[..., h] if n % 2 else (srt[..., h - 1] + srt[..., h]) / 2.0
    med = np.where(np.isnan(srt[..., -1]), np.nan, med)  # NaN sorts last; np.median gives NaN
    s2 = med / (_MEDIAN_CHI2_2 * (n - 3) / n)
    return np.where(s2 > SCALE_TRIGGER, s2, 1.0)


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


#: An estimate whose angle sigmas exceed this (or whose height sigma exceeds its height) is not ok.
MAX_ANGLE_SIGMA_RAD = 0.5


def pose_constrained(params: np.ndarray, sigmas: np.ndarray) -> np.ndarray:
    """Whether each covariance pins its pose down at all.

    Every sigma finite, sigma height below the height, and every angle sigma below
    :data:`MAX_ANGLE_SIGMA_RAD` (near-coincident or collinear points give a finite but
    meaningless covariance). The one home of this test, for the single-frame and the
    batched estimates.

    Parameters
    ----------
    params : (F, 6) array of float
        Pose parameters (:data:`~deckpose.records.POSE_PARAMS`).
    sigmas : (F, 6) array of float
        Their standard deviations (rad, m).

    Returns
    -------
    (F,) array of bool
    """
    # (comparisons with NaN give False without a warning: no errstate needed)
    return (np.isfinite(sigmas).all(axis=1) & (sigmas[:, 5] < np.abs(params[:, 5]))
            & (sigmas[:, :3] < MAX_ANGLE_SIGMA_RAD).all(axis=1))


def make_estimate(
    method: str,
    result: Candidate | str,
    obs: Observations,
    n_ignored: int,
    removed: list[int],
    *,
    max_reprojection_rms_px: float,
    refined: bool,
) -> PoseEstimate:
    """Assemble one frame's estimate with covariance, sigmas, reprojection RMS and honest flags.

    Parameters
    ----------
    method : str
    result : Candidate or str
        The robust search's result (a failure reason as a str).
    obs : Observations
        The points it used, of one frame (``F = 1``).
    n_ignored : int
        The frame's detections not used.
    removed : list of int
        Ids removed as outliers.
    max_reprojection_rms_px : float, keyword-only
    refined : bool, keyword-only

    Returns
    -------
    PoseEstimate
    """
    base = {"n_points": float(obs.n_points), "n_ignored": float(n_ignored),
            "n_outliers_removed": float(len(removed)), "refined": float(refined)}
    for k, i in enumerate(removed[:MAX_OUTLIER_IDS]):
        base[f"outlier_id_{k}"] = float(i)
    if isinstance(result, str):
        return PoseEstimate.failed(method, result, **base)
    fit = result.fit
    p = fit.params[0]
    rms_px, chi2 = float(fit.rms_px[0]), float(fit.chi2[0])
    extras = dict(base)
    extras.update(result.extras)
    extras["reprojection_rms_px"] = rms_px
    extras["chi2"] = chi2
    extras["dof"] = float(2 * obs.n_points - 6)
    problems = []
    if result.problem:
        problems.append(result.problem)
    covs, cov_ok = fit.covariance()
    cov = covs[0] if cov_ok[0] and np.all(np.isfinite(p)) else None
    pc = fit.point_chi2()[0]
    scale = float(covariance_scale(pc)) if pc.size and np.all(np.isfinite(pc)) else 1.0
    if cov is not None and scale > 1.0:
        # the residuals say the detections' covariances are too small: widen the pose's alike
        cov = cov * scale
    if not np.all(np.isfinite(p)) or not math.isfinite(chi2):
        problems.append("non-finite pose or reprojection error")
    elif cov is None:
        problems.append("covariance undefined: the beacons do not constrain all six parameters")
    elif not pose_constrained(p[None], np.sqrt(np.diag(cov))[None])[0]:
        problems.append(
            f"the beacons hardly constrain the pose: sigma height {np.sqrt(cov[5, 5]):.3g} m for a height of "
            f"{p[5]:.3g} m, sigma roll/pitch/yaw up to {np.degrees(np.sqrt(np.max(np.diag(cov)[:3]))):.3g} deg "
            f"(limits: sigma height < height, angle sigmas < {np.degrees(MAX_ANGLE_SIGMA_RAD):.0f} deg)")
    if math.isfinite(rms_px) and rms_px > max_reprojection_rms_px:
        problems.append(
            f"reprojection RMS {rms_px:.2f} px exceeds max_reprojection_rms_px={max_reprojection_rms_px}")
    elif not math.isfinite(rms_px):
        problems.append("reprojection error is not finite")
    if cov is not None:
        for name, v in zip(POSE_PARAMS, np.diag(cov)):
            extras["sigma_" + name] = float(np.sqrt(v))
    if np.all(np.isfinite(p)):
        R_cd, t_cd = relative_from_params(p, obs.R_world_from_cam[0])
        rvec = cv2.Rodrigues(R_cd)[0].ravel()
        for k, ax in enumerate("xyz"):
            extras[f"rvec_cam_from_deck_{ax}"] = float(rvec[k])
            extras[f"t_cam_from_deck_{ax}_m"] = float(t_cd[k])
    if cov is not None and scale > 1.0:
        extras["covariance_scale"] = scale
    if problems:
        for name, v in zip(POSE_PARAMS, p):
            extras["untrusted_" + name] = float(v)
        return PoseEstimate.failed(method, "; ".join(problems), **extras)
    return PoseEstimate(
        method=method, ok=True, roll_rad=float(p[0]), pitch_rad=float(p[1]), yaw_rad=float(p[2]),
        height_m=float(p[5]), surge_m=float(p[3]), sway_m=float(p[4]), covariance=cov,
        inliers=tuple(obs.ids.tolist()), extras=extras,
    )


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
