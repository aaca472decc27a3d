import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deckpose.errors import ConfigError
from deckpose.motion.filtered_noise import FilteredNoise
from deckpose.motion.irregular import (
    IrregularSea,
    irregular_series,
    predicted_variances,
    series_significant_amplitudes,
    ss6_frigate_sea,
    wave_components,
)
from deckpose.motion.offset import motion_at_offset
from deckpose.motion.plot import channel_psd
from deckpose.motion.series import MotionSeries
from deckpose.motion.ship import ffg7_ship, thesis_ship
from deckpose.motion.spectrum import SpectrumKind, spectrum_for_sea_state

#: The issue's tolerance on the variance of a long seeded series vs the frequency-domain value.
VARIANCE_REL_TOL = 0.05
QUIET = FilteredNoise(0.0, 10.0)
THREE_HOURS_S = 3 * 3600.0


def _long(ship, sea, seed=11):
    return irregular_series(ship, sea, duration_s=THREE_HOURS_S, dt_s=0.5, rng=np.random.default_rng(seed))


@pytest.mark.parametrize("ship, state, kind, heading_deg, speed_kn", [
    (ffg7_ship(), 6, SpectrumKind.JONSWAP, 135.0, 15.0),
    (ffg7_ship(), 5, SpectrumKind.PIERSON_MOSKOWITZ, 60.0, 10.0),
    (thesis_ship(), 4, SpectrumKind.JONSWAP, 160.0, 0.0),
])
def test_variance_matches_frequency_domain(ship, state, kind, heading_deg, speed_kn):
    sea = IrregularSea(spectrum_for_sea_state(state, kind=kind), math.radians(heading_deg),
                       speed_kn / 1.94384, yaw=QUIET, surge=QUIET, sway=QUIET)
    s = _long(ship, sea)
    v = predicted_variances(ship, sea)
    assert np.var(s.heave_m) == pytest.approx(v.heave_m2, rel=VARIANCE_REL_TOL)
    assert np.var(s.pitch_rad) == pytest.approx(v.pitch_rad2, rel=VARIANCE_REL_TOL)
    assert np.var(s.roll_rad) == pytest.approx(v.roll_rad2, rel=VARIANCE_REL_TOL)


def test_roll_spectrum_peaks_at_the_roll_period_not_the_wave_peak():
    ship = ffg7_ship()  # roll period 11.0 s
    sea = IrregularSea(spectrum_for_sea_state(4), math.radians(100.0), 0.0)  # Tp 8.8 s
    s = _long(ship, sea)
    w, p = channel_psd(s.t_s, s.roll_rad)
    w_roll = 2 * math.pi / ship.roll_period_s
    w_peak = w[np.argmax(p)]
    assert w_peak == pytest.approx(w_roll, rel=0.08)
    assert abs(w_peak - w_roll) < 0.5 * abs(sea.spectrum.omega_peak_rad_s - w_roll)
    wh, ph = channel_psd(s.t_s, s.heave_m)  # heave follows the waves
    assert wh[np.argmax(ph)] == pytest.approx(sea.spectrum.omega_peak_rad_s, rel=0.08)


def test_same_seed_same_series_other_seed_other_series():
    sea = ss6_frigate_sea()
    a = irregular_series(ffg7_ship(), sea, duration_s=120.0, dt_s=0.1, rng=np.random.default_rng(5))
    b = irregular_series(ffg7_ship(), sea, duration_s=120.0, dt_s=0.1, rng=np.random.default_rng(5))
    c = irregular_series(ffg7_ship(), sea, duration_s=120.0, dt_s=0.1, rng=np.random.default_rng(6))
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert not np.allclose(getattr(a, name), getattr(c, name))


def test_components_are_jittered_and_never_repeat_on_a_grid():
    comps = wave_components(spectrum_for_sea_state(6), 600, np.random.default_rng(0))
    dw = np.diff(comps.omega_rad_s)
    assert np.all(dw > 0) and np.std(dw) > 0.1 * np.mean(dw)
    assert np.all((comps.phase_rad >= 0) & (comps.phase_rad < 2 * math.pi))


def test_ss6_frigate_preset_is_in_the_published_range():
    ship, sea = ffg7_ship(), ss6_frigate_sea()
    assert sea.spectrum.hs_m == 5.0 and sea.spectrum.tp_s == 12.4
    assert math.degrees(sea.heading_rad) == pytest.approx(135.0)
    predicted = predicted_variances(ship, sea).significant_amplitudes()
    measured = series_significant_amplitudes(_long(ship, sea))
    for sig in (predicted, measured):  # significant single amplitudes, 2 sigma
        assert 3.0 <= sig["roll_deg"] <= 10.5, sig
        assert 2.0 <= sig["pitch_deg"] <= 3.5, sig
        assert 1.4 <= sig["heave_m"] <= 3.0, sig


def test_default_yaw_and_drift_have_their_sigmas():
    sea = IrregularSea(spectrum_for_sea_state(6), math.pi, n_components=16)  # default yaw and drift
    s = irregular_series(ffg7_ship(), sea, duration_s=20 * 3600.0, dt_s=1.0, rng=np.random.default_rng(2))
    assert np.degrees(np.std(s.yaw_rad)) == pytest.approx(1.0, rel=0.1)
    assert np.std(s.surge_m) == pytest.approx(0.5, rel=0.1)
    assert np.std(s.sway_m) == pytest.approx(0.5, rel=0.1)


def test_offset_point_heave_adds_pitch_lever():
    # The closed form puts pitch in quadrature with heave, so a point x metres along the
    # ship heaves with variance var(heave) + x^2 var(pitch) (small angles).
    ship = ffg7_ship()
    x_m = -40.0
    sea = IrregularSea(spectrum_for_sea_state(6), math.pi, 5.0, yaw=QUIET, surge=QUIET, sway=QUIET,
                       deck_offset_m=(x_m, 0.0, 0.0))
    s = _long(ship, sea)
    v = predicted_variances(ship, sea)
    assert np.var(s.heave_m) == pytest.approx(v.heave_m2 + x_m**2 * v.pitch_rad2, rel=VARIANCE_REL_TOL)
    assert np.var(s.heave_m) > 1.3 * v.heave_m2


def test_motion_at_offset_is_a_rigid_transform():
    rng = np.random.default_rng(1)
    n = 20
    s = MotionSeries(np.arange(n) * 0.1, *(rng.normal(0, 0.2, n) for _ in range(3)),
                     heave_m=rng.normal(size=n), surge_m=rng.normal(size=n), sway_m=rng.normal(size=n))
    p = np.array([-30.0, 2.0, 5.0])
    moved = motion_at_offset(s, p)
    R = Rotation.from_euler("ZYX", np.c_[s.yaw_rad, s.pitch_rad, s.roll_rad]).as_matrix()
    want = np.c_[s.surge_m, s.sway_m, s.heave_m] + R @ p - p
    np.testing.assert_allclose(np.c_[moved.surge_m, moved.sway_m, moved.heave_m], want, atol=1e-12)
    np.testing.assert_array_equal(moved.roll_rad, s.roll_rad)
    with pytest.raises(ConfigError, match="3 finite"):
        motion_at_offset(s, [1.0, 2.0])


def test_bad_irregular_parameters():
    spec = spectrum_for_sea_state(6)
    with pytest.raises(ConfigError, match="speed"):
        IrregularSea(spec, math.pi, -1.0)
    with pytest.raises(ConfigError, match="n_components"):
        IrregularSea(spec, math.pi, n_components=3)
    with pytest.raises(ConfigError, match="deck_offset_m"):
        IrregularSea(spec, math.pi, deck_offset_m=(0.0, float("nan"), 0.0))
    with pytest.raises(ConfigError, match="time step"):
        irregular_series(ffg7_ship(), IrregularSea(spec, math.pi), duration_s=10.0, dt_s=0.0,
                         rng=np.random.default_rng(0))
    with pytest.raises(ConfigError, match="duration"):
        irregular_series(ffg7_ship(), IrregularSea(spec, math.pi), duration_s=-5.0, dt_s=0.1,
                         rng=np.random.default_rng(0))
