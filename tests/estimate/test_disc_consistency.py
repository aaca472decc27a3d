"""The centre disc's consistency test (Hausman) on a linear-Gaussian model with a known answer.

The ring's edge points are linear observations ``y1 = A1 x + e1`` of the six pose parameters,
the disc's ``y2 = A2 x + b + e2`` (``b``: a bias), unit white noise. Least squares on ``y1``
is the ring-only estimate (covariance ``(A1^T A1)^-1``), on both the estimate with the disc
(``(A^T A)^-1``). Without a bias the statistic is chi-square with as many degrees of freedom as
it reports, so over many draws its mean is the dof and it passes the 1e-3 quantile about once
in a thousand; a bias of a few sigmas of the disc's own information is caught.
"""

from __future__ import annotations

import numpy as np
from deckpose.estimate.painted_ring_pose import DISC_CHECK_ALPHA, METHOD, disc_consistency
from scipy.stats import chi2, ncx2

from deckpose.records import PoseEstimate


def _record(x: np.ndarray, cov: np.ndarray) -> PoseEstimate:
    return PoseEstimate(METHOD, True, roll_rad=float(x[0]), pitch_rad=float(x[1]), yaw_rad=float(x[2]),
                        surge_m=float(x[3]), sway_m=float(x[4]), height_m=float(x[5]), covariance=cov)


def _design(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    scale = [100.0, 100.0, 50.0, 1.0, 1.0, 1.0]  # angles to ~0.01 rad: no wrapping
    return rng.normal(size=(40, 6)) * scale, rng.normal(size=(12, 6)) * scale


def _draws(bias: float, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A1, A2 = _design(0)
    A = np.vstack([A1, A2])
    S1, S = np.linalg.inv(A1.T @ A1), np.linalg.inv(A.T @ A)
    x = np.array([0.01, -0.02, 0.3, 0.5, -0.4, 30.0])
    stats, dofs = [], []
    for _ in range(n):
        y1 = A1 @ x + rng.normal(size=40)
        y2 = A2 @ x + bias + rng.normal(size=12)
        x1 = S1 @ A1.T @ y1
        x12 = S @ A.T @ np.concatenate([y1, y2])
        s, d = disc_consistency(_record(x1, S1), _record(x12, S))
        stats.append(s)
        dofs.append(d)
    return np.array(stats), np.array(dofs)


def test_unbiased_disc_gives_chi_square():
    stats, dofs = _draws(0.0, 3000, 1)
    assert (dofs == dofs[0]).all() and 1 <= dofs[0] <= 6
    k = int(dofs[0])
    # mean of chi2(k) is k with standard error sqrt(2k / 3000) (< 0.07): 5 of those
    assert abs(stats.mean() - k) < 5 * np.sqrt(2 * k / 3000), (stats.mean(), k)
    # false alarms at the test's own rate: 3 expected in 3000, Poisson; at most 12 (p < 1e-4)
    assert (stats > chi2.ppf(1 - DISC_CHECK_ALPHA, k)).sum() <= 12


def test_biased_disc_is_caught_at_the_noncentral_chi_square_rate():
    # a bias of 3 noise sigmas on each of the disc's 12 points moves the estimate with the disc
    # by delta = S A2^T b; the statistic is then noncentral chi-square with noncentrality
    # delta^T (S1 - S)^-1 delta (all six directions kept here), which gives the test's power
    bias = 3.0
    A1, A2 = _design(0)
    S1, S = np.linalg.inv(A1.T @ A1), np.linalg.inv(np.vstack([A1, A2]).T @ np.vstack([A1, A2]))
    delta = S @ A2.T @ np.full(12, bias)
    nc = float(delta @ np.linalg.solve(S1 - S, delta))
    stats, dofs = _draws(bias, 400, 2)
    assert (dofs == 6).all()
    q = chi2.ppf(1 - DISC_CHECK_ALPHA, 6)
    power = float(ncx2.sf(q, 6, nc))
    rate = float(np.mean(stats > q))
    assert power > 0.5  # the bias is one the test should catch more often than not
    assert abs(rate - power) < 4 * np.sqrt(power * (1 - power) / 400) + 0.01, (rate, power)


def test_no_information_no_test():
    S = np.diag([1e-4, 1e-4, 4e-4, 1.0, 1.0, 1.0])
    x = np.zeros(6)
    stat, dof = disc_consistency(_record(x, S), _record(x + 0.001, S))
    assert dof == 0 and stat == 0.0
