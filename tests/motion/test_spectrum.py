import itertools
import math

import numpy as np
import pytest
from scipy import integrate

from deckpose.errors import ConfigError
from deckpose.motion.spectrum import (
    SEA_STATES,
    SpectrumKind,
    WaveSpectrum,
    sea_state_row,
    spectrum_for_sea_state,
)


def _m0(spec: WaveSpectrum) -> float:
    wp = spec.omega_peak_rad_s
    return sum(integrate.quad(spec.density, a, b, limit=400)[0]
               for a, b in [(0.0, 0.8 * wp), (0.8 * wp, 1.3 * wp), (1.3 * wp, math.inf)])


@pytest.mark.parametrize("kind", list(SpectrumKind))
@pytest.mark.parametrize("hs, tp", [(5.0, 12.4), (1.0, 6.0), (12.0, 17.0)])
def test_spectrum_holds_hs(kind, hs, tp):
    spec = WaveSpectrum(hs, tp, kind)
    assert 4.0 * math.sqrt(_m0(spec)) == pytest.approx(hs, rel=1e-7)


@pytest.mark.parametrize("kind", list(SpectrumKind))
def test_spectrum_peaks_at_tp(kind):
    spec = WaveSpectrum(5.0, 12.4, kind)
    w = np.linspace(0.1, 2.0, 19001)
    assert w[np.argmax(spec.density(w))] == pytest.approx(2 * math.pi / 12.4, abs=2e-4)


def test_pierson_moskowitz_formula_and_jonswap_peak():
    hs, tp = 4.0, 10.0
    wp = 2 * math.pi / tp
    w = np.array([0.3, wp, 1.1])
    pm = WaveSpectrum(hs, tp, SpectrumKind.PIERSON_MOSKOWITZ).density(w)
    np.testing.assert_allclose(pm, 5 / 16 * hs**2 * wp**4 * w**-5 * np.exp(-1.25 * (wp / w) ** 4), rtol=1e-12)
    js = WaveSpectrum(hs, tp, SpectrumKind.JONSWAP, gamma=3.3).density(w)
    # Same m0 with a peak enhanced by gamma: JONSWAP/PM at the peak is gamma / (normalisation ~ 1.5-2).
    assert 1.5 < js[1] / pm[1] < 2.5
    assert WaveSpectrum(hs, tp, SpectrumKind.JONSWAP, gamma=1.0).density(w) == pytest.approx(pm, rel=1e-12)


def test_band_holds_the_energy():
    spec = spectrum_for_sea_state(6)
    lo, hi = spec.band_rad_s()
    inside = integrate.quad(spec.density, lo, hi, limit=400, points=[spec.omega_peak_rad_s])[0]
    assert inside / (spec.hs_m**2 / 16) > 0.998


def test_sea_state_table():
    assert [r.code for r in SEA_STATES] == list(range(1, 10))
    for lower, upper in itertools.pairwise(SEA_STATES):
        assert lower.hs_max_m == upper.hs_min_m  # ranges tile
    for r in SEA_STATES:
        assert r.hs_min_m <= r.hs_default_m <= r.hs_max_m and r.tp_default_s > 0
    s6 = sea_state_row(6)
    assert (s6.hs_min_m, s6.hs_max_m, s6.hs_default_m, s6.tp_default_s) == (4.0, 6.0, 5.0, 12.4)
    spec = spectrum_for_sea_state(6, hs_m=4.5, tp_s=10.0, kind=SpectrumKind.PIERSON_MOSKOWITZ)
    assert (spec.hs_m, spec.tp_s, spec.kind) == (4.5, 10.0, SpectrumKind.PIERSON_MOSKOWITZ)


@pytest.mark.parametrize("code", [0, 10, -1, 2.5, True, "6"])
def test_sea_state_outside_1_to_9(code):
    with pytest.raises(ConfigError, match="1 to 9"):
        spectrum_for_sea_state(code)


def test_bad_heights_and_periods():
    with pytest.raises(ConfigError, match="> 0 m"):
        spectrum_for_sea_state(6, hs_m=-2.0)
    with pytest.raises(ConfigError, match="outside sea state 6"):
        spectrum_for_sea_state(6, hs_m=2.0)
    with pytest.raises(ConfigError, match="> 0 m"):
        WaveSpectrum(-1.0, 10.0)
    with pytest.raises(ConfigError, match="peak period"):
        WaveSpectrum(1.0, 0.0)
    with pytest.raises(ConfigError, match="gamma"):
        WaveSpectrum(1.0, 8.0, gamma=0.5)


def test_sea_states_are_half_open_so_every_height_has_one():
    # Closed at both ends, 2.5 m was both sea state 4 and 5.
    from deckpose.motion.spectrum import sea_state_of

    for r in SEA_STATES[:-1]:
        assert sea_state_of(r.hs_max_m).code == r.code  # a boundary belongs to the lower state
        assert sea_state_of(np.nextafter(r.hs_max_m, np.inf)).code == r.code + 1
    for hs in np.concatenate([np.linspace(0.01, 30.0, 3001), [r.hs_max_m for r in SEA_STATES[:-1]]]):
        assert sum(r.contains(float(hs)) for r in SEA_STATES) == 1, hs
    spectrum_for_sea_state(4, hs_m=2.5)
    with pytest.raises(ConfigError, match=r"outside sea state 5 .*it is sea state 4"):
        spectrum_for_sea_state(5, hs_m=2.5)
    with pytest.raises(ConfigError, match="> 0 m"):
        sea_state_of(0.0)
