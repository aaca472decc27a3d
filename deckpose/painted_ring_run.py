"""A run's painted ring, frame by frame: ring edges, then the pose from them (``deckpose painted-ring``).

Reads a dataset rendered with a ``painted_ring:`` section (its manifest's resolved config
holds the ring), detects the ring's edges in every frame
(:func:`deckpose.detect.ring_edges.detect_ring_edges`) and estimates the pose from them
(:func:`deckpose.estimate.painted_ring_pose.estimate_painted_ring`, the camera attitude from
the frames table, as for the beacon estimators), and writes::

    RUN/detections/ring-edges.parquet                  one row per frame (RING_DETECTION_COLUMNS)
    RUN/estimates/ring-edges--painted-ring.parquet     the standard estimates table
    RUN/estimates/ring-edges--painted-ring.bound.parquet   the bound's sigmas per frame

so ``deckpose evaluate`` and the benchmark read the painted ring's estimates like any
other. Times are this thread's CPU seconds (``time.thread_time``).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from deckpose.counted import counted
from deckpose.errors import InputDataError
from deckpose.painted_ring import PaintedRing, painted_ring_from_dict
from deckpose.run_folder import RING_DETECTOR, RunPaths, read_cameras, read_frames
from deckpose.shell_command import deckpose_command
from deckpose.table_schemas import PAINTED_RING_BOUND_COLUMNS, RING_DETECTION_COLUMNS, typed_frame
from deckpose.tables import write_table

__all__ = ["DETECTOR", "PaintedRingRunResult", "bound_row", "painted_ring_of_run", "painted_ring_run", "read_bounds"]

#: The ring-edge detector's name in the run folder.
DETECTOR = RING_DETECTOR


@dataclass(frozen=True)
class PaintedRingRunResult:
    """What :func:`painted_ring_run` wrote and how it went."""

    detections: Path
    estimates: Path
    bounds: Path
    n_frames: int
    n_detected: int
    n_ok: int

    def summary(self) -> str:
        return (f"painted ring: {self.n_detected} of {counted(self.n_frames, 'frame')} detected, {self.n_ok} estimated ok; "
                f"{self.estimates}")


def painted_ring_of_run(run: RunPaths) -> PaintedRing:
    """The painted ring a dataset was rendered with (from its manifest's config)."""
    if not run.manifest.is_file():
        raise InputDataError(f"{run.root}: no manifest.json; render a dataset first (deckpose render)")
    doc = json.loads(run.manifest.read_text())
    ring = doc.get("config", {}).get("painted_ring")
    if ring is None:
        raise InputDataError(f"{run.root}: the dataset has no painted ring; render it with a painted_ring: "
                             "section in its config (README, Painted ring)")
    return painted_ring_from_dict(ring, f"{run.manifest}: config.painted_ring")


def bound_row(frame_id: int, bound: np.ndarray | None, chi2_per_point: float,
              bound_known_levels: np.ndarray | None = None, used_disc: bool = False,
              disc_check_chi2: float = math.nan, bound_correlated: np.ndarray | None = None) -> dict[str, object]:
    """The bound table's row of one frame (NaN without a bound)."""
    s = np.sqrt(np.diag(bound)) if bound is not None else np.full(6, math.nan)
    k = np.sqrt(np.diag(bound_known_levels)) if bound_known_levels is not None else np.full(6, math.nan)
    c = np.sqrt(np.diag(bound_correlated)) if bound_correlated is not None else np.full(6, math.nan)
    corr = {f"bound_correlated_{p}_{u}": math.degrees(c[i]) if u == "deg" else float(c[i])
            for i, (p, u) in enumerate((("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("surge", "m"),
                                        ("sway", "m"), ("height", "m")))}
    return {**corr, "frame_id": frame_id, "bound_roll_deg": math.degrees(s[0]), "bound_pitch_deg": math.degrees(s[1]),
            "bound_yaw_deg": math.degrees(s[2]), "bound_surge_m": s[3], "bound_sway_m": s[4],
            "bound_height_m": s[5], "bound_known_levels_roll_deg": math.degrees(k[0]),
            "bound_known_levels_pitch_deg": math.degrees(k[1]), "bound_known_levels_yaw_deg": math.degrees(k[2]),
            "bound_known_levels_height_m": k[5], "used_disc": used_disc,
            "disc_check_chi2": disc_check_chi2, "chi2_per_point": chi2_per_point}


def painted_ring_run(run_dir: str | os.PathLike[str], *, progress: bool = False,
                     centre_disc: bool = False) -> PaintedRingRunResult:
    """Detect the painted ring and estimate the pose in every frame of a run (module docstring).

    ``centre_disc``: also fit the centre disc's edge (:class:`RingEdgeOptions` ``centre_disc``);
    the estimate keeps it only where it agrees with the ring
    (:func:`deckpose.estimate.painted_ring_pose.disc_consistency`).

    Raises
    ------
    InputDataError
        When the folder is not a dataset, or was rendered without a painted ring.
    """
    from tqdm import tqdm

    from deckpose.detect.ring_edges import RingEdgeOptions, detect_ring_edges, ring_detection_row
    from deckpose.detect.sources import read_image
    from deckpose.estimate.painted_ring_pose import METHOD, estimate_painted_ring
    from deckpose.estimate.results_table import estimates_frame

    run = RunPaths(Path(run_dir))
    ring = painted_ring_of_run(run)
    frames = read_frames(run)
    cameras = read_cameras(run)
    det_rows, ests, bounds = [], [], []
    ids = frames["frame_id"].to_numpy(np.int64)
    for f, fid_ in tqdm(zip(frames.itertuples(), ids, strict=True), total=len(frames), unit="frame",
                        desc="painted ring", disable=None if progress else True):
        fid = int(fid_)
        img = read_image(run.root / str(f.image))
        camera = cameras[str(f.camera)]
        R_wc = np.array([[float(getattr(f, f"R_world_from_cam_{i}{j}")) for j in range(3)] for i in range(3)])
        t0 = time.thread_time()
        if isinstance(img, str):
            from deckpose.ring_detection import RingDetection

            det = RingDetection(False, img, frame_id=fid)
        else:
            det = detect_ring_edges(img, camera, ring, RingEdgeOptions(centre_disc=centre_disc), frame_id=fid)
        t1 = time.thread_time()
        res = estimate_painted_ring(det, camera, ring, R_wc)
        t2 = time.thread_time()
        det_rows.append(ring_detection_row(det, t1 - t0))
        ests.append(res.estimate)
        bounds.append({**bound_row(fid, res.bound, res.chi2_per_point, res.bound_known_levels, res.used_disc,
                                   res.disc_check_chi2, res.bound_correlated),
                       "seconds": t2 - t1})
    run.detections_dir.mkdir(parents=True, exist_ok=True)
    run.estimates_dir.mkdir(parents=True, exist_ok=True)
    det_path = run.detections(DETECTOR)
    write_table(typed_frame(det_rows, RING_DETECTION_COLUMNS), det_path, "ring detections")
    est_path = run.estimates(DETECTOR, METHOD)
    write_table(estimates_frame(ests), est_path, "estimates")
    bound_path = est_path.with_name(est_path.name.replace(".parquet", ".bound.parquet"))
    write_table(typed_frame(bounds, PAINTED_RING_BOUND_COLUMNS), bound_path, "painted ring bounds")
    n_det = sum(bool(r["ok"]) for r in det_rows)
    return PaintedRingRunResult(det_path, est_path, bound_path, len(frames), n_det, sum(e.ok for e in ests))


def read_bounds(run: RunPaths) -> pd.DataFrame:
    """The painted ring's bound table of a run (after :func:`painted_ring_run`)."""
    from deckpose.estimate.painted_ring_pose import METHOD
    from deckpose.tables import read_table

    p = run.estimates(DETECTOR, METHOD)
    p = p.with_name(p.name.replace(".parquet", ".bound.parquet"))
    if not p.is_file():
        raise InputDataError(f"{p}: missing; run {deckpose_command('painted-ring', run.root)} first")
    return read_table(p, "painted ring bounds")
