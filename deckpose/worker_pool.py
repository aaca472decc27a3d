"""Local worker processes that a Ctrl-C stops cleanly, within seconds.

Every stage that runs frames in worker processes (render, detect, the thesis tables) opens
its pool here, so the rule is kept in one place:

* the workers ignore SIGINT. A Ctrl-C in a terminal goes to every process of the job; a
  worker that took it died with a traceback, and one that died holding the pool's queue lock
  (a semaphore) left the others, and the parent's shutdown, waiting for ever. The parent
  alone handles the Ctrl-C. A spawned worker ignores it from its first instruction: the
  parent ignores SIGINT while it starts a worker (SIGINT blocked meanwhile, so a Ctrl-C in
  that instant is delivered afterwards, not lost), and the child inherits the disposition
  through ``exec``; the pool's initializer says it again.
* when the block that uses the pool ends with an exception (the parent's
  ``KeyboardInterrupt``, or a frame's error), the frames not yet started are cancelled, the
  workers get ``grace_s`` seconds to finish the frame in hand, and those still running are
  terminated. Every writer writes atomically (:mod:`deckpose.atomic_io`), so a terminated
  worker leaves at most a temporary file, which the next run of the stage removes.

The workers are spawned, never forked: each one creates its own GL context and imports
what it needs.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.context import SpawnContext, SpawnProcess

__all__ = ["GRACE_S", "ignore_interrupts", "worker_pool"]

#: Seconds the workers get to finish their frame in hand after the job is interrupted.
GRACE_S = 3.0


def ignore_interrupts() -> None:
    """Ignore SIGINT in this process (a worker's initializer: the parent handles Ctrl-C)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def _children_ignore_sigint() -> Iterator[None]:
    """Within the block, processes started from this one begin with SIGINT ignored.

    Only the main thread can change a signal's handler; elsewhere the block does nothing
    (the worker's initializer still ignores SIGINT, from its first task on).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # Blocked first: a SIGINT that arrives while it is ignored stays pending (Linux never
    # discards a blocked signal) and reaches the restored handler when it is unblocked.
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


class _WorkerProcess(SpawnProcess):
    """A spawned process that begins with SIGINT ignored."""

    def start(self) -> None:
        with _children_ignore_sigint():
            super().start()


class _WorkerContext(SpawnContext):
    """The spawn context of :func:`worker_pool`'s processes."""

    Process = _WorkerProcess


def _stop(pool: ProcessPoolExecutor, grace_s: float) -> None:
    """Cancel the tasks not started, give the workers ``grace_s`` to finish theirs, then terminate them."""
    # the executor's own record of its worker processes (pid -> process); shutdown() drops it
    started = list((pool._processes or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    try:
        deadline = time.monotonic() + grace_s
        for p in started:
            p.join(max(0.0, deadline - time.monotonic()))
    except KeyboardInterrupt:  # a second Ctrl-C: stop waiting
        pass
    finally:
        for p in started:
            if p.is_alive():
                p.terminate()
        for p in started:
            p.join(2.0)
            if p.is_alive():
                p.kill()
                p.join()


@contextlib.contextmanager
def worker_pool(workers: int, *, grace_s: float = GRACE_S,
                initializer: Callable[[], object] | None = None) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``workers`` spawned processes that ignore SIGINT, stopped cleanly on any exception.

    Parameters
    ----------
    workers : int
        Worker processes (>= 1).
    grace_s : float, keyword-only
        Seconds, after an exception in the block, that the workers get to finish their task
        in hand before they are terminated.
    initializer : callable, optional, keyword-only
        Run in each worker after SIGINT is ignored.

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor
        Shut down (waiting for its tasks) when the block ends normally.
    """
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=_WorkerContext(),
                               initializer=_initialize, initargs=(initializer,))
    try:
        yield pool
    except BaseException:
        _stop(pool, grace_s)
        raise
    pool.shutdown(wait=True)


def _initialize(then: Callable[[], object] | None) -> None:
    ignore_interrupts()
    if then is not None:
        then()
