"""Local worker processes that a Ctrl-C stops cleanly, within seconds.

Every stage that runs frames in worker processes (render, detect, estimate, evaluate, the
thesis tables) opens its pool here, so the rule is kept in one place:

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

:func:`map_ordered` is the stages' one way to run chunks of frames side by side and get
their results back in order (here, in local workers, or on a Dask cluster through
:func:`connect_scheduler`), so the process that owns the output writes it in frame order,
whatever the number of workers.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.context import SpawnContext, SpawnProcess
from typing import TYPE_CHECKING, TypeVar

from deckpose.errors import ConfigError

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["GRACE_S", "connect_scheduler", "ignore_interrupts", "map_ordered", "task_count", "worker_pool"]

T = TypeVar("T")
R = TypeVar("R")

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


def connect_scheduler(address: str) -> Client:
    """A Dask client of the scheduler at ``address`` (``tcp://host:8786``), or a clear error.

    Raises
    ------
    ConfigError
        ``dask.distributed`` is not installed, or the scheduler cannot be reached.
    """
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed: pip install 'deckpose[cluster]'") from None
    try:
        return Client(address)
    except (OSError, ValueError) as exc:  # unreachable (OSError, TimeoutError) or malformed
        raise ConfigError(f"cannot reach the Dask scheduler at {address!r} ({exc}); start one "
                          "(dask scheduler) or give its address as --scheduler tcp://HOST:8786") from None


def task_count(n_items: int, min_task: int, *, workers: int, scheduler: str | None = None) -> int:
    """Tasks to split ``n_items`` into: one per worker, none of fewer than ``min_task`` items.

    With a ``scheduler`` the count is not bounded by ``workers`` (the cluster's size is its
    own). 1 means: run them in this process (:func:`map_ordered` does, for one task).
    """
    most = n_items // max(1, min_task)
    if scheduler is None:
        most = min(most, workers)
    return max(1, most)


def map_ordered(fn: Callable[[T], R], tasks: Sequence[T], *, workers: int,
                scheduler: str | None = None) -> Generator[R, None, None]:
    """``fn(task)`` of every task, yielded in task order, wherever it ran.

    Parameters
    ----------
    fn : callable
        A module-level function (the workers import it), pure: its result depends on its
        task alone, so where it runs does not change it.
    tasks : sequence
        Its arguments, one per call (picklable; a chunk of frames each, not one frame).
    workers : int
        Local worker processes (:func:`worker_pool`); with 0 or 1, or a single task, every
        call runs in this process (a pool would only add its start-up).
    scheduler : str, optional
        A Dask scheduler's address: the calls run on its workers instead (``workers`` is
        then ignored).

    Yields
    ------
    object
        ``fn(tasks[0])``, ``fn(tasks[1])``, ... A generator: close it (``contextlib.closing``)
        so that an interrupt in the caller's loop stops the workers at once, not when it is
        collected.
    """
    if workers < 0:
        raise ConfigError(f"workers must be >= 0 (0 or 1: in this process), got {workers}")
    if scheduler is not None:
        client = connect_scheduler(scheduler)
        futures = []
        try:
            futures = client.map(fn, list(tasks), pure=False)
            for fut in futures:
                yield fut.result()
                fut.release()
        finally:
            client.cancel(futures)
            client.close()
        return
    if workers <= 1 or len(tasks) <= 1:
        for task in tasks:
            yield fn(task)
        return
    # workers ignore Ctrl-C; on it (or any error) the tasks not started are cancelled and the
    # workers stopped within seconds
    with worker_pool(min(workers, len(tasks))) as pool:
        yield from pool.map(fn, tasks)
