"""Statistics of the noise models, checked against their closed-form moments."""

import math

import numpy as np
import pytest

from deckpose import noise
from deckpose.errors import ConfigError, ShapeError

N = 200_000


def test_thesis_uniform_moments_and_bounds():
    rng = np.random.default_rng(0)
    P = np.tile([[1000.0, -500.0]], (N, 1))
    out = noise.thesis_uniform(P, 8.0, 3840, 2160, rng)
    p = 8.0 / math.hypot(1920, 1080)
    rel = (out - P) / P
    # delta ~ U[-p, p]: |delta| <= p, mean 0, variance p^2/3 (SE of the variance ~ 0.3%)
    assert np.all(np.abs(rel) <= p + 1e-15)
    assert np.abs(rel.mean(axis=0)).max() < 4 * p / math.sqrt(3 * N)
    np.testing.assert_allclose(rel.var(axis=0), p * p / 3, rtol=0.015)
    # independent components
    assert abs(np.corrcoef(rel.T)[0, 1]) < 0.01


def test_thesis_uniform_reaches_n_pixels_only_at_the_corner():
    rng = np.random.default_rng(1)
    corner = np.tile([[1920.0, 1080.0]], (N, 1))
    err = noise.thesis_uniform(corner, 8.0, 3840, 2160, rng) - corner
    # each component's bound is p*|X'|; the error vector's norm is at most N px
    assert np.max(np.linalg.norm(err, axis=1)) <= 8.0 + 1e-9
    assert np.max(np.linalg.norm(err, axis=1)) > 7.9
    centre = np.zeros((10, 2))
    np.testing.assert_array_equal(noise.thesis_uniform(centre, 8.0, 3840, 2160, rng), centre)


def test_norm_scaled_uniform_is_direction_free():
    rng = np.random.default_rng(2)
    P = np.tile([[1000.0, 0.0]], (N, 1))
    err = noise.norm_scaled_uniform(P, 8.0, 3840, 2160, rng) - P
    p = 8.0 / math.hypot(1920, 1080)
    # both components scale with ||P|| = 1000 even though Y' = 0
    np.testing.assert_allclose(err.var(axis=0), (p * 1000) ** 2 / 3, rtol=0.015)


def test_gaussian_sigma():
    rng = np.random.default_rng(3)
    err = noise.gaussian(np.zeros((N, 2)), 0.5, rng)
    np.testing.assert_allclose(err.std(axis=0), 0.5, rtol=0.01)
    # kurtosis of a normal is 3 (uniform would be 1.8)
    k = np.mean(err[:, 0] ** 4) / np.mean(err[:, 0] ** 2) ** 2
    assert k == pytest.approx(3.0, abs=0.1)


def test_same_seed_same_noise_and_bad_input():
    a = noise.gaussian(np.zeros((5, 2)), 1.0, np.random.default_rng(9))
    b = noise.gaussian(np.zeros((5, 2)), 1.0, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ConfigError):
        noise.gaussian(np.zeros((5, 2)), -1.0, np.random.default_rng(0))
    with pytest.raises(ShapeError):
        noise.thesis_uniform(np.zeros((5, 3)), 8, 100, 100, np.random.default_rng(0))
    with pytest.raises(ConfigError):
        noise.thesis_uniform(np.zeros((5, 2)), float("nan"), 100, 100, np.random.default_rng(0))
