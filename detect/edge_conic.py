"""A robust conic through edge points: Sampson distance, iteratively reweighted, outliers dropped."""

from __future__ import annotations

import numpy as np
from deckpose.detect.conic import conic_design, conic_matrix
from numpy.typing import NDArray

__all__ = ["REJECT_SIGMAS", "fit_edge_conic", "sampson_distance"]

FloatArray = NDArray[np.float64]

#: Robust sigmas beyond which an edge point is dropped from its ellipse.
REJECT_SIGMAS = 4.0


def sampson_distance(C: FloatArray, points: FloatArray) -> FloatArray:
    """First-order geometric distance of points (N, 2) from conic ``C``, the points' units (signed)."""
    X = np.column_stack([points, np.ones(len(points))])
    CX = X @ C
    f = np.sum(CX * X, axis=1)
    grad = 2.0 * np.hypot(CX[:, 0], CX[:, 1])
    return f / np.where(grad > 0, grad, np.inf)


def fit_edge_conic(points_px: FloatArray, *, iterations: int = 6) -> tuple[FloatArray, NDArray[np.bool_]] | None:
    """Robust conic of edge points: Sampson distance, iteratively reweighted, outliers dropped.

    Parameters
    ----------
    points_px : (N, 2) array of float, pixels
    iterations : int, keyword-only

    Returns
    -------
    (C, inliers) or None
        ``C`` (3, 3), unit Frobenius norm, negative inside; ``inliers`` (N,) bool. None when
        fewer than 8 points or no ellipse fits.
    """
    p = np.asarray(points_px, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 8:
        return None
    mean = p.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((p - mean) ** 2, axis=1))))
    if not scale > 0:
        return None
    q = (p - mean) / scale
    D = conic_design(q)
    keep = np.ones(len(q), bool)
    w = np.ones(len(q))
    theta = np.zeros(6)
    for _ in range(iterations):
        Dk = D[keep] * np.sqrt(w[keep])[:, None]
        _, _, Vt = np.linalg.svd(Dk, full_matrices=False)
        theta = Vt[-1]
        C = conic_matrix(theta)
        d = sampson_distance(C, q)
        X = np.column_stack([q, np.ones(len(q))]) @ C
        grad2 = 4.0 * (X[:, 0] ** 2 + X[:, 1] ** 2)
        w = 1.0 / np.maximum(grad2, 1e-300)
        sigma = 1.4826 * float(np.median(np.abs(d[keep])))
        keep = np.abs(d) <= max(REJECT_SIGMAS * sigma, 1e-6)
        if keep.sum() < 8:
            return None
    T = np.array([[1 / scale, 0, -mean[0] / scale], [0, 1 / scale, -mean[1] / scale], [0, 0, 1]])
    C = T.T @ conic_matrix(theta) @ T
    C /= np.linalg.norm(C)
    if np.linalg.det(C[:2, :2]) <= 0:
        return None
    centre = -np.linalg.solve(C[:2, :2], C[:2, 2])
    inside = np.array([*centre, 1.0]) @ C @ np.array([*centre, 1.0])
    return (C if inside < 0 else -C), keep
