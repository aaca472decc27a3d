import numpy as np
from deckpose.detect.synthetic import SensorModel, add_noise, expected_electrons, pixel_fractions
from scipy.integrate import quad
from scipy.stats import norm


def test_pixel_fractions_match_numerical_integration():
    xs = np.arange(-4, 6)
    got = pixel_fractions(0.37, 1.3, xs)
    want = [quad(lambda t: norm.pdf(t, 0.37, 1.3), x - 0.5, x + 0.5)[0] for x in xs]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_expected_electrons_conserves_flux_and_centre():
    mu = expected_electrons((40, 50), [[20.3, 17.8]], [1.7], [1000.0], 5.0)
    s = mu - 5.0
    assert abs(s.sum() - 1000.0) < 1e-6
    vv, uu = np.mgrid[0:40, 0:50]
    # The centroid of a pixel-integrated Gaussian is exactly its centre (window +-6 sigma).
    assert abs((s * uu).sum() / s.sum() - 20.3) < 1e-6
    assert abs((s * vv).sum() / s.sum() - 17.8) < 1e-6


def test_noise_mean_and_variance_follow_the_model():
    sensor = SensorModel(gain_dn_per_e=2.0, read_noise_e=3.0, background_e=0.0, offset_dn=100.0)
    mu = np.full((400, 500), 50.0)
    img = add_noise(mu, sensor, np.random.default_rng(0)).astype(float)
    # mean = gain * mu + offset; var = gain^2 (mu + read^2) + 1/12 (rounding); 2e5 samples:
    # relative standard errors ~0.1 % (mean) and ~0.4 % (variance).
    assert abs(img.mean() - 200.0) < 0.2
    assert abs(img.var() / (4.0 * (50.0 + 9.0) + 1 / 12) - 1.0) < 0.02
