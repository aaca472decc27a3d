"""Sub-pixel edges of a painted ring: coarse ring, edge profiles, the model fit of each edge's pixels.

1. **Coarse ring.** Bright, band-shaped components (:mod:`deckpose.detect.ring_candidates`),
   on the frame shrunk to at most :data:`COARSE_SIDE_PX` a side, are tried largest first until
   one gives the ring's edges with the ring's size ratio (the deck's edge and the helipad
   circle are passed over).
2. **First edges.** Along the outward normal of the ring's mid line, at one profile per
   pixel of its length, the raw image is sampled every 0.25 px (bilinear), smoothed along
   the profile (sigma ``smooth_px``), and differentiated. The inner edge is the largest
   rise, the outer the largest fall; a parabola through the three samples at each extreme
   gives a first sub-pixel position (it locks toward pixel positions, 0.04 px RMS). A profile
   counts when both edges are found in order and its step (paint minus deck) is at least
   ``min_contrast_fraction`` of the median step: occluders, shadows, the worn paint and the
   bow gap drop out here. Each edge's points are undistorted and fitted by a robust conic
   (:func:`deckpose.detect.edge_conic.fit_edge_conic`); a second pass samples the profiles
   again along the mid line of the two fitted ellipses.
3. **Edges from their pixels.** The edge blur is measured (:func:`~deckpose.detect.edge_profile_fit.blur_of_edges`)
   and each edge's pixels, one image row or column at a time, are fitted by the image of a
   blurred step over a local deck line and a paint level (:func:`deckpose.detect.model_edge.model_edge`):
   points without pixel locking, each with its own Cramér–Rao bound, and a robust conic
   through them. ``centre_disc`` adds the centre disc's edge the same way
   (:mod:`deckpose.detect.centre_disc`).
4. **Bow mark.** The paint along the ring's mid line (gap: where it is missing) or along a
   curve through the bar (bar: where paint is present outside the ring) is a signature
   along the ring; the longest run below (gap) or above (bar) half the step is the mark,
   its two ends found by linear interpolation at half the step.
5. **What the image allows.** ``contrast_dn`` is the median fitted step, ``noise_dn`` the
   deck's robust residual noise beside the inner edge, ``blur_px`` the fitted blur,
   ``edge_crb_px`` the median of the points' bounds; ``crb_ratio`` and ``residual_scale``
   say how far the points' real scatter about their ellipse exceeds their bounds (RMS ratio,
   and the variance factor of its correlation along the edge).

Only paint brighter than the deck is looked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from deckpose.detect.centre_disc import find_centre_disc
from deckpose.detect.edge_conic import fit_edge_conic
from deckpose.detect.edge_profile_fit import blur_of_edges, conic_edge_profiles
from deckpose.detect.model_edge import ModelEdge, model_edge
from deckpose.detect.ring_candidates import ring_candidates
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.painted_ring import BowMark, CentreMark, PaintedRing, ellipse_params
from deckpose.ring_detection import RingDetection

__all__ = ["RingEdgeOptions", "detect_ring_edges", "ring_detection_row"]

FloatArray = NDArray[np.float64]

#: Most profiles per edge (a 64 MP frame's ring from 20 m is ~8000 px around).
MAX_PROFILES = 12000
#: Longest side of the image the coarse ring is looked for in, pixels (larger frames are shrunk).
COARSE_SIDE_PX = 1200
#: The bow mark's ends are half-level crossings interpolated linearly between signature samples
#: about a pixel apart on a box-sampled edge: 0.045 px RMS measured on analytic images
#: (tests/estimate/test_painted_ring_pose.py's frames) where the noise alone gives 0.02 px;
#: this is added in quadrature to the noise's sigma.
BOW_INTERPOLATION_PX = 0.04
#: Reach into the deck of the profiles the edge blur is measured on, pixels.
BLUR_DECK_PX = 5.0
#: Coarse rings tried, largest first, until one gives the ring's edges.
MAX_CANDIDATES = 4
#: Largest relative difference of the edges' size ratio (sqrt of the ellipses' axis products, inner
#: over outer) from the ring's radius ratio: perspective moves it by ~1e-4 (0.93924 measured
#: against 0.93939); the helipad circle's 0.3 m line on 6 m gives 0.951, 1.3 % off the 8 m ring's.
RATIO_TOLERANCE = 0.005


@dataclass(frozen=True)
class RingEdgeOptions:
    """Options of :func:`detect_ring_edges`.

    Attributes
    ----------
    smooth_px : float
        Gaussian sigma of the smoothing along each profile before the derivative, pixels.
    step_px : float
        Sample spacing along a profile, pixels.
    min_contrast_fraction : float
        A profile counts when its step is at least this fraction of the median step.
    min_coverage : float
        Fraction of the ring's profiles that must give both edges (less: the ring is cut by
        the frame edge or hidden beyond what the fit tolerates).
    centre_disc : bool
        Also fit the centre disc's edge (:mod:`deckpose.detect.centre_disc`) for the
        estimator. Off by default: its bound is 1.8x tighter in tilt, but on analytic frames
        its pose errors reach 4.6 of their sigmas (the frames of tests/estimate/test_painted_ring_pose.py,
        seed 3) where the ring alone stays within 2.
    """

    smooth_px: float = 1.0
    step_px: float = 0.25
    min_contrast_fraction: float = 0.5
    min_coverage: float = 0.6
    centre_disc: bool = False

    def __post_init__(self) -> None:
        for name, lo, hi in (("smooth_px", 0.3, 5.0), ("step_px", 0.05, 1.0), ("min_contrast_fraction", 0.0, 1.0),
                             ("min_coverage", 0.05, 1.0)):
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise ConfigError(f"RingEdgeOptions.{name}: must be in [{lo}, {hi}], got {v}")


def _grey(image: NDArray[Any]) -> NDArray[np.float32]:
    img = np.asarray(image)
    if img.ndim == 3:
        return img.astype(np.float32).sum(axis=2, dtype=np.float32)
    return img.astype(np.float32)


def _ellipse_points(cu: float, cv: float, a: float, b: float, th: float, n: int) -> FloatArray:
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    c, s = math.cos(th), math.sin(th)
    x, y = a * np.cos(t), b * np.sin(t)
    return np.column_stack([cu + c * x - s * y, cv + s * x + c * y])


def _outward_normals(curve: FloatArray, centre: FloatArray) -> FloatArray:
    """Unit normals of a closed curve's points (central differences), pointing away from ``centre``."""
    tangent = np.roll(curve, -1, axis=0) - np.roll(curve, 1, axis=0)
    n = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    flip = np.sum(n * (curve - centre), axis=1) < 0
    n[flip] *= -1
    return n


def _sample(grey: NDArray[np.float32], pts: FloatArray) -> FloatArray:
    """Bilinear samples of the image at points (..., 2); NaN outside."""
    mx = np.ascontiguousarray(pts[..., 0], np.float32)
    my = np.ascontiguousarray(pts[..., 1], np.float32)
    out = cv2.remap(grey, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    H, W = grey.shape
    inside = (mx >= 0) & (my >= 0) & (mx <= W - 1) & (my <= H - 1)
    return np.where(inside, out, np.nan).astype(float)


@dataclass(frozen=True)
class _Profiles:
    inner_px: FloatArray      # (N, 2)
    outer_px: FloatArray      # (N, 2)
    valid: NDArray[np.bool_]  # (N,)
    step_dn: FloatArray       # (N,) paint minus deck
    peak_slope: FloatArray    # (N,) mean |derivative| at the two edges, DN/px
    mid_dn: FloatArray        # (N,) raw paint level on the mid line


def _profiles(grey: NDArray[np.float32], mid: FloatArray, normals: FloatArray, half_px: FloatArray,
              opt: RingEdgeOptions) -> _Profiles:
    """Edge points of the inner and outer edges along the normals of the mid line."""
    L = float(np.max(1.8 * half_px + 3.0 * opt.smooth_px + 4.0))
    s = np.arange(-L, L + 0.5 * opt.step_px, opt.step_px)
    pts = mid[:, None, :] + s[None, :, None] * normals[:, None, :]
    raw = _sample(grey, pts)
    ok = np.all(np.isfinite(raw), axis=1)
    raw_f = np.where(np.isfinite(raw), raw, 0.0)
    prof = gaussian_filter1d(raw_f, opt.smooth_px / opt.step_px, axis=1, mode="nearest")
    d = np.gradient(prof, opt.step_px, axis=1)
    hw = half_px[:, None]
    d_in = np.where(s[None, :] < 0.5 * hw, d, -np.inf)
    d_out = np.where(s[None, :] > -0.5 * hw, -d, -np.inf)
    k_in, k_out = np.argmax(d_in, axis=1), np.argmax(d_out, axis=1)
    n = len(s)
    ok &= (k_in > 0) & (k_in < n - 1) & (k_out > 0) & (k_out < n - 1) & (k_in < k_out)

    def refine(dd: FloatArray, k: NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
        kk = np.clip(k, 1, n - 2)
        r = np.arange(len(k))
        y0, y1, y2 = dd[r, kk - 1], dd[r, kk], dd[r, kk + 1]
        den = y0 - 2 * y1 + y2
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.where(den < 0, 0.5 * (y0 - y2) / den, 0.0)
        return s[kk] + np.clip(delta, -1, 1) * opt.step_px, y1

    s_in, peak_in = refine(d, k_in)
    s_out, peak_out = refine(-d, k_out)
    r = np.arange(len(mid))
    # deck beside each edge (beyond 3 smoothing sigmas), paint between them: smoothed levels
    margin = 3.0 * opt.smooth_px + 1.0
    k_dl = np.clip(np.searchsorted(s, s_in - margin), 0, n - 1)
    k_dr = np.clip(np.searchsorted(s, s_out + margin), 0, n - 1)
    k_mid = np.clip(np.searchsorted(s, 0.5 * (s_in + s_out)), 0, n - 1)
    deck = 0.5 * (prof[r, k_dl] + prof[r, k_dr])
    step = prof[r, k_mid] - deck
    ok &= (step > 0) & (peak_in > 0) & (peak_out > 0)
    if np.any(ok):
        ok &= step >= opt.min_contrast_fraction * float(np.median(step[ok]))
    inner = mid + s_in[:, None] * normals
    outer = mid + s_out[:, None] * normals
    mid_dn = raw_f[r, k_mid]
    return _Profiles(inner, outer, ok, step, 0.5 * (peak_in + peak_out), mid_dn)


def _bow_ends(grey: NDArray[np.float32], mid: FloatArray, normals: FloatArray, half_px: FloatArray,
              ring: PaintedRing, deck_dn: float, paint_dn: float, noise_dn: float
              ) -> tuple[FloatArray, float] | None:
    """The bow mark's two ends along the ring (distorted pixels) and their sigma, or None."""
    n = len(mid)
    if ring.bow_mark is BowMark.GAP:
        offsets = np.linspace(-0.5, 0.5, 5)[None, :] * half_px[:, None]
        along = mid
    else:
        bar_px = half_px * 2 * ring.bar_length_m / ring.line_width_m
        along = mid + (half_px + 0.5 * bar_px)[:, None] * normals
        offsets = np.linspace(-0.3, 0.3, 5)[None, :] * bar_px[:, None]
    pts = along[:, None, :] + offsets[..., None] * normals[:, None, :]
    sig = np.nanmean(_sample(grey, pts), axis=1)
    q = (sig - deck_dn) / (paint_dn - deck_dn)
    on = (q < 0.5) if ring.bow_mark is BowMark.GAP else (q > 0.5)
    on &= np.isfinite(q)
    if not on.any() or on.all():
        return None
    # close short interruptions (a deck line crossing the gap, a noisy sample): a quarter of the mark
    mark = ring.gap_deg / 360.0 if ring.bow_mark is BowMark.GAP else ring.line_width_m / (2 * math.pi * ring.radius_m)
    close = max(1, round(0.25 * mark * n))
    kernel = np.ones(2 * close + 1, np.uint8)
    wrapped = np.concatenate([on[-close:], on, on[:close]]).astype(np.uint8)[None, :]
    closed = cv2.erode(cv2.dilate(wrapped, kernel[None, :]), kernel[None, :])[0, close:close + n].astype(bool)
    on = closed & np.isfinite(q) if not closed.all() else on
    # the longest circular run of `on`
    start = int(np.argmin(on))  # an index that is off: runs do not wrap past it
    order = (np.arange(n) + start) % n
    best_len, best = 0, (0, 0)
    run = 0
    for i, k in enumerate(order):
        run = run + 1 if on[k] else 0
        if run > best_len:
            best_len, best = run, (i - run + 1, i)
    if best_len < 2:
        return None
    i0, i1 = order[best[0]], order[best[1]]
    ends = []
    slopes = []
    for k_on, k_off in ((i0, (i0 - 1) % n), (i1, (i1 + 1) % n)):
        qa, qb = q[k_off], q[k_on]
        if not (np.isfinite(qa) and np.isfinite(qb)) or qa == qb:
            return None
        f = float(np.clip((0.5 - qa) / (qb - qa), 0, 1))
        ends.append(along[k_off] + f * (along[k_on] - along[k_off]))
        slopes.append(abs(qb - qa) / max(float(np.linalg.norm(along[k_on] - along[k_off])), 1e-9))
    # each signature value averages ~ the line width in pixels; its noise over the slope
    averaged = max(1.0, float(np.median(2 * half_px)))
    sigma = noise_dn / math.sqrt(averaged) / (abs(paint_dn - deck_dn) * max(min(slopes), 1e-9))
    return np.array(ends), math.hypot(sigma, BOW_INTERPOLATION_PX)


def _refine_ring(grey: NDArray[np.float32], camera: CameraModel, ring: PaintedRing, opt: RingEdgeOptions,
                 coarse: tuple[float, float, float, float, float]) -> tuple[Any, ...] | str:
    """Two passes of edge profiles and conic fits from a coarse mid line, or why it is not the ring.

    Returns ``(fits, profiles, mid, centre, n, perimeter)``. Besides coverage and the fits, the two
    edges' size ratio must be the ring's (inner over outer radius, within :data:`RATIO_TOLERANCE`):
    another circle on the deck (the helipad's) has another.
    """
    cu, cv, a, b, th = coarse
    ratio = 0.5 * ring.line_width_m / ring.radius_m
    centre = np.array([cu, cv])
    perimeter = math.pi * (3 * (a + b) - math.sqrt((3 * a + b) * (a + 3 * b)))  # Ramanujan
    n = int(np.clip(round(perimeter), 64, MAX_PROFILES))
    mid = _ellipse_points(cu, cv, a, b, th, n)
    fits: list[tuple[FloatArray, NDArray[np.bool_]]] = []
    prof: _Profiles | None = None
    for _ in range(2):  # coarse mid line, then the mid line of the fitted edges
        normals = _outward_normals(mid, centre)
        half_px = ratio * np.linalg.norm(mid - centre, axis=1)
        prof = _profiles(grey, mid, normals, half_px, opt)
        if prof.valid.mean() < opt.min_coverage:
            return (f"only {prof.valid.mean():.0%} of the ring gives both edges (needs "
                    f"{opt.min_coverage:.0%}): cut by the frame edge, hidden or too faint")
        fits = []
        for pts in (prof.inner_px, prof.outer_px):
            got = fit_edge_conic(camera.undistort(pts[prof.valid]))
            if got is None:
                return "an edge's points admit no ellipse"
            fits.append(got)
        ei, eo = ellipse_params(fits[0][0]), ellipse_params(fits[1][0])
        if ei is None or eo is None:
            return "an edge's fitted conic is not an ellipse"
        centre_und = np.array([0.5 * (ei.centre_u_px + eo.centre_u_px), 0.5 * (ei.centre_v_px + eo.centre_v_px)])
        und_mid = _ellipse_points(float(centre_und[0]), float(centre_und[1]),
                                  0.5 * (ei.semi_major_px + eo.semi_major_px),
                                  0.5 * (ei.semi_minor_px + eo.semi_minor_px), eo.angle_rad, n)
        mid = _distort(camera, und_mid)
        centre = _distort(camera, centre_und[None])[0]
        if not np.all(np.isfinite(mid)):
            return "the ring's mid line leaves the camera's field"
        size_ratio = math.sqrt(ei.semi_major_px * ei.semi_minor_px / (eo.semi_major_px * eo.semi_minor_px))
        want = ring.inner_radius_m / ring.outer_radius_m
        if abs(size_ratio / want - 1) > RATIO_TOLERANCE:
            return (f"the edges' size ratio {size_ratio:.4f} is not the ring's {want:.4f}: another circle "
                    "(the helipad's, the deck's edge?)")
    if prof is None:  # (the loop always runs)
        return "no edge profiles"
    return fits, prof, mid, centre, n, perimeter


def detect_ring_edges(image: NDArray[Any], camera: CameraModel, ring: PaintedRing,
                      options: RingEdgeOptions | None = None, *, frame_id: int = 0) -> RingDetection:
    """Find the painted ring's inner and outer edges to sub-pixel accuracy (module docstring).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        The frame (any integer or float type; channels are summed).
    camera : CameraModel
    ring : PaintedRing
        The ring's geometry (its width-to-radius ratio and bow mark).
    options : RingEdgeOptions, optional
    frame_id : int, keyword-only

    Returns
    -------
    RingDetection
        Falsy, with a reason, when no ring is found, too little of it gives edges, or the
        bow mark is not found. Never raises on a bad image.
    """
    opt = options or RingEdgeOptions()
    grey = _grey(image)

    def failed(reason: str) -> RingDetection:
        return RingDetection(False, reason, frame_id=frame_id)

    # the coarse ring on an image of at most COARSE_SIDE_PX a side (area-averaged), scaled back
    shrink = max(1, math.ceil(max(grey.shape) / COARSE_SIDE_PX))
    small = grey if shrink == 1 else np.asarray(cv2.resize(grey, (grey.shape[1] // shrink, grey.shape[0] // shrink),
                                                           interpolation=cv2.INTER_AREA), np.float32)
    candidates = ring_candidates(small, ring)
    if not candidates:
        return failed("no ring-shaped bright component in the image")
    reason = ""
    for cu, cv, a, b, th in candidates[:MAX_CANDIDATES]:  # the largest first: the deck's edge or helipad may pass too
        got_ring = _refine_ring(grey, camera, ring, opt, ((cu + 0.5) * shrink - 0.5, (cv + 0.5) * shrink - 0.5,
                                                           a * shrink, b * shrink, th))
        if isinstance(got_ring, str):
            reason = reason or got_ring
            continue
        break
    else:
        return failed(reason)
    fits, prof, mid, centre, n, perimeter = got_ring
    ratio = 0.5 * ring.line_width_m / ring.radius_m
    valid = prof.valid
    half_px = ratio * np.linalg.norm(mid - centre, axis=1)
    # the model fit of each edge's pixels, from the gradient maxima's points and conics
    anchors = [prof.inner_px[valid], prof.outer_px[valid]]
    paint_px = [ratio * np.linalg.norm(a - centre, axis=1) for a in anchors]
    blur = float(np.mean([blur_of_edges(conic_edge_profiles(
        grey, a, camera.undistort(a), fits[k][0], paint_outside=k == 0, deck_px=BLUR_DECK_PX, paint_px=paint_px[k]))
        for k, a in enumerate(anchors)]))
    edges: list[ModelEdge] = []
    for k, a in enumerate(anchors):
        got_edge = model_edge(grey, camera, a, fits[k][0], blur, paint_px[k], paint_outside=k == 0,
                              min_contrast_fraction=opt.min_contrast_fraction)
        if isinstance(got_edge, str):
            return failed(f"{('inner', 'outer')[k]} edge: {got_edge}")
        edges.append(got_edge)
    spacing = perimeter / n * np.array([1 - ratio, 1 + ratio])
    step = float(np.median(np.concatenate([e.step_dn for e in edges])))
    noise = float(edges[0].noise_deck_dn)
    crb = float(np.median(np.concatenate([e.crb_px for e in edges])))
    deck_dn = float(np.median(prof.mid_dn[valid] - prof.step_dn[valid]))
    paint_dn = float(np.median(prof.mid_dn[valid]))
    normals = _outward_normals(mid, centre)
    bow = _bow_ends(grey, mid, normals, half_px, ring, deck_dn, paint_dn, noise)
    disc = None
    if opt.centre_disc and ring.centre_mark is CentreMark.DISC:
        disc = find_centre_disc(grey, camera, ring, fits[0][0], fits[1][0], blur)
    common: dict[str, Any] = {
        "inner_px": edges[0].points_px, "outer_px": edges[1].points_px,
        "inner_crb_px": edges[0].crb_px, "outer_crb_px": edges[1].crb_px,
        "conics_px": np.stack([edges[0].conic_px, edges[1].conic_px]),
        "rms_px": np.array([e.rms_px for e in edges]), "spacing_px": spacing,
        "contrast_dn": step, "noise_dn": noise, "blur_px": blur, "edge_crb_px": crb,
        "residual_scale": np.array([e.correlation for e in edges]),
        "crb_ratio": np.array([e.rms_over_crb for e in edges]),
        "known_levels_ratio": float(np.mean([e.known_levels_ratio for e in edges])), "frame_id": frame_id,
    }
    if disc is not None:
        common.update({"disc_px": disc.points_px, "disc_crb_px": disc.crb_px, "disc_conic_px": disc.conic_px,
                       "disc_sigma_scale": disc.sigma_scale})
    if bow is None:
        return RingDetection(False, f"bow mark ({ring.bow_mark.value}) not found", **common)
    return RingDetection(True, "", bow_ends_px=bow[0], bow_sigma_px=bow[1], **common)


def _distort(camera: CameraModel, und_px: FloatArray) -> FloatArray:
    """Undistorted pixels back to the camera's (distorted) image."""
    if not camera.has_distortion:
        return und_px
    y = (und_px[:, 1] - camera.cy) / camera.fy
    x = (und_px[:, 0] - camera.cx - camera.K[0, 1] * y) / camera.fx
    return camera.project(np.column_stack([x, y, np.ones_like(x)]))


def ring_detection_row(det: RingDetection, seconds: float = math.nan) -> dict[str, Any]:
    """The ``detections/ring-edges.parquet`` row of a detection (schema: ``RING_DETECTION_COLUMNS``)."""
    row: dict[str, Any] = {"frame_id": det.frame_id, "ok": det.ok, "reason": det.reason}
    for k, edge in enumerate(("inner", "outer")):
        e = ellipse_params(det.conics_px[k]) if np.all(np.isfinite(det.conics_px[k])) else None
        row[f"{edge}_u_px"] = e.centre_u_px if e else math.nan
        row[f"{edge}_v_px"] = e.centre_v_px if e else math.nan
        row[f"{edge}_semi_major_px"] = e.semi_major_px if e else math.nan
        row[f"{edge}_semi_minor_px"] = e.semi_minor_px if e else math.nan
        row[f"{edge}_angle_deg"] = math.degrees(e.angle_rad) if e else math.nan
        row[f"{edge}_n_points"] = len(det.edges_px[k])
        row[f"{edge}_rms_px"] = float(det.rms_px[k])
    bow = det.bow_ends_px.mean(axis=0)
    row.update({"bow_u_px": float(bow[0]), "bow_v_px": float(bow[1]), "bow_sigma_px": det.bow_sigma_px,
                "edge_contrast_dn": det.contrast_dn, "noise_dn": det.noise_dn, "blur_px": det.blur_px,
                "edge_crb_px": det.edge_crb_px, "seconds": seconds})
    return row
