"""Prediction ahead and the landing window against theory and brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm

from deckpose.errors import ConfigError
from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    discretise,
    prior,
    state_size,
    state_slices,
)
from deckpose.tracking.landing_window import (
    LandingLimits,
    landing_window_go,
    truth_window_calm,
    window_calm_probability,
    window_horizons_s,
)
from deckpose.tracking.prediction import predict_outputs

MODEL = DeckMotionModel(periods_s=(9.0,), damping_ratio=0.15, heave_sigma_m=1.2)
#: quad's absolute error on these smooth integrands is ~1e-12 of the variance scale.
QUAD_RTOL = 1e-8


def _heave_state(p: float, v: float) -> np.ndarray:
    x = np.zeros(state_size(MODEL))
    sl = state_slices(MODEL)["heave"]
    x[sl.start], x[sl.start + 1] = p, v
    return x


def test_prediction_mean_is_the_free_response():
    w, z = 2 * math.pi / 9.0, 0.15
    A = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    x = _heave_state(0.8, -0.3)
    hs = np.array([0.0, 0.5, 1.0, 2.0, 5.0])
    mean, _ = predict_outputs(x[None], np.zeros((1, len(x), len(x))), MODEL, hs)
    ref = np.array([expm(A * h) @ [0.8, -0.3] for h in hs])
    np.testing.assert_allclose(mean[0, :, 2:4], ref, atol=1e-12)  # heave, heave rate
    np.testing.assert_allclose(mean[0, :, 4], -ref[:, 0], atol=1e-12)  # height: uav_height 0 - heave
    np.testing.assert_allclose(mean[0, :, :2], 0.0, atol=1e-15)    # roll, pitch untouched


def test_prediction_variance_from_a_known_state_is_the_impulse_response_integral():
    # from an exactly known state, var p(h) = q int_0^h g(s)^2 ds with the impulse response
    # g(s) = e^{-zeta w s} sin(w_d s) / w_d and q = 4 zeta w^3 sigma^2 (stationary var sigma^2)
    w, z, sigma = 2 * math.pi / 9.0, 0.15, 1.2
    wd = w * math.sqrt(1 - z * z)
    q = 4 * z * w ** 3 * sigma ** 2
    n = state_size(MODEL)
    hs = np.array([0.5, 1.0, 2.0, 5.0, 20.0, 200.0])
    _, cov = predict_outputs(np.zeros((1, n)), np.zeros((1, n, n)), MODEL, hs)
    var = cov[0, :, 2, 2]
    ref = [q * quad(lambda s: (math.exp(-z * w * s) * math.sin(wd * s) / wd) ** 2, 0, h, limit=400)[0]
           for h in hs]
    np.testing.assert_allclose(var, ref, rtol=QUAD_RTOL)
    assert np.all(np.diff(var) > 0)                          # grows with the horizon
    assert var[-1] == pytest.approx(sigma ** 2, rel=1e-6)    # ... to the stationary variance


def test_prediction_of_a_posterior_propagates_its_covariance():
    # batch of two states: the prior itself (stationary: its output variance stays sigma^2 at any
    # horizon) and a sharp one
    x0, P0 = prior(MODEL)
    P_sharp = P0 * 1e-4
    _, cov = predict_outputs(np.stack([x0, x0]), np.stack([P0, P_sharp]), MODEL, np.array([0.0, 1.0, 3.0]))
    np.testing.assert_allclose(cov[0, :, 2, 2], 1.2 ** 2, rtol=1e-9)
    assert cov[1, 0, 2, 2] == pytest.approx(1.2 ** 2 * 1e-4) and np.all(np.diff(cov[1, :, 2, 2]) > 0)


def test_truth_window_calm_is_brute_force():
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.05, 0.2, 300))
    roll = np.radians(3.5) * np.sin(0.6 * t)
    pitch = np.radians(1.0) * np.sin(0.9 * t + 1)
    hr = 0.6 * np.sin(0.7 * t + 2)
    lim = LandingLimits(roll_deg=3.0, pitch_deg=2.0, heave_rate_m_per_s=0.5, window_s=2.0)
    got = truth_window_calm(t, roll, pitch, hr, lim)
    for i in range(len(t)):
        if t[i] + 2.0 > t[-1]:
            assert np.isnan(got[i])
            continue
        w = (t >= t[i]) & (t <= t[i] + 2.0)
        calm = np.all((np.abs(roll[w]) < math.radians(3)) & (np.abs(pitch[w]) < math.radians(2))
                      & (np.abs(hr[w]) < 0.5))
        assert got[i] == float(calm), i
    assert 0 < np.nanmean(got) < 1                     # both answers occur


def test_landing_window_says_go_only_with_margin():
    # a calm sea (heave sigma 0.1 m: stationary heave-rate sigma 0.07 m/s, roll 0.5 deg, pitch 0.3 deg)
    model = DeckMotionModel(periods_s=(9.0,), damping_ratio=0.15, heave_sigma_m=0.1, roll_sigma_deg=0.5,
                            pitch_sigma_deg=0.3)
    n = state_size(model)
    lim = LandingLimits(roll_deg=3.0, pitch_deg=2.0, heave_rate_m_per_s=0.5, window_s=3.0, confidence=0.9)
    P_small = np.eye(n) * 1e-10
    sl = state_slices(model)["heave"]
    calm, rough = np.zeros(n), np.zeros(n)
    rough[sl.start + 1] = 0.9                          # heave rate 0.9 m/s now
    go = landing_window_go(np.stack([calm, rough]), np.stack([P_small, P_small]), model, lim)
    assert go.tolist() == [True, False]
    # the same calm state in MODEL's sea (heave sigma 1.2 m, heave-rate sigma 0.84 m/s): within
    # 3 s the heave rate leaves +-0.5 m/s with probability near 1
    assert not landing_window_go(np.zeros((1, state_size(MODEL))), np.zeros((1, state_size(MODEL),
                                                                                state_size(MODEL))), MODEL, lim)[0]
    x0, P0 = prior(model)
    lim_tight = LandingLimits(heave_rate_m_per_s=0.1, confidence=0.9)
    assert not landing_window_go(x0[None], P0[None], model, lim_tight)[0]   # P(|N(0, 0.07)| < 0.1) = 0.85 < 0.9
    assert window_horizons_s(lim).tolist() == [0.25 * k for k in range(13)]


def test_window_probability_is_brute_force_simulation():
    # Independent check: draw whole trajectories from the state's Gaussian, step them through the
    # model's one-step F and Q over the window's grid, count the share that stays within the
    # limits at every grid time. 20000 draws: binomial standard error <= 0.0036; the scrambled-QMC
    # estimate's own error is ~0.003 here (seen across scrambling seeds), so 0.02 is > 4 combined sigmas.
    model = DeckMotionModel(periods_s=(7.0, 11.0), damping_ratio=0.1, heave_sigma_m=0.4, roll_sigma_deg=2.0,
                            pitch_sigma_deg=1.0)
    lim = LandingLimits(roll_deg=3.0, pitch_deg=1.5, heave_rate_m_per_s=0.5, window_s=2.0, step_s=0.5,
                        confidence=0.5)
    n = state_size(model)
    x0, P0 = prior(model)
    rng = np.random.default_rng(3)
    P1 = 0.05 * P0 + np.diag(np.full(n, 1e-8))
    x1 = 0.3 * rng.multivariate_normal(np.zeros(n), P0)          # some state the sea could be in
    got = window_calm_probability(np.stack([x0, x1]), np.stack([0.3 * P0, P1]), model, lim)
    d = discretise(model, lim.step_s)
    sl = state_slices(model)
    idx = [sl["roll"].start, sl["roll"].start + 1, sl["roll"].start + 3]   # offset + the two oscillators
    for k, (x, P) in enumerate(((x0, 0.3 * P0), (x1, P1))):
        s = rng.multivariate_normal(x, P, size=20000)
        inside = np.ones(len(s), bool)
        for step in range(len(window_horizons_s(lim))):
            if step:
                s = s @ d.F.T + rng.multivariate_normal(np.zeros(n), d.Q, size=len(s))
            roll = s[:, idx].sum(axis=1)
            pitch = s[:, sl["pitch"].start] + s[:, sl["pitch"].start + 1] + s[:, sl["pitch"].start + 3]
            heave_rate = s[:, sl["heave"].start + 1] + s[:, sl["heave"].start + 3]
            inside &= ((np.abs(roll) < math.radians(3.0)) & (np.abs(pitch) < math.radians(1.5))
                       & (np.abs(heave_rate) < 0.5))
        assert abs(got[k] - inside.mean()) < 0.02, (k, got[k], inside.mean())
    assert 0.02 < got.min() and got.max() < 0.98          # neither trivially 0 nor 1


@pytest.mark.parametrize("kwargs", [{"window_s": 0.0}, {"step_s": 5.0}, {"confidence": 1.0},
                                    {"roll_deg": math.nan}])
def test_bad_limits_are_refused(kwargs):
    with pytest.raises(ConfigError):
        LandingLimits(**kwargs)
