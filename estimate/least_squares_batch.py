"""The pose model and weighted least squares of :mod:`~estimate.least_squares`, for many frames at once.

Every function here is the stacked twin of a single-frame function and follows
it step by step, so the two agree to rounding:

* :func:`project_normalised_batch` — :func:`estimate.pose_model.project_normalised`;
* :func:`evaluate_fit_batch` — :func:`estimate.least_squares.evaluate_fit`;
* :func:`levenberg_marquardt_batch` — :func:`estimate.least_squares.levenberg_marquardt`
  (same damping schedule and stopping rules, per frame);
* :func:`params_from_relative_batch` — :func:`estimate.pose_model.params_from_relative`.

Frames share one beacon set (``M`` points, ``(M, 3)`` deck positions); each has its
own observations, whitening and camera attitude. Leading axis ``F`` = frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, overload

import numpy as np
from numpy.typing import NDArray

from deckpose.rotation import zyx_from_R

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Stop when every parameter step is below this fraction of its standard deviation
#: (the value of :data:`estimate.least_squares.STEP_TOL_SIGMA`).
STEP_TOL_SIGMA = 1e-3


@dataclass(frozen=True)
class FrameObservations:
    """The observations of ``F`` frames that share one beacon set (internal to the estimators).

    The stacked form of :class:`~estimate.observations.Observations`.

    Attributes
    ----------
    ids : (M,) array of int
        Layout id of each observation, the same for every frame.
    points_deck_m : (M, 3) array of float
        Layout position of each observation's beacon, deck frame, metres.
    xy : (F, M, 2) array of float
        Undistorted normalised image coordinates.
    sqrt_info : (F, M, 2, 2) or (F, 1, 2, 2) array of float
        ``L`` with ``L.T @ L`` the inverse covariance of ``xy`` (one per frame
        when it is the same for all points).
    px_from_norm : (F, M, 2, 2) or (F, 1, 2, 2) array of float
        Local Jacobian d(pixel)/d(normalised).
    R_world_from_cam : (F, 3, 3) array of float
        Camera attitude of each frame.
    """

    ids: NDArray[np.int64]
    points_deck_m: FloatArray
    xy: FloatArray
    sqrt_info: FloatArray
    px_from_norm: FloatArray
    R_world_from_cam: FloatArray

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def take(self, rows: NDArray[np.int64]) -> FrameObservations:
        """The frames ``rows`` (index array)."""
        return FrameObservations(self.ids, self.points_deck_m, self.xy[rows], self.sqrt_info[rows],
                                 self.px_from_norm[rows], self.R_world_from_cam[rows])


@dataclass(frozen=True)
class FitBatch:
    """Least-squares fits of ``F`` frames, one parameter vector each (the stacked :class:`Fit`).

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
        return np.sqrt(np.sum(self.residuals_px**2, axis=(1, 2)) / n)

    def point_chi2(self) -> FloatArray:
        """Squared Mahalanobis residual of each point, (F, M)."""
        return np.sum(self.whitened**2, axis=2)

    def covariance(self) -> tuple[FloatArray, BoolArray]:
        """``(J^T Sigma^-1 J)^-1`` of each frame and whether it exists (positive definite, finite)."""
        return covariance_from_information(self.information)


def _rows_ok(a: FloatArray) -> BoolArray:
    return np.all(np.isfinite(a), axis=tuple(range(1, a.ndim)))


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
        The matrix was finite and positive definite and its inverse finite
        (the single-frame ``Fit.covariance`` is not None).
    """
    F = H.shape[0]
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
            cov[sel] = np.swapaxes(Linv, 1, 2) @ Linv
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


def _trig(angles_rad: FloatArray) -> tuple[FloatArray, ...]:
    """``cos, sin`` of roll, pitch, yaw of (..., 3) angles: six (...) arrays."""
    a = angles_rad
    return (np.cos(a[..., 0]), np.sin(a[..., 0]), np.cos(a[..., 1]), np.sin(a[..., 1]),
            np.cos(a[..., 2]), np.sin(a[..., 2]))


def _fill_rotation(R: FloatArray, cr: FloatArray, sr: FloatArray, cp: FloatArray, sp: FloatArray,
                   cy: FloatArray, sy: FloatArray) -> None:
    """Write ``R_world_from_deck`` (ZYX) of the given sines and cosines into ``R`` (..., 3, 3)."""
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr


def rotation_batch(angles_rad: FloatArray) -> FloatArray:
    """``R_world_from_deck`` (ZYX) of (..., 3) roll, pitch, yaw: (..., 3, 3).

    The values of :func:`deckpose.rotation.R_from_zyx`, written out (no stacking or
    matrix products), as :func:`rotation_and_derivatives_batch` computes them.
    """
    R = np.empty(angles_rad.shape[:-1] + (3, 3))
    _fill_rotation(R, *_trig(angles_rad))
    return R


def rotation_and_derivatives_batch(angles_rad: FloatArray) -> FloatArray:
    """``R_world_from_deck`` (ZYX) and its derivatives by roll, pitch, yaw: (F, 4, 3, 3).

    Parameters
    ----------
    angles_rad : (F, 3) array of float
        Roll, pitch, yaw.
    """
    cr, sr, cp, sp, cy, sy = _trig(angles_rad)
    out = np.empty((angles_rad.shape[0], 4, 3, 3))
    R, dr, dp, dy = out[:, 0], out[:, 1], out[:, 2], out[:, 3]
    _fill_rotation(R, cr, sr, cp, sp, cy, sy)
    dr[:, :, 0] = 0.0
    dr[:, 0, 1] = cy * sp * cr + sy * sr
    dr[:, 0, 2] = -cy * sp * sr + sy * cr
    dr[:, 1, 1] = sy * sp * cr - cy * sr
    dr[:, 1, 2] = -sy * sp * sr - cy * cr
    dr[:, 2, 1] = cp * cr
    dr[:, 2, 2] = -cp * sr
    dp[:, 0, 0] = -cy * sp
    dp[:, 0, 1] = cy * cp * sr
    dp[:, 0, 2] = cy * cp * cr
    dp[:, 1, 0] = -sy * sp
    dp[:, 1, 1] = sy * cp * sr
    dp[:, 1, 2] = sy * cp * cr
    dp[:, 2, 0] = -cp
    dp[:, 2, 1] = -sp * sr
    dp[:, 2, 2] = -sp * cr
    dy[:, 0] = -R[:, 1]
    dy[:, 1] = R[:, 0]
    dy[:, 2] = 0.0
    return out


def _project(params: FloatArray, points_deck_m: FloatArray, R_world_from_cam: FloatArray,
             jacobian: bool) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """Component-major projection: ``x, y, depth`` (F, M) and ``dP`` (F, 3, 6, M) = d(camera point)/d(params).

    ``x, y`` are the normalised image coordinates; ``dP`` is None without ``jacobian``.
    """
    F, M = params.shape[0], points_deck_m.shape[0]
    R_cw = np.swapaxes(R_world_from_cam, 1, 2)
    tw = np.stack([params[:, 3], params[:, 4], -params[:, 5]], axis=1)
    d = (R_cw @ tw[:, :, None])[:, :, 0]
    if not jacobian:  # the rotation alone, not its derivatives
        Q = (R_cw @ rotation_batch(params[:, :3])) @ points_deck_m.T  # (F, 3, M) camera-frame points
        Z = Q[:, 2] + d[:, 2, None]
        invZ = 1.0 / Z
        return (Q[:, 0] + d[:, 0, None]) * invZ, (Q[:, 1] + d[:, 1, None]) * invZ, Z, None
    Rs = R_cw[:, None] @ rotation_and_derivatives_batch(params[:, :3])  # (F, 4, 3, 3)
    QT = (Rs.reshape(-1, 3) @ points_deck_m.T).reshape(F, 4, 3, M)  # camera-frame points, derivatives
    Z = QT[:, 0, 2] + d[:, 2, None]
    invZ = 1.0 / Z
    x = (QT[:, 0, 0] + d[:, 0, None]) * invZ
    y = (QT[:, 0, 1] + d[:, 1, None]) * invZ
    dP = np.empty((F, 3, 6, M))
    dP[:, :, :3, :] = QT[:, 1:].transpose(0, 2, 1, 3)
    dP[:, :, 3:, :] = (R_cw * np.array([1.0, 1.0, -1.0]))[:, :, :, None]
    return x, y, Z, dP


def _image_jacobian(x: FloatArray, y: FloatArray, Z: FloatArray, dP: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """d(x, y)/d(params) as two (F, 6, M) arrays."""
    invZ = 1.0 / Z[:, None, :]
    return (dP[:, 0] - x[:, None, :] * dP[:, 2]) * invZ, (dP[:, 1] - y[:, None, :] * dP[:, 2]) * invZ


def project_normalised_batch(
    params: FloatArray, points_deck_m: FloatArray, R_world_from_cam: FloatArray, *, jacobian: bool = True
) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Normalised image points of deck points for ``F`` poses, and their Jacobians.

    Parameters
    ----------
    params : (F, 6) array of float
    points_deck_m : (M, 3) array of float, metres
    R_world_from_cam : (F, 3, 3) array of float
    jacobian : bool, keyword-only

    Returns
    -------
    xy : (F, M, 2) array of float
    J : (F, M, 2, 6) array of float or None
    depth_m : (F, M) array of float
    """
    x, y, Z, dP = _project(params, points_deck_m, R_world_from_cam, jacobian)
    xy = np.stack([x, y], axis=2)
    if dP is None:
        return xy, None, Z
    Jx, Jy = _image_jacobian(x, y, Z, dP)
    return xy, np.stack([Jx, Jy], axis=1).transpose(0, 3, 1, 2), Z


def _apply(L: FloatArray, vx: FloatArray, vy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``L @ (vx, vy)`` per point: ``L`` (F, M, 2, 2); ``v`` (F, M) or Jacobian rows (F, 6, M)."""
    l00, l01, l10, l11 = L[..., 0, 0], L[..., 0, 1], L[..., 1, 0], L[..., 1, 1]
    if vx.ndim == 3:
        l00, l01, l10, l11 = l00[:, None], l01[:, None], l10[:, None], l11[:, None]
    return l00 * vx + l01 * vy, l10 * vx + l11 * vy


@overload
def _whitened(params: FloatArray, obs: FrameObservations, jacobian: Literal[True] = ...
              ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]: ...


@overload
def _whitened(params: FloatArray, obs: FrameObservations, jacobian: Literal[False]
              ) -> tuple[FloatArray, None, BoolArray, FloatArray]: ...


def _whitened(params: FloatArray, obs: FrameObservations, jacobian: bool = True
              ) -> tuple[FloatArray, FloatArray | None, BoolArray, FloatArray]:
    """Whitened residuals (F, 2, M), whitened Jacobian (F, 6, 2, M), all-in-front (F,), raw residuals (F, 2, M)."""
    x, y, Z, dP = _project(params, obs.points_deck_m, obs.R_world_from_cam, jacobian)
    front = np.all(Z > 0, axis=1)
    F, M = x.shape
    res = np.empty((F, 2, M))
    res[:, 0] = x - obs.xy[:, :, 0]
    res[:, 1] = y - obs.xy[:, :, 1]
    r = np.empty((F, 2, M))
    r[:, 0], r[:, 1] = _apply(obs.sqrt_info, res[:, 0], res[:, 1])
    if dP is None:
        return r, None, front, res
    Jx, Jy = _image_jacobian(x, y, Z, dP)
    Jw = np.empty((F, 6, 2, M))
    Jw[:, :, 0], Jw[:, :, 1] = _apply(obs.sqrt_info, Jx, Jy)
    return r, Jw, front, res


def chi2_batch(params: FloatArray, obs: FrameObservations) -> FloatArray:
    """Sum of squared whitened residuals per frame (inf where a point is behind the camera)."""
    r, _, front, _ = _whitened(params, obs, jacobian=False)
    c = np.sum(r * r, axis=(1, 2))
    return np.where(front & np.isfinite(c), c, np.inf)


def _normal_equations(r: FloatArray, Jw: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``J^T J`` (F, 6, 6) and ``J^T r`` (F, 6) from whitened residuals (F, 2, M) and Jacobian (F, 6, 2, M)."""
    F, _, M = r.shape
    A = Jw.reshape(F, 6, 2 * M)
    return A @ np.swapaxes(A, 1, 2), (A @ r.reshape(F, 2 * M, 1))[:, :, 0]


def evaluate_fit_batch(params: FloatArray, obs: FrameObservations,
                       iterations: NDArray[np.int64] | None = None,
                       converged: BoolArray | None = None) -> FitBatch:
    """The fit quantities at ``params`` (F, 6) without iterating."""
    r, Jw, front, res = _whitened(params, obs)
    assert Jw is not None
    H, g = _normal_equations(r, Jw)
    chi2 = np.where(front, np.sum(r * r, axis=(1, 2)), np.inf)
    res_px = np.stack(_apply(obs.px_from_norm, res[:, 0], res[:, 1]), axis=2)
    F = params.shape[0]
    return FitBatch(np.array(params, dtype=float), chi2, H, np.swapaxes(r, 1, 2), res_px, g,
                    np.zeros(F, dtype=np.int64) if iterations is None else iterations,
                    np.ones(F, dtype=bool) if converged is None else converged)


def levenberg_marquardt_batch(params0: FloatArray, obs: FrameObservations, *,
                              max_iterations: int = 30) -> FitBatch:
    """Minimise each frame's whitened reprojection error from ``params0`` (F, 6).

    Frame by frame the same iteration as
    :func:`estimate.least_squares.levenberg_marquardt`: damping ``1e-4`` scaled by
    10 down on success and up on failure, stop when every step is below
    :data:`STEP_TOL_SIGMA` standard deviations, when the damping exceeds 1e8, or
    after ``max_iterations``. A frame whose start puts a point behind the camera
    (or gives non-finite residuals) gets ``chi2 = inf`` and NaN information.
    """
    F = params0.shape[0]
    p = np.array(params0, dtype=float)
    r, Jw, front, _ = _whitened(p, obs)
    start_ok = front & _rows_ok(r)
    cost = np.where(start_ok, np.sum(r * r, axis=(1, 2)), np.inf)
    lam = np.full(F, 1e-4)
    it = np.zeros(F, dtype=np.int64)
    converged = np.zeros(F, dtype=bool)
    active = np.flatnonzero(start_ok)
    while active.size:
        it[active] += 1
        H, g = _normal_equations(r[active], Jw[active])
        dH = np.diagonal(H, axis1=1, axis2=2).copy()
        A = H.copy()
        A[:, np.arange(6), np.arange(6)] += lam[active, None] * dH
        neg_step, solved = solve_batch(A, g)
        step = -neg_step
        p_new = p[active] + step
        sub = obs.take(active)
        r_new, J_new, front_new, _ = _whitened(p_new, sub)
        with np.errstate(invalid="ignore"):
            cost_new = np.where(front_new, np.sum(r_new * r_new, axis=(1, 2)), np.inf)
            blown = ~np.isfinite(cost_new) & ~np.isfinite(step.sum(axis=1))
            small = np.max(np.abs(step) * np.sqrt(np.abs(dH)), axis=1) < STEP_TOL_SIGMA
            better = cost_new <= cost[active]
        accept = solved & ~blown & better
        acc = active[accept]
        p[acc], r[acc], Jw[acc], cost[acc] = p_new[accept], r_new[accept], J_new[accept], cost_new[accept]
        lam[acc] = np.maximum(lam[acc] * 0.1, 1e-12)
        reject = solved & ~blown & ~better
        lam[active[reject & ~small]] *= 10.0
        done_small = solved & ~blown & small
        converged[active[done_small]] = True
        stop = ~solved | blown | done_small | (reject & ~small & (lam[active] > 1e8))
        stop |= it[active] >= max_iterations
        active = active[~stop]
    fit = evaluate_fit_batch(p, obs, it, converged)
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
        fit = FitBatch(fit.params, chi2, H, fit.whitened, res_px, g, fit.iterations, fit.converged)
    return fit


def params_from_relative_batch(R_cam_from_deck: FloatArray, t_cam_from_deck: FloatArray,
                               R_world_from_cam: FloatArray) -> FloatArray:
    """Pose parameters (F, 6) from ``T_cam_from_deck`` (F, 3, 3), (F, 3) and the camera attitude (F, 3, 3)."""
    R_wd = R_world_from_cam @ R_cam_from_deck
    roll, pitch, yaw = zyx_from_R(R_wd)
    d = np.einsum("fij,fj->fi", R_world_from_cam, t_cam_from_deck)
    return np.stack([roll, pitch, yaw, d[:, 0], d[:, 1], -d[:, 2]], axis=1)


def relative_from_params_batch(params: FloatArray, R_world_from_cam: FloatArray
                               ) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`params_from_relative_batch`: ``R_cam_from_deck`` (F, 3, 3), ``t`` (F, 3)."""
    R_cw = np.swapaxes(R_world_from_cam, 1, 2)
    R_wd = rotation_batch(params[:, :3])
    tw = np.stack([params[:, 3], params[:, 4], -params[:, 5]], axis=1)
    return R_cw @ R_wd, np.einsum("fij,fj->fi", R_cw, tw)


def rotation_vectors(R: FloatArray) -> FloatArray:
    """Rodrigues vectors (F, 3) of rotation matrices (F, 3, 3), as ``cv2.Rodrigues`` gives them.

    Rotations within 1e-5 (in ``sin``) of 0 or pi, where the closed form loses
    precision, are handed to ``cv2.Rodrigues`` one by one.
    """
    import cv2

    v = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    s = np.sqrt(np.sum(v * v, axis=1) * 0.25)
    c = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(c)
    special = ~(s >= 1e-5)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = v * (theta / (2.0 * s))[:, None]
    for i in np.flatnonzero(special):
        if np.all(np.isfinite(R[i])):
            out[i] = cv2.Rodrigues(np.ascontiguousarray(R[i]))[0].ravel()
        else:
            out[i] = np.nan
    return out
