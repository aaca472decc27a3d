"""The messages of each frame of a run's MCAP log, built apart from the writing.

:func:`log_task` turns a :class:`LogTask` (a chunk of frames in log order, with the rows
of every table that concern them) into each frame's :class:`LogMessage` list: serialized
protobuf or JSON, with its topic and log time. It is a pure function of its task, so
worker processes can build the chunks side by side while the process that writes the
log (:func:`deckpose.evaluate.mcap_log.write_run_log`) adds them in frame order: the
file is the same for any number of workers. Topics, schemas and conventions:
:mod:`deckpose.evaluate.mcap_log`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate.log_topics import (
    TRUTH_DECK_TOPIC,
    errors_topic,
    estimate_frame,
    estimates_topic,
    prediction_frame,
    prediction_topic,
    track_frame,
    track_topic,
)
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
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.message import Message
from google.protobuf.timestamp_pb2 import Timestamp
from scipy.spatial.transform import Rotation

from deckpose import run_folder as rl
from deckpose.camera import CameraModel
from deckpose.errors import InputDataError
from deckpose.image_store import ImageFormat, decode_image, encode_image
from deckpose.layout import DeckLayout
from deckpose.preview import make_preview, preview_size
from deckpose.rotation import R_from_zyx

__all__ = ["DETECTION_POINT_PX", "DETECTION_RGBA", "ERRORS_SCHEMA", "ESTIMATE_LOGGED", "FOXGLOVE_DISTORTION_MODELS",
           "PROTO_TYPES", "TRUTH_LOGGED", "TRUTH_POINT_PX", "TRUTH_RGBA", "TRUTH_SCHEMA", "LogMessage", "LogSetting", "LogTask",
           "annotations_msg", "calibration_msg", "due_schema", "json_bytes", "log_task", "preview_png"]

TRUTH_RGBA = (0.1, 0.9, 0.2, 1.0)
DETECTION_RGBA = (1.0, 0.3, 0.1, 1.0)
#: Point sizes, preview pixels: the truth's larger, so it rings the detection drawn over it.
TRUTH_POINT_PX = 12.0
DETECTION_POINT_PX = 6.0


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
ESTIMATE_LOGGED = ("ok", "reason", "roll_deg", "pitch_deg", "yaw_deg", "surge_m", "sway_m", "height_m",
                    "sigma_roll_deg", "sigma_pitch_deg", "sigma_yaw_deg", "sigma_surge_m", "sigma_sway_m",
                    "sigma_height_m")
TRUTH_LOGGED = ("roll_deg", "pitch_deg", "yaw_deg", "heave_m", "surge_m", "sway_m", "camera_height_m")


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



def json_bytes(obj: dict) -> bytes:
    """A JSON message's bytes (NaN refused: :func:`_finite` writes it as null first)."""
    return json.dumps(obj, allow_nan=False).encode()


@dataclass(frozen=True)
class LogMessage:
    """One message of the log, serialized.

    Attributes
    ----------
    topic : str
    stamp_ns : int
        Log and publish time, integer nanoseconds.
    data : bytes
        The serialized message (protobuf, or JSON).
    proto : str
        The protobuf message's full name (a key of :data:`PROTO_TYPES`, whose class gives
        the schema), or ``""`` for JSON.
    schema : str
        JSON: the key of its JSON Schema in :class:`LogSetting`'s ``schemas``.
    """

    topic: str
    stamp_ns: int
    data: bytes
    proto: str = ""
    schema: str = ""


@dataclass(frozen=True)
class LogSetting:
    """What every frame of a run's log shares (the same in every :class:`LogTask`).

    Attributes
    ----------
    root : Path
        The run folder (previews and, at another ``preview_px``, the frames are read from it).
    layout : DeckLayout
    deck_half_m : float
        Half the deck plate's side, metres.
    cameras : dict of str to CameraModel
    preview_px : int
        Long side of the log's previews, pixels.
    stored_preview_px : int or None
        Long side of the render stage's stored previews (the manifest's).
    detectors : tuple of str
        Detectors with detections, in the log's order.
    estimate_columns : dict of (str, str) to tuple of str
        Per (detector, method) in the log's order: the estimates' columns logged.
    truth_columns : tuple of str
        The frames table's columns logged on ``/truth/deck``.
    track_columns : dict of str to tuple of str
        Per track (its stem) in the log's order: the tracks' columns logged.
    error_pairs : tuple of (str, str)
        The (detector, method) pairs with errors, in the log's order.
    """

    root: Path
    layout: DeckLayout
    deck_half_m: float
    cameras: dict[str, CameraModel]
    preview_px: int
    stored_preview_px: int | None
    detectors: tuple[str, ...]
    estimate_columns: dict[tuple[str, str], tuple[str, ...]]
    truth_columns: tuple[str, ...]
    track_columns: dict[str, tuple[str, ...]]
    error_pairs: tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class LogTask:
    """A chunk of the log's frames with the rows of each table that concern them.

    Attributes
    ----------
    setting : LogSetting
    frames : DataFrame
        The chunk's rows of the frames table, in log order.
    stamps_ns : (F,) array of int64
        Each row's log time, integer nanoseconds.
    beacons : DataFrame
        The chunk's rows of the beacons table (truth).
    detections : dict of str to DataFrame
        Per detector, the chunk's detections.
    estimates : dict of (str, str) to DataFrame
        Per (detector, method), the chunk's estimates, indexed by frame id.
    tracks : dict of str to DataFrame
        Per track, the chunk's filtered states, indexed by frame id.
    due : dict of str to DataFrame
        Per track, the predictions due at the chunk's frames (:func:`~deckpose.tracking.
        due_predictions.predictions_due`).
    errors : dict of (str, str) to DataFrame
        Per (detector, method), the chunk's errors, indexed by frame id.
    """

    setting: LogSetting
    frames: pd.DataFrame
    stamps_ns: np.ndarray
    beacons: pd.DataFrame
    detections: dict[str, pd.DataFrame]
    estimates: dict[tuple[str, str], pd.DataFrame]
    tracks: dict[str, pd.DataFrame]
    due: dict[str, pd.DataFrame]
    errors: dict[tuple[str, str], pd.DataFrame]


def log_task(task: LogTask) -> list[list[LogMessage]]:
    """Each frame's messages of ``task``, in log order (the workers' entry point)."""
    s = task.setting
    # each detector's points and ids per frame, grouped once (a .loc per frame cost 1-5 ms)
    dets = {d: {f: (g[["u_px", "v_px"]].to_numpy(float), g["beacon_id"].to_numpy())
                for f, g in task.detections[d].groupby("frame_id", sort=False)}
            for d in s.detectors}
    no_points = (np.zeros((0, 2)), np.zeros(0))
    beacons_by_frame = {f: g for f, g in task.beacons.groupby("frame_id")}
    due_by_track = {stem: {f: g for f, g in due.groupby("frame_id")} for stem, due in task.due.items()}
    out = []
    for i in range(len(task.frames)):
        row = task.frames.iloc[i]
        f = int(row["frame_id"])
        ts = int(task.stamps_ns[i])
        msgs: list[LogMessage] = []

        def proto(topic: str, msg: Message, ts: int = ts, msgs: list[LogMessage] = msgs) -> None:
            msgs.append(LogMessage(topic, ts, msg.SerializeToString(), proto=msg.DESCRIPTOR.full_name))

        def json_msg(topic: str, obj: dict, schema: str, ts: int = ts, msgs: list[LogMessage] = msgs) -> None:
            msgs.append(LogMessage(topic, ts, json_bytes(_finite(obj)), schema=schema))

        cam = s.cameras[row["camera"]]
        png, w, h = preview_png(rl.RunPaths(s.root), f, s.root / row["image"], cam, s.preview_px,
                                s.stored_preview_px)
        sx, sy = w / cam.width_px, h / cam.height_px
        proto("/camera/image", CompressedImage(timestamp=_ts(ts), frame_id="camera", data=png, format="png"))
        proto("/camera/calibration", calibration_msg(cam, ts, w, h))
        b = beacons_by_frame.get(f)
        if b is not None:
            vis = b[b["visible"].astype(bool)]
            proto("/annotations/truth", annotations_msg(vis[["u_px", "v_px"]].to_numpy(float),
                                                        vis["beacon_id"].to_numpy(), sx, sy, ts, TRUTH_RGBA, "T",
                                                        thickness_px=TRUTH_POINT_PX))
        for d, by_frame in dets.items():
            uv, ids = by_frame.get(f, no_points)
            proto(f"/annotations/{d}", annotations_msg(uv, ids, sx, sy, ts, DETECTION_RGBA, ""))
        R_deck = R_from_zyx(*(math.radians(row[f"{q}_deg"]) for q in ("roll", "pitch", "yaw")))
        tfs = FrameTransforms()
        tfs.transforms.append(_transform("world", "deck", R_deck,
                                         np.array([row["surge_m"], row["sway_m"], row["heave_m"]]), ts))
        tfs.transforms.append(_transform("world", "camera", rl.R_world_from_cam(row),
                                         np.array([row["cam_x_m"], row["cam_y_m"], row["cam_z_m"]]), ts))
        entities = [deck_entity(s.layout, s.deck_half_m, ts), camera_entity(cam, float(row["camera_height_m"]), ts)]
        keys = {"frame_id": f, "t_s": float(row["t_s"]), "stamp_ns": int(row["stamp_ns"])}
        json_msg(TRUTH_DECK_TOPIC, {**_plain(row[list(s.truth_columns)]), **keys}, TRUTH_SCHEMA)
        for k, ((d, m), cols) in enumerate(s.estimate_columns.items()):
            edf = task.estimates[(d, m)]
            if f not in edf.index:
                continue
            e = _row(edf, f)
            json_msg(estimates_topic(d, m), {**_plain(e[list(cols)]), **keys, "detector": d, "method": m},
                     estimates_topic(d, m))
            if not bool(e["ok"]):
                continue
            R_est = R_from_zyx(*np.radians([e["roll_deg"], e["pitch_deg"], e["yaw_deg"]]))
            frame_est = estimate_frame(d, m)
            tfs.transforms.append(_transform("world", frame_est, R_est,
                                             _deck_translation(row, float(e["surge_m"]), float(e["sway_m"]),
                                                               float(e["height_m"])), ts))
            entities.append(estimate_entity(frame_est, s.layout.radius_m, ESTIMATE_RGBA[k % len(ESTIMATE_RGBA)], ts))
        for k, (stem, track_cols) in enumerate(s.track_columns.items()):
            tdf = task.tracks[stem]
            if f not in tdf.index:
                continue
            tr = _row(tdf, f)
            json_msg(track_topic(stem), {**_plain(tr[list(track_cols)]), **keys, "track": stem}, track_topic(stem))
            R_tr = R_from_zyx(*np.radians([tr["roll_deg"], tr["pitch_deg"], tr["yaw_deg"]]))
            colour = ESTIMATE_RGBA[(len(s.estimate_columns) + k) % len(ESTIMATE_RGBA)]
            tfs.transforms.append(_transform("world", track_frame(stem), R_tr,
                                             _deck_translation(row, float(tr["surge_m"]), float(tr["sway_m"]),
                                                               float(tr["height_m"])),
                                             ts))
            entities.append(estimate_entity(track_frame(stem), s.layout.radius_m, colour, ts))
            due = due_by_track[stem].get(f)
            for _, p in (due.iterrows() if due is not None else ()):
                h = float(p["horizon_s"])
                json_msg(prediction_topic(stem, h), {**_plain(p.drop("frame_id")), **keys, "track": stem},
                         due_schema(stem))
                # the predicted deck: predicted roll, pitch and height; yaw, surge and sway as filtered now
                R_p = R_from_zyx(*np.radians([p["roll_deg"], p["pitch_deg"], tr["yaw_deg"]]))
                tfs.transforms.append(_transform("world", prediction_frame(stem, h), R_p,
                                                 _deck_translation(row, float(tr["surge_m"]), float(tr["sway_m"]),
                                                                   float(p["height_m"])), ts))
                entities.append(estimate_entity(prediction_frame(stem, h), s.layout.radius_m,
                                                (colour[0], colour[1], colour[2], 0.15), ts))
        proto("/tf", tfs)
        proto("/scene", scene_update(entities, ts))
        for d, m in s.error_pairs:
            edf = task.errors[(d, m)]
            if f in edf.index:
                obj = _plain(_row(edf, f))
                obj.update(keys, detector=d, method=m)
                json_msg(errors_topic(d, m), obj, ERRORS_SCHEMA)
        out.append(msgs)
    return out


#: The protobuf messages of the log by full name (:attr:`LogMessage.proto`; the classes do not
#: pickle, so a worker sends the name).
PROTO_TYPES: dict[str, type[Message]] = {cls.DESCRIPTOR.full_name: cls for cls in (
    CompressedImage, CameraCalibration, ImageAnnotations, FrameTransforms, SceneUpdate)}

#: :attr:`LogMessage.schema` keys of the truth's and the errors' JSON Schemas (an estimate's and a
#: track's is its topic; a track's predictions', :func:`due_schema`).
TRUTH_SCHEMA = "truth"
ERRORS_SCHEMA = "errors"


def due_schema(stem: str) -> str:
    """The :attr:`LogMessage.schema` key of a track's predictions' JSON Schema."""
    return f"due:{stem}"
