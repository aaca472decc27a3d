"""Reproduce the thesis's Tables 4.2-4.15 and write them beside the published values.

One command (``deckpose thesis-tables``) runs every cell with
:func:`deckpose.evaluate.thesis_sim.simulate_cell`, in parallel processes, each
cell seeded from ``(seed, cell index)`` so results do not depend on the number
of workers, and writes ``thesis_tables.md``, ``thesis_tables.csv`` and a
manifest (config, seed, versions, timing) into the output folder.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate import thesis_reference as ref
from deckpose.evaluate.thesis_sim import CellResult, CellSpec, load_thesis_motion, simulate_cell

from deckpose.atomic_io import atomic_open
from deckpose.errors import ConfigError
from deckpose.shell_command import deckpose_command
from deckpose.tables import write_table

RESOLUTIONS = ("4mp", "8mp", "16mp", "64mp")
NOISE_PX = (8, 6, 4)
HEIGHTS = (20, 30, 40, 50, 80)
#: Tables 4.14 and 4.15 also have 60 units (8 MP, 8 px).
HEIGHTS_8MP_8PX = (20, 30, 40, 50, 60, 80)
QUANTITIES = ("roll_deg", "pitch_deg", "yaw_deg", "height")


@dataclass(frozen=True)
class ThesisTablesConfig:
    """What to run. Defaults are the thesis's full scale (500 x 495 images per cell)."""

    repetitions: int = 500
    seed: int = 20221
    workers: int = 0  # 0 = one per CPU core

    def __post_init__(self) -> None:
        if self.repetitions < 1:
            raise ConfigError(f"repetitions must be at least 1, got {self.repetitions}")
        if self.workers < 0:
            raise ConfigError(f"workers must be >= 0 (0 = all cores), got {self.workers}")


def cell_specs() -> list[CellSpec]:
    """Every cell the tables need, in a fixed order (the order defines the seeds)."""
    specs = [CellSpec(r, n, h) for r in RESOLUTIONS for n in NOISE_PX for h in HEIGHTS]
    specs += [CellSpec("8mp", 8, h) for h in HEIGHTS_8MP_8PX if h not in HEIGHTS]
    return specs


def _run_one(args: tuple[int, CellSpec, int, int]) -> CellResult:
    index, spec, repetitions, seed = args
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))
    return simulate_cell(spec, load_thesis_motion(), repetitions, rng)


def run_cells(
    config: ThesisTablesConfig, progress: Callable[[int, int], object] | None = None
) -> list[CellResult]:
    """Simulate every cell; ``progress(done, total)`` is called as cells finish."""
    specs = cell_specs()
    jobs = [(i, s, config.repetitions, config.seed) for i, s in enumerate(specs)]
    workers = config.workers or os.cpu_count() or 1
    results: list[CellResult] = []
    if workers == 1:
        for j in jobs:
            results.append(_run_one(j))
            if progress:
                progress(len(results), len(jobs))
        return results
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for r in pool.map(_run_one, jobs):
            results.append(r)
            if progress:
                progress(len(results), len(jobs))
    return results


def results_frame(results: list[CellResult]) -> pd.DataFrame:
    """Long table: one row per table cell with ours, thesis and ratio."""
    rows = []
    for r in results:
        s = r.spec
        key = (s.resolution, int(s.noise_px))
        h = int(s.height)
        if key in ref.TABLE_NUMBER and h in ref.MAX_ERROR[key]:
            theirs = ref.MAX_ERROR[key][h]
            ours = list(r.max_abs) + [r.rms_mean_px, r.rms_sigma_px]
            names = ["max_" + q for q in QUANTITIES] + ["rms_mean_px", "rms_sigma_px"]
            for name, o, t in zip(names, ours, theirs):
                rows.append({"table": f"Table 4.{ref.TABLE_NUMBER[key]}", "resolution": s.resolution,
                                 "noise_px": int(s.noise_px), "height": h, "quantity": name, "ours": o, "thesis": t})
        if key == ("8mp", 8) and h in ref.YZ2:
            for name, o, t in zip(("yz2_within_sigma_pct", "yz2_sign_pct"),
                                  (r.yz2_within_sigma_pct, r.yz2_sign_pct), ref.YZ2[h]):
                rows.append({"table": "Table 4.14", "resolution": "8mp", "noise_px": 8, "height": h, "quantity": name, "ours": o, "thesis": t})
            for name, o, t in zip(["sigma_" + q for q in QUANTITIES], r.sigma, ref.SIGMA[h]):
                rows.append({"table": "Table 4.15", "resolution": "8mp", "noise_px": 8, "height": h, "quantity": name, "ours": o, "thesis": t})
    df = pd.DataFrame(rows)
    df["ratio"] = df["ours"] / df["thesis"]
    return df


def _fmt(v: float, digits: int) -> str:
    return f"{v:.{digits}f}"


def _cell(o: float, t: float, digits: int) -> str:
    return f"{_fmt(o, digits)} / {_fmt(t, digits)} / {o / t:.2f}"


def markdown_report(df: pd.DataFrame, results: list[CellResult], config: ThesisTablesConfig,
                    seconds: float, out_dir: Path | str = "reports") -> str:
    """The Markdown report: every table as ``ours / thesis / ratio``, plus an honest summary."""
    n_img = results[0].n_images if results else 0
    lines = [
        "# The thesis's tables 4.2-4.15, reproduced",
        "",
        "Each cell reads **ours / thesis / ratio** (ours divided by the thesis's value).",
        (f"Set-up: the reference page's reconstruction of the thesis experiment: 12 beacons on a "
        f"radius-10 ring, thesis camera (75 deg focal angle, non-square eq. 1.8/1.9), the 495-sample "
        f"regular-wave motion series, camera distance = table height + heave, beacons outside the "
        f"image dropped, eq. 4.1-4.3 noise, the faithful `thesis` estimator. "
        f"{config.repetitions} repetitions x 495 samples = {n_img:,} images per row; seed {config.seed}; "
        f"{len(results)} cells in {seconds:.0f} s on {platform.machine()} with {os.cpu_count()} cores "
        f"({config.workers or os.cpu_count()} worker processes)."),
        "",
        ("Regenerate with `" + deckpose_command("thesis-tables", "--repetitions", str(config.repetitions),
                                                "--seed", str(config.seed), "-o", out_dir) + "`."),
        "",
    ]
    lines += _summary(df, results, n_img)
    for (res, noise), num in sorted(ref.TABLE_NUMBER.items(), key=lambda kv: kv[1]):
        sub = df[(df.table == f"Table 4.{num}")]
        lines += ["", f"## Table 4.{num}: estimation max absolute error [{res.upper()} - {noise} pixels noise]", "",
                  "| Height | Roll [deg] | Pitch [deg] | Yaw [deg] | Height [U] | RMS [px] | sigma [px] |",
                  "|---|---|---|---|---|---|---|"]
        for h in HEIGHTS:
            row = sub[sub.height == h].set_index("quantity")
            ours, thesis = row["ours"], row["thesis"]
            cells = [_cell(ours.loc["max_" + q], thesis.loc["max_" + q], 3) for q in QUANTITIES]
            cells += [_cell(ours.loc[q], thesis.loc[q], 2) for q in ("rms_mean_px", "rms_sigma_px")]
            lines.append(f"| {h} [U] | " + " | ".join(cells) + " |")
    sub = df[df.table == "Table 4.14"]
    lines += ["", "## Table 4.14: Y''_z estimate accuracy [8MP - 8 pixels noise]", "",
              "| Height | Y''_z error within one sigma [%] | sign(Y''_z) accuracy [%] |", "|---|---|---|"]
    for h in HEIGHTS_8MP_8PX:
        row = sub[sub.height == h].set_index("quantity")
        ours, thesis = row["ours"], row["thesis"]
        lines.append(f"| {h} [U] | " + " | ".join(
            _cell(ours.loc[q], thesis.loc[q], 2) for q in ("yz2_within_sigma_pct", "yz2_sign_pct")) + " |")
    sub = df[df.table == "Table 4.15"]
    lines += ["", "## Table 4.15: USV orientation estimation sigma [8MP - 8 pixels noise]", "",
              "| Height | Roll sigma [deg] | Pitch sigma [deg] | Yaw sigma [deg] | Height sigma [U] |", "|---|---|---|---|---|"]
    for h in HEIGHTS_8MP_8PX:
        row = sub[sub.height == h].set_index("quantity")
        ours, thesis = row["ours"], row["thesis"]
        lines.append(f"| {h} [U] | " + " | ".join(
            _cell(ours.loc["sigma_" + q], thesis.loc["sigma_" + q], 4) for q in QUANTITIES) + " |")
    fails = sum(sum(r.failures.values()) for r in results)
    total = sum(r.n_images for r in results)
    lines += ["", "## Failures", "",
              f"{fails} of {total:,} estimates were flagged not ok "
              + ("(none)." if not fails else "; by reason: " + ", ".join(
                  f"{k}: {v}" for k, v in _sum_failures(results).items()) + ". Maxima are over ok estimates.")]
    return "\n".join(lines) + "\n"


def _sum_failures(results: list[CellResult]) -> dict[str, int]:
    out: dict[str, int] = {}
    for r in results:
        for k, v in r.failures.items():
            out[k] = out.get(k, 0) + v
    return out


def _mean(df: pd.DataFrame, quantity: str, column: str) -> float:
    return float(df[df.quantity == quantity][column].mean())


def _summary(df: pd.DataFrame, results: list[CellResult], n_draws: int) -> list[str]:
    """Plain statements of where we agree and where we do not, computed from the numbers."""
    mx = df[df.table.isin([f"Table 4.{n}" for n in range(2, 14)])]

    def med(q: str, heights: tuple[int, ...] = HEIGHTS) -> float:
        s = mx[(mx.quantity == q) & mx.height.isin(heights)]
        return float(s.ratio.median())

    sig = df[df.table == "Table 4.15"]
    t14 = df[df.table == "Table 4.14"]
    rp = mx[mx.quantity.isin(["max_roll_deg", "max_pitch_deg"])].ratio
    out = [
        "## Summary",
        "",
        (f"- **Roll and pitch maxima** (Tables 4.2-4.13): median ratio {rp.median():.2f} "
        f"(range {rp.min():.2f}-{rp.max():.2f}) over {len(rp)} cells. Maxima of {n_draws:,} draws "
        "are themselves noisy, so single cells scatter around the median."),
        (f"- **Image RMS** of the injected noise: median ratio {med('rms_mean_px'):.2f} (mean), "
        f"{med('rms_sigma_px'):.2f} (sigma)."),
        (f"- **Table 4.15 sigma**: roll {sig[sig.quantity == 'sigma_roll_deg'].ratio.median():.3f}, "
        f"pitch {sig[sig.quantity == 'sigma_pitch_deg'].ratio.median():.3f}, "
        f"yaw {sig[sig.quantity == 'sigma_yaw_deg'].ratio.median():.3f}, "
        f"height {sig[sig.quantity == 'sigma_height'].ratio.median():.3f} (median ratios)."),
        (f"- **Yaw**: median ratio of the yaw maxima {med('max_yaw_deg'):.2f}; expect no agreement: the thesis's "
        "own motion input for yaw is unknown (the published series' \"yaw\" is a synthetic heave*sin(t) "
        "signal), so we do not tune toward its yaw column."),
        (f"- **Height**: median ratio of the maxima {med('max_height', (80,)):.2f} at 80 U "
        f"against {med('max_height', (20, 30, 40, 50)):.2f} at 20-50 U."),
        (f"- **Table 4.14** (Y''_z, 8 MP, 8 px): sign accuracy ours {_mean(t14, 'yz2_sign_pct', 'ours'):.1f}% "
        f"vs thesis {_mean(t14, 'yz2_sign_pct', 'thesis'):.1f}% (mean over heights); errors within one sigma ours "
        f"{_mean(t14, 'yz2_within_sigma_pct', 'ours'):.1f}% vs {_mean(t14, 'yz2_within_sigma_pct', 'thesis'):.1f}%. "
        "The thesis does not define the Y''_z error precisely; we use the difference from the noise-free "
        "estimate of the same sample, and a mismatch here says only that the definitions differ."),
        ("- Under this noise model the angle and height errors depend on the resolution only through "
        "p = N/||(W/2, H/2)|| (the relative size of the noise) and cropping; the thesis's \"pixelation "
        "effect\" is a scaling of injected noise, not real pixelation. Rendered frames measure the real thing."),
    ]
    return out


def write_outputs(out_dir: Path, results: list[CellResult], config: ThesisTablesConfig, seconds: float) -> Path:
    """Write ``thesis_tables.md``, ``thesis_tables.csv`` and ``thesis_tables.manifest.json``."""
    import deckpose

    out_dir.mkdir(parents=True, exist_ok=True)
    df = results_frame(results)
    write_table(df, out_dir / "thesis_tables.csv", "thesis tables")
    md = out_dir / "thesis_tables.md"
    with atomic_open(md, "w") as fh:
        fh.write(markdown_report(df, results, config, seconds, out_dir))
    manifest = {
        "config": asdict(config),
        "deckpose": deckpose.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "seconds": round(seconds, 1),
        "cells": [dict(asdict(r.spec), n_images=r.n_images, n_ok=r.n_ok, failures=r.failures) for r in results],
    }
    with atomic_open(out_dir / "thesis_tables.manifest.json", "w") as fh:
        json.dump(manifest, fh, indent=1)
    return md


def run_thesis_tables(config: ThesisTablesConfig, out_dir: Path,
                      progress: Callable[[int, int], object] | None = None) -> Path:
    """Run every cell and write the report; returns the Markdown path."""
    t0 = time.perf_counter()
    results = run_cells(config, progress)
    return write_outputs(Path(out_dir), results, config, time.perf_counter() - t0)
