"""Fits turned into :class:`~deckpose.records.PoseEstimate` records: the one home of the trust rules.

A fit makes an ok estimate when its pose and chi-square are finite, its information
matrix is positive definite, its covariance pins the pose down
(:func:`pose_constrained`) and its reprojection RMS is within the limit
(:func:`fit_tests`; :func:`fit_problem` says why not). A covariance that the residuals say is
too small is widened alike (:func:`covariance_scale`). :func:`make_estimate` judges one
frame's fit, ok or not (the robust search's); :func:`finish_batch` judges many frames at
once, where the batch settles them. Both end each record the same way: its head
(:func:`record_head`), the chosen solution's extras, the tail (:func:`record_tails`, in
the order of :data:`TAIL_EXTRAS`) and the verdict (:func:`pose_record`).
"""

from __future__ import annotations

import math

import numpy as np
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_candidates import (
    BatchCandidates,
    Candidate,
    candidate_extras,
    pick_batch,
    slot_values,
)
from deckpose.estimate.pose_model import relative_from_params, rotation_vectors
from numpy.typing import NDArray

from deckpose.estimates_schema import MAX_OUTLIER_IDS
from deckpose.records import POSE_PARAMS, PoseEstimate

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Median of a chi-square variable with 2 degrees of freedom (a point's squared Mahalanobis residual).
_MEDIAN_CHI2_2 = 2.0 * math.log(2.0)

#: Fewest points for which the residuals say anything about the detections' covariance scale.
MIN_POINTS_FOR_SCALE = 7

#: The detections' covariances are taken as underestimated when the robust scale exceeds this.
SCALE_TRIGGER = 2.0



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



#: An estimate whose angle sigmas exceed this (or whose height sigma exceeds its height) is not ok.
MAX_ANGLE_SIGMA_RAD = 0.5



def pose_constrained(params: np.ndarray, sigmas: np.ndarray) -> np.ndarray:
    """Whether each covariance pins its pose down at all.

    Every sigma finite, sigma height below the height, and every angle sigma below
    :data:`MAX_ANGLE_SIGMA_RAD` (near-coincident or collinear points give a finite but
    meaningless covariance). The one home of this test, for the batched
    estimates and the robust search's.

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
    # (comparisons with NaN give False without a warning: no errstate needed; a NaN or inf
    # sigma makes its row's sum non-finite)
    return (np.isfinite(np.add.reduce(sigmas, axis=1)) & (sigmas[:, 5] < np.abs(params[:, 5]))
            & np.logical_and.reduce(sigmas[:, :3] < MAX_ANGLE_SIGMA_RAD, axis=1))



def fit_tests(params: FloatArray, chi2: FloatArray, covariance_ok: BoolArray, sigmas: FloatArray,
              rms_px: FloatArray, max_reprojection_rms_px: float
              ) -> tuple[BoolArray, BoolArray, BoolArray, BoolArray]:
    """The tests a fit must pass to make an ok estimate: the one home of these tests.

    A fit makes an ok estimate where all four hold (:func:`fit_problem` says why not).

    Parameters
    ----------
    params : (F, 6) array of float
    chi2 : (F,) array of float
    covariance_ok : (F,) array of bool
        The information matrix is positive definite.
    sigmas : (F, 6) array of float
        Standard deviations of ``params`` (after :func:`covariance_scale`); NaN without a covariance.
    rms_px : (F,) array of float
        Reprojection RMS, pixels.
    max_reprojection_rms_px : float

    Returns
    -------
    finite : (F,) array of bool
        The pose and chi-square are finite.
    covariance_ok : (F,) array of bool
        The information matrix is positive definite (the covariance exists).
    constrained : (F,) array of bool
        :func:`pose_constrained`.
    rms_ok : (F,) array of bool
        The reprojection RMS is at most the limit (False where it is not finite).
    """
    # (comparisons with NaN give False without a warning; a NaN or inf in a row makes its sum
    # non-finite, and poses and chi-squares are far below overflow; the ufunc's own reduce
    # skips ndarray.sum's Python wrapper, which a lone frame pays for)
    return (np.isfinite(np.add.reduce(params, axis=1) + chi2), covariance_ok, pose_constrained(params, sigmas),
            rms_px <= max_reprojection_rms_px)


def fit_problem(params: FloatArray, chi2: float, covariance_ok: bool, sigmas: FloatArray, rms_px: float,
                max_reprojection_rms_px: float) -> str:
    """Why one frame's fit makes no ok estimate; ``""`` when it does.

    Parameters
    ----------
    params : (6,) array of float
    chi2 : float
    covariance_ok : bool
    sigmas : (6,) array of float
    rms_px : float
    max_reprojection_rms_px : float
    """
    finite, cov_ok, constrained, rms_ok = (bool(t[0]) for t in fit_tests(
        params[None], np.array([chi2]), np.array([covariance_ok]), sigmas[None], np.array([rms_px]),
        max_reprojection_rms_px))
    problems = []
    if not finite:
        problems.append("non-finite pose or reprojection error")
    elif not cov_ok:
        problems.append("covariance undefined: the beacons do not constrain all six parameters")
    elif not constrained:
        problems.append(
            f"the beacons hardly constrain the pose: sigma height {sigmas[5]:.3g} m for a height of "
            f"{params[5]:.3g} m, sigma roll/pitch/yaw up to {np.degrees(np.max(sigmas[:3])):.3g} deg "
            f"(limits: sigma height < height, angle sigmas < {np.degrees(MAX_ANGLE_SIGMA_RAD):.0f} deg)")
    if not rms_ok:
        problems.append(
            f"reprojection RMS {rms_px:.2f} px exceeds max_reprojection_rms_px={max_reprojection_rms_px}"
            if math.isfinite(rms_px) else "reprojection error is not finite")
    return "; ".join(problems)


#: The extras after the method's own and the ambiguity's, in the order of every record.
TAIL_EXTRAS = (("reprojection_rms_px", "chi2", "dof") + tuple("sigma_" + n for n in POSE_PARAMS)
                + tuple(name for ax in "xyz" for name in (f"rvec_cam_from_deck_{ax}", f"t_cam_from_deck_{ax}_m")))



def record_head(n_points: int, n_ignored: int, removed: list[int], refined: bool) -> dict[str, float]:
    """The first extras of every record, in order: the one home of this part of a record.

    ``n_points``, ``n_ignored``, ``n_outliers_removed``, ``refined``, then ``outlier_id_k``
    for the first :data:`~deckpose.estimates_schema.MAX_OUTLIER_IDS` ids removed.
    """
    head = {"n_points": float(n_points), "n_ignored": float(n_ignored),
            "n_outliers_removed": float(len(removed)), "refined": float(refined)}
    for k, i in enumerate(removed[:MAX_OUTLIER_IDS]):
        head[f"outlier_id_{k}"] = float(i)
    return head


def record_tails(rms_px: FloatArray, chi2: FloatArray, dof: float, sigmas: FloatArray, params: FloatArray,
                 R_world_from_cam: FloatArray) -> list[list[float]]:
    """The :data:`TAIL_EXTRAS` values of F records, as rows of floats: the one home of a record's tail.

    Parameters
    ----------
    rms_px, chi2 : (F,) array of float
        Reprojection RMS (px) and chi-square of each frame's fit.
    dof : float
        Degrees of freedom (twice the points, less six).
    sigmas : (F, 6) array of float
        Standard deviations of ``params`` (rad, m; NaN without a covariance).
    params : (F, 6) array of float
        Pose parameters; where they are not finite, so is the relative pose (``rvec``/``t``).
    R_world_from_cam : (F, 3, 3) array of float

    Returns
    -------
    list of F lists of 15 floats
    """
    # (a pose that is not finite makes matrices that are not: their rows are read only where
    # the pose is finite, :func:`pose_record`)
    R_cd, t_cd = relative_from_params(params, R_world_from_cam)
    tail = np.empty((params.shape[0], len(TAIL_EXTRAS)))
    tail[:, 0] = rms_px
    tail[:, 1] = chi2
    tail[:, 2] = dof
    tail[:, 3:9] = sigmas
    tail[:, 9::2] = rotation_vectors(R_cd)
    tail[:, 10::2] = t_cd
    return tail.tolist()


def pose_record(method: str, extras: dict[str, float], tail: list[float], params: list[float],
                covariance: FloatArray | None, covariance_scale: float, inliers: tuple[int, ...],
                problem: str = "") -> PoseEstimate:
    """One frame's record from its extras so far, its tail and its trust verdict: the one home of a record's end.

    The tail (:func:`record_tails`) follows ``extras`` (the :func:`record_head` and the
    chosen solution's extras): all of it for an ok record; for a failed one, the sigmas
    only where there is a covariance and the relative pose only where the pose is finite.
    ``covariance_scale`` follows where the covariance was widened. A ``problem`` makes a
    failed record that keeps the pose as ``untrusted_*`` extras; none makes an ok one (whose
    pose is finite and whose covariance exists: :func:`fit_tests`).

    Parameters
    ----------
    method : str
    extras : dict of str to float
        The record's extras so far; extended in place.
    tail : list of 15 float
        The frame's row of :func:`record_tails`.
    params : list of 6 float
        The pose (:data:`~deckpose.records.POSE_PARAMS`).
    covariance : (6, 6) array of float or None
        The pose's covariance after widening; None where it is undefined.
    covariance_scale : float
        The widening factor (:func:`covariance_scale`; 1 where not widened).
    inliers : tuple of int
        The beacon ids used.
    problem : str
        Why the record is not ok (``""`` for an ok record).
    """
    if not problem:
        extras.update(zip(TAIL_EXTRAS, tail))
    else:
        extras.update(zip(TAIL_EXTRAS[:3], tail[:3]))
        if covariance is not None:
            extras.update(zip(TAIL_EXTRAS[3:9], tail[3:9]))
        if all(map(math.isfinite, params)):
            extras.update(zip(TAIL_EXTRAS[9:], tail[9:]))
    if covariance is not None and covariance_scale > 1.0:
        extras["covariance_scale"] = covariance_scale
    if problem:
        for name, v in zip(POSE_PARAMS, params):
            extras["untrusted_" + name] = v
        return PoseEstimate.failed(method, problem, **extras)
    p = params
    return PoseEstimate(
        method=method, ok=True, roll_rad=p[0], pitch_rad=p[1], yaw_rad=p[2], height_m=p[5],
        surge_m=p[3], sway_m=p[4], covariance=covariance, inliers=inliers, extras=extras)


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
    extras = record_head(obs.n_points, n_ignored, removed, refined)
    if isinstance(result, str):
        return PoseEstimate.failed(method, result, **extras)
    fit = result.fit
    p = fit.params[0]
    extras.update(result.extras)
    covs, cov_ok = fit.covariance()
    finite = bool(np.isfinite(p).all())
    cov = covs[0] if cov_ok[0] and finite else None
    pc = fit.point_chi2()[0]
    scale = float(covariance_scale(pc)) if pc.size and np.isfinite(pc).all() else 1.0
    if cov is not None and scale > 1.0:
        # the residuals say the detections' covariances are too small: widen the pose's alike
        cov = cov * scale
    sig = np.sqrt(np.diag(cov)) if cov is not None else np.full(6, np.nan)
    problems = [result.problem] if result.problem else []
    problem = fit_problem(p, float(fit.chi2[0]), bool(cov_ok[0]), sig, float(fit.rms_px[0]), max_reprojection_rms_px)
    if problem:
        problems.append(problem)
    tail = record_tails(fit.rms_px, fit.chi2, float(2 * obs.n_points - 6), sig[None], fit.params,
                        obs.R_world_from_cam)[0]
    return pose_record(method, extras, tail, p.tolist(), cov, scale, tuple(obs.ids.tolist()), "; ".join(problems))


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
    """Choose each frame's solution and build its record; None where the robust search must decide.

    Frame by frame this is :func:`~estimate.pose_candidates.pick_candidates`, the first test of
    the robust search (:mod:`~estimate.robust_search`) and :func:`make_estimate` for the case
    where they produce an ok estimate without removing a point; the records end as
    :func:`make_estimate`'s do (:func:`record_tails`, :func:`pose_record`).
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
    # widen the covariance when the residuals exceed it alike (as make_estimate does)
    scale = covariance_scale(pc)
    rms = np.sqrt((res_px * res_px).sum(axis=(1, 2)) / M)
    cov = choice.covariance * scale[:, None, None]
    sig = np.sqrt(cov.reshape(F, 36)[:, ::7])  # the diagonals (``cov`` is a fresh product)
    chi2 = slot_values(cands.fits, "chi2", kb)
    # the frames where pick_candidates, the robust search's first test and make_estimate give an ok
    # estimate without removing a point
    settled = (choice.n_good > 0) & (pc.max(axis=1) <= outlier_chi2) & ~(cands.unsolved | choice.unresolved)
    finite, cov_ok, constrained, rms_ok = fit_tests(best_p, chi2, choice.covariance_ok, sig, rms,
                                                    max_reprojection_rms_px)
    settled &= finite & cov_ok & constrained & rms_ok
    settled_list = settled.tolist()
    if not any(settled_list):
        return [None] * F
    tails = record_tails(rms, chi2, float(2 * M - 6), sig, best_p, obs.R_world_from_cam)
    ids = tuple(obs.ids.tolist())
    head = record_head(M, 0, [], refined)
    chosen = candidate_extras(cands, choice, n_solutions=pick)
    n_ign = n_ignored.tolist()
    scale_list = scale.tolist()
    p_list = best_p.tolist()
    out: list[PoseEstimate | None] = []
    for i in range(F):
        if not settled_list[i]:
            out.append(None)
            continue
        ex = dict(head)
        ex["n_ignored"] = float(n_ign[i])
        ex.update(chosen[i])
        out.append(pose_record(method, ex, tails[i], p_list[i], cov[i], scale_list[i], ids))
    return out
