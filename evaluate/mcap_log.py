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

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate.export_frames import deck_half_size_m
from deckpose.evaluate.log_topics import (
    TRUTH_DECK_TOPIC,
    errors_topic,
    estimate_frame,
    estimates_topic,
    prediction_frame,
    prediction_topic,
    track_frame,
    track_stem,
    track_topic,
)
from deckpose.evaluate.mcap_records import write_records
from deckpose.evaluate.mcap_scene import (
    ESTIMATE_RGBA,
    camera_entity,
    deck_entity,
    estimate_entity,
    scene_update,
)
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from deckpose import run_folder as rl
from deckpose.atomic_io import atomic_path
from deckpose.camera import CameraModel
from deckpose.capture_time import EPOCH_FLOOR_NS, capture_epoch, log_stamps
from deckpose.errors import InputDataError
from deckpose.image_store import ImageFormat, decode_image, encode_image
from deckpose.preview import PREVIEW_PX, make_preview, preview_size
from deckpose.rotation import R_from_zyx
from deckpose.tracking.due_predictions import predictions_due

TRUTH_RGBA = (0.1, 0.9, 0.2, 1.0)
DETECTION_RGBA = (1.0, 0.3, 0.1, 1.0)
#: Point sizes, preview pixels: the truth's larger, so it rings the detection drawn over it.
TRUTH_POINT_PX = 12.0
DETECTION_POINT_PX = 6.0


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
        cid = self._channel(topic, schema["title"], "json", json.dumps(schema).encode(),
                            "jsonschema")
        self._w.add_message(cid, log_time=stamp_ns, publish_time=stamp_ns,
                            data=json.dumps(obj, allow_nan=False).encode())

    def metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record: ``name`` and string key-value pairs."""
        self._w.add_metadata(name, data)

    def attachment(self, name: str, media_type: str, data: bytes, stamp_ns: int) -> None:
        """An attachment (a file's bytes), created and logged at ``stamp_ns``."""
        self._w.add_attachment(create_time=stamp_ns, log_time=stamp_ns, name=name, media_type=media_type, data=data)

    def finish(self) -> None:
        self._w.finish()


def _ts(stamp_ns: int) -> Timestamp:
    return Timestamp(seconds=stamp_ns // 1_000_000_000, nanos=stamp_ns % 1_000_000_000)


def _color(rgba: tuple[float, float, float, float]) -> Color:
    return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def preview_png(run: rl.RunPaths, frame_id: int, image: Path, camera: CameraModel, preview_px: int,
                stored_preview_px: int | None) -> tuple[bytes, int, int]:
    """A frame's preview as PNG bytes with its width and height, pixels.

    The render stage's own preview (``previews/<frame_id>.png``) when it has this
    ``preview_px`` (``stored_preview_px``, from the manifest), else made from the frame
    (decoded once more) by the same rule, :func:`deckpose.preview.make_preview`.
    """
    w, h = preview_size(camera.width_px, camera.height_px, preview_px)
    stored = run.preview(frame_id)
    if stored_preview_px == preview_px and stored.is_file():
        return stored.read_bytes(), w, h
    if not image.is_file():
        raise InputDataError(f"cannot read image {image}: no such file")
    img = decode_image(image.read_bytes(), str(image))
    small = make_preview(img, preview_px)
    return encode_image(small, ImageFormat.PNG), small.shape[1], small.shape[0]


#: Foxglove's names of distortion models where they differ from ROS's (``foxglove.CameraCalibration``
#: knows ``plumb_bob``, ``rational_polynomial`` and ``kannala_brandt``, the equidistant fisheye).
FOXGLOVE_DISTORTION_MODELS = {"equidistant": "kannala_brandt"}


def calibration_msg(camera: CameraModel, stamp_ns: int, width: int, height: int) -> CameraCalibration:
    """Calibration of the preview image: K scaled with the image (pixel centres kept)."""
    sx, sy = width / camera.width_px, height / camera.height_px
    K = camera.K.copy()
    K[0, 0] *= sx
    K[1, 1] *= sy
    K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
    K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
    P = np.hstack([K, np.zeros((3, 1))])
    D = list(camera.dist_coeffs) if camera.dist_coeffs.size else [0.0] * 5
    return CameraCalibration(timestamp=_ts(stamp_ns), frame_id="camera", width=width, height=height,
                             distortion_model=FOXGLOVE_DISTORTION_MODELS.get(camera.distortion_model,
                                                                             camera.distortion_model),
                             D=D, K=list(K.ravel()),
                             R=list(np.eye(3).ravel()), P=list(P.ravel()))


def annotations_msg(points_px: np.ndarray, ids: np.ndarray, sx: float, sy: float, stamp_ns: int,
                    rgba: tuple[float, float, float, float], label: str, *,
                    thickness_px: float = DETECTION_POINT_PX) -> ImageAnnotations:
    """Points (with id labels) in preview pixels, in Foxglove's image coordinates.

    Parameters
    ----------
    points_px : (N, 2) array of float, pixels
        Full-resolution points, OpenCV convention (pixel centres at integers).
    ids : (N,) array of int
        Beacon ids (-1: unidentified).
    sx, sy : float
        Preview pixels per full-resolution pixel along u and v.
    stamp_ns : int
        Annotation timestamp, integer nanoseconds (the image's).
    thickness_px : float
        Point diameter, preview pixels.

    Foxglove puts the origin at the top-left corner of the top-left pixel, so a
    full-resolution pixel centre ``u`` lands at ``(u + 0.5) * sx`` in the preview.
    """
    pts = [Point2(x=float((u + 0.5) * sx), y=float((v + 0.5) * sy)) for u, v in points_px]
    ann = ImageAnnotations()
    ann.points.append(PointsAnnotation(timestamp=_ts(stamp_ns), type=PointsAnnotation.Type.POINTS, points=pts,
                                       outline_color=_color(rgba), fill_color=_color(rgba), thickness=thickness_px))
    for p, i in zip(pts, ids):
        ann.texts.append(TextAnnotation(timestamp=_ts(stamp_ns), position=Point2(x=p.x + 6, y=p.y - 6),
                                        text=f"{label}{int(i)}" if i >= 0 else f"{label}?", font_size=12.0,
                                        text_color=_color(rgba), background_color=_color((0, 0, 0, 0.5))))
    return ann


def _transform(parent: str, child: str, R: np.ndarray, t: np.ndarray, stamp_ns: int) -> FrameTransform:
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return FrameTransform(timestamp=_ts(stamp_ns), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                          rotation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))


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


def _finite(d: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def _plain(rec: pd.Series) -> dict:
    """A table row as JSON-ready Python values (numpy scalars unwrapped, pandas NA as None)."""
    out = {}
    for k, v in rec.items():
        v = v.item() if hasattr(v, "item") else v
        out[str(k)] = None if v is pd.NA else v
    return out


#: Columns of the estimates and tracks tables logged as JSON (the covariances stay in the tables).
_ESTIMATE_LOGGED = ("ok", "reason", "roll_deg", "pitch_deg", "yaw_deg", "surge_m", "sway_m", "height_m",
                    "sigma_roll_deg", "sigma_pitch_deg", "sigma_yaw_deg", "sigma_surge_m", "sigma_sway_m",
                    "sigma_height_m")
_TRUTH_LOGGED = ("roll_deg", "pitch_deg", "yaw_deg", "heave_m", "surge_m", "sway_m", "camera_height_m")


def _row(table: pd.DataFrame, frame_id: int) -> pd.Series:
    """The row of ``table`` (indexed by frame id) of one frame."""
    return table.loc[frame_id]  # pyright: ignore[reportReturnType]  (a unique index gives one row)


def _deck_translation(row: pd.Series, surge_m: float, sway_m: float, height_m: float) -> np.ndarray:
    """World position of a deck estimated relative to the camera of frames-table ``row``.

    Surge and sway are the deck centre minus the camera (world x, y) and height the
    camera above the deck centre, so the deck sits at the camera's true position plus
    (surge, sway, -height); an unknown surge or sway (NaN) is taken as 0.
    """
    tx = row["cam_x_m"] + (surge_m if np.isfinite(surge_m) else 0.0)
    ty = row["cam_y_m"] + (sway_m if np.isfinite(sway_m) else 0.0)
    return np.array([tx, ty, row["cam_z_m"] - height_m])


def write_run_log(run: rl.RunPaths, out_path: Path | None = None, *, preview_px: int = PREVIEW_PX,
                  errors: pd.DataFrame | None = None, command: Sequence[str] = (),
                  progress: Callable[[int, int], object] | None = None) -> Path:
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
    """
    if not 16 <= preview_px <= 4096:
        raise InputDataError(f"preview_px must be within 16..4096 (viewers cannot show larger textures), got {preview_px}")
    frames = rl.read_frames(run)
    beacons = rl.read_beacons(run)
    manifest = rl.read_manifest(run)
    layout = rl.read_layout(run)
    deck_half_m = deck_half_size_m(manifest, layout)
    camera_names = sorted(frames["camera"].unique())
    cameras = rl.read_cameras(run, camera_names)
    # each detector's points and ids per frame, grouped once (a .loc per frame cost 1-5 ms)
    dets = {d: {f: (g[["u_px", "v_px"]].to_numpy(float), g["beacon_id"].to_numpy())
                for f, g in rl.read_detections(run, d).groupby("frame_id", sort=False)}
            for d in run.detectors()}
    no_points = (np.zeros((0, 2)), np.zeros(0))
    pairs = run.estimate_pairs()
    ests = {p: rl.read_estimates(run, *p).set_index("frame_id") for p in pairs}
    est_logged = {p: [c for c in _ESTIMATE_LOGGED if c in e.columns] for p, e in ests.items()}
    est_schema = {p: table_json_schema(ests[p][est_logged[p]], "deckpose.FrameEstimate") for p in pairs}
    truth_cols = [c for c in _TRUTH_LOGGED if c in frames.columns]
    truth_schema = table_json_schema(frames[truth_cols], "deckpose.DeckTruth")
    tracks = {}
    for t in run.track_triples():
        tr = rl.read_tracks(run, *t)
        due = predictions_due(tr, rl.read_track_predictions(run, *t))
        track_cols = [c for c in tr.columns if not c.startswith("cov_") and c != "frame_id"]
        tracks[track_stem(*t)] = (tr.set_index("frame_id"), track_cols,
                                  {f: g for f, g in due.groupby("frame_id")},
                                  table_json_schema(tr[track_cols], "deckpose.TrackState"),
                                  table_json_schema(due.drop(columns="frame_id"), "deckpose.DuePrediction"))
    err_by_pair = {}
    err_schema: dict = {}
    if errors is not None and len(errors):
        err_schema = errors_json_schema(errors)
        for (d, m), g in errors.groupby(["detector", "method"]):
            err_by_pair[(d, m)] = g.set_index("frame_id")
    if len(frames) and int(frames["stamp_ns"].min()) >= EPOCH_FLOOR_NS:
        epoch = (0, "stamps")
    else:
        epoch = capture_epoch(manifest)
    stamps = log_stamps(frames, epoch[0])
    beacons_by_frame = {f: g for f, g in beacons.groupby("frame_id")}
    stored_preview_px = manifest.get("preview_px")
    out = Path(out_path) if out_path else run.mcap
    with atomic_path(out) as tmp, open(tmp, "wb") as fh:
        log = McapLog(fh)
        write_records(log, run, manifest, camera_names, command, epoch, int(stamps.min()) if len(stamps) else 0)
        for k, i in enumerate(np.argsort(stamps.to_numpy(), kind="stable")):
            if progress is not None and k:  # k frames logged
                progress(k, len(frames))
            row = frames.iloc[i]
            f = int(row["frame_id"])
            ts = int(stamps.iloc[i])
            cam = cameras[row["camera"]]
            png, w, h = preview_png(run, f, run.root / row["image"], cam, preview_px, stored_preview_px)
            sx, sy = w / cam.width_px, h / cam.height_px
            log.proto("/camera/image", CompressedImage(timestamp=_ts(ts), frame_id="camera",
                                                       data=png, format="png"), ts)
            log.proto("/camera/calibration", calibration_msg(cam, ts, w, h), ts)
            b = beacons_by_frame.get(f)
            if b is not None:
                vis = b[b["visible"].astype(bool)]
                log.proto("/annotations/truth", annotations_msg(vis[["u_px", "v_px"]].to_numpy(float),
                                                                vis["beacon_id"].to_numpy(), sx, sy, ts, TRUTH_RGBA, "T",
                                                                thickness_px=TRUTH_POINT_PX), ts)
            for d, by_frame in dets.items():
                uv, ids = by_frame.get(f, no_points)
                log.proto(f"/annotations/{d}", annotations_msg(uv, ids, sx, sy, ts, DETECTION_RGBA, ""), ts)
            R_deck = R_from_zyx(*(math.radians(row[f"{q}_deg"]) for q in ("roll", "pitch", "yaw")))
            tfs = FrameTransforms()
            tfs.transforms.append(_transform("world", "deck", R_deck,
                                             np.array([row["surge_m"], row["sway_m"], row["heave_m"]]), ts))
            tfs.transforms.append(_transform("world", "camera", rl.R_world_from_cam(row),
                                             np.array([row["cam_x_m"], row["cam_y_m"], row["cam_z_m"]]), ts))
            entities = [deck_entity(layout, deck_half_m, ts), camera_entity(cam, float(row["camera_height_m"]), ts)]
            keys = {"frame_id": f, "t_s": float(row["t_s"]), "stamp_ns": int(row["stamp_ns"])}
            log.json(TRUTH_DECK_TOPIC, _finite({**_plain(row[truth_cols]), **keys}), ts, truth_schema)
            for k, ((d, m), edf) in enumerate(ests.items()):
                if f not in edf.index:
                    continue
                e = _row(edf, f)
                log.json(estimates_topic(d, m), _finite({**_plain(e[est_logged[(d, m)]]), **keys,
                                                         "detector": d, "method": m}), ts, est_schema[(d, m)])
                if not bool(e["ok"]):
                    continue
                R_est = R_from_zyx(*np.radians([e["roll_deg"], e["pitch_deg"], e["yaw_deg"]]))
                frame_est = estimate_frame(d, m)
                tfs.transforms.append(_transform("world", frame_est, R_est,
                                                 _deck_translation(row, float(e["surge_m"]), float(e["sway_m"]),
                                                                   float(e["height_m"])), ts))
                entities.append(estimate_entity(frame_est, layout.radius_m, ESTIMATE_RGBA[k % len(ESTIMATE_RGBA)], ts))
            for k, (stem, (tdf, track_cols, due_by_frame, track_schema, due_schema)) in enumerate(tracks.items()):
                if f not in tdf.index:
                    continue
                tr = _row(tdf, f)
                log.json(track_topic(stem), _finite({**_plain(tr[track_cols]), **keys, "track": stem}), ts,
                         track_schema)
                R_tr = R_from_zyx(*np.radians([tr["roll_deg"], tr["pitch_deg"], tr["yaw_deg"]]))
                colour = ESTIMATE_RGBA[(len(ests) + k) % len(ESTIMATE_RGBA)]
                tfs.transforms.append(_transform("world", track_frame(stem), R_tr,
                                                 _deck_translation(row, float(tr["surge_m"]), float(tr["sway_m"]),
                                                                   float(tr["height_m"])),
                                                 ts))
                entities.append(estimate_entity(track_frame(stem), layout.radius_m, colour, ts))
                due = due_by_frame.get(f)
                for _, p in (due.iterrows() if due is not None else ()):
                    h = float(p["horizon_s"])
                    log.json(prediction_topic(stem, h), _finite({**_plain(p.drop("frame_id")), **keys,
                                                                  "track": stem}), ts, due_schema)
                    # the predicted deck: predicted roll, pitch and height; yaw, surge and sway as filtered now
                    R_p = R_from_zyx(*np.radians([p["roll_deg"], p["pitch_deg"], tr["yaw_deg"]]))
                    tfs.transforms.append(_transform("world", prediction_frame(stem, h), R_p,
                                                     _deck_translation(row, float(tr["surge_m"]), float(tr["sway_m"]),
                                                                       float(p["height_m"])), ts))
                    entities.append(estimate_entity(prediction_frame(stem, h), layout.radius_m,
                                                    (colour[0], colour[1], colour[2], 0.15), ts))
            log.proto("/tf", tfs, ts)
            log.proto("/scene", scene_update(entities, ts), ts)
            for (d, m), edf in err_by_pair.items():
                if f in edf.index:
                    obj = _plain(_row(edf, f))
                    obj.update(keys, detector=d, method=m)
                    log.json(errors_topic(d, m), _finite(obj), ts, err_schema)
        log.finish()
    if progress is not None:
        progress(len(frames), len(frames))
    return out
