"""The deck-motion model's exact discretisation against Van Loan's matrix exponential (scipy.linalg.expm)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_lyapunov

from deckpose.errors import ConfigError
from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    discretise,
    measurement_matrix,
    ncv_discretisation,
    oscillator_discretisation,
    output_matrix,
    prior,
    state_size,
    state_slices,
)

#: expm (Pade approximation with scaling and squaring) against closed forms on unit-scale
#: 2x2 blocks: agreement to a few hundred float64 round-offs.
EXPM_TOL = 1e-10


def van_loan(A: np.ndarray, G: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F = expm(A dt) and Q = int_0^dt e^{A s} G G^T e^{A^T s} ds by Van Loan's block exponential (1978)."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = G @ G.T
    M[n:, n:] = A.T
    E = expm(M * dt)
    F = E[n:, n:].T
    return F, F @ E[:n, n:]


@pytest.mark.parametrize("period_s,zeta,dt", [(11.0, 0.1, 0.1), (5.0, 0.05, 0.5), (20.0, 0.3, 2.0), (8.0, 0.08, 0.0)])
def test_oscillator_discretisation_is_van_loans(period_s, zeta, dt):
    w, sigma = 2 * math.pi / period_s, 0.07
    A = np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]])
    q = 4 * zeta * w ** 3 * sigma ** 2          # white-noise density giving stationary var(p) = sigma^2
    F_ref, Q_ref = van_loan(A, np.array([[0.0], [math.sqrt(q)]]), dt)
    F, Q = oscillator_discretisation(np.array([w]), zeta, np.array([sigma]), dt)
    np.testing.assert_allclose(F[0], F_ref, atol=EXPM_TOL)
    np.testing.assert_allclose(Q[0], Q_ref, atol=EXPM_TOL * sigma ** 2 * max(1, w * w))


def test_oscillator_stationary_covariance_is_the_continuous_one():
    # the discrete Lyapunov equation P = F P F^T + Q has the continuous process's stationary
    # covariance diag(sigma^2, omega^2 sigma^2) (var p = q / (4 zeta omega^3), var v = q / (4 zeta omega))
    w, zeta, sigma = 2 * math.pi / 9.0, 0.12, 1.3
    F, Q = oscillator_discretisation(np.array([w]), zeta, np.array([sigma]), 0.1)
    P = solve_discrete_lyapunov(F[0], Q[0])
    np.testing.assert_allclose(P, np.diag([sigma ** 2, (w * sigma) ** 2]), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("dt", [0.0, 0.1, 1.0, 7.5])
def test_ncv_discretisation_is_van_loans(dt):
    q = 0.3
    F_ref, Q_ref = van_loan(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [q]]), dt)
    F, Q = ncv_discretisation(q, dt)
    np.testing.assert_allclose(F, F_ref, atol=EXPM_TOL)
    np.testing.assert_allclose(Q, Q_ref, atol=EXPM_TOL * max(1.0, dt ** 3))


def test_whole_model_is_the_exponential_of_its_generator():
    # the full block-diagonal model against one Van Loan exponential of the whole continuous system
    m = DeckMotionModel(periods_s=(6.0, 11.0), damping_ratio=0.1)
    n, sl, dt = state_size(m), state_slices(m), 0.25
    A, G = np.zeros((n, n)), np.zeros((n, n))
    for name, sigma in (("roll", math.radians(m.roll_sigma_deg)), ("pitch", math.radians(m.pitch_sigma_deg)),
                        ("heave", m.heave_sigma_m)):
        start = sl[name].start
        if name != "heave":
            G[start, start] = math.radians(m.offset_rate_deg_per_sqrt_s)
            start += 1
        for j, period in enumerate(m.periods_s):
            w, s = 2 * math.pi / period, sigma / math.sqrt(len(m.periods_s))
            b = start + 2 * j
            A[b, b + 1], A[b + 1, b], A[b + 1, b + 1] = 1.0, -w * w, -2 * m.damping_ratio * w
            G[b + 1, b + 1] = math.sqrt(4 * m.damping_ratio * w ** 3 * s * s)
    for name, q in (("yaw", math.radians(m.yaw_accel_deg_per_s2)), ("surge", m.surge_accel_m_per_s2),
                    ("sway", m.sway_accel_m_per_s2), ("uav_height", m.height_accel_m_per_s2)):
        A[sl[name].start, sl[name].start + 1] = 1.0
        G[sl[name].start + 1, sl[name].start + 1] = q
    F_ref, Q_ref = van_loan(A, G, dt)
    d = discretise(m, dt)
    np.testing.assert_allclose(d.F, F_ref, atol=EXPM_TOL)
    np.testing.assert_allclose(d.Q, Q_ref, atol=EXPM_TOL)
    assert not d.F.flags.writeable and not d.Q.flags.writeable


def test_measurement_and_output_matrices_read_the_channels():
    m = DeckMotionModel(periods_s=(7.0, 12.0))
    sl = state_slices(m)
    x = np.zeros(state_size(m))
    x[sl["roll"]] = [0.01, 0.02, 9.0, 0.03, 9.0]          # offset, (p, v), (p, v)
    x[sl["pitch"]] = [0.0, -0.01, 9.0, 0.005, 9.0]
    x[sl["heave"]] = [0.4, 0.1, 0.2, -0.3]
    x[sl["yaw"]], x[sl["surge"]], x[sl["sway"]], x[sl["uav_height"]] = [0.5, 9], [1.0, 9], [-2.0, 9], [40.0, 9]
    np.testing.assert_allclose(measurement_matrix(m) @ x, [0.06, -0.005, 0.5, 1.0, -2.0, 40.0 - 0.6])
    np.testing.assert_allclose(output_matrix(m) @ x, [0.06, -0.005, 0.6, -0.2, 40.0 - 0.6])


def test_prior_holds_the_oscillators_at_their_stationary_covariance():
    m = DeckMotionModel(periods_s=(8.0, 12.0))
    x0, P0 = prior(m)
    d = discretise(m, 0.1)
    P1 = d.F @ P0 @ d.F.T + d.Q
    sl = state_slices(m)
    b = slice(sl["roll"].start + 1, sl["heave"].stop)      # all oscillator blocks (between them the pitch offset)
    keep = [i for i in range(b.start, b.stop) if i != sl["pitch"].start]
    np.testing.assert_allclose(P1[np.ix_(keep, keep)], P0[np.ix_(keep, keep)], atol=1e-12)
    assert not x0.any()


@pytest.mark.parametrize("kwargs,match", [({"periods_s": ()}, "periods_s"), ({"damping_ratio": 1.0}, "damping_ratio"),
                                          ({"periods_s": (5.0, -1.0)}, "periods_s"),
                                          ({"heave_sigma_m": 0.0}, "heave_sigma_m")])
def test_bad_model_parameters_are_one_line_errors(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        DeckMotionModel(**kwargs)
