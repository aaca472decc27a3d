"""``deckpose.machine_load``: the load a long job ran under, by stage, and peak memory."""

from __future__ import annotations

import pytest

from deckpose.machine_load import LoadSampler, peak_rss_gib, summarize_load


def test_summary_selects_the_samples_inside_a_span() -> None:
    clock = iter([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    loads = iter([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    sampler = LoadSampler(interval_s=1e6, read=lambda: next(loads), clock=lambda: next(clock))
    with sampler:  # the thread's first sample is 1e6 s away: only the calls below sample
        for _ in range(4):
            sampler.sample()
    # samples (t, load): (0,1) (1,2) (2,3) (3,4) (4,5) (5,6): the last from __exit__
    assert sampler.summary() == summarize_load([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    inside = sampler.summary(1.0, 3.0)
    assert (inside.mean, inside.max, inside.samples) == (3.0, 4.0, 3)
    # a span between samples takes the first sample after it: the load just after it ran
    between = sampler.summary(1.2, 1.8)
    assert (between.mean, between.samples) == (3.0, 1)
    # a span after the last sample takes the last one
    assert sampler.summary(9.0, 10.0).mean == 6.0


def test_the_thread_samples_while_the_block_runs() -> None:
    import time

    with LoadSampler(interval_s=0.01) as sampler:
        time.sleep(0.2)
    summary = sampler.summary()
    assert summary.samples >= 3  # start, end and the thread's samples between
    assert 0 <= summary.mean <= summary.max


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="positive"):
        LoadSampler(interval_s=0)
    with pytest.raises(ValueError, match="context manager"):
        LoadSampler().summary()
    with pytest.raises(ValueError, match="no load samples"):
        summarize_load([])


def test_peak_memory_is_in_gib() -> None:
    import numpy as np

    block = np.ones(64 * 2**20 // 8)  # 64 MiB touched: the peak is at least that
    peak = peak_rss_gib()
    assert peak["this_process"] >= 64 / 1024 and block.sum() > 0
    assert peak["largest_worker"] >= 0
