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

:func:`estimate_with_prior` is the walk over a sequence given each frame's own
identification and estimate (as ``deckpose detect`` and the estimate stage made them:
:func:`deckpose.sequence_run.estimate_run_with_prior`); :func:`estimate_sequence` makes
those from the detections first.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.detect.identification import Identification, IdentifyOptions
from deckpose.detect.identify import identify_beacons
from deckpose.detect.prior_identify import PriorIdentifyOptions, identify_with_prior
from deckpose.errors import ConfigError, check_shape
from deckpose.estimate.batch import estimate_batch
from deckpose.estimate.pose_model import relative_from_params
from deckpose.estimate.registry import EstimateOptions
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

__all__ = ["IdentifiedBy", "SequenceFrame", "SequenceOptions", "SequenceResult", "estimate_sequence",
           "estimate_with_prior"]

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
        Age of the prior tried, seconds: the one that identified the frame (``PRIOR``) or
        the one that failed to (``NONE``); NaN where no prior was tried.
    """

    estimate: PoseEstimate
    identified_by: IdentifiedBy
    beacon_ids: NDArray[np.int64]
    prior_age_s: float = math.nan


def _params(e: PoseEstimate) -> FloatArray:
    return np.array([e.roll_rad, e.pitch_rad, e.yaw_rad, e.surge_m, e.sway_m, e.height_m], float)


def _check_time_order(frames: Sequence[SequenceFrame]) -> None:
    stamps = [f.stamp_ns for f in frames]
    if any(b < a for a, b in itertools.pairwise(stamps)):
        raise ConfigError("estimate_sequence: frames must be in increasing stamp_ns; sort them by capture time")


def estimate_sequence(
    frames: Sequence[SequenceFrame],
    camera: CameraModel,
    layout: DeckLayout,
    estimate_options: EstimateOptions,
    *,
    options: SequenceOptions = SequenceOptions(),
) -> list[SequenceResult]:
    """Identify and estimate frames in time order, each helped by the last ok estimate.

    Each frame is identified alone (:func:`~deckpose.detect.identify.identify_beacons`)
    and the identified ones estimated as one batch; then :func:`estimate_with_prior`.

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
    _check_time_order(frames)
    idents = [identify_beacons(f.points_px, layout, camera, rgb_flux=f.rgb_flux, options=options.identify)
              for f in frames]
    done = [k for k, i in enumerate(idents) if i.ok]
    dets = [Detections(frames[k].points_px, idents[k].beacon_ids, frames[k].covariance_px2,
                       frame_id=frames[k].frame_id) for k in done]
    R = np.stack([frames[k].R_world_from_cam for k in done]) if done else np.zeros((0, 3, 3))
    got = estimate_batch(options.method, dets, camera, layout, estimate_options, R_world_from_cam=R) if done else []
    alone = [PoseEstimate(method=options.method, ok=False, reason=f"identification: {i.reason}",
                          frame_id=f.frame_id) for f, i in zip(frames, idents, strict=True)]
    for k, e in zip(done, got, strict=True):
        alone[k] = e
    return estimate_with_prior(frames, idents, alone, camera, layout, estimate_options, options=options)


def estimate_with_prior(
    frames: Sequence[SequenceFrame],
    identifications: Sequence[Identification],
    estimates: Sequence[PoseEstimate],
    camera: CameraModel,
    layout: DeckLayout,
    estimate_options: EstimateOptions,
    *,
    options: SequenceOptions = SequenceOptions(),
) -> list[SequenceResult]:
    """Walk a time sequence, identifying by the last ok estimate the frames not identified alone.

    A frame identified alone, or whose own estimate is ok, keeps its estimate
    (``FRAME``). Any other frame, where an ok estimate at most
    ``options.max_prior_age_s`` old exists, is identified by that estimate's pose seen
    with the frame's camera attitude (:func:`~deckpose.detect.prior_identify.identify_with_prior`)
    and estimated with ``options.method`` (``PRIOR``); its ok estimate is the next prior.
    Where that fails the frame is ``NONE``: its reason is its identification's, and what
    the prior did.

    Parameters
    ----------
    frames : sequence of SequenceFrame
        In increasing ``stamp_ns``, all of one camera.
    identifications : sequence of Identification
        Each frame's own (ok where its ids came from the frame alone).
    estimates : sequence of PoseEstimate
        Each frame's estimate from those ids (a failed one where there were none).
    camera : CameraModel
    layout : DeckLayout
    estimate_options : EstimateOptions
    options : SequenceOptions, keyword-only

    Returns
    -------
    list of SequenceResult
        One per frame, in order.

    Raises
    ------
    ConfigError
        Frames out of time order, or the three sequences of different lengths.
    """
    if not len(frames) == len(identifications) == len(estimates):
        raise ConfigError(f"estimate_with_prior: {len(frames)} frames, {len(identifications)} identifications and "
                          f"{len(estimates)} estimates; give one of each per frame")
    _check_time_order(frames)
    out: list[SequenceResult] = []
    last: tuple[int, PoseEstimate] | None = None
    for f, ident, alone in zip(frames, identifications, estimates, strict=True):
        if ident.ok or alone.ok:
            if alone.ok:
                last = (f.stamp_ns, alone)
            out.append(SequenceResult(alone, IdentifiedBy.FRAME, ident.beacon_ids))
            continue
        reason = f"identification: {ident.reason}"
        if last is None:
            out.append(SequenceResult(
                dataclasses.replace(alone, reason=reason + "; no earlier ok estimate to identify by"),
                IdentifiedBy.NONE, ident.beacon_ids))
            continue
        age = (f.stamp_ns - last[0]) * 1e-9
        if age > options.max_prior_age_s:
            out.append(SequenceResult(
                dataclasses.replace(alone, reason=reason + f"; the last ok estimate is {age:.2f} s old "
                                    f"(> {options.max_prior_age_s} s)"),
                IdentifiedBy.NONE, ident.beacon_ids))
            continue
        R, t = relative_from_params(_params(last[1]), f.R_world_from_cam)
        by_prior = identify_with_prior(f.points_px, layout, camera, R, t, options=options.prior)
        if not by_prior.ok:
            out.append(SequenceResult(
                dataclasses.replace(alone, reason=reason + f"; with the prior pose ({age:.2f} s old): "
                                    f"{by_prior.reason}"),
                IdentifiedBy.NONE, ident.beacon_ids, age))
            continue
        det = Detections(f.points_px, by_prior.beacon_ids, f.covariance_px2, frame_id=f.frame_id)
        est = estimate_batch(options.method, [det], camera, layout, estimate_options,
                             R_world_from_cam=f.R_world_from_cam[None])[0]
        if est.ok:
            last = (f.stamp_ns, est)
        out.append(SequenceResult(est, IdentifiedBy.PRIOR, by_prior.beacon_ids, age))
    return out
