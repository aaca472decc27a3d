"""Direct least-squares ellipse fit in float64, with Hartley normalisation.

Fitzgibbon, Pilu & Fisher (1999) in the numerically stable form of Halíř &
Flusser (1998): the conic ``a x² + b xy + c y² + d x + e y + f = 0`` minimising
the algebraic distance subject to ``4ac - b² = 1`` (always an ellipse). Points
are first centred and scaled to unit RMS radius, and the conic is mapped back,
so nothing is rounded to float32 (unlike OpenCV's ``fitEllipse*``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Inverse of the ellipse constraint matrix C1 of the Halir-Flusser direct fit (4ac - b^2 = 1).
C1_INV = np.array([[0.0, 0.0, 0.5], [0.0, -1.0, 0.0], [0.5, 0.0, 0.0]])


def fit_ellipse_direct(points: FloatArray) -> FloatArray | None:
    """Fit an ellipse to 2-D points.

    Parameters
    ----------
    points : (N, 2) array of float
        N >= 5 points, any units (here: normalised image coordinates).

    Returns
    -------
    (3, 3) array of float or None
        Symmetric conic matrix ``C`` with ``[x, y, 1] C [x, y, 1]^T = 0`` on the
        ellipse, scaled to unit Frobenius norm; None if fewer than 5 points or
        the points admit no ellipse (collinear, degenerate).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 5 or not np.all(np.isfinite(pts)):
        return None
    mean = pts.mean(axis=0)
    q = pts - mean
    s = np.sqrt(np.mean(np.sum(q * q, axis=1)))
    if not s > 0:
        return None
    q = q / s
    x, y = q[:, 0], q[:, 1]
    D1 = np.column_stack([x * x, x * y, y * y])
    D2 = np.column_stack([x, y, np.ones_like(x)])
    S1 = D1.T @ D1
    S2 = D1.T @ D2
    S3 = D2.T @ D2
    try:
        T = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError:
        return None
    M = C1_INV @ (S1 + S2 @ T)
    try:
        w, V = np.linalg.eig(M)
    except np.linalg.LinAlgError:
        return None
    if np.iscomplexobj(w):
        w, V = np.real(w), np.real(V)
    cond = 4.0 * V[0] * V[2] - V[1] ** 2
    good = np.flatnonzero(cond > 0)
    if good.size == 0:
        return None
    # Of the admissible eigenvectors take the one with the smallest non-negative eigenvalue.
    k = good[np.argmin(np.abs(w[good]))]
    a1 = V[:, k]
    a2 = T @ a1
    A, B, C = a1
    Dd, E, F = a2
    Cn = np.array([[A, B / 2, Dd / 2], [B / 2, C, E / 2], [Dd / 2, E / 2, F]])
    # x_n = N x with N = [[1/s, 0, -mx/s], [0, 1/s, -my/s], [0, 0, 1]]: C = N^T Cn N.
    N = np.array([[1.0 / s, 0.0, -mean[0] / s], [0.0, 1.0 / s, -mean[1] / s], [0.0, 0.0, 1.0]])
    Cm = N.T @ Cn @ N
    norm = np.sqrt(np.sum(Cm * Cm))
    if not np.isfinite(norm) or norm == 0:
        return None
    return Cm / norm
