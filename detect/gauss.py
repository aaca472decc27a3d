"""``gauss``: weighted least-squares fit of a pixel-integrated 2-D Gaussian per blob.

Model per pixel: ``b + N * Ex(u, su) * Ey(v, sv)`` with ``Ex``, ``Ey`` the exact
fractions of an axis-aligned Gaussian in each unit pixel (erf differences), six
parameters (centre, two widths, flux, background). Weights are the inverse of
the modelled noise variance (background noise plus shot noise of the model),
updated once from the first fit, which makes the fit close to the Poisson
maximum-likelihood estimate; the centre covariance is the ``(u, v)`` block of
``inv(J^T W J)``, the Fisher information of the fitted model. The noise model
(background variance and gain) is the frame's own: the spots are fitted once with
the candidates' first guesses, and the two are fitted to those fits' residuals
(:func:`frame_noise_model`); on 8-bit frames from the independent generator this
took ``gauss`` from 1.06x to 0.97x the Cramér–Rao bound (48 frames of rgb8_uneven,
``benchmarks/bench_independent.py``). A frame without enough of those fits (every spot a
core on its pedestal: only bright cores found) pools the core fits of its unsaturated
cores with them.

A core that saturates, or that sits on a pedestal (a marking, a housing or glow
around it: :attr:`~deckpose.detect.candidates.Candidate.clip_signal`), is fitted
by :func:`deckpose.detect.core_fit.core_fit` instead: a censored least-squares
fit of an elliptical Gaussian to the unsaturated wings of the core, saturated
pixels counting only as "at or above full scale". ``gauss`` falls back to the
``cog`` centre only when that fit fails (too few unsaturated pixels).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.candidates import measure_candidate_batch
from deckpose.detect.centroid import cog_centroid, cog_centroids
from deckpose.detect.core_fit import core_fit, core_fit_residuals
from deckpose.detect.crb import gaussian_pixel_terms
from deckpose.detect.gain import MIN_FITTED_SPOTS, fitted_noise_model
from deckpose.detect.registry import BlobRow, Blobs, DetectorOptions, register, register_kernel
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


def gauss_fit(cand: Candidate, window_sigma: float = 3.0) -> BlobRow | None:
    """Fit one candidate; ``None`` when the fit fails or is degenerate."""
    return gauss_fit_from(cand, cog_centroid(cand, window_sigma, above_floor=False), window_sigma)


def gauss_fit_from(cand: Candidate, start: BlobRow | None, window_sigma: float = 3.0) -> BlobRow | None:
    """:func:`gauss_fit` from the candidate's ``cog`` row ``start`` (its first pass, ``above_floor=False``).

    ``None`` when ``start`` is (``cog`` found no centre) or the fit fails or is degenerate.
    """
    if start is None:
        return None
    if _clipped(cand):
        # A clipped core, or one framed by a marking or housing: fit the core's own
        # wings, saturated pixels censored.
        return core_fit(cand, start, window_sigma)
    fit = _fit(cand, start, window_sigma)
    return None if fit is None else fit[0]


def _clipped(cand: Candidate) -> bool:
    """Whether the candidate goes to :func:`~deckpose.detect.core_fit.core_fit` (module docstring)."""
    return bool(cand.clip_signal or cand.saturated[cand.mask].any())


def _fit(cand: Candidate, start: BlobRow, window_sigma: float) -> tuple[BlobRow, np.ndarray, np.ndarray] | None:
    """The unclipped fit: its row, and per fitted pixel the squared residual over ``1 - h`` and the spot signal.

    Returns ``(row, sq_residual_dn2 (M,), signal_dn (M,))``, the inputs of
    :func:`~deckpose.detect.gain.fitted_noise_model` (``h``: the pixel's leverage in the
    weighted fit), or ``None`` when the fit fails or is degenerate.
    """
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
    spot = np.maximum(m - b, 0.0)
    var = cand.noise_dn**2 + cand.gain_dn_per_e * spot
    try:
        n_inv = np.linalg.inv((J / var[:, None]).T @ J)
    except np.linalg.LinAlgError:
        return None
    # leverage of each pixel in the weighted fit: diag(W^1/2 J N^-1 J^T W^1/2)
    lev = np.einsum("ij,jk,ik->i", J, n_inv, J) / var
    sq_res = (data - m) ** 2 / np.maximum(1.0 - lev, 0.05)
    row = cand.blob(u, v, flux_dn=float(F), size_px=math.sqrt(su * sv), cov_px2=n_inv[:2, :2])
    return row, sq_res, spot


def frame_noise_model(cands: list[Candidate], starts: list[BlobRow | None],
                      window_sigma: float = 3.0) -> list[Candidate]:
    """The candidates with the noise model their frame's own fits give (or as they are).

    The candidates' background noise and gain are first guesses (the frame's difference
    noise, floored at 1 DN per channel on integer frames; the gain of
    :func:`~deckpose.detect.gain.estimate_gain`), and they set the fit weights. On
    frames from the independent generator they were far off (8-bit: noise 1.73 DN for
    0.74 and gain 1 DN/e for 0.0425; 12-bit in 16: noise 50 DN for 43, gain 0.14-3.6
    DN/e for 3.28; before session 21 a bright core measured on the channel sum also carried
    the peak channel's noise, 17 DN), which cost ``gauss`` 9 % of its accuracy on 8-bit frames. The fits of
    the unclipped spots are made once with those guesses, and
    :func:`~deckpose.detect.gain.fitted_noise_model` fits the background variance and
    the gain to their residuals; every candidate then gets that gain, and every one
    measured on the channel sum (no saturated core pixel: a clipped core on a colour
    frame is measured on its peak channel) that background noise. With fewer than
    :data:`~deckpose.detect.gain.MIN_FITTED_SPOTS` fits, or no positive variance, the
    candidates are returned as they are.

    Where fewer than :data:`~deckpose.detect.gain.MIN_FITTED_SPOTS` unclipped spots are
    fitted that way, the core fits of the cores framed by their pedestal that do not
    saturate (``clip_signal``, :func:`~deckpose.detect.core_fit.core_fit_residuals`)
    are pooled with them. On 8-bit RGB frames of the independent generator at 0.01275
    DN/e the background is 0.38 DN a channel, the median pixel 0 DN, and before the
    significance search ran on such frames every candidate was such a core: the first-guess
    gain stayed (0.040-0.075 DN/e, its ``cog`` model's
    misfit counted as shot noise) and the covariance was overstated (RMS error / own
    sigma 0.93 / 0.84 over 36 frames; 0.96 / 0.86 with these fits pooled, accuracy
    unchanged). The pooled gain is still 2-3x the true one: the rounding of a
    sub-DN background is no noise but a level-dependent offset between the spot's wings
    and its surroundings (up to ~1 DN on the channel sum), which the residuals count as
    shot noise, so the covariance errs on the large side. The Gaussian fits come first
    where there are enough of them (their model holds more of the spot than the core fit's).

    Parameters
    ----------
    cands : list of Candidate
        One frame's candidates.
    starts : list of BlobRow or None
        Their ``cog`` rows (``above_floor=False``), one per candidate.
    window_sigma : float
        As :func:`gauss_fit`'s.
    """
    refined = _with_noise_model(cands, _first_fits(cands, starts, window_sigma))
    return cands if refined is None else refined


def _first_fits(cands: list[Candidate], starts: list[BlobRow | None], window_sigma: float
                ) -> list[tuple[BlobRow, np.ndarray, np.ndarray] | None]:
    """The first fit of each candidate with a start under its first-guess noise model (else None).

    :func:`_fit` of each unclipped candidate; where fewer than
    :data:`~deckpose.detect.gain.MIN_FITTED_SPOTS` of those fit, also
    :func:`~deckpose.detect.core_fit.core_fit_residuals` of each core framed by its
    pedestal that does not saturate (``clip_signal``, no saturated pixel in its blob).
    """
    fits = [_fit(c, s, window_sigma) if s is not None and not _clipped(c) else None for c, s in zip(cands, starts)]
    if sum(f is not None for f in fits) >= MIN_FITTED_SPOTS:
        return fits
    return [core_fit_residuals(c, s, window_sigma) if s is not None and _unsaturated_core(c) else f
            for c, s, f in zip(cands, starts, fits)]


def _unsaturated_core(cand: Candidate) -> bool:
    """Whether the candidate goes to :func:`~deckpose.detect.core_fit.core_fit` without a saturated pixel."""
    return bool(cand.clip_signal and not cand.saturated[cand.mask].any())


def _with_noise_model(cands: list[Candidate], first: list[tuple[BlobRow, np.ndarray, np.ndarray] | None]
                      ) -> list[Candidate] | None:
    """:func:`frame_noise_model` from the first fits; None where the candidates stay as they are."""
    fits = [f for f in first if f is not None]
    if len(fits) < MIN_FITTED_SPOTS:
        return None
    model = fitted_noise_model(np.concatenate([f[1] for f in fits]),
                               np.concatenate([f[2] for f in fits]))
    if model is None:
        return None
    var_dn2, gain = model
    return [replace(c, gain_dn_per_e=gain, noise_dn=c.noise_dn if c.saturated[c.mask].any()
                    else math.sqrt(var_dn2)) for c in cands]


def measure_gauss(cands: list[Candidate], options: DetectorOptions) -> list[BlobRow | None]:
    """The ``gauss`` row of each candidate (``None``: no fit and no clipped core to fall back on).

    The fit weights come from the frame's own noise model (:func:`frame_noise_model`).
    """
    # the cog starts of all the candidates together (cog_centroids' batch)
    starts = cog_centroids(cands, options.window_sigma, above_floor=False)
    first = _first_fits(cands, starts, options.window_sigma)
    refined = _with_noise_model(cands, first)
    if refined is None:  # the first guesses stay: their fits are the rows
        rows = [f[0] if f is not None else (gauss_fit_from(c, s, options.window_sigma) if _clipped(c) else None)
                for c, s, f in zip(cands, starts, first)]
    else:
        cands = refined
        rows = [gauss_fit_from(c, s, options.window_sigma) for c, s in zip(cands, starts)]
    # Too few unsaturated core pixels to fit: keep the windowed centroid rather than
    # lose the beacon.
    lost = [i for i, (c, r) in enumerate(zip(cands, rows)) if r is None and _clipped(c)]
    for i, row in zip(lost, cog_centroids([cands[i] for i in lost], options.window_sigma)):
        rows[i] = row
    return rows


@register("gauss")
def detect_gauss(frame: Frame, options: DetectorOptions) -> Blobs:
    """Weighted least-squares pixel-integrated Gaussian fit per blob (with covariance)."""
    return measure_candidate_batch(frame, options, lambda cands: measure_gauss(cands, options))


register_kernel("gauss", measure_gauss)
