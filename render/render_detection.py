"""Detection at render time: each frame detected in the worker that rendered it, from memory.

A run that needs detections (a resolution sweep, a detector benchmark) need not write
every frame and decode it again: ``deckpose render CONFIG OUT --detect cog,gauss`` runs
the detectors on each frame as it is rendered, in the worker that rendered it (a local
process or a Dask worker), on the same array the image file would hold (PNG and the
Zstandard store are lossless, so the tables equal those ``deckpose detect`` writes from
the files, but for the timing columns). With ``--no-images`` the frames are not kept at
all: the dataset holds its previews, tables and detections, and the choice is recorded
in the manifest (``images_kept``, ``detect_at_render``) and in each detections run file
(``detected_at_render``).

The per-frame results travel in the frame's part file (``.parts/<frame_id>.json``,
``"detections"``), so an interrupted run resumes as before; the tables are written
into the run layout (``detections/<detector>.parquet``) when the dataset is complete.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from deckpose.detect import registry
from deckpose.detect.identify import IdentifyOptions
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.run import assemble_tables, frame_results, write_run
from deckpose.detect.sources import declared_gain, open_dataset
from deckpose.detect.tables import DETECTION_COLUMNS

from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.records import Frame

__all__ = ["RenderDetection", "detect_rendered", "manifest_fields", "resolve_detection",
           "write_rendered_detections"]


@dataclass(frozen=True)
class RenderDetection:
    """What to detect at render time, and whether the frames are kept.

    Attributes
    ----------
    detectors : tuple of str
        Registered detector names (may be empty: then only ``keep_images`` matters).
    options : DetectorOptions
        With ``gain_dn_per_e = None``, the sensor's gain is filled in by the render stage
        (as ``deckpose detect`` takes it from the manifest).
    identify_options : IdentifyOptions
    keep_images : bool
        Write each frame's image file (``False``: previews and tables only).
    """

    detectors: tuple[str, ...] = ()
    options: DetectorOptions = DetectorOptions()
    identify_options: IdentifyOptions = IdentifyOptions()
    keep_images: bool = True



def manifest_fields(job: RenderDetection | None) -> dict[str, Any]:
    """The manifest's record of the choice: ``images_kept`` and ``detect_at_render`` (compared on
    ``--resume``); empty without ``job``, so the manifests of earlier versions are unchanged."""
    if job is None:
        return {}
    return {"images_kept": job.keep_images,
            "detect_at_render": {"detectors": list(job.detectors), "options": dataclasses.asdict(job.options),
                                 "identify_options": dataclasses.asdict(job.identify_options)}}


def resolve_detection(job: RenderDetection, sensor_block: dict[str, Any]) -> RenderDetection:
    """``job`` checked (known detectors; ``keep_images=False`` needs a detector) with its gain set.

    ``options.gain_dn_per_e = None`` takes the gain the dataset's manifest will declare
    (``sensor_block``, :func:`deckpose.detect.sources.declared_gain`), as ``deckpose detect``
    does. Raises :class:`~deckpose.errors.ConfigError`.
    """
    if not job.keep_images and not job.detectors:
        raise ConfigError("--no-images keeps no frame, so no later stage could detect in them: "
                          "give --detect DETECTOR[,...] with it")
    for name in job.detectors:
        registry.get(name)  # an unknown name fails before anything is written
    if job.options.gain_dn_per_e is None:
        gain = declared_gain({"sensor": sensor_block})
        job = dataclasses.replace(job, options=dataclasses.replace(job.options, gain_dn_per_e=gain))
    return job


def detect_rendered(frame: Frame, camera_name: str, image_relpath: str, layout: DeckLayout,
                    job: RenderDetection) -> dict[str, dict[str, Any]]:
    """Detect one frame in memory with every detector of ``job``: the part file's ``detections``.

    Returns, per detector, ``{"rows": {column: list}, "frame": frame row}`` (JSON-ready;
    floats round-trip exactly through JSON).
    """
    results = frame_results(frame, frame.frame_id, camera_name, frame.stamp_ns, image_relpath,
                            job.detectors, layout, job.options, job.identify_options)
    return {det: {"rows": rows.to_dict("list"), "frame": frame_row}
            for det, (rows, frame_row) in zip(job.detectors, results)}


def _rows_frame(rows: dict[str, list[Any]]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=list(DETECTION_COLUMNS))
    for c in ("frame_id", "beacon_id"):
        df[c] = df[c].astype("int64")
    for c in DETECTION_COLUMNS:
        if c not in ("frame_id", "beacon_id", "detector"):
            df[c] = df[c].astype("float64")
    df["detector"] = df["detector"].astype(str)
    return df


def write_rendered_detections(out: Path, parts: list[dict[str, Any]], job: RenderDetection) -> list[Path]:
    """Write each detector's tables from the frames' part documents (in frame order).

    Called once the dataset's tables and manifest are written (the run layout's detect
    files name the dataset's cameras). Returns the detections tables written.
    """
    if not job.detectors:
        return []
    frameset = open_dataset(out)
    written = []
    for det in job.detectors:
        entries = [p["detections"][det] for p in parts]
        dets, frames = assemble_tables(det, [_rows_frame(e["rows"]) for e in entries],
                                       [e["frame"] for e in entries])
        written.append(write_run(None, frameset, det, dets, frames, job.options, job.identify_options,
                                 detected_at_render=True))
    return written
