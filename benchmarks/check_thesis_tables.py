"""Re-run the README's full-scale thesis tables and compare them with the committed ones.

Runs ``deckpose thesis-tables -o OUT`` (the README's command: 500 passes over the 495-sample
series per cell, about 15 million estimates; 42 s on this 2-core machine when quiet, several
minutes under load) into a scratch folder, then compares ``thesis_tables.csv`` with the
committed ``reports/thesis_tables.csv``: the noise draws are seeded, so every value must agree
to a relative 1e-9 (floating-point summation order only). Prints the largest relative
difference and exits 1 on a mismatch.

This is heavy work and lives here, not in the test suite: the suite runs the same README
command at 4 repetitions (``tests/test_readme_examples.py``), which checks the command and its
outputs but cannot reproduce the committed maxima of 247,500 draws.

    .venv/bin/python benchmarks/check_thesis_tables.py
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtol", type=float, default=1e-9, help="largest relative difference allowed")
    args = ap.parse_args(argv)
    committed = pd.read_csv(ROOT / "reports" / "thesis_tables.csv")
    with tempfile.TemporaryDirectory() as tmp:
        print(f"load before: {' '.join(f'{x:.1f}' for x in os.getloadavg())}", flush=True)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "deckpose", "thesis-tables", "-o", tmp], check=True)
        seconds = time.perf_counter() - t0
        ours = pd.read_csv(Path(tmp) / "thesis_tables.csv")
    print(f"thesis-tables full scale: {seconds:.0f} s wall; "
          f"load after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    keys = ["table", "resolution", "noise_px", "height", "quantity"]
    if len(ours) != len(committed) or not ours[keys].equals(committed[keys]):
        print("MISMATCH: the cells or quantities differ from reports/thesis_tables.csv")
        return 1
    rel = np.abs(ours["ours"].to_numpy() - committed["ours"].to_numpy()) / np.maximum(
        np.abs(committed["ours"].to_numpy()), 1e-300)
    worst = float(np.max(rel))
    print(f"{len(ours)} values; largest relative difference from the committed table {worst:.2g} "
          f"(allowed {args.rtol:g})")
    return 0 if worst <= args.rtol else 1


if __name__ == "__main__":
    sys.exit(main())
