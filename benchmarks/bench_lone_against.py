"""A lone frame here against the same frame at another commit, in one process: issue 17's gate.

The issue asks that a lone frame never get slower than "today's single-frame path". On a
shared, noisy machine two processes run minutes apart disagree by tens of percent; this
script times both trees in one process, frame passes interleaved, so both see the same load.
It exports the other commit's ``deckpose`` (with ``estimate/``, ``detect/``, ``evaluate/``,
``render/``) by ``git archive`` into a temporary folder as a package named ``deckpose_base``
(every ``deckpose.`` in its sources renamed), then for each variant and round times, per frame
(8 MP camera, 30 m, sigma 0.5 px, attitudes from the thesis motion series):

* ``base lone``: the other commit's ``run_estimator`` on one frame at a time;
* ``lone``: this tree's ``run_estimator`` on one frame at a time;
* ``of-one``: this tree's ``estimate_batch`` on a list of one frame;
* ``base batch`` and ``batch``: one ``estimate_batch`` call on all frames, each tree.

It prints the medians (thread CPU µs a frame, one BLAS and one OpenCV thread) and the
medians of the per-round ratios against the other commit (for ``lone`` also their first
and third quartiles: the ratio's own spread), with the load before and after.
A ratio above 1 for ``lone`` fails the gate; ``of-one`` says whether routing a lone frame
through the batch would.

Run::

    .venv/bin/python benchmarks/bench_lone_against.py --commit 5cdfdbc --frames 100 --rounds 5
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import io
import re
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from types import ModuleType

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_estimators import load_attitudes, make_cell
from bench_lone_frame import VARIANTS
from deckpose.estimate.batch import estimate_batch, run_estimator
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import CameraModel, preset
from deckpose.layout import DeckLayout
from deckpose.records import Detections

cv2.setNumThreads(1)

REPO = Path(__file__).resolve().parent.parent
#: The folders that install as deckpose and its stage subpackages (pyproject's package-dir).
_SUBPACKAGES = ("estimate", "detect", "evaluate", "render")


def import_commit(commit: str, into: Path) -> dict[str, ModuleType]:
    """The other commit's estimate batch module, registry, records, camera and layout modules.

    Its sources are exported to ``into/deckpose_base`` with ``deckpose.`` renamed.
    """
    tar = subprocess.run(["git", "-C", str(REPO), "archive", "--format=tar", commit, "deckpose",
                          *_SUBPACKAGES], capture_output=True, check=True).stdout
    src = into / "src"
    with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
        tf.extractall(src, filter="data")
    root = into / "deckpose_base"
    shutil.copytree(src / "deckpose", root)
    for sub in _SUBPACKAGES:
        shutil.copytree(src / sub, root / sub)
    for py in root.rglob("*.py"):
        text = py.read_text()
        text = re.sub(r"\bdeckpose\.", "deckpose_base.", text)
        text = text.replace("from deckpose import", "from deckpose_base import")
        py.write_text(text)
    sys.path.insert(0, str(into))
    import importlib

    names = {"batch": "estimate.batch", "registry": "estimate.registry", "records": "records",
             "camera": "camera", "layout": "layout"}
    return {k: importlib.import_module("deckpose_base." + v) for k, v in names.items()}


def _each(fn: Callable[..., object], name: str, dets: Sequence[object], *rest: object) -> None:
    """``fn(name, d, *rest)`` for each frame ``d``: the lone-frame pass."""
    for d in dets:
        fn(name, d, *rest)


def _each_of_one(name: str, dets: Sequence[Detections], camera: CameraModel, layout: DeckLayout,
                 opts: EstimateOptions) -> None:
    """``estimate_batch`` on a list of one frame, for each frame."""
    for d in dets:
        estimate_batch(name, [d], camera, layout, opts)


def _ratio(t: dict[str, list[float]], a: str, b: str) -> float:
    """Median over the rounds of ``t[a] / t[b]`` (paired: the same round)."""
    return statistics.median(x / y for x, y in zip(t[a], t[b], strict=True))


def _quartiles(t: dict[str, list[float]], a: str, b: str) -> str:
    """The first and third quartile of the paired ratios ``t[a] / t[b]``, as ``q1-q3``."""
    r = [x / y for x, y in zip(t[a], t[b], strict=True)]
    if len(r) < 2:
        return "-"
    q1, _, q3 = statistics.quantiles(r, n=4, method="inclusive")
    return f"{q1:.2f}-{q3:.2f}"


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", required=True, help="the commit to compare with (e.g. the branch point)")
    ap.add_argument("--frames", type=int, default=100, help="frames of each pass")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds (medians)")
    ap.add_argument("--seed", type=int, default=20261203)
    ap.add_argument("--variants", nargs="+", default=[v[0] for v in VARIANTS])
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="deckpose-base-") as tmp:
        base = import_commit(args.commit, Path(tmp))
        camera, layout = preset("8mp"), DeckLayout()
        b_camera, b_layout = base["camera"].preset("8mp"), base["layout"].DeckLayout()
        dets, _, _ = make_cell(0.5, 30.0, "8mp", load_attitudes(None), args.frames,
                               np.random.default_rng(args.seed), {})
        b_dets = [base["records"].Detections(d.points_px, d.beacon_ids, d.covariance_px2, frame_id=d.frame_id)
                  for d in dets]
        n = len(dets)
        print(f"# {n} frames, 8mp, 30 m, sigma 0.5 px; thread CPU us/frame, medians of {args.rounds} rounds, "
              f"this tree against {args.commit} in one process; load before {_load()}")
        print(f"{'variant':>14} {'base lone':>9} {'lone':>7} {'of-one':>7} {'lone/base':>9} {'quartiles':>9} "
              f"{'one/base':>8} {'base batch':>10} {'batch':>7} {'batch/base':>10}")
        for label, name, over in VARIANTS:
            if label not in args.variants:
                continue
            opts = dataclasses.replace(EstimateOptions(sigma_px=0.5), **over)
            b_opts = dataclasses.replace(base["registry"].EstimateOptions(sigma_px=0.5), **over)
            runs: dict[str, Callable[[], object]] = {
                "base": partial(_each, base["batch"].run_estimator, name, b_dets, b_camera, b_layout, b_opts),
                "lone": partial(_each, run_estimator, name, dets, camera, layout, opts),
                "one": partial(_each_of_one, name, dets, camera, layout, opts),
                "base_batch": partial(base["batch"].estimate_batch, name, b_dets, b_camera, b_layout, b_opts),
                "batch": partial(estimate_batch, name, dets, camera, layout, opts),
            }
            t: dict[str, list[float]] = {k: [] for k in runs}
            for r in range(args.rounds):
                for k in (list(runs) if r % 2 == 0 else list(runs)[::-1]):
                    t0 = time.thread_time()
                    runs[k]()
                    t[k].append((time.thread_time() - t0) / n)
            med = {k: 1e6 * statistics.median(v) for k, v in t.items()}

            print(f"{label:>14} {med['base']:>9.0f} {med['lone']:>7.0f} {med['one']:>7.0f} "
                  f"{_ratio(t, 'lone', 'base'):>9.2f} {_quartiles(t, 'lone', 'base'):>9} "
                  f"{_ratio(t, 'one', 'base'):>8.2f} {med['base_batch']:>10.1f} "
                  f"{med['batch']:>7.1f} {_ratio(t, 'batch', 'base_batch'):>10.2f}", flush=True)
        print(f"# load after {_load()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
