"""What each column of the run folder's tables means: name, type, unit, description.

One :class:`Column` per column, one tuple per table kind (the ``kind`` that
:func:`deckpose.tables.write_table` records). The estimates table's columns are in
:mod:`deckpose.estimates_schema`; those of the dataset and detection tables are here.
:func:`deckpose.tables.write_table` puts each known column's unit and description in a
Parquet file's metadata, so a file explains itself; the estimates table is also held to
its columns, order and types (the same for every method, so a run's estimates read
together by glob).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import pandas as pd

__all__ = ["BEACON_COLUMNS", "DETECTION_COLUMNS", "DETECT_FRAME_COLUMNS", "FRAME_COLUMNS", "HOT_PIXEL_COLUMNS",
           "Column", "Dtype", "column", "pandas_dtype"]

#: A column's type: its Arrow/Parquet type (``int64``, ``double``, ``bool``, ``string``).
Dtype = Literal["int64", "float64", "bool", "string"]


@dataclass(frozen=True)
class Column:
    """One documented column.

    Attributes
    ----------
    name : str
        The column's name (its unit suffix, if any, agrees with ``unit``).
    dtype : {"int64", "float64", "bool", "string"}
        Its Arrow/Parquet type (polars ``Int64``/``Float64``/``Boolean``/``String``,
        DuckDB ``BIGINT``/``DOUBLE``/``BOOLEAN``/``VARCHAR``).
    unit : str
        Unit of its values (``deg``, ``m``, ``px^2``, ``rad m``); empty for counts,
        ids, flags, ratios and names.
    description : str
        One line: what the value is, and where it is null.
    nullable : bool
        May be null. Null float values read as NaN in pandas; nullable integer and
        boolean columns read as pandas ``Int64`` and ``boolean``.
    extra : str
        Estimates only: the :attr:`~deckpose.records.PoseEstimate.extras` key the
        column holds (empty for the record's own fields).
    """

    name: str
    dtype: Dtype
    unit: str
    description: str
    nullable: bool = True
    extra: str = ""


def column(name: str, dtype: Dtype, unit: str, description: str, *, nullable: bool = True,
           extra: str = "") -> Column:
    """A :class:`Column` (a short spelling for the schema tables)."""
    return Column(name, dtype, unit, description, nullable, extra)


def pandas_dtype(col: Column) -> Literal["Int64", "int64", "boolean", "bool", "object", "float64"]:
    """The pandas dtype that holds ``col`` (``Int64``/``boolean`` where integers or flags may be null)."""
    if col.dtype == "int64":
        return "Int64" if col.nullable else "int64"
    if col.dtype == "bool":
        return "boolean" if col.nullable else "bool"
    return "object" if col.dtype == "string" else "float64"


def typed_frame(rows: list[dict[str, object]], columns: tuple[Column, ...]) -> pd.DataFrame:
    """``rows`` as a table with exactly ``columns``, each of its schema's pandas dtype (empty allowed)."""
    df = pd.DataFrame(rows, columns=[c.name for c in columns])
    return df.astype({c.name: pandas_dtype(c) for c in columns})


_C = column
_ROTATION = tuple(
    _C(f"r{i}{j}", "float64", "", f"R_world_from_cam[{i}, {j}]: the camera's attitude, row {i} column {j} "
       "(camera axes OpenCV: x right, y down, z along the optical axis)", nullable=False)
    for i in range(3) for j in range(3))

#: ``frames.parquet``: one row per rendered frame, the ground truth of its scene.
FRAME_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id, unique in the run", nullable=False),
    _C("image", "string", "", "the frame's image, relative to the run folder", nullable=False),
    _C("camera", "string", "", "camera name (cameras/<camera>.yaml)", nullable=False),
    _C("stamp_ns", "int64", "ns", "capture time", nullable=False),
    _C("t_s", "float64", "s", "time in the sea-state motion series", nullable=False),
    _C("camera_height_m", "float64", "m", "nominal camera height of the frame's cell", nullable=False),
    _C("roll_rad", "float64", "rad", "true deck roll (ZYX)", nullable=False),
    _C("pitch_rad", "float64", "rad", "true deck pitch (ZYX)", nullable=False),
    _C("yaw_rad", "float64", "rad", "true deck yaw (ZYX)", nullable=False),
    _C("heave_m", "float64", "m", "true deck-centre displacement along world z (up)", nullable=False),
    _C("surge_m", "float64", "m", "true deck-centre displacement along world x", nullable=False),
    _C("sway_m", "float64", "m", "true deck-centre displacement along world y", nullable=False),
    _C("thesis_roll_deg", "float64", "deg", "true roll in the thesis's convention (R = Rx Ry Rz)", nullable=False),
    _C("thesis_pitch_deg", "float64", "deg", "true pitch in the thesis's convention", nullable=False),
    _C("thesis_yaw_deg", "float64", "deg", "true yaw in the thesis's convention", nullable=False),
    _C("lighting", "string", "", "lighting preset (night, day; synthetic-analytic for analytic spots)",
       nullable=False),
    _C("seed", "int64", "", "the frame's noise seed", nullable=False),
    _C("n_visible", "int64", "", "beacons in the image and facing the camera", nullable=False),
    *_ROTATION,
    _C("cam_x_m", "float64", "m", "camera position, world x", nullable=False),
    _C("cam_y_m", "float64", "m", "camera position, world y", nullable=False),
    _C("cam_z_m", "float64", "m", "camera position, world z (up)", nullable=False),
    _C("exposure", "float64", "", "exposure the auto-exposure chose (unit of sensor.exposure: 1 = the raster's "
       "white fills the well); the column exists only with sensor.auto_exposure"),
)

#: ``beacons.parquet``: one row per frame x beacon, the true projection and spot model.
BEACON_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("beacon_id", "int64", "", "layout id (ring 0..n-1 from the bow, counter-clockwise; centre n)",
       nullable=False),
    _C("u_px", "float64", "px", "true centre in the distorted image, column (pixel centres at integers)",
       nullable=False),
    _C("v_px", "float64", "px", "true centre in the distorted image, row", nullable=False),
    _C("visible", "bool", "", "in the image and facing the camera", nullable=False),
    _C("in_image", "bool", "", "in front of the camera and inside the image", nullable=False),
    _C("facing", "bool", "", "the beacon's lit side faces the camera", nullable=False),
    _C("apparent_radius_px", "float64", "px", "the beacon's radius in the image"),
    _C("spot_sigma_px", "float64", "px", "Gaussian-equivalent sigma of the spot's core (null: no spot)"),
    _C("spot_flux_e", "float64", "e-", "electrons in the spot's core, summed over channels"),
    _C("spot_background_e", "float64", "e-",
       "mean background electrons per pixel within 2 sigma of the centre, summed over channels"),
    _C("spot_peak_e", "float64", "e-", "expected electrons of the brightest pixel in the brightest channel"),
    _C("unit_factor", "float64", "", "the beacon unit's intensity factor (LED tolerance x bow intensity; 1 = nominal)"),
    _C("occluded_fraction", "float64", "", "fraction of the spot's light hidden by an occluder (0: none; 1: hidden)"),
    _C("light_u_px", "float64", "px", "centroid of the beacon's light in the image, column (differs from u_px "
       "where an occluder cuts the spot or a vibration path moves it; null: no light)"),
    _C("light_v_px", "float64", "px", "centroid of the beacon's light in the image, row"),
    _C("global_u_px", "float64", "px", "true centre at the frame time (global shutter), column; u_px is "
       "the beacon at its own row's time when a rolling shutter is on, else the same"),
    _C("global_v_px", "float64", "px", "true centre at the frame time (global shutter), row"),
    _C("spot_crb_px", "float64", "px", "per-axis centroid Cramér-Rao bound computed numerically from the PSF "
       "drawn (optics on; null: off, the benchmark's Gaussian bound applies)"),
    _C("defocus_px", "float64", "px", "thin-lens blur-circle diameter at the beacon's depth (optics; null: off)"),
    _C("field_blur_sigma_px", "float64", "px", "field-dependent blur sigma at the beacon (optics; null: off)"),
    _C("vignetting", "float64", "", "cos(theta)^n vignetting gain at the beacon, in spot_flux_e (optics; null: off)"),
    _C("u_r_px", "float64", "px", "true centre of the red channel under lateral chromatic aberration, column "
       "(u_px, v_px are the green, geometric centre; optics; null: off)"),
    _C("v_r_px", "float64", "px", "true centre of the red channel, row"),
    _C("u_b_px", "float64", "px", "true centre of the blue channel under lateral chromatic aberration, column"),
    _C("v_b_px", "float64", "px", "true centre of the blue channel, row"),
    _C("spot_flux_r_e", "float64", "e-", "electrons of spot_flux_e that the red light gives (the channel sum's "
       "share of the red channel; with u_r_px, v_r_px it places the light a channel-sum detector sees; optics; "
       "null: off)"),
    _C("spot_flux_g_e", "float64", "e-", "electrons of spot_flux_e that the green light gives (optics; null: off)"),
    _C("spot_flux_b_e", "float64", "e-", "electrons of spot_flux_e that the blue light gives (optics; null: off)"),
)

#: ``lights.parquet``: one row per frame x non-beacon light (navigation lights, floodlights, glints).
LIGHT_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("light_id", "int64", "", "the light's index in the frame", nullable=False),
    _C("kind", "string", "", "port, starboard, masthead, stern, floodlight or glint", nullable=False),
    _C("u_px", "float64", "px", "projected centre at mid-exposure, distorted image column (null: behind the camera)"),
    _C("v_px", "float64", "px", "projected centre at mid-exposure, distorted image row"),
    _C("in_image", "bool", "", "in front of the camera and inside the image", nullable=False),
    _C("flux_e", "float64", "e-", "electrons in the light's core, summed over channels (0: not drawn)"),
)

#: ``cameras/<name>_hot_pixels.parquet``: one row per hot pixel of a camera (the same in every frame).
HOT_PIXEL_COLUMNS: tuple[Column, ...] = (
    _C("u_px", "int64", "px", "the hot pixel's column", nullable=False),
    _C("v_px", "int64", "px", "the hot pixel's row", nullable=False),
    _C("excess_e", "float64", "e-", "its dark signal above the DSNU, electrons per frame", nullable=False),
)

#: ``detections/<detector>.parquet``: one row per frame x detection.
DETECTION_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("beacon_id", "int64", "", "layout id the detection was identified as; -1 = unassigned", nullable=False),
    _C("u_px", "float64", "px", "detected centre, distorted image column", nullable=False),
    _C("v_px", "float64", "px", "detected centre, distorted image row", nullable=False),
    _C("cov_uu", "float64", "px^2", "the centre's covariance, u-u entry", nullable=False),
    _C("cov_uv", "float64", "px^2", "the centre's covariance, u-v entry", nullable=False),
    _C("cov_vv", "float64", "px^2", "the centre's covariance, v-v entry", nullable=False),
    _C("flux", "float64", "DN", "background-subtracted flux of the spot (digital numbers, summed over pixels)"),
    _C("size_px", "float64", "px", "Gaussian-equivalent sigma of the spot"),
    _C("score", "float64", "",
       "detection confidence: flux over the background noise in the spot's area (signal-to-noise; larger = better)"),
    _C("detector", "string", "", "the detector's name", nullable=False),
)

#: ``detections/<detector>.frames.parquet``: one row per frame, the detector's outcome.
DETECT_FRAME_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("ok", "bool", "", "detection and identification both succeeded", nullable=False),
    _C("reason", "string", "", "why not (empty when ok)", nullable=False),
    _C("n_detections", "int64", "", "detections in the frame", nullable=False),
    _C("seconds", "float64", "s", "wall time of detection and identification"),
    _C("cpu_seconds", "float64", "s", "CPU time of the same work (this thread)"),
    _C("n_identified", "int64", "", "detections with a beacon id", nullable=False),
    _C("camera", "string", "", "camera name"),
    _C("stamp_ns", "int64", "ns", "capture time"),
    _C("image", "string", "", "the frame's image, relative to the run folder"),
)
