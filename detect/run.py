"""Batch detection over a :class:`~deckpose.detect.sources.FrameSet`, written to an output folder.

Outputs (see :func:`write_run`) go either into the dataset's run layout
(``DATASET/detections/<detector>.parquet`` + ``<detector>.frames.parquet``, read
by ``deckpose estimate --run``) or into a self-contained folder
(``detections.parquet``, ``detect_frames.parquet``, ``cameras/<name>.yaml``,
``detect_run.json``), with a metadata file of format ``deckpose-detections/1``
(detector, options, layout, source, package versions). A bad frame is a row
with ``ok = False`` and a reason; the batch goes on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import platform
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from deckpose.detect.frame_detection import FrameDetections, detect_frame
from deckpose.detect.identify import IdentifyOptions
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.sources import FrameSet, FrameSource, load_frame
from deckpose.detect.tables import detection_rows, write_tables

from deckpose.atomic_io import atomic_open
from deckpose.camera import CameraModel
from deckpose.camera_info import write_camera_info
from deckpose.counted import counted
from deckpose.errors import ConfigError, InputDataError
from deckpose.layout import DeckLayout, layout_to_dict
from deckpose.records import Frame
from deckpose.run_folder import (
    DETECT_RECORD,
    DETECTIONS_FORMAT,
    FOLDER_ESTIMATES,
    RunPaths,
    detections_folder_record,
)
from deckpose.shell_command import deckpose_command

log = logging.getLogger(__name__)


__all__ = ["DetectRunResult", "assemble_tables", "detect_frames", "detect_frames_with", "detect_run",
           "frame_results", "write_run"]


@dataclass(frozen=True)
class DetectRunResult:
    """What the detect stage wrote.

    Attributes
    ----------
    path : Path
        The detections table.
    detections : pandas.DataFrame
        One row per detection.
    frames : pandas.DataFrame
        One row per frame with ``ok`` and ``reason``.
    """

    path: Path
    detections: pd.DataFrame
    frames: pd.DataFrame

    @property
    def n_ok(self) -> int:
        return int(self.frames["ok"].sum()) if len(self.frames) else 0

    def summary(self) -> str:
        """One line: frames, how many ok, detections, where they went."""
        return f"{counted(len(self.frames), 'frame')}, {self.n_ok} ok, {counted(len(self.detections), 'detection')} -> {self.path}"


def detect_run(
    source: str | os.PathLike[str],
    detector: str,
    *,
    options: DetectorOptions = DetectorOptions(),
    identify_options: IdentifyOptions = IdentifyOptions(),
    out_dir: str | os.PathLike[str] | None = None,
    camera_file: str | os.PathLike[str] | None = None,
    layout_file: str | os.PathLike[str] | None = None,
    progress: bool = False,
    workers: int = 1,
) -> DetectRunResult:
    """The detect stage: detect and identify in every frame of a dataset or an image folder.

    The CLI (``deckpose detect``) and the pipeline both call this.

    Parameters
    ----------
    source : path
        A deckpose dataset folder, or a folder of images (then ``camera_file`` and
        ``out_dir`` are required).
    detector : str
        A registered detector.
    options : DetectorOptions, keyword-only
        With ``gain_dn_per_e = None`` the gain a dataset's manifest declares is used.
    identify_options : IdentifyOptions, keyword-only
    out_dir : path, optional, keyword-only
        A self-contained output folder (default for a dataset: its run layout).
    camera_file, layout_file : path, optional, keyword-only
        ROS camera_info and layout YAML of an image folder.
    progress : bool, keyword-only
    workers : int, keyword-only
        Worker processes that decode and detect frames side by side; the tables are the
        same for any number, but for the timing columns.

    Returns
    -------
    DetectRunResult

    Raises
    ------
    ConfigError
        An unknown detector, or an image folder without a camera file or output folder.
    """
    from deckpose.detect import registry
    from deckpose.detect.sources import (
        declared_gain,
        is_dataset,
        open_dataset,
        open_image_folder,
        require_images,
    )

    from deckpose.output_folder import claim_output

    registry.get(detector)  # fail early on an unknown name
    if not Path(source).exists():
        raise InputDataError(f"{source} does not exist; give a dataset folder (deckpose render) or a folder of "
                             "images with --camera CAMERA.yaml")
    if is_dataset(source):
        frameset = open_dataset(source)
        def fix() -> str:
            at_render = frameset.manifest.get("detect_at_render", {}).get("detectors", [])
            if detector in at_render:
                return (f"its {detector} detections were made at render time "
                        f"({RunPaths(frameset.root).detections(detector)}): estimate from them "
                        f"({deckpose_command('estimate', '--run', source, '--detector', detector)})")
            return (f"its detections were made at render time ({', '.join(at_render) or 'none'}); for "
                    f"{detector}, render it again with --detect {detector} (or without --no-images)")

        require_images(frameset, fix)
    else:
        record = detections_folder_record(source)
        if record is not None:
            raise InputDataError(
                f"{source} is a detections folder ('deckpose detect -o' wrote it) and holds no images; "
                f"detect the frames it came from: {record.get('source', 'their dataset or image folder')}")
        if not camera_file:
            raise ConfigError(
                f"{source} is not a deckpose dataset (no manifest.json); for a folder of "
                "images pass --camera CAMERA.yaml and -o DIR (and optionally --layout)"
            )
        if not out_dir:
            raise ConfigError("a folder of images needs an output folder: add -o DIR")
        frameset = open_image_folder(source, camera_file, layout_file)
    if options.gain_dn_per_e is None:
        options = dataclasses.replace(options, gain_dn_per_e=declared_gain(frameset.manifest))
    if out_dir and is_dataset(out_dir):
        raise ConfigError(
            f"-o {out_dir} is a rendered dataset; -o writes a detections folder of its own (its tables at "
            "the top level). To add the detections to a dataset, detect it without -o "
            f"({deckpose_command('detect', out_dir, '--detector', detector)}); or give -o a new folder")
    # before any frame is detected: the output folder can be written and is no other job's
    # (a dataset's own folder when detections go into it: a render still writing it is refused)
    claim_output(Path(out_dir) if out_dir else frameset.root, what="detect")
    dets, frames = detect_frames(frameset, detector, options=options, identify_options=identify_options,
                                 progress=progress, workers=workers)
    path = write_run(out_dir, frameset, detector, dets, frames, options, identify_options)
    return DetectRunResult(path, dets, frames)


def detect_frames(
    frameset: FrameSet,
    detector: str,
    *,
    options: DetectorOptions = DetectorOptions(),
    identify_options: IdentifyOptions = IdentifyOptions(),
    progress: bool = False,
    workers: int = 1,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Detect in every frame (``workers`` processes); returns ``(detections table, frames table)``."""
    return detect_frames_with(
        frameset,
        [detector],
        options=options,
        identify_options=identify_options,
        progress=progress,
        workers=workers,
    )[detector]


def detect_frames_with(
    frameset: FrameSet,
    detectors: list[str],
    *,
    options: DetectorOptions = DetectorOptions(),
    identify_options: IdentifyOptions = IdentifyOptions(),
    progress: bool = False,
    workers: int = 1,
) -> dict[str, tuple[pd.DataFrame, pd.DataFrame]]:
    """Run several detectors on every frame, decoding each image once.

    Parameters
    ----------
    frameset : FrameSet
    detectors : list of str
    options : DetectorOptions, keyword-only
    identify_options : IdentifyOptions, keyword-only
    progress : bool, keyword-only
    workers : int, keyword-only
        Worker processes that decode and detect frames side by side (0 or 1 = in this
        process, as ``render``'s 0). The tables are the same for any number, but for the
        timing columns.

    Returns
    -------
    dict
        Detector name to ``(detections table, frames table)``, as :func:`detect_frames`.
    """
    from tqdm import tqdm

    if workers < 0:
        raise ConfigError(f"workers must be >= 0 (0 or 1: detect in this process), got {workers}")
    det_parts: dict[str, list[pd.DataFrame]] = {d: [] for d in detectors}
    frame_rows: dict[str, list[dict[str, Any]]] = {d: [] for d in detectors}
    desc = f"detect {','.join(detectors)}"
    job = _DetectJob(frameset.cameras, frameset.layout, frameset.root, tuple(detectors), options,
                     identify_options)
    # closing: on an interrupt in this loop the workers are stopped now, not when collected
    with (tqdm(total=len(frameset.sources), desc=desc, unit="frame", disable=None if progress else True) as bar,
          contextlib.closing(_detect_chunks(job, frameset.sources, workers)) as chunks):
        for chunk in chunks:
            for per_frame in chunk:
                for detector, (rows, frame_row) in zip(detectors, per_frame):
                    det_parts[detector].append(rows)
                    frame_rows[detector].append(frame_row)
            bar.update(len(chunk))
    return {d: assemble_tables(d, det_parts[d], frame_rows[d]) for d in detectors}


def assemble_tables(detector: str, detection_parts: list[pd.DataFrame],
                    frame_rows: list[dict[str, Any]]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One detector's ``(detections table, frames table)`` from its per-frame rows, in frame order."""
    parts = [d for d in detection_parts if len(d)]  # (concatenating empties is deprecated)
    dets = (
        pd.concat(parts, ignore_index=True)
        if parts
        else detection_rows(FrameDetections.failed(-1, detector, "none"))
    )
    return dets, pd.DataFrame(frame_rows)


@dataclass(frozen=True)
class _DetectJob:
    """What a worker needs to detect frames (sent once per chunk; small)."""

    cameras: dict[str, CameraModel]
    layout: DeckLayout
    root: Path
    detectors: tuple[str, ...]
    options: DetectorOptions
    identify_options: IdentifyOptions
    plugins: tuple[str, ...] = ()


#: Frames a worker detects per task: enough to hide the hand-over, few enough to balance.
CHUNK_FRAMES = 4

_FrameResult = list[tuple[pd.DataFrame, dict[str, Any]]]

#: The plugins this (worker) process has imported for :func:`_detect_chunk`.
_IMPORTED_PLUGINS: set[str] = set()


def _detect_chunks(job: _DetectJob, sources: tuple[FrameSource, ...], workers: int
                   ) -> Generator[list[_FrameResult], None, None]:
    """Each chunk's per-frame results, in input order, from this process or ``workers`` processes."""
    chunks = [sources[i:i + CHUNK_FRAMES] for i in range(0, len(sources), CHUNK_FRAMES)]
    if workers <= 1 or len(chunks) <= 1:
        for c in chunks:
            yield _detect_chunk(job, c)
        return
    from deckpose.detect import registry

    from deckpose.worker_pool import worker_pool

    job = dataclasses.replace(job, plugins=registry.plugins_for(job.detectors))
    # workers ignore Ctrl-C; on it (or any error) the chunks not started are cancelled and the
    # workers stopped within seconds (deckpose.worker_pool)
    with worker_pool(min(workers, len(chunks))) as pool:
        yield from pool.map(_detect_chunk, [job] * len(chunks), chunks)


def _detect_chunk(job: _DetectJob, sources: tuple[FrameSource, ...]) -> list[_FrameResult]:
    """Decode and detect each frame of ``sources``: per frame, per detector, its rows and frame row."""
    if job.plugins:
        from deckpose.detect import registry

        for mod in job.plugins:
            if mod not in _IMPORTED_PLUGINS:  # once per worker process
                registry.load_plugin(mod)
                _IMPORTED_PLUGINS.add(mod)
    return [
        frame_results(load_frame(src, job.cameras[src.camera_name]), src.frame_id, src.camera_name,
                      src.stamp_ns, os.path.relpath(src.image_path, job.root), job.detectors,
                      job.layout, job.options, job.identify_options)
        for src in sources
    ]


def frame_results(
    frame: Frame | str,
    frame_id: int,
    camera_name: str,
    stamp_ns: int,
    image_relpath: str,
    detectors: tuple[str, ...],
    layout: DeckLayout,
    options: DetectorOptions,
    identify_options: IdentifyOptions,
) -> _FrameResult:
    """One frame's detections by each detector: its ``detections`` rows and its frame row.

    The detect stage calls this on each decoded frame, and the render stage on each frame
    in memory when it detects at render time (:mod:`deckpose.render.render_detection`),
    so both write the same tables. ``frame`` is the frame, or why it cannot be used (then
    every detector's frame row says so).
    """
    per_frame: _FrameResult = []
    for detector in detectors:
        if isinstance(frame, str):
            fd = FrameDetections.failed(frame_id, detector, frame)
        else:
            fd = detect_frame(frame, detector, layout, options=options, identify_options=identify_options)
        log.debug("frame %d, %s: %s", frame_id, detector, "ok" if fd.ok else f"failed: {fd.reason}")
        per_frame.append((detection_rows(fd), {
            "frame_id": frame_id,
            "ok": fd.ok,
            "reason": fd.reason,
            "n_detections": len(fd.detections),
            "seconds": fd.seconds,
            "cpu_seconds": fd.cpu_seconds,
            "n_identified": int((fd.detections.beacon_ids >= 0).sum()),
            "camera": camera_name,
            "stamp_ns": stamp_ns,
            "image": image_relpath,
        }))
    return per_frame


def write_run(
    out_dir: str | os.PathLike[str] | None,
    frameset: FrameSet,
    detector: str,
    detections: pd.DataFrame,
    frames: pd.DataFrame,
    options: DetectorOptions,
    identify_options: IdentifyOptions,
    *,
    detected_at_render: bool = False,
) -> Path:
    """Write the detection outputs; returns the detections table's path.

    ``detected_at_render`` (recorded in the metadata file) says the frames were detected
    in memory as they were rendered (``deckpose render --detect``), not decoded from disk.

    With ``out_dir``: a self-contained folder ``out_dir/{detections.parquet,
    detect_frames.parquet, detect_run.json, cameras/}``. Without (datasets only):
    into the dataset's run layout, ``DATASET/detections/<detector>.parquet``,
    ``<detector>.frames.parquet`` and ``<detector>.run.json``, where
    ``deckpose estimate --run DATASET --detector <detector>`` reads them.
    """
    if out_dir is None:
        if frameset.kind != "dataset":
            raise ConfigError("a folder of images needs an output folder (--out)")
        run = RunPaths(frameset.root)
        base = run.detections_dir
        det_path, frames_path = run.detections(detector), run.detect_frames(detector)
        meta_path, cam_dir = run.detect_run_record(detector), None
        stale = run.made_from_detections(detector) if det_path.is_file() else []
    else:
        base = Path(out_dir)
        det_path, frames_path = base / "detections.parquet", base / "detect_frames.parquet"
        meta_path, cam_dir = base / DETECT_RECORD, base / "cameras"
        stale = [base / FOLDER_ESTIMATES] if meta_path.is_file() and (base / FOLDER_ESTIMATES).is_file() else []
    for p in stale:  # estimated or tracked from the detections this run replaces: stale
        p.unlink()
    if stale:
        log.warning("removed %s, made from the %s detections this run replaces (deckpose estimate makes "
                    "it again)", ", ".join(str(p) for p in stale), detector)
    write_tables(det_path, frames_path, detections, frames)
    cams = {}
    for name, cam in frameset.cameras.items():
        if cam_dir is not None:
            write_camera_info(cam, cam_dir / f"{name}.yaml")
            cams[name] = f"cameras/{name}.yaml"
        else:
            cams[name] = os.path.relpath(frameset.camera_files[name], base)
    meta: dict[str, Any] = {
        "format": DETECTIONS_FORMAT,
        "detector": detector,
        "detections": det_path.name,
        "frames": frames_path.name,
        "detector_options": dataclasses.asdict(options),
        "identify_options": dataclasses.asdict(identify_options),
        "layout": layout_to_dict(frameset.layout),
        "source": str(frameset.root.resolve()),
        "source_kind": frameset.kind,
        "cameras": cams,
        "n_frames": len(frames),
        "n_frames_ok": int(frames["ok"].sum()) if len(frames) else 0,
        "detected_at_render": detected_at_render,
        "versions": _versions(),
    }
    with atomic_open(meta_path, "w") as fh:
        json.dump(meta, fh, indent=2)
    return det_path


def _versions() -> dict[str, str]:
    import cv2
    import numpy
    import scipy
    import skimage

    from deckpose import __version__

    return {
        "deckpose": __version__,
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "opencv": cv2.__version__,
        "scikit-image": skimage.__version__,  # pyright: ignore[reportAttributeAccessIssue]  # missing from skimage's stub
    }
