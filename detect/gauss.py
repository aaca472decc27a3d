"""``gauss``: weighted least-squares fit of a pixel-integrated 2-D Gaussian per blob.

Model per pixel: ``b + N * Ex(u, su) * Ey(v, sv)`` with ``Ex``, ``Ey`` the exact
fractions of an axis-aligned Gaussian in each unit pixel (erf differences), six
parameters (centre, two widths, flux, background). Weights are the inverse of
the modelled noise variance (background noise plus shot noise of the model),
updated once from the first fit, which makes the fit close to the Poisson
maximum-likelihood estimate; the centre covariance is the ``(u, v)`` block of
``inv(J^T W J)``, the Fisher information of the fitted model.

A core that saturates, or that sits on a pedestal (a marking, a housing or glow
around it: :attr:`~deckpose.detect.candidates.Candidate.clip_signal`), is fitted
by :func:`deckpose.detect.core_fit.core_fit` instead: a censored least-squares
fit of an elliptical Gaussian to the unsaturated wings of the core, saturated
pixels counting only as "at or above full scale". ``gauss`` falls back to the
``cog`` centre only when that fit fails (too few unsaturated pixels).
"""

from __future__ import annotations

import math

import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.candidates import measure_candidate_batch
from deckpose.detect.centroid import Row, cog_centroid, cog_centroids
from deckpose.detect.core_fit import core_fit
from deckpose.detect.crb import gaussian_pixel_terms
from deckpose.detect.registry import Blobs, DetectorOptions, register, register_kernel
from scipy.optimize import least_squares

from deckpose.records import Frame


def _model_and_jac(
    p: np.ndarray, xs: np.ndarray, ys: np.ndarray, sel: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    u, v, su, sv, F, b = p
    Ex, dEx, sEx = gaussian_pixel_terms(u, su, xs)
    Ey, dEy, sEy = gaussian_pixel_terms(v, sv, ys)
    shape = np.outer(Ey, Ex).ravel()[sel]
    m = b + F * shape
    J = np.empty((m.size, 6))
    J[:, 0] = F * np.outer(Ey, dEx).ravel()[sel]
    J[:, 1] = F * np.outer(dEy, Ex).ravel()[sel]
    J[:, 2] = F * np.outer(Ey, sEx).ravel()[sel]
    J[:, 3] = F * np.outer(sEy, Ex).ravel()[sel]
    J[:, 4] = shape
    J[:, 5] = 1.0
    return m, J


def gauss_fit(cand: Candidate, window_sigma: float = 3.0) -> Row | None:
    """Fit one candidate; ``None`` when the fit fails or is degenerate."""
    return gauss_fit_from(cand, cog_centroid(cand, window_sigma, above_floor=False), window_sigma)


def gauss_fit_from(cand: Candidate, start: Row | None, window_sigma: float = 3.0) -> Row | None:
    """:func:`gauss_fit` from the candidate's ``cog`` row ``start`` (its first pass, ``above_floor=False``).

    ``None`` when ``start`` is (``cog`` found no centre) or the fit fails or is degenerate.
    """
    if start is None:
        return None
    if cand.clip_signal or cand.saturated[cand.mask].any():
        # A clipped core, or one framed by a marking or housing: fit the core's own
        # wings, saturated pixels censored.
        return core_fit(cand, start, window_sigma)
    u0, v0, _, F0, s0, _ = start
    h, w = cand.pixels.shape
    xs = np.arange(w, dtype=float) + cand.u0
    ys = np.arange(h, dtype=float) + cand.v0
    uu, vv = np.meshgrid(xs, ys)
    R = max(window_sigma + 1.0, 4.0) * s0 + 1.0
    sel = ((np.hypot(uu - u0, vv - v0) <= R) & ~cand.saturated).ravel()
    if sel.sum() < 8:
        return None
    data = cand.signal().ravel()[sel]  # local background plane removed; b fits what is left
    p = np.array([u0, v0, s0, s0, F0, 0.0])
    for _ in range(2):  # weights from the current model, then once more from the fit
        m, _ = _model_and_jac(p, xs, ys, sel)
        wts = 1.0 / np.sqrt(cand.noise_dn**2 + cand.gain_dn_per_e * np.maximum(m - p[5], 0.0))

        def fun(q: np.ndarray, wts: np.ndarray = wts) -> np.ndarray:
            return (_model_and_jac(q, xs, ys, sel)[0] - data) * wts

        def jac(q: np.ndarray, wts: np.ndarray = wts) -> np.ndarray:
            return _model_and_jac(q, xs, ys, sel)[1] * wts[:, None]

        try:
            # scipy has no types: pyright takes jac's type (str) from its default
            res = least_squares(fun, p, jac=jac,  # pyright: ignore[reportArgumentType]
                                method="lm", x_scale="jac", max_nfev=60)
        except (ValueError, np.linalg.LinAlgError):
            return None
        p = res.x
    u, v, su, sv, F, b = p
    su, sv = abs(su), abs(sv)
    if not (np.all(np.isfinite(p)) and F > 0 and 0.2 < su < 4 * R and 0.2 < sv < 4 * R):
        return None
    if math.hypot(u - u0, v - v0) > 2.0 * s0 + 1.0:
        return None
    m, J = _model_and_jac(np.array([u, v, su, sv, F, b]), xs, ys, sel)
    var = cand.noise_dn**2 + cand.gain_dn_per_e * np.maximum(m - b, 0.0)
    try:
        cov = np.linalg.inv((J / var[:, None]).T @ J)[:2, :2]
    except np.linalg.LinAlgError:
        return None
    return cand.blob(u, v, flux_dn=float(F), size_px=math.sqrt(su * sv), cov_px2=cov)


def measure_gauss(cands: list[Candidate], options: DetectorOptions) -> list[Row | None]:
    """The ``gauss`` row of each candidate (``None``: no fit and no clipped core to fall back on)."""
    # the cog starts of all the candidates together (cog_centroids' batch)
    starts = cog_centroids(cands, options.window_sigma, above_floor=False)
    rows = [gauss_fit_from(c, s, options.window_sigma) for c, s in zip(cands, starts)]
    # Too few unsaturated core pixels to fit: keep the windowed centroid rather than
    # lose the beacon.
    lost = [i for i, (c, r) in enumerate(zip(cands, rows))
            if r is None and (c.clip_signal or c.saturated[c.mask].any())]
    for i, row in zip(lost, cog_centroids([cands[i] for i in lost], options.window_sigma)):
        rows[i] = row
    return rows


@register("gauss")
def detect_gauss(frame: Frame, options: DetectorOptions) -> Blobs:
    """Weighted least-squares pixel-integrated Gaussian fit per blob (with covariance)."""
    return measure_candidate_batch(frame, options, lambda cands: measure_gauss(cands, options))


register_kernel("gauss", measure_gauss)
