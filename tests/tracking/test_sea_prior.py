"""The bank fitted to a sea state, and the causal-filter bound, against independent computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from scipy.linalg import solve_discrete_are
from scipy.signal import freqs

from deckpose.errors import ConfigError
from deckpose.motion.config import parse_sea_run
from deckpose.motion.irregular import predicted_variances
from deckpose.tracking.config import TrackConfig, load_track_config, track_config_to_mapping
from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    channel_oscillators,
    discretise,
    oscillator_discretisation,
    state_size,
)
from deckpose.tracking.filter_bound import optimal_filtered_variance
from deckpose.tracking.sea_prior import (
    SeaPrior,
    encounter_spectra,
    fit_bank_sigmas,
    oscillator_density,
)


def _scipy_oscillator_density(omega, w0, zeta, sigma):
    """One-sided density of p'' + 2 zeta w0 p' + w0^2 p = w (two-sided white density q) via scipy's transfer function."""
    q = 4 * zeta * w0 ** 3 * sigma ** 2
    _, h = freqs([1.0], [1.0, 2 * zeta * w0, w0 ** 2], worN=omega)
    return q * np.abs(h) ** 2 / math.pi


def test_oscillator_density_is_the_transfer_function_and_has_unit_variance():
    omega = np.linspace(1e-4, 60.0, 600_001)
    for period, zeta in ((9.0, 0.02), (5.0, 0.1)):
        w0 = 2 * math.pi / period
        got = oscillator_density(omega, np.array([w0]), zeta)[:, 0]
        np.testing.assert_allclose(got, _scipy_oscillator_density(omega, w0, zeta, 1.0), rtol=1e-10)
        # unit variance: the integral over (0, 60] rad/s; the tail beyond holds ~q / (3 pi 60^3) < 1e-4
        assert np.trapezoid(got, omega) == pytest.approx(1.0, abs=2e-3)


def test_fit_recovers_the_sigmas_of_a_bank_spectrum():
    # the target is made from scipy's transfer functions, not from the fit's own basis
    periods, zeta = (6.0, 8.0, 10.0, 13.0), 0.05
    sig_true = np.array([0.0, 0.3, 1.0, 0.5])
    omega = np.linspace(0.005, 4 * 2 * math.pi / 6.0, 4000)
    dens = sum(_scipy_oscillator_density(omega, 2 * math.pi / p, zeta, s) for p, s in zip(periods, sig_true))
    got = fit_bank_sigmas(omega, dens, periods, zeta, 1e-6 * dens.max())
    # a floor of 1e-6 of the peak: the fit is exact where the bank can be; an oscillator the target
    # lacks comes out at most ~1e-3 of the others (its spectrum below the floor)
    np.testing.assert_allclose(got[1:], sig_true[1:], rtol=0.02)
    assert got[0] < 0.02


def test_encounter_spectra_hold_the_frequency_domain_variances():
    # deckpose.motion integrates |RAO|^2 S by Gauss-Legendre over wave frequency; ours bins on a grid
    prior = SeaPrior(sea_state=6)
    run = parse_sea_run({"sea": {"sea_state": 6, "heading_deg": 135.0, "speed_kn": 15.0}})
    ref = predicted_variances(run.ship, run.sea)
    omega = np.linspace(0.005, 12.0, 6000)
    spec = encounter_spectra(prior, omega)
    d = omega[1] - omega[0]
    # 20000 wave nodes over the band and linear binning: ~0.5 % of the variance
    assert spec["roll"].sum() * d == pytest.approx(ref.roll_rad2, rel=0.01)
    assert spec["pitch"].sum() * d == pytest.approx(ref.pitch_rad2, rel=0.01)
    assert spec["heave"].sum() * d == pytest.approx(ref.heave_m2, rel=0.01)


def test_bound_is_the_riccati_steady_state_of_the_true_model():
    # one oscillator measured in white noise: the Kalman filter built on the signal's own model
    # is optimal, so its steady-state filtered variance (discrete algebraic Riccati equation) is
    # the spectral bound (Kolmogorov-Szego), computed from the density alone
    dt, period, zeta, sigma = 0.1, 9.0, 0.1, 1.0
    w0 = 2 * math.pi / period
    F, Q = oscillator_discretisation(np.array([w0]), zeta, np.array([sigma]), dt)
    H = np.array([[1.0, 0.0]])
    omega = np.linspace(1e-5, math.pi / dt, 400_001)
    dens = _scipy_oscillator_density(omega, w0, zeta, sigma)
    for r in (1e-4, 1e-2, 0.5):
        P = solve_discrete_are(F[0].T, H.T, Q[0], np.array([[r]]))
        filt = P[0, 0] - P[0, 0] ** 2 / (P[0, 0] + r)
        got = optimal_filtered_variance(omega, dens, r, dt)[0]
        # the sampled process aliases the density's tail above pi / dt (~1e-6 of the variance here)
        # and the integral is on 65536 nodes: 1 %
        assert got == pytest.approx(filt, rel=0.01), r


def test_a_filter_told_the_signal_spectrum_reaches_the_bound_on_simulated_data():
    # a lightly damped oscillator (a near-sinusoid of random amplitude and phase) in white noise,
    # filtered by the deck filter's own discretisation; 40000 steps: the RMS error's sampling
    # error is ~1 % (correlated errors over ~10 steps), so 5 % is ~4 sigmas
    dt, period, zeta, sigma, r = 0.1, 10.0, 0.03, 1.0, 0.05 ** 2
    w0 = 2 * math.pi / period
    F, Q = (a[0] for a in oscillator_discretisation(np.array([w0]), zeta, np.array([sigma]), dt))
    rng = np.random.default_rng(5)
    n = 40_000
    x = rng.multivariate_normal(np.zeros(2), np.diag([sigma ** 2, (w0 * sigma) ** 2]))
    xe, P = np.zeros(2), np.diag([sigma ** 2, (w0 * sigma) ** 2])
    err = np.empty(n)
    L = np.linalg.cholesky(Q)
    for k in range(n):
        x = F @ x + L @ rng.normal(size=2)
        y = x[0] + math.sqrt(r) * rng.normal()
        xe, P = F @ xe, F @ P @ F.T + Q
        K = P[:, 0] / (P[0, 0] + r)
        xe = xe + K * (y - xe[0])
        P = P - np.outer(K, P[0])
        err[k] = xe[0] - x[0]
    omega = np.linspace(1e-5, math.pi / dt, 400_001)
    bound = optimal_filtered_variance(omega, _scipy_oscillator_density(omega, w0, zeta, sigma), r, dt)[0]
    rms = float(np.sqrt(np.mean(err[1000:] ** 2)))
    assert rms == pytest.approx(math.sqrt(bound), rel=0.05)


def test_a_config_told_the_sea_fits_the_bank_and_reads_back_the_same(tmp_path):
    model = DeckMotionModel(periods_s=(6.0, 8.0, 10.0, 12.0, 16.0, 30.0), damping_ratio=0.05)
    cfg = TrackConfig(model=model, sea=SeaPrior(sea_state=6))
    m = cfg.model
    assert len(m.roll_bank_sigmas_deg) == 6 and m.roll_sigma_deg == pytest.approx(math.hypot(*m.roll_bank_sigmas_deg))
    # the fitted bank's variance is of the sea's order (a Whittle fit of a bank whose tails are
    # heavier than the sea's keeps less than all of it), and its energy sits near the sea's periods
    run = parse_sea_run({"sea": {"sea_state": 6}})
    ref = predicted_variances(run.ship, run.sea)
    assert 0.3 < math.radians(m.roll_sigma_deg) / math.sqrt(ref.roll_rad2) < 1.2
    # the heave bank keeps the sea's variance (SeaPrior.keep_variance); the encounter spectra
    # integrate to motion's own quadrature within ~0.5 % (test above), so 1 %
    assert m.heave_sigma_m == pytest.approx(math.sqrt(ref.heave_m2), rel=0.01)
    assert math.hypot(*m.heave_bank_sigmas_m) == pytest.approx(m.heave_sigma_m, rel=1e-12)
    roll = np.asarray(m.roll_bank_sigmas_deg)
    assert model.periods_s[int(np.argmax(roll))] in (10.0, 12.0)
    assert roll[-1] < 0.01 * roll.max()                   # nothing at 30 s
    # oscillators pruned to sigma 0 are not in the state
    n_active = sum(len(om) for om, _ in channel_oscillators(m).values())
    assert state_size(m) == 2 + 2 * n_active + 8
    assert discretise(m, 0.1).F.shape == (state_size(m),) * 2
    path = tmp_path / "t.yaml"
    path.write_text(yaml.safe_dump(track_config_to_mapping(cfg)))
    assert load_track_config(path) == cfg


@pytest.mark.parametrize("text,match", [
    ("sea: {sea_state: 12}\n", "sea"),
    ("sea: {sea_state: 6, floor_rel: 2}\n", "floor_rel"),
    ("sea: {sea_state: 6, ship: dinghy}\n", "dinghy"),
    ("sea: {sea_state: 6, keep_variance: [yaw]}\n", "keep_variance"),
    ("model: {periods_s: [8, 11], roll_bank_sigmas_deg: [1]}\n", "roll_bank_sigmas_deg"),
])
def test_bad_sea_configs_are_one_line_errors(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as e:
        load_track_config(path)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("name,state", [("sea_state_6.yaml", 6), ("sea_state_4.yaml", 4)])
def test_the_committed_sea_configs_fit_their_sea(name, state):
    from pathlib import Path

    cfg = load_track_config(Path(__file__).resolve().parents[2] / "configs" / "track" / name)
    assert cfg.sea is not None and cfg.sea.sea_state == state
    m = cfg.model
    assert len(m.roll_bank_sigmas_deg) == len(m.periods_s) == 24
    run = parse_sea_run({"sea": {"sea_state": state, "heading_deg": 135.0, "speed_kn": 15.0}})
    ref = predicted_variances(run.ship, run.sea)
    assert m.heave_sigma_m == pytest.approx(math.sqrt(ref.heave_m2), rel=0.01)   # keep_variance: heave
