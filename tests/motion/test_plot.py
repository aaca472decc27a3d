import numpy as np
import pytest

from deckpose.errors import InputDataError
from deckpose.motion.plot import channel_psd, plot_series
from deckpose.motion.series import MotionSeries


def test_psd_integrates_to_the_variance():
    t = np.arange(20_000) * 0.1
    x = 2.0 * np.sin(0.7 * t) + np.random.default_rng(0).normal(0.0, 0.1, t.size)
    w, p = channel_psd(t, x)
    assert np.sum(p) * (w[1] - w[0]) == pytest.approx(np.var(x), rel=0.02)
    assert w[np.argmax(p)] == pytest.approx(0.7, abs=0.01)


def test_plot_writes_png_atomically(tmp_path):
    t = np.arange(300) * 0.1
    s = MotionSeries(t, 0.05 * np.sin(t), 0.02 * np.cos(t), np.zeros_like(t), np.sin(0.5 * t))
    out = plot_series(s, tmp_path / "m.png", title="test")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["m.png"]  # no temporary left behind


def test_plot_non_uniform_series_and_psd_refuses_it(tmp_path):
    t = np.cumsum(np.random.default_rng(1).uniform(0.05, 0.15, 100))
    s = MotionSeries(t, np.sin(t), np.zeros_like(t), np.zeros_like(t), np.zeros_like(t))
    plot_series(s, tmp_path / "n.png")
    with pytest.raises(InputDataError, match="uniformly sampled"):
        channel_psd(t, np.sin(t))
