"""Identify and estimate a time sequence of frames, each frame helped by the last good pose.

A frame is identified alone first (:func:`deckpose.detect.identify.identify_beacons`:
the outer ring, else the inner ring of a two-ring layout). Where that fails (the bow
beacons out of view, too little of a ring for its ellipse) and an ok estimate of an
earlier frame is at most ``max_prior_age_s`` old, that estimate's deck pose, seen with
this frame's camera attitude, predicts where every beacon lies, and the detections are
matched to it (:func:`deckpose.detect.prior_identify.identify_with_prior`). The pose
then comes from whatever was identified (``pnp``: 4 beacons or more), with its own
ok, reason and covariance. A frame identified neither way is not ok, and says why.

The prior is the previous ok *estimate*, never the truth, and never a filtered state
(a filter that had been fed a wrong estimate would carry it on).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.detect.identify import IdentifyOptions, identify_beacons
from deckpose.detect.prior_identify import PriorIdentifyOptions, identify_with_prior
from deckpose.errors import ConfigError, check_shape
from deckpose.estimate.batch import estimate_batch
from deckpose.estimate.pose_model import relative_from_params
from deckpose.estimate.registry import EstimateOptions
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

__all__ = ["IdentifiedBy", "SequenceFrame", "SequenceOptions", "SequenceResult", "estimate_sequence"]

FloatArray = NDArray[np.float64]


class IdentifiedBy(Enum):
    """How a frame's beacon ids were found."""

    FRAME = "frame"  # the frame alone (a ring's ellipse and its bow)
    PRIOR = "prior"  # the last ok estimate's pose
    NONE = "none"  # not identified


@dataclass(frozen=True)
class SequenceFrame:
    """One frame's detections before identification.

    Attributes
    ----------
    frame_id : int
    stamp_ns : int
        Capture time, integer nanoseconds (one time base for the sequence).
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    covariance_px2 : (N, 2, 2) array of float
        Their covariances, px^2.
    R_world_from_cam : (3, 3) array of float
        The camera attitude (the IMU's).
    rgb_flux : (N, 3) array of float or None
        Per-channel flux of each blob (None: mono).
    """

    frame_id: int
    stamp_ns: int
    points_px: FloatArray
    covariance_px2: FloatArray
    R_world_from_cam: FloatArray
    rgb_flux: FloatArray | None = None

    def __post_init__(self) -> None:
        pts = np.array(self.points_px, dtype=float)
        check_shape("points_px", pts, (None, 2))
        cov = np.array(self.covariance_px2, dtype=float)
        check_shape("covariance_px2", cov, (pts.shape[0], 2, 2))
        R = np.array(self.R_world_from_cam, dtype=float)
        check_shape("R_world_from_cam", R, (3, 3))
        arrays = {"points_px": pts, "covariance_px2": cov, "R_world_from_cam": R}
        if self.rgb_flux is not None:
            rgb = np.array(self.rgb_flux, dtype=float)
            check_shape("rgb_flux", rgb, (pts.shape[0], 3))
            arrays["rgb_flux"] = rgb
        for name, a in arrays.items():
            a.setflags(write=False)
            object.__setattr__(self, name, a)


@dataclass(frozen=True)
class SequenceOptions:
    """Options of :func:`estimate_sequence`.

    Attributes
    ----------
    max_prior_age_s : float
        Oldest ok estimate used as a prior, seconds (0: never use a prior). The prior
        must predict every beacon to within the gate (0.3 of the beacons' spacing in
        the image): a tenth of a second of ship and UAV motion moves them a few pixels
        where the spacing is hundreds; seconds can move them by a whole spacing.
    method : str
        The estimator (any registered; ``pnp`` takes any 4 or more identified beacons).
    identify : IdentifyOptions
        Identification of a frame alone.
    prior : PriorIdentifyOptions
        Identification by the prior pose.
    """

    max_prior_age_s: float = 0.5
    method: str = "pnp"
    identify: IdentifyOptions = field(default_factory=IdentifyOptions)
    prior: PriorIdentifyOptions = field(default_factory=PriorIdentifyOptions)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_prior_age_s) and self.max_prior_age_s >= 0):
            raise ConfigError(f"max_prior_age_s must be >= 0 seconds, got {self.max_prior_age_s}")


@dataclass(frozen=True)
class SequenceResult:
    """One frame's identification and estimate.

    Attributes
    ----------
    estimate : PoseEstimate
    identified_by : IdentifiedBy
    beacon_ids : (N,) array of int64
        The ids given to the frame's detections (-1: none).
    prior_age_s : float
        Age of the prior used (NaN when none was used).
    """

    estimate: PoseEstimate
    identified_by: IdentifiedBy
    beacon_ids: NDArray[np.int64]
    prior_age_s: float = math.nan


def _params(e: PoseEstimate) -> FloatArray:
    return np.array([e.roll_rad, e.pitch_rad, e.yaw_rad, e.surge_m, e.sway_m, e.height_m], float)


def estimate_sequence(
    frames: Sequence[SequenceFrame],
    camera: CameraModel,
    layout: DeckLayout,
    estimate_options: EstimateOptions,
    *,
    options: SequenceOptions = SequenceOptions(),
) -> list[SequenceResult]:
    """Identify and estimate frames in time order, each helped by the last ok estimate.

    Parameters
    ----------
    frames : sequence of SequenceFrame
        In increasing ``stamp_ns``.
    camera : CameraModel
    layout : DeckLayout
    estimate_options : EstimateOptions
        Options of the estimator (its ``R_world_from_cam`` is replaced by each frame's).
    options : SequenceOptions, keyword-only

    Returns
    -------
    list of SequenceResult
        One per frame, in order.

    Raises
    ------
    ConfigError
        Frames out of time order.
    """
    id_opts, prior_opts = options.identify, options.prior
    stamps = [f.stamp_ns for f in frames]
    if any(b < a for a, b in itertools.pairwise(stamps)):
        raise ConfigError("estimate_sequence: frames must be in increasing stamp_ns; sort them by capture time")
    out: list[SequenceResult] = []
    last: tuple[int, PoseEstimate] | None = None
    for f in frames:
        ident = identify_beacons(f.points_px, layout, camera, rgb_flux=f.rgb_flux, options=id_opts)
        how, age, reason = IdentifiedBy.FRAME, math.nan, ""
        if not ident.ok:
            reason = f"identification: {ident.reason}"
            how = IdentifiedBy.NONE
            if last is not None:
                age = (f.stamp_ns - last[0]) * 1e-9
                if age <= options.max_prior_age_s:
                    R, t = relative_from_params(_params(last[1]), f.R_world_from_cam)
                    by_prior = identify_with_prior(f.points_px, layout, camera, R, t, options=prior_opts)
                    if by_prior.ok:
                        ident, how = by_prior, IdentifiedBy.PRIOR
                    else:
                        reason += f"; with the prior pose ({age:.2f} s old): {by_prior.reason}"
                else:
                    reason += f"; the last ok estimate is {age:.2f} s old (> {options.max_prior_age_s} s)"
                    age = math.nan
            else:
                reason += "; no earlier ok estimate to identify by"
        if how is IdentifiedBy.NONE:
            est = PoseEstimate(method=options.method, ok=False, reason=reason, frame_id=f.frame_id)
        else:
            det = Detections(f.points_px, ident.beacon_ids, f.covariance_px2, frame_id=f.frame_id)
            est = estimate_batch(options.method, [det], camera, layout, estimate_options,
                                 R_world_from_cam=f.R_world_from_cam[None])[0]
            if est.ok:
                last = (f.stamp_ns, est)
        out.append(SequenceResult(est, how, ident.beacon_ids, age if how is IdentifiedBy.PRIOR else math.nan))
    return out
