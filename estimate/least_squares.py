"""Weighted (maximum-likelihood) least squares on the pose parameters, and its covariance, batch-first.

Minimises ``sum_i |L_i (x_i(p) - m_i)|^2`` over the 6 pose parameters of each frame with
Levenberg–Marquardt, where ``L_i`` whitens observation ``i``
(:class:`~estimate.observations.Observations`). With Gaussian detection noise
this is the maximum-likelihood estimate, and ``(J^T Sigma^-1 J)^-1`` at the
optimum is its first-order covariance.

Every function takes ``F`` frames at once (leading axis ``F``) that share one beacon set
(``M`` points); one frame is a batch of one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, cast, overload

import numpy as np
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_model import project_from_camera
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Levenberg–Marquardt (:func:`levenberg_marquardt`): stop when every parameter step is below this
#: fraction of its standard deviation.
STEP_TOL_SIGMA = 1e-3
#: Levenberg–Marquardt damping at the start (a fraction of the information's diagonal).
DAMPING_START = 1e-4
#: Factor of the damping after an accepted step, and its floor.
DAMPING_DOWN, DAMPING_FLOOR = 0.1, 1e-12
#: Factor of the damping after a rejected step, and the ceiling above which a frame stops.
DAMPING_UP, DAMPING_CEILING = 10.0, 1e8
#: Levenberg–Marquardt iterations at most (default).
MAX_ITERATIONS = 30


@dataclass(frozen=True)
class Fit:
    """Least-squares fits of ``F`` frames, one parameter vector each (one frame is a batch of one).

    Attributes
    ----------
    params : (F, 6) array of float
    chi2 : (F,) array of float
        Inf where a point lies behind the camera or the start was invalid.
    information : (F, 6, 6) array of float
    whitened : (F, M, 2) array of float
    residuals_px : (F, M, 2) array of float
    gradient : (F, 6) array of float
    iterations : (F,) array of int
    converged : (F,) array of bool
    """

    params: FloatArray
    chi2: FloatArray
    information: FloatArray
    whitened: FloatArray
    residuals_px: FloatArray
    gradient: FloatArray
    iterations: NDArray[np.int64]
    converged: BoolArray

    @property
    def rms_px(self) -> FloatArray:
        """Root mean square reprojection error of each frame, pixels, (F,)."""
        n = self.residuals_px.shape[1]
        if n == 0:
            return np.full(self.chi2.shape, np.nan)
        return np.sqrt((self.residuals_px**2).sum(axis=(1, 2)) / n)

    def point_chi2(self) -> FloatArray:
        """Squared Mahalanobis residual of each point, (F, M)."""
        return (self.whitened**2).sum(axis=2)

    def covariance(self) -> tuple[FloatArray, BoolArray]:
        """``(J^T Sigma^-1 J)^-1`` of each frame and whether it exists (positive definite, finite)."""
        return covariance_from_information(self.information)

    def take(self, rows: slice | NDArray[np.bool_] | NDArray[np.int64]) -> Fit:
        """The frames ``rows`` (a slice gives views of these arrays, a mask or index copies)."""
        return Fit(self.params[rows], self.chi2[rows], self.information[rows], self.whitened[rows],
                   self.residuals_px[rows], self.gradient[rows], self.iterations[rows], self.converged[rows])

    def frame(self, f: int) -> Fit:
        """Frame ``f``'s fit as a batch of one (views; this fit where it is one)."""
        return self if self.params.shape[0] == 1 else self.take(slice(f, f + 1))


def _rows_ok(a: FloatArray) -> BoolArray:
    return np.logical_and.reduce(np.isfinite(a.reshape(a.shape[0], math.prod(a.shape[1:]))), axis=1)


def covariance_from_information(H: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Inverse of each information matrix through its Cholesky factor.

    Parameters
    ----------
    H : (F, 6, 6) array of float

    Returns
    -------
    cov : (F, 6, 6) array of float
        NaN where not ``ok``.
    ok : (F,) array of bool
        The matrix was finite and positive definite and its inverse finite.
    """
    F = H.shape[0]
    if F and np.isfinite(H).all():  # the common case: every matrix at once, no gathers
        try:
            Linv = np.linalg.inv(np.linalg.cholesky(H))
        except np.linalg.LinAlgError:
            pass  # some matrix is not positive definite: row by row below
        else:
            cov = Linv.swapaxes(1, 2) @ Linv
            if np.isfinite(cov).all():  # (the usual case: no test per matrix)
                return cov, np.ones(F, dtype=bool)
            ok = np.logical_and.reduce(np.isfinite(cov), axis=(1, 2))
            cov[~ok] = np.nan
            return cov, ok
    cov = np.full(H.shape, np.nan)
    ok = _rows_ok(H)
    idx = np.flatnonzero(ok)
    if idx.size:
        try:
            Lc = np.linalg.cholesky(H[idx])
            good = np.ones(idx.size, dtype=bool)
        except np.linalg.LinAlgError:
            Lc = np.full((idx.size, 6, 6), np.nan)
            good = np.zeros(idx.size, dtype=bool)
            for k, i in enumerate(idx):
                try:
                    Lc[k] = np.linalg.cholesky(H[i])
                    good[k] = True
                except np.linalg.LinAlgError:
                    pass
        sel = idx[good]
        if sel.size:
            Linv = np.linalg.inv(Lc[good])
            cov[sel] = Linv.swapaxes(1, 2) @ Linv
        ok = np.zeros(F, dtype=bool)
        ok[sel] = True
        ok &= _rows_ok(cov)
    cov[~ok] = np.nan
    return cov, ok


def solve_batch(A: FloatArray, b: FloatArray) -> tuple[FloatArray, BoolArray]:
    """``A[f]^-1 b[f]`` for each frame; ``ok`` False (and NaN) where ``A[f]`` is singular.

    Parameters
    ----------
    A : (F, n, n) array of float
    b : (F, n) or (F, n, k) array of float
        Right-hand vectors or matrices.
    """
    vec = b.ndim == 2
    B = b[..., None] if vec else b
    x: FloatArray
    try:
        x = np.asarray(np.linalg.solve(A, B), dtype=np.float64)
        ok = np.ones(A.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        x = np.full(B.shape, np.nan)
        ok = np.zeros(A.shape[0], dtype=bool)
        for i in range(A.shape[0]):
            try:
                x[i] = np.linalg.solve(A[i], B[i])
                ok[i] = True
            except np.linalg.LinAlgError:
                pass
    return (x[..., 0] if vec else x), ok


@overload
def _whitened(params: FloatArray, obs: Observations, jacobian: Literal[True] = ...
              ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]: ...
@overload
def _whitened(params: FloatArray, obs: Observations, jacobian: Literal[False]
              ) -> tuple[FloatArray, None, BoolArray, FloatArray]: ...
def _whitened(params: FloatArray, obs: Observations, jacobian: bool = True
              ) -> tuple[FloatArray, FloatArray | None, BoolArray, FloatArray]:
    """Whitened residuals (F, M, 2), whitened Jacobian (F, M, 2, 6), all-in-front (F,), raw residuals (F, M, 2)."""
    xy, J, Z = project_from_camera(params, obs.points_deck_m, obs.R_cam_from_world,
                        obs.translation_jacobian if jacobian else None)
    front = cast(BoolArray, (Z > 0).all(axis=1))  # (the method: np.all's wrapper costs as much on a lone frame)
    res = xy - obs.xy
    r = (obs.sqrt_info @ res[:, :, :, None])[:, :, :, 0]
    if J is None:
        return r, None, front, res
    return r, obs.sqrt_info @ J, front, res


def chi2_at(params: FloatArray, obs: Observations) -> FloatArray:
    """Sum of squared whitened residuals per frame (inf where a point is behind the camera)."""
    r, _, front, _ = _whitened(params, obs, jacobian=False)
    c = (r * r).sum(axis=(1, 2))
    return np.where(front & np.isfinite(c), c, np.inf)


def _normal_equations(r: FloatArray, Jw: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``J^T J`` (F, 6, 6) and ``J^T r`` (F, 6) from whitened residuals (F, M, 2) and Jacobian (F, M, 2, 6)."""
    F, M = r.shape[0], r.shape[1]
    A = Jw.reshape(F, 2 * M, 6)
    At = A.transpose(0, 2, 1)
    return At @ A, (At @ r.reshape(F, 2 * M, 1))[:, :, 0]


def evaluate_fit(params: FloatArray, obs: Observations,
                       iterations: NDArray[np.int64] | None = None,
                       converged: BoolArray | None = None) -> Fit:
    """The fit quantities at ``params`` (F, 6) without iterating."""
    r, Jw, front, res = _whitened(params, obs)
    H, g = _normal_equations(r, Jw)
    chi2 = np.where(front, (r * r).sum(axis=(1, 2)), np.inf)
    res_px = (obs.px_from_norm @ res[:, :, :, None])[:, :, :, 0]
    F = params.shape[0]
    return Fit(np.array(params, dtype=float), chi2, H, r, res_px, g,
                    np.zeros(F, dtype=np.int64) if iterations is None else iterations,
                    np.ones(F, dtype=bool) if converged is None else converged)


def levenberg_marquardt(params0: FloatArray, obs: Observations, *,
                              max_iterations: int = MAX_ITERATIONS) -> Fit:
    """Minimise each frame's whitened reprojection error from ``params0`` (F, 6).

    Levenberg–Marquardt, frame by frame: damping :data:`DAMPING_START` scaled down on
    success and up on failure, stop when every step is below :data:`STEP_TOL_SIGMA`
    standard deviations, when the damping exceeds :data:`DAMPING_CEILING`, or after
    ``max_iterations``.
    A frame whose start puts a point behind the camera (or gives non-finite
    residuals) gets ``chi2 = inf`` and NaN information. Frames still iterating are
    computed together; the others drop out of the stack.
    """
    F = params0.shape[0]
    p = np.array(params0, dtype=float)
    r, Jw, front, res = _whitened(p, obs)
    start_ok = front & _rows_ok(r)
    cost = np.where(start_ok, (r * r).sum(axis=(1, 2)), np.inf)
    lam = np.full(F, DAMPING_START)
    it = np.zeros(F, dtype=np.int64)
    converged = np.zeros(F, dtype=bool)
    active = np.flatnonzero(start_ok)
    everyone = active.size == F  # no frame has stopped: no indexing by ``active``
    n_everyone = 0  # the iterations of every frame while ``everyone`` (``it`` is set when it ends)
    with np.errstate(invalid="ignore", over="ignore"):
        while active.size:
            if everyone:
                sub, r_a, J_a, lam_a, cost_a = obs, r, Jw, lam, cost
                n_everyone += 1
            else:
                sub, r_a, J_a, lam_a, cost_a = obs.take(active), r[active], Jw[active], lam[active], cost[active]
                it[active] += 1
            H, g = _normal_equations(r_a, J_a)
            H_flat = H.reshape(-1, 36)  # (a view: H is a fresh product) the diagonal is every 7th entry
            dH = H_flat[:, ::7].copy()
            H_flat[:, ::7] += lam_a[:, None] * dH
            neg_step, solved = solve_batch(H, g)
            p_new = (p if everyone else p[active]) - neg_step
            r_new, J_new, front_new, res_new = _whitened(p_new, sub)
            cost_new = np.where(front_new, (r_new * r_new).sum(axis=(1, 2)), np.inf)
            small = (np.abs(neg_step) * np.sqrt(dH)).max(axis=1) < STEP_TOL_SIGMA  # dH: sums of squares
            better = cost_new <= cost_a
            finite = np.isfinite(cost_new)
            # not blown up (a non-finite cost with a finite step is a point behind the camera)
            ok = solved if finite.all() else solved & (finite | np.isfinite(neg_step.sum(axis=1)))
            accept = ok & better
            if everyone and accept.all():
                p, r, Jw, res, cost = p_new, r_new, J_new, res_new, cost_new
                lam = np.maximum(lam * DAMPING_DOWN, DAMPING_FLOOR)
                stop = small
            else:
                acc = active[accept]
                p[acc], r[acc], Jw[acc], cost[acc] = p_new[accept], r_new[accept], J_new[accept], cost_new[accept]
                res[acc] = res_new[accept]
                lam[acc] = np.maximum(lam[acc] * DAMPING_DOWN, DAMPING_FLOOR)
                reject = ok & ~better
                lam[active[reject & ~small]] *= DAMPING_UP
                stop = ~ok | (ok & small) | (reject & ~small & (lam[active] > DAMPING_CEILING))
            if everyone:
                converged |= ok & small
                if n_everyone >= max_iterations:
                    stop = np.ones(F, dtype=bool)
            else:
                converged[active[ok & small]] = True
                stop |= it[active] >= max_iterations
            if stop.any():
                if everyone:
                    it[:] = n_everyone
                active = active[~stop]
                everyone = False
    # The fit at the final parameters from the residuals and Jacobian already there (every
    # frame's were computed at its ``p``, where all points lie in front unless the start failed)
    H, g = _normal_equations(r, Jw)
    res_px = (obs.px_from_norm @ res[:, :, :, None])[:, :, :, 0]
    fit = Fit(p, np.where(start_ok, (r * r).sum(axis=(1, 2)), np.inf), H, r, res_px, g, it, converged)
    if not start_ok.all():
        bad = ~start_ok
        chi2 = fit.chi2.copy()
        chi2[bad] = np.inf
        H = fit.information.copy()
        H[bad] = np.nan
        res_px = fit.residuals_px.copy()
        res_px[bad] = np.nan
        g = fit.gradient.copy()
        g[bad] = np.nan
        fit = Fit(fit.params, chi2, H, fit.whitened, res_px, g, fit.iterations, fit.converged)
    return fit
