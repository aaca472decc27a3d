"""``deckpose evaluate``: join a run's stages into errors, resolution tables and an MCAP log."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate.errors import frame_errors, run_errors
from deckpose.evaluate.resolution_tables import resolution_markdown, resolution_table

from deckpose import run_folder as rl
from deckpose.atomic_io import atomic_open
from deckpose.camera import CameraModel
from deckpose.errors import InputDataError
from deckpose.layout import DeckLayout
from deckpose.preview import PREVIEW_PX
from deckpose.shell_command import deckpose_command
from deckpose.tables import read_table, write_table


def frame_crb(run: rl.RunPaths, frames: pd.DataFrame, centroid_rms_px: pd.Series, *, workers: int = 1,
              scheduler: str | None = None) -> pd.DataFrame:
    """Per-frame Cramér–Rao bound of roll, pitch, yaw (deg) and height (m).

    The pixel noise of a frame is taken as the detector's measured per-axis
    centroid error there (centroid RMS / sqrt(2)), so the bound says how well any
    unbiased estimator could do with those detections. NaN where unknown.

    ``workers`` processes (or a Dask ``scheduler``'s workers) compute one chunk of at least
    :data:`MIN_CRB_TASK_FRAMES` frames each (fewer frames: this process); a frame's bound
    depends on that frame alone, so the table is the same for any ``workers``.
    """
    import contextlib

    from deckpose.worker_pool import map_ordered, task_count

    layout = rl.read_layout(run)
    cameras = rl.read_cameras(run, sorted(frames["camera"].unique()))
    rms = np.array([float(centroid_rms_px.get(int(f), float("nan"))) for f in frames["frame_id"]])
    bounds = np.array_split(np.arange(len(frames)),
                            task_count(len(frames), MIN_CRB_TASK_FRAMES, workers=workers, scheduler=scheduler))
    tasks = [_CrbTask(layout, cameras, frames.iloc[b], rms[b]) for b in bounds]
    with contextlib.closing(map_ordered(_crb_task, tasks, workers=workers, scheduler=scheduler)) as done:
        rows = [r for chunk in done for r in chunk]
    return pd.DataFrame(rows, columns=list(CRB_COLUMNS))


#: The columns of :func:`frame_crb`'s table.
CRB_COLUMNS = ("frame_id", "crb_roll_deg", "crb_pitch_deg", "crb_yaw_deg", "crb_height_m")
#: Fewest frames of one worker's task of :func:`frame_crb`: a bound costs about 2 ms (1.8 ms at load
#: 8), starting two workers that import it 8-14 s on this shared 2-core machine (benchmarks/bench_stage_workers.py,
#: reports/throughput/stage_workers.txt), so smaller tasks cannot win that back.
MIN_CRB_TASK_FRAMES = 4096


@dataclass(frozen=True)
class _CrbTask:
    """Frames whose bounds one worker computes (:func:`_crb_task`)."""

    layout: DeckLayout
    cameras: dict[str, CameraModel]
    frames: pd.DataFrame
    centroid_rms_px: np.ndarray


def _crb_task(task: _CrbTask) -> list[dict[str, float]]:
    """The rows of :func:`frame_crb` of one task's frames (the workers' entry point)."""
    import math

    from deckpose.estimate.crb import cramer_rao_bound

    from deckpose.records import POSE_PARAMS

    idx = {p: i for i, p in enumerate(POSE_PARAMS)}
    rows = []
    for (_, fr), rms in zip(task.frames.iterrows(), task.centroid_rms_px, strict=True):
        f = int(fr["frame_id"])
        out = {"frame_id": f, "crb_roll_deg": math.nan, "crb_pitch_deg": math.nan,
               "crb_yaw_deg": math.nan, "crb_height_m": math.nan}
        if math.isfinite(rms) and rms > 0:
            ship, pose = rl.frame_poses(fr)
            cov = cramer_rao_bound(task.layout, task.cameras[fr["camera"]], ship, pose, rms / math.sqrt(2.0)).covariance
            sd = np.sqrt(np.diag(cov))
            out.update(crb_roll_deg=math.degrees(sd[idx["roll_rad"]]), crb_pitch_deg=math.degrees(sd[idx["pitch_rad"]]),
                       crb_yaw_deg=math.degrees(sd[idx["yaw_rad"]]), crb_height_m=float(sd[idx["height_m"]]))
        rows.append(out)
    return rows


def compute_errors(run: rl.RunPaths, *, workers: int = 1, scheduler: str | None = None) -> pd.DataFrame:
    """Per-frame errors of every (detector, method) pair with estimates in the run.

    ``workers`` (or a Dask ``scheduler``) compute the Cramér–Rao bounds (:func:`frame_crb`), the
    per-frame part; the table is the same for any ``workers``.
    """
    frames = rl.read_frames(run)
    beacons = rl.read_beacons(run)
    pairs = run.estimate_pairs()
    if not pairs:
        dets = run.detectors()
        hint = (deckpose_command("estimate", "--run", run.root, "--detector", dets[0], "--method", "pnp") if dets
                else f"{deckpose_command('detect', run.root, '--detector', 'cog')}, then "
                     f"{deckpose_command('estimate', '--run', run.root, '--detector', 'cog')}")
        raise InputDataError(f"{run.root} has no estimates (folder {run.root / 'estimates'}); make them with: {hint}")
    parts = []
    crb_by_detector: dict[str, pd.DataFrame] = {}
    for det, method in pairs:
        e = rl.read_estimates(run, det, method)
        if det == rl.RING_DETECTOR:  # painted-ring: one row of fitted ellipses per frame, no beacon centroids
            rl.check_frames_match(frames, e, f"estimates of {det}+{method}", deckpose_command("painted-ring", run.root))
            errs = frame_errors(frames, e)
            errs.insert(1, "detector", det)
            parts.append(errs)
            continue
        d = rl.read_detections(run, det)
        rl.check_frames_match(frames, d, f"detections of {det}",
                              deckpose_command("detect", run.root, "--detector", det))
        rl.check_frames_match(frames, e, f"estimates of {det}+{method}",
                              deckpose_command("estimate", "--run", run.root, "--detector", det, "--method", method))
        errs = run_errors(frames, beacons, d, e, det)
        if det not in crb_by_detector:
            rms = errs.set_index("frame_id")["centroid_rms_px"]
            crb_by_detector[det] = frame_crb(run, frames[frames["frame_id"].isin(errs["frame_id"])], rms,
                                             workers=workers, scheduler=scheduler)
        parts.append(errs.merge(crb_by_detector[det], on="frame_id", how="left"))
    return pd.concat(parts, ignore_index=True)


def evaluate_run(run: rl.RunPaths, *, mcap: bool = True, preview_px: int = PREVIEW_PX,
                 command: Sequence[str] = (), progress: Callable[[int, int], object] | None = None,
                 workers: int = 1, scheduler: str | None = None) -> dict[str, Path]:
    """Write errors, resolution tables, the MCAP log and its Foxglove layout; return their paths.

    ``command`` (the command line that asked for it) is recorded in the log's metadata.
    ``workers`` local processes (0 or 1: this one) compute the per-frame parts side by side:
    the Cramér–Rao bounds (:func:`compute_errors`; on a Dask ``scheduler``'s workers when one
    is given) and the log's messages (:func:`write_log`); this process writes every file, in
    frame order, so none depends on ``workers``.
    ``progress(done, total)`` counts the run's frames: once when their errors are computed
    (every frame at once), then as each is logged (``mcap``), so ``total`` is the frames
    times 1 or 2.
    """
    n_frames = len(rl.read_frames(run))
    steps = n_frames * (2 if mcap else 1)
    errors = compute_errors(run, workers=workers, scheduler=scheduler)
    if progress is not None:
        progress(n_frames, steps)
    out = run.evaluation_dir
    write_table(errors, run.errors, "errors")
    table = resolution_table(errors)
    write_table(table, out / "resolution_tables.csv", "resolution tables")
    with atomic_open(out / "resolution_tables.md", "w") as fh:
        fh.write(resolution_markdown(table))
    paths = {"errors": run.errors, "tables": out / "resolution_tables.md"}
    if mcap:
        logged = None if progress is None else (lambda done, _total: progress(n_frames + done, steps))
        paths.update(write_log(run, errors=errors, preview_px=preview_px, command=command, progress=logged,
                               workers=workers))
    return paths


def track_horizons(run: rl.RunPaths) -> list[tuple[str, str, str, list[float]]]:
    """``(detector, method, tracker, horizons_s)`` of every track of the run, horizons ascending."""
    out = []
    for d, m, t in run.track_triples():
        horizons = rl.read_track_predictions(run, d, m, t)["horizon_s"].to_numpy(float)
        out.append((d, m, t, sorted({float(h) for h in horizons})))
    return out


def write_log(run: rl.RunPaths, *, errors: pd.DataFrame | None = None, preview_px: int = PREVIEW_PX,
              command: Sequence[str] = (), progress: Callable[[int, int], object] | None = None,
              workers: int = 1) -> dict[str, Path]:
    """Write the run's MCAP log and its Foxglove layout; return their paths (``mcap``, ``layout``).

    The log attaches the run's report when there is one, so the pipeline writes it after
    the report. ``errors`` (from :func:`compute_errors`) saves reading them again; without
    it, the run's ``evaluation/errors.parquet`` is read when there is one, and the layout
    plots the errors the log holds. ``progress(done, total)`` counts the frames logged.
    ``workers`` local processes build the frames' messages
    (:func:`~deckpose.evaluate.mcap_log.write_run_log`; they read the run's previews, so they
    run on this machine even where the other stages use a Dask scheduler).
    """
    from deckpose.evaluate.foxglove_layout import foxglove_layout
    from deckpose.evaluate.mcap_log import write_run_log

    if errors is None and run.errors.is_file():
        errors = read_table(run.errors, "errors")
    mcap = write_run_log(run, errors=errors, preview_px=preview_px, command=command, progress=progress,
                         workers=workers)
    layout_path = run.root / "foxglove_layout.json"
    plotted = sorted({(str(d), str(m)) for d, m in zip(errors["detector"], errors["method"])}) if errors is not None else []
    with atomic_open(layout_path, "w") as fh:
        json.dump(foxglove_layout(run.detectors(), plotted, track_horizons(run)), fh, indent=1)
    return {"mcap": mcap, "layout": layout_path}
