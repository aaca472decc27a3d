"""What the machine was doing while a long job ran: its 1-minute load, sampled, and peak memory.

A run's timings mean little without the load they were measured under (this project's machines
are shared), so ``deckpose pipeline`` records both in ``pipeline.json``: the 1-minute load
average sampled every few seconds over each stage (mean and largest), and the peak resident
memory of its own process and of its largest worker process.
"""
from __future__ import annotations

import os
import resource
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Self


@dataclass(frozen=True)
class LoadSummary:
    """The 1-minute load average over one span of time.

    Attributes
    ----------
    mean : float
        Mean of the samples (the load on this machine's cores, not per core).
    max : float
        Largest sample.
    samples : int
        How many samples were taken (at least one: the span's end).
    """

    mean: float
    max: float
    samples: int

    def as_dict(self) -> dict[str, float | int]:
        return {"mean": round(self.mean, 2), "max": round(self.max, 2), "samples": self.samples}


def summarize_load(samples: list[float]) -> LoadSummary:
    """Mean and largest of load samples (non-empty)."""
    if not samples:
        raise ValueError("no load samples to summarize")
    return LoadSummary(mean=sum(samples) / len(samples), max=max(samples), samples=len(samples))


class LoadSampler:
    """Sample the 1-minute load average in a background thread while a block runs.

    Parameters
    ----------
    interval_s : float
        Seconds between samples.
    read : callable, optional
        Returns the 1-minute load (default ``os.getloadavg()[0]``); tests pass their own.
    clock : callable, optional
        Seconds on a monotonic clock (default ``time.perf_counter``), the times that
        :meth:`summary` selects samples by.

    Examples
    --------
    >>> with LoadSampler(interval_s=5.0) as sampler:
    ...     pass  # the long work
    >>> sampler.summary().samples >= 1
    True
    """

    def __init__(self, interval_s: float = 10.0, read: Callable[[], float] | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        if not interval_s > 0:
            raise ValueError(f"interval_s must be positive, got {interval_s}")
        self._interval_s = interval_s
        self._read = read or (lambda: os.getloadavg()[0])
        self._clock = clock or time.perf_counter
        self._samples: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _loop(self) -> None:
        while not self._stop.wait(self._interval_s):
            self.sample()

    def sample(self) -> None:
        """Take one sample now (the thread calls this every ``interval_s``)."""
        self._samples.append((self._clock(), self._read()))

    def __enter__(self) -> Self:
        self._samples = []
        self.sample()
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="load-sampler", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.sample()

    def summary(self, start: float | None = None, end: float | None = None) -> LoadSummary:
        """The samples taken between ``start`` and ``end`` (clock seconds; default: all).

        A span shorter than the interval may hold no sample: it then takes the first
        sample after its end (or the last one taken), the load just after it ran.
        """
        samples = list(self._samples)
        if not samples:
            raise ValueError("no load samples yet: use the sampler as a context manager")
        lo = -float("inf") if start is None else start
        hi = float("inf") if end is None else end
        inside = [load for t, load in samples if lo <= t <= hi]
        if not inside:
            after = [load for t, load in samples if t > hi]
            inside = [after[0] if after else samples[-1][1]]
        return summarize_load(inside)


def peak_rss_gib() -> dict[str, float]:
    """Peak resident memory, GiB: this process, and its largest waited-for child process.

    Returns
    -------
    dict of str to float
        ``this_process`` and ``largest_worker`` (0.0 when no child process has ended yet;
        Linux reports ``ru_maxrss`` in KiB).
    """
    kib = 2.0 ** 20
    return {"this_process": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / kib, 2),
            "largest_worker": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / kib, 2)}
