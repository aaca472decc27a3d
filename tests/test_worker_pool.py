"""deckpose.worker_pool: workers ignore SIGINT; an exception in the block stops them within the grace."""

from __future__ import annotations

import signal
import time

import pytest

from deckpose.worker_pool import worker_pool


def _sigint_ignored(_: int) -> bool:
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def _sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def test_workers_ignore_sigint() -> None:
    with worker_pool(2) as pool:
        assert all(pool.map(_sigint_ignored, range(4)))
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the parent's is restored


def test_an_interrupt_cancels_the_queue_and_stops_busy_workers_within_the_grace() -> None:
    grace_s = 0.5
    with pytest.raises(KeyboardInterrupt), worker_pool(2, grace_s=grace_s) as pool:
        futures = [pool.submit(_sleep, 60.0) for _ in range(6)]
        while not all(f.running() for f in futures[:2]):  # both workers busy
            time.sleep(0.01)
        t0 = time.monotonic()
        raise KeyboardInterrupt
    # grace, then terminate and join: well under the 60 s tasks (a hang would wait for them all)
    assert time.monotonic() - t0 < grace_s + 5.0
    assert all(f.cancelled() for f in futures[3:])  # queued tasks never ran (the pool queues 1 extra)
    assert not any(f.done() and not f.cancelled() and f.exception() is None for f in futures)
