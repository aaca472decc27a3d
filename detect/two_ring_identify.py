"""Identification of a two-ring layout (outer ring, centre, inner ring) in a frame alone.

The outer ring is identified first (:func:`~deckpose.detect.one_ring_identify.identify_one_ring`:
its ellipse, its spacing, its red bow); where it is not (its bow or too much of it out of
view), the inner ring by the same steps. The identified ring's deck-plane homography then
predicts the other ring's visible beacons.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from deckpose.detect.identification import Identification, IdentifyOptions, failed_identification
from deckpose.detect.one_ring_identify import identify_one_ring
from deckpose.detect.ring_ellipse import ransac_ellipse
from deckpose.detect.ring_homography import apply_homography, ring_homography
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError, check_shape
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED

__all__ = ["ALIAS_MIN_BLOBS", "COMPACT_TRIES", "TWO_RING_MAX_AXIS_RATIO", "identify_two_rings"]

FloatArray = NDArray[np.float64]


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
        pred = apply_homography(H, plane)
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

    :func:`~deckpose.detect.one_ring_identify.identify_one_ring` on all blobs first. A partial outer arc can win its RANSAC, or
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
        sub = identify_one_ring(pts_d[keep], layout, camera, rgb_flux=None if rgb is None else rgb[keep],
                             options=options)
        if sub.ok:
            ids = np.full(N, UNASSIGNED, np.int64)
            ids[keep] = sub.beacon_ids
            return Identification(ids, True, "")
        if first is None:
            first = sub
    return failed_identification(N, first.reason if first is not None else "no ring found")


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

    Each ring is identified alone by :func:`~deckpose.detect.one_ring_identify.identify_one_ring`'s steps (its ellipse,
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
    outer_try = identify_one_ring(pts_d, _one_ring(layout, False), camera, rgb_flux=rgb_flux, options=options)
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
            return failed_identification(N, f"outer ring: {outer_try.reason}; inner ring: {inner_try.reason}")
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
        return failed_identification(N, "degenerate ring geometry: no homography from the identified ring", ids)
    if not outer_try.ok:
        n_alias = _alias_blobs(H, pts, ids, n_this, options.assign_tol_frac)
        if n_alias >= ALIAS_MIN_BLOBS:
            return failed_identification(N, (
                f"outer ring: {outer_try.reason}; the ring taken for the inner ring has {n_alias} blobs "
                "between its beacons or inside it: it may be every other beacon of the outer ring"))
    ang = 2 * np.pi * np.arange(n_other) / n_other
    plane = (r_other / r_this) * np.column_stack([np.cos(ang), np.sin(ang)])
    ids = _assign_more(H, plane, pts, ids, np.asarray(other_ids, np.int64), options.assign_tol_frac)
    return Identification(ids, True, "")
