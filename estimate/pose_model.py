"""The 6-parameter pose model shared by the estimators, the refinement and the Cramér–Rao bound.

Parameters ``p`` follow :data:`deckpose.records.POSE_PARAMS`:
``(roll_rad, pitch_rad, yaw_rad, surge_m, sway_m, height_m)`` — ZYX angles of
``R_world_from_deck``, the deck centre's displacement along world x and y from
the point under the camera, and the camera's height above the deck centre
along world z. With a known camera attitude ``R_world_from_cam``::

    d_world = (surge_m, sway_m, -height_m)          # deck centre minus camera centre
    P_cam   = R_world_from_cam.T @ (R_world_from_deck @ P_deck + d_world)

and the observation of a beacon is its *normalised* image point
``(P_cam.x / P_cam.z, P_cam.y / P_cam.z)`` (undistorted, ``K`` removed).

Batch-first: every function takes ``F`` poses at once (leading axis ``F``); one
pose is a batch of one. The frames share one beacon set (``M`` points).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.rotation import zyx_from_R

FloatArray = NDArray[np.float64]

#: Up to this many rotations a loop of ``cv2.Rodrigues`` costs less than the closed form's ufuncs.
RODRIGUES_LOOP_MAX = 8


#: Sign of the translation parameters in the camera-frame offset: (surge, sway, -height).
TRANSLATION_SIGN = np.array([1.0, 1.0, -1.0])


def _rotation_coefficients() -> FloatArray:
    """``R_world_from_deck`` (ZYX) and its roll, pitch, yaw derivatives as linear maps of trig monomials.

    Every entry of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` and of its three derivatives is a sum of
    products ``a * b * c`` with ``a`` in (1, cos roll, sin roll), ``b`` in (1, cos pitch, sin
    pitch) and ``c`` in (1, cos yaw, sin yaw). The table (36, 27) maps the 27 monomials to the
    36 entries of the stacked (4, 3, 3) matrices, so many poses' rotations and derivatives are
    one product (:func:`deck_rotations_and_derivatives`). It is built here from the factors.
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


def deck_rotations(angles_rad: FloatArray) -> FloatArray:
    """``R_world_from_deck`` (ZYX) of (..., 3) roll, pitch, yaw: (..., 3, 3).

    The values of :func:`deckpose.rotation.R_from_zyx`, from the same monomial table as
    :func:`deck_rotations_and_derivatives`.
    """
    a = np.asarray(angles_rad, dtype=float)
    flat = a.reshape(-1, 3)
    R = _trig_monomials(flat) @ _ROTATION_TABLE[:, :9]
    return R.reshape(a.shape[:-1] + (3, 3))


def deck_rotations_and_derivatives(angles_rad: FloatArray) -> FloatArray:
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
    d = R_cw @ (params[:, 3:] * TRANSLATION_SIGN)[:, :, None]  # (F, 3, 1)
    if d_translation is None:
        Rs = R_cw @ deck_rotations(params[:, :3])
        return (Rs @ points_deck_m.T + d).swapaxes(1, 2), None
    Rs = R_cw[:, None] @ deck_rotations_and_derivatives(params[:, :3])  # (F, 4, 3, 3)
    F, M = params.shape[0], points_deck_m.shape[0]
    # Q[f, m, c, k] = sum_j P[m, j] Rs[f, k, c, j]: component c of the point (k = 0) and of its
    # derivatives by roll, pitch, yaw (k = 1..3), point-major so that no large array is transposed.
    Q = (points_deck_m @ Rs.transpose(0, 3, 2, 1).reshape(F, 3, 12)).reshape(F, M, 3, 4)
    Pc = Q[:, :, :, 0] + d[:, None, :, 0]
    dP = np.empty((F, M, 3, 6))
    dP[:, :, :, :3] = Q[:, :, :, 1:]
    dP[:, :, :, 3:] = d_translation
    return Pc, dP


def project_normalised(
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
    R_cw = R_world_from_cam.swapaxes(1, 2)
    return project_from_camera(params, points_deck_m, R_cw, (R_cw * TRANSLATION_SIGN)[:, None] if jacobian else None)


def project_from_camera(params: FloatArray, points_deck_m: FloatArray, R_cw: FloatArray, d_translation: FloatArray | None
             ) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """:func:`project_normalised` from ``R_cam_from_world`` and, for the Jacobian, the translation block."""
    Pc, dP = _camera_points(params, points_deck_m, R_cw, d_translation)
    Z = Pc[:, :, 2]
    invZ = 1.0 / Z[:, :, None]
    xy = Pc[:, :, :2] * invZ
    if dP is None:
        return xy, None, Z
    J = (dP[:, :, :2, :] - xy[:, :, :, None] * dP[:, :, 2:3, :]) * invZ[:, :, :, None]
    return xy, J, Z


def params_from_relative(R_cam_from_deck: FloatArray, t_cam_from_deck: FloatArray,
                         R_world_from_cam: FloatArray) -> FloatArray:
    """Pose parameters from the relative pose ``T_cam_from_deck`` and the camera attitude.

    Parameters
    ----------
    R_cam_from_deck : (..., 3, 3) array of float
    t_cam_from_deck : (..., 3) array of float, metres
        Deck centre in the camera frame.
    R_world_from_cam : (..., 3, 3) array of float

    Returns
    -------
    (..., 6) array of float
        ``(roll_rad, pitch_rad, yaw_rad, surge_m, sway_m, height_m)`` (module docstring).
    """
    R_wd = R_world_from_cam @ R_cam_from_deck
    out = np.empty(R_wd.shape[:-2] + (6,))
    out[..., 0], out[..., 1], out[..., 2] = zyx_from_R(R_wd)
    out[..., 3:] = (R_world_from_cam @ t_cam_from_deck[..., None])[..., 0]
    out[..., 5] *= -1.0
    return out


def relative_from_params(params: FloatArray, R_world_from_cam: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`params_from_relative`.

    Parameters
    ----------
    params : (..., 6) array of float
    R_world_from_cam : (..., 3, 3) array of float

    Returns
    -------
    R_cam_from_deck : (..., 3, 3) array of float
    t_cam_from_deck : (..., 3) array of float, metres
    """
    R_cw = R_world_from_cam.swapaxes(-1, -2)
    R_wd = deck_rotations(params[..., :3])
    tw = params[..., 3:, None] * TRANSLATION_SIGN[:, None]  # (surge, sway, -height)
    return R_cw @ R_wd, (R_cw @ tw)[..., 0]


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
