import math

import numpy as np
import pytest
from scipy import signal

from deckpose.errors import ConfigError
from deckpose.motion.filtered_noise import (
    FilteredNoise,
    ar2_coefficients,
    ar2_stationary_variance,
    filtered_noise,
)


def test_stationary_variance_formula_matches_impulse_response():
    a1, a2 = ar2_coefficients(FilteredNoise(1.0, 30.0, 0.4), 0.1)
    h = signal.lfilter([1.0], [1.0, -a1, -a2], np.r_[1.0, np.zeros(200_000)])
    assert ar2_stationary_variance(a1, a2) == pytest.approx(float(np.sum(h**2)), rel=1e-9)


def test_noise_has_its_sigma_and_period():
    noise = FilteredNoise(sigma=math.radians(1.0), period_s=30.0, damping_ratio=0.2)
    x = filtered_noise(noise, 200_000, 0.5, np.random.default_rng(7))  # ~28 h
    # ~3000 correlation times: the sample std is within a few percent.
    assert np.std(x) == pytest.approx(noise.sigma, rel=0.06)
    f, p = signal.welch(x, fs=2.0, nperseg=4096)
    assert 1.0 / f[np.argmax(p)] == pytest.approx(30.0, rel=0.15)
    # Stationary from the first sample: the first minute is no quieter than the rest.
    starts = x.reshape(-1, 1000)[:, :120]
    assert np.std(starts[:, 0]) == pytest.approx(noise.sigma, rel=0.25)


def test_zero_sigma_and_seeding():
    assert not np.any(filtered_noise(FilteredNoise(0.0, 10.0), 5, 0.1, np.random.default_rng(0)))
    a = filtered_noise(FilteredNoise(1.0, 10.0), 100, 0.1, np.random.default_rng(3))
    b = filtered_noise(FilteredNoise(1.0, 10.0), 100, 0.1, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    assert filtered_noise(FilteredNoise(1.0, 10.0), 1, 0.1, np.random.default_rng(3)).shape == (1,)


def test_bad_noise():
    with pytest.raises(ConfigError, match="sigma"):
        FilteredNoise(-1.0, 10.0)
    with pytest.raises(ConfigError, match="damping"):
        FilteredNoise(1.0, 10.0, 1.0)
    with pytest.raises(ConfigError, match="time step"):
        filtered_noise(FilteredNoise(1.0, 10.0), 10, 0.0, np.random.default_rng(0))
