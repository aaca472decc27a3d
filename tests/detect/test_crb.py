import numpy as np
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.synthetic import SensorModel


def test_crb_reaches_the_photon_limit_for_a_wide_bright_spot():
    # No background and negligible read/quantisation noise: a continuous Gaussian under
    # Poisson noise has Var(u) >= sigma^2 / N; pixelation adds about 1/12 px^2 to sigma^2.
    sensor = SensorModel(gain_dn_per_e=100.0, read_noise_e=0.0, background_e=0.0)
    sigma, n = 4.0, 1e5
    crb = centroid_crb_px2(10.2, 20.4, sigma, n, sensor)
    want = (sigma**2 + 1 / 12) / n
    assert abs(crb[0, 0] / want - 1) < 0.02
    assert abs(crb[1, 1] / want - 1) < 0.02
    assert abs(crb[0, 1]) < 1e-3 * want


def test_crb_grows_with_background_and_shrinks_with_flux():
    quiet = SensorModel(read_noise_e=1.0, background_e=1.0)
    noisy = SensorModel(read_noise_e=10.0, background_e=200.0)
    a = np.trace(centroid_crb_px2(0.0, 0.0, 1.2, 1e4, quiet))
    b = np.trace(centroid_crb_px2(0.0, 0.0, 1.2, 1e4, noisy))
    c = np.trace(centroid_crb_px2(0.0, 0.0, 1.2, 1e5, quiet))
    assert b > 1.5 * a
    assert c < a / 5
