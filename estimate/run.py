"""The estimate stage: poses for a detections table or a whole run folder.

The CLI (``deckpose estimate``) and the pipeline both call these functions; they
parse nothing and print nothing. Frames go to :func:`~deckpose.estimate.batch.
estimate_batch` one camera at a time, which chunks them by its ``CHUNK_FRAMES``
(the one chunking policy) and advances ``progress`` per chunk.

With ``workers`` (or a Dask ``scheduler``) those chunks, a camera's ``CHUNK_FRAMES``
frames each (and its rest), are the tasks that :func:`deckpose.worker_pool.map_ordered`
runs side by side; the estimates are put back in frame order. The batches are the same
as in this process, so the table is the same, to the bit, for any number of workers (a
frame's estimate depends, at the rounding level, on the frames batched with it: about
1e-13 relative, so the batches must not depend on the workers). A run of fewer than
:data:`MIN_PARALLEL_FRAMES` frames is estimated here: a worker's start-up costs more than
it saves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from deckpose.estimate.batch import estimate_batch
from deckpose.estimate.registry import EstimateOptions, MethodSpec
from deckpose.estimate.results_table import estimates_frame

from deckpose.camera import CameraModel
from deckpose.counted import counted
from deckpose.errors import ConfigError, InputDataError
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate
from deckpose.shell_command import deckpose_command

if TYPE_CHECKING:
    from deckpose.run_folder import RunPaths

__all__ = ["MIN_PARALLEL_FRAMES", "EstimateRunResult", "estimate_inputs", "estimate_run", "estimate_table",
           "method_options", "read_estimate_inputs"]

#: ``progress(n)``: ``n`` more frames are done (what it returns is ignored).
Progress = Callable[[int], object]

#: Fewest frames estimated by worker processes; fewer are estimated in this process. A frame
#: costs about 7 ms a method at load 7-10, starting two workers that import the estimators 8-14 s,
#: and on a 990-frame run two workers took 3.0x one (benchmarks/bench_stage_workers.py,
#: reports/throughput/stage_workers.txt).
MIN_PARALLEL_FRAMES = 4096


@dataclass(frozen=True)
class EstimateRunResult:
    """What the estimate stage wrote.

    Attributes
    ----------
    path : Path
        The estimates table.
    table : pandas.DataFrame
        Its rows, one per frame (``ok``, ``reason``, the pose, sigmas, extras).
    """

    path: Path
    table: pd.DataFrame

    @property
    def n_frames(self) -> int:
        return len(self.table)

    @property
    def n_ok(self) -> int:
        return int(self.table["ok"].sum()) if len(self.table) else 0

    def summary(self) -> str:
        """One line: frames, how many ok and failed, where they went."""
        return f"{counted(self.n_frames, 'frame')}, {self.n_ok} ok, {self.n_frames - self.n_ok} failed -> {self.path}"


def method_options(spec: MethodSpec, sigma_px: float = 1.0) -> EstimateOptions:
    """The :class:`EstimateOptions` a method label's variant asks for (``pnp+mean``: posterior mean)."""
    return EstimateOptions(sigma_px=sigma_px, refine=spec.refine, posterior_mean=spec.posterior_mean)


def estimate_table(
    detections: pd.DataFrame,
    camera: CameraModel,
    layout: DeckLayout,
    spec: MethodSpec,
    *,
    sigma_px: float = 1.0,
    source: str = "detections",
    progress: Progress | None = None,
    workers: int = 1,
    scheduler: str | None = None,
) -> pd.DataFrame:
    """Poses for a detections table of one camera (``deckpose estimate DETECTIONS``).

    Frames whose detections are all unassigned (``beacon_id = -1``) are identified
    first, as ``deckpose detect`` does; where that fails the frame's reason says why.

    Parameters
    ----------
    detections : pandas.DataFrame
        Rows ``frame_id, beacon_id, u_px, v_px`` (optional covariance, ``is_bow`` or flux columns).
    camera : CameraModel
    layout : DeckLayout
    spec : MethodSpec
        The estimator and its variant.
    sigma_px : float, keyword-only
        Pixel sigma where detections carry no covariance.
    source : str, keyword-only
        How messages name the table (its path).
    progress : callable, optional, keyword-only
    workers : int, keyword-only
        Worker processes (0 or 1: this process), from :data:`MIN_PARALLEL_FRAMES` frames on;
        the table does not depend on it.
    scheduler : str, optional, keyword-only
        A Dask scheduler's address: the tasks run on its workers instead.

    Returns
    -------
    pandas.DataFrame
        One row per frame (:func:`~deckpose.estimate.results_table.estimates_frame`).
    """
    from deckpose.detections_io import detections_from_frame, identify_unassigned

    frames = detections_from_frame(detections, layout, source)
    frames, unidentified = identify_unassigned(detections, frames, layout, camera)
    group = _CameraFrames([frames[i] for i in frames], camera, None, np.arange(len(frames)))
    results = _estimate_groups(spec.name, [group], len(frames), layout, method_options(spec, sigma_px),
                               workers=workers, scheduler=scheduler, progress=progress)
    df = estimates_frame(results).assign(method=spec.label)
    if unidentified:  # the frame failed for want of ids: say so, not "0 usable"
        miss = df["frame_id"].isin(list(unidentified)) & ~df["ok"].astype(bool)
        df.loc[miss, "reason"] = df.loc[miss, "frame_id"].map(unidentified)
    return df


def estimate_run(
    run_dir: str | Path,
    spec: MethodSpec,
    *,
    detector: str | None = None,
    sigma_px: float = 1.0,
    radius_m: float | None = None,
    progress: Progress | None = None,
    workers: int = 1,
    scheduler: str | None = None,
) -> EstimateRunResult:
    """Estimate every frame of a run folder and write ``RUN/estimates/DETECTOR--LABEL.parquet``.

    Each frame gets its own camera and camera attitude from the run's frames table;
    frames of one camera are estimated as one batch. The output is named after the
    variant's label (``cog--pnp+mean.parquet``), so a method's variants sit side by side.

    Parameters
    ----------
    run_dir : str or Path
        A rendered run with ``detections/DETECTOR.parquet``.
    spec : MethodSpec
    detector : str, optional, keyword-only
        Whose detections; default the run's only detector.
    sigma_px : float, keyword-only
    radius_m : float, optional, keyword-only
        Ring radius instead of the run's layout's.
    progress : callable, optional, keyword-only
    workers : int, keyword-only
        Worker processes (0 or 1: this process); the table does not depend on it.
    scheduler : str, optional, keyword-only
        A Dask scheduler's address: the tasks run on its workers instead.

    Returns
    -------
    EstimateRunResult

    Raises
    ------
    ConfigError
        No detector given where the run has several (or none).
    InputDataError
        A missing dataset or detections table, or detections of other frames.
    """
    from deckpose.tables import write_table

    run, detector, layout, frames, cameras, dets = read_estimate_inputs(run_dir, detector=detector,
                                                                      radius_m=radius_m)
    df = estimate_inputs(frames, dets, cameras, layout, spec, sigma_px=sigma_px, progress=progress,
                         workers=workers, scheduler=scheduler)
    out = run.estimates(detector, spec.label)
    write_table(df, out, "estimates")
    return EstimateRunResult(out, df)


def read_estimate_inputs(run_dir: str | Path, *, detector: str | None = None, radius_m: float | None = None
                         ) -> tuple[RunPaths, str, DeckLayout, pd.DataFrame, dict[str, CameraModel],
                                    dict[int, Detections]]:
    """What the estimate stage reads from a run folder, checked (see :func:`estimate_run`).

    Returns
    -------
    run, detector, layout, frames, cameras, detections
        The run's paths, the detector (resolved when ``None``), the layout (with ``radius_m``),
        the frames table, the cameras by name and each frame's detections by frame id.
    """
    from deckpose import run_folder as rl
    from deckpose.detections_io import detections_from_frame
    from deckpose.output_folder import claim_output

    run = rl.run_paths(run_dir)
    rl.require_dataset(run)  # a missing folder says so, not "no detections"
    claim_output(run.root, what="estimate")
    if detector is None:
        detectors = run.detectors()
        if not detectors:
            raise InputDataError(f"{run.root} has no detections yet; make them with: "
                                 + deckpose_command("detect", run.root, "--detector", "cog"))
        if len(detectors) != 1:
            raise ConfigError(f"--run needs --detector: this run has detections of {', '.join(detectors)}")
        detector = detectors[0]
    layout = rl.read_layout(run)
    if radius_m is not None:
        layout = dataclasses.replace(layout, radius_m=float(radius_m))
    frames = rl.read_frames(run)
    cameras = rl.read_cameras(run, sorted(frames["camera"].unique()))
    det_df = rl.read_detections(run, detector)
    rl.check_frames_match(frames, det_df, f"detections of {detector}",
                          deckpose_command("detect", run.root, "--detector", detector))
    dets = detections_from_frame(det_df, layout, str(run.detections(detector)))
    return run, detector, layout, frames, cameras, dets


def estimate_inputs(frames: pd.DataFrame, dets: dict[int, Detections], cameras: dict[str, CameraModel],
                    layout: DeckLayout, spec: MethodSpec, *, sigma_px: float = 1.0,
                    progress: Progress | None = None, workers: int = 1,
                    scheduler: str | None = None) -> pd.DataFrame:
    """The estimates table of a run's frames (:func:`read_estimate_inputs`): frames of one camera as one batch.

    With ``workers`` >= 2 (or a ``scheduler``) and at least :data:`MIN_PARALLEL_FRAMES`
    frames, the batches (a camera's ``CHUNK_FRAMES`` frames) are estimated side by side
    (:func:`deckpose.worker_pool.map_ordered`); the table is the same for any ``workers``.
    """
    from deckpose import run_folder as rl

    ids = [int(f) for f in frames["frame_id"]]
    R_all = rl.R_world_from_cam_all(frames)
    no_detections = np.zeros((0, 2))
    groups = []
    for cam_name, rows in frames.groupby("camera", sort=True).indices.items():
        dets_cam = [dets.get(ids[k], Detections(no_detections, np.zeros(0, dtype=np.int64), frame_id=ids[k]))
                    for k in rows]
        groups.append(_CameraFrames(dets_cam, cameras[str(cam_name)], R_all[rows], np.asarray(rows)))
    results = _estimate_groups(spec.name, groups, len(ids), layout, method_options(spec, sigma_px),
                               workers=workers, scheduler=scheduler, progress=progress)
    return estimates_frame(results).assign(method=spec.label)


@dataclass(frozen=True)
class _CameraFrames:
    """Frames of one camera to estimate: their detections, attitudes and places in the output."""

    detections: list[Detections]
    camera: CameraModel
    R_world_from_cam: np.ndarray | None
    positions: np.ndarray


def _estimate_groups(name: str, groups: list[_CameraFrames], n_frames: int, layout: DeckLayout,
                     options: EstimateOptions, *, workers: int, scheduler: str | None,
                     progress: Progress | None) -> list[PoseEstimate]:
    """Estimate every group, each estimate in its group's place of the ``n_frames`` of the output.

    Here: a group a batch (:func:`estimate_batch` chunks it). In workers: a task a chunk of
    ``CHUNK_FRAMES``, the same batches, so the same estimates.
    """
    import contextlib

    from deckpose.estimate import batch

    from deckpose.worker_pool import map_ordered

    results: list[PoseEstimate | None] = [None] * n_frames
    if scheduler is None and (workers <= 1 or n_frames < MIN_PARALLEL_FRAMES):
        for g in groups:
            task = _EstimateTask(name, tuple(g.detections), g.camera, layout, options, g.R_world_from_cam)
            for k, e in zip(g.positions, _estimate_task(task, progress), strict=True):
                results[k] = e
    else:
        tasks: list[_EstimateTask] = []
        places: list[np.ndarray] = []  # each task's places in the output
        for g in groups:
            for part in batch.chunk_slices(len(g.detections)):  # estimate_batch's own batches
                R = None if g.R_world_from_cam is None else g.R_world_from_cam[part]
                tasks.append(_EstimateTask(name, tuple(g.detections[part]), g.camera, layout, options, R))
                places.append(g.positions[part])
        with contextlib.closing(map_ordered(_estimate_task, tasks, workers=workers, scheduler=scheduler)) as done:
            for at, got in zip(places, done, strict=True):
                for k, e in zip(at, got, strict=True):
                    results[k] = e
                if progress is not None:
                    progress(len(at))
    out = [e for e in results if e is not None]
    assert len(out) == n_frames, "every frame is in one group, so every frame is estimated"
    return out


@dataclass(frozen=True)
class _EstimateTask:
    """Frames of one camera that a worker estimates as one batch (:func:`_estimate_task`)."""

    name: str
    detections: tuple[Detections, ...]
    camera: CameraModel
    layout: DeckLayout
    options: EstimateOptions
    R_world_from_cam: np.ndarray | None


def _estimate_task(task: _EstimateTask, progress: Progress | None = None) -> list[PoseEstimate]:
    """Estimate one task's frames (the workers' entry point)."""
    return estimate_batch(task.name, task.detections, task.camera, task.layout, task.options,
                          R_world_from_cam=task.R_world_from_cam, progress=progress)
