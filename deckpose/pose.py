"""Ship and camera poses, as frozen records that know their frames.

* :class:`ShipPose` gives ``T_world_from_deck``: ZYX attitude plus surge (world x),
  sway (world y) and heave (world z, positive up) of the deck centre.
* :class:`CameraPose` gives ``T_world_from_cam`` for an OpenCV camera
  (x right, y down, z forward).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError, check_shape
from deckpose.rotation import R_from_zyx, thesis_from_R, zyx_from_R

FloatArray = NDArray[np.float64]

#: ``R_world_from_cam`` of a camera looking straight down with the image top toward
#: the bow: camera x = world -y (starboard), camera y = world -x (stern), camera z = world -z.
R_WORLD_FROM_NADIR_CAM: FloatArray = np.array(
    [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]
)
R_WORLD_FROM_NADIR_CAM.setflags(write=False)


@dataclass(frozen=True)
class ShipPose:
    """Pose of the deck in the world frame.

    Attributes
    ----------
    roll_rad, pitch_rad, yaw_rad : float
        ZYX angles, ``R_world_from_deck = Rz(yaw) Ry(pitch) Rx(roll)``.
    heave_m, surge_m, sway_m : float
        Deck-centre displacement along world z (up), x and y, metres.
    """

    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    heave_m: float = 0.0
    surge_m: float = 0.0
    sway_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ConfigError(f"ShipPose.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)

    @property
    def R_world_from_deck(self) -> FloatArray:
        return R_from_zyx(self.roll_rad, self.pitch_rad, self.yaw_rad)

    @property
    def t_world_from_deck(self) -> FloatArray:
        return np.array([self.surge_m, self.sway_m, self.heave_m])

    @property
    def T_world_from_deck(self) -> FloatArray:
        T = np.eye(4)
        T[:3, :3] = self.R_world_from_deck
        T[:3, 3] = self.t_world_from_deck
        return T

    def thesis_angles_rad(self) -> tuple[float, float, float]:
        """The same attitude as thesis (X-Y-Z) roll, pitch, yaw."""
        r, p, y = thesis_from_R(self.R_world_from_deck)
        return float(r), float(p), float(y)

    @classmethod
    def from_R(cls, R_world_from_deck: FloatArray, t_world_m: FloatArray | None = None) -> ShipPose:
        """Build from a rotation matrix and optional ``(surge, sway, heave)``."""
        roll, pitch, yaw = zyx_from_R(R_world_from_deck)
        t = np.zeros(3) if t_world_m is None else np.asarray(t_world_m, dtype=float)
        return cls(float(roll), float(pitch), float(yaw), float(t[2]), float(t[0]), float(t[1]))


@dataclass(frozen=True)
class CameraPose:
    """Pose of the (OpenCV) camera in the world frame.

    Attributes
    ----------
    R_world_from_cam : (3, 3) array of float
    position_world_m : (3,) array of float, metres
    """

    R_world_from_cam: FloatArray
    position_world_m: FloatArray

    def __post_init__(self) -> None:
        R = np.array(self.R_world_from_cam, dtype=float)
        t = np.array(self.position_world_m, dtype=float).ravel()
        check_shape("R_world_from_cam", R, (3, 3))
        check_shape("position_world_m", t, (3,))
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ConfigError("R_world_from_cam must be a proper rotation matrix")
        if not np.all(np.isfinite(t)):
            raise ConfigError("camera position must be finite")
        R.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "R_world_from_cam", R)
        object.__setattr__(self, "position_world_m", t)

    @classmethod
    def nadir(
        cls,
        height_m: float,
        *,
        x_m: float = 0.0,
        y_m: float = 0.0,
        R_nadir_from_cam: FloatArray | None = None,
    ) -> CameraPose:
        """A camera at ``height_m`` above the world origin looking straight down, image top to bow.

        ``R_nadir_from_cam`` optionally tilts the camera away from nadir
        (a rotation expressed in the nadir camera's own frame).
        """
        if not math.isfinite(height_m) or height_m <= 0:
            raise ConfigError(f"camera height must be positive, got {height_m}")
        R = R_WORLD_FROM_NADIR_CAM if R_nadir_from_cam is None else R_WORLD_FROM_NADIR_CAM @ R_nadir_from_cam
        return cls(R, np.array([x_m, y_m, height_m]))

    @property
    def T_world_from_cam(self) -> FloatArray:
        T = np.eye(4)
        T[:3, :3] = self.R_world_from_cam
        T[:3, 3] = self.position_world_m
        return T

    @property
    def T_cam_from_world(self) -> FloatArray:
        T = np.eye(4)
        T[:3, :3] = self.R_world_from_cam.T
        T[:3, 3] = -self.R_world_from_cam.T @ self.position_world_m
        return T


def T_cam_from_deck(ship: ShipPose, camera_pose: CameraPose) -> FloatArray:
    """``T_cam_from_deck = T_cam_from_world @ T_world_from_deck``, (4, 4)."""
    return camera_pose.T_cam_from_world @ ship.T_world_from_deck
