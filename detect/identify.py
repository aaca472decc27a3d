"""Beacon identification: which detection is which beacon of the layout.

1. Undistort the detections; RANSAC over 5-point conics finds the largest set
   lying on one ellipse: the ring. Blobs off it (glints, reflections, the
   centre beacon) are set aside.
2. Order the ring blobs by angle in the ellipse's normalised frame; the angular
   gaps (in units of ``2 pi / n``) give relative ring positions, leaving room
   for missing beacons.
3. A homography from the deck plane (unit circle) to the image, fitted to the
   relative positions, predicts every ring beacon and the centre (exact under
   perspective). Blobs are re-assigned to the nearest prediction; blobs far from
   every prediction are spurious and stay unassigned.
4. The bow beacon is the ring blob that is distinctly red; it fixes the ids.
   Mono frames cannot show colour: ring ids are then left unassigned, with a
   reason, and only the centre beacon is identified.

Ring ids increase counter-clockwise seen from above; a camera looking down at
the deck sees the same sense counter-clockwise in the image as displayed
(u right, v down), i.e. with increasing ``atan2(-(v - vc), u - uc)``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from deckpose.detect import conic as cn
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError, check_shape
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class IdentifyOptions:
    """Options of :func:`identify_beacons`.

    Attributes
    ----------
    inlier_tol_px : float
        Floor of the ring-ellipse inlier distance, pixels.
    inlier_tol_frac : float
        Inlier distance as a fraction of the ellipse's mean semi-axis (the larger wins).
    assign_tol_frac : float
        A blob takes a predicted beacon position when closer than this fraction
        of the predicted spacing between neighbouring ring beacons.
    min_ring : int or None
        Fewest ring beacons to accept (None: ``max(5, n_ring - n_ring // 3)``).
    min_red_margin : float
        The bow's red share must exceed the median of the other ring blobs by this.
    max_ransac : int
        Most RANSAC samples (adaptive stopping usually needs far fewer; up to 100
        5-subsets are tried exhaustively).
    seed : int
        Seed of the RANSAC sampler (identification is deterministic per frame).
    max_axis_ratio : float or None
        RANSAC rejects ring ellipses more elongated than this (major over minor
        semi-axis); None: no limit. :func:`identify_two_rings` sets it (see
        :data:`TWO_RING_MAX_AXIS_RATIO`), where a thin ellipse through half of the
        outer ring, the inner ring and the centre can outnumber the outer ring.
    """

    inlier_tol_px: float = 2.0
    inlier_tol_frac: float = 0.005
    assign_tol_frac: float = 0.15
    min_ring: int | None = None
    min_red_margin: float = 0.15
    max_ransac: int = 1000
    seed: int = 0
    max_axis_ratio: float | None = None

    def __post_init__(self) -> None:
        if not (
            self.inlier_tol_px > 0 and self.inlier_tol_frac >= 0 and 0 < self.assign_tol_frac < 0.5
        ):
            raise ConfigError(
                "inlier_tol_px > 0, inlier_tol_frac >= 0 and 0 < assign_tol_frac < 0.5"
            )
        if self.max_axis_ratio is not None and not self.max_axis_ratio > 1:
            raise ConfigError(f"max_axis_ratio must be > 1 (or None: no limit), got {self.max_axis_ratio}")
        if self.min_ring is not None and self.min_ring < 5:
            raise ConfigError(
                f"min_ring must be >= 5 (a conic needs 5 points), got {self.min_ring}"
            )


@dataclass(frozen=True)
class Identification:
    """Beacon ids of a frame's detections; falsy with a ``reason`` if incomplete.

    Attributes
    ----------
    beacon_ids : (N,) array of int64
        Layout id per detection, ``UNASSIGNED`` (-1) for spurious or unidentified blobs.
    ok : bool
    reason : str
    """

    beacon_ids: NDArray[np.int64]
    ok: bool
    reason: str = ""

    def __post_init__(self) -> None:
        ids = np.array(self.beacon_ids, dtype=np.int64).reshape(-1)
        ids.setflags(write=False)
        object.__setattr__(self, "beacon_ids", ids)

    def __bool__(self) -> bool:
        return self.ok


def _fail(n: int, reason: str, ids: np.ndarray | None = None) -> Identification:
    return Identification(np.full(n, UNASSIGNED) if ids is None else ids, False, reason)


def _ellipse_inliers(
    c: FloatArray, points: FloatArray, opts: IdentifyOptions
) -> tuple[NDArray[np.bool_] | None, FloatArray, float]:
    axes = cn.ellipse_semi_axes(c) if c[1] ** 2 - 4 * c[0] * c[2] < 0 else None
    if axes is None:
        return None, np.zeros(0), 0.0
    if opts.max_axis_ratio is not None and not max(axes) <= opts.max_axis_ratio * min(axes):
        return None, np.zeros(0), 0.0
    tol = max(opts.inlier_tol_px, opts.inlier_tol_frac * 0.5 * sum(axes))
    d = cn.sampson_distance(c, points)
    return d < tol, d, tol


#: Fewest RANSAC samples before the adaptive stop (which needs a 99.9 % chance of one
#: all-inlier sample given the best inlier ratio so far).
MIN_RANSAC_SAMPLES = 8


def ransac_ellipse(
    points: FloatArray, opts: IdentifyOptions, max_inliers: int
) -> NDArray[np.bool_]:
    """Largest set of points (at most ``max_inliers``) on one ellipse (boolean mask)."""
    n = points.shape[0]
    best = np.zeros(n, bool)
    best_cost = math.inf
    exhaustive = math.comb(n, 5) <= 100
    if exhaustive:
        samples: object = itertools.combinations(range(n), 5)
    else:
        rng = np.random.default_rng(opts.seed)
        samples = (rng.choice(n, 5, replace=False) for _ in range(opts.max_ransac))
    needed = opts.max_ransac
    tried = 0
    for s in samples:  # type: ignore[attr-defined]
        c = cn.fit_conic(points[list(s)])
        inl, d, tol = _ellipse_inliers(c, points, opts)
        if inl is None or inl.sum() <= 5:
            continue
        # Local optimisation: refit on the inliers and count again, so a conic that
        # only passes near points by the first-order distance does not win.
        c = cn.fit_conic(points[inl])
        inl, d, tol = _ellipse_inliers(c, points, opts)
        if inl is None:
            continue
        k = int(inl.sum())
        if k < 5 or k > max_inliers:
            continue
        cost = -k + float(np.sum(np.minimum(d, tol))) / (tol * (n + 1))
        if cost < best_cost:
            best, best_cost = inl, cost
            # Adaptive stopping: samples needed to draw one all-inlier 5-set with 99.9 %.
            w5 = (k / n) ** 5
            needed = math.ceil(math.log(1e-3) / math.log1p(-w5)) if w5 < 1 else 1
        tried += 1
        if not exhaustive and tried >= max(needed, MIN_RANSAC_SAMPLES):
            break
    return best


def _ring_angles(pts: FloatArray, conic: FloatArray) -> FloatArray | None:
    """Angle of each point in the ellipse's normalised (circular) frame, ccw as displayed."""
    M = cn.ellipse_shape(conic)
    if M is None:
        return None
    w, V = np.linalg.eigh(M)
    L = V @ np.diag(np.sqrt(w)) @ V.T
    d = (pts - cn.ellipse_centre(conic)) @ L.T
    return np.arctan2(-d[:, 1], d[:, 0])  # v points down


def _gap_misfit(ang: FloatArray, n: int) -> tuple[float, NDArray[np.int64], NDArray[np.int64]]:
    """Worst non-integer part of the angular gaps (ring steps), the order, the rounded steps."""
    order = np.argsort(ang)
    gaps = np.diff(np.append(ang[order], ang[order[0]] + 2 * np.pi)) / (2 * np.pi / n)
    steps = np.rint(gaps).astype(np.int64)
    misfit = float(np.max(np.abs(gaps - steps)))
    if np.any(steps < 1) or steps.sum() != n:
        misfit = max(misfit, 0.5)
    return misfit, order, steps


def relative_positions(
    ang: FloatArray, n: int, *, max_misfit: float = 0.3, max_drop: int = 3
) -> tuple[NDArray[np.int64], NDArray[np.bool_]] | None:
    """Ring positions (relative to the first kept point) from angles, dropping spurious points.

    Gaps between consecutive angles must be whole ring steps (``2 pi / n``);
    while they are not, the point whose removal fits best is dropped (a glint
    that happens to lie on the ring ellipse), at most ``max_drop`` times.

    Returns ``(rel, keep)``, ``rel`` valid where ``keep``; ``None`` if no fit.
    """
    keep = np.ones(ang.size, bool)
    for _ in range(max_drop + 1):
        idx = np.flatnonzero(keep)
        misfit, order, steps = _gap_misfit(ang[idx], n)
        if misfit <= max_misfit:
            rel = np.full(ang.size, -1, np.int64)
            rel[idx[order]] = np.concatenate([[0], np.cumsum(steps[:-1])])
            return rel, keep
        if idx.size <= 5:
            return None
        trials = [(_gap_misfit(np.delete(ang[idx], j), n)[0], j) for j in range(idx.size)]
        keep[idx[min(trials)[1]]] = False
    return None


def _homography(rel: NDArray[np.int64], pts: FloatArray, n: int) -> FloatArray | None:
    ang = 2 * np.pi * rel / n
    plane = np.column_stack([np.cos(ang), np.sin(ang)])
    H, _ = cv2.findHomography(plane.reshape(-1, 1, 2), pts.reshape(-1, 1, 2), 0)
    return None if H is None else np.asarray(H, float)


def search_homography(
    ring_sorted: FloatArray, pts: FloatArray, n: int, tol_frac: float
) -> FloatArray | None:
    """Ring homography from hypotheses on 4 angle-consecutive ring points.

    For every run of 4 consecutive points (in angle order) and every pattern of
    ring steps between them (all 1, or one gap of 2: a missing beacon), fit the
    homography from the unit circle and keep the one that places the most blobs
    on predicted ring positions (exact under perspective, unlike angle gaps).
    """
    m = ring_sorted.shape[0]
    if m < 4:
        return None
    best, best_key = None, (-1, np.inf)
    for start in range(m):
        quad = ring_sorted[[(start + k) % m for k in range(4)]]
        for steps in ((1, 1, 1), (2, 1, 1), (1, 2, 1), (1, 1, 2)):
            rel = np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)
            H = _homography(rel, quad, n)
            if H is None or not np.all(np.isfinite(H)):
                continue
            ids, pred, _tol = _assign_ring(H, pts, n, tol_frac)
            ok = ids >= 0
            resid = float(np.sum(np.linalg.norm(pts[ok] - pred[ids[ok]], axis=1)))
            key = (int(ok.sum()), -resid)
            if key > (best_key[0], -best_key[1]):
                best, best_key = H, (int(ok.sum()), resid)
    return best


def _apply(H: FloatArray, plane: FloatArray) -> FloatArray:
    p = np.column_stack([plane, np.ones(plane.shape[0])]) @ H.T
    return p[:, :2] / p[:, 2:3]


def _assign_ring(
    H: FloatArray, pts: FloatArray, n: int, tol_frac: float
) -> tuple[NDArray[np.int64], FloatArray, float]:
    """Nearest predicted ring position per blob (-1 if none within tolerance)."""
    ang = 2 * np.pi * np.arange(n) / n
    pred = _apply(H, np.column_stack([np.cos(ang), np.sin(ang)]))
    spacing = float(np.min(np.linalg.norm(pred - np.roll(pred, 1, axis=0), axis=1)))
    tol = tol_frac * spacing
    d = np.linalg.norm(pts[:, None, :] - pred[None], axis=2)
    rel = np.full(pts.shape[0], UNASSIGNED, np.int64)
    for j in np.argsort(d.min(axis=1)):  # closest first; each position taken once
        k = int(np.argmin(d[j]))
        if d[j, k] < tol and k not in rel:
            rel[j] = k
    return rel, pred, tol


def identify_beacons(
    points_px: FloatArray,
    layout: DeckLayout,
    camera: CameraModel,
    *,
    rgb_flux: FloatArray | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> Identification:
    """Assign layout beacon ids to detections.

    A layout with an inner ring (``layout.inner_n_ring > 0``) is identified by
    :func:`identify_two_rings`: the outer ring as below when enough of it, its
    bow included, is in view; else the inner ring by the same steps; the other
    ring's visible beacons then by the identified ring's homography.

    Parameters
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    layout : DeckLayout
    camera : CameraModel
        For undistortion.
    rgb_flux : (N, 3) array of float, optional
        Per-channel flux of each blob (:func:`deckpose.detect.colour.blob_rgb_flux`);
        ``None`` for mono frames.
    options : IdentifyOptions

    Returns
    -------
    Identification
    """
    if layout.inner_n_ring:
        return identify_two_rings(points_px, layout, camera, rgb_flux=rgb_flux, options=options)
    return _identify_ring(points_px, layout, camera, rgb_flux=rgb_flux, options=options)


def _identify_ring(
    points_px: FloatArray,
    layout: DeckLayout,
    camera: CameraModel,
    *,
    rgb_flux: FloatArray | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> Identification:
    """Assign the ids of a one-ring layout (its ring and centre) to detections.

    Parameters
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    layout : DeckLayout
    camera : CameraModel
        For undistortion.
    rgb_flux : (N, 3) array of float, optional
        Per-channel flux of each blob (:func:`deckpose.detect.colour.blob_rgb_flux`);
        ``None`` for mono frames.
    options : IdentifyOptions

    Returns
    -------
    Identification
    """
    from deckpose.detect.colour import redness

    pts_d = np.asarray(points_px, dtype=float)
    check_shape("points_px", pts_d, (None, 2))
    N = pts_d.shape[0]
    n = layout.n_ring
    min_ring = options.min_ring or max(5, n - n // 3)
    if n < 5:
        return _fail(N, f"identification needs a ring of >= 5 beacons (conic test), layout has {n}")
    if N < min_ring:
        return _fail(N, f"only {N} blobs detected; identification needs >= {min_ring} ring beacons")
    pts = camera.undistort(pts_d)
    usable = np.isfinite(pts).all(axis=1)
    if not usable.all():  # no ray in front of the camera (a fisheye past 90 deg): never a beacon
        rgb = None if rgb_flux is None else np.asarray(rgb_flux, dtype=float).reshape(-1, 3)[usable]
        sub = _identify_ring(pts_d[usable], layout, camera, rgb_flux=rgb, options=options)
        ids = np.full(N, UNASSIGNED, np.int64)
        ids[usable] = sub.beacon_ids
        return Identification(ids, sub.ok, sub.reason)
    on_ring = ransac_ellipse(pts, options, max_inliers=n + 2)
    if on_ring.sum() < min_ring:
        return _fail(
            N, f"only {int(on_ring.sum())} blobs lie on a common ellipse; need >= {min_ring}"
        )
    idx = np.flatnonzero(on_ring)
    conic = cn.fit_conic(pts[idx])
    ang = _ring_angles(pts[idx], conic)
    if ang is None:
        return _fail(N, "degenerate ring ellipse")
    found = relative_positions(ang, n)
    H = None
    if found is not None:
        rel0, keep = found
        H = _homography(rel0[keep], pts[idx[keep]], n)
    if H is None:  # strong perspective or spurious blobs: search the ring's homography
        H = search_homography(pts[idx[np.argsort(ang)]], pts, n, options.assign_tol_frac)
    if H is None:
        return _fail(
            N, "ring blobs are not evenly spaced on the ellipse (spurious blobs on the ring?)"
        )
    rel = np.full(N, UNASSIGNED, np.int64)
    tol = 0.0
    for _ in range(2):  # assign all blobs to predictions, refit, assign again
        rel, _pred, tol = _assign_ring(H, pts, n, options.assign_tol_frac)
        good = rel >= 0
        if good.sum() < min_ring:
            return _fail(
                N, f"only {int(good.sum())} blobs match the predicted ring; need >= {min_ring}"
            )
        H2 = _homography(rel[good], pts[good], n)
        if H2 is None:
            return _fail(N, "degenerate ring geometry: no homography from the ring")
        H = H2
    ids = np.full(N, UNASSIGNED, np.int64)
    reasons = []
    if layout.has_centre:
        c_pred = _apply(H, np.zeros((1, 2)))[0]
        free = np.flatnonzero(rel < 0)
        if free.size:
            dc = np.linalg.norm(pts[free] - c_pred, axis=1)
            if dc.min() < tol:
                ids[free[np.argmin(dc)]] = layout.n_ring
    ring = np.flatnonzero(rel >= 0)
    if rgb_flux is None:
        reasons.append(
            "mono frame: the bow beacon is told by its colour, so ring ids stay unassigned"
        )
    else:
        red = redness(np.asarray(rgb_flux, dtype=float).reshape(-1, 3)[ring])
        if ring.size < 2 or np.count_nonzero(np.isfinite(red)) < 2:
            # one blob's colour has nothing to be distinctly red against (its margin over
            # the others' median was NaN, which passed the margin test)
            reasons.append("no colour measured on the ring blobs" if not np.any(np.isfinite(red))
                           else "colour measured on only one ring blob: the bow cannot be told")
        else:
            b = int(np.nanargmax(red))
            others = np.delete(red, b)
            margin = float(red[b] - np.nanmedian(others))
            if margin < options.min_red_margin:
                reasons.append(
                    "bow beacon not found: no ring blob is distinctly red "
                    f"(best margin {margin:.2f} "
                    f"< {options.min_red_margin}); it may be hidden"
                )
            else:
                ids[ring] = (rel[ring] - rel[ring[b]] + layout.bow_id) % n
    if reasons:
        return Identification(ids, False, "; ".join(reasons))
    return Identification(ids, True, "")


#: The most elongated ring ellipse :func:`identify_two_rings` accepts (major / minor semi-axis).
#: A circle's image is elongated by about ``1 / cos(tilt)`` between the deck and the image
#: plane; 3 allows a tilt of 70 deg, far beyond a downward camera over a ship in sea state 9,
#: and rejects the near-parabolas that pass through two opposite arcs of the outer ring and the
#: inner ring between them.
TWO_RING_MAX_AXIS_RATIO = 3.0
#: Free blobs at an inner ring's midpoints or inside half its radius that make it an alias.
ALIAS_MIN_BLOBS = 2


def _one_ring(layout: DeckLayout, inner: bool) -> DeckLayout:
    """The outer (``inner=False``) or the inner ring of a two-ring layout, with its centre, as a one-ring layout."""
    if not inner:
        return dataclasses.replace(layout, inner_n_ring=0)
    return dataclasses.replace(layout, n_ring=layout.inner_n_ring, radius_m=layout.inner_radius_m,
                               inner_n_ring=0)


def ring_homography(ids: NDArray[np.int64], points_px: FloatArray, n: int) -> FloatArray | None:
    """Homography from a ring's deck plane (radius 1, bow on +x) to undistorted pixels.

    Parameters
    ----------
    ids : (K,) array of int
        Ring positions ``0..n-1`` (counter-clockwise from the bow) of ``K >= 4`` blobs.
    points_px : (K, 2) array of float
        Their undistorted pixel positions.
    n : int
        Beacons on the ring.

    Returns
    -------
    (3, 3) array of float or None
        None when the points are degenerate.
    """
    return _homography(np.asarray(ids, np.int64), np.asarray(points_px, float), n)


def _assign_more(
    H: FloatArray, plane: FloatArray, pts: FloatArray, ids: NDArray[np.int64], new_ids: NDArray[np.int64],
    tol_frac: float,
) -> NDArray[np.int64]:
    """Give free blobs (``ids < 0``) the ids ``new_ids`` of deck points ``plane`` predicted through ``H``.

    A blob takes a prediction when nearer than ``tol_frac`` of the smallest spacing
    between the predictions; each prediction is taken once, the closest blob first.
    Blobs without a finite undistorted position stay free.
    """
    with np.errstate(invalid="ignore"):
        pred = _apply(H, plane)
    out = ids.copy()
    if pred.shape[0] < 2:
        return out
    gap = np.linalg.norm(pred[:, None] - pred[None], axis=2)
    spacing = float(np.min(gap[~np.eye(pred.shape[0], dtype=bool)]))
    free = np.flatnonzero((ids < 0) & np.isfinite(pts).all(axis=1))
    if not free.size:
        return out
    d = np.linalg.norm(pts[free][:, None, :] - pred[None], axis=2)
    taken: set[int] = set()
    for j in np.argsort(d.min(axis=1)):
        k = int(np.argmin(d[j]))
        if d[j, k] < tol_frac * spacing and k not in taken:
            out[free[j]] = int(new_ids[k])
            taken.add(k)
    return out


#: Compact blob groups tried as the inner ring (its centre and nearest neighbours), most compact first.
COMPACT_TRIES = 3


def _identify_inner(
    pts_d: FloatArray, layout: DeckLayout, camera: CameraModel, rgb_flux: FloatArray | None,
    options: IdentifyOptions, outer_max_inliers: int,
) -> Identification:
    """The inner ring (``layout``: the inner ring as a one-ring layout) among all of a frame's blobs.

    :func:`_identify_ring` on all blobs first. A partial outer arc can win its RANSAC, or
    lend blobs to a chance ellipse through inner beacons (any 5 points fit a conic), so
    where that fails: again without the largest ellipse of at most ``outer_max_inliers``
    blobs (an outer arc); then on compact groups, each a blob and its ``n + 1`` nearest
    neighbours (the centre beacon and the inner ring, one spare), the
    :data:`COMPACT_TRIES` most compact first. The first failure's reason is kept when
    every try fails.
    """
    N = pts_d.shape[0]
    rgb = None if rgb_flux is None else np.asarray(rgb_flux, dtype=float).reshape(-1, 3)
    pts = camera.undistort(pts_d)
    usable = np.flatnonzero(np.isfinite(pts).all(axis=1))
    tries: list[NDArray[np.int64]] = [np.arange(N)]
    if usable.size >= 10:  # an arc to set aside and a ring after it: 5 blobs each
        on = ransac_ellipse(pts[usable], options, max_inliers=outer_max_inliers)
        tries.append(np.setdiff1d(np.arange(N), usable[on]))
    k = layout.n_ring + 2
    if usable.size > k:
        d = np.linalg.norm(pts[usable][:, None] - pts[usable][None], axis=2)
        near = np.argsort(d, axis=1)[:, :k]  # each blob first (distance 0), then its neighbours
        spread = np.take_along_axis(d, near, axis=1).sum(axis=1)
        tries += [np.sort(usable[near[j]]) for j in np.argsort(spread, kind="stable")[:COMPACT_TRIES]]
    first: Identification | None = None
    for keep in tries:
        sub = _identify_ring(pts_d[keep], layout, camera, rgb_flux=None if rgb is None else rgb[keep],
                             options=options)
        if sub.ok:
            ids = np.full(N, UNASSIGNED, np.int64)
            ids[keep] = sub.beacon_ids
            return Identification(ids, True, "")
        if first is None:
            first = sub
    return _fail(N, first.reason if first is not None else "no ring found")


def _alias_blobs(
    H: FloatArray, pts: FloatArray, ids: NDArray[np.int64], n: int, tol_frac: float
) -> int:
    """Free blobs that say a ring identified as the inner ring is every other outer beacon.

    Under that alias the outer ring's other beacons sit midway between the "inner"
    beacons, on the same ellipse, and the true inner ring lies well inside it: count
    free blobs near a midpoint (within ``tol_frac`` of the ring's spacing) or inside
    half the ring's radius (deck plane through ``H``).
    """
    free = np.flatnonzero((ids < 0) & np.isfinite(pts).all(axis=1))
    if not free.size:
        return 0
    ang = 2 * np.pi * (np.arange(n) + 0.5) / n
    mid = np.column_stack([np.cos(ang), np.sin(ang)])
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.column_stack([pts[free], np.ones(free.size)]) @ np.linalg.inv(H).T
        plane = q[:, :2] / q[:, 2:3]
    step = 2 * np.sin(np.pi / n)  # chord between neighbours, ring radii
    near_mid = np.min(np.linalg.norm(plane[:, None] - mid[None], axis=2), axis=1) < tol_frac * step
    inside = np.linalg.norm(plane, axis=1) < 0.5
    return int(np.count_nonzero(near_mid | inside))


def identify_two_rings(
    points_px: FloatArray,
    layout: DeckLayout,
    camera: CameraModel,
    *,
    rgb_flux: FloatArray | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> Identification:
    """Assign the ids of a two-ring layout: by the outer ring where it is identified, else by the inner.

    Each ring is identified alone by :func:`identify_beacons`'s steps (its ellipse,
    its even spacing, its own red bow beacon); the outer ring is tried first. The
    deck-plane homography of the identified ring then predicts the other ring's
    beacons (exact under perspective: both lie on the deck plane), and free blobs
    near a prediction take its id. Fails with both rings' reasons when neither is
    identified (then :func:`deckpose.detect.prior_identify.identify_with_prior`
    can use the previous frame's pose).

    Parameters
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    layout : DeckLayout
        With ``inner_n_ring > 0``.
    camera : CameraModel
    rgb_flux : (N, 3) array of float, optional
    options : IdentifyOptions

    Returns
    -------
    Identification
    """
    pts_d = np.asarray(points_px, dtype=float)
    check_shape("points_px", pts_d, (None, 2))
    if not layout.inner_n_ring:
        raise ConfigError("identify_two_rings needs a layout with an inner ring (inner_n_ring > 0)")
    N = pts_d.shape[0]
    first = layout.n_ring + int(layout.has_centre)  # the inner ring's bow id
    if options.max_axis_ratio is None:
        options = dataclasses.replace(options, max_axis_ratio=TWO_RING_MAX_AXIS_RATIO)
    outer_try = _identify_ring(pts_d, _one_ring(layout, False), camera, rgb_flux=rgb_flux, options=options)
    if outer_try.ok:
        ids = outer_try.beacon_ids.copy()
        n_this, r_this = layout.n_ring, layout.radius_m
        this_ring = (ids >= 0) & (ids < layout.n_ring)
        this_pos = ids[this_ring]
        n_other, r_other = layout.inner_n_ring, layout.inner_radius_m
        other_ids = layout.inner_ring_ids()
    else:
        inner_try = _identify_inner(pts_d, _one_ring(layout, True), camera, rgb_flux, options,
                                    layout.n_ring + 2)
        if not inner_try.ok:
            return _fail(N, f"outer ring: {outer_try.reason}; inner ring: {inner_try.reason}")
        sub = inner_try.beacon_ids
        m = layout.inner_n_ring
        ids = np.where(sub < 0, UNASSIGNED, np.where(sub == m, layout.n_ring, first + sub)).astype(np.int64)
        n_this, r_this = m, layout.inner_radius_m
        this_ring = (sub >= 0) & (sub < m)
        this_pos = sub[this_ring]
        n_other, r_other = layout.n_ring, layout.radius_m
        other_ids = layout.ring_ids()
    pts = camera.undistort(pts_d)
    H = ring_homography(this_pos, pts[this_ring], n_this)
    if H is None or not np.all(np.isfinite(H)):
        return _fail(N, "degenerate ring geometry: no homography from the identified ring", ids)
    if not outer_try.ok:
        n_alias = _alias_blobs(H, pts, ids, n_this, options.assign_tol_frac)
        if n_alias >= ALIAS_MIN_BLOBS:
            return _fail(N, (
                f"outer ring: {outer_try.reason}; the ring taken for the inner ring has {n_alias} blobs "
                "between its beacons or inside it: it may be every other beacon of the outer ring"))
    ang = 2 * np.pi * np.arange(n_other) / n_other
    plane = (r_other / r_this) * np.column_stack([np.cos(ang), np.sin(ang)])
    ids = _assign_more(H, plane, pts, ids, np.asarray(other_ids, np.int64), options.assign_tol_frac)
    return Identification(ids, True, "")
