"""The estimate and evaluate stages with 1 worker against 2, on the same run: wall time, interleaved.

For a run folder with detections (``RUN``), each round times both worker counts (1 then 2,
2 then 1 the next round) of:

* ``estimate``: :func:`~deckpose.sequence_run.estimate_run_with_prior` for each ``--method``
  (default thesis, conic, pnp), as the pipeline's estimate stage calls it;
* ``evaluate``: :func:`~deckpose.evaluate.run.evaluate_run` without the log (errors with the
  Cramér–Rao bounds, resolution tables), as the pipeline's evaluate stage;
* ``log``: :func:`~deckpose.evaluate.run.write_log`, the MCAP log the pipeline writes after
  the report.

Each figure is the median wall time (``time.perf_counter`` around the whole call, the
workers' start-up included) over ``--repeats`` rounds, with the ratio 2/1 and the 1-minute
load before and after. The stages keep small runs in this process (``MIN_PARALLEL_FRAMES``,
``MIN_CRB_TASK_FRAMES``, ``MIN_PARALLEL_LOG_FRAMES``): with the defaults, 2 workers on a small
run are 1 worker. ``--force`` sets those minimums to 1, so that 2 workers always split the
work, to measure what the split costs or saves at this run's size (the figures the minimums
are set from). The files written are checked to be the same bytes whatever the workers.

The stages write into RUN what the pipeline writes (estimates, evaluation, log), the same
each time.

Run::

    .venv/bin/python benchmarks/bench_stage_workers.py RUN --repeats 5 [--force]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from deckpose.estimate import run as estimate_stage
from deckpose.estimate.registry import parse_method
from deckpose.evaluate import mcap_log
from deckpose.evaluate import run as evaluate_stage
from deckpose.evaluate.run import evaluate_run, write_log

from deckpose import run_folder as rl
from deckpose.sequence_run import estimate_run_with_prior


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _digest(paths: list[Path]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="run folder with detections (render and detect done)")
    ap.add_argument("--detector", default="cog")
    ap.add_argument("--method", default="thesis,conic,pnp", help="methods, comma-separated")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--force", action="store_true",
                    help="minimums of the parallel paths set to 1: 2 workers always split the work")
    args = ap.parse_args()
    if args.force:
        estimate_stage.MIN_PARALLEL_FRAMES = 1
        evaluate_stage.MIN_CRB_TASK_FRAMES = 1
        mcap_log.MIN_PARALLEL_LOG_FRAMES = 1
    run = rl.run_paths(args.run)
    methods = [parse_method(m) for m in args.method.split(",")]
    n_frames = len(rl.read_frames(run))

    def estimate(workers: int) -> list[Path]:
        return [estimate_run_with_prior(run.root, spec, detector=args.detector, workers=workers).path
                for spec in methods]

    def evaluate(workers: int) -> list[Path]:
        return list(evaluate_run(run, mcap=False, workers=workers).values())

    def log(workers: int) -> list[Path]:
        return list(write_log(run, workers=workers).values())

    stages: dict[str, Callable[[int], list[Path]]] = {"estimate": estimate, "evaluate": evaluate, "log": log}
    times: dict[tuple[str, int], list[float]] = {(s, w): [] for s in stages for w in (1, 2)}
    digests: dict[str, set[str]] = {s: set() for s in stages}
    load_before = _load()
    for r in range(args.repeats):
        for name, fn in stages.items():
            for w in ((1, 2) if r % 2 == 0 else (2, 1)):
                t = time.perf_counter()
                paths = fn(w)
                times[(name, w)].append(time.perf_counter() - t)
                digests[name].add(_digest(paths))
                print(f"# round {r + 1} {name} workers {w}: {times[(name, w)][-1]:.2f} s (load {_load()})",
                      flush=True)
    print(f"# {run.root}: {n_frames} frames, methods {args.method}, detector {args.detector}; "
          f"{'minimums forced to 1' if args.force else 'default minimums'}; wall s, median of {args.repeats} "
          f"interleaved rounds; load before {load_before}")
    print(f"{'stage':>9} {'1 worker':>9} {'2 workers':>10} {'2/1':>6}  same files")
    for name in stages:
        one, two = (statistics.median(times[(name, w)]) for w in (1, 2))
        print(f"{name:>9} {one:9.2f} {two:10.2f} {two / one:6.2f}  {'yes' if len(digests[name]) == 1 else 'NO'}")
    print(f"# load after {_load()}")


if __name__ == "__main__":
    main()
