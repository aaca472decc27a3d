"""The UAV camera's pose during a frame: steady velocity and turn rate, plus vibration.

The camera of a frame sits at :attr:`deckpose.render.plan.FrameSpec.camera_pose` at the
frame time ``t_frame`` (mid-readout, mid-exposure). At motion time ``t`` it is at

* position ``p(t) = p0 + v (t - t_frame)`` (``v`` = ``shutter.uav_velocity_m_per_s``,
  world frame), and
* attitude ``R(t) = R0 Exp(w (t - t_frame)) Exp(j(t))``, with ``w`` the turn rate
  (``shutter.uav_rate_deg_per_s``, about the camera's own x, y, z axes) and ``j(t)`` the
  vibration, a rotation vector in the camera frame whose component on axis ``a`` is
  ``sqrt(2) s sin(2 pi f (t - t_frame) + phi_a)`` (``s`` = ``vibration_deg_rms``, so
  each axis has that RMS over a period; ``f`` = ``vibration_hz``; the phases ``phi_a``
  are drawn per frame from the frame's vibration stream).

A single sinusoid per axis is the simplest model of a multirotor's dominant vibration,
at the propellers' rotation frequency, left by the gimbal's damping. The vibration at
``t_frame`` itself is part of the camera's true pose (``frames.parquet`` records it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.render.shutter_config import ShutterSpec
from numpy.typing import NDArray

from deckpose.pose import CameraPose

__all__ = ["VIBRATION_STREAM", "CameraMotion", "camera_motion", "rotation_from_rotvec"]

#: Stream index of the vibration phases in ``SeedSequence([frame seed, stream])`` (issue 23, item 4).
VIBRATION_STREAM = 2341


@dataclass(frozen=True)
class CameraMotion:
    """The camera's trajectory around one frame time.

    Attributes
    ----------
    base : CameraPose
        The planned camera pose (before vibration) at ``t_frame_s``.
    t_frame_s : float
        Frame time on the motion time base, seconds.
    velocity_m_per_s : (3,) array of float
        Camera velocity, world frame, m/s.
    rate_rad_per_s : (3,) array of float
        Turn rate about the camera's x, y, z axes, rad/s.
    amplitude_rad : float
        Vibration amplitude per axis, radians (``sqrt(2)`` x the RMS).
    frequency_hz : float
        Vibration frequency, Hz.
    phase_rad : (3,) array of float
        Vibration phase per camera axis, radians.
    """

    base: CameraPose
    t_frame_s: float
    velocity_m_per_s: NDArray[np.float64]
    rate_rad_per_s: NDArray[np.float64]
    amplitude_rad: float
    frequency_hz: float
    phase_rad: NDArray[np.float64]

    def pose_at(self, t_s: float) -> CameraPose:
        """The camera pose at motion time ``t_s``, seconds."""
        R, C = self.matrices_at(np.array([float(t_s)]))
        return CameraPose(R[0], C[0])

    def matrices_at(self, t_s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``R_world_from_cam`` (M, 3, 3) and the camera centre (M, 3), metres, at times ``t_s`` (M,)."""
        dt = np.asarray(t_s, float)[:, None] - self.t_frame_s
        jitter = self.amplitude_rad * np.sin(2.0 * math.pi * self.frequency_hz * dt + self.phase_rad)
        R = self.base.R_world_from_cam @ rotation_from_rotvec(self.rate_rad_per_s * dt) @ rotation_from_rotvec(jitter)
        return R, self.base.position_world_m + self.velocity_m_per_s * dt


def rotation_from_rotvec(w_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices (M, 3, 3) of rotation vectors (M, 3), radians (Rodrigues' formula).

    ``R = I + a [w]x + b [w]x^2`` with ``a = sin(t)/t``, ``b = (1 - cos t)/t^2``, ``t = |w|``;
    below ``t = 1e-4`` their Taylor series (error < 1e-17), so ``w = 0`` gives ``I`` exactly.
    """
    w = np.asarray(w_rad, float)
    t2 = np.einsum("mi,mi->m", w, w)
    t = np.sqrt(t2)
    small = t < 1e-4
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(ts) / ts)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ts)) / (ts * ts))
    K = np.zeros((w.shape[0], 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


def camera_motion(spec: ShutterSpec, base: CameraPose, t_frame_s: float,
                  rng: np.random.Generator) -> CameraMotion:
    """The frame's camera trajectory; draws three phases from ``rng`` (the frame's vibration stream).

    Parameters
    ----------
    spec : ShutterSpec
    base : CameraPose
        The planned camera pose at the frame time.
    t_frame_s : float
        Frame time, seconds.
    rng : numpy.random.Generator
        The frame's vibration stream; three uniform phases are drawn whether or not
        the vibration is on.
    """
    phase = rng.uniform(0.0, 2.0 * math.pi, 3)
    return CameraMotion(base, float(t_frame_s), np.asarray(spec.uav_velocity_m_per_s, float),
                        np.radians(np.asarray(spec.uav_rate_deg_per_s, float)),
                        math.sqrt(2.0) * math.radians(spec.vibration_deg_rms), spec.vibration_hz, phase)
