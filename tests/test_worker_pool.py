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
    # pytest started in the background of a shell (``&``, nohup) runs with SIGINT ignored; the
    # parent here handles it, as a command run in a terminal does
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with worker_pool(2) as pool:
            assert all(pool.map(_sigint_ignored, range(4)))
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the parent's is restored
    finally:
        signal.signal(signal.SIGINT, outer)


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


def _pid_after(seconds: float) -> int:
    import os

    time.sleep(seconds)
    return os.getpid()


def test_map_ordered_yields_in_task_order_from_the_workers_and_runs_small_jobs_here() -> None:
    import os

    from deckpose.worker_pool import map_ordered, task_count

    # the first task ends last: the results still come in task order, from other processes
    delays = [0.6, 0.0, 0.0, 0.0]
    pids = list(map_ordered(_pid_after, delays, workers=2))
    assert len(pids) == 4 and os.getpid() not in pids
    assert list(map_ordered(_sleep, delays, workers=2)) == delays
    for workers in (0, 1):  # no pool: this process
        assert list(map_ordered(_pid_after, [0.0, 0.0], workers=workers)) == [os.getpid()] * 2
    assert list(map_ordered(_pid_after, [0.0], workers=2)) == [os.getpid()]  # one task: no pool either
    # one task per worker, none under the minimum; a cluster's count is not bounded by workers
    assert [task_count(n, 100, workers=2) for n in (0, 99, 199, 200, 5000)] == [1, 1, 1, 2, 2]
    assert task_count(5000, 100, workers=2, scheduler="tcp://x:1") == 50
    with pytest.raises(ValueError, match="workers must be >= 0"):
        list(map_ordered(_sleep, [0.0], workers=-1))
