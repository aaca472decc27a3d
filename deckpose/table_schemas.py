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

import math
from dataclasses import dataclass
from typing import Literal

import pandas as pd

__all__ = ["BEACON_COLUMNS", "DETECTION_COLUMNS", "DETECT_FRAME_COLUMNS", "FRAME_COLUMNS", "HOT_PIXEL_COLUMNS",
           "LEGACY_COLUMNS", "PAINTED_RING_BOUND_COLUMNS", "PAINTED_RING_COLUMNS", "RING_DETECTION_COLUMNS",
           "ROTATION_COLUMN_NAMES", "TRACK_COLUMNS", "TRACK_PREDICTION_COLUMNS", "Column", "Dtype", "column",
           "pandas_dtype", "rotation_column", "upgrade_legacy_columns"]

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


def rotation_column(i: int, j: int) -> str:
    """The frames-table column of ``R_world_from_cam[i, j]`` (``R_world_from_cam_01``)."""
    return f"R_world_from_cam_{i}{j}"


#: The frames table's nine camera-rotation columns, row-major.
ROTATION_COLUMN_NAMES: tuple[str, ...] = tuple(rotation_column(i, j) for i in range(3) for j in range(3))

_ROTATION = tuple(
    _C(rotation_column(i, j), "float64", "", f"R_world_from_cam[{i}, {j}]: the camera's attitude, row {i} "
       f"column {j} (camera axes OpenCV: x right, y down, z along the optical axis)", nullable=False)
    for i in range(3) for j in range(3))

#: ``frames.parquet``: one row per rendered frame, the ground truth of its scene.
FRAME_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id, unique in the run", nullable=False),
    _C("image", "string", "", "the frame's image, relative to the run folder", nullable=False),
    _C("camera", "string", "", "camera name (cameras/<camera>.yaml)", nullable=False),
    _C("stamp_ns", "int64", "ns", "capture time", nullable=False),
    _C("t_s", "float64", "s", "time in the sea-state motion series", nullable=False),
    _C("camera_height_m", "float64", "m", "nominal camera height of the frame's cell", nullable=False),
    _C("roll_deg", "float64", "deg", "true deck roll (ZYX)", nullable=False),
    _C("pitch_deg", "float64", "deg", "true deck pitch (ZYX)", nullable=False),
    _C("yaw_deg", "float64", "deg", "true deck yaw (ZYX)", nullable=False),
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
    _C("metered_exposure", "float64", "", "exposure this frame's own metering asks for; the auto-exposure "
       "controller sets the frame's exposure from the meterings of the frames before it; the column exists "
       "only with sensor.auto_exposure.time_constant_s > 0 or max_step_stops"),
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
    _C("kind", "string", "", "port, starboard, masthead, stern, floodlight, glint (sea) or deck_glint (wet deck)", nullable=False),
    _C("u_px", "float64", "px", "projected centre at mid-exposure, distorted image column (null: behind the camera)"),
    _C("v_px", "float64", "px", "projected centre at mid-exposure, distorted image row"),
    _C("in_image", "bool", "", "in front of the camera and inside the image", nullable=False),
    _C("flux_e", "float64", "e-", "electrons in the light's core, summed over channels (0: not drawn)"),
)

_CONIC = tuple(_C(f"conic_px_{i}{j}", "float64", "", f"entry ({i}, {j}) of the edge's image conic in undistorted pixels, "
                  "[u, v, 1] C [u, v, 1]^T = 0, unit Frobenius norm, negative inside", nullable=False)
               for i in range(3) for j in range(3))

#: ``painted_ring.parquet``: one row per frame x edge of the painted ring (configs with ``painted_ring``).
PAINTED_RING_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("edge", "string", "", "inner or outer edge circle of the painted line", nullable=False),
    _C("ellipse_u_px", "float64", "px", "centre of the edge's image ellipse, undistorted column (null: not an "
       "ellipse)"),
    _C("ellipse_v_px", "float64", "px", "centre of the edge's image ellipse, undistorted row"),
    _C("semi_major_px", "float64", "px", "semi-major axis of the edge's image ellipse (undistorted image)"),
    _C("semi_minor_px", "float64", "px", "semi-minor axis of the edge's image ellipse (undistorted image)"),
    _C("angle_deg", "float64", "deg", "major axis angle from image +u toward +v (undistorted image)"),
    _C("centre_u_px", "float64", "px", "image of the deck centre, distorted column (not the ellipse's centre)",
       nullable=False),
    _C("centre_v_px", "float64", "px", "image of the deck centre, distorted row", nullable=False),
    _C("bow_u_px", "float64", "px", "image of the ring's mid line at the bow, deck (radius_m, 0), distorted column",
       nullable=False),
    _C("bow_v_px", "float64", "px", "image of the ring's mid line at the bow, distorted row", nullable=False),
    _C("in_image_fraction", "float64", "", "fraction of the edge circle inside the image (720 points)",
       nullable=False),
    _C("distorted", "bool", "", "the camera has distortion: the conic holds in the undistorted image only",
       nullable=False),
    *_CONIC,
)

#: ``detections/ring-edges.parquet``: one row per frame, the painted ring found in it.
RING_DETECTION_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("ok", "bool", "", "both edges fitted and the bow mark found", nullable=False),
    _C("reason", "string", "", "why not (empty when ok)", nullable=False),
    *(c for edge in ("inner", "outer") for c in (
        _C(f"{edge}_u_px", "float64", "px", f"centre of the fitted {edge} edge ellipse, undistorted column"),
        _C(f"{edge}_v_px", "float64", "px", f"centre of the fitted {edge} edge ellipse, undistorted row"),
        _C(f"{edge}_semi_major_px", "float64", "px", f"semi-major axis of the fitted {edge} edge ellipse"),
        _C(f"{edge}_semi_minor_px", "float64", "px", f"semi-minor axis of the fitted {edge} edge ellipse"),
        _C(f"{edge}_angle_deg", "float64", "deg", f"major axis angle of the fitted {edge} edge ellipse"),
        _C(f"{edge}_n_points", "int64", "", f"sub-pixel {edge} edge points kept (inliers of the ellipse fit)",
           nullable=False),
        _C(f"{edge}_rms_px", "float64", "px", f"RMS distance of the {edge} edge points from their fitted ellipse"),
    )),
    _C("bow_u_px", "float64", "px", "the bow mark's image on the ring's mid line (middle of its two ends), distorted column"),
    _C("bow_v_px", "float64", "px", "the bow mark's image on the ring's mid line, distorted row"),
    _C("bow_sigma_px", "float64", "px", "standard deviation of the bow mark's position along the ring"),
    _C("edge_contrast_dn", "float64", "DN", "median step across the edges (paint minus deck, channel sum)"),
    _C("noise_dn", "float64", "DN", "robust noise of the channel-sum image on the deck beside the inner edge "
       "(residuals of the edge model fit)"),
    _C("blur_px", "float64", "px", "Gaussian blur sigma of the edges beyond the pixel's own square (model fit)"),
    _C("edge_crb_px", "float64", "px", "median Cramér-Rao bound of an edge point (one image row or column "
       "across the edge; deck level and slope, paint level unknown)"),
    _C("seconds", "float64", "s", "CPU time of the ring detection (this thread)"),
)

#: ``estimates/ring-edges--painted-ring.bound.parquet``: one row per frame, the painted ring's bound.
PAINTED_RING_BOUND_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    *(_C(f"bound_{p}_{u}", "float64", u, f"{p}: bound's standard deviation, each edge point at its own "
         "Cramér-Rao bound (model fit of its pixels, white noise, the deck's level and slope and the paint's level "
         "unknown), same Jacobian as the estimate (null: no estimate)")
      for p, u in (("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("surge", "m"), ("sway", "m"),
                   ("height", "m"))),
    *(_C(f"bound_known_levels_{p}_{u}", "float64", u, f"{p}: the same bound were the deck's and paint's levels "
         "beside each edge point known (white noise, position only; null: no estimate)")
      for p, u in (("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("height", "m"))),
    *(_C(f"bound_correlated_{p}_{u}", "float64", u, f"{p}: correlated-noise bound's standard deviation: each edge "
         "point at its own Cramér-Rao bound, correlated along its edge as the residuals are (Newey-West sandwich; "
         "null: no estimate)")
      for p, u in (("roll", "deg"), ("pitch", "deg"), ("yaw", "deg"), ("surge", "m"), ("sway", "m"),
                   ("height", "m"))),
    _C("used_disc", "bool", "", "whether the centre disc's edge was in the fit"),
    _C("disc_check_chi2", "float64", "", "Hausman chi-square of the pose with the centre disc against the ring "
       "alone (null: no disc detected); above the 1e-3 tail the disc is left out"),
    _C("chi2_per_point", "float64", "", "chi-square of the optimum over its residuals (whitened by the measured "
       "edge noise)"),
    _C("seconds", "float64", "s", "CPU time of the estimation (this thread)"),
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
    _C("flux_dn", "float64", "DN", "background-subtracted flux of the spot (digital numbers, summed over pixels)"),
    _C("size_px", "float64", "px", "Gaussian-equivalent sigma of the spot"),
    _C("snr", "float64", "",
       "signal-to-noise ratio: the flux over the background noise in the spot's area (the detection's confidence)"),
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


#: Columns renamed by table format ``deckpose-table/3``, by table kind: old name -> (new name,
#: factor from the old unit to the new). Tables written before it are read with the new names
#: (:func:`upgrade_legacy_columns`), so runs made by an older deckpose stay usable.
LEGACY_COLUMNS: dict[str, dict[str, tuple[str, float]]] = {
    "frames": {
        "roll_rad": ("roll_deg", 180.0 / math.pi), "pitch_rad": ("pitch_deg", 180.0 / math.pi),
        "yaw_rad": ("yaw_deg", 180.0 / math.pi),
        **{f"r{i}{j}": (rotation_column(i, j), 1.0) for i in range(3) for j in range(3)},
    },
    "detections": {"flux": ("flux_dn", 1.0), "score": ("snr", 1.0)},
}


def upgrade_legacy_columns(df: pd.DataFrame, kind: str) -> pd.DataFrame:
    """``df`` with the columns :data:`LEGACY_COLUMNS` renamed for ``kind``, in the new units.

    A column is renamed only where the new name is absent; ``df`` itself is not changed.
    """
    renames = {old: new for old, (new, _f) in LEGACY_COLUMNS.get(kind, {}).items()
               if old in df.columns and new not in df.columns}
    if not renames:
        return df
    out = df.rename(columns=renames)
    for old, new in renames.items():
        factor = LEGACY_COLUMNS[kind][old][1]
        if factor != 1.0:
            out[new] = out[new].astype(float) * factor
    return out


_TRACK_POSE = (("roll_deg", "deg", "roll"), ("pitch_deg", "deg", "pitch"), ("yaw_deg", "deg", "yaw"),
               ("surge_m", "m", "surge (deck centre minus camera, world x)"),
               ("sway_m", "m", "sway (deck centre minus camera, world y)"),
               ("height_m", "m", "height (camera above the deck centre, world z)"))
_TRACK_PARAMS = ("roll_rad", "pitch_rad", "yaw_rad", "surge_m", "sway_m", "height_m")  # POSE_PARAMS' order


def _cov_unit(a: str, b: str) -> str:
    ua, ub = a.rsplit("_", 1)[1], b.rsplit("_", 1)[1]
    return f"{ua}^2" if ua == ub else f"{ua} {ub}"


#: ``tracks/<detector>--<method>--<tracker>.parquet``: one row per frame, the filtered state.
TRACK_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "frame id", nullable=False),
    _C("sequence", "int64", "", "the time sequence the frame belongs to (camera x height x lighting of the "
       "render plan); the filter starts afresh on each", nullable=False),
    _C("stamp_ns", "int64", "ns", "capture time (the log's time base)", nullable=False),
    _C("status", "string", "", "what the filter did with the frame's estimate: updated, gated (rejected as an "
       "outlier by the Mahalanobis gate) or skipped (not ok or no covariance: prediction only)", nullable=False),
    _C("nis", "float64", "", "normalised innovation squared of the frame's estimate (chi-square, 6 dof, where "
       "the model holds); null where skipped"),
    *(_C(name, "float64", unit, f"filtered {what}", nullable=False) for name, unit, what in _TRACK_POSE),
    _C("heave_m", "float64", "m", "filtered deck heave, the oscillating part (the slow part is in the camera's "
       "own height)", nullable=False),
    _C("heave_rate_m_per_s", "float64", "m/s", "filtered deck heave rate (up)", nullable=False),
    *(_C(f"sigma_{name}", "float64", unit, f"standard deviation of the filtered {what.split(' ')[0]}",
         nullable=False) for name, unit, what in _TRACK_POSE),
    _C("sigma_heave_m", "float64", "m", "standard deviation of the filtered heave", nullable=False),
    _C("sigma_heave_rate_m_per_s", "float64", "m/s", "standard deviation of the filtered heave rate",
       nullable=False),
    *(_C(f"cov_{_TRACK_PARAMS[i]}__{_TRACK_PARAMS[j]}", "float64", _cov_unit(_TRACK_PARAMS[i], _TRACK_PARAMS[j]),
         f"covariance of the filtered pose, {_TRACK_PARAMS[i]} x {_TRACK_PARAMS[j]} (radians and metres)",
         nullable=False) for i in range(6) for j in range(i, 6)),
    _C("landing_go", "bool", "", "landing-window indicator: predicted |roll|, |pitch| and |heave rate| stay "
       "below the limits over the next window with the configured confidence (run.json: landing)",
       nullable=False),
)

#: ``tracks/<detector>--<method>--<tracker>.predictions.parquet``: one row per frame x horizon.
TRACK_PREDICTION_COLUMNS: tuple[Column, ...] = (
    _C("frame_id", "int64", "", "the frame the prediction was made at", nullable=False),
    _C("horizon_s", "float64", "s", "how far ahead", nullable=False),
    _C("stamp_ns", "int64", "ns", "capture time predicted for (the frame's stamp plus the horizon)",
       nullable=False),
    _C("roll_deg", "float64", "deg", "predicted deck roll (ZYX)", nullable=False),
    _C("pitch_deg", "float64", "deg", "predicted deck pitch (ZYX)", nullable=False),
    _C("heave_m", "float64", "m", "predicted deck heave, the oscillating part", nullable=False),
    _C("heave_rate_m_per_s", "float64", "m/s", "predicted deck heave rate (up)", nullable=False),
    _C("height_m", "float64", "m", "predicted height of the camera above the deck centre (the UAV holding its "
       "filtered vertical velocity)", nullable=False),
    _C("sigma_roll_deg", "float64", "deg", "standard deviation of the predicted roll", nullable=False),
    _C("sigma_pitch_deg", "float64", "deg", "standard deviation of the predicted pitch", nullable=False),
    _C("sigma_heave_m", "float64", "m", "standard deviation of the predicted heave", nullable=False),
    _C("sigma_heave_rate_m_per_s", "float64", "m/s", "standard deviation of the predicted heave rate",
       nullable=False),
    _C("sigma_height_m", "float64", "m", "standard deviation of the predicted height", nullable=False),
)
