"""The ``pnp`` estimator: OpenCV SQPnP and IPPE on identified beacons, then Levenberg–Marquardt.

The beacons are undistorted and normalised first (so the solvers see an ideal
camera with ``K = I``); SQPnP gives the global minimiser of its algebraic error
and IPPE the two solutions of the planar two-fold ambiguity. Each distinct
solution is refined by minimising the (covariance-weighted) reprojection error;
the better one wins, and the result reports IPPE's second solution, the ratio
of IPPE's two reprojection errors and whether the ambiguity is resolved. EPnP is
not used: it fails on this coplanar layout even without noise.
"""

from __future__ import annotations

import cv2
import numpy as np
from deckpose.estimate.least_squares import Fit, chi2_at, levenberg_marquardt
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_model import params_from_relative
from deckpose.estimate.registry import EstimateOptions, register
from deckpose.estimate.solution import Candidate, estimate_robustly, pick_candidate

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import wrap_angle_rad

#: Identified beacons PnP needs (IPPE's minimum for a planar target).
MIN_BEACONS = 4
#: The camera matrix of normalised image coordinates (PnP runs on undistorted, K-removed points).
K_NORMALISED = np.eye(3)
#: An unrefined alternative solution is refined only if its chi2 is within this of the best.
ALT_MARGIN_CHI2 = 100.0


def params_from_rodrigues(rvec: np.ndarray, tvec: np.ndarray, R_world_from_cam: np.ndarray) -> np.ndarray:
    """Pose parameters (6,) from an OpenCV ``rvec, tvec`` (``T_cam_from_deck``) and the camera attitude."""
    R = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
    return params_from_relative(R, np.asarray(tvec, dtype=float).ravel(), R_world_from_cam)


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
        False where a value is NaN.
    """
    d = np.abs(a - b)
    d[..., :3] = np.abs(wrap_angle_rad(d[..., :3]))  # (comparisons with NaN raise no warning)
    return np.logical_and((d[..., :3] < tol).all(axis=-1), (d[..., 3:] < tol * (1 + np.abs(a[..., 5:6]))).all(axis=-1))


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(poses_close(a[None], b[None], SAME_TOL)[0])


def _near(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(poses_close(a[None], b[None], BASIN_TOL)[0])


def pnp_candidates(obs: Observations, R_world_from_cam: np.ndarray) -> tuple[list[Fit], dict[str, float]] | str:
    """SQPnP and both IPPE solutions, each refined by weighted least squares."""
    if len(obs) < MIN_BEACONS:
        return f"too few identified beacons for PnP: {len(obs)}, need at least {MIN_BEACONS}"
    obj = np.ascontiguousarray(obs.points_deck_m, dtype=np.float64)
    img = np.ascontiguousarray(obs.xy, dtype=np.float64)
    starts: list[np.ndarray] = []
    extras: dict[str, float] = {}
    n_ippe, rvecs, tvecs, errs = cv2.solvePnPGeneric(obj, img, K_NORMALISED, None, flags=cv2.SOLVEPNP_IPPE)
    for rv, tv in zip(rvecs[:n_ippe], tvecs[:n_ippe]):
        starts.append(params_from_rodrigues(rv, tv, R_world_from_cam))
    if n_ippe >= 2:
        e = np.asarray(errs, dtype=float).ravel()
        extras["ippe_error_ratio"] = float(e[1] / e[0]) if e[0] > 0 else float("inf")
        extras["ippe_alt_roll_rad"], extras["ippe_alt_pitch_rad"], extras["ippe_alt_yaw_rad"] = (
            float(v) for v in starts[1][:3])
        extras["ippe_alt_height_m"] = float(starts[1][5])
    ok, rv, tv = cv2.solvePnP(obj, img, K_NORMALISED, None, flags=cv2.SOLVEPNP_SQPNP)
    if ok:
        p = params_from_rodrigues(rv, tv, R_world_from_cam)
        if not (starts and poses_close(np.broadcast_to(p, (len(starts), 6)), np.array(starts), SAME_TOL).any()):
            starts.insert(0, p)
    starts = [s for s in starts if np.all(np.isfinite(s))]
    if not starts:
        return "PnP found no pose (degenerate beacon configuration)"
    # Refine the start with the lowest chi2 first; refine another only if it could compete
    # (its unrefined chi2 within ALT_MARGIN_CHI2 of the best refined one) and is not the same basin.
    # (the starts' chi2 alone: no Jacobian is needed to rank them)
    raw = sorted(((chi2_at(s, obs, R_world_from_cam), s) for s in starts), key=lambda cs: cs[0])
    fits: list[Fit] = [levenberg_marquardt(raw[0][1], obs, R_world_from_cam)]
    for chi2_0, p0 in raw[1:]:
        if _near(p0, fits[0].params) or not chi2_0 < fits[0].chi2 + ALT_MARGIN_CHI2:
            continue
        f = levenberg_marquardt(p0, obs, R_world_from_cam)
        if not any(_same(f.params, g.params) for g in fits):
            fits.append(f)
    return fits, extras


@register("pnp")
def estimate_pnp(
    detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate the deck pose by PnP on identified beacons (see module docstring).

    Needs at least 4 identified beacons. The refinement always weights residuals
    by the detections' covariances (or ``sigma_px``), so it is the maximum-likelihood
    estimate with or without ``options.refine``.
    """
    def solve(o: Observations, R_wc: np.ndarray) -> Candidate | str:
        res = pnp_candidates(o, R_wc)
        if isinstance(res, str):
            return res
        fits, extras = res
        return pick_candidate(fits, ambiguity_chi2=options.ambiguity_chi2,
                              assume_level_deck=options.assume_level_deck, extras=extras)

    return estimate_robustly("pnp", solve, detections, camera, layout, options,
                             min_points=MIN_BEACONS, refined=True)
