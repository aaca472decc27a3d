"""The run folder: its format names, where each stage's output lives, and reading it with clear errors.

Every stage reads and writes a run folder through this module (render, the synthetic
dataset writer, detect, estimate, evaluate, report).

A run folder is a rendered dataset (``deckpose render``) that later stages add to::

    RUN/manifest.json, cameras/, images/, frames.parquet, beacons.parquet,
        lights.parquet, painted_ring.parquet                                (render)
    RUN/detections/<detector>.parquet [+ <detector>.frames.parquet]       (deckpose detect)
    RUN/estimates/<detector>--<method>.parquet                             (deckpose estimate --run)
    RUN/tracks/<detector>--<method>--<tracker>.parquet [+ .predictions.parquet, .run.json]
                                                                           (deckpose track)
    RUN/evaluation/errors.parquet, resolution_tables.{md,csv}              (deckpose evaluate)
    RUN/log.mcap                                                           (deckpose evaluate)
    RUN/report/report.md, report/figures/*.png                             (deckpose report)

A missing stage output raises :class:`~deckpose.errors.InputDataError` naming
the file and the command that makes it.
"""

from __future__ import annotations

import json
import math
import os
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from deckpose.camera import CameraModel
from deckpose.camera_info import camera_to_dict, read_camera_info
from deckpose.errors import CameraFileError, InputDataError
from deckpose.layout import DeckLayout, layout_from_dict
from deckpose.output_folder import held_by_another
from deckpose.pose import CameraPose, ShipPose
from deckpose.shell_command import deckpose_command
from deckpose.table_schemas import (
    LIGHT_COLUMNS,
    ROTATION_COLUMN_NAMES,
    typed_frame,
    upgrade_legacy_columns,
)
from deckpose.tables import read_table

#: Format of a rendered (or synthetic) dataset, recorded in its manifest.
DATASET_FORMAT = "deckpose-dataset/1"
#: Format of a detect run's metadata file.
DETECTIONS_FORMAT = "deckpose-detections/1"
#: The record ``deckpose detect -o DIR`` writes beside its tables: DIR is a detections folder
#: (``detections.parquet``, ``detect_frames.parquet``, ``cameras/``), not a run folder.
DETECT_RECORD = "detect_run.json"
#: Where ``deckpose estimate FOLDER`` writes a detections folder's estimates (unless ``-o``).
FOLDER_ESTIMATES = "estimates.parquet"
#: Between the detector and the method in an estimates file name (``cog--pnp.parquet``).
SEPARATOR = "--"
#: The painted ring's edge detector (``deckpose painted-ring``): its detections table is one row
#: per frame (fitted ellipses), not beacons, so :meth:`RunPaths.detectors` leaves it out.
RING_DETECTOR = "ring-edges"
#: The folders of the cameras' ROS camera_info files and of the frames' images.
CAMERAS_DIR, IMAGES_DIR, PREVIEWS_DIR = "cameras", "images", "previews"


def camera_relpath(name: str) -> str:
    """A camera's camera_info file, relative to the run folder (``cameras/8mp.yaml``)."""
    return f"{CAMERAS_DIR}/{name}.yaml"


def image_relpath(frame_id: int, suffix: str = ".png") -> str:
    """A frame's image, relative to the run folder (``images/000042.png``; ``.zst``: :mod:`deckpose.image_store`)."""
    return f"{IMAGES_DIR}/{frame_id:06d}{suffix}"


def preview_relpath(frame_id: int) -> str:
    """A frame's 8-bit preview (:mod:`deckpose.preview`), relative to the run folder (``previews/000042.png``)."""
    return f"{PREVIEWS_DIR}/{frame_id:06d}.png"


def manifest_cameras(cameras: dict[str, CameraModel]) -> list[dict[str, Any]]:
    """The manifest's ``cameras`` entries: name, camera file (relative) and its camera_info."""
    return [{"name": n, "file": camera_relpath(n), "camera_info": camera_to_dict(c)}
            for n, c in cameras.items()]


@dataclass(frozen=True)
class RunPaths:
    """Paths inside one run folder."""

    root: Path

    @property
    def manifest(self) -> Path:
        return self.root / "manifest.json"

    @property
    def frames(self) -> Path:
        return self.root / "frames.parquet"

    @property
    def beacons(self) -> Path:
        return self.root / "beacons.parquet"

    @property
    def lights(self) -> Path:
        """Non-beacon lights per frame (render; absent from datasets of earlier versions)."""
        return self.root / "lights.parquet"

    @property
    def painted_ring(self) -> Path:
        """The painted ring's truth per frame and edge (render; only with ``painted_ring``)."""
        return self.root / "painted_ring.parquet"

    @property
    def cameras_dir(self) -> Path:
        return self.root / CAMERAS_DIR

    def camera_file(self, name: str) -> Path:
        return self.root / camera_relpath(name)

    def hot_pixels_file(self, name: str) -> Path:
        """A camera's hot pixels (render with ``sensor.hot_pixel_fraction`` > 0 only)."""
        return self.cameras_dir / f"{name}_hot_pixels.parquet"

    @property
    def images_dir(self) -> Path:
        return self.root / IMAGES_DIR

    @property
    def previews_dir(self) -> Path:
        return self.root / PREVIEWS_DIR

    def preview(self, frame_id: int) -> Path:
        """The frame's preview image (written by the render stage since the preview existed)."""
        return self.root / preview_relpath(frame_id)

    @property
    def detections_dir(self) -> Path:
        return self.root / "detections"

    def detections(self, detector: str) -> Path:
        return self.detections_dir / f"{detector}.parquet"

    def detect_frames(self, detector: str) -> Path:
        return self.detections_dir / f"{detector}.frames.parquet"

    def detect_run_record(self, detector: str) -> Path:
        return self.detections_dir / f"{detector}.run.json"

    @property
    def estimates_dir(self) -> Path:
        return self.root / "estimates"

    def estimates(self, detector: str, method: str) -> Path:
        return self.estimates_dir / f"{detector}{SEPARATOR}{method}.parquet"

    @property
    def tracks_dir(self) -> Path:
        return self.root / "tracks"

    def made_from_detections(self, detector: str) -> list[Path]:
        """The files estimated or tracked from ``detector``'s detections (``estimates/cog--*``,
        ``tracks/cog--*``): stale once those detections are made again."""
        return sorted(p for d in (self.estimates_dir, self.tracks_dir) if d.is_dir()
                      for p in d.glob(f"{detector}{SEPARATOR}*") if p.is_file())

    def _track_stem(self, detector: str, method: str, tracker: str) -> str:
        return f"{detector}{SEPARATOR}{method}{SEPARATOR}{tracker}"

    def tracks(self, detector: str, method: str, tracker: str) -> Path:
        """The filtered states of one estimates table (``tracks/cog--pnp--wave-bank.parquet``)."""
        return self.tracks_dir / f"{self._track_stem(detector, method, tracker)}.parquet"

    def track_predictions(self, detector: str, method: str, tracker: str) -> Path:
        """The predictions ahead of each filtered state (``tracks/cog--pnp--wave-bank.predictions.parquet``)."""
        return self.tracks_dir / f"{self._track_stem(detector, method, tracker)}.predictions.parquet"

    def track_run_record(self, detector: str, method: str, tracker: str) -> Path:
        """The resolved tracker config, inputs and counts of a track run (``.run.json``)."""
        return self.tracks_dir / f"{self._track_stem(detector, method, tracker)}.run.json"

    @property
    def evaluation_dir(self) -> Path:
        return self.root / "evaluation"

    @property
    def errors(self) -> Path:
        return self.evaluation_dir / "errors.parquet"

    @property
    def mcap(self) -> Path:
        return self.root / "log.mcap"

    @property
    def report_dir(self) -> Path:
        return self.root / "report"

    def detectors(self) -> list[str]:
        """Detectors with outputs in this run."""
        d = self.detections_dir
        # a hidden name is a writer's temporary file (atomic_io), never a stage output
        return sorted(p.stem for p in d.glob("*.parquet")
                      if not p.name.endswith(".frames.parquet") and not p.name.startswith(".")
                      and p.stem != RING_DETECTOR) if d.is_dir() else []

    def estimate_pairs(self) -> list[tuple[str, str]]:
        """``(detector, method)`` pairs with estimates in this run."""
        d = self.estimates_dir
        if not d.is_dir():
            return []
        pairs = []
        for p in sorted(d.glob(f"*{SEPARATOR}*.parquet")):
            if p.name.startswith(".") or "." in p.stem:  # a writer's temporary file; a side table (.bound)
                continue
            det, _, method = p.stem.partition(SEPARATOR)
            pairs.append((det, method))
        return pairs

    def track_triples(self) -> list[tuple[str, str, str]]:
        """``(detector, method, tracker)`` triples with tracks in this run (``deckpose track``'s outputs)."""
        d = self.tracks_dir
        if not d.is_dir():
            return []
        triples = []
        for p in sorted(d.glob(f"*{SEPARATOR}*{SEPARATOR}*.parquet")):
            if p.name.startswith(".") or p.name.endswith(".predictions.parquet"):
                continue
            parts = p.stem.split(SEPARATOR)
            if len(parts) == 3:
                triples.append((parts[0], parts[1], parts[2]))
        return triples


def _require(path: Path, command: str) -> None:
    if not path.exists():
        raise InputDataError(f"{path} is missing; make it with: {command}")


def unfinished_render(run: RunPaths) -> str | None:
    """Why ``run``'s dataset cannot be read yet: a render still writing it, or one that
    stopped before its last frame (with the command that finishes it); None when its
    manifest says it is complete, or there is no manifest to say."""
    try:
        manifest = json.loads(run.manifest.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("complete") is not False:
        return None
    parts = run.root / ".parts"
    done = len(list(parts.glob("*.json"))) if parts.is_dir() else 0
    total = manifest.get("n_frames", "?")
    writer = held_by_another(run.root)
    if writer is not None:
        return (f"{run.root} is still being rendered by another deckpose job ({writer}; {done} of "
                f"{total} frames so far); wait for it to finish")
    return (f"{run.root} is an unfinished dataset ({done} of {total} frames rendered); finish it "
            f"with: {deckpose_command('render', 'CONFIG.yaml', run.root, '--resume')}")


def require_dataset(run: RunPaths) -> None:
    """Raise unless the render stage's outputs are present.

    A detections folder (``deckpose detect -o DIR``) is named as such, with what to run
    instead, rather than as a run folder that lacks its frames; a file, as a file; an
    interrupted render, with the command that finishes it.
    """
    if run.root.is_file():
        raise InputDataError(f"{run.root} is a file, not a run folder; give the folder that "
                             f"deckpose render (or deckpose pipeline) wrote")
    if not run.root.is_dir():
        raise InputDataError(f"run folder {run.root} does not exist; make it with: "
                             f"{deckpose_command('render', 'CONFIG.yaml', run.root)}")
    if not run.manifest.exists():
        record = detections_folder_record(run.root)
        if record is not None:
            raise InputDataError(detections_folder_message(run.root, record))
    unfinished = unfinished_render(run)
    if unfinished is not None:
        raise InputDataError(unfinished)
    for p in (run.manifest, run.frames, run.beacons):
        _require(p, deckpose_command("render", "CONFIG.yaml", run.root))


def detections_folder_record(root: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The :data:`DETECT_RECORD` of a detections folder (``deckpose detect -o``); None for any other folder."""
    path = Path(root) / DETECT_RECORD
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("format") == DETECTIONS_FORMAT else None


@dataclass(frozen=True)
class DetectionsFolder:
    """A detections folder (``deckpose detect -o DIR``) as its record describes it.

    Attributes
    ----------
    root : Path
        The folder.
    detections : Path
        Its detections table.
    camera_files : dict of str to Path
        Each camera's camera_info file, by camera name (one per camera its frames came from).
    layout : DeckLayout
        The deck layout the frames were identified with.
    detector, source, source_kind : str
        The detector, the folder or dataset it detected, and ``"dataset"`` or ``"images"``.
    """

    root: Path
    detections: Path
    camera_files: dict[str, Path]
    layout: DeckLayout
    detector: str
    source: str
    source_kind: str


def read_detections_folder(root: str | os.PathLike[str]) -> DetectionsFolder | None:
    """The detections folder at ``root``; None where ``root`` holds no :data:`DETECT_RECORD`.

    Raises
    ------
    ConfigError
        The record's layout is not a valid layout.
    """
    record = detections_folder_record(root)
    if record is None:
        return None
    root = Path(root)
    cameras = record.get("cameras") or {}
    return DetectionsFolder(
        root=root, detections=root / str(record.get("detections", "detections.parquet")),
        camera_files={str(name): root / str(rel) for name, rel in cameras.items()},
        layout=layout_from_dict(record.get("layout"), f"{root / DETECT_RECORD}: layout"),
        detector=str(record.get("detector", "cog")), source=str(record.get("source", "SOURCE")),
        source_kind=str(record.get("source_kind", "")))


def detections_folder_message(root: str | os.PathLike[str], record: dict[str, Any]) -> str:
    """What a detections folder is, and what to run instead of giving it where a run folder is needed.

    Parameters
    ----------
    root : path-like
        The folder ``deckpose detect -o`` wrote.
    record : dict
        Its :data:`DETECT_RECORD` (:func:`detections_folder_record`).
    """
    root = Path(root)
    detector = str(record.get("detector", "cog"))
    source = str(record.get("source", "SOURCE"))
    cameras = record.get("cameras") or {}
    table = deckpose_command("estimate", root)
    what = (f"{root} is a detections folder: 'deckpose detect -o' wrote {detector}'s detections of "
            f"{source} there; it holds no frames or ground truth, so it is not a run folder")
    alone = (f"; or estimate from its table alone: {table}" if len(cameras) <= 1 else
             f" (its frames come from {len(cameras)} cameras, so its table cannot be estimated with one "
             "--camera)")
    if record.get("source_kind") != "dataset":  # a folder of images: nothing to evaluate against
        return f"{what}. Estimate from its table: {table}"
    return (f"{what}. Detect into the dataset itself (without -o) and give the dataset to this "
            f"command, e.g.: {deckpose_command('detect', source, '--detector', detector)} then "
            f"{deckpose_command('estimate', '--run', source, '--detector', detector)}{alone}")


def several_cameras_message(folder: DetectionsFolder) -> str:
    """Why a detections folder of several cameras' frames cannot be estimated as one table, and what to run."""
    names = ", ".join(sorted(folder.camera_files))
    return (f"{folder.root}: its frames come from {len(folder.camera_files)} cameras ({names}), and one "
            "table estimate takes one camera, so the others' frames would be solved with the wrong camera. "
            f"Detect into the dataset itself and estimate it as a run: {deckpose_command('detect', folder.source)} "
            f"then {deckpose_command('estimate', '--run', folder.source)}")


def check_folder_camera(folder: DetectionsFolder, camera: CameraModel, detections: str | os.PathLike[str]) -> None:
    """Refuse ``--camera`` for a detections folder's table whose frames another camera took.

    A table that ``deckpose detect -o`` wrote sits beside its record, which names the cameras
    of its frames (:data:`DETECT_RECORD`, read into ``folder``). Estimated with a camera of
    another image size, or with one camera where there were several, its frames would be
    solved with the wrong intrinsics and look ok (a 960x540 frame solved as 640x480: 20 m for
    a true 30 m).

    Raises
    ------
    InputDataError
        The folder's frames come from several cameras, or from one of another image size.
    """
    if len(folder.camera_files) > 1:
        raise InputDataError(several_cameras_message(folder))
    if len(folder.camera_files) == 1:
        name, path = next(iter(folder.camera_files.items()))
        try:
            own = read_camera_info(path)
        except CameraFileError:  # an unreadable record camera: nothing to compare with
            return
        if (own.width_px, own.height_px) != (camera.width_px, camera.height_px):
            raise InputDataError(
                f"{detections}: its frames are {own.width_px}x{own.height_px} (camera {name}), but "
                f"--camera is {camera.width_px}x{camera.height_px}; give the camera that took them: "
                f"--camera {shlex.quote(os.fspath(path))}")


def read_manifest(run: RunPaths) -> dict[str, Any]:
    require_dataset(run)
    try:
        return json.loads(run.manifest.read_text())
    except json.JSONDecodeError as exc:
        raise InputDataError(f"{run.manifest}: not valid JSON ({exc})") from exc


def read_layout(run: RunPaths) -> DeckLayout:
    """The deck layout recorded in the run's manifest."""
    man = read_manifest(run)
    return layout_from_dict(man.get("layout"), f"{run.manifest}: layout")


def read_frames(run: RunPaths) -> pd.DataFrame:
    """The run's frames table (an older run's columns under today's names and units)."""
    require_dataset(run)
    return upgrade_legacy_columns(read_table(run.frames, "frames table"), "frames")


def read_beacons(run: RunPaths) -> pd.DataFrame:
    require_dataset(run)
    return read_table(run.beacons, "beacons table")


def read_lights(run: RunPaths) -> pd.DataFrame:
    """The run's non-beacon lights; an empty table where the dataset records none."""
    require_dataset(run)
    if not run.lights.exists():
        return typed_frame([], LIGHT_COLUMNS)
    return read_table(run.lights, "lights table")


def read_cameras(run: RunPaths, names: list[str] | None = None) -> dict[str, CameraModel]:
    """Camera models by name from ``cameras/<name>.yaml``."""
    require_dataset(run)
    if names is None:
        names = sorted(p.stem for p in run.cameras_dir.glob("*.yaml"))
    out = {}
    for n in names:
        path = run.camera_file(n)
        _require(path, deckpose_command("render", "CONFIG.yaml", run.root))
        out[n] = read_camera_info(path)
    return out


def read_detections(run: RunPaths, detector: str) -> pd.DataFrame:
    p = run.detections(detector)
    _require(p, deckpose_command("detect", run.root, "--detector", detector))
    return upgrade_legacy_columns(read_table(p, "detections"), "detections")


def read_detect_frames(run: RunPaths, detector: str) -> pd.DataFrame | None:
    """A detector's per-frame outcome (``DETECT_FRAME_COLUMNS``: ``ok``, ``reason``), None where not written."""
    p = run.detect_frames(detector)
    return read_table(p, "detect frames") if p.exists() else None


def read_estimates(run: RunPaths, detector: str, method: str) -> pd.DataFrame:
    p = run.estimates(detector, method)
    _require(p, deckpose_command("estimate", "--run", run.root, "--detector", detector, "--method", method))
    return read_table(p, "estimates")


def read_tracks(run: RunPaths, detector: str, method: str, tracker: str) -> pd.DataFrame:
    """The filtered states of one track (``TRACK_COLUMNS``)."""
    p = run.tracks(detector, method, tracker)
    _require(p, deckpose_command("track", run.root, "--detector", detector, "--estimates", method, "--method", tracker))
    return read_table(p, "tracks")


def read_track_predictions(run: RunPaths, detector: str, method: str, tracker: str) -> pd.DataFrame:
    """The predictions of one track (``TRACK_PREDICTION_COLUMNS``)."""
    p = run.track_predictions(detector, method, tracker)
    _require(p, deckpose_command("track", run.root, "--detector", detector, "--estimates", method, "--method", tracker))
    return read_table(p, "track predictions")


def check_frames_match(frames: pd.DataFrame, other: pd.DataFrame, what: str, command: str) -> None:
    """Raise if ``other`` names frames the dataset does not have (stale or foreign output)."""
    known = set(frames["frame_id"].to_numpy(np.int64))
    ids = set(other["frame_id"].to_numpy(np.int64)) if len(other) else set()
    extra = sorted(ids - known)
    if extra:
        raise InputDataError(
            f"{what} has frame ids the dataset does not have (e.g. {extra[:5]}): it belongs to another "
            f"run or is stale; remake it with: {command}"
        )


def R_world_from_cam(row: pd.Series) -> np.ndarray:
    """The camera rotation stored in a frames-table row (columns ``R_world_from_cam_00..22``)."""
    return np.array([row[c] for c in ROTATION_COLUMN_NAMES], dtype=float).reshape(3, 3)


def R_world_from_cam_all(frames: pd.DataFrame) -> np.ndarray:
    """The camera rotations of every frames-table row, (F, 3, 3) (columns ``R_world_from_cam_00..22``)."""
    return frames[list(ROTATION_COLUMN_NAMES)].to_numpy(float).reshape(-1, 3, 3)


def true_attitudes_rad(frames: pd.DataFrame) -> np.ndarray:
    """The true deck roll, pitch and yaw (ZYX) of every frames-table row, (F, 3), radians."""
    return np.radians(frames[["roll_deg", "pitch_deg", "yaw_deg"]].to_numpy(float))


def frame_truth_row(frame_id: int, image: str, camera: str, stamp_ns: int, t_s: float, camera_height_m: float,
                    ship: ShipPose, camera_pose: CameraPose, lighting: str, seed: int,
                    n_visible: int) -> dict[str, Any]:
    """A ``frames.parquet`` row (:data:`~deckpose.table_schemas.FRAME_COLUMNS`): the one rule
    that the render stage and the synthetic dataset writer both use.

    The deck attitude goes in degrees (ZYX, and the thesis's convention), the camera's
    rotation as its nine ``R_world_from_cam_ij`` entries and its position in metres.
    """
    roll, pitch, yaw = (math.degrees(a) for a in (ship.roll_rad, ship.pitch_rad, ship.yaw_rad))
    tr, tp, ty = (math.degrees(float(a)) for a in ship.thesis_angles_rad())
    row: dict[str, Any] = {
        "frame_id": frame_id, "image": image, "camera": camera, "stamp_ns": stamp_ns, "t_s": t_s,
        "camera_height_m": camera_height_m, "roll_deg": roll, "pitch_deg": pitch, "yaw_deg": yaw,
        "heave_m": ship.heave_m, "surge_m": ship.surge_m, "sway_m": ship.sway_m,
        "thesis_roll_deg": tr, "thesis_pitch_deg": tp, "thesis_yaw_deg": ty, "lighting": lighting,
        "seed": seed, "n_visible": n_visible,
    }
    R = np.asarray(camera_pose.R_world_from_cam, float)
    row.update({c: float(v) for c, v in zip(ROTATION_COLUMN_NAMES, R.ravel())})
    row["cam_x_m"], row["cam_y_m"], row["cam_z_m"] = (float(x) for x in camera_pose.position_world_m)
    return row


def frame_poses(row: pd.Series) -> tuple[ShipPose, CameraPose]:
    """The ship pose (``T_world_from_deck``) and camera pose (``T_world_from_cam``) of a frames-table row."""
    ship = ShipPose(math.radians(row["roll_deg"]), math.radians(row["pitch_deg"]), math.radians(row["yaw_deg"]),
                    row["heave_m"], row["surge_m"], row["sway_m"])
    camera = CameraPose(R_world_from_cam(row), np.array([row["cam_x_m"], row["cam_y_m"], row["cam_z_m"]]))
    return ship, camera


def run_paths(root: str | os.PathLike[str]) -> RunPaths:
    return RunPaths(Path(root))
