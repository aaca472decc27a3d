"""Synthetic detections for the estimator tests: exact projection plus seeded Gaussian noise."""

from __future__ import annotations

import numpy as np

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Detections


def detections_for(
    layout: DeckLayout,
    ship: ShipPose,
    camera_pose: CameraPose,
    camera: CameraModel,
    *,
    sigma_px: float = 0.0,
    rng: np.random.Generator | None = None,
    drop_ids: tuple[int, ...] = (),
) -> Detections:
    """Visible beacons of ``layout`` with optional isotropic noise, ids = layout ids."""
    proj = project_layout(layout, ship, camera_pose, camera)
    ids = np.array([i for i in np.flatnonzero(proj.visible) if i not in drop_ids], dtype=int)
    pts = proj.points_px[ids].copy()
    if sigma_px > 0:
        if rng is None:
            raise ValueError("pass a numpy Generator for noisy detections")
        pts = pts + rng.normal(0.0, sigma_px, pts.shape)
    s2 = sigma_px**2 if sigma_px > 0 else 0.25
    return Detections(pts, ids, np.broadcast_to(np.eye(2) * s2, (len(ids), 2, 2)))


def pose_error(est: object, ship: ShipPose, camera_pose: CameraPose) -> np.ndarray:
    """(roll, pitch, yaw, surge, sway, height) error of an estimate; truth relative to the camera."""
    truth = np.array([ship.roll_rad, ship.pitch_rad, ship.yaw_rad,
                      ship.surge_m - camera_pose.position_world_m[0],
                      ship.sway_m - camera_pose.position_world_m[1],
                      camera_pose.position_world_m[2] - ship.heave_m])
    got = np.array([est.roll_rad, est.pitch_rad, est.yaw_rad,  # type: ignore[attr-defined]
                    est.surge_m, est.sway_m, est.height_m])  # type: ignore[attr-defined]
    d = got - truth
    d[:3] = (d[:3] + np.pi) % (2 * np.pi) - np.pi
    return d
