"""Where the thesis method's own assumptions make it wrong: an off-centre deck.

The faithful ``thesis`` estimator assumes the deck centre lies on the optical
axis (no surge, no sway). Off that axis its roll and pitch are biased, and
steeply: on exact projections at 40 m with roll = pitch = 3 deg, 0.05 m of surge
gave pitch 1.85 deg, 0.3 m gave -3.89 deg, all called ok. This check marks such a
frame not ok (its faithful outputs stay in their columns), by three steps per frame:

1. an estimator without the assumption (``pnp``) gives the deck's offset and its
   covariance; an offset within :data:`OFFSET_CHI2` of zero is no evidence
   against the assumption, and the frame stays ok;
2. the thesis method's *bias* at that pose: the layout projected exactly at the
   ``pnp`` pose (with its offset) goes through the thesis method, and its roll,
   pitch and yaw are compared with the pose's own;
3. the thesis method's *noise* at that pose: the pixel covariance propagated
   through the thesis method (finite differences of its outputs in every image
   coordinate).

Where the bias of roll, pitch or yaw exceeds that angle's noise sigma, the
assumption makes the error larger than the noise does, and the frame is not ok.
The thesis's own batch (:func:`~deckpose.estimate.thesis_algorithm.thesis_algorithm`)
does all thesis evaluations of a frame in one call.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from deckpose.estimate.observations import pixel_covariances
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.thesis import thesis_inputs
from deckpose.estimate.thesis_algorithm import thesis_algorithm

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Detections, PoseEstimate
from deckpose.rotation import wrap_angle_deg, zyx_from_thesis

__all__ = ["OFFSET_CHI2", "flag_off_centre"]

#: Chi-square (2 dof) above which the deck's (surge, sway) is told from zero: 99.9 %.
OFFSET_CHI2 = 13.8
#: Image-coordinate step of the finite differences, pixels.
STEP_PX = 1e-3


def _zyx_deg(res, idx: np.ndarray) -> np.ndarray:
    """ZYX roll, pitch, yaw (degrees) of thesis batch results ``idx``, (k, 3)."""
    t = np.radians(np.column_stack([res.roll_deg[idx], res.pitch_deg[idx], res.yaw_deg[idx]]))
    return np.degrees(np.array([zyx_from_thesis(*row) for row in t]).reshape(-1, 3))



def flag_off_centre(
    estimates: Sequence[PoseEstimate],
    detections: Sequence[Detections],
    references: Sequence[PoseEstimate],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
) -> list[PoseEstimate]:
    """The thesis ``estimates`` with frames its centring assumption biases beyond noise not ok.

    Parameters
    ----------
    estimates : sequence of PoseEstimate
        Unrefined ``thesis`` estimates, one per frame.
    detections : sequence of Detections
        The frames' detections.
    references : sequence of PoseEstimate
        ``pnp`` estimates of the same frames (surge, sway and their covariance).
    camera, layout, options
        As the estimates were made with.

    Returns
    -------
    list of PoseEstimate
        The estimates, a flagged one with ``ok = False``, a reason and its numbers kept.
    """
    out = list(estimates)
    cam0 = camera.pinhole()  # thesis inputs are undistorted
    for i, (est, det, ref) in enumerate(zip(estimates, detections, references)):
        if not est.ok or not ref.ok or ref.covariance is None:
            continue
        off = np.array([ref.surge_m, ref.sway_m])
        C = np.asarray(ref.covariance)[3:5, 3:5]
        try:
            chi2 = float(off @ np.linalg.solve(C, off))
        except np.linalg.LinAlgError:
            continue
        if not (math.isfinite(chi2) and chi2 > OFFSET_CHI2):
            continue
        pose = ShipPose(ref.roll_rad, ref.pitch_rad, ref.yaw_rad, surge_m=ref.surge_m,
                        sway_m=ref.sway_m)
        exact = project_layout(layout, pose, CameraPose.nadir(ref.height_m), cam0).points_px
        mask = thesis_inputs([det], camera, layout)[1][0]
        ring = np.flatnonzero(mask)
        base = np.full((layout.n_ring, 2), np.nan)
        base[ring, 0] = exact[ring, 0] - camera.cx
        base[ring, 1] = camera.cy - exact[ring, 1]
        # frame 0: the exact projections; then one per image coordinate moved by STEP_PX
        n = ring.size
        stack = np.repeat(base[None], 1 + 2 * n, axis=0)
        for k, r in enumerate(ring):
            stack[1 + 2 * k, r, 0] += STEP_PX
            stack[2 + 2 * k, r, 1] += STEP_PX  # Y' = cy - v: +dY is -dv
        res = thesis_algorithm(stack, np.repeat(mask[None], len(stack), axis=0),
                                    camera.fx, camera.fy, layout.radius_m)
        if not res.ok.all():
            continue  # the thesis method fails near this pose: no bias to measure
        ang = _zyx_deg(res, np.arange(len(stack)))
        truth = np.degrees([ref.roll_rad, ref.pitch_rad, ref.yaw_rad])
        bias = wrap_angle_deg(ang[0] - truth)
        J = wrap_angle_deg(ang[1:] - ang[0]).T / STEP_PX  # (3, 2n): d angle / d (X', Y') per point
        J[:, 1::2] *= -1.0  # back to d / d v
        cov_px, _ = pixel_covariances(np.asarray(det.covariance_px2, dtype=float), options.sigma_px,
                                      options.use_detection_covariance)
        ids = det.beacon_ids
        blocks = np.zeros((2 * n, 2 * n))
        for k, r in enumerate(ring):
            j = int(np.flatnonzero(ids == r)[0])
            blocks[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = cov_px[j]
        sigma = np.sqrt(np.maximum(np.diag(J @ blocks @ J.T), 0.0))
        worse = np.abs(bias) > sigma
        if not worse.any():
            continue
        names = ("roll", "pitch", "yaw")
        which = ", ".join(f"{names[k]} {bias[k]:+.2f} deg (noise {sigma[k]:.2f})"
                          for k in np.flatnonzero(worse))
        reason = (
            f"off-centre deck: the thesis method assumes the deck centre on the optical axis, "
            f"but pnp puts it {math.hypot(*off):.2f} m off (chi2 {chi2:.0f}); that biases {which}; "
            "use --method pnp or conic, or --refine"
        )
        out[i] = dataclasses.replace(est, ok=False, reason=reason)
    return out
