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

import numpy as np

from deckpose.camera import CameraModel
from deckpose.estimate.registry import EstimateOptions, register
from deckpose.estimate.thesis_batch import estimate_thesis_batch
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import zyx_from_thesis

METHOD = "thesis"


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
        return PoseEstimate.failed(METHOD, "the thesis method assumes a nadir camera with the image top to the bow")
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
