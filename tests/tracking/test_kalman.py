"""The Kalman filter against independent computations of the optimal linear-Gaussian answer.

* the whole sequence filter against the posterior of the joint Gaussian of all states and
  measurements, conditioned in one dense solve (no recursion);
* the covariance's steady state against the discrete algebraic Riccati equation
  (``scipy.linalg.solve_discrete_are``);
* consistency (NIS and the filtered error's Mahalanobis distance) on data drawn from the model;
* the gate rejecting a planted outlier.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    discretise,
    measurement_matrix,
    prior,
    state_size,
)
from deckpose.tracking.kalman import kalman_predict, kalman_update
from deckpose.tracking.sequence_filter import FilterStatus, filter_sequence, gate_nis

#: Recursive filter against one dense conditioning of a ~200-dimensional Gaussian: both are
#: exact; their difference is round-off amplified by the conditioning of the prior
#: covariance (position sigma 100 m against mrad oscillators, about 1e10): relative 1e-6.
DENSE_RTOL = 1e-6


def _small_model() -> DeckMotionModel:
    return DeckMotionModel(periods_s=(9.0,), damping_ratio=0.1, position_sigma_m=20.0, rate_sigma_m_per_s=2.0,
                           yaw_sigma_deg=20.0)


def _simulate(model: DeckMotionModel, t_s: np.ndarray, R: np.ndarray, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray]:
    """States drawn from the model (prior, then F x + w) and measurements H x + v."""
    x0, P0 = prior(model)
    x = rng.multivariate_normal(x0, P0)
    H = measurement_matrix(model)
    xs, zs = [], []
    for i, t in enumerate(t_s):
        if i:
            d = discretise(model, float(t - t_s[i - 1]))
            x = d.F @ x + rng.multivariate_normal(np.zeros(len(x)), d.Q, method="eigh")
        xs.append(x)
        zs.append(H @ x + rng.multivariate_normal(np.zeros(6), R[i]))
    return np.array(xs), np.array(zs)


def _meas_cov(n: int, rng: np.random.Generator) -> np.ndarray:
    """Full, different measurement covariances (radians, metres), correlated like an estimate's."""
    scale = np.array([2e-3, 2e-3, 4e-3, 0.05, 0.05, 0.08])
    out = []
    for _ in range(n):
        a = rng.normal(size=(6, 6)) * 0.3 + np.eye(6)
        out.append(np.diag(scale) @ (a @ a.T) @ np.diag(scale))
    return np.array(out)


def _dense_posterior(model: DeckMotionModel, t_s: np.ndarray, z: np.ndarray, R: np.ndarray, usable: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the last state given all usable measurements, by one Gaussian conditioning.

    X = [x_0 .. x_{N-1}] = L [x_0, w_1 .. w_{N-1}] with L built from the transitions; its
    covariance is L blockdiag(P0, Q_1, ...) L^T. Y = blockdiag(H) X + v. Then
    E[X | Y] = m + C_XY C_YY^-1 (Y - E Y).
    """
    n, N = state_size(model), len(t_s)
    x0, P0 = prior(model)
    H = measurement_matrix(model)
    Fs = [np.eye(n)] + [discretise(model, float(t_s[i] - t_s[i - 1])).F for i in range(1, N)]
    Qs = [P0] + [discretise(model, float(t_s[i] - t_s[i - 1])).Q for i in range(1, N)]
    L = np.zeros((N * n, N * n))
    for i in range(N):
        for j in range(i + 1):
            Phi = np.eye(n)
            for k in range(j + 1, i + 1):
                Phi = Fs[k] @ Phi
            L[i * n:(i + 1) * n, j * n:(j + 1) * n] = Phi
    S = np.zeros((N * n, N * n))
    for j in range(N):
        S[j * n:(j + 1) * n, j * n:(j + 1) * n] = Qs[j]
    mean = L @ np.concatenate([x0] + [np.zeros(n)] * (N - 1))
    cov = L @ S @ L.T
    rows = [i for i in range(N) if usable[i]]
    Hb = np.zeros((6 * len(rows), N * n))
    Rb = np.zeros((6 * len(rows), 6 * len(rows)))
    for r, i in enumerate(rows):
        Hb[6 * r:6 * r + 6, i * n:(i + 1) * n] = H
        Rb[6 * r:6 * r + 6, 6 * r:6 * r + 6] = R[i]
    y = np.concatenate([z[i] for i in rows])
    Cxy = cov @ Hb.T
    Cyy = Hb @ cov @ Hb.T + Rb
    gain = np.linalg.solve(Cyy, Cxy.T).T
    post_mean = mean + gain @ (y - Hb @ mean)
    post_cov = cov - gain @ Cxy.T
    last = slice((N - 1) * n, N * n)
    return post_mean[last], post_cov[last, last]


def test_sequence_filter_equals_the_dense_joint_gaussian_posterior():
    rng = np.random.default_rng(3)
    model = _small_model()
    t_s = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.4, 11)])       # irregular steps
    R = _meas_cov(len(t_s), rng)
    _, z = _simulate(model, t_s, R, rng)
    usable = np.ones(len(t_s), bool)
    usable[[4, 5, 9]] = False                                      # not ok: prediction only
    track = filter_sequence(t_s, z, R, usable, model, gate_probability=1.0)
    mean, cov = _dense_posterior(model, t_s, z, R, usable)
    scale = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(track.x[-1] / scale, mean / scale, atol=DENSE_RTOL * 10)
    np.testing.assert_allclose(track.P[-1], cov, rtol=DENSE_RTOL, atol=DENSE_RTOL * np.outer(scale, scale).max())
    assert [s for s in track.status] == [FilterStatus.SKIPPED if not u else FilterStatus.UPDATED for u in usable]


def test_covariance_converges_to_the_riccati_steady_state():
    # a 2-state near-constant-velocity target measured in position at a fixed rate: the
    # predicted covariance's fixed point is the discrete algebraic Riccati equation's solution
    dt, q, r = 0.1, 0.7, 0.04
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q ** 2 * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    H, R = np.array([[1.0, 0.0]]), np.array([[r]])
    P_pred_ss = solve_discrete_are(F.T, H.T, Q, R)
    x, P = np.zeros(2), np.eye(2) * 100.0
    for _ in range(400):
        x, P = kalman_predict(x, P, F, Q)
        P_pred = P
        up = kalman_update(x, P, np.array([0.0]), R, H)
        x, P = up.x, up.P
    np.testing.assert_allclose(P_pred, P_pred_ss, rtol=1e-9)
    # and the updated covariance is the steady state's measurement update, in information form
    np.testing.assert_allclose(P, np.linalg.inv(np.linalg.inv(P_pred_ss) + H.T @ np.linalg.inv(R) @ H), rtol=1e-9)


def test_filter_is_consistent_on_data_drawn_from_its_model():
    # NIS of an optimal filter is chi-square with 6 dof: mean 6, variance 12; over 300 frames
    # the sample mean has sigma sqrt(12/300) = 0.2: 4 sigma is 0.8. Likewise the filtered
    # pose's squared Mahalanobis error (truth in its own covariance).
    rng = np.random.default_rng(11)
    model = DeckMotionModel(periods_s=(7.0, 12.0))
    t_s = 0.1 * np.arange(300)
    R = _meas_cov(len(t_s), rng)
    xs, z = _simulate(model, t_s, R, rng)
    track = filter_sequence(t_s, z, R, np.ones(len(t_s), bool), model, gate_probability=1.0)
    assert abs(np.mean(track.nis) - 6.0) < 0.8
    H = measurement_matrix(model)
    err = (track.x - xs) @ H.T
    cov = np.einsum("in,Nnm,jm->Nij", H, track.P, H)
    m2 = np.einsum("Ni,Ni->N", err, np.linalg.solve(cov, err[..., None])[..., 0])
    assert abs(np.mean(m2) - 6.0) < 0.8 * 2  # errors of successive frames correlate: twice the margin


def test_gate_rejects_a_planted_outlier_and_keeps_the_prediction():
    rng = np.random.default_rng(5)
    model = DeckMotionModel(periods_s=(8.0, 11.0))
    t_s = 0.1 * np.arange(80)
    R = _meas_cov(len(t_s), rng)
    _, z = _simulate(model, t_s, R, rng)
    z_bad = z.copy()
    z_bad[50, 0] += math.radians(5.0)            # 5 deg of roll: ~40 of the estimate's sigmas
    clean = filter_sequence(t_s, z, R, np.ones(len(t_s), bool), model)
    track = filter_sequence(t_s, z_bad, R, np.ones(len(t_s), bool), model)
    assert track.status[50] is FilterStatus.GATED and track.nis[50] > gate_nis(0.9999)
    assert all(s is FilterStatus.UPDATED for i, s in enumerate(track.status) if i != 50)
    # the gated frame's state is the prediction from frame 49: what the clean filter had before its update
    d = discretise(model, 0.1)
    x_pred, P_pred = kalman_predict(clean.x[49], clean.P[49], d.F, d.Q)
    np.testing.assert_allclose(track.x[50], x_pred, atol=1e-12)
    np.testing.assert_allclose(track.P[50], P_pred, atol=1e-15)
    # with no gate the outlier pulls the roll off
    ungated = filter_sequence(t_s, z_bad, R, np.ones(len(t_s), bool), model, gate_probability=1.0)
    H = measurement_matrix(model)
    assert abs((ungated.x[50] - clean.x[50]) @ H[0]) > 10 * abs((track.x[50] - clean.x[50]) @ H[0])


def test_the_filter_reacquires_after_a_run_of_gated_estimates():
    rng = np.random.default_rng(8)
    model = DeckMotionModel(periods_s=(8.0,))
    t_s = 0.1 * np.arange(40)
    R = _meas_cov(len(t_s), rng)
    _, z = _simulate(model, t_s, R, rng)
    z[20:, 3] += 30.0                              # the deck "jumps" 30 m: a real change, not an outlier
    track = filter_sequence(t_s, z, R, np.ones(len(t_s), bool), model, reacquire_after=5)
    assert [s.value for s in track.status[20:26]] == ["gated"] * 5 + ["updated"]


def test_yaw_innovation_is_wrapped():
    model = _small_model()
    x, P = prior(model)
    H = measurement_matrix(model)
    x = x.copy()
    x[np.flatnonzero(H[2])[0]] = math.pi - 0.01
    R = np.diag([1e-4] * 6)
    up = kalman_update(x, P, np.array([0, 0, -math.pi + 0.01, 0, 0, 0]), R, H, angle_rows=(2,))
    assert abs((up.x @ H[2]) - (math.pi - 0.01)) < 0.03   # moved by the wrapped 0.02 rad, not by 2 pi


@pytest.mark.parametrize("bad", ["shape", "order"])
def test_bad_sequences_are_refused(bad):
    model = _small_model()
    t_s = np.array([0.0, 0.1, 0.2]) if bad == "shape" else np.array([0.0, 0.2, 0.1])
    n = 2 if bad == "shape" else 3
    with pytest.raises(ValueError):
        filter_sequence(t_s, np.zeros((n, 6)), np.tile(np.eye(6), (n, 1, 1)), np.ones(n, bool), model)
