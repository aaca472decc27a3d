"""Rotation conventions of deckpose, and the thesis's own convention.

Frames (see README "Conventions"):

* deck (ship body) frame: x toward the bow, y to port, z up;
* world frame: the level, unyawed deck frame at the nominal deck centre;
* attitude is reported as ZYX yaw-pitch-roll,
  ``R_world_from_deck = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (active rotations of
  column vectors);
* the thesis's "roll, pitch, yaw" are the angles of
  ``R_world_from_deck = Rx(roll) @ Ry(pitch) @ Rz(yaw)`` in the same deck frame
  (verified against the published implementation).

All angles are radians; degrees appear only at the edges (CLI, tables, plots).
Functions accept scalars or arrays of any leading shape ``(...)`` and return
matrices of shape ``(..., 3, 3)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def rot_x(angle_rad: ArrayLike) -> FloatArray:
    """Active rotation about x. Returns (..., 3, 3)."""
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(angle_rad: ArrayLike) -> FloatArray:
    """Active rotation about y. Returns (..., 3, 3)."""
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(angle_rad: ArrayLike) -> FloatArray:
    """Active rotation about z. Returns (..., 3, 3)."""
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def R_from_zyx(roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike) -> FloatArray:
    """``R_world_from_deck = Rz(yaw) Ry(pitch) Rx(roll)`` for ZYX angles."""
    return rot_z(yaw_rad) @ rot_y(pitch_rad) @ rot_x(roll_rad)


def zyx_from_R(R: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Inverse of :func:`R_from_zyx`: ``(roll_rad, pitch_rad, yaw_rad)``, pitch in [-pi/2, pi/2].

    Parameters
    ----------
    R : (..., 3, 3) array of float
        Rotation matrices.
    """
    M = np.asarray(R, dtype=float)
    pitch = -np.arcsin(np.minimum(np.maximum(M[..., 2, 0], -1.0), 1.0))  # (np.clip, without its overhead)
    roll = np.arctan2(M[..., 2, 1], M[..., 2, 2])
    yaw = np.arctan2(M[..., 1, 0], M[..., 0, 0])
    return roll, pitch, yaw


def R_from_thesis(roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike) -> FloatArray:
    """The thesis convention: ``R_world_from_deck = Rx(roll) Ry(pitch) Rz(yaw)``."""
    return rot_x(roll_rad) @ rot_y(pitch_rad) @ rot_z(yaw_rad)


def thesis_from_R(R: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Inverse of :func:`R_from_thesis`: thesis ``(roll_rad, pitch_rad, yaw_rad)``."""
    M = np.asarray(R, dtype=float)
    pitch = np.arcsin(np.clip(M[..., 0, 2], -1.0, 1.0))
    roll = np.arctan2(-M[..., 1, 2], M[..., 2, 2])
    yaw = np.arctan2(-M[..., 0, 1], M[..., 0, 0])
    return roll, pitch, yaw


def zyx_from_thesis(
    roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Convert thesis (X-Y-Z) angles to our ZYX roll, pitch, yaw (same rotation)."""
    return zyx_from_R(R_from_thesis(roll_rad, pitch_rad, yaw_rad))


def thesis_from_zyx(
    roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Convert our ZYX roll, pitch, yaw to the thesis's X-Y-Z angles (same rotation)."""
    return thesis_from_R(R_from_zyx(roll_rad, pitch_rad, yaw_rad))


def wrap_angle_rad(angle_rad: ArrayLike) -> FloatArray:
    """Wrap angles to [-pi, pi)."""
    a = np.asarray(angle_rad, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def wrap_angle_deg(angle_deg: ArrayLike) -> FloatArray:
    """Wrap angles to [-180, 180) degrees."""
    a = np.asarray(angle_deg, dtype=float)
    return (a + 180.0) % 360.0 - 180.0

