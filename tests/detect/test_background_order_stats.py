"""background.median and background.percentile: numpy's values, exactly, with less overhead."""

import numpy as np
import pytest
from deckpose.detect.background import median, percentile


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.float32, np.float64])
@pytest.mark.parametrize("n", [1, 2, 7, 30_000, 30_001])
def test_median_is_numpy_median(dtype: type, n: int) -> None:
    rng = np.random.default_rng(n)
    # many ties (a frame's integer DN) and values near the dtype's top (no overflow of the
    # two middle values' sum)
    top = 255 if dtype == np.uint8 else 30_000
    v = rng.integers(top - 40, top + 1, n).astype(dtype)
    if np.dtype(dtype).kind == "f":
        v = v + rng.normal(0, 0.3, n).astype(dtype)
    assert median(v) == float(np.median(v))
    assert median(v.reshape(1, -1)) == float(np.median(v))


def test_median_leaves_nan_and_empty_to_numpy() -> None:
    v = np.array([1.0, np.nan, 3.0])
    assert np.isnan(median(v))
    with pytest.warns(RuntimeWarning):
        assert np.isnan(median(np.zeros(0)))


def test_percentile_is_numpy_percentile() -> None:
    rng = np.random.default_rng(1)
    for i in range(3000):
        n = int(rng.integers(1, 400))
        # ties (whole DN) and continuous values; every interpolation weight, both of numpy's sides
        v = rng.integers(0, 8, n).astype(float) if i % 2 else rng.normal(0.0, 10.0, n)
        for q in (0.0, 10.0, 20.0, 33.3, 50.0, 75.0, 90.0, 100.0):
            assert percentile(v, q) == float(np.percentile(v, q)), (n, q)


def test_percentile_leaves_nan_to_numpy() -> None:
    assert np.isnan(percentile(np.array([1.0, np.nan, 3.0]), 20.0))


def test_percentile_refuses_q_outside_0_100_as_numpy_does() -> None:
    for q in (-10.0, 110.0):
        with pytest.raises(ValueError):
            np.percentile(np.arange(5.0), q)
        with pytest.raises(ValueError, match="within"):
            percentile(np.arange(5.0), q)
