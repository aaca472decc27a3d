"""The ``conic`` estimator: the thesis's ring-ellipse idea done right for a physical camera.

1. Undistort the detections and remove ``K`` (any fx, fy, skew, principal point).
2. Fit the ring beacons' ellipse in float64 (direct, normalised least squares).
3. Recover the deck plane from the conic (:mod:`~deckpose.estimate.circle_pose`):
   when the image of the deck centre is known — from the centre beacon and the
   lines through diametrically opposite ring beacons, which all pass through it —
   the plane's normal is the centre's polar (the vanishing line), a single
   solution; otherwise the conic's eigen-decomposition gives two candidates.
4. For each candidate, align the layout in the plane with every identified
   beacon (2-D Procrustes: yaw about the normal from the bow beacon's id and all
   others, and the centre offset).
5. Keep the candidate that reprojects the identified beacons best. Without the
   imaged centre the ring ids decide, or — if that fails and
   ``assume_level_deck`` is set — the more level deck (stated in the extras).

Full pose (roll, pitch, yaw, height, surge, sway) in the world frame via the
known camera attitude ``options.R_world_from_cam``. The imaged-centre route
makes the closed-form tilt first-order in the image measurements, so the pure
geometric solution stays within about 1.6x the Cramér–Rao bound
(``benchmarks/bench_estimators.py``); the eigen route alone, whose tilt comes
from the ellipse's eccentricity, is several times above it near nadir.
By default one Gauss–Newton step on all identified beacons follows
(``options.conic_polish_steps``; 0 = pure geometry): the reported covariance
assumes an efficient estimate, and with few, noisy beacons far away the pure
geometric solution can sit several of those sigmas off. With
``options.refine`` each candidate is refined to the maximum-likelihood optimum
before the choice.
"""

from __future__ import annotations

import numpy as np
from deckpose.estimate.circle_pose import (
    circle_planes,
    imaged_centre,
    in_plane_alignment,
    plane_from_centre,
)
from deckpose.estimate.ellipse_fit import fit_ellipse_direct
from deckpose.estimate.least_squares import Fit, chi2_at, evaluate_fit, levenberg_marquardt
from deckpose.estimate.observations import Observations
from deckpose.estimate.pose_model import params_from_relative
from deckpose.estimate.registry import EstimateOptions, register
from deckpose.estimate.solution import Candidate, estimate_robustly, pick_candidate

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

#: Ring beacons the ellipse fit needs (5 determine a conic).
MIN_RING_BEACONS = 5
#: The second candidate plane is kept only if its closed-form chi2 is within this of the first's.
ALT_MARGIN_CHI2 = 1000.0


def _polish(fit: Fit, obs: Observations, R_world_from_cam: np.ndarray, steps: int) -> Fit:
    for _ in range(steps):
        p1 = fit.gauss_newton_step()
        if p1 is None or not np.all(np.isfinite(p1)):
            break
        f1 = evaluate_fit(p1, obs, R_world_from_cam)
        if not f1.chi2 <= fit.chi2:
            break
        fit = f1
    return fit


def conic_candidates(obs: Observations, layout: DeckLayout, R_world_from_cam: np.ndarray,
                     *, refine: bool, polish_steps: int = 1) -> list[Fit] | str:
    """The (up to two) pose solutions of the conic method for a set of observations.

    ``polish_steps`` Gauss-Newton steps on all identified beacons follow the
    closed-form solution; ``refine`` runs Levenberg-Marquardt to convergence instead.
    """
    ring = obs.ids < layout.n_ring
    n_ring = int(np.count_nonzero(ring))
    if n_ring < MIN_RING_BEACONS:
        return (f"too few ring beacons for the ellipse fit: {n_ring}, need at least "
                f"{MIN_RING_BEACONS}")
    C = fit_ellipse_direct(obs.xy[ring])
    if C is None:
        return "the ring beacons do not fit an ellipse (collinear or degenerate points)"
    planes = circle_planes(C, layout.radius_m)
    centre = imaged_centre(obs.xy, obs.points_deck_m, ring, obs.ids == layout.centre_id)
    plane = None if centre is None else plane_from_centre(C, centre, obs.xy[ring], layout.radius_m)
    if plane is not None:
        # The imaged-centre plane is the better closed form; the eigen candidate farthest
        # from it stays as the competitor, so a real two-fold ambiguity is still tested.
        up = plane.normal_up
        others = sorted(planes, key=lambda p: -float(np.linalg.norm(p.normal_up - up)))
        planes = [plane, *others[:1]]
    if not planes:
        return "the fitted conic is not the image of a circle in front of the camera"
    starts = []
    for plane in planes:
        aligned = in_plane_alignment(obs.xy, obs.points_deck_m, plane)
        if aligned is None:
            continue
        p0 = params_from_relative(aligned[0], aligned[1], R_world_from_cam)
        if np.all(np.isfinite(p0)):
            starts.append((chi2_at(p0, obs, R_world_from_cam), p0))
    starts.sort(key=lambda s: s[0])
    fits = []
    for chi2_0, p0 in starts:
        if fits and not chi2_0 < starts[0][0] + ALT_MARGIN_CHI2:
            continue  # the other plane reprojects far worse: not a competing solution
        if refine:
            fits.append(levenberg_marquardt(p0, obs, R_world_from_cam))
        else:
            fits.append(_polish(evaluate_fit(p0, obs, R_world_from_cam), obs, R_world_from_cam,
                                polish_steps))
    if not fits:
        return "no candidate plane gives a valid pose (rays parallel to the deck)"
    return fits


@register("conic")
def estimate_conic(
    detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate the deck pose from the ring's image conic (see module docstring).

    Needs at least 5 identified ring beacons; the centre beacon, when detected,
    resolves the two-fold ambiguity. Never raises on bad detections: failures come
    back as a falsy estimate with a reason.
    """
    def solve(o: Observations, R_wc: np.ndarray) -> Candidate | str:
        fits = conic_candidates(o, layout, R_wc, refine=options.refine,
                                polish_steps=options.conic_polish_steps)
        if isinstance(fits, str):
            return fits
        extras = {"centre_beacon_used": float(layout.centre_id in o.ids)
                  if layout.centre_id is not None else 0.0}
        cand = pick_candidate(fits, ambiguity_chi2=options.ambiguity_chi2,
                              assume_level_deck=options.assume_level_deck, extras=extras)
        if not options.refine and isinstance(cand, Candidate) and (
                cand.problem or "assumed_level_deck" in cand.extras):
            # Unconverged candidates can look ambiguous while they share one minimum:
            # settle it at the optima before reporting an ambiguity.
            converged = [levenberg_marquardt(f.params, o, R_wc) for f in fits]
            cand = pick_candidate(converged, ambiguity_chi2=options.ambiguity_chi2,
                                  assume_level_deck=options.assume_level_deck, extras=extras)
        return cand

    return estimate_robustly("conic", solve, detections, camera, layout, options,
                             min_points=MIN_RING_BEACONS, refined=options.refine)
