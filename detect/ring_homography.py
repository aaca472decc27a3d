"""The homography from a ring's deck plane (unit circle, bow on +x) to the image.

Fitted to ring positions, it predicts every ring beacon and the centre (exact under
perspective); blobs are assigned to the nearest prediction.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.records import UNASSIGNED

__all__ = ["apply_homography", "assign_ring_positions", "ring_homography", "search_homography"]

FloatArray = NDArray[np.float64]


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
    rel = np.asarray(ids, np.int64)
    pts = np.asarray(points_px, float)
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
            H = ring_homography(rel, quad, n)
            if H is None or not np.all(np.isfinite(H)):
                continue
            ids, pred, _tol = assign_ring_positions(H, pts, n, tol_frac)
            ok = ids >= 0
            resid = float(np.sum(np.linalg.norm(pts[ok] - pred[ids[ok]], axis=1)))
            key = (int(ok.sum()), -resid)
            if key > (best_key[0], -best_key[1]):
                best, best_key = H, (int(ok.sum()), resid)
    return best


def apply_homography(H: FloatArray, plane: FloatArray) -> FloatArray:
    """Map deck-plane points through a homography.

    Parameters
    ----------
    H : (3, 3) array of float
    plane : (K, 2) array of float
        Deck-plane points (ring radii).

    Returns
    -------
    (K, 2) array of float
        Undistorted pixels.
    """
    p = np.column_stack([plane, np.ones(plane.shape[0])]) @ H.T
    return p[:, :2] / p[:, 2:3]


def assign_ring_positions(
    H: FloatArray, pts: FloatArray, n: int, tol_frac: float
) -> tuple[NDArray[np.int64], FloatArray, float]:
    """Nearest predicted ring position per blob (-1 if none within tolerance).

    Parameters
    ----------
    H : (3, 3) array of float
        Ring homography (:func:`ring_homography`).
    pts : (N, 2) array of float
        Undistorted pixels.
    n : int
        Beacons on the ring.
    tol_frac : float
        Tolerance as a fraction of the smallest predicted spacing.

    Returns
    -------
    rel : (N,) array of int64
        Ring position per blob (``UNASSIGNED``: none).
    pred : (n, 2) array of float
        Predicted ring positions, undistorted pixels.
    tol : float
        The tolerance used, pixels.
    """
    ang = 2 * np.pi * np.arange(n) / n
    pred = apply_homography(H, np.column_stack([np.cos(ang), np.sin(ang)]))
    spacing = float(np.min(np.linalg.norm(pred - np.roll(pred, 1, axis=0), axis=1)))
    tol = tol_frac * spacing
    d = np.linalg.norm(pts[:, None, :] - pred[None], axis=2)
    rel = np.full(pts.shape[0], UNASSIGNED, np.int64)
    for j in np.argsort(d.min(axis=1)):  # closest first; each position taken once
        k = int(np.argmin(d[j]))
        if d[j, k] < tol and k not in rel:
            rel[j] = k
    return rel, pred, tol
