"""The thesis's tables 4.2-4.13 and 4.15 for several estimators side by side.

Same experiment as :mod:`deckpose.evaluate.thesis_tables` (eq. 4.1 noise on the
495-sample series), run for each estimator with the same random draws per cell,
so differences between columns come from the estimators alone. The Markdown
goes between two marker comments in ``reports/estimators.md`` (created if
missing), leaving the rest of that file alone.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate import thesis_reference as ref
from deckpose.evaluate.thesis_sim import (
    CellResult,
    CellSpec,
    load_thesis_motion,
    registry_batch_estimator,
    simulate_cell,
    thesis_batch_estimator,
)
from deckpose.evaluate.thesis_tables import HEIGHTS, HEIGHTS_8MP_8PX, NOISE_PX, RESOLUTIONS

from deckpose.atomic_io import atomic_open
from deckpose.shell_command import deckpose_command
from deckpose.tables import write_table

START = "<!-- estimator-thesis-tables:start -->"
END = "<!-- estimator-thesis-tables:end -->"
_Q = ("roll", "pitch", "yaw", "height")


def _cells() -> list[CellSpec]:
    specs = [CellSpec(r, n, h) for r in RESOLUTIONS for n in NOISE_PX for h in HEIGHTS]
    return specs + [CellSpec("8mp", 8, h) for h in HEIGHTS_8MP_8PX if h not in HEIGHTS]


def _one(args: tuple[int, CellSpec, str, int, int]) -> tuple[str, CellResult]:
    index, spec, method, repetitions, seed = args
    # Same seed for every method in a cell: identical noise draws.
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))
    est = thesis_batch_estimator if method == "thesis" else registry_batch_estimator(method)
    return method, simulate_cell(spec, load_thesis_motion(), repetitions, rng, estimator=est)


def run_estimator_cells(methods: Sequence[str], repetitions: int, seed: int, workers: int = 0,
                        progress: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """Long table: method, resolution, noise_px, height, quantity, value (max/sigma), n_ok, n_images."""
    jobs = [(i, s, m, repetitions, seed) for i, s in enumerate(_cells()) for m in methods]
    rows = []
    n = workers or os.cpu_count() or 1
    with ProcessPoolExecutor(max_workers=n) as pool:
        for k, (method, r) in enumerate(pool.map(_one, jobs)):
            base = {"method": method, "resolution": r.spec.resolution, "noise_px": int(r.spec.noise_px),
                        "height": int(r.spec.height), "n_ok": r.n_ok, "n_images": r.n_images}
            for q, mx, sg in zip(_Q, r.max_abs, r.sigma):
                rows.append(dict(base, quantity=f"max_{q}", value=float(mx)))
                rows.append(dict(base, quantity=f"sigma_{q}", value=float(sg)))
            if progress:
                progress(k + 1, len(jobs))
    return pd.DataFrame(rows)


def _fmt(v: float, d: int = 3) -> str:
    return "fail" if not np.isfinite(v) else f"{v:.{d}f}"


def estimator_markdown(df: pd.DataFrame, methods: Sequence[str], repetitions: int, seed: int, seconds: float,
                       out_dir: str = "reports") -> str:
    piv = df.pivot_table(index=["resolution", "noise_px", "height", "quantity"], columns="method", values="value")
    ok = df.groupby("method")[["n_ok", "n_images"]].sum()
    lines = [START, "", "## The thesis's tables for every estimator", "",
             f"The thesis's experiment (eq. 4.1 noise, 495-sample motion, no centre beacon) with {repetitions} x 495 "
             f"images per cell (the thesis used 500 x 495), seed {seed}, identical noise draws for every estimator; "
             f"{seconds:.0f} s on {os.cpu_count()} cores. Each cell: **published thesis / "
             + " / ".join(methods) + "**; angles in the thesis's convention, degrees; height in units. "
             "Maxima grow with the number of images, so at fewer images than the thesis compare the columns "
             "among themselves; the full-scale thesis estimator is in `thesis_tables.md`. "
             "Regenerate: `" + deckpose_command("estimator-tables", "--method", ",".join(methods), "--repetitions",
                                                str(repetitions), "--seed", str(seed), "-o", out_dir) + "`.", "",
             "Frames estimated ok: " + ", ".join(f"{m} {ok['n_ok'].loc[m] / ok['n_images'].loc[m]:.2%}" for m in methods) + ".", ""]
    # How much each beats the published numbers, as one line per method.
    mx = df[df.quantity.isin([f"max_{q}" for q in ("roll", "pitch", "height")])]
    for m in methods:
        ratios = []
        for _, r in mx[mx.method == m].iterrows():
            pub = ref.MAX_ERROR[(r.resolution, r.noise_px)].get(r.height)
            if pub is None:
                continue
            t = pub[("roll", "pitch", "yaw", "height").index(r.quantity[4:])]
            ratios.append(r.value / t)
        if ratios:
            lines.append(f"- `{m}`: roll/pitch/height maxima are {np.median(ratios):.2f}x the published thesis values (median over cells).")
    for (res, noise), num in sorted(ref.TABLE_NUMBER.items(), key=lambda kv: kv[1]):
        lines += ["", f"### Table 4.{num}: max absolute error [{res.upper()} - {noise} px]", "",
                  "| Height | Roll [deg] | Pitch [deg] | Yaw [deg] | Height [U] |", "|---|---|---|---|---|"]
        for h in HEIGHTS:
            pub = ref.MAX_ERROR[(res, noise)][h]
            cells = []
            for qi, q in enumerate(_Q):
                vals = [_fmt(piv[m].loc[(res, noise, h, f"max_{q}")]) for m in methods]
                cells.append(" / ".join([f"{pub[qi]:.3f}"] + vals))
            lines.append(f"| {h} | " + " | ".join(cells) + " |")
    lines += ["", "### Table 4.15: error sigma [8MP - 8 px]", "",
              "| Height | Roll [deg] | Pitch [deg] | Yaw [deg] | Height [U] |", "|---|---|---|---|---|"]
    for h in HEIGHTS_8MP_8PX:
        pub = ref.SIGMA[h]
        cells = [" / ".join([f"{pub[qi]:.4f}"] + [_fmt(piv[m].loc[("8mp", 8, h, f"sigma_{q}")], 4) for m in methods])
                 for qi, q in enumerate(_Q)]
        lines.append(f"| {h} | " + " | ".join(cells) + " |")
    lines += ["", END]
    return "\n".join(lines)


def write_estimator_tables(out_dir: Path, methods: Sequence[str], repetitions: int = 20, seed: int = 20221,
                           workers: int = 0, progress: Callable[[int, int], None] | None = None) -> Path:
    """Run the comparison and splice it into ``out_dir/estimators.md``; also write a CSV."""
    t0 = time.perf_counter()
    df = run_estimator_cells(methods, repetitions, seed, workers, progress)
    section = estimator_markdown(df, methods, repetitions, seed, time.perf_counter() - t0, os.fspath(out_dir))
    out_dir.mkdir(parents=True, exist_ok=True)
    write_table(df, out_dir / "estimators_thesis_tables.csv", "estimator tables")
    md = out_dir / "estimators.md"
    old = md.read_text() if md.exists() else "# Estimators\n"
    if START in old and END in old:
        new = re.sub(re.escape(START) + ".*?" + re.escape(END), lambda _: section, old, flags=re.DOTALL)
    else:
        new = old.rstrip("\n") + "\n\n" + section + "\n"
    with atomic_open(md, "w") as fh:
        fh.write(new)
    return md
