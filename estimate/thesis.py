"""The faithful ``thesis`` estimator for one frame, registered as ``"thesis"``.

A thin per-frame front end to :func:`deckpose.estimate.thesis_batch.estimate_thesis_batch`
(one implementation serves single frames and Monte Carlo batches). It uses the
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
from deckpose.estimate.thesis_batch import estimate_thesis_batch

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import zyx_from_thesis

METHOD = "thesis"
_NOT_NADIR = "the thesis method assumes a nadir camera with the image top to the bow"


def thesis_inputs(
    detections: Detections, camera: CameraModel, layout: DeckLayout
) -> tuple[np.ndarray, np.ndarray]:
    """Arrange one frame's detections the way the thesis method reads them.

    Returns
    -------
    points_c : (n_ring, 2) array of float
        Centred coordinates ``(X', Y')`` per ring id (row 0 = bow), NaN where missing.
    mask : (n_ring,) array of bool
        Which ring beacons were detected.
    """
    ids = detections.beacon_ids
    keep = (ids >= 0) & (ids < layout.n_ring)
    uv = camera.undistort(detections.points_px[keep])
    points = np.full((layout.n_ring, 2), np.nan)
    points[ids[keep], 0] = uv[:, 0] - camera.cx
    points[ids[keep], 1] = camera.cy - uv[:, 1]
    mask = np.zeros(layout.n_ring, dtype=bool)
    mask[ids[keep]] = True
    return points, mask


@register(METHOD)
def estimate_thesis(
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions = EstimateOptions(),
) -> PoseEstimate:
    """Estimate the deck pose of one frame with the thesis's Algorithm 2.

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
    if not np.allclose(options.R_world_from_cam, R_WORLD_FROM_NADIR_CAM, atol=1e-12):
        return PoseEstimate.failed(METHOD, _NOT_NADIR)
    points, mask = thesis_inputs(detections, camera, layout)
    res = estimate_thesis_batch(points[None], mask[None], camera.fx, camera.fy, layout.radius_m)
    if not res.ok[0]:
        return PoseEstimate.failed(METHOD, res.reason(0))
    t_roll, t_pitch, t_yaw = (float(a[0]) for a in (res.roll_deg, res.pitch_deg, res.yaw_deg))
    roll, pitch, yaw = zyx_from_thesis(*np.radians([t_roll, t_pitch, t_yaw]))
    return PoseEstimate(
        method=METHOD,
        ok=True,
        roll_rad=float(roll),
        pitch_rad=float(pitch),
        yaw_rad=float(yaw),
        height_m=float(res.height[0]),
        surge_m=math.nan,
        sway_m=math.nan,
        inliers=tuple(int(i) for i in np.flatnonzero(mask)),
        extras={
            "thesis_roll_deg": t_roll,
            "thesis_pitch_deg": t_pitch,
            "thesis_yaw_deg": t_yaw,
            "yz2": float(res.yz2[0]),
        },
    )


def estimate_thesis_frames(
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    R_world_from_cam: np.ndarray,
) -> list[PoseEstimate | None]:
    """:func:`estimate_thesis` for many frames in one :func:`estimate_thesis_batch` call.

    Parameters
    ----------
    detections : sequence of Detections
    camera : CameraModel
    layout : DeckLayout
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude (the method needs nadir).

    Returns
    -------
    list of PoseEstimate or None
        The records :func:`estimate_thesis` gives; None for a frame that lists a
        ring beacon twice (left to the single-frame function).
    """
    F = len(detections)
    out: list[PoseEstimate | None] = [None] * F
    if F == 0:
        return out
    nadir = np.all(np.isclose(R_world_from_cam, R_WORLD_FROM_NADIR_CAM, rtol=1e-5, atol=1e-12), axis=(1, 2))
    counts = np.array([len(d) for d in detections], dtype=np.int64)
    frame_of = np.repeat(np.arange(F), counts)
    ids = np.concatenate([d.beacon_ids for d in detections]) if counts.sum() else np.zeros(0, np.int64)
    pts = np.concatenate([d.points_px for d in detections]) if counts.sum() else np.zeros((0, 2))
    keep = (ids >= 0) & (ids < layout.n_ring)
    slot = frame_of[keep] * layout.n_ring + ids[keep]
    twice = np.bincount(slot, minlength=F * layout.n_ring).reshape(F, layout.n_ring).max(axis=1) > 1
    uv = camera.undistort(pts[keep])
    points = np.full((F * layout.n_ring, 2), np.nan)
    points[slot, 0] = uv[:, 0] - camera.cx
    points[slot, 1] = camera.cy - uv[:, 1]
    mask = np.zeros(F * layout.n_ring, dtype=bool)
    mask[slot] = True
    points, mask = points.reshape(F, layout.n_ring, 2), mask.reshape(F, layout.n_ring)
    res = estimate_thesis_batch(points, mask, camera.fx, camera.fy, layout.radius_m)
    roll, pitch, yaw = zyx_from_thesis(*np.radians([res.roll_deg, res.pitch_deg, res.yaw_deg]))
    cols = [a.tolist() for a in (res.roll_deg, res.pitch_deg, res.yaw_deg, roll, pitch, yaw,
                                 res.height, res.yz2)]
    for i in range(F):
        if twice[i]:
            continue
        if not nadir[i]:
            out[i] = PoseEstimate.failed(METHOD, _NOT_NADIR)
        elif not res.ok[i]:
            out[i] = PoseEstimate.failed(METHOD, res.reason(i))
        else:
            t_roll, t_pitch, t_yaw, r, p, y, h, yz2 = (c[i] for c in cols)
            out[i] = PoseEstimate(
                method=METHOD, ok=True, roll_rad=r, pitch_rad=p, yaw_rad=y, height_m=h,
                surge_m=math.nan, sway_m=math.nan, inliers=tuple(np.flatnonzero(mask[i]).tolist()),
                extras={"thesis_roll_deg": t_roll, "thesis_pitch_deg": t_pitch,
                        "thesis_yaw_deg": t_yaw, "yz2": yz2})
    return out
