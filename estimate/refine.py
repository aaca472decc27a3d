"""Maximum-likelihood refinement of any estimator's result (``--refine``).

Starting from an estimate (the thesis's, which has no surge or sway, starts
them at 0: the deck centre under the camera), minimise the reprojection error
of the identified beacons weighted by the detections' covariances, with the
same outlier removal, covariance and flags as the package's own estimators.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from deckpose.estimate.least_squares import levenberg_marquardt
from deckpose.estimate.observations import Observations
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution import Candidate, estimate_robustly

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

#: Identified beacons the refinement needs (6 parameters, 2 residuals per beacon, plus margin).
MIN_BEACONS = 4


def initial_params(estimate: PoseEstimate) -> np.ndarray | None:
    """The 6 pose parameters of an estimate; surge and sway default to 0. None if unusable."""
    p = [estimate.roll_rad, estimate.pitch_rad, estimate.yaw_rad,
         0.0 if math.isnan(estimate.surge_m) else estimate.surge_m,
         0.0 if math.isnan(estimate.sway_m) else estimate.sway_m, estimate.height_m]
    arr = np.array(p, dtype=float)
    return arr if np.all(np.isfinite(arr)) and arr[5] > 0 else None


def refine_estimate(
    estimate: PoseEstimate,
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
) -> PoseEstimate:
    """Refine ``estimate`` to the maximum-likelihood pose.

    Parameters
    ----------
    estimate : PoseEstimate
        Any estimator's result; a failed one is returned unchanged.
    detections, camera, layout, options
        As for the estimator that produced it.

    Returns
    -------
    PoseEstimate
        Same ``method``; ``extras["refined"] = 1`` plus the original extras
        (the original values under ``unrefined_*``).
    """
    if not estimate.ok:
        return estimate
    p0 = initial_params(estimate)
    if p0 is None:
        return estimate

    def solve(o: Observations, R_wc: np.ndarray) -> Candidate | str:
        return Candidate(levenberg_marquardt(p0, o, R_wc))

    refined = estimate_robustly(estimate.method, solve, detections, camera, layout, options,
                                min_points=MIN_BEACONS, refined=True,
                                failure_prefix="refinement failed numerically")
    if not refined.ok and refined.reason.startswith("refinement failed numerically"):
        return refined
    extras = {k: v for k, v in estimate.extras.items() if k not in refined.extras}
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "height_m", "surge_m", "sway_m"):
        extras["unrefined_" + name] = float(getattr(estimate, name))
    extras.update(refined.extras)
    return dataclasses.replace(refined, extras=extras)
