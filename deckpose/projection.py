"""Exact projection of the deck layout into a camera: the ground truth of every stage.

Two forms:

* :func:`project_layout` — any ship pose, camera pose and camera model (with
  distortion), returning pixel positions and visibility;
* :func:`project_thesis_centred` — the thesis's Algorithm 1, vectorised over
  frames: a camera at distance D straight above the deck centre, centred image
  coordinates ``X' = u - W/2`` (right) and ``Y' = H/2 - v`` (up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from deckpose.camera import CameraModel
from deckpose.errors import check_shape
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class BeaconProjection:
    """Where each beacon of a layout lands in an image.

    Attributes
    ----------
    points_px : (N, 2) array of float
        Distorted pixel position of each beacon centre (NaN where behind the camera).
    depth_m : (N,) array of float
        Camera-frame z of each beacon, metres.
    in_image : (N,) array of bool
        ``0 <= u <= W`` and ``0 <= v <= H`` and in front of the camera.
    facing : (N,) array of bool
        The camera sees the lit (upper) side of the deck.
    apparent_radius_px : (N,) array of float
        Approximate image radius of the beacon's emitting disc, pixels.
    """

    points_px: FloatArray
    depth_m: FloatArray
    in_image: BoolArray
    facing: BoolArray
    apparent_radius_px: FloatArray

    def __post_init__(self) -> None:
        n = np.shape(self.points_px)[0]
        check_shape("points_px", np.asarray(self.points_px), (n, 2))
        for name in ("depth_m", "in_image", "facing", "apparent_radius_px"):
            check_shape(name, np.asarray(getattr(self, name)), (n,))
            object.__setattr__(self, name, _ro(getattr(self, name)))
        object.__setattr__(self, "points_px", _ro(self.points_px))

    @property
    def visible(self) -> BoolArray:
        """In the image and not hidden by the deck itself."""
        return self.in_image & self.facing


def project_layout(
    layout: DeckLayout, ship: ShipPose, camera_pose: CameraPose, camera: CameraModel
) -> BeaconProjection:
    """Project every beacon of ``layout`` for one ship pose and camera.

    Parameters
    ----------
    layout : DeckLayout
    ship : ShipPose
        ``T_world_from_deck``.
    camera_pose : CameraPose
        ``T_world_from_cam``.
    camera : CameraModel
        Intrinsics and distortion.

    Returns
    -------
    BeaconProjection
    """
    T = T_cam_from_deck(ship, camera_pose)
    P_deck = layout.positions_deck_m()
    P_cam = P_deck @ T[:3, :3].T + T[:3, 3]
    depth = P_cam[:, 2]
    in_front = depth > 1e-9
    pts = np.full((P_cam.shape[0], 2), np.nan)
    if np.any(in_front):
        pts[in_front] = camera.project(P_cam[in_front])
    in_image = in_front & camera.in_image(np.nan_to_num(pts, nan=-1.0))
    # Deck normal (deck +z) in camera frame; the lit side faces the camera when the
    # vector from a beacon to the camera centre has a positive component along it.
    n_cam = T[:3, 2]
    facing = (-P_cam) @ n_cam > 0.0
    f_px = float(np.sqrt(camera.fx * camera.fy))
    with np.errstate(divide="ignore", invalid="ignore"):
        radius_px = np.where(in_front, layout.beacon_radius_m * f_px / np.where(in_front, depth, 1.0), np.nan)
    return BeaconProjection(pts, depth, in_image, facing, radius_px)


def project_thesis_centred(
    points_deck: ArrayLike, R_world_from_deck: ArrayLike, distance: ArrayLike, fx: float, fy: float
) -> FloatArray:
    """The thesis's forward model (Algorithm 1), vectorised over frames.

    A camera at distance ``D`` straight above the deck centre, image top toward
    the bow. Beacon ``P = R @ P0`` lands at ``X' = -fx*Py/(D - Pz)``,
    ``Y' = fy*Px/(D - Pz)`` (centred coordinates, X' right, Y' up, pixels).

    Parameters
    ----------
    points_deck : (N, 3) array of float
        Beacon positions in the deck frame (thesis units).
    R_world_from_deck : (F, 3, 3) array of float
        Deck attitude per frame.
    distance : (F,) array of float
        Camera distance above the deck centre per frame.
    fx, fy : float
        Focal lengths, pixels.

    Returns
    -------
    (F, N, 2) array of float
        Centred image coordinates ``(X', Y')``.
    """
    P0 = np.asarray(points_deck, dtype=float)
    R = np.asarray(R_world_from_deck, dtype=float)
    D = np.asarray(distance, dtype=float)
    check_shape("points_deck", P0, (None, 3))
    check_shape("R_world_from_deck", R, (None, 3, 3))
    check_shape("distance", D, (R.shape[0],))
    P = np.einsum("fij,nj->fni", R, P0)
    denom = D[:, None] - P[..., 2]
    return np.stack([-fx * P[..., 1] / denom, fy * P[..., 0] / denom], axis=-1)
