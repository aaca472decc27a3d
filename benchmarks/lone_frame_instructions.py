"""A lone frame's instructions here against another commit: issue 17's gate, which load cannot move.

Time on a shared 2-core machine moves by tens of percent with the other jobs; the number of
instructions a lone frame retires does not. For each variant and tree this runs a child process
under ``valgrind --tool=callgrind --instr-atstart=no``: the child builds 20 frames (8 MP camera,
30 m, sigma 0.5 px, attitudes from the thesis motion series), estimates each twice through
``run_estimator`` to warm up, then asks this script to switch the instrumentation on
(``callgrind_control -i on``), runs ``--passes`` passes over the 20 frames one at a time, and asks
for it to be switched off. The instructions collected in that window, divided by the frames,
are the figure; the other commit runs from its sources exported by
:func:`bench_lone_against.import_commit` (``deckpose`` renamed ``deckpose_base``), in the same
interpreter and environment. Repeats alternate the trees.

Run::

    .venv/bin/python benchmarks/lone_frame_instructions.py --commit 461b492 \\
        --variants conic conic-geom conic+refine pnp --repeats 2

Needs valgrind (``apt-get install valgrind``); a child takes about a minute.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: (label, registry name, options overrides), as bench_lone_frame.py names them.
VARIANTS = {
    "thesis": ("thesis", {}), "thesis+refine": ("thesis", {"refine": True}),
    "conic": ("conic", {}), "conic-geom": ("conic", {"conic_polish_steps": 0}),
    "conic+refine": ("conic", {"refine": True}), "pnp": ("pnp", {}), "pnp+mean": ("pnp", {"posterior_mean": True}),
}
FRAMES = 20


def _child(tree: str, variant: str, passes: int, sync: Path, base_dir: str) -> None:
    """Under callgrind: warm up, then ``passes`` passes of lone frames inside the window."""
    import cv2
    import numpy as np

    cv2.setNumThreads(1)
    sys.path.insert(0, str(HERE))
    from bench_estimators import load_attitudes, make_cell

    name, over = VARIANTS[variant]
    dets, _, _ = make_cell(0.5, 30.0, "8mp", load_attitudes(None), FRAMES, np.random.default_rng(7), {})
    if tree == "base":
        sys.path.insert(0, base_dir)
        import importlib

        batch = importlib.import_module("deckpose_base.estimate.batch")
        registry = importlib.import_module("deckpose_base.estimate.registry")
        records = importlib.import_module("deckpose_base.records")
        camera = importlib.import_module("deckpose_base.camera").preset("8mp")
        layout = importlib.import_module("deckpose_base.layout").DeckLayout()
        dets = [records.Detections(d.points_px, d.beacon_ids, d.covariance_px2, frame_id=d.frame_id) for d in dets]
        run_estimator, options = batch.run_estimator, registry.EstimateOptions(sigma_px=0.5)
    else:
        from deckpose.estimate.batch import run_estimator
        from deckpose.estimate.registry import EstimateOptions

        from deckpose.camera import preset
        from deckpose.layout import DeckLayout

        camera, layout, options = preset("8mp"), DeckLayout(), EstimateOptions(sigma_px=0.5)
    opts = dataclasses.replace(options, **over)
    for _ in range(2):
        for d in dets:
            run_estimator(name, d, camera, layout, opts)

    def handshake(tag: str) -> None:
        sync.with_suffix(f".{tag}.ready").touch()
        while not sync.with_suffix(f".{tag}.go").exists():
            time.sleep(0.05)

    handshake("on")
    for _ in range(passes):
        for d in dets:
            run_estimator(name, d, camera, layout, opts)
    handshake("off")


def _measure(tree: str, variant: str, passes: int, base_dir: str, tmp: Path) -> float:
    """Millions of instructions a lone frame retires in ``tree`` ('this' or 'base')."""
    sync = tmp / f"sync-{tree}-{variant}-{time.monotonic_ns()}"
    log = sync.with_suffix(".log")
    cmd = ["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={sync}.out",
           sys.executable, __file__, "--child", tree, variant, str(passes), str(sync), base_dir]
    env = dict(os.environ, PYTHONHASHSEED="0")
    with open(log, "w") as fh:
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
        for tag, switch in (("on", "on"), ("off", "off")):
            while not sync.with_suffix(f".{tag}.ready").exists():
                if proc.poll() is not None:
                    raise SystemExit(f"the {tree} child for {variant} ended early; see its log:\n{log.read_text()}")
                time.sleep(0.1)
            subprocess.run(["callgrind_control", "-i", switch, str(proc.pid)], check=True, capture_output=True)
            time.sleep(1.0)  # (callgrind takes the switch at its next check)
            sync.with_suffix(f".{tag}.go").touch()
        proc.wait()
    found = re.findall(r"Collected : (\d+)", log.read_text())
    if not found:
        raise SystemExit(f"no instruction count in the {tree} child's log:\n{log.read_text()}")
    return int(found[-1]) / (passes * FRAMES) / 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", required=True, help="the commit to compare with (e.g. the branch point)")
    ap.add_argument("--variants", nargs="+", default=["conic", "conic-geom", "conic+refine"],
                    choices=sorted(VARIANTS))
    ap.add_argument("--passes", type=int, default=5, help="passes over the 20 frames inside the window")
    ap.add_argument("--repeats", type=int, default=1, help="children per tree and variant (trees alternate)")
    args = ap.parse_args(argv)
    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        raise SystemExit("valgrind not found: apt-get install valgrind")
    sys.path.insert(0, str(HERE))
    from bench_lone_against import import_commit

    with tempfile.TemporaryDirectory(prefix="deckpose-ir-") as tmp_name:
        tmp = Path(tmp_name)
        import_commit(args.commit, tmp / "base")
        print(f"# million instructions a lone frame (run_estimator; 8mp, 30 m, sigma 0.5 px; {FRAMES} frames x "
              f"{args.passes} passes inside the window), this tree against {args.commit}; valgrind callgrind, "
              f"PYTHONHASHSEED=0, load-independent", flush=True)
        print(f"{'variant':>14} {'base':>8} {'this':>8} {'this/base':>9}  (each child)", flush=True)
        for variant in args.variants:
            got: dict[str, list[float]] = {"base": [], "this": []}
            for r in range(args.repeats):
                for tree in (("base", "this") if r % 2 == 0 else ("this", "base")):
                    got[tree].append(_measure(tree, variant, args.passes, str(tmp / "base"), tmp))
            b, t = statistics.median(got["base"]), statistics.median(got["this"])
            each = " ".join(f"{x:.4f}" for x in got["base"]) + " | " + " ".join(f"{x:.4f}" for x in got["this"])
            print(f"{variant:>14} {b:>8.4f} {t:>8.4f} {t / b:>9.4f}  ({each})", flush=True)
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        _child(*sys.argv[2:4], int(sys.argv[4]), Path(sys.argv[5]), sys.argv[6])
    else:
        raise SystemExit(main())
