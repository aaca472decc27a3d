"""MCAP logs of a run for Foxglove: images, calibration, annotations, transforms, scene, errors.

Topics (Foxglove protobuf schemas, zstd-compressed chunks):

* ``/camera/image`` (``foxglove.CompressedImage``, PNG): a downscaled preview, at most
  ``preview_px`` on its long side (viewers cannot show 64 MP textures; full frames
  stay in the dataset), and ``/camera/calibration`` (``foxglove.CameraCalibration``)
  scaled to match;
* ``/annotations/truth`` and ``/annotations/<detector>`` (``foxglove.ImageAnnotations``):
  projected and detected beacon centres with their ids, in preview pixels;
* ``/tf`` (``foxglove.FrameTransforms``): ``world -> deck`` (truth), ``world -> camera``
  and ``world -> deck_est/<detector>--<method>`` per solved estimate;
* ``/scene`` (``foxglove.SceneUpdate``): the deck, ring and beacons, the camera frustum and
  each estimator's deck (:mod:`deckpose.evaluate.mcap_scene`);
* ``/errors/<detector>--<method>`` (JSON): the per-frame errors, for Foxglove's Plot panel;
* ``/estimates/<detector>--<method>`` and ``/truth/deck`` (JSON): each frame's estimated and
  true deck pose, to plot against time;
* with tracks (``deckpose track``): ``/tracks/<detector>--<method>--<tracker>`` (JSON, the
  filtered state with its sigmas, status and landing-window indicator),
  ``/predictions/<...>/<horizon>`` (JSON, what the filter predicted for this frame one
  horizon earlier), and ``deck_track/<...>`` and ``deck_pred/<...>/<horizon>`` decks in
  ``/tf`` and ``/scene``. Names: :mod:`deckpose.evaluate.log_topics`.

Log times (:func:`deckpose.capture_time.log_stamps`) are on a capture epoch. A dataset whose ``stamp_ns`` is
already on one (at or after 2000-01-01) is logged at ``stamp_ns``. A rendered dataset's
``stamp_ns`` is motion time (from 0), and a run replays one motion series for every
camera, height and lighting, which repeats stamps; its frames are logged from the
manifest's ``capture_epoch_ns`` (when it has one) or :data:`DEFAULT_CAPTURE_EPOCH_NS`,
each replay after the previous one. Every JSON message keeps ``stamp_ns`` and the motion
time ``t_s``; the ``deckpose.time`` metadata record states the rule. Log and publish
times are always given explicitly.

The file also holds metadata records (``deckpose.run``: seed, command, dataset name;
``deckpose.config``: the resolved render config; ``deckpose.versions``; ``deckpose.time``)
and attachments (each camera's ``camera_info`` YAML, the manifest and, when it exists,
the run's report): :mod:`deckpose.evaluate.mcap_records`.

The messages follow what the Foxglove app reads (checked with the app's reader
libraries by ``tools/foxglove_check``, and drawn by Foxglove Studio 1.48 in
``tools/foxglove_viewer``): image annotation points use the top-left corner of the
top-left pixel as origin (Foxglove's convention, half a pixel off OpenCV's pixel
centres); JSON channels carry a JSON Schema with a typed ``properties`` entry per field
(the app's parser requires them).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate.export_frames import deck_half_size_m
from deckpose.evaluate.log_topics import estimates_topic, track_stem, track_topic
from deckpose.evaluate.mcap_messages import (
    ERRORS_SCHEMA,
    ESTIMATE_LOGGED,
    PROTO_TYPES,
    TRUTH_LOGGED,
    TRUTH_SCHEMA,
    LogMessage,
    LogSetting,
    LogTask,
    annotations_msg,
    calibration_msg,
    due_schema,
    json_bytes,
    log_task,
    preview_png,
)
from deckpose.evaluate.mcap_records import write_records
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from deckpose import run_folder as rl
from deckpose.atomic_io import atomic_path
from deckpose.capture_time import EPOCH_FLOOR_NS, capture_epoch, log_stamps
from deckpose.errors import InputDataError
from deckpose.preview import PREVIEW_PX
from deckpose.tracking.due_predictions import predictions_due
from deckpose.worker_pool import map_ordered

__all__ = ["LOG_TASK_FRAMES", "MIN_PARALLEL_LOG_FRAMES", "McapLog", "annotations_msg", "calibration_msg",
           "errors_json_schema", "preview_png", "table_json_schema", "write_run_log"]

#: Frames of the log built by one worker task: enough to hide the hand-over, few enough that
#: the built messages waiting to be written (previews included) stay small.
LOG_TASK_FRAMES = 64
#: Fewest frames whose log is built by worker processes; a smaller log is built in this process.
#: A frame's messages cost about 21 ms to build (load 6-7), starting two workers 5 s and more,
#: and on a 990-frame run two workers took 1.38x one at load 7-10 (benchmarks/bench_stage_workers.py,
#: reports/throughput/stage_workers.txt).
MIN_PARALLEL_LOG_FRAMES = 4096


class McapLog:
    """An open MCAP file that registers schemas and channels on first use."""

    def __init__(self, fh) -> None:  # fh: a binary file object
        self._w = Writer(fh, compression=CompressionType.ZSTD)
        self._w.start(profile="", library="deckpose")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}

    def _channel(self, topic: str, schema_name: str, encoding: str, schema_data: bytes, schema_enc: str) -> int:
        if topic not in self._channels:
            if schema_name not in self._schemas:
                self._schemas[schema_name] = self._w.register_schema(schema_name, schema_enc, schema_data)
            self._channels[topic] = self._w.register_channel(topic, encoding, self._schemas[schema_name])
        return self._channels[topic]

    def proto(self, topic: str, msg, stamp_ns: int) -> None:  # msg: a protobuf message
        cid = self._channels.get(topic)
        if cid is None:  # the schema's descriptor set is built once per topic, not per message
            cid = self._channel(topic, msg.DESCRIPTOR.full_name, "protobuf",
                                build_file_descriptor_set(type(msg)).SerializeToString(), "protobuf")
        self._w.add_message(cid, log_time=stamp_ns, publish_time=stamp_ns, data=msg.SerializeToString())

    def json(self, topic: str, obj: dict, stamp_ns: int, schema: dict) -> None:
        """Log ``obj`` as JSON on ``topic``; ``schema`` is its JSON Schema, named by its title."""
        self._json_bytes(topic, json_bytes(obj), stamp_ns, schema)

    def _json_bytes(self, topic: str, data: bytes, stamp_ns: int, schema: dict) -> None:
        cid = self._channel(topic, schema["title"], "json", json.dumps(schema).encode(),
                            "jsonschema")
        self._w.add_message(cid, log_time=stamp_ns, publish_time=stamp_ns, data=data)

    def add(self, msg: LogMessage, schemas: Mapping[str, dict]) -> None:
        """Log a message built apart (:func:`~deckpose.evaluate.mcap_messages.log_task`); ``schemas``
        holds the JSON Schemas by :attr:`~deckpose.evaluate.mcap_messages.LogMessage.schema` key."""
        if not msg.proto:
            self._json_bytes(msg.topic, msg.data, msg.stamp_ns, schemas[msg.schema])
            return
        cid = self._channels.get(msg.topic)
        if cid is None:  # the schema's descriptor set is built once per topic, not per message
            cid = self._channel(msg.topic, msg.proto, "protobuf",
                                build_file_descriptor_set(PROTO_TYPES[msg.proto]).SerializeToString(), "protobuf")
        self._w.add_message(cid, log_time=msg.stamp_ns, publish_time=msg.stamp_ns, data=msg.data)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record: ``name`` and string key-value pairs."""
        self._w.add_metadata(name, data)

    def attachment(self, name: str, media_type: str, data: bytes, stamp_ns: int) -> None:
        """An attachment (a file's bytes), created and logged at ``stamp_ns``."""
        self._w.add_attachment(create_time=stamp_ns, log_time=stamp_ns, name=name, media_type=media_type, data=data)

    def finish(self) -> None:
        self._w.finish()



def errors_json_schema(errors: pd.DataFrame, title: str = "deckpose.FrameErrors") -> dict:
    """JSON Schema of the per-frame error messages (the columns of ``errors`` plus ``t_s``).

    Every field gets a ``properties`` entry with a JSON type the Foxglove app's
    parser accepts (number, integer, boolean, string); NaN is written as null.
    """
    return table_json_schema(errors, title)


def table_json_schema(table: pd.DataFrame, title: str) -> dict:
    """JSON Schema of per-frame messages made of ``table``'s columns plus the frame's keys.

    The frame's keys (``frame_id``, ``t_s``, ``stamp_ns``, ``detector``, ``method``) are
    always declared; every column gets the JSON type of its dtype (number, integer,
    boolean, string), which the Foxglove app's parser requires.
    """
    props: dict[str, dict] = {}
    for name, dtype in table.dtypes.items():
        if pd.api.types.is_bool_dtype(dtype):
            kind = "boolean"
        elif pd.api.types.is_integer_dtype(dtype):
            kind = "integer"
        elif pd.api.types.is_float_dtype(dtype):
            kind = "number"
        else:
            kind = "string"
        props[str(name)] = {"type": kind}
    props.update(frame_id={"type": "integer"},
                 t_s={"type": "number", "description": "motion time, s"},
                 stamp_ns={"type": "integer", "description": "the frame's stamp_ns (frames.parquet), ns"},
                 detector={"type": "string"}, method={"type": "string"},
                 track={"type": "string", "description": "<detector>--<method>--<tracker>"})
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title,
            "type": "object", "properties": props}




def write_run_log(run: rl.RunPaths, out_path: Path | None = None, *, preview_px: int = PREVIEW_PX,
                  errors: pd.DataFrame | None = None, command: Sequence[str] = (),
                  progress: Callable[[int, int], object] | None = None, workers: int = 1) -> Path:
    """Write the run's MCAP log (atomically) and return its path.

    Parameters
    ----------
    run : RunPaths
        A run with detections (and, for ``/tf`` estimates and the estimators' decks, estimates).
    out_path : Path, optional
        Where to write (default ``RUN/log.mcap``).
    preview_px : int
        Long side of the image previews, pixels (16..4096).
    errors : DataFrame, optional
        Per-frame errors (``deckpose evaluate``'s), logged on ``/errors/<detector>--<method>``.
    command : sequence of str
        The command line that made the log, recorded in the ``deckpose.run`` metadata.
    progress : callable, optional
        ``progress(done, total)`` after each frame is logged.
    workers : int, keyword-only
        Local worker processes that build the frames' messages, :data:`LOG_TASK_FRAMES` frames
        a task, from :data:`MIN_PARALLEL_LOG_FRAMES` frames on (0 or 1, or fewer frames: this
        process). This process writes them in log order, so the file is the same for any
        ``workers``. (They read the run's previews, so they run here, never on a Dask cluster.)
    """
    if not 16 <= preview_px <= 4096:
        raise InputDataError(f"preview_px must be within 16..4096 (viewers cannot show larger textures), got {preview_px}")
    frames = rl.read_frames(run)
    manifest = rl.read_manifest(run)
    layout = rl.read_layout(run)
    camera_names = sorted(frames["camera"].unique())
    pairs = run.estimate_pairs()
    ests = {p: rl.read_estimates(run, *p).set_index("frame_id") for p in pairs}
    est_logged = {p: tuple(c for c in ESTIMATE_LOGGED if c in e.columns) for p, e in ests.items()}
    truth_cols = tuple(c for c in TRUTH_LOGGED if c in frames.columns)
    schemas = {TRUTH_SCHEMA: table_json_schema(frames[list(truth_cols)], "deckpose.DeckTruth")}
    schemas.update({estimates_topic(*p): table_json_schema(ests[p][list(est_logged[p])], "deckpose.FrameEstimate")
                    for p in pairs})
    tracks, dues, track_cols = {}, {}, {}
    for t in run.track_triples():
        stem = track_stem(*t)
        tr = rl.read_tracks(run, *t)
        due = predictions_due(tr, rl.read_track_predictions(run, *t))
        track_cols[stem] = tuple(c for c in tr.columns if not c.startswith("cov_") and c != "frame_id")
        tracks[stem], dues[stem] = tr.set_index("frame_id"), due
        schemas[track_topic(stem)] = table_json_schema(tr[list(track_cols[stem])], "deckpose.TrackState")
        schemas[due_schema(stem)] = table_json_schema(due.drop(columns="frame_id"), "deckpose.DuePrediction")
    err_by_pair = {}
    if errors is not None and len(errors):
        schemas[ERRORS_SCHEMA] = errors_json_schema(errors)
        for (d, m), g in errors.groupby(["detector", "method"]):
            err_by_pair[(str(d), str(m))] = g.set_index("frame_id")
    if len(frames) and int(frames["stamp_ns"].min()) >= EPOCH_FLOOR_NS:
        epoch = (0, "stamps")
    else:
        epoch = capture_epoch(manifest)
    stamps = log_stamps(frames, epoch[0])
    order = np.argsort(stamps.to_numpy(), kind="stable")
    setting = LogSetting(run.root, layout, deck_half_size_m(manifest, layout),
                         rl.read_cameras(run, camera_names), preview_px, manifest.get("preview_px"),
                         tuple(run.detectors()), est_logged, truth_cols, track_cols, tuple(err_by_pair))
    tables = LogTask(setting, frames.iloc[order], stamps.to_numpy(np.int64)[order], rl.read_beacons(run),
                     {d: rl.read_detections(run, d) for d in setting.detectors}, ests, tracks, dues, err_by_pair)
    parallel = workers >= 2 and len(frames) >= MIN_PARALLEL_LOG_FRAMES
    tasks = _log_tasks(tables, LOG_TASK_FRAMES) if parallel else [tables]
    out = Path(out_path) if out_path else run.mcap
    with (atomic_path(out) as tmp, open(tmp, "wb") as fh,
          contextlib.closing(map_ordered(log_task, tasks, workers=workers)) as built):
        log = McapLog(fh)
        write_records(log, run, manifest, camera_names, command, epoch, int(stamps.min()) if len(stamps) else 0)
        k = 0
        for chunk in built:
            for msgs in chunk:
                if progress is not None and k:  # k frames logged
                    progress(k, len(frames))
                for msg in msgs:
                    log.add(msg, schemas)
                k += 1
        log.finish()
    if progress is not None:
        progress(len(frames), len(frames))
    return out


def _log_tasks(tables: LogTask, n: int) -> list[LogTask]:
    """``tables`` (every frame, in log order) in tasks of ``n`` frames, each with its frames' rows."""
    tasks = []
    for lo in range(0, len(tables.frames), n):
        frames = tables.frames.iloc[lo:lo + n]
        ids = frames["frame_id"].to_numpy()

        def rows(df: pd.DataFrame, ids: np.ndarray = ids) -> pd.DataFrame:
            at = df.index.isin(ids) if df.index.name == "frame_id" else df["frame_id"].isin(ids).to_numpy()
            return df[at]

        tasks.append(LogTask(tables.setting, frames, tables.stamps_ns[lo:lo + n], rows(tables.beacons),
                             {d: rows(t) for d, t in tables.detections.items()},
                             {p: rows(t) for p, t in tables.estimates.items()},
                             {s: rows(t) for s, t in tables.tracks.items()},
                             {s: rows(t) for s, t in tables.due.items()},
                             {p: rows(t) for p, t in tables.errors.items()}))
    return tasks
