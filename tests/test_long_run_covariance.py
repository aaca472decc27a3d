"""The Newey-West (HAC) covariance against AR(1) noise, whose long-run covariance is known in closed form.

AR(1): ``e_i = phi e_{i-1} + u_i``, ``u`` white of variance 1, stationary variance
``1 / (1 - phi^2)`` and ``Cov(e_i, e_j) = phi^|i-j| / (1 - phi^2)``. For a regression
``y = X b + e`` fitted by ordinary least squares the exact covariance of ``b`` is
``(X^T X)^-1 X^T Sigma X (X^T X)^-1`` with that ``Sigma`` written out as an N x N matrix here (an
independent computation: no lag sums, no bandwidth); the HAC sandwich from the fitted residuals
must reach it on average, where the white-noise ``(X^T X)^-1 s^2`` is ``(1 + phi) / (1 - phi)``
times too small.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from deckpose.long_run_covariance import (
    ar1_bandwidth,
    autocorrelation,
    bartlett_weights,
    long_run_covariance,
    long_run_covariance_of_model,
    sandwich,
)

N = 2000


def _ar1(phi: float, n: int, rng: np.random.Generator) -> np.ndarray:
    u = rng.normal(size=n + 200)
    e = np.empty_like(u)
    e[0] = u[0] / math.sqrt(1 - phi * phi)
    for i in range(1, len(u)):
        e[i] = phi * e[i - 1] + u[i]
    return e[200:]


def _design(n: int) -> np.ndarray:
    # an edge's regressors: a level and the first two harmonics around it (smooth along the order)
    t = 2 * math.pi * np.arange(n) / n
    return np.column_stack([np.ones(n), np.cos(t), np.sin(t), np.cos(2 * t), np.sin(2 * t)])


def _exact(X: np.ndarray, phi: float) -> np.ndarray:
    i = np.arange(len(X))
    Sigma = phi ** np.abs(i[:, None] - i[None, :]) / (1 - phi * phi)
    A_inv = np.linalg.inv(X.T @ X)
    return A_inv @ X.T @ Sigma @ X @ A_inv


def test_bartlett_weights():
    np.testing.assert_allclose(bartlett_weights(3), [1.0, 0.75, 0.5, 0.25])
    with pytest.raises(ValueError):
        bartlett_weights(-1)


def test_sum_of_ar1_terms_against_its_long_run_variance():
    # Var(sum e_i) for AR(1), exactly: 1^T Sigma 1; the HAC of the terms themselves (p = 1)
    phi = 0.6
    i = np.arange(N)
    exact = float(np.sum(phi ** np.abs(i[:, None] - i[None, :]))) / (1 - phi * phi)
    rng = np.random.default_rng(5)
    got = []
    for _ in range(200):
        e = _ar1(phi, N, rng)
        got.append(long_run_covariance(e[:, None], ar1_bandwidth(e))[0, 0])
    # 200 draws: the mean's standard error is ~2 % (each estimate ~25 % spread at L ~ 20);
    # the Bartlett kernel's bias at Andrews' bandwidth is -2 sum l rho(l) / (L + 1) / LRV
    # ~ -3.75 / 4 / 21 ~ -5 %; 12 % covers both
    assert abs(np.mean(got) / exact - 1) < 0.12, np.mean(got) / exact
    # and white-noise independence (L = 0) is (1 - phi) / (1 + phi) = 0.25 of it: far off
    assert float(np.mean(e * e)) * N / exact < 0.3


def test_hac_of_known_errors_has_the_expectation_of_its_lag_window():
    # with the errors themselves (no fit) and a fixed bandwidth, E[S] is X^T (W o Sigma) X exactly,
    # W_ij = 1 - |i - j| / (L + 1) inside the window: the matrix form against the lag sums
    phi, L = 0.6, 23
    X = _design(N)
    i = np.arange(N)
    lag = np.abs(i[:, None] - i[None, :])
    Sigma = phi ** lag / (1 - phi * phi)
    want = X.T @ (np.clip(1 - lag / (L + 1), 0, None) * Sigma) @ X
    rng = np.random.default_rng(3)
    got = np.mean([long_run_covariance(X * _ar1(phi, N, rng)[:, None], L) for _ in range(200)], axis=0)
    # 200 draws of an estimate of ~15 % spread (L / N = 1 %, LRV 4x the variance): the mean to ~1 %,
    # 4 % is 3-4 standard errors
    np.testing.assert_allclose(np.diag(got), np.diag(want), rtol=0.04)


@pytest.mark.parametrize("phi", [0.0, 0.4, 0.6])
def test_sandwich_reaches_the_exact_ols_covariance_under_ar1_noise(phi: float):
    # the edges' residuals have lag-1 correlations of 0.1-0.4 (rendered decks, reports/painted_circle)
    X = _design(N)
    exact = _exact(X, phi)
    rng = np.random.default_rng(int(phi * 10) + 1)
    A = X.T @ X
    hac, naive, errs = [], [], []
    for _ in range(100):
        y = _ar1(phi, N, rng)  # true coefficients 0
        b = np.linalg.solve(A, X.T @ y)
        r = y - X @ b
        hac.append(np.diag(sandwich(A, long_run_covariance(X * r[:, None], ar1_bandwidth(r)))))
        naive.append(np.diag(np.linalg.inv(A)) * float(r @ r) / (N - 5))
        errs.append(b)
    ratio = np.mean(hac, axis=0) / np.diag(exact)
    # the estimator is biased low, known and measured here: the Bartlett window drops
    # sum |l| rho(l) / (L + 1) (-6 % at phi 0.4, -8 % at 0.6, from the matrix form above) and the
    # fitted residuals lose their low frequencies (-6 % more at 0.6, L / N = 1 %); the mean of
    # 100 draws is good to ~2 %. So 0.8-1.05, where the white-noise formula is 0.43 at 0.4
    assert np.all((ratio > 0.8) & (ratio < 1.05)), ratio
    # the Monte Carlo spread of the estimates agrees with the exact covariance too (100 draws:
    # a variance to +-14 % at 1 standard error, so 45 %); this checks _exact itself
    mc = np.var(np.array(errs), axis=0)
    assert np.all(np.abs(mc / np.diag(exact) - 1) < 0.45), mc / np.diag(exact)
    if phi >= 0.4:  # the white-noise formula is too small by ~(1 + phi) / (1 - phi) on the level
        assert np.mean(naive, axis=0)[0] < 0.6 * exact[0, 0]


def test_model_covariance_with_the_ar1_correlation_is_the_exact_one():
    # with rho(l) = phi^l untapered up to a long lag, the lag sum is 1^T-weighted Sigma exactly
    # (up to the phi^L tail): the correlated-noise bound's computation against the matrix form
    phi = 0.7
    X = _design(400)
    L = 120  # phi^120 ~ 3e-19
    rho = phi ** np.arange(L + 1)
    got = sandwich(X.T @ X, long_run_covariance_of_model(X, rho)) / (1 - phi * phi)
    np.testing.assert_allclose(got, _exact(X, phi), rtol=1e-9, atol=1e-15)


def test_autocorrelation_and_bandwidth():
    rng = np.random.default_rng(2)
    e = _ar1(0.5, 20000, rng)
    rho = autocorrelation(e, 3)
    # 20000 samples: each rho(l) to ~0.01 (Bartlett's formula, sqrt((1 + phi^2) / N))
    np.testing.assert_allclose(rho, 0.5 ** np.arange(4), atol=0.03)
    # Andrews: 1.1447 (alpha N)^(1/3), alpha = 4 phi^2 / ((1 - phi)^2 (1 + phi)^2) = 1.78 at 0.5
    want = 1.1447 * (4 * 0.25 / (0.25 * 2.25) * 20000) ** (1 / 3)
    assert abs(ar1_bandwidth(e) - want) <= 2
    assert ar1_bandwidth(rng.normal(size=20000)) <= 3  # white: rho ~ 0, a few lags at most
    assert ar1_bandwidth(np.zeros(3)) == 0
