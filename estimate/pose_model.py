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
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from deckpose.rotation import zyx_from_R

FloatArray = NDArray[np.float64]

def params_from_relative(
    R_cam_from_deck: FloatArray, t_cam_from_deck: FloatArray, R_world_from_cam: FloatArray
) -> FloatArray:
    """Pose parameters from the relative pose ``T_cam_from_deck`` and the camera attitude.

    Parameters
    ----------
    R_cam_from_deck : (3, 3) array of float
    t_cam_from_deck : (3,) array of float, metres
        Deck centre in the camera frame.
    R_world_from_cam : (3, 3) array of float

    Returns
    -------
    (6,) array of float
        ``(roll_rad, pitch_rad, yaw_rad, surge_m, sway_m, height_m)``.
    """
    R_wd = R_world_from_cam @ R_cam_from_deck
    roll, pitch, yaw = zyx_from_R(R_wd)
    d = R_world_from_cam @ np.asarray(t_cam_from_deck, dtype=float)
    return np.array([float(roll), float(pitch), float(yaw), d[0], d[1], -d[2]])


def relative_from_params(
    params: FloatArray, R_world_from_cam: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`params_from_relative`: ``(R_cam_from_deck, t_cam_from_deck)``."""
    p = np.asarray(params, dtype=float)
    R_cw = np.asarray(R_world_from_cam, dtype=float).T
    R_wd = _rotation_and_derivatives(float(p[0]), float(p[1]), float(p[2]))[0]
    return R_cw @ R_wd, R_cw @ np.array([p[3], p[4], -p[5]])


def _rotation_and_derivatives(roll: float, pitch: float, yaw: float) -> FloatArray:
    """``R_world_from_deck`` and its derivatives by roll, pitch, yaw, stacked (4, 3, 3)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    # R = Rz(yaw) Ry(pitch) Rx(roll)
    R = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
         [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
         [-sp, cp * sr, cp * cr]]
    dr = [[0.0, cy * sp * cr + sy * sr, -cy * sp * sr + sy * cr],
          [0.0, sy * sp * cr - cy * sr, -sy * sp * sr - cy * cr],
          [0.0, cp * cr, -cp * sr]]
    dp = [[-cy * sp, cy * cp * sr, cy * cp * cr],
          [-sy * sp, sy * cp * sr, sy * cp * cr],
          [-cp, -sp * sr, -sp * cr]]
    dy = [[-R[1][0], -R[1][1], -R[1][2]], [R[0][0], R[0][1], R[0][2]], [0.0, 0.0, 0.0]]
    return np.array([R, dr, dp, dy])


def project_normalised(
    params: FloatArray, points_deck_m: FloatArray, R_world_from_cam: FloatArray, *, jacobian: bool = True
) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Normalised image points of deck points, and their Jacobian with respect to the parameters.

    Parameters
    ----------
    params : (6,) array of float
        Pose parameters (module docstring).
    points_deck_m : (N, 3) array of float, metres
    R_world_from_cam : (3, 3) array of float
    jacobian : bool, keyword-only
        Also return the (N, 2, 6) Jacobian.

    Returns
    -------
    xy : (N, 2) array of float
        Normalised image coordinates ``(X/Z, Y/Z)``.
    J : (N, 2, 6) array of float or None
        ``d xy / d params``.
    depth_m : (N,) array of float
        Camera-frame Z of each point (positive in front of the camera).
    """
    R_cw = R_world_from_cam.T
    Rs = R_cw @ _rotation_and_derivatives(float(params[0]), float(params[1]), float(params[2]))
    d = R_cw @ np.array([params[3], params[4], -params[5]])
    # (4, N, 3): camera-frame points, then their derivatives by roll, pitch, yaw.
    Q = points_deck_m @ Rs.transpose(0, 2, 1)
    Pc = Q[0] + d
    invZ = 1.0 / Pc[:, 2]
    xy = Pc[:, :2] * invZ[:, None]
    if not jacobian:
        return xy, None, Pc[:, 2]
    # d Pc / d params as (N, 3, 6): rotations act on the point, translations are constant columns.
    dPc = np.concatenate([Q[1:].transpose(1, 2, 0),
                          np.broadcast_to(R_cw * np.array([1.0, 1.0, -1.0]), (Pc.shape[0], 3, 3))], axis=2)
    J = (dPc[:, :2, :] - xy[:, :, None] * dPc[:, 2:3, :]) * invZ[:, None, None]
    return xy, J, Pc[:, 2]
