"""Sub-pixel edge positions by fitting a model of the pixels across each edge (no pixel locking).

Each edge point is one image row (or column) crossing a locally straight edge: the pixels of
that row, at signed distances ``d`` (pixels, along the edge normal, positive toward the
paint) from a start point, are fitted by the image of a blurred step,

    m(d) = (c0 + c1 d) (1 - F(d - delta)) + p F(d - delta),

the deck a local line ``c0 + c1 d`` (its texture and shading: a nuisance, per profile), the
paint a level ``p``, and ``F`` the mean over the pixel's square of a Gaussian-blurred unit
step (:func:`step_coverage`: the pixel box projected on the normal, a trapezoid of widths
``|n_u|`` and ``|n_v|``, convolved with the blur ``sigma_b``). This is how the renderer mixes
paint into a pixel (area coverage) and what a sensor integrates, so the fit has no pixel
locking beyond the model's mismatch (a bilinear or smoothed profile's gradient maximum locks
toward pixel positions). ``delta`` (pixels along the normal) is the edge's offset from the
start point; the four parameters are fitted per profile by damped Gauss-Newton, all
profiles at once.

Each pixel is used once per edge (one profile per row or column the edge crosses), weighted
by the noise variance of its side, ``(1 - F) s_deck^2 + F s_paint^2`` (both measured from the
fit's residuals: shot noise makes the paint noisier than the deck). The inverse Fisher
information of that weighted model, nuisance parameters included, is each edge point's
Cramér–Rao bound along the normal (:attr:`EdgeFit.crb_px`): the bound of any unbiased
estimate from those pixels when the noise is white with those variances, the deck's local
level and slope and the paint's level unknown.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

__all__ = ["BLUR_GRID_PX", "EdgeFit", "EdgeProfiles", "blur_of_edges", "conic_edge_profiles", "fit_edge_profiles",
           "row_column_profiles", "step_coverage"]

FloatArray = NDArray[np.float64]

#: Smallest blur sigma and box width the closed form is evaluated at (pixels): the box's
#: variance 1/12 dominates, and the limits keep the differences of ``step_coverage`` exact.
MIN_SIGMA_PX = 0.02
MIN_WIDTH_PX = 0.05
#: Blur sigmas tried by :func:`blur_of_edges`, pixels.
BLUR_GRID_PX = (0.02, 0.06, 0.1, 0.2, 0.3, 0.4, 0.5, 0.65, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5, 3.2)
#: Largest offset of a fitted edge from its start point, pixels (beyond: not this edge).
MAX_OFFSET_PX = 1.5
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
#: A profile's fit has converged when its proposed step is below this: the edge offset in
#: pixels, the levels relative to ``1 + |level|`` (a thousandth of the smallest CRB seen).
STEP_TOL = 1e-9
#: Distance beyond the pixel box, in blur sigmas, past which a blurred step is flat (see
#: :func:`step_coverage`).
TAIL_SIGMAS = 9.0


def step_coverage(x_px: FloatArray, a_px: FloatArray, b_px: FloatArray, sigma_px: float
                  ) -> tuple[FloatArray, FloatArray]:
    """Mean over a pixel of a Gaussian-blurred unit step, and its derivative.

    Parameters
    ----------
    x_px : array of float, pixels
        Signed distance of the pixel centre beyond the step (positive: the step's high side).
    a_px, b_px : array of float, broadcastable to ``x_px``
        Widths of the pixel box projected on the step's normal: ``|n_u|`` and ``|n_v|``.
    sigma_px : float
        Gaussian blur sigma, pixels (at least :data:`MIN_SIGMA_PX` is used).

    Returns
    -------
    F, dF_dx : arrays of float, the shape of ``x_px``
        ``F = E[Phi((x + X + Y) / sigma)]`` with ``X ~ U(-a/2, a/2)``, ``Y ~ U(-b/2, b/2)``,
        in closed form from the second antiderivative of ``Phi``,
        ``psi2(t) = ((t^2 + 1) Phi(t) + t phi(t)) / 2``, and the derivative from the first,
        ``psi1(t) = t Phi(t) + phi(t)`` (``psi2 = (t psi1 + Phi) / 2``: one ``Phi`` and one
        ``phi`` per corner of the trapezoid).
    """
    s = max(float(sigma_px), MIN_SIGMA_PX)
    shape = np.broadcast(x_px, a_px, b_px).shape
    x = np.broadcast_to(x_px, shape)
    a = np.broadcast_to(np.maximum(a_px, MIN_WIDTH_PX), shape)
    b = np.broadcast_to(np.maximum(b_px, MIN_WIDTH_PX), shape)
    # Beyond TAIL_SIGMAS blur sigmas from the pixel box, Phi is 0 or 1 to double precision
    # (Phi(-9) = 1e-19), so F is exactly 0 or 1 there and its derivative 0: only pixels near
    # the step are evaluated (most of a long profile lies in the flat deck or paint).
    near = np.abs(x) < 0.5 * (a + b) + TAIL_SIGMAS * s
    F = (x > 0).astype(float)
    f = np.zeros(shape)
    xn, an, bn = x[near], a[near], b[near]
    Fn = np.zeros(xn.shape)
    fn = np.zeros(xn.shape)
    for sa, sb, sign in ((1, 1, 1.0), (1, -1, -1.0), (-1, 1, -1.0), (-1, -1, 1.0)):
        t = (xn + 0.5 * sa * an + 0.5 * sb * bn) / s
        cdf = ndtr(t)
        pdf = _INV_SQRT_2PI * np.exp(-0.5 * t * t)
        psi1 = t * cdf + pdf
        Fn += sign * (0.5 * (t * psi1 + cdf))
        fn += sign * psi1
    ab = an * bn
    F[near] = np.clip(Fn * (s * s) / ab, 0.0, 1.0)
    f[near] = fn * s / ab
    return F, f


@dataclass(frozen=True)
class EdgeProfiles:
    """Profiles along image rows or columns (:func:`row_column_profiles`): pixels (K, M), masked."""

    base_px: FloatArray       # (K, 2) the start point on the profile's row or column
    along: FloatArray         # (K, 2) unit step from the base along the row or column
    normal: FloatArray        # (K, 2) unit normal toward the paint
    scale: FloatArray         # (K,) normal distance per pixel step along the row or column (|.| >= 0.707)
    values: FloatArray        # (K, M)
    d_px: FloatArray          # (K, M) signed normal distance from the base's line, curvature-corrected
    mask: NDArray[np.bool_]   # (K, M)
    width_a: FloatArray       # (K,) |n_u|
    width_b: FloatArray       # (K,) |n_v|


def row_column_profiles(grey: NDArray[np.float32], anchors_px: FloatArray, normals: FloatArray,
                        curvature_per_px: FloatArray, deck_px: float, paint_px: FloatArray) -> EdgeProfiles:
    """One profile per image row (or column) the edge crosses near the anchors.

    Parameters
    ----------
    grey : (H, W) array of float32
    anchors_px : (N, 2) array of float, pixels
        Points near the edge (at most a pixel or so apart along it).
    normals : (N, 2) array of float
        Unit normals at the anchors, pointing toward the paint.
    curvature_per_px : (N,) array of float
        The edge's curvature, 1/pixels, positive where its centre of curvature lies toward the
        paint: a pixel's distance is taken from the osculating circle (``d - k t^2 / 2`` to
        second order, ``t`` along the tangent), exact for a circle however small.
    deck_px : float
        Reach of a profile into the deck, pixels along the normal.
    paint_px : (N,) array of float
        Reach into the paint, pixels along the normal (half the line width: the other edge).

    Returns
    -------
    EdgeProfiles
        Row profiles where ``|n_u| >= |n_v|``, column profiles elsewhere; one per (row or
        column, side), the first anchor's.
    """
    H, W = grey.shape
    p = np.asarray(anchors_px, float)
    n = np.asarray(normals, float)
    by_row = np.abs(n[:, 0]) >= np.abs(n[:, 1])
    major = np.where(by_row, 0, 1)          # the axis pixels step along
    minor = 1 - major
    line = np.rint(p[np.arange(len(p)), minor])  # the row (v) or column (u) index
    key = np.column_stack([major, line, np.sign(n[np.arange(len(p)), major])])
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(n), axis=1)
    _, first = np.unique(key[ok], axis=0, return_index=True)
    idx = np.flatnonzero(ok)[np.sort(first)]
    p, n, major, minor, line = p[idx], n[idx], major[idx], minor[idx], line[idx]
    r = np.arange(len(idx))
    n_major, n_minor = n[r, major], n[r, minor]
    # the edge line through the anchor meets the row/column at base
    base_major = p[r, major] - (line - p[r, minor]) * n_minor / n_major
    base = np.empty_like(p)
    base[r, major], base[r, minor] = base_major, line
    along = np.zeros_like(p)
    along[r, major] = 1.0
    reach = float(max(deck_px, float(np.max(paint_px, initial=0.0)))) / math.sqrt(0.5) + 1.0
    M = math.ceil(reach)
    j = np.arange(-M, M + 1)[None, :]
    pix_major = np.rint(base_major)[:, None] + j                      # (K, M)
    delta = pix_major - base_major[:, None]
    d = delta * n_major[:, None]
    # tangential offset from the anchor (where the edge touches its tangent line): the base's own,
    # then the pixel's (delta along major) . tangent, the tangent (-n_v, n_u)
    tangent = np.column_stack([-n[:, 1], n[:, 0]])
    t0 = np.sum((base - p) * tangent, axis=1)
    t = t0[:, None] + delta * tangent[r, major][:, None]
    # distance from the osculating circle (radius 1/|k|, centre toward the paint when k > 0)
    k = np.asarray(curvature_per_px, float)[idx][:, None]
    sgn = np.sign(k)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.where(np.abs(k) > 1e-9, 1.0 / np.abs(k), np.inf)
        d = np.where(np.isfinite(R), -sgn * (np.hypot(R - sgn * d, t) - R), d)
    uu = np.where(major[:, None] == 0, pix_major, line[:, None])
    vv = np.where(major[:, None] == 0, line[:, None], pix_major)
    inside = (uu >= 0) & (uu <= W - 1) & (vv >= 0) & (vv <= H - 1)
    ui = np.clip(uu, 0, W - 1).astype(np.intp)
    vi = np.clip(vv, 0, H - 1).astype(np.intp)
    values = grey[vi, ui].astype(float)
    mask = inside & (d >= -deck_px) & (d <= np.asarray(paint_px, float)[idx][:, None])
    # a pixel serves one profile: column profiles leave out the pixels a row profile of the edge
    # used (where the edge turns through 45 degrees both kinds meet; sharing would count a
    # pixel's information twice in the points' bounds)
    lo_v, lo_u = int(vi.min(initial=0)), int(ui.min(initial=0))
    used = np.zeros((int(vi.max(initial=0)) - lo_v + 1, int(ui.max(initial=0)) - lo_u + 1), bool)
    rows_m = mask & (major[:, None] == 0)
    used[vi[rows_m] - lo_v, ui[rows_m] - lo_u] = True
    mask &= ~((major[:, None] == 1) & used[vi - lo_v, ui - lo_u])
    return EdgeProfiles(base, along, n, n_major, values, d, mask, np.abs(n[:, 0]), np.abs(n[:, 1]))


@dataclass(frozen=True)
class EdgeFit:
    """Fitted edge profiles (:func:`fit_edge_profiles`).

    Attributes
    ----------
    points_px : (K, 2) array of float
        Sub-pixel edge points, one per row or column crossed (image pixels).
    normals : (K, 2) array of float
        Unit normals toward the paint.
    crb_px : (K,) array of float
        Each point's Cramér–Rao bound along the normal, pixels (module docstring).
    crb_known_levels_px : (K,) array of float
        The same bound were the deck's level and slope and the paint's level known (the
        white-noise bound of the edge position alone), pixels.
    step_dn : (K,) array of float
        Paint level minus deck level at the edge, DN.
    valid : (K,) array of bool
        Converged, within :data:`MAX_OFFSET_PX` of the start, paint brighter than deck.
    noise_deck_dn, noise_paint_dn : float
        Robust RMS residual of deck-side and paint-side pixels, DN (the weights' noise).
    sigma_b_px : float
        The blur the profiles were fitted with, pixels.
    """

    points_px: FloatArray
    normals: FloatArray
    crb_px: FloatArray
    crb_known_levels_px: FloatArray
    step_dn: FloatArray
    valid: NDArray[np.bool_]
    noise_deck_dn: float
    noise_paint_dn: float
    sigma_b_px: float


def _gauss_newton(rows: EdgeProfiles, sigma_b: float, var_deck: float, var_paint: float, iterations: int,
                  start: FloatArray | None = None
                  ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], FloatArray, FloatArray, FloatArray]:
    """Fit ``(c0, c1, p, delta)`` per profile.

    Returns params (K, 4), inverse Fisher information (K, 4, 4), ok (K,), the residuals
    standardised by their leverage ``r / sqrt(1 - h)`` (K, M; NaN off the profile or where
    ``h >= 0.9``: a pixel the fit follows), the raw residuals (K, M; 0 off the profile) and the
    model's coverage ``F`` (K, M).
    """
    d, y, m = rows.d_px, rows.values, rows.mask.astype(float)
    K = len(d)
    deck = np.where(rows.mask & (d < -1.0), y, np.nan)
    paint = np.where(rows.mask & (d > 0.75), y, np.nan)
    with warnings.catch_warnings():  # all-NaN rows (no pixel on a side) give NaN, handled below
        warnings.simplefilter("ignore", RuntimeWarning)
        c0 = np.nanmedian(deck, axis=1)
        pp = np.nanmedian(paint, axis=1)
    c0 = np.where(np.isfinite(c0), c0, np.nanmin(np.where(rows.mask, y, np.nan), axis=1, initial=np.inf))
    pp = np.where(np.isfinite(pp), pp, np.nanmax(np.where(rows.mask, y, np.nan), axis=1, initial=-np.inf))
    theta = np.column_stack([c0, np.zeros(K), pp, np.zeros(K)])
    theta = np.where(np.isfinite(theta), theta, 0.0)
    if start is not None:  # a nearby fit's optimum (another blur), where it has one
        theta = np.where(np.all(np.isfinite(start), axis=1, keepdims=True), start, theta)
    a, b = rows.width_a[:, None], rows.width_b[:, None]
    lam = np.full(K, 1e-3)
    info_inv = np.full((K, 4, 4), np.nan)

    def model(th: FloatArray, k: NDArray[np.intp]) -> tuple[FloatArray, FloatArray, FloatArray]:
        F, f = step_coverage(d[k] - th[:, 3:4], a[k], b[k], sigma_b)
        deck_line = th[:, 0:1] + th[:, 1:2] * d[k]
        return deck_line * (1 - F) + th[:, 2:3] * F, F, f

    def weights(F: FloatArray, k: NDArray[np.intp]) -> FloatArray:
        return m[k] / ((1 - F) * var_deck + F * var_paint)

    every = np.arange(K)
    pred, F, f = model(theta, every)
    w = weights(F, every)
    cost = np.sum(w * (y - pred) ** 2, axis=1)
    # Profiles still moving. A profile whose accepted step is below STEP_TOL (offset in pixels,
    # levels relative to their size) has converged: its further steps would change nothing a
    # fit reports, so it leaves the loop (the same optimum, found at a fraction of the cost).
    act = every
    for _ in range(iterations):
        if act.size == 0:
            break
        th, dk, yk, Fk, fk, wk = theta[act], d[act], y[act], F[act], f[act], w[act]
        deck_line = th[:, 0:1] + th[:, 1:2] * dk
        J = np.stack([1 - Fk, dk * (1 - Fk), Fk, -(th[:, 2:3] - deck_line) * fk], axis=2)  # (k, M, 4)
        JwT = (J * wk[..., None]).transpose(0, 2, 1)  # (k, 4, M): stacked matmuls, far cheaper than einsum
        A = JwT @ J
        g = (JwT @ (yk - pred[act])[..., None])[..., 0]
        diag = np.diagonal(A, axis1=1, axis2=2)
        ridge = lam[act, None] * np.maximum(diag, 1e-12) + 1e-12 * (1.0 + diag.sum(axis=1, keepdims=True))
        step = np.linalg.solve(A + ridge[..., None] * np.eye(4), g[..., None])[..., 0]
        step[:, 3] = np.clip(step[:, 3], -0.5, 0.5)
        trial = th + step
        pred_t, F_t, f_t = model(trial, act)
        w_t = weights(F_t, act)
        cost_t = np.sum(w_t * (yk - pred_t) ** 2, axis=1)
        better = np.isfinite(cost_t) & (cost_t <= cost[act])
        upd = act[better]
        theta[upd], pred[upd], F[upd], f[upd], w[upd] = (trial[better], pred_t[better], F_t[better],
                                                          f_t[better], w_t[better])
        cost[upd] = cost_t[better]
        lam[act] = np.where(better, lam[act] * 0.3, lam[act] * 10.0)
        level_scale = 1.0 + np.abs(th[:, :3])
        small = (np.abs(step[:, 3]) <= STEP_TOL) & np.all(np.abs(step[:, :3]) <= STEP_TOL * level_scale, axis=1)
        # converged: an accepted, nearly undamped (Gauss-Newton) step that is small; a damped
        # step is small only by its damping
        act = act[~(better & small & (lam[act] <= 1e-4))]
    deck_line = theta[:, 0:1] + theta[:, 1:2] * d
    J = np.stack([1 - F, d * (1 - F), F, -(theta[:, 2:3] - deck_line) * f], axis=2)
    A = (J * w[..., None]).transpose(0, 2, 1) @ J
    ok = np.linalg.cond(A) < 1e12
    info_inv[ok] = np.linalg.inv(A[ok])
    # leverage of each pixel: its residual's variance is (1 - h) of the noise's
    h = np.sum((J @ np.nan_to_num(info_inv)) * J, axis=2) * w
    ok &= np.abs(theta[:, 3]) <= MAX_OFFSET_PX
    ok &= theta[:, 2] > theta[:, 0]
    ok &= np.sum(rows.mask & (d < -0.5), axis=1) >= 2
    ok &= np.sum(rows.mask & (d > 0.5), axis=1) >= 1
    with np.errstate(invalid="ignore", divide="ignore"):
        standardised = np.where(rows.mask & (h < 0.9), (y - pred) / np.sqrt(1.0 - h), np.nan)
    return theta, info_inv, ok, standardised, np.where(rows.mask, y - pred, 0.0), F


def _robust_rms(r: FloatArray) -> float:
    r = r[np.isfinite(r)]
    return float(1.4826 * np.median(np.abs(r))) if r.size >= 10 else math.nan


def fit_edge_profiles(rows: EdgeProfiles, sigma_b_px: float, *, iterations: int = 30) -> EdgeFit:
    """Fit every profile of :func:`row_column_profiles` (module docstring).

    Two rounds: unit weights, then each side's noise variance measured from the first
    round's residuals (pixels well inside the deck or the paint, standardised by their
    leverage: a profile of ten pixels and four parameters leaves residuals smaller than the
    noise) and the profiles fitted again
    with those weights; the Fisher information is taken at the second round's optimum.

    Parameters
    ----------
    rows : EdgeProfiles
        From :func:`row_column_profiles`.
    sigma_b_px : float
        The edge blur (:func:`blur_of_edges`), pixels.
    iterations : int, keyword-only
        Gauss-Newton steps per round.

    Returns
    -------
    EdgeFit
    """
    r = rows
    theta, _, ok, res, _, F = _gauss_newton(r, sigma_b_px, 1.0, 1.0, iterations)
    mask = r.mask & ok[:, None]
    n_deck = _robust_rms(res[mask & (F < 0.05)])
    n_paint = _robust_rms(res[mask & (F > 0.95)])
    if not (n_deck > 0):
        n_deck = n_paint if n_paint > 0 else 1.0
    if not (n_paint > 0):
        n_paint = n_deck
    theta, info_inv, ok, _, _, _ = _gauss_newton(r, sigma_b_px, n_deck ** 2, n_paint ** 2, iterations)
    info = np.linalg.inv(np.where(np.isfinite(info_inv), info_inv, np.eye(4)))
    delta = theta[:, 3]
    points = r.base_px + (delta / r.scale)[:, None] * r.along
    crb = np.sqrt(np.clip(info_inv[:, 3, 3], 0.0, None))
    ok &= np.isfinite(crb) & (crb > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        known = 1.0 / np.sqrt(info[:, 3, 3])
    return EdgeFit(points, r.normal, np.where(ok, crb, np.nan), np.where(ok, known, np.nan),
                   theta[:, 2] - theta[:, 0], ok, n_deck, n_paint, float(sigma_b_px))


def blur_of_edges(rows: EdgeProfiles, *, max_profiles: int = 400) -> float:
    """The blur sigma (pixels) that fits a sample of the edge profiles best.

    The profiles are fitted at each sigma of :data:`BLUR_GRID_PX` (unit weights); the summed
    squared residual of the profiles that converge at every sigma where most of them do is
    minimised, with a parabola through the best grid point and its neighbours (in the grid's
    index).
    """
    r = rows
    K = len(r.d_px)
    if K == 0:
        return BLUR_GRID_PX[2]
    pick = np.linspace(0, K - 1, min(K, max_profiles)).astype(int)
    sub = EdgeProfiles(r.base_px[pick], r.along[pick], r.normal[pick], r.scale[pick], r.values[pick], r.d_px[pick],
                r.mask[pick], r.width_a[pick], r.width_b[pick])
    costs, oks = [], []
    start = None
    for s in BLUR_GRID_PX:
        theta, _, ok, _, raw, _ = _gauss_newton(sub, s, 1.0, 1.0, 30, start)
        start = np.where(ok[:, None], theta, np.nan)
        costs.append(np.sum(raw ** 2, axis=1))
        oks.append(ok)
    # sigmas at which most profiles fit (a blur wider than the profiles' reach fits none),
    # compared on the profiles that fit at all of them
    usable = [k for k, ok in enumerate(oks) if ok.mean() >= 0.5]
    if not usable:
        return BLUR_GRID_PX[2]
    keep = np.all([oks[k] for k in usable], axis=0)
    if not keep.any():
        return BLUR_GRID_PX[2]
    total = np.array([costs[k][keep].sum() if k in usable else np.inf for k in range(len(BLUR_GRID_PX))])
    i = int(np.argmin(total))
    if 0 < i < len(total) - 1 and np.isfinite(total[i - 1]) and np.isfinite(total[i + 1]):
        y0, y1, y2 = total[i - 1], total[i], total[i + 1]
        den = y0 - 2 * y1 + y2
        x = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        g = np.asarray(BLUR_GRID_PX)
        return float(np.interp(i + float(np.clip(x, -0.5, 0.5)), np.arange(len(g)), g))
    return float(BLUR_GRID_PX[i])


def conic_edge_profiles(grey: NDArray[np.float32], anchors_px: FloatArray, anchors_und_px: FloatArray,
                        conic_und: FloatArray, *, paint_outside: bool, deck_px: float, paint_px: FloatArray
                        ) -> EdgeProfiles:
    """:func:`row_column_profiles` of an elliptical edge: normals and curvature from its conic.

    Parameters
    ----------
    grey : (H, W) array of float32
    anchors_px : (N, 2) array of float
        Points near the edge in the image, pixels.
    anchors_und_px : (N, 2) array of float
        The same points undistorted (where the conic holds), pixels.
    conic_und : (3, 3) array of float
        The edge's conic in undistorted pixels, negative inside.
    paint_outside : bool, keyword-only
        Whether the paint lies outside the conic (a ring's inner edge) or inside it (the outer
        edge, a disc).
    deck_px, paint_px
        See :func:`row_column_profiles`.
    """
    C = 0.5 * (np.asarray(conic_und, float) + np.asarray(conic_und, float).T)
    q = np.asarray(anchors_und_px, float)
    grad = q @ C[:2, :2] + C[:2, 2]  # half the conic's gradient: points outward (negative inside)
    norm = np.linalg.norm(grad, axis=1)
    n = grad / np.where(norm > 0, norm, np.nan)[:, None]
    tangent = np.column_stack([-n[:, 1], n[:, 0]])
    # curvature of the level set: t^T (2 A) t / |2 grad|; positive toward the conic's inside
    k_inside = np.einsum("ki,ij,kj->k", tangent, C[:2, :2], tangent) / np.where(norm > 0, norm, np.nan)
    sign = 1.0 if paint_outside else -1.0
    return row_column_profiles(grey, anchors_px, sign * n, -sign * k_inside, deck_px, paint_px)
