"""Maximum-likelihood refinement of any estimator's result (``--refine``).

Starting from an estimate (the thesis's, which has no surge or sway, starts
them at 0: the deck centre under the camera), minimise the reprojection error
of the identified beacons weighted by the detections' covariances, with the
same outlier removal, covariance and flags as the package's own estimators.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from deckpose.estimate.least_squares import levenberg_marquardt
from deckpose.estimate.observations import Observations, build_observations
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.solution import Candidate, make_estimate, solve_robust

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
    R_wc = np.asarray(options.R_world_from_cam, dtype=float)
    with np.errstate(all="ignore"):
        try:
            obs = build_observations(detections, camera, layout, sigma_px=options.sigma_px,
                                     use_detection_covariance=options.use_detection_covariance)

            def solve(o: Observations) -> Candidate | str:
                return Candidate(levenberg_marquardt(p0, o, R_wc))

            result, used, removed = solve_robust(
                obs, solve, min_points=MIN_BEACONS, outlier_chi2=options.outlier_chi2,
                max_outliers=options.max_outliers)
            refined = make_estimate(estimate.method, result, used, removed, R_world_from_cam=R_wc,
                                    max_reprojection_rms_px=options.max_reprojection_rms_px,
                                    refined=True)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, cv2.error) as exc:
            return PoseEstimate.failed(estimate.method, f"refinement failed numerically: {exc}")
    extras = {k: v for k, v in estimate.extras.items() if k not in refined.extras}
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "height_m", "surge_m", "sway_m"):
        extras["unrefined_" + name] = float(getattr(estimate, name))
    extras.update(refined.extras)
    return dataclasses.replace(refined, extras=extras)
