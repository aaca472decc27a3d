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

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal, cast, overload

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.rotation import zyx_from_R

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Levenberg–Marquardt (here and in :func:`estimate.least_squares.levenberg_marquardt`):
#: stop when every parameter step is below this fraction of its standard deviation.
STEP_TOL_SIGMA = 1e-3
#: Levenberg–Marquardt damping at the start (a fraction of the information's diagonal).
DAMPING_START = 1e-4
#: Factor of the damping after an accepted step, and its floor.
DAMPING_DOWN, DAMPING_FLOOR = 0.1, 1e-12
#: Factor of the damping after a rejected step, and the ceiling above which a frame stops.
DAMPING_UP, DAMPING_CEILING = 10.0, 1e8
#: Levenberg–Marquardt iterations at most (default).
MAX_ITERATIONS = 30
#: Up to this many rotations a loop of ``cv2.Rodrigues`` costs less than the closed form's ufuncs.
RODRIGUES_LOOP_MAX = 8


#: Sign of the translation parameters in the camera-frame offset: (surge, sway, -height).
_TRANSLATION_SIGN = np.array([1.0, 1.0, -1.0])


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

    @cached_property
    def R_cam_from_world(self) -> FloatArray:
        """``R_world_from_cam`` transposed, (F, 3, 3) (computed once: every iteration needs it)."""
        return np.swapaxes(self.R_world_from_cam, 1, 2)

    @cached_property
    def translation_jacobian(self) -> FloatArray:
        """d(camera-frame point)/d(surge, sway, height), (F, 1, 3, 3): the same for every point."""
        return (self.R_cam_from_world * _TRANSLATION_SIGN)[:, None]

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
        return np.sqrt((self.residuals_px**2).sum(axis=(1, 2)) / n)

    def point_chi2(self) -> FloatArray:
        """Squared Mahalanobis residual of each point, (F, M)."""
        return (self.whitened**2).sum(axis=2)

    def covariance(self) -> tuple[FloatArray, BoolArray]:
        """``(J^T Sigma^-1 J)^-1`` of each frame and whether it exists (positive definite, finite)."""
        return covariance_from_information(self.information)


def _rows_ok(a: FloatArray) -> BoolArray:
    return np.all(np.isfinite(a.reshape(a.shape[0], math.prod(a.shape[1:]))), axis=1)


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
    if F and np.isfinite(H).all():  # the common case: every matrix at once, no gathers
        try:
            Linv = np.linalg.inv(np.linalg.cholesky(H))
        except np.linalg.LinAlgError:
            pass  # some matrix is not positive definite: row by row below
        else:
            cov = np.swapaxes(Linv, 1, 2) @ Linv
            if np.isfinite(cov).all():  # (the usual case: no test per matrix)
                return cov, np.ones(F, dtype=bool)
            ok = np.all(np.isfinite(cov), axis=(1, 2))
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


def _rotation_coefficients() -> FloatArray:
    """``R_world_from_deck`` (ZYX) and its roll, pitch, yaw derivatives as linear maps of trig monomials.

    Every entry of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` and of its three derivatives is a sum of
    products ``a * b * c`` with ``a`` in (1, cos roll, sin roll), ``b`` in (1, cos pitch, sin
    pitch) and ``c`` in (1, cos yaw, sin yaw). The table (36, 27) maps the 27 monomials to the
    36 entries of the stacked (4, 3, 3) matrices, so many poses' rotations and derivatives are
    one product (:func:`rotation_and_derivatives_batch`). It is built here from the factors.
    """
    def mono(a: int, b: int, c: int, sign: float = 1.0) -> FloatArray:
        v = np.zeros(27)
        v[9 * a + 3 * b + c] = sign
        return v

    one, cos, sin = 0, 1, 2
    # (roll factor, pitch factor, yaw factor, sign) terms of R's nine entries
    R_terms = [
        [(one, cos, cos, 1)], [(cos, one, sin, -1), (sin, sin, cos, 1)], [(cos, sin, cos, 1), (sin, one, sin, 1)],
        [(one, cos, sin, 1)], [(cos, one, cos, 1), (sin, sin, sin, 1)], [(cos, sin, sin, 1), (sin, one, cos, -1)],
        [(one, sin, one, -1)], [(sin, cos, one, 1)], [(cos, cos, one, 1)],
    ]

    def d(factor: int, axis: int) -> tuple[int, float]:
        """Derivative of one factor of the given axis: d cos = -sin, d sin = cos, d 1 = 0."""
        return {one: (one, 0.0), cos: (sin, -1.0), sin: (cos, 1.0)}[factor]

    table = np.zeros((4, 9, 27))
    for entry, terms in enumerate(R_terms):
        for t in terms:
            table[0, entry] += mono(t[0], t[1], t[2], t[3])
            for axis in range(3):
                f, s = d(t[axis], axis)
                if s:
                    u = list(t[:3])
                    u[axis] = f
                    table[1 + axis, entry] += mono(u[0], u[1], u[2], t[3] * s)
    return table.reshape(36, 27)


#: :func:`_rotation_coefficients`, transposed for a right-hand product: (27, 36).
_ROTATION_TABLE = _rotation_coefficients().T.copy()


def _trig_monomials(angles_rad: FloatArray) -> FloatArray:
    """The 27 monomials ``a * b * c`` of :func:`_rotation_coefficients` for (F, 3) angles: (F, 27)."""
    F = angles_rad.shape[0]
    T = np.empty((F, 3, 3))
    T[:, :, 0] = 1.0
    np.cos(angles_rad, out=T[:, :, 1])
    np.sin(angles_rad, out=T[:, :, 2])
    return (T[:, 0, :, None, None] * T[:, 1, None, :, None] * T[:, 2, None, None, :]).reshape(F, 27)


def rotation_batch(angles_rad: FloatArray) -> FloatArray:
    """``R_world_from_deck`` (ZYX) of (..., 3) roll, pitch, yaw: (..., 3, 3).

    The values of :func:`deckpose.rotation.R_from_zyx`, from the same monomial table as
    :func:`rotation_and_derivatives_batch`.
    """
    a = np.asarray(angles_rad, dtype=float)
    flat = a.reshape(-1, 3)
    R = _trig_monomials(flat) @ _ROTATION_TABLE[:, :9]
    return R.reshape(a.shape[:-1] + (3, 3))


def rotation_and_derivatives_batch(angles_rad: FloatArray) -> FloatArray:
    """``R_world_from_deck`` (ZYX) and its derivatives by roll, pitch, yaw: (F, 4, 3, 3).

    Parameters
    ----------
    angles_rad : (F, 3) array of float
        Roll, pitch, yaw.
    """
    return (_trig_monomials(angles_rad) @ _ROTATION_TABLE).reshape(-1, 4, 3, 3)


def _camera_points(params: FloatArray, points_deck_m: FloatArray, R_cw: FloatArray,
                   d_translation: FloatArray | None) -> tuple[FloatArray, FloatArray | None]:
    """Camera-frame points (F, M, 3) and, given ``d_translation`` (F, 1, 3, 3), their derivatives (F, M, 3, 6).

    ``R_cw`` (F, 3, 3) is ``R_cam_from_world``.
    """
    d = R_cw @ (params[:, 3:] * _TRANSLATION_SIGN)[:, :, None]  # (F, 3, 1)
    if d_translation is None:
        Rs = R_cw @ rotation_batch(params[:, :3])
        return np.swapaxes(Rs @ points_deck_m.T + d, 1, 2), None
    Rs = R_cw[:, None] @ rotation_and_derivatives_batch(params[:, :3])  # (F, 4, 3, 3)
    F, M = params.shape[0], points_deck_m.shape[0]
    # Q[f, m, c, k] = sum_j P[m, j] Rs[f, k, c, j]: component c of the point (k = 0) and of its
    # derivatives by roll, pitch, yaw (k = 1..3), point-major so that no large array is transposed.
    Q = (points_deck_m @ Rs.transpose(0, 3, 2, 1).reshape(F, 3, 12)).reshape(F, M, 3, 4)
    Pc = Q[:, :, :, 0] + d[:, None, :, 0]
    dP = np.empty((F, M, 3, 6))
    dP[:, :, :, :3] = Q[:, :, :, 1:]
    dP[:, :, :, 3:] = d_translation
    return Pc, dP


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
    R_cw = np.swapaxes(R_world_from_cam, 1, 2)
    return _project(params, points_deck_m, R_cw, (R_cw * _TRANSLATION_SIGN)[:, None] if jacobian else None)


def _project(params: FloatArray, points_deck_m: FloatArray, R_cw: FloatArray, d_translation: FloatArray | None
             ) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """:func:`project_normalised_batch` from ``R_cam_from_world`` and, for the Jacobian, the translation block."""
    Pc, dP = _camera_points(params, points_deck_m, R_cw, d_translation)
    Z = Pc[:, :, 2]
    invZ = 1.0 / Z[:, :, None]
    xy = Pc[:, :, :2] * invZ
    if dP is None:
        return xy, None, Z
    J = (dP[:, :, :2, :] - xy[:, :, :, None] * dP[:, :, 2:3, :]) * invZ[:, :, :, None]
    return xy, J, Z


@overload
def _whitened(params: FloatArray, obs: FrameObservations, jacobian: Literal[True] = ...
              ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray]: ...


@overload
def _whitened(params: FloatArray, obs: FrameObservations, jacobian: Literal[False]
              ) -> tuple[FloatArray, None, BoolArray, FloatArray]: ...


def _whitened(params: FloatArray, obs: FrameObservations, jacobian: bool = True
              ) -> tuple[FloatArray, FloatArray | None, BoolArray, FloatArray]:
    """Whitened residuals (F, M, 2), whitened Jacobian (F, M, 2, 6), all-in-front (F,), raw residuals (F, M, 2)."""
    xy, J, Z = _project(params, obs.points_deck_m, obs.R_cam_from_world,
                        obs.translation_jacobian if jacobian else None)
    front = cast(BoolArray, (Z > 0).all(axis=1))  # (the method: np.all's wrapper costs as much on a lone frame)
    res = xy - obs.xy
    r = (obs.sqrt_info @ res[:, :, :, None])[:, :, :, 0]
    if J is None:
        return r, None, front, res
    return r, obs.sqrt_info @ J, front, res


def chi2_batch(params: FloatArray, obs: FrameObservations) -> FloatArray:
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


def evaluate_fit_batch(params: FloatArray, obs: FrameObservations,
                       iterations: NDArray[np.int64] | None = None,
                       converged: BoolArray | None = None) -> FitBatch:
    """The fit quantities at ``params`` (F, 6) without iterating."""
    r, Jw, front, res = _whitened(params, obs)
    H, g = _normal_equations(r, Jw)
    chi2 = np.where(front, (r * r).sum(axis=(1, 2)), np.inf)
    res_px = (obs.px_from_norm @ res[:, :, :, None])[:, :, :, 0]
    F = params.shape[0]
    return FitBatch(np.array(params, dtype=float), chi2, H, r, res_px, g,
                    np.zeros(F, dtype=np.int64) if iterations is None else iterations,
                    np.ones(F, dtype=bool) if converged is None else converged)


def levenberg_marquardt_batch(params0: FloatArray, obs: FrameObservations, *,
                              max_iterations: int = MAX_ITERATIONS) -> FitBatch:
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
    fit = FitBatch(p, np.where(start_ok, (r * r).sum(axis=(1, 2)), np.inf), H, r, res_px, g, it, converged)
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
    out = np.empty((R_wd.shape[0], 6))
    out[:, 0], out[:, 1], out[:, 2] = zyx_from_R(R_wd)
    out[:, 3:] = (R_world_from_cam @ t_cam_from_deck[:, :, None])[:, :, 0]
    out[:, 5] *= -1.0
    return out


def relative_from_params_batch(params: FloatArray, R_world_from_cam: FloatArray
                               ) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`params_from_relative_batch`: ``R_cam_from_deck`` (F, 3, 3), ``t`` (F, 3)."""
    R_cw = np.swapaxes(R_world_from_cam, 1, 2)
    R_wd = rotation_batch(params[:, :3])
    tw = params[:, 3:, None] * _TRANSLATION_SIGN[:, None]  # (surge, sway, -height)
    return R_cw @ R_wd, (R_cw @ tw)[:, :, 0]


def rotation_vectors(R: FloatArray) -> FloatArray:
    """Rodrigues vectors (F, 3) of rotation matrices (F, 3, 3), as ``cv2.Rodrigues`` gives them.

    Rotations within 1e-5 (in ``sin``) of 0 or pi, where the closed form loses
    precision, are handed to ``cv2.Rodrigues`` one by one, and so are up to
    :data:`RODRIGUES_LOOP_MAX` rotations (a lone frame's), where the loop costs less
    than the closed form's ufuncs. NaN where a matrix is not finite.
    """
    if R.shape[0] <= RODRIGUES_LOOP_MAX:
        if np.isfinite(R).all():  # (the usual case: no test per matrix)
            return np.array([cv2.Rodrigues(np.ascontiguousarray(r))[0].ravel() for r in R],
                            dtype=np.float64).reshape(-1, 3)
        out = np.full((R.shape[0], 3), np.nan)
        for i in range(R.shape[0]):
            if np.isfinite(R[i]).all():
                out[i] = cv2.Rodrigues(np.ascontiguousarray(R[i]))[0].ravel()
        return out
    flat = R.reshape(-1, 9)
    # the skew part (R - R^T) / 2 as a vector: entries (2,1)-(1,2), (0,2)-(2,0), (1,0)-(0,1)
    v = flat[:, [7, 2, 3]] - flat[:, [5, 6, 1]]
    s = np.sqrt((v * v).sum(axis=1) * 0.25)
    c = np.minimum(np.maximum((flat[:, 0] + flat[:, 4] + flat[:, 8] - 1.0) * 0.5, -1.0), 1.0)
    theta = np.arccos(c)
    special = ~(s >= 1e-5)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = v * (theta / (2.0 * s))[:, None]
    if not special.any():
        return out
    for i in np.flatnonzero(special):
        if np.all(np.isfinite(R[i])):
            out[i] = cv2.Rodrigues(np.ascontiguousarray(R[i]))[0].ravel()
        else:
            out[i] = np.nan
    return out
