"""Tracking a run: the deck-motion filter over each time sequence of a run's per-frame estimates.

:func:`track_table` is the pure function on tables (frames + estimates -> filtered states
and predictions); :func:`track_run` reads a run folder and writes
``RUN/tracks/<detector>--<method>--<tracker>.parquet`` (one row per frame),
``.predictions.parquet`` (one row per frame x horizon) and ``.run.json`` (resolved config,
inputs, counts) through :mod:`deckpose.run_folder`.

A run's frames are one or more time sequences: the render plan replays its motion
series for every camera, height and lighting, so a sequence is a (camera, camera
height, lighting) group in capture-time order (:func:`sequence_ids`); the filter starts
afresh on each.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from deckpose.atomic_io import atomic_open
from deckpose.capture_time import capture_epoch, log_stamps
from deckpose.counted import counted
from deckpose.errors import ConfigError, InputDataError
from deckpose.output_folder import ensure_writable
from deckpose.records import POSE_PARAMS
from deckpose.rotation import wrap_angle_rad
from deckpose.run_folder import (
    RunPaths,
    check_frames_match,
    read_estimates,
    read_frames,
    read_manifest,
    run_paths,
)
from deckpose.shell_command import deckpose_command
from deckpose.table_schemas import TRACK_COLUMNS, TRACK_PREDICTION_COLUMNS, pandas_dtype
from deckpose.tables import write_table
from deckpose.tracking.config import TRACKERS, TrackConfig, track_config_to_mapping
from deckpose.tracking.deck_motion_model import measurement_matrix, output_matrix
from deckpose.tracking.landing_window import landing_window_go
from deckpose.tracking.measurements import POSE_COLUMNS, measurements_from_estimates
from deckpose.tracking.prediction import predict_outputs
from deckpose.tracking.sequence_filter import FilterStatus, filter_sequence

__all__ = ["TrackRunResult", "sequence_ids", "track_run", "track_table"]

Progress = Callable[[int], object]
#: Format of a track run's record (``.run.json``).
TRACK_RUN_FORMAT = "deckpose-track/1"


@dataclass(frozen=True)
class TrackRunResult:
    """What ``deckpose track`` wrote.

    Attributes
    ----------
    path, predictions_path, record_path : Path
        The filtered states, the predictions and the run record.
    table : pandas.DataFrame
        The filtered states (``TRACK_COLUMNS``).
    """

    path: Path
    predictions_path: Path
    record_path: Path
    table: pd.DataFrame

    def summary(self) -> str:
        """One line: frames and sequences, how the estimates were used, where they went."""
        st = self.table["status"].value_counts()
        n_seq = self.table["sequence"].nunique()
        return (f"{counted(len(self.table), 'frame')} in {counted(n_seq, 'sequence')}: {int(st.get('updated', 0))} updated, "
                f"{int(st.get('gated', 0))} gated out, {int(st.get('skipped', 0))} skipped (no usable estimate) "
                f"-> {self.path}")


def sequence_ids(frames: pd.DataFrame, stamps_ns: NDArray[np.int64]) -> NDArray[np.int64]:
    """Each frame's time sequence: its (camera, camera_height_m, lighting) group, numbered in time order.

    Parameters
    ----------
    frames : DataFrame
        The frames table (``camera``, ``camera_height_m``, ``lighting``).
    stamps_ns : (N,) array of int
        The frames' capture times.
    """
    key = frames[["camera", "camera_height_m", "lighting"]].astype(str).agg("\x1f".join, axis=1)
    first = pd.Series(np.asarray(stamps_ns, np.int64), index=frames.index).groupby(key).transform("min")
    order = pd.DataFrame({"key": key, "first": first}).drop_duplicates("key").sort_values(["first", "key"])
    rank = {k: i for i, k in enumerate(order["key"])}
    return np.asarray(key.map(rank).to_numpy(), dtype=np.int64)


def track_table(frames: pd.DataFrame, estimates: pd.DataFrame, config: TrackConfig, *,
                epoch_ns: int | None = None, source: str = "estimates",
                progress: Progress | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Filtered states and predictions for every frame of ``frames``.

    Parameters
    ----------
    frames : DataFrame
        The frames table (``frame_id, camera, camera_height_m, lighting, stamp_ns``); no truth is read.
    estimates : DataFrame
        One estimates table (one method's rows; frames without a row are predicted only).
    config : TrackConfig
    epoch_ns : int, optional, keyword-only
        Capture time of motion time 0, for datasets whose stamps are motion time
        (:func:`deckpose.capture_time.log_stamps`).
    source : str, keyword-only
        How messages name the estimates.
    progress : callable, optional, keyword-only
        Called with the number of frames done after each sequence.

    Returns
    -------
    tracks : DataFrame
        ``TRACK_COLUMNS``, one row per frame, in sequence then time order.
    predictions : DataFrame
        ``TRACK_PREDICTION_COLUMNS``, one row per frame x horizon.
    """
    if not len(frames):
        raise InputDataError("the run has no frames to track")
    stamps = (log_stamps(frames) if epoch_ns is None else log_stamps(frames, epoch_ns)).to_numpy(np.int64)
    seq = sequence_ids(frames, stamps)
    model = config.model
    H, C = measurement_matrix(model), output_matrix(model)
    horizons = np.asarray(config.horizons_s, float)
    track_parts: list[pd.DataFrame] = []
    pred_parts: list[pd.DataFrame] = []
    for s in range(int(seq.max()) + 1):
        idx = np.flatnonzero(seq == s)
        idx = idx[np.argsort(stamps[idx], kind="stable")]
        ids = frames["frame_id"].to_numpy(np.int64)[idx]
        st = stamps[idx]
        meas = measurements_from_estimates(estimates, ids, source=source)
        t_s = (st - st[0]) / 1e9
        track = filter_sequence(t_s, meas.z, meas.R, meas.usable, model, gate_probability=config.gate_probability,
                                reacquire_after=config.reacquire_after)
        track_parts.append(_track_rows(s, ids, st, track.x, track.P, track.nis, track.status, H, C,
                                       landing_window_go(track.x, track.P, model, config.landing)))
        mean, cov = predict_outputs(track.x, track.P, model, horizons)
        pred_parts.append(_prediction_rows(ids, st, horizons, mean, cov))
        if progress is not None:
            progress(len(idx))
    return pd.concat(track_parts, ignore_index=True), pd.concat(pred_parts, ignore_index=True)


def _track_rows(seq: int, ids: NDArray[np.int64], stamps: NDArray[np.int64], x: NDArray[np.float64],
                P: NDArray[np.float64], nis: NDArray[np.float64], status: tuple[FilterStatus, ...],
                H: NDArray[np.float64], C: NDArray[np.float64], go: NDArray[np.bool_]) -> pd.DataFrame:
    pose = x @ H.T                                               # (N, 6) POSE_PARAMS
    pose[:, 2] = wrap_angle_rad(pose[:, 2])
    pose_cov = np.einsum("in,Nnm,jm->Nij", H, P, H, optimize=True)
    deck = x @ C.T                                               # roll, pitch, heave, heave rate, height
    deck_var = np.einsum("in,Nnm,im->Ni", C, P, C, optimize=True)
    cols: dict[str, object] = {
        "frame_id": ids, "sequence": np.full(len(ids), seq, np.int64), "stamp_ns": stamps,
        "status": [s.value for s in status], "nis": nis,
    }
    sig = np.sqrt(np.maximum(np.diagonal(pose_cov, axis1=1, axis2=2), 0.0))
    for k, name in enumerate(POSE_COLUMNS):
        deg = name.endswith("_deg")
        cols[name] = np.degrees(pose[:, k]) if deg else pose[:, k]
    cols["heave_m"], cols["heave_rate_m_per_s"] = deck[:, 2], deck[:, 3]
    for k, name in enumerate(POSE_COLUMNS):
        cols[f"sigma_{name}"] = np.degrees(sig[:, k]) if name.endswith("_deg") else sig[:, k]
    cols["sigma_heave_m"] = np.sqrt(np.maximum(deck_var[:, 2], 0.0))
    cols["sigma_heave_rate_m_per_s"] = np.sqrt(np.maximum(deck_var[:, 3], 0.0))
    for i in range(6):
        for j in range(i, 6):
            cols[f"cov_{POSE_PARAMS[i]}__{POSE_PARAMS[j]}"] = pose_cov[:, i, j]
    cols["landing_go"] = np.asarray(go, bool)
    return pd.DataFrame(cols)[[c.name for c in TRACK_COLUMNS]]


def _prediction_rows(ids: NDArray[np.int64], stamps: NDArray[np.int64], horizons: NDArray[np.float64],
                     mean: NDArray[np.float64], cov: NDArray[np.float64]) -> pd.DataFrame:
    n, h = mean.shape[:2]
    sig = np.sqrt(np.maximum(np.diagonal(cov, axis1=2, axis2=3), 0.0))
    return pd.DataFrame({
        "frame_id": np.repeat(ids, h), "horizon_s": np.tile(horizons, n),
        "stamp_ns": (stamps[:, None] + np.round(horizons * 1e9).astype(np.int64)[None, :]).reshape(-1),
        "roll_deg": np.degrees(mean[..., 0]).reshape(-1), "pitch_deg": np.degrees(mean[..., 1]).reshape(-1),
        "heave_m": mean[..., 2].reshape(-1), "heave_rate_m_per_s": mean[..., 3].reshape(-1),
        "height_m": mean[..., 4].reshape(-1),
        "sigma_roll_deg": np.degrees(sig[..., 0]).reshape(-1), "sigma_pitch_deg": np.degrees(sig[..., 1]).reshape(-1),
        "sigma_heave_m": sig[..., 2].reshape(-1), "sigma_heave_rate_m_per_s": sig[..., 3].reshape(-1),
        "sigma_height_m": sig[..., 4].reshape(-1),
    })[[c.name for c in TRACK_PREDICTION_COLUMNS]]


def _pick_estimates(run: RunPaths, detector: str | None, method: str | None) -> tuple[str, str]:
    pairs = run.estimate_pairs()
    if not pairs:
        raise InputDataError(f"{run.estimates_dir} holds no estimates; make them with: "
                             f"{deckpose_command('estimate', '--run', run.root, '--method', 'pnp')}")
    cand = [(d, m) for d, m in pairs if (detector is None or d == detector) and (method is None or m == method)]
    if len(cand) == 1:
        return cand[0]
    listed = ", ".join(f"--detector {d} --estimates {m}" for d, m in pairs)
    if not cand:
        several = " (one estimates table per call)" if "," in f"{detector or ''}{method or ''}" else ""
        asked = " and ".join(f"{what} {name}" for what, name in (("detector", detector), ("method", method)) if name)
        raise InputDataError(f"no estimates of {asked or 'any detector and method'} in {run.root}{several}; "
                             f"the run has: {listed}")
    raise InputDataError(f"{run.root} has several estimates tables; choose one with {listed}")


def track_run(run_dir: str | Path, config: TrackConfig, *, tracker: str = "wave-bank", detector: str | None = None,
              method: str | None = None, command: list[str] | None = None,
              progress: Progress | None = None, name: str | None = None) -> TrackRunResult:
    """Track one estimates table of a run folder and write the tracks.

    Parameters
    ----------
    run_dir : str or Path
        A run with ``estimates/DETECTOR--METHOD.parquet``.
    config : TrackConfig
    tracker : str, keyword-only
        The tracker (:data:`~deckpose.tracking.config.TRACKERS`).
    detector, method : str, optional, keyword-only
        Which estimates (default: the run's only table).
    command : list of str, optional, keyword-only
        The command line, for the run record.
    progress : callable, optional, keyword-only
    name : str, optional, keyword-only
        The track's name in the run folder, ``tracks/DETECTOR--METHOD--NAME.parquet``
        (default: the tracker's): two configs of one tracker kept side by side. Letters,
        digits, ``_``, ``.``, ``+`` and single ``-``.

    Returns
    -------
    TrackRunResult
    """
    if tracker not in TRACKERS:
        raise ConfigError(f"unknown tracker {tracker!r}; choose one of {list(TRACKERS)}")
    label = tracker if name is None else name
    if not re.fullmatch(r"[A-Za-z0-9_.+]+(-[A-Za-z0-9_.+]+)*", label):
        raise ConfigError(f"track name {label!r}: use letters, digits, '_', '.', '+' and single '-' "
                          "(it becomes part of a file name, tracks/DETECTOR--METHOD--NAME.parquet)")
    run = run_paths(run_dir)
    frames = read_frames(run)
    manifest = read_manifest(run)
    motion = (manifest.get("config") or {}).get("motion") or {}
    if motion.get("source") == "fixed":
        raise InputDataError(
            f"{run.root} holds fixed attitudes, not a time series (motion source 'fixed'): a filter needs "
            "frames in time; render an approach (a config's approach: section) or a motion series "
            "(motion.source sea_state, file or thesis)")
    epoch, _ = capture_epoch(manifest)
    det, meth = _pick_estimates(run, detector, method)
    estimates = read_estimates(run, det, meth)
    check_frames_match(frames, estimates, f"{run.estimates(det, meth)}",
                       deckpose_command("estimate", "--run", run.root, "--detector", det, "--method", meth))
    ensure_writable(run.tracks_dir)
    tracks, predictions = track_table(frames, estimates, config, epoch_ns=epoch,
                                      source=str(run.estimates(det, meth)), progress=progress)
    tracks = tracks.astype({c.name: pandas_dtype(c) for c in TRACK_COLUMNS})
    path = run.tracks(det, meth, label)
    pred_path = run.track_predictions(det, meth, label)
    write_table(tracks, path, "tracks")
    write_table(predictions, pred_path, "track predictions")
    from deckpose import __version__

    st = tracks["status"].value_counts()
    record = {
        "format": TRACK_RUN_FORMAT, "deckpose_version": __version__, "command": command,
        "tracker": tracker, "name": label, "detector": det, "method": meth,
        "estimates": str(run.estimates(det, meth).name),
        "config": track_config_to_mapping(config),
        "n_frames": len(tracks), "n_sequences": int(tracks["sequence"].nunique()),
        **{f"n_{s.value}": int(st.get(s.value, 0)) for s in FilterStatus},
        "landing_go_fraction": float(tracks["landing_go"].mean()) if len(tracks) else math.nan,
    }
    record_path = run.track_run_record(det, meth, label)
    with atomic_open(record_path) as f:
        json.dump(record, f, indent=2)
    return TrackRunResult(path, pred_path, record_path, tracks)
