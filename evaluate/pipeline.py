"""``deckpose evaluate``: join a run's stages into errors, resolution tables and an MCAP log."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from deckpose.atomic_io import atomic_open
from deckpose.errors import InputDataError
from deckpose.evaluate import run_layout as rl
from deckpose.evaluate.errors import run_errors
from deckpose.evaluate.resolution_tables import resolution_markdown, resolution_table
from deckpose.tables import write_table


def compute_errors(run: rl.RunPaths) -> pd.DataFrame:
    """Per-frame errors of every (detector, method) pair with estimates in the run."""
    frames = rl.read_frames(run)
    beacons = rl.read_beacons(run)
    pairs = run.estimate_pairs()
    if not pairs:
        dets = run.detectors()
        hint = (f"deckpose estimate --run {run.root} --detector {dets[0]} --method thesis" if dets
                else f"deckpose detect {run.root} --detector cog, then deckpose estimate --run {run.root} --detector cog")
        raise InputDataError(f"{run.root} has no estimates (folder {run.root / 'estimates'}); make them with: {hint}")
    parts = []
    for det, method in pairs:
        d = rl.read_detections(run, det)
        e = rl.read_estimates(run, det, method)
        rl.check_frames_match(frames, d, f"detections of {det}", f"deckpose detect {run.root} --detector {det}")
        rl.check_frames_match(frames, e, f"estimates of {det}+{method}",
                              f"deckpose estimate --run {run.root} --detector {det} --method {method}")
        parts.append(run_errors(frames, beacons, d, e, det))
    return pd.concat(parts, ignore_index=True)


def evaluate_run(run: rl.RunPaths, *, mcap: bool = True, preview_px: int = 1920) -> dict[str, Path]:
    """Write errors, resolution tables, the MCAP log and its Foxglove layout; return their paths."""
    errors = compute_errors(run)
    out = run.evaluation_dir
    write_table(errors, run.errors, "errors")
    table = resolution_table(errors)
    write_table(table, out / "resolution_tables.csv", "resolution tables")
    with atomic_open(out / "resolution_tables.md", "w") as fh:
        fh.write(resolution_markdown(table))
    paths = {"errors": run.errors, "tables": out / "resolution_tables.md"}
    if mcap:
        from deckpose.evaluate.mcap_log import foxglove_layout, write_run_log

        paths["mcap"] = write_run_log(run, errors=errors, preview_px=preview_px)
        layout_path = run.root / "foxglove_layout.json"
        with atomic_open(layout_path, "w") as fh:
            json.dump(foxglove_layout(run.detectors(), run.estimate_pairs()), fh, indent=1)
        paths["layout"] = layout_path
    return paths
