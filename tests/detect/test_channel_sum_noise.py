"""The channel sum's own noise (``background.channel_sum_noise``) against a known one."""

import math

import numpy as np
import pytest
from deckpose.detect.background import channel_sum_noise


@pytest.mark.parametrize(("sigma_dn", "level_dn", "dtype"),
                         [(0.3, 40.25, np.uint8), (0.8, 40.0, np.uint8), (5.0, 1000.0, np.uint16)])
def test_channel_sum_noise_of_a_rounded_gaussian_frame(sigma_dn, level_dn, dtype):
    # Each channel: a flat level plus Gaussian noise, rounded to whole DN; the frame is flat,
    # so the standard deviation of its whole channel sum is the noise to find (rounding
    # included: below about 0.5 DN its variance depends on the level's phase, not only on
    # sigma^2 + 1/12). About 30,000 differences: the estimate's relative sampling error is
    # 1 / sqrt(2 n) = 0.4 %; 3 % allows it and the 4-sigma clipping's bias.
    rng = np.random.default_rng(4)
    image = np.rint(level_dn + rng.normal(0.0, sigma_dn, (1080, 1920, 3))).astype(dtype)
    want = float(image.astype(np.float64).sum(axis=2).std())
    assert channel_sum_noise(image) == pytest.approx(want, rel=0.03)
    if sigma_dn >= 0.8:  # well above the rounding step the textbook sum holds too
        assert want == pytest.approx(math.sqrt(3.0 * (sigma_dn**2 + 1.0 / 12.0)), rel=0.02)


def test_a_noiseless_integer_frame_reads_its_rounding_not_zero():
    image = np.full((500, 600, 3), 17, np.uint8)
    assert channel_sum_noise(image) == pytest.approx(math.sqrt(3.0 / 12.0))
    mono = np.full((500, 600), 17, np.uint16)
    assert channel_sum_noise(mono) == pytest.approx(math.sqrt(1.0 / 12.0))
