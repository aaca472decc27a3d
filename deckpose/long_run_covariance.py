"""Covariance of a sum of serially correlated terms: the Newey–West (Bartlett) estimator, HAC.

Points ordered along an edge carry errors that are correlated over a few points (the deck
texture under neighbouring edge pixels), so a least-squares fit to them is more uncertain than
``(J^T J)^-1`` says. For whitened rows ``J_i`` and residuals ``r_i`` (``i`` in order along the
edge) the fit's covariance is the sandwich ``A^-1 S A^-1``, ``A = J^T J``, where ``S`` is the
covariance of the sum of the scores ``s_i = J_i r_i``:

    S = sum_{|l| <= L} w_l G_l,   G_l = sum_i s_i s_{i+l}^T,   w_l = 1 - |l| / (L + 1)

(Newey and West 1987; the Bartlett weights keep ``S`` positive semi-definite). The bandwidth
``L`` follows Andrews (1991) for an AR(1) fit to the residuals (:func:`ar1_bandwidth`).
:func:`long_run_covariance_of_model` is the same sum for a known correlation ``rho(l)`` of the
residuals instead of their products: the covariance of the scores were the noise of that
correlation and the rows' unit variance (the bound of a fit under correlated noise).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["ar1_bandwidth", "autocorrelation", "bartlett_weights", "long_run_covariance",
           "long_run_covariance_of_model", "sandwich"]

FloatArray = NDArray[np.float64]


def bartlett_weights(bandwidth: int) -> FloatArray:
    """``w_l = 1 - l / (L + 1)`` for lags ``l = 0 .. L``, (L + 1,)."""
    if bandwidth < 0:
        raise ValueError(f"bandwidth: at least 0, got {bandwidth}")
    return 1.0 - np.arange(bandwidth + 1) / (bandwidth + 1.0)


def ar1_bandwidth(residuals: FloatArray) -> int:
    """Andrews' (1991) bandwidth of the Bartlett kernel for an AR(1) fit to ``residuals`` (N,).

    ``L = 1.1447 (alpha N)^(1/3)``, ``alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2)`` with ``rho``
    the lag-1 autocorrelation (clipped to [-0.97, 0.97]); at most ``N / 4``, at least 0.
    """
    r = np.asarray(residuals, float)
    n = len(r)
    if n < 4:
        return 0
    c = r - r.mean()
    v = float(c @ c)
    if not v > 0:
        return 0
    rho = float(np.clip((c[:-1] @ c[1:]) / v, -0.97, 0.97))
    alpha = 4 * rho * rho / ((1 - rho) ** 2 * (1 + rho) ** 2)
    return int(min(n // 4, math.floor(1.1447 * (alpha * n) ** (1.0 / 3.0))))


def autocorrelation(residuals: FloatArray, max_lag: int) -> FloatArray:
    """Sample autocorrelation ``rho(l)``, ``l = 0 .. max_lag`` (biased: sums over ``N``), (max_lag + 1,)."""
    r = np.asarray(residuals, float)
    c = r - r.mean()
    v = float(c @ c)
    out = np.zeros(max_lag + 1)
    if not v > 0:
        out[0] = 1.0
        return out
    for lag in range(max_lag + 1):
        out[lag] = float(c[:len(c) - lag] @ c[lag:]) / v
    return out


def long_run_covariance(scores: FloatArray, bandwidth: int) -> FloatArray:
    """Newey–West estimate of the covariance of ``sum_i s_i`` (module docstring).

    Parameters
    ----------
    scores : (N, p) array of float
        Terms in their order (along the edge); their expectation is taken as 0 (not demeaned:
        least-squares scores at the truth have mean 0).
    bandwidth : int
        Largest lag ``L`` (0: the terms independent, ``sum s_i s_i^T``).

    Returns
    -------
    (p, p) array of float
    """
    s = np.asarray(scores, float)
    if s.ndim != 2:
        raise ValueError(f"scores: expected shape (N, p), got {s.shape}")
    w = bartlett_weights(min(bandwidth, max(len(s) - 1, 0)))
    S = s.T @ s
    for lag in range(1, len(w)):
        G = s[:-lag].T @ s[lag:]
        S += w[lag] * (G + G.T)
    return S


def long_run_covariance_of_model(rows: FloatArray, rho: FloatArray) -> FloatArray:
    """Covariance of ``sum_i J_i e_i`` for unit-variance ``e`` of correlation ``rho(l)``, (p, p).

    Parameters
    ----------
    rows : (N, p) array of float
        The whitened rows ``J_i`` in order.
    rho : (L + 1,) array of float
        Correlation at lags ``0 .. L`` (``rho[0]`` taken as 1), already tapered as wanted
        (for instance by :func:`bartlett_weights`); zero beyond ``L``.
    """
    J = np.asarray(rows, float)
    S = J.T @ J
    for lag in range(1, min(len(rho), len(J))):
        G = J[:-lag].T @ J[lag:]
        S += float(rho[lag]) * (G + G.T)
    return S


def sandwich(A: FloatArray, S: FloatArray) -> FloatArray:
    """``A^-1 S A^-1`` (symmetrised), the covariance of a least-squares fit of normal matrix ``A``."""
    Ai = np.linalg.inv(A)
    C = Ai @ S @ Ai
    return np.asarray(0.5 * (C + C.T), dtype=np.float64)
