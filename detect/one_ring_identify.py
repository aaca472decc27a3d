"""Identification of a one-ring layout (its ring and centre) in a frame alone.

1. Undistort the detections; RANSAC over 5-point conics finds the largest set
   lying on one ellipse: the ring (:mod:`~deckpose.detect.ring_ellipse`). Blobs off
   it (glints, reflections, the centre beacon) are set aside.
2. Order the ring blobs by angle in the ellipse's normalised frame; the angular
   gaps (in units of ``2 pi / n``) give relative ring positions, leaving room
   for missing beacons.
3. A homography from the deck plane (unit circle) to the image, fitted to the
   relative positions (:mod:`~deckpose.detect.ring_homography`), predicts every ring
   beacon and the centre (exact under perspective). Blobs are re-assigned to the
   nearest prediction; blobs far from every prediction are spurious and stay
   unassigned.
4. The bow beacon is the ring blob that is distinctly red; it fixes the ids.
   Mono frames cannot show colour: ring ids are then left unassigned, with a
   reason, and only the centre beacon is identified.

Ring ids increase counter-clockwise seen from above; a camera looking down at
the deck sees the same sense counter-clockwise in the image as displayed
(u right, v down), i.e. with increasing ``atan2(-(v - vc), u - uc)``.
"""

from __future__ import annotations

import numpy as np
from deckpose.detect import conic as cn
from deckpose.detect.identification import Identification, IdentifyOptions, failed_identification
from deckpose.detect.ring_ellipse import (
    flux_groups,
    ransac_ellipse,
    relative_positions,
    ring_angles,
)
from deckpose.detect.ring_homography import (
    apply_homography,
    assign_ring_positions,
    ring_homography,
    search_homography,
)
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import check_shape
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED

__all__ = ["identify_one_ring"]

FloatArray = NDArray[np.float64]


def identify_one_ring(
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
        return failed_identification(N, f"identification needs a ring of >= 5 beacons (conic test), layout has {n}")
    if N < min_ring:
        return failed_identification(N, f"only {N} blobs detected; identification needs >= {min_ring} ring beacons")
    pts = camera.undistort(pts_d)
    usable = np.isfinite(pts).all(axis=1)
    if not usable.all():  # no ray in front of the camera (a fisheye past 90 deg): never a beacon
        rgb = None if rgb_flux is None else np.asarray(rgb_flux, dtype=float).reshape(-1, 3)[usable]
        sub = identify_one_ring(pts_d[usable], layout, camera, rgb_flux=rgb, options=options)
        ids = np.full(N, UNASSIGNED, np.int64)
        ids[usable] = sub.beacon_ids
        return Identification(ids, sub.ok, sub.reason)
    # blobs of like brightness together (every other RANSAC sample): in clutter the ring's are
    # among n + 2 consecutive blobs by flux more often than among all
    prefer = None if rgb_flux is None else flux_groups(np.asarray(rgb_flux, float).reshape(-1, 3).sum(axis=1), n + 2)
    on_ring = ransac_ellipse(pts, options, max_inliers=n + 2, ring_size=n, min_support=min_ring, prefer=prefer)
    if on_ring.sum() < min_ring:
        return failed_identification(
            N, f"only {int(on_ring.sum())} blobs lie on a common ellipse; need >= {min_ring}"
        )
    idx = np.flatnonzero(on_ring)
    conic = cn.fit_conic(pts[idx])
    ang = ring_angles(pts[idx], conic)
    if ang is None:
        return failed_identification(N, "degenerate ring ellipse")
    found = relative_positions(ang, n)
    H = None
    if found is not None:
        rel0, keep = found
        H = ring_homography(rel0[keep], pts[idx[keep]], n)
    if H is None:  # strong perspective or spurious blobs: search the ring's homography
        H = search_homography(pts[idx[np.argsort(ang)]], pts, n, options.assign_tol_frac)
    if H is None:
        return failed_identification(
            N, "ring blobs are not evenly spaced on the ellipse (spurious blobs on the ring?)"
        )
    rel = np.full(N, UNASSIGNED, np.int64)
    tol = 0.0
    for _ in range(2):  # assign all blobs to predictions, refit, assign again
        rel, _pred, tol = assign_ring_positions(H, pts, n, options.assign_tol_frac)
        good = rel >= 0
        if good.sum() < min_ring:
            return failed_identification(
                N, f"only {int(good.sum())} blobs match the predicted ring; need >= {min_ring}"
            )
        H2 = ring_homography(rel[good], pts[good], n)
        if H2 is None:
            return failed_identification(N, "degenerate ring geometry: no homography from the ring")
        H = H2
    ids = np.full(N, UNASSIGNED, np.int64)
    reasons = []
    if layout.has_centre:
        c_pred = apply_homography(H, np.zeros((1, 2)))[0]
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
        ring_rgb = np.asarray(rgb_flux, dtype=float).reshape(-1, 3)[ring]
        red = redness(ring_rgb)
        grey = ring.size >= 2 and bool(np.all(ring_rgb == ring_rgb[:, :1]))
        if grey:  # R = G = B on every ring blob: a grey image stored as colour (RGB, or grey + alpha)
            reasons.append(
                "grey image: every ring blob has equal red, green and blue, so the bow beacon, told "
                "by its colour, cannot be found; use the camera's colour image"
            )
        elif ring.size < 2 or np.count_nonzero(np.isfinite(red)) < 2:
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
        return Identification(ids, False, "; ".join(reasons), ring_homography=H, ring_slot=rel)
    return Identification(ids, True, "", ring_homography=H, ring_slot=rel)
