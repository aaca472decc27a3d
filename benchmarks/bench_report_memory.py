"""Peak memory of ``deckpose report`` on a run with 64 MP frames (target: <= 1.5 GiB for any run).

The report draws example frames and figures; a 64 MP frame handed to matplotlib whole
once peaked at 4.6 GiB. This benchmark runs ``deckpose report RUN`` in a fresh process
and prints that process's peak resident memory (``ru_maxrss``). Without ``RUN`` it first
makes a small run with a 64 MP and an 8 MP camera (six frames, ``deckpose pipeline``,
in a temporary folder, a few minutes on 2 cores).

Usage::

    .venv/bin/python benchmarks/bench_report_memory.py [RUN]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

TARGET_GIB = 1.5

CONFIG = textwrap.dedent("""\
    name: report_memory
    seed: 5
    backend: egl
    cameras: [{preset: 64mp}, {preset: 8mp}]
    heights_m: [40]
    lighting: [night]
    motion: {source: thesis, every: 50, max_samples: 3}
    sensor: {bit_depth: 8, read_noise_e: 5}
    scene: {shading: flat}
    layout: {n_ring: 12, radius_m: 10.0, has_centre: false}
    """)

CHILD = ("import resource, sys\n"
         "from deckpose.cli import main\n"
         "rc = main(['report', sys.argv[1]])\n"
         "print('PEAK_KIB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
         "sys.exit(rc)\n")


def peak_report_gib(run: Path) -> float:
    """Peak resident memory of ``deckpose report run`` in its own process, GiB."""
    out = subprocess.run([sys.executable, "-c", CHILD, str(run)], capture_output=True, text=True, check=True)
    kib = next(int(line.split()[1]) for line in out.stdout.splitlines() if line.startswith("PEAK_KIB"))
    return kib / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?", type=Path, help="an evaluated run folder (default: make one)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="deckpose-report-mem-") as tmp:
        run = args.run
        if run is None:
            cfg = Path(tmp) / "config.yaml"
            cfg.write_text(CONFIG)
            run = Path(tmp) / "run"
            subprocess.run([sys.executable, "-m", "deckpose", "pipeline", str(cfg), str(run), "--workers", "1",
                            "--detector", "cog", "--method", "pnp", "--no-mcap", "--no-progress"],
                           check=True, stdout=subprocess.DEVNULL)
        import pandas as pd

        frames = pd.read_parquet(run / "frames.parquet")
        cams = sorted(frames["camera"].unique())
        peak = peak_report_gib(run)
        load = os.getloadavg()[0]
        print(f"deckpose report on {run} ({len(frames)} frames; cameras {', '.join(cams)}): "
              f"peak resident memory {peak:.2f} GiB (target <= {TARGET_GIB} GiB: "
              f"{'met' if peak <= TARGET_GIB else 'NOT met'}); 1-minute load {load:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
