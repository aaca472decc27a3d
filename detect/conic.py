"""Conics through image points: the ring of beacons images as an ellipse.

A conic is ``A x^2 + B x y + C y^2 + D x + E y + F = 0``, stored as the
coefficient vector ``(A, B, C, D, E, F)``. Fits are algebraic (SVD) on
Hartley-normalised points, and distances are first-order geometric (Sampson).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import check_shape

FloatArray = NDArray[np.float64]


def _normalisers(points: FloatArray) -> FloatArray:
    """Hartley normalisation of each point set, (M, 3, 3): centroid to 0, mean distance sqrt(2)."""
    c = points.mean(axis=1)  # (M, 2)
    spread = np.linalg.norm(points - c[:, None, :], axis=2).mean(axis=1)
    s = np.sqrt(2.0) / np.maximum(spread, 1e-12)
    T = np.zeros((points.shape[0], 3, 3))
    T[:, 0, 0] = T[:, 1, 1] = s
    T[:, 0, 2] = -s * c[:, 0]
    T[:, 1, 2] = -s * c[:, 1]
    T[:, 2, 2] = 1.0
    return T


def conic_design(points: FloatArray) -> FloatArray:
    """Rows ``[x^2, xy, y^2, x, y, 1]`` of the points, (..., N, 6) for (..., N, 2)."""
    x, y = points[..., 0], points[..., 1]
    return np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=-1)


def conic_matrix(conic: FloatArray) -> FloatArray:
    """The symmetric 3x3 matrix ``Q`` with ``[x y 1] Q [x y 1]^T = 0``, (..., 3, 3) for (..., 6)."""
    A, B, C, D, E, F = np.moveaxis(np.asarray(conic, dtype=float), -1, 0)
    return np.stack([np.stack([A, B / 2, D / 2], axis=-1),
                     np.stack([B / 2, C, E / 2], axis=-1),
                     np.stack([D / 2, E / 2, F], axis=-1)], axis=-2)


def fit_conic(points_px: FloatArray) -> FloatArray:
    """Algebraic least-squares conic through ``points_px`` (N >= 5), unit-norm coefficients.

    A batch of one of :func:`fit_conics`.

    Parameters
    ----------
    points_px : (N, 2) array of float

    Returns
    -------
    (6,) array of float
    """
    p = np.asarray(points_px, dtype=float)
    check_shape("points_px", p, (None, 2))
    return fit_conics(p[None])[0]


def fit_conics(points_px: FloatArray) -> FloatArray:
    """Algebraic least-squares conic through each of M point sets (N >= 5 each), unit-norm coefficients.

    Each set is Hartley-normalised, and its conic is the design matrix's right singular
    vector of the least singular value, mapped back. A set's conic does not depend on
    the others in the batch (each goes through the same LAPACK and BLAS calls as alone).

    Parameters
    ----------
    points_px : (M, N, 2) array of float

    Returns
    -------
    (M, 6) array of float
    """
    p = np.asarray(points_px, dtype=float)
    check_shape("points_px", p, (None, None, 2))
    T = _normalisers(p)
    pn = p @ T[:, :2, :2].transpose(0, 2, 1) + T[:, None, :2, 2]
    _, _, vt = np.linalg.svd(conic_design(pn))
    Q = T.transpose(0, 2, 1) @ conic_matrix(vt[:, -1]) @ T
    c = np.stack([Q[:, 0, 0], 2 * Q[:, 0, 1], Q[:, 1, 1], 2 * Q[:, 0, 2], 2 * Q[:, 1, 2], Q[:, 2, 2]],
                 axis=-1)
    # each norm as np.linalg.norm's of one vector (a dot product: (1, 6) @ (6, 1) per set)
    return c / np.sqrt(c[:, None, :] @ c[:, :, None])[:, 0]


def ellipse_centre(conic: FloatArray) -> FloatArray:
    """Centre of an ellipse conic, (2,)."""
    A, B, C, D, E, _ = conic
    return np.linalg.solve(np.array([[2 * A, B], [B, 2 * C]]), -np.array([D, E]))


def ellipse_shape(conic: FloatArray) -> FloatArray | None:
    """``M`` (2x2, positive definite) with ``(p - c)^T M (p - c) = 1`` on the ellipse, or None."""
    A, B, C = conic[:3]
    c = ellipse_centre(conic)
    Q2 = np.array([[A, B / 2], [B / 2, C]])
    fc = float(np.append(c, 1.0) @ conic_matrix(conic) @ np.append(c, 1.0))
    if fc == 0.0:
        return None
    M = Q2 / -fc
    if np.any(np.linalg.eigvalsh(M) <= 0):
        return None
    return M


def ellipse_semi_axes(conic: FloatArray) -> tuple[float, float] | None:
    """``(major, minor)`` semi-axes, or ``None`` if the conic is no real ellipse."""
    M = ellipse_shape(conic)
    if M is None:
        return None
    ev = np.linalg.eigvalsh(M)
    return float(1.0 / np.sqrt(ev[0])), float(1.0 / np.sqrt(ev[1]))


def sampson_distance(conic: FloatArray, points_px: FloatArray) -> FloatArray:
    """First-order geometric distance of each point to the conic, (N,) pixels."""
    p = np.asarray(points_px, dtype=float)
    A, B, C, D, E, _ = conic
    x, y = p[:, 0], p[:, 1]
    f = conic_design(p) @ conic
    gx = 2 * A * x + B * y + D
    gy = B * x + 2 * C * y + E
    return np.abs(f) / np.maximum(np.hypot(gx, gy), 1e-300)
