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
from deckpose.render.config import ShutterSpec
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from deckpose.pose import CameraPose

__all__ = ["VIBRATION_STREAM", "CameraMotion", "camera_motion"]

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
        dt = float(t_s) - self.t_frame_s
        jitter = self.amplitude_rad * np.sin(2.0 * math.pi * self.frequency_hz * dt + self.phase_rad)
        R = (self.base.R_world_from_cam @ Rotation.from_rotvec(self.rate_rad_per_s * dt).as_matrix()
             @ Rotation.from_rotvec(jitter).as_matrix())
        return CameraPose(R, self.base.position_world_m + self.velocity_m_per_s * dt)


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
