"""Least-squares conic fit of the thesis (eq. 2.17) and its canonical parameters.

The thesis fits ``A x^2 + 2B xy + C y^2 + 2D x + 2E y + F = 0`` with ``A = 1`` by
ordinary least squares on ``2B xy + C y^2 + 2D x + 2E y + F = -x^2``, then reads
off the centre ``(k, h)``, the semi-axes and the tilt (section 2.5). Everything
here is vectorised over frames: points come as ``(F, N)`` arrays with a
``(F, N)`` boolean mask of which beacons are present, so frames with different
numbers of visible beacons share one call.

The fit is solved in coordinates scaled to unit size (the minimiser is the same
as for the raw pixels, since the residual only gains a constant factor ``s^4``)
which keeps the 5x5 normal equations well conditioned in float64.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ShapeError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Relative eccentricity ``1 - minor/major`` below which a conic counts as a circle
#: (tilt undefined). A deck tilted by 0.003 deg still clears it.
CIRCLE_TOL = 1e-9


@dataclass(frozen=True)
class ConicFit:
    """Fitted conics for a batch of frames (all arrays have shape (F,)).

    Attributes
    ----------
    B, C, D, E, F : array of float
        Coefficients with ``A = 1``.
    k, h : array of float
        Centre x and y.
    a, b : array of float
        The two semi-axes as the thesis's formulas give them (a' and b').
    major, minor : array of float
        ``max(a, b)`` and ``min(a, b)``.
    tilt_rad : array of float
        The thesis's tilt Theta (radians; the thesis states it in degrees).
    ok : array of bool
        A real ellipse with a defined tilt was found.
    circle : array of bool
        The conic is (numerically) a circle, so the tilt is undefined.
    """

    B: FloatArray
    C: FloatArray
    D: FloatArray
    E: FloatArray
    F: FloatArray
    k: FloatArray
    h: FloatArray
    a: FloatArray
    b: FloatArray
    major: FloatArray
    minor: FloatArray
    tilt_rad: FloatArray
    ok: BoolArray
    circle: BoolArray


def fit_conic_coefficients(x: FloatArray, y: FloatArray, mask: BoolArray) -> FloatArray:
    """Least-squares ``(B, C, D, E, F)`` of eq. 2.17 with ``A = 1``, per frame.

    Parameters
    ----------
    x, y : (F, N) array of float
        Point coordinates (any units; typically centred pixels).
    mask : (F, N) array of bool
        Which points take part. Frames need at least 5.

    Returns
    -------
    (F, 5) array of float
        ``B, C, D, E, F``; NaN rows where the system is singular.
    """
    if not (x.shape == y.shape == mask.shape) or x.ndim != 2:
        raise ShapeError(f"x, y and mask must share one (F, N) shape, got {x.shape}, {y.shape}, {mask.shape}")
    w = mask.astype(float)
    absmax = np.max(np.where(mask, np.maximum(np.abs(x), np.abs(y)), 0.0), axis=1)
    s = np.where(absmax > 0, 1.0 / np.where(absmax > 0, absmax, 1.0), 1.0)[:, None]
    xs, ys = x * s * w, y * s * w
    # Columns of the design matrix, zeroed where the mask is off (zero rows do not
    # change a least-squares solution).
    M = np.stack([2.0 * xs * ys, ys * ys, 2.0 * xs, 2.0 * ys, w], axis=-1)  # (F, N, 5)
    rhs = -(xs * xs)
    G = np.einsum("fni,fnj->fij", M, M)
    g = np.einsum("fni,fn->fi", M, rhs)
    out = np.full((x.shape[0], 5), np.nan)
    det = np.linalg.det(G)
    good = np.isfinite(det) & (np.abs(det) > 1e-300) & (mask.sum(axis=1) >= 5)
    if good.any():
        out[good] = np.linalg.solve(G[good], g[good][..., None])[..., 0]
    s1 = s[:, 0]
    out[:, 2] /= s1
    out[:, 3] /= s1
    out[:, 4] /= s1 * s1
    return out


def canonical(coef: FloatArray) -> ConicFit:
    """Canonical parameters of ``x^2 + 2Bxy + Cy^2 + 2Dx + 2Ey + F = 0`` (thesis section 2.5).

    Follows the published implementation exactly: centre, semi-axes ``a', b'``
    and a tilt ``Theta = 0.5*acot((C - A)/(2B))`` in (-90, 90] deg, plus 90 deg
    when ``a' < b'``, minus 180 deg when then ``B < 0`` and ``Theta > 90`` deg.

    Parameters
    ----------
    coef : (F, 5) array of float
        ``B, C, D, E, F`` per frame.
    """
    A = 1.0
    B, C, D, E, F = (coef[:, i] for i in range(5))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        delta = B * B - A * C
        k = (C * D - B * E) / delta
        h = (A * E - B * D) / delta
        num = 2.0 * (A * E * E + C * D * D + F * B * B - 2.0 * B * D * E - A * C * F)
        s = np.sqrt(1.0 + 4.0 * B * B / (A - C) ** 2)
        a = np.sqrt(num / (delta * ((C - A) * s - (C + A))))
        b = np.sqrt(num / (delta * ((A - C) * s - (C + A))))
        # acot(x) = atan(1/x), range (-90, 90] deg; x = 0 gives +90 deg.
        xcot = (C - A) / (2.0 * B)
        acot = np.where(xcot == 0.0, np.pi / 2.0, np.arctan(1.0 / xcot))
        tilt = 0.5 * acot
        tilt = np.where(a < b, tilt + np.pi / 2.0, tilt)
        tilt = np.where((B < 0) & (tilt > np.pi / 2.0), tilt - np.pi, tilt)
        major = np.maximum(a, b)
        minor = np.minimum(a, b)
        circle = ~(1.0 - minor / major > CIRCLE_TOL)
    finite = np.isfinite(k) & np.isfinite(h) & np.isfinite(a) & np.isfinite(b) & np.isfinite(tilt)
    ok = finite & (delta < 0) & (a > 0) & (b > 0) & ~circle
    return ConicFit(B, C, D, E, F, k, h, a, b, major, minor, tilt, ok, circle & np.isfinite(delta))


def fit_conic(x: FloatArray, y: FloatArray, mask: BoolArray) -> ConicFit:
    """Fit eq. 2.17 and return its canonical parameters; see :func:`canonical`."""
    return canonical(fit_conic_coefficients(x, y, mask))


def ray_ellipse_distances(
    vx: FloatArray,
    vy: FloatArray,
    k: FloatArray,
    h: FloatArray,
    tilt_rad: FloatArray,
    major: FloatArray,
    minor: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Signed distances ``L1 >= L2`` at which ``L*(vx, vy)`` meets the thesis's ellipse.

    The ellipse is ``[(x-k)cos T - (y-h)sin T]^2/major^2 + [(x-k)sin T + (y-h)cos T]^2/minor^2 = 1``
    (eqs. 3.7-3.18 as the published code writes them). Ellipse parameters
    broadcast against the ray directions, e.g. ``(F, 1)`` against ``(F, N)``.

    Returns
    -------
    L1, L2 : array of float
        The larger and smaller root; NaN where the ray misses the ellipse.
    """
    c, s = np.cos(tilt_rad), np.sin(tilt_rad)
    a1 = vx * c - vy * s
    a2 = vx * s + vy * c
    b1 = k * c - h * s
    b2 = k * s + h * c
    im2, in2 = 1.0 / (major * major), 1.0 / (minor * minor)
    qa = a1 * a1 * im2 + a2 * a2 * in2
    qb = -2.0 * (a1 * b1 * im2 + a2 * b2 * in2)
    qc = b1 * b1 * im2 + b2 * b2 * in2 - 1.0
    disc = qb * qb - 4.0 * qa * qc
    with np.errstate(invalid="ignore"):
        root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    # Numerically stable pair of roots.
    q = -0.5 * (qb + np.copysign(root, qb))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = q / qa
        r2 = qc / q
    return np.maximum(r1, r2), np.minimum(r1, r2)
