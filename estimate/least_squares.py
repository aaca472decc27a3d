"""Weighted (maximum-likelihood) least squares on the pose parameters, and its covariance.

Minimises ``sum_i |L_i (x_i(p) - m_i)|^2`` over the 6 pose parameters with
Levenberg–Marquardt, where ``L_i`` whitens observation ``i``
(:class:`~estimate.observations.Observations`). With Gaussian detection noise
this is the maximum-likelihood estimate, and ``(J^T Sigma^-1 J)^-1`` at the
optimum is its first-order covariance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from deckpose.estimate.least_squares_batch import (
    DAMPING_CEILING,
    DAMPING_DOWN,
    DAMPING_FLOOR,
    DAMPING_START,
    DAMPING_UP,
    MAX_ITERATIONS,
    STEP_TOL_SIGMA,
    FitBatch,
)
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_model import project_normalised
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Fit:
    """The state of a least-squares fit at one parameter vector.

    Attributes
    ----------
    params : (6,) array of float
    chi2 : float
        Sum of squared whitened residuals (inf if a point is behind the camera).
    information : (6, 6) array of float
        ``J^T Sigma^-1 J``.
    whitened : (N, 2) array of float
        Whitened residuals.
    residuals_px : (N, 2) array of float
        Residuals in (distorted) pixels, to first order.
    gradient : (6,) array of float
        ``J^T Sigma^-1 r``, half the gradient of chi2.
    iterations : int
    converged : bool
    """

    params: FloatArray
    chi2: float
    information: FloatArray
    whitened: FloatArray
    residuals_px: FloatArray
    gradient: FloatArray
    iterations: int = 0
    converged: bool = True

    @property
    def rms_px(self) -> float:
        """Root mean square reprojection error over the points, pixels."""
        n = self.residuals_px.shape[0]
        return float(np.sqrt(np.sum(self.residuals_px**2) / n)) if n else float("nan")

    def point_chi2(self) -> FloatArray:
        """Squared Mahalanobis residual of each point, (N,)."""
        return np.sum(self.whitened**2, axis=1)

    @cached_property
    def covariance(self) -> FloatArray | None:
        """``(J^T Sigma^-1 J)^-1``, or None when the information matrix is not positive definite."""
        H = self.information
        if not np.all(np.isfinite(H)):
            return None
        try:
            Linv = np.linalg.inv(np.linalg.cholesky(H))
        except np.linalg.LinAlgError:
            return None
        cov = Linv.T @ Linv
        if not np.all(np.isfinite(cov)):
            return None
        return cov

    def gauss_newton_step(self) -> FloatArray | None:
        """Parameters after one undamped Gauss-Newton step, or None if singular."""
        cov = self.covariance
        if cov is None:
            return None
        return self.params - cov @ self.gradient


def _whitened(params: FloatArray, obs: Observations, R_world_from_cam: FloatArray
              ) -> tuple[FloatArray, FloatArray, bool, FloatArray]:
    """Whitened residuals (N, 2), whitened Jacobian (N, 2, 6), all-in-front flag, raw residuals."""
    xy, J, Z = project_normalised(params, obs.points_deck_m, R_world_from_cam)
    front = bool(np.all(Z > 0))
    res = xy - obs.xy
    L = obs.sqrt_info
    r = L[:, :, 0] * res[:, 0:1] + L[:, :, 1] * res[:, 1:2]
    Jw = L[:, :, 0, None] * J[:, 0:1, :] + L[:, :, 1, None] * J[:, 1:2, :]  # type: ignore[index]
    return r, Jw, front, res


def chi2_at(params: FloatArray, obs: Observations, R_world_from_cam: FloatArray) -> float:
    """Sum of squared whitened residuals at ``params`` (inf if a point is behind the camera)."""
    xy, _, Z = project_normalised(params, obs.points_deck_m, R_world_from_cam, jacobian=False)
    if not bool(np.all(Z > 0)):
        return math.inf
    res = xy - obs.xy
    L = obs.sqrt_info
    r = L[:, :, 0] * res[:, 0:1] + L[:, :, 1] * res[:, 1:2]
    c = float(np.sum(r * r))
    return c if math.isfinite(c) else math.inf


def evaluate_fit(params: FloatArray, obs: Observations, R_world_from_cam: FloatArray,
                 iterations: int = 0, converged: bool = True) -> Fit:
    """The fit quantities at ``params`` without iterating."""
    r, Jw, front, res = _whitened(params, obs, R_world_from_cam)
    J2 = Jw.reshape(-1, 6)
    chi2 = float(np.sum(r * r)) if front else float("inf")
    D = obs.px_from_norm
    res_px = D[:, :, 0] * res[:, 0:1] + D[:, :, 1] * res[:, 1:2]
    return Fit(np.array(params, dtype=float), chi2, J2.T @ J2, r, res_px, J2.T @ r.ravel(),
               iterations, converged)


def levenberg_marquardt(
    params0: FloatArray,
    obs: Observations,
    R_world_from_cam: FloatArray,
    *,
    max_iterations: int = MAX_ITERATIONS,
) -> Fit:
    """Minimise the whitened reprojection error from ``params0``.

    Parameters
    ----------
    params0 : (6,) array of float
        Starting pose parameters.
    obs : Observations
        At least 3 points (6 residuals) for a determined problem.
    R_world_from_cam : (3, 3) array of float
    max_iterations : int, keyword-only

    Returns
    -------
    Fit
        At the best parameters found; ``converged`` False if the iteration limit hit
        or the start was invalid.
    """
    p = np.array(params0, dtype=float)
    r, Jw, front, _ = _whitened(p, obs, R_world_from_cam)
    if not front or not np.all(np.isfinite(r)):
        return Fit(p, float("inf"), np.full((6, 6), np.nan), r, np.full_like(r, np.nan),
                   np.full(6, np.nan), 0, False)
    cost = float(np.sum(r * r))
    lam = DAMPING_START
    it = 0
    converged = False
    while it < max_iterations:
        it += 1
        J2 = Jw.reshape(-1, 6)
        H = J2.T @ J2
        g = J2.T @ r.ravel()
        dH = H.diagonal().copy()
        A = H.copy()
        A.flat[::7] += lam * dH
        try:
            step = -np.linalg.solve(A, g)
        except np.linalg.LinAlgError:
            break
        p_new = np.asarray(p + step, dtype=np.float64)
        r_new, J_new, front_new, _ = _whitened(p_new, obs, R_world_from_cam)
        cost_new = float(np.sum(r_new * r_new)) if front_new else math.inf
        if not math.isfinite(cost_new) and not math.isfinite(float(step.sum())):
            break
        small = float(np.max(np.abs(step) * np.sqrt(np.abs(dH)))) < STEP_TOL_SIGMA
        if cost_new <= cost:
            p, r, Jw, cost = p_new, r_new, J_new, cost_new
            lam = max(lam * DAMPING_DOWN, DAMPING_FLOOR)
            if small:
                converged = True
                break
        else:
            if small:
                converged = True
                break
            lam *= DAMPING_UP
            if lam > DAMPING_CEILING:
                break
    return evaluate_fit(p, obs, R_world_from_cam, it, converged)


def fit_of_row(fits: FitBatch, i: int) -> Fit:
    """Frame ``i`` of a batch of fits as a :class:`Fit` (views, no copies)."""
    return Fit(fits.params[i], float(fits.chi2[i]), fits.information[i], fits.whitened[i],
               fits.residuals_px[i], fits.gradient[i], int(fits.iterations[i]), bool(fits.converged[i]))
