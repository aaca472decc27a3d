"""Frames of a two-ring deck seen from low heights, projected here by hand (pinhole, no library projection).

A small thesis-form camera (640x480, 75 deg focal angle both ways, as the thesis's) over the
two-ring layout of ``configs/approach_tworing.yaml`` (12 at 10 m, the centre, 6 at 1 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.rotation import R_from_zyx

LAYOUT = DeckLayout(n_ring=12, radius_m=10.0, has_centre=True, inner_n_ring=6, inner_radius_m=1.0)
W, H, FOCAL_ANGLE_DEG = 640, 480, 75.0


def camera() -> CameraModel:
    t = math.tan(math.radians(FOCAL_ANGLE_DEG) / 2)
    K = np.array([[W / 2 / t, 0, W / 2], [0, H / 2 / t, H / 2], [0, 0, 1.0]])
    return CameraModel(W, H, K, np.zeros(0), "small-thesis")


@dataclass(frozen=True)
class TrueFrame:
    """Exact image of the deck: visible beacons' pixels, their true ids and colours, the truth."""

    points_px: np.ndarray  # (K, 2) exact
    ids: np.ndarray  # (K,)
    rgb: np.ndarray  # (K, 3)
    R_world_from_cam: np.ndarray
    params: np.ndarray  # (6,) roll, pitch, yaw, surge, sway, height: what the estimator reports


def true_frame(height_m: float, *, x_m: float = 0.0, y_m: float = 0.0, roll_rad: float = 0.03,
               pitch_rad: float = -0.02, yaw_rad: float = 0.4, layout: DeckLayout = LAYOUT) -> TrueFrame:
    """A nadir camera at ``(x_m, y_m, height_m)`` over a deck at the origin with the given attitude."""
    R_wd = R_from_zyx(roll_rad, pitch_rad, yaw_rad)
    R_wc = np.asarray(R_WORLD_FROM_NADIR_CAM, float)
    c = np.array([x_m, y_m, height_m])
    P_world = layout.positions_deck_m() @ R_wd.T
    P_cam = (P_world - c) @ R_wc  # R_cam_from_world = R_wc.T
    K = camera().K
    u = K[0, 0] * P_cam[:, 0] / P_cam[:, 2] + K[0, 2]
    v = K[1, 1] * P_cam[:, 1] / P_cam[:, 2] + K[1, 2]
    # in front, inside the image (pixel centres at integers: edges at -0.5 and W - 0.5)
    vis = (P_cam[:, 2] > 0) & (u > -0.5) & (u < W - 0.5) & (v > -0.5) & (v < H - 0.5)
    ids = np.flatnonzero(vis)
    # the estimator's parameters: deck centre minus camera along world x, y; camera height over it
    params = np.array([roll_rad, pitch_rad, yaw_rad, -x_m, -y_m, height_m])
    return TrueFrame(np.column_stack([u, v])[ids], ids, layout.beacon_rgb_all()[ids], R_wc, params)


def shuffled_noisy(f: TrueFrame, sigma_px: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points with Gaussian noise, in a random order (ids kept aside), their colours, the true ids."""
    order = rng.permutation(f.ids.size)
    pts = f.points_px[order] + rng.normal(0.0, sigma_px, (f.ids.size, 2))
    return pts, f.rgb[order], f.ids[order]
