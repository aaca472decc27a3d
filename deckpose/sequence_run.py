"""The estimate stage of a run folder, with frames that detection left unidentified identified by a prior pose.

:func:`estimate_run_with_prior` is what ``deckpose estimate --run`` and ``deckpose
pipeline`` call. It estimates every frame from the ids ``deckpose detect`` gave
(as :func:`deckpose.estimate.run.estimate_run` does, on the inputs it reads), then walks each time sequence
of the run (a camera x camera height x lighting group in capture-time order,
:func:`deckpose.tracking.run.sequence_ids`: one approach, or one cell of a render grid)
in time order: a frame whose detection identified no ring (its bow beacons out of view,
too little of a ring for its ellipse) and whose estimate is not ok is identified by the
last ok estimate of its sequence at most ``max_prior_age_s`` old, from all its detected
blobs (the unidentified ones are in the detections table with ``beacon_id = -1``), and
estimated again (:func:`deckpose.sequence_estimate.estimate_with_prior`).

The estimates table records how each frame was identified (``identified_by``: frame,
prior or none; ``prior_age_s``). Rows of frames where no prior was tried stay as the
estimate stage wrote them, so a run without such frames (or whose frames are too far
apart in time) is estimated exactly as before. With ``prior=False`` no frame is
re-identified and the unidentified frames' reasons say the prior was turned off.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from deckpose import run_folder as rl
from deckpose.camera import CameraModel
from deckpose.capture_time import log_stamps
from deckpose.detect.identification import Identification
from deckpose.estimate.registry import MethodSpec
from deckpose.estimate.results_table import estimates_frame, estimates_from_frame
from deckpose.estimate.run import (
    EstimateRunResult,
    estimate_inputs,
    method_options,
    read_estimate_inputs,
)
from deckpose.layout import DeckLayout
from deckpose.records import Detections
from deckpose.sequence_estimate import (
    IdentifiedBy,
    SequenceFrame,
    SequenceOptions,
    SequenceResult,
    estimate_with_prior,
)
from deckpose.tracking.run import sequence_ids

__all__ = ["NO_PRIOR_NOTE", "estimate_run_with_prior", "prior_pass"]

#: ``progress(n)``: ``n`` more frames are done (what it returns is ignored).
Progress = Callable[[int], object]
#: Appended to the reason of a frame detection left unidentified when the prior is turned off.
NO_PRIOR_NOTE = "identification by the last ok estimate's pose is off (--no-prior)"
#: Detect's prefix of an identification failure in its frames table (``identification: ...``).
_DETECT_PREFIX = "identification: "


def prior_pass(
    frames: pd.DataFrame,
    detections: dict[int, Detections],
    identified: dict[int, tuple[bool, str]],
    estimates: pd.DataFrame,
    cameras: dict[str, CameraModel],
    layout: DeckLayout,
    spec: MethodSpec,
    *,
    sigma_px: float = 1.0,
    options: SequenceOptions = SequenceOptions(),
) -> pd.DataFrame:
    """An estimates table with the frames detection left unidentified identified by a prior, where one helps.

    Parameters
    ----------
    frames : DataFrame
        The run's frames table (``frame_id, camera, camera_height_m, lighting, stamp_ns`` and
        the ``R_world_from_cam_ij`` columns); no truth is read.
    detections : dict of int to Detections
        Each frame's detections, unidentified blobs (``UNASSIGNED``) included.
    identified : dict of int to (bool, str)
        Per frame: whether detection identified it, and why not (detect's frames table).
    estimates : DataFrame
        The estimate stage's table of the run (one row per frame, ``ESTIMATE_COLUMNS``).
    cameras : dict of str to CameraModel
    layout : DeckLayout
    spec : MethodSpec
        The estimator and variant of ``estimates`` (frames identified by the prior use it too).
    sigma_px : float, keyword-only
        Pixel sigma where detections carry no covariance.
    options : SequenceOptions, keyword-only
        ``max_prior_age_s`` and the prior's gate (its ``method`` is replaced by ``spec.name``).

    Returns
    -------
    DataFrame
        ``estimates`` with ``identified_by`` and ``prior_age_s`` filled, and the rows of the
        frames a prior was tried for replaced.
    """
    options = dataclasses.replace(options, method=spec.name)
    est_opts = method_options(spec, sigma_px)
    by_id = {e.frame_id: e for e in estimates_from_frame(estimates)}
    stamps = log_stamps(frames).to_numpy(np.int64)
    seq = sequence_ids(frames, stamps)
    R_all = rl.R_world_from_cam_all(frames)
    fids = frames["frame_id"].to_numpy(np.int64)
    results: dict[int, SequenceResult] = {}
    for s in range(int(seq.max()) + 1 if len(seq) else 0):
        idx = np.flatnonzero(seq == s)
        idx = idx[np.argsort(stamps[idx], kind="stable")]
        camera = cameras[str(frames["camera"].iloc[idx[0]])]
        seq_frames, idents, alone = [], [], []
        for k in idx:
            fid = int(fids[k])
            d = detections.get(fid, Detections(np.zeros((0, 2)), np.zeros(0, np.int64), frame_id=fid))
            seq_frames.append(SequenceFrame(fid, int(stamps[k]), d.points_px, d.covariance_px2, R_all[k]))
            ok, why = identified[fid]
            idents.append(Identification(d.beacon_ids, ok, why.removeprefix(_DETECT_PREFIX)))
            alone.append(by_id[fid])
        for r in estimate_with_prior(seq_frames, idents, alone, camera, layout, est_opts, options=options):
            results[r.estimate.frame_id] = r
    out = estimates.copy()
    tried = [fid for fid, r in results.items() if not math.isnan(r.prior_age_s)]
    if tried:  # those rows from the new records, column by column in the schema's dtypes
        new = estimates_frame([results[f].estimate for f in tried]).assign(method=spec.label)
        at = out["frame_id"].isin(tried).to_numpy()
        src = new.set_index("frame_id").loc[out.loc[at, "frame_id"].to_numpy()]
        for c in src.columns:
            col = out[c].copy()
            col[at] = src[c].array
            out[c] = col
    fids_out = out["frame_id"].to_numpy(np.int64)
    out["identified_by"] = pd.Series([results[int(f)].identified_by.value for f in fids_out], index=out.index,
                                     dtype=object)
    out["prior_age_s"] = np.array([results[int(f)].prior_age_s for f in fids_out], float)
    return out


def _identified(
    det_frames: pd.DataFrame | None, detections: dict[int, Detections], frame_ids: list[int]
) -> dict[int, tuple[bool, str]]:
    """Per frame: did detection identify it, and why not (detect's frames table; else: any id given)."""
    rows = det_frames.set_index("frame_id") if det_frames is not None else None
    out = {}
    for f in frame_ids:
        if rows is not None and f in rows.index:
            out[f] = (bool(rows.at[f, "ok"]), str(rows.at[f, "reason"]))
            continue
        d = detections.get(f)
        some = d is not None and bool(np.any(np.asarray(d.beacon_ids) >= 0))
        out[f] = (some, "" if some else "the detections carry no beacon ids")
    return out


def estimate_run_with_prior(
    run_dir: str | Path,
    spec: MethodSpec,
    *,
    detector: str | None = None,
    sigma_px: float = 1.0,
    radius_m: float | None = None,
    prior: bool = True,
    max_prior_age_s: float = SequenceOptions().max_prior_age_s,
    progress: Progress | None = None,
    workers: int = 1,
    scheduler: str | None = None,
) -> EstimateRunResult:
    """Estimate every frame of a run folder, identifying by a prior what detection could not.

    Writes ``RUN/estimates/DETECTOR--LABEL.parquet`` (as
    :func:`~deckpose.estimate.run.estimate_run`, plus ``identified_by`` and ``prior_age_s``).

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
    prior : bool, keyword-only
        Identify the frames detection left unidentified by the last ok estimate (False: ``--no-prior``).
    max_prior_age_s : float, keyword-only
        Oldest ok estimate used as a prior, seconds.
    progress : callable, optional, keyword-only
    workers : int, keyword-only
        Worker processes of the estimates of each frame alone
        (:func:`~deckpose.estimate.run.estimate_inputs`; 0 or 1: this process); the walk over
        each sequence runs here. The table does not depend on it.
    scheduler : str, optional, keyword-only
        A Dask scheduler's address: those estimates run on its workers instead.

    Returns
    -------
    EstimateRunResult

    Raises
    ------
    ConfigError
        No detector given where the run has several (or none); a negative ``max_prior_age_s``.
    InputDataError
        A missing dataset or detections table, or detections of other frames.
    """
    from deckpose.tables import write_table

    options = SequenceOptions(max_prior_age_s=max_prior_age_s)  # validates before the work
    run, detector, layout, frames, cameras, dets = read_estimate_inputs(run_dir, detector=detector,
                                                                      radius_m=radius_m)
    df = estimate_inputs(frames, dets, cameras, layout, spec, sigma_px=sigma_px, progress=progress,
                         workers=workers, scheduler=scheduler)
    ids = [int(f) for f in frames["frame_id"]]
    identified = _identified(rl.read_detect_frames(run, detector), dets, ids)
    if prior:
        df = prior_pass(frames, dets, identified, df, cameras, layout, spec, sigma_px=sigma_px, options=options)
    else:
        df = _without_prior(df, identified)
    out = run.estimates(detector, spec.label)
    write_table(df, out, "estimates")  # once: the stage's table with how each frame was identified
    return EstimateRunResult(out, df)


def _without_prior(estimates: pd.DataFrame, identified: dict[int, tuple[bool, str]]) -> pd.DataFrame:
    """``identified_by`` frame or none, and the unidentified frames that failed saying the prior is off."""
    out = estimates.copy()
    alone = (np.array([identified[int(f)][0] for f in out["frame_id"].to_numpy(np.int64)], bool)
             | out["ok"].to_numpy(bool))
    out["identified_by"] = np.where(alone, IdentifiedBy.FRAME.value, IdentifiedBy.NONE.value).astype(object)
    out["prior_age_s"] = np.nan
    miss = ~alone
    out.loc[miss, "reason"] = [f"{r}; {NO_PRIOR_NOTE}" for r in out.loc[miss, "reason"]]
    return out

