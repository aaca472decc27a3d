"""Ship pose from a painted ring's edges: the conic method, then a refinement on the edge points.

1. **Closed form.** The outer edge's fitted conic (undistorted pixels, ``K`` removed) gives
   the two candidate deck planes of a circle of the outer radius
   (:func:`deckpose.estimate.conic_geometry.circle_planes`); on each, the bow mark's two ends
   (cast onto the plane) give the bow direction, hence yaw.
2. **Refinement.** From each candidate, the six pose parameters
   (:mod:`deckpose.estimate.pose_model`, the camera attitude known) are fitted to every edge
   point: each point's ray meets the deck plane at distance ``rho`` from the centre, and its
   residual is ``(rho - r_edge) / |grad rho|``, its distance from the projected edge circle in
   pixels to first order (``grad rho`` in metres per pixel, taken at the linearisation pose);
   the bow mark adds the mean deck angle of its two ends (0 at the bow) over its sigma.
   The line's width is a seventh, nuisance parameter (:data:`FREE_WIDTH`): the inner edge
   lies at ``r_inner - w / 2``, the outer at ``r_outer + w / 2``, ``w`` the width's excess
   over its nominal value. Painted lines are not exactly their nominal width, and the model
   fit of the edge pixels places both edges of a ring on a textured deck slightly toward
   the paint (on average up to 0.14 of a point's bound by day at 1 and 8 MP,
   0.002-0.005 px at 1 MP; under 0.04 of a bound on a flat deck; reports/painted_circle):
   with the width fixed, the bow gap (the edges' arcs are not whole) passes that narrowing
   into pitch and surge, and the two edges' opposite offsets into height. With it free, neither moves them; it costs the pose's bound under
   0.5 % (the width is fixed by the two edges' difference, nearly orthogonal to the pose).
   Each point's residual is whitened by its sigma: its own Cramér–Rao bound
   (:attr:`RingDetection.inner_crb_px <deckpose.ring_detection.RingDetection>`, the model fit
   of its pixels) times its edge's measured excess, the RMS of the points' distances from
   their ellipse over their bounds times the square root of their correlation factor along
   the edge. (Detections without per-point bounds use each edge's RMS distance, as before.)
   The centre disc's edge, when detected, adds its points the same way (circle of
   ``centre_radius_m``). The candidate of least chi-square wins; when the other fits as well
   (chi-square within :data:`AMBIGUITY_CHI2`) at a pose more than 5 sigmas away, the
   estimate is not ok ("ambiguous").
3. **Covariance and bounds.** The covariance is the sandwich ``A^-1 S A^-1`` of the whitened
   Jacobian ``J`` at the optimum, ``A = J^T J``, with ``S`` the Newey–West sum of each edge's
   scores ``J_i r_i`` over their order along the edge
   (:mod:`deckpose.long_run_covariance`): the deck texture under neighbouring edge pixels
   moves neighbouring points together (lag-1 correlation 0.1-0.4 on rendered decks), which
   ``(J^T J)^-1`` would count as independent. Three bounds sit beside it, each the same
   Jacobian with each edge point's sigma replaced by its Cramér–Rao bound (the bow row
   unchanged): ``bound``, the white-noise bound (any unbiased estimator from the same pixels
   under white noise of the measured level, the deck's local level and slope and the paint's
   level beside each point unknown: nuisance parameters); ``bound_known_levels``, the same
   with those levels known (below it); and ``bound_correlated``, the correlated-noise bound:
   each point at its bound, correlated along its edge as the residuals are (the sandwich with
   the residuals' Bartlett-tapered autocorrelation; for the pose's smooth regressors the
   weighted fit is efficient under such noise to first order, Grenander's theorem, so this
   is close to the Cramér–Rao bound of that correlated noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from deckpose.estimate.conic_geometry import circle_planes
from deckpose.estimate.pose_model import params_from_relative, relative_from_params
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.stats import chi2 as chi2_dist

from deckpose.camera import CameraModel
from deckpose.long_run_covariance import (
    ar1_bandwidth,
    autocorrelation,
    bartlett_weights,
    long_run_covariance,
    long_run_covariance_of_model,
    sandwich,
)
from deckpose.painted_ring import CentreMark, PaintedRing
from deckpose.records import POSE_PARAMS, PoseEstimate
from deckpose.ring_detection import RingDetection
from deckpose.rotation import wrap_angle_rad

__all__ = ["AMBIGUITY_CHI2", "DISC_CHECK_ALPHA", "METHOD", "PaintedRingPose", "disc_consistency",
           "estimate_painted_ring"]

FloatArray = NDArray[np.float64]

#: The estimator's name in tables.
METHOD = "painted-ring"
#: A second candidate this close in chi-square at a distinct pose makes the tilt ambiguous.
AMBIGUITY_CHI2 = 25.0
#: Whether :func:`estimate_painted_ring` fits the painted line's width (module docstring, step 2).
FREE_WIDTH = True
#: Edge points the refinement needs per edge.
MIN_POINTS = 20
#: Centre-disc edge points the fit needs to use the disc.
MIN_DISC_POINTS = 12
#: False-alarm rate of the disc's consistency test (:func:`disc_consistency`): a disc whose
#: pose disagrees with the ring's beyond this chi-square tail is left out of the estimate.
DISC_CHECK_ALPHA = 1e-3


@dataclass(frozen=True)
class PaintedRingPose:
    """A painted-ring estimate with its bound.

    Attributes
    ----------
    estimate : PoseEstimate
        Method :data:`METHOD`; covariance from the measured edge-point noise.
    bound : (6, 6) array of float or None
        White-noise bound: each edge point at its Cramér–Rao bound, same Jacobian (None when not ok).
    chi2_per_point : float
        Chi-square of the optimum over the number of residuals.
    bound_known_levels : (6, 6) array of float or None
        The bound were the deck's and paint's levels beside each edge point known (white
        noise only): below ``bound``, which has them as nuisance parameters.
    used_disc : bool
        Whether the centre disc's edge was in the fit.
    disc_check_chi2 : float
        :func:`disc_consistency`'s statistic when a disc was detected (NaN otherwise): above
        the chi-square quantile of :data:`DISC_CHECK_ALPHA`, the disc is left out.
    bound_correlated : (6, 6) array of float or None
        Correlated-noise bound: each edge point at its Cramér–Rao bound, correlated along its
        edge as the residuals are (module docstring, step 3).
    """

    estimate: PoseEstimate
    bound: FloatArray | None = None
    chi2_per_point: float = math.nan
    bound_known_levels: FloatArray | None = None
    used_disc: bool = False
    disc_check_chi2: float = math.nan
    bound_correlated: FloatArray | None = None


def _normalised(camera: CameraModel, points_px: FloatArray) -> FloatArray:
    """Undistorted normalised rays ``(x, y, 1)`` of pixels, (N, 3)."""
    und = camera.undistort(points_px)
    y = (und[:, 1] - camera.cy) / camera.fy
    x = (und[:, 0] - camera.cx - camera.K[0, 1] * y) / camera.fx
    return np.column_stack([x, y, np.ones_like(x)])


def _deck_xy(params: FloatArray, R_wc: FloatArray, rays: FloatArray) -> FloatArray:
    """Deck-frame ``(x, y)`` metres where rays (N, 3) meet the deck plane of pose ``params``."""
    R, t = relative_from_params(params, R_wc)
    n = R[:, 2]
    denom = rays @ n
    s = float(n @ t) / np.where(np.abs(denom) > 1e-12, denom, np.nan)
    P = s[:, None] * rays - t
    return (P @ R)[:, :2]


def _grad_norm(camera: CameraModel, params: FloatArray, R_wc: FloatArray, points_px: FloatArray,
               f: str) -> FloatArray:
    """``|d q / d pixel|`` of ``q`` = ``rho`` (m/px) or ``phi`` (rad/px) at each point, by differences."""
    def q(p: FloatArray) -> FloatArray:
        xy = _deck_xy(params, R_wc, _normalised(camera, p))
        return np.hypot(xy[:, 0], xy[:, 1]) if f == "rho" else np.arctan2(xy[:, 1], xy[:, 0])

    h = 0.5
    du = (q(points_px + [h, 0]) - q(points_px - [h, 0])) / (2 * h)
    dv = (q(points_px + [0, h]) - q(points_px - [0, h])) / (2 * h)
    return np.hypot(du, dv)


def _residuals(p: FloatArray, R_wc: FloatArray, edges: list[_Edge], end_rays: FloatArray, sig_phi: float
               ) -> FloatArray:
    """Whitened residuals: each edge point's pixel distance from its edge circle, then the bow angle.

    ``p`` holds the six pose parameters and, when the line width is free, a seventh: the
    line's width minus its nominal width, metres (each ring edge moves by half of it).
    """
    pose = p[:6]
    width_m = float(p[6]) if len(p) > 6 else 0.0
    res = []
    for e in edges:
        xy = _deck_xy(pose, R_wc, e.rays)
        res.append((np.hypot(xy[:, 0], xy[:, 1]) - e.radius_m - e.width_side * width_m) / e.m_per_px / e.sigma_px)
    e_xy = _deck_xy(pose, R_wc, end_rays)
    ang = np.arctan2(e_xy[:, 1], e_xy[:, 0])
    phi = math.atan2(float(np.sin(ang).sum()), float(np.cos(ang).sum()))  # mean angle of the two ends
    res.append(np.array([phi / sig_phi]))
    return np.nan_to_num(np.concatenate(res), nan=1e6)


@dataclass(frozen=True)
class _Edge:
    """One edge circle's points for the fit: rays, radius, pixel scale and per-point sigmas."""

    points_px: FloatArray
    rays: FloatArray
    radius_m: float
    sigma_px: FloatArray      # (N,) the points' sigma (measured scatter)
    bound_px: FloatArray      # (N,) their Cramér–Rao bound
    m_per_px: FloatArray      # (N,) |grad rho| at the linearisation pose
    width_side: float = 0.0   # how the edge's radius moves with the line's width: -1/2 inner, +1/2 outer

    def at(self, m_per_px: FloatArray) -> _Edge:
        return _Edge(self.points_px, self.rays, self.radius_m, self.sigma_px, self.bound_px, m_per_px,
                     self.width_side)


def _edges(det: RingDetection, camera: CameraModel, ring: PaintedRing) -> list[_Edge]:
    """The edges the fit uses: the ring's two, and the centre disc's when detected."""
    out = []
    ones = [np.ones(len(p)) for p in det.edges_px]
    if det.has_point_bounds:
        crbs = [det.inner_crb_px, det.outer_crb_px]
        sig = [c * det.crb_ratio[k] * math.sqrt(det.residual_scale[k]) for k, c in enumerate(crbs)]
        bnd = crbs
    else:  # points without their own bounds: the edge's RMS and the image-derived bound per point
        sig = [o * det.rms_px[k] * math.sqrt(det.residual_scale[k]) for k, o in enumerate(ones)]
        bnd = [o * det.edge_crb_px / math.sqrt(det.spacing_px[k]) for k, o in enumerate(ones)]
    for k, r in enumerate(ring.edge_radii_m):
        pts = det.edges_px[k]
        out.append(_Edge(pts, _normalised(camera, pts), r, sig[k], bnd[k], ones[k], (-0.5, 0.5)[k]))
    if (ring.centre_mark is CentreMark.DISC and len(det.disc_px) >= MIN_DISC_POINTS
            and math.isfinite(det.disc_sigma_scale)):
        out.append(_Edge(det.disc_px, _normalised(camera, det.disc_px), ring.centre_radius_m,
                         det.disc_crb_px * det.disc_sigma_scale, det.disc_crb_px, np.ones(len(det.disc_px))))
    return out


def _candidates(det: RingDetection, camera: CameraModel, ring: PaintedRing, R_wc: FloatArray) -> list[FloatArray]:
    """Closed-form pose parameters of both candidate deck planes (outer conic and bow)."""
    Cn = camera.K.T @ det.conics_px[1] @ camera.K
    ends = _normalised(camera, det.bow_ends_px)
    out = []
    with np.errstate(all="ignore"):  # (NaN where the conic is no circle's image: ``valid`` says so)
        normals, centres, valid = circle_planes(Cn[None], ring.outer_radius_m)  # a batch of one
    for n, c in zip(normals[0][valid[0]], centres[0][valid[0]]):
        s = float(n @ c) / (ends @ n)
        v = (s[:, None] * ends).mean(axis=0) - c
        v -= (v @ n) * n  # the ends' midpoint lies on the bow ray from the centre (gap and bar alike)
        if not np.linalg.norm(v) > 0:
            continue
        x = v / np.linalg.norm(v)
        R = np.asarray(np.column_stack([x, np.cross(n, x), n]), dtype=np.float64)
        out.append(params_from_relative(R, c, R_wc))
    return out


def _failed(det: RingDetection, reason: str) -> PaintedRingPose:
    """A failed estimate of the detection's frame, with its reason."""
    return PaintedRingPose(PoseEstimate.failed(METHOD, reason).for_frame(det.frame_id))


def estimate_painted_ring(det: RingDetection, camera: CameraModel, ring: PaintedRing,
                          R_world_from_cam: FloatArray, *, free_width: bool = FREE_WIDTH) -> PaintedRingPose:
    """Ship pose from a :class:`~deckpose.ring_detection.RingDetection` (module docstring).

    Parameters
    ----------
    det : RingDetection
    camera : CameraModel
    ring : PaintedRing
    R_world_from_cam : (3, 3) array of float
        The camera's attitude (known, as for every estimator of deckpose).
    free_width : bool, keyword-only
        Fit the painted line's width as a nuisance parameter (module docstring, step 2).

    Returns
    -------
    PaintedRingPose
        Never raises on a bad detection: failures are a falsy estimate with a reason.
    """
    if not det.ok:
        return _failed(det, f"ring not detected: {det.reason}")
    if min(len(det.inner_px), len(det.outer_px)) < MIN_POINTS:
        return _failed(det, f"too few edge points (needs {MIN_POINTS} per edge)")
    R_wc = np.asarray(R_world_from_cam, dtype=float)
    edges = _edges(det, camera, ring)
    if not all(np.all(e.sigma_px > 0) for e in edges):
        return _failed(det, "edge points without scatter: no noise to weigh them by")
    with_disc = _fit(det, camera, ring, R_wc, edges, free_width)
    if len(edges) == 2 or not with_disc.estimate.ok:
        return with_disc
    ring_only = _fit(det, camera, ring, R_wc, edges[:2], free_width)
    if not ring_only.estimate.ok:
        return with_disc
    stat, dof = disc_consistency(ring_only.estimate, with_disc.estimate)
    if dof > 0 and stat > float(chi2_dist.ppf(1.0 - DISC_CHECK_ALPHA, dof)):
        return replace(ring_only, used_disc=False, disc_check_chi2=stat)
    return replace(with_disc, used_disc=True, disc_check_chi2=stat)


def disc_consistency(ring_only: PoseEstimate, with_disc: PoseEstimate) -> tuple[float, int]:
    """Hausman's test of the centre disc: does adding it move the pose more than its noise allows?

    Were the disc's edge unbiased, the ring-only estimate and the estimate with the disc would
    differ by noise of covariance ``S_ring - S_disc`` (the efficient one's difference from a
    less efficient one is uncorrelated with it). The statistic is that difference's
    chi-square, ``d^T (S_ring - S_disc)^+ d``, over the directions in which the disc lowers
    the variance by at least 5 % (whitened by ``S_ring``; elsewhere the difference carries no
    information about the disc), with as many degrees of freedom.

    Returns
    -------
    stat : float
    dof : int
        0 when the disc adds no information (then ``stat`` is 0).
    """
    S_r, S_d = ring_only.covariance, with_disc.covariance
    if S_r is None or S_d is None:
        return 0.0, 0
    d = np.array([getattr(with_disc, p) - getattr(ring_only, p) for p in POSE_PARAMS])
    d[:3] = wrap_angle_rad(d[:3])
    vals, vecs = np.linalg.eigh(S_r)
    W = vecs @ np.diag(1.0 / np.sqrt(np.maximum(vals, 1e-300))) @ vecs.T  # S_r^(-1/2)
    lam, U = np.linalg.eigh(np.eye(6) - W @ S_d @ W)
    keep = lam >= 0.05
    z = U[:, keep].T @ (W @ d)
    return float(np.sum(z * z / lam[keep])), int(keep.sum())


def _fit(det: RingDetection, camera: CameraModel, ring: PaintedRing, R_wc: FloatArray,
         edges: list[_Edge], free_width: bool) -> PaintedRingPose:
    """The refinement on ``edges`` (module docstring, steps 1-3); ``free_width`` adds the line's width."""
    end_rays = _normalised(camera, det.bow_ends_px)

    def solve(x0: FloatArray) -> tuple[FloatArray, FloatArray, float, FloatArray]:
        x = x0
        J, cost, r = np.zeros((0, 6)), math.inf, np.zeros(0)
        for _ in range(2):  # the pixel scales at the start, then at the first optimum
            fit_edges = [e.at(_grad_norm(camera, x[:6], R_wc, e.points_px, "rho")) for e in edges]
            g_phi = _grad_norm(camera, x[:6], R_wc, det.bow_ends_px, "phi")
            sig_phi = float(det.bow_sigma_px * np.mean(g_phi) / math.sqrt(2.0))
            sol = least_squares(_residuals, x, method="lm", x_scale="jac", args=(R_wc, fit_edges, end_rays, sig_phi))
            x, J, cost = np.asarray(sol.x, np.float64), np.asarray(sol.jac, np.float64), float(sol.cost)
            r = np.asarray(sol.fun, np.float64)
        return x, J, 2.0 * cost, r

    cands = _candidates(det, camera, ring, R_wc)
    if not cands:
        return _failed(det, "the outer edge's conic is not the image of a circle in front of the camera")
    extra = [0.0] if free_width else []
    sols = sorted((solve(np.concatenate([c, extra])) for c in cands), key=lambda s: s[2])
    x, J, chi2, r = sols[0]
    n_res = sum(len(e.points_px) for e in edges) + 1
    # the bounds' rows: the same Jacobian, each edge row at its point's bound (the bow row unchanged)
    ratio = np.concatenate([e.sigma_px / e.bound_px for e in edges] + [np.ones(1)])
    try:
        cov, bound_corr = _correlated_covariances(J, r, [len(e.points_px) for e in edges], ratio)
    except np.linalg.LinAlgError:
        return _failed(det, "singular normal matrix: the edges do not fix the pose")
    # the pose's block: the line width, when free, is a nuisance whose uncertainty the pose's includes
    cov, bound_corr = cov[:6, :6], bound_corr[:6, :6]
    sig = np.sqrt(np.maximum(np.diag(cov), 0.0))  # (exact points: a variance of roundoff, either sign)
    if len(sols) > 1 and sols[1][2] - chi2 < AMBIGUITY_CHI2:
        d = sols[1][0][:6] - x[:6]
        d[:3] = wrap_angle_rad(d[:3])
        if np.any(np.abs(d) > 5 * sig):
            return _failed(det, f"ambiguous: both deck planes fit the edges (chi2 {chi2:.0f} and {sols[1][2]:.0f})")
    bound = _bound(J, ratio)
    known = det.known_levels_ratio
    bound_known = _bound(J, ratio / np.concatenate([np.full(n_res - 1, known), [1.0]])) if math.isfinite(known) else None
    est = PoseEstimate(METHOD, True, roll_rad=float(x[0]), pitch_rad=float(x[1]), yaw_rad=float(x[2]),
                       surge_m=float(x[3]), sway_m=float(x[4]), height_m=float(x[5]), covariance=cov,
                       frame_id=det.frame_id)
    return PaintedRingPose(est, bound, chi2 / n_res, bound_known, len(edges) > 2,
                           bound_correlated=bound_corr if np.all(np.isfinite(ratio) & (ratio > 0)) else None)


def _correlated_covariances(J: FloatArray, r: FloatArray, sizes: list[int], ratio: FloatArray
                            ) -> tuple[FloatArray, FloatArray]:
    """The fit's covariance and its correlated-noise bound, both sandwiches over the edges' order.

    ``J`` (n, 6) and ``r`` (n,) are the whitened Jacobian and residuals at the optimum: the
    edges' points in their order along each edge (``sizes`` of them per edge), then the bow
    row. Each edge's scores ``J_i r_i`` are summed with their correlation along the edge
    (:func:`~deckpose.long_run_covariance.long_run_covariance`, Andrews' bandwidth from the
    edge's residuals); the bow row counts at its model variance (one residual tells nothing
    of its own scatter). The covariance is ``A^-1 S A^-1``.

    The correlated-noise bound is the same sandwich with each edge row at its point's
    white-noise bound (rows times ``ratio``) and the residuals' measured correlation
    (Bartlett-tapered) in place of their products: the covariance this fit would have were
    each point's noise at its Cramér–Rao bound, correlated along the edge as measured.

    Raises
    ------
    numpy.linalg.LinAlgError
        When the normal matrix is singular.
    """
    A = J.T @ J
    Jb = J * np.where(np.isfinite(ratio) & (ratio > 0), ratio, 1.0)[:, None]
    S, Sb = J[-1:].T @ J[-1:], Jb[-1:].T @ Jb[-1:]
    start = 0
    for n in sizes:
        sl = slice(start, start + n)
        start += n
        lag = ar1_bandwidth(r[sl])
        S += long_run_covariance(J[sl] * r[sl, None], lag)
        Sb += long_run_covariance_of_model(Jb[sl], autocorrelation(r[sl], lag) * bartlett_weights(lag))
    return sandwich(A, S), sandwich(Jb.T @ Jb, Sb)


def _bound(J: FloatArray, ratio: FloatArray) -> FloatArray | None:
    """The pose block of ``(J^T J)^-1`` with each whitened row scaled by ``ratio`` (its sigma over its bound), or None."""
    if not np.all(np.isfinite(ratio) & (ratio > 0)):
        return None
    Jb = J * ratio[:, None]
    try:
        return np.asarray(np.linalg.inv(Jb.T @ Jb)[:6, :6], dtype=np.float64)
    except np.linalg.LinAlgError:
        return None
