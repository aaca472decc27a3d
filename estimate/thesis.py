"""The faithful ``thesis`` estimator, registered as ``"thesis"``: frames in, records out.

:func:`estimate_thesis_frames` arranges many frames' detections
(:func:`thesis_inputs`) for :func:`deckpose.estimate.thesis_algorithm.thesis_algorithm`
and turns its results into records; a lone frame (:func:`estimate_thesis`, the
registered per-frame form) is a batch of one. It uses the
identified ring beacons only (the published method has no centre beacon and
takes the image centre as the deck centre's image), bow beacon first, in the
centred coordinates ``X' = u - cx``, ``Y' = cy - v``. Lens distortion, if the
camera has any, is removed first (the thesis assumes corrected images).

The thesis's own angles (``R = Rx(roll) Ry(pitch) Rz(yaw)``) are returned in
``extras`` as ``thesis_roll_deg`` etc.; the estimate's roll/pitch/yaw are the
same rotation in our ZYX convention. The method gives no surge or sway.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from deckpose.estimate.registry import EstimateOptions, register
from deckpose.estimate.thesis_algorithm import thesis_algorithm

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import zyx_from_thesis

METHOD = "thesis"
_NOT_NADIR = "the thesis method assumes a nadir camera with the image top to the bow"


def thesis_inputs(
    detections: Sequence[Detections], camera: CameraModel, layout: DeckLayout
) -> tuple[np.ndarray, np.ndarray]:
    """Arrange frames' detections the way the thesis method reads them.

    Parameters
    ----------
    detections : sequence of F Detections
    camera : CameraModel
        Distortion, if any, is removed first (the thesis assumes corrected images).
    layout : DeckLayout

    Returns
    -------
    points_c : (F, n_ring, 2) array of float
        Centred coordinates ``(X', Y')`` per ring id (column 0 = bow), pixels, NaN where
        missing; of a ring id listed twice in a frame, its last detection.
    mask : (F, n_ring) array of bool
        Which ring beacons each frame detected.
    """
    F, n_ring = len(detections), layout.n_ring
    counts = np.fromiter((len(d) for d in detections), dtype=np.int64, count=F)
    frame_of = np.repeat(np.arange(F), counts)
    if counts.sum():
        ids = np.concatenate([d.beacon_ids for d in detections])
        pts = np.concatenate([d.points_px for d in detections])
    else:
        ids, pts = np.zeros(0, np.int64), np.zeros((0, 2))
    rows = np.flatnonzero((ids >= 0) & (ids < n_ring))
    slot = frame_of[rows] * n_ring + ids[rows]
    if len(set(slot.tolist())) < slot.size:  # a ring id listed twice in a frame: its last detection
        _, first_of_reversed = np.unique(slot[::-1], return_index=True)
        rows = rows[rows.size - 1 - first_of_reversed]
        slot = frame_of[rows] * n_ring + ids[rows]
    uv = camera.undistort(pts[rows])
    points = np.full((F * n_ring, 2), np.nan)
    points[slot, 0] = uv[:, 0] - camera.cx
    points[slot, 1] = camera.cy - uv[:, 1]
    mask = np.zeros(F * n_ring, dtype=bool)
    mask[slot] = True
    return points.reshape(F, n_ring, 2), mask.reshape(F, n_ring)


@register(METHOD)
def estimate_thesis(
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions = EstimateOptions(),
) -> PoseEstimate:
    """Estimate the deck pose of one frame with the thesis's Algorithm 2 (a batch of one).

    Parameters
    ----------
    detections : Detections
        Identified beacon centres, pixels; unassigned and centre detections are ignored.
    camera : CameraModel
    layout : DeckLayout
        Ring radius and beacon count.
    options : EstimateOptions
        The camera must look straight down (the method knows no other attitude).

    Returns
    -------
    PoseEstimate
        Falsy with a reason where the published method breaks down.
    """
    R = np.asarray(options.R_world_from_cam, dtype=float)[None]
    return estimate_thesis_frames([detections], camera, layout, R)[0]


def estimate_thesis_frames(
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    R_world_from_cam: np.ndarray,
) -> list[PoseEstimate]:
    """The thesis's Algorithm 2 for many frames in one :func:`thesis_algorithm` call.

    Parameters
    ----------
    detections : sequence of F Detections
    camera : CameraModel
    layout : DeckLayout
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude (the method needs nadir).

    Returns
    -------
    list of F PoseEstimate
        Falsy with a reason where the published method breaks down.
    """
    F = len(detections)
    if F == 0:
        return []
    # np.isclose(R, nadir, rtol=1e-5, atol=1e-12), written out (a lone frame pays for isclose's checks)
    with np.errstate(invalid="ignore"):
        nadir = np.logical_and.reduce(np.abs(R_world_from_cam - R_WORLD_FROM_NADIR_CAM)
                                      <= 1e-12 + 1e-5 * np.abs(R_WORLD_FROM_NADIR_CAM), axis=(1, 2))
    points, mask = thesis_inputs(detections, camera, layout)
    res = thesis_algorithm(points, mask, camera.fx, camera.fy, layout.radius_m)
    roll, pitch, yaw = zyx_from_thesis(*np.radians([res.roll_deg, res.pitch_deg, res.yaw_deg]))
    cols = [a.tolist() for a in (res.roll_deg, res.pitch_deg, res.yaw_deg, roll, pitch, yaw,
                                 res.height, res.yz2)]
    out: list[PoseEstimate] = []
    for i in range(F):
        if not nadir[i]:
            out.append(PoseEstimate.failed(METHOD, _NOT_NADIR))
        elif not res.ok[i]:
            out.append(PoseEstimate.failed(METHOD, res.reason(i)))
        else:
            t_roll, t_pitch, t_yaw, r, p, y, h, yz2 = (c[i] for c in cols)
            out.append(PoseEstimate(
                method=METHOD, ok=True, roll_rad=r, pitch_rad=p, yaw_rad=y, height_m=h,
                surge_m=math.nan, sway_m=math.nan, inliers=tuple(np.flatnonzero(mask[i]).tolist()),
                extras={"thesis_roll_deg": t_roll, "thesis_pitch_deg": t_pitch,
                        "thesis_yaw_deg": t_yaw, "yz2": yz2}))
    return out
