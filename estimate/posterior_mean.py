"""The posterior mean of the pose under a uniform prior, around a maximum-likelihood fit.

Where the signal-to-noise ratio is low (2 px of noise on a ring 377 x 282 px
across: 4 MP at 80 m) the likelihood of the six pose parameters is no longer
Gaussian: its tilt direction is curved, and the maximum-likelihood (ML)
estimate's errors grow heavier tails than the Cramér–Rao bound describes
(``reports/ml_low_snr.txt``). The mean of the posterior under a uniform prior on
(roll, pitch, yaw, surge, sway, height) averages over that shape instead of
taking its peak, and has a lower RMS error there; where the likelihood is
Gaussian it is the ML estimate.

The mean is found by importance sampling with a fixed set of nodes: a
multivariate Student-t proposal (``T_DOF`` degrees of freedom) centred on the ML
estimate, scaled by its covariance ``(J^T Sigma^-1 J)^-1``, at ``N_NODES``
scrambled-Sobol points taken in antithetic pairs (each node and its mirror
image). The nodes are drawn once from a constant seed, so the result is a
deterministic function of the detections; the pairs make it exactly the ML
estimate wherever the likelihood is symmetric about its peak.

The estimate is biased (it trades bias for variance), so the Cramér–Rao bound,
which holds for unbiased estimators, does not bound its error.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from deckpose.estimate.observations import (
    Observations,
    group_observations,
    observe_frame,
    stack_detections,
)
from deckpose.estimate.pose_model import project_normalised, relative_from_params, rotation_vectors
from numpy.typing import NDArray
from scipy import stats
from scipy.stats import qmc

from deckpose.records import POSE_PARAMS, Detections, PoseEstimate

if TYPE_CHECKING:
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout

FloatArray = NDArray[np.float64]

#: Importance-sampling nodes per frame (half of them the mirror images of the other half).
N_NODES = 128
#: Degrees of freedom of the Student-t proposal (heavier tails than the likelihood's).
T_DOF = 10.0
#: Below this effective number of nodes the sample cannot be trusted and the ML estimate is kept.
MIN_EFFECTIVE_NODES = 8.0
#: Fixed seed of the node set (the estimate must not depend on a caller's generator).
_NODE_SEED = 20261125
#: Frames per stacked likelihood evaluation (bounds memory at N_NODES x this x beacons).
_FRAMES_PER_CALL = 64


@functools.cache
def unit_nodes() -> tuple[FloatArray, FloatArray]:
    """The proposal's nodes for a unit covariance and their log densities (up to a constant).

    Returns
    -------
    nodes : (N_NODES, 6) array of float
        Student-t points, in antithetic pairs (``nodes[k + N/2] = -nodes[k]``).
    log_density : (N_NODES,) array of float
        Log of the proposal density at each node, without its normalising constant.
    """
    half = N_NODES // 2
    u = qmc.Sobol(7, scramble=True, rng=np.random.default_rng(_NODE_SEED)).random(half)
    z = stats.norm.ppf(u[:, :6])
    w = stats.chi2.ppf(u[:, 6], T_DOF) / T_DOF
    x = z / np.sqrt(w)[:, None]
    x = np.vstack([x, -x])
    log_q = -0.5 * (6.0 + T_DOF) * np.log1p(np.sum(x * x, axis=1) / T_DOF)
    x.setflags(write=False)
    log_q.setflags(write=False)
    return x, log_q


def chi2_at_nodes(params: FloatArray, obs: Observations) -> FloatArray:
    """Chi-square of ``S`` poses of each of ``F`` frames against that frame's observations.

    :func:`~estimate.least_squares.chi2_at` for ``S`` poses per frame, without
    copying the observations ``S`` times.

    Parameters
    ----------
    params : (F, S, 6) array of float
        Pose parameters (roll, pitch, yaw in rad; surge, sway, height in m).
    obs : Observations
        ``F`` frames.

    Returns
    -------
    (F, S) array of float
        Sum of squared whitened residuals; inf where a beacon is not in front of the camera.
    """
    F, S = params.shape[:2]
    R_wc = np.broadcast_to(obs.R_world_from_cam[:, None], (F, S, 3, 3)).reshape(F * S, 3, 3)
    xy, _, Z = project_normalised(params.reshape(F * S, 6), obs.points_deck_m, R_wc, jacobian=False)
    M = obs.points_deck_m.shape[0]
    xy, Z = xy.reshape(F, S, M, 2), Z.reshape(F, S, M)
    rx = xy[..., 0] - obs.xy[:, None, :, 0]
    ry = xy[..., 1] - obs.xy[:, None, :, 1]
    Li = obs.sqrt_info[:, None]  # (F, 1, M or 1, 2, 2)
    wx = Li[..., 0, 0] * rx + Li[..., 0, 1] * ry
    wy = Li[..., 1, 0] * rx + Li[..., 1, 1] * ry
    c = np.sum(wx * wx + wy * wy, axis=2)
    return np.where((Z > 0).all(axis=2) & np.isfinite(c), c, np.inf)


def posterior_moments_batch(
    params_ml: FloatArray, covariance_ml: FloatArray, obs: Observations
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Posterior mean and covariance of the pose of ``F`` frames under a uniform prior.

    Parameters
    ----------
    params_ml : (F, 6) array of float
        Maximum-likelihood pose parameters (roll, pitch, yaw in rad; surge, sway,
        height in m), the proposal's centre.
    covariance_ml : (F, 6, 6) array of float
        Their covariance ``(J^T Sigma^-1 J)^-1``, the proposal's scale; must be
        positive definite.
    obs : Observations
        The observations the likelihood is evaluated on (whitened as in the fit).

    Returns
    -------
    mean : (F, 6) array of float
        Posterior mean; angles wrapped to [-pi, pi). NaN where the sample has
        fewer than :data:`MIN_EFFECTIVE_NODES` effective nodes.
    covariance : (F, 6, 6) array of float
        Posterior covariance (NaN where the mean is).
    effective_nodes : (F,) array of float
        Kish's effective sample size ``1 / sum(w^2)`` of the normalised weights.
    """
    params_ml = np.asarray(params_ml, dtype=float)
    F = params_ml.shape[0]
    x, log_q = unit_nodes()
    C = np.array(covariance_ml, dtype=float)
    with np.errstate(invalid="ignore"):
        is_pd = np.logical_and.reduce(np.isfinite(C), axis=(1, 2))
        is_pd[is_pd] = (np.linalg.eigvalsh(C[is_pd]) > 0).all(axis=1)
    C[~is_pd] = np.eye(6)
    L = np.linalg.cholesky(C)  # (F, 6, 6)
    mean = np.empty((F, 6))
    cov = np.empty((F, 6, 6))
    ess = np.empty(F)
    for lo in range(0, F, _FRAMES_PER_CALL):
        sl = slice(lo, min(F, lo + _FRAMES_PER_CALL))
        dx = np.einsum("fij,sj->fsi", L[sl], x)  # (n, S, 6)
        chi2 = chi2_at_nodes(params_ml[sl, None, :] + dx, obs.take(np.arange(sl.start, sl.stop)))
        log_w = -0.5 * chi2 - log_q[None, :]
        with np.errstate(invalid="ignore"):
            log_w -= np.max(log_w, axis=1, keepdims=True)
        w = np.exp(log_w)
        w /= np.sum(w, axis=1, keepdims=True)
        d_mean = np.einsum("fs,fsi->fi", w, dx)
        centred = dx - d_mean[:, None, :]
        mean[sl] = params_ml[sl] + d_mean
        cov[sl] = np.einsum("fs,fsi,fsj->fij", w, centred, centred)
        ess[sl] = 1.0 / np.sum(w * w, axis=1)
    bad = ~is_pd | ~(ess >= MIN_EFFECTIVE_NODES) | ~np.isfinite(mean).all(axis=1)
    mean[bad] = np.nan
    cov[bad] = np.nan
    mean[:, :3] = (mean[:, :3] + np.pi) % (2.0 * np.pi) - np.pi
    return mean, cov, np.where(np.isfinite(ess), ess, 0.0)


def _inlier_detections(det: Detections, est: PoseEstimate, camera: CameraModel, layout: DeckLayout,
                       options: EstimateOptions, R_world_from_cam: FloatArray) -> Detections | None:
    """The detections the estimate's fit used: its inlier ids, one detection each.

    Where an inlier id was detected more than once, the fit kept one of them (the
    others were removed as outliers); it is the one nearest the estimate's
    projection of that beacon. None if the inliers cannot be matched.
    """
    ids = np.asarray(det.beacon_ids)
    inliers = np.asarray(est.inliers, dtype=np.int64)
    if ids.size == inliers.size and np.array_equal(np.sort(ids), np.sort(inliers)):
        return det
    keep = np.isin(ids, inliers)
    if np.count_nonzero(keep) > inliers.size:  # a beacon detected twice: keep the row the fit kept
        group = observe_frame(det, camera, layout, R_world_from_cam, sigma_px=options.sigma_px,
                              use_detection_covariance=options.use_detection_covariance)
        obs = group.observations
        p = np.array([[getattr(est, q) for q in POSE_PARAMS]])
        xy, _, _ = project_normalised(p, obs.points_deck_m, obs.R_world_from_cam, jacobian=False)
        r = obs.sqrt_info @ (obs.xy - xy)[:, :, :, None]
        dist = np.sum(r * r, axis=(2, 3))[0]
        keep = np.zeros(ids.size, dtype=bool)
        for b in inliers:
            rows = np.flatnonzero(obs.ids == b)
            if rows.size == 0:
                return None
            keep[group.detection_rows[0, rows[np.argmin(dist[rows])]]] = True
    if np.count_nonzero(keep) != inliers.size:
        return None
    return Detections(np.asarray(det.points_px)[keep], ids[keep], np.asarray(det.covariance_px2)[keep],
                      frame_id=det.frame_id)


def apply_posterior_mean(
    estimates: Sequence[PoseEstimate],
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    R_world_from_cam: FloatArray,
) -> list[PoseEstimate]:
    """Replace each refined estimate's maximum-likelihood pose by its posterior mean.

    Parameters
    ----------
    estimates : sequence of PoseEstimate
        One per frame; only ok, refined ones (``extras["refined"] = 1``) with a
        covariance change.
    detections : sequence of Detections
        The frames' detections; the likelihood uses the estimate's inliers only,
        weighted as the fit was (``options``' covariance choice, widened by
        ``extras["covariance_scale"]``).
    camera, layout, options
        As for the estimator.
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude.

    Returns
    -------
    list of PoseEstimate
        The pose is the posterior mean; ``extras`` add ``posterior_mean = 1``,
        ``ml_<param>`` (the maximum-likelihood pose), ``posterior_sigma_<param>``,
        ``posterior_effective_nodes`` and the ``rvec``/``t_cam_from_deck`` of the
        new pose. The covariance, chi-square and reprojection RMS stay those of
        the maximum-likelihood fit. Where the sample is too poor
        (:data:`MIN_EFFECTIVE_NODES`), or the fit's detections cannot be told
        apart from the others, the estimate keeps its ML pose with
        ``posterior_mean = 0``.
    """
    out = list(estimates)
    todo, sub = [], []
    for i, e in enumerate(estimates):
        if e.ok and e.covariance is not None and e.extras.get("refined", 0.0):
            d = _inlier_detections(detections[i], e, camera, layout, options, R_world_from_cam[i])
            if d is None:
                out[i] = _with_mean(e, np.full(6, np.nan), np.full((6, 6), np.nan), 0.0, np.zeros(3),
                                    np.zeros(3))
            else:
                todo.append(i)
                sub.append(d)
    if not todo:
        return out
    groups = group_observations(stack_detections(sub), camera, layout, R_world_from_cam[todo],
                                sigma_px=options.sigma_px,
                                use_detection_covariance=options.use_detection_covariance)
    for g in groups:
        frames = [todo[f] for f in g.frames.tolist()]
        scale = np.array([estimates[i].extras.get("covariance_scale", 1.0) for i in frames])
        obs = dataclasses.replace(g.observations,
                                  sqrt_info=g.observations.sqrt_info / np.sqrt(scale)[:, None, None, None])
        p_ml = np.array([[getattr(estimates[i], q) for q in POSE_PARAMS] for i in frames])
        cov_ml = np.array([estimates[i].covariance for i in frames])
        with np.errstate(all="ignore"):
            mean, cov, ess = posterior_moments_batch(p_ml, cov_ml, obs)
            R_cd, t_cd = relative_from_params(np.nan_to_num(mean), obs.R_world_from_cam)
            rvec = rotation_vectors(R_cd)
        for k, i in enumerate(frames):
            out[i] = _with_mean(estimates[i], mean[k], cov[k], float(ess[k]), rvec[k], t_cd[k])
    for i in todo:
        if "posterior_mean" not in out[i].extras:  # no usable observations after all
            out[i] = _with_mean(estimates[i], np.full(6, np.nan), np.full((6, 6), np.nan), 0.0,
                                np.zeros(3), np.zeros(3))
    return out


def _with_mean(est: PoseEstimate, mean: FloatArray, cov: FloatArray, ess: float, rvec: FloatArray,
               t_cd: FloatArray) -> PoseEstimate:
    extras = dict(est.extras)
    extras["posterior_effective_nodes"] = ess
    for name in POSE_PARAMS:
        extras["ml_" + name] = float(getattr(est, name))
    if not np.isfinite(mean).all():
        extras["posterior_mean"] = 0.0
        return dataclasses.replace(est, extras=extras)
    extras["posterior_mean"] = 1.0
    for name, s in zip(POSE_PARAMS, np.sqrt(np.diag(cov))):
        extras["posterior_sigma_" + name] = float(s)
    for k, ax in enumerate("xyz"):
        extras[f"rvec_cam_from_deck_{ax}"] = float(rvec[k])
        extras[f"t_cam_from_deck_{ax}_m"] = float(t_cd[k])
    values = {name: float(v) for name, v in zip(POSE_PARAMS, mean)}
    return dataclasses.replace(est, extras=extras, **values)
