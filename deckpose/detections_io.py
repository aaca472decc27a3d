"""Read and validate detection tables (CSV or Parquet) into :class:`Detections` per frame.

Required columns: ``frame_id, beacon_id, u_px, v_px``. Optional: ``cov_uu, cov_uv,
cov_vv`` (px^2) and ``snr`` (each detection's signal-to-noise ratio; ``score``, its name before
deckpose-table/3, is read as it). ``beacon_id = -1`` marks an unassigned detection; a
frame whose detections are all unassigned can be identified from their positions
(:func:`identify_unassigned`, with ``is_bow`` or ``flux_r, flux_g, flux_b`` telling
the bow).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pandas as pd

from deckpose.camera import CameraModel
from deckpose.errors import InputDataError, short_repr
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED, Detections
from deckpose.table_schemas import upgrade_legacy_columns
from deckpose.tables import read_table

REQUIRED = ("frame_id", "beacon_id", "u_px", "v_px")


#: Largest integer a float64 holds exactly.
_FLOAT_EXACT = 2**53


def integer_column(df: pd.DataFrame, col: str, source: str) -> np.ndarray:
    """A column of 64-bit integer ids, never passed through float64, (n,) int64.

    An integer column is taken as it is; a text column (CSV ids too long for pandas's
    int64 come as text) is parsed digit by digit; a float column must hold whole
    numbers within +-2^53, beyond which a float has already rounded the id.

    Raises
    ------
    InputDataError
        Naming the first bad row.
    """
    s = df[col]
    if pd.api.types.is_integer_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype):
        if s.dtype == np.uint64 and len(s) and int(s.max()) >= 2**63:
            row = int(np.flatnonzero(s.to_numpy() >= np.uint64(2**63))[0])
            raise InputDataError(
                f"{source}: row {row + 1}: {col} {s.iloc[row]} does not fit a 64-bit integer")
        return s.to_numpy(np.int64)
    if pd.api.types.is_float_dtype(s.dtype):
        v = s.to_numpy(float)
        bad = (v != np.round(v)) | (np.abs(v) > _FLOAT_EXACT)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            why = ("must be an integer" if v[row] == v[row] and v[row] != np.round(v[row])
                   else "is beyond 2^53 in a float column, where digits are lost; store ids as "
                   "integers")
            raise InputDataError(f"{source}: row {row + 1}: {col} {why}, got {short_repr(v[row])}")
        return v.astype(np.int64)
    out = np.empty(len(s), np.int64)
    for row, x in enumerate(s.tolist()):
        try:
            n = int(str(x).strip())
        except ValueError:
            raise InputDataError(
                f"{source}: row {row + 1}: {col} must be an integer, got {str(x)[:40]!r}") from None
        if not -(2**63) <= n < 2**63:
            raise InputDataError(
                f"{source}: row {row + 1}: {col} {n} does not fit a 64-bit integer")
        out[row] = n
    return out


def detections_from_frame(df: pd.DataFrame, layout: DeckLayout, source: str = "detections") -> dict[int, Detections]:
    """Validate a detections table and split it into one :class:`Detections` per frame.

    Raises
    ------
    InputDataError
        Missing columns, NaN or non-integer ids, ids outside the layout, or a
        beacon id listed twice in one frame; the message names the row or frame.
    """
    df = upgrade_legacy_columns(df, "detections")  # an older table's score is the snr
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise InputDataError(
            f"{source}: missing column(s) {missing}; a detections table needs {list(REQUIRED)}"
        )
    for col in REQUIRED:
        bad = df[col].isna() | ~np.isfinite(pd.to_numeric(df[col], errors="coerce").astype(float))
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise InputDataError(f"{source}: row {row + 1} has a missing or non-numeric {col} ({short_repr(df[col].iloc[row])})")
    ids = integer_column(df, "beacon_id", source)
    unknown = (ids != UNASSIGNED) & ((ids < 0) | (ids >= layout.n_beacons))
    if unknown.any():
        row = int(np.flatnonzero(unknown)[0])
        raise InputDataError(
            f"{source}: row {row + 1}: unknown beacon_id {ids[row]}; the layout has ids "
            f"0..{layout.n_beacons - 1} (use -1 for an unassigned detection, or --layout/--radius "
            "to describe your deck)"
        )
    frames = integer_column(df, "frame_id", source)
    assigned = ids != UNASSIGNED
    key = pd.DataFrame({"f": frames[assigned], "b": ids[assigned]})
    dup = key.duplicated(keep=False).to_numpy()
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise InputDataError(
            f"{source}: beacon_id {key['b'].iloc[i]} appears more than once in frame {key['f'].iloc[i]}"
        )
    for col in ("cov_uu", "cov_uv", "cov_vv", "snr"):  # optional, but numeric when given
        if col in df.columns:
            num = pd.to_numeric(df[col], errors="coerce")
            bad = num.isna() & df[col].notna()
            if bad.any():
                row = int(np.flatnonzero(bad.to_numpy())[0])
                raise InputDataError(
                    f"{source}: row {row + 1}: {col} must be a number (or empty), got "
                    f"{str(df[col].iloc[row])[:40]!r}")
            df = df.assign(**{col: num})
    uv = df[["u_px", "v_px"]].to_numpy(float)
    has_cov = all(c in df.columns for c in ("cov_uu", "cov_uv", "cov_vv"))
    cov = None
    if has_cov:
        c = df[["cov_uu", "cov_uv", "cov_vv"]].to_numpy(float)
        with np.errstate(invalid="ignore"):
            not_pd = np.all(np.isfinite(c), axis=1) & ~(
                (c[:, 0] > 0) & (c[:, 2] > 0) & (c[:, 0] * c[:, 2] - c[:, 1] ** 2 > 0))
        if not_pd.any():
            row = int(np.flatnonzero(not_pd)[0])
            raise InputDataError(
                f"{source}: row {row + 1}: covariance (cov_uu, cov_uv, cov_vv) = {tuple(c[row].tolist())} px^2 "
                "is not positive definite; variances must be positive and cov_uv^2 < cov_uu * cov_vv "
                "(leave all three empty where a detection's covariance is unknown)")
        cov = np.stack([np.stack([c[:, 0], c[:, 1]], -1), np.stack([c[:, 1], c[:, 2]], -1)], -2)
    score = df["snr"].to_numpy(float) if "snr" in df.columns else None
    out: dict[int, Detections] = {}
    order = np.argsort(frames, kind="stable")
    bounds = np.flatnonzero(np.diff(frames[order])) + 1
    for idx in np.split(order, bounds) if order.size else []:
        f = int(frames[idx[0]])
        out[f] = Detections(
            points_px=uv[idx],
            beacon_ids=ids[idx],
            covariance_px2=None if cov is None else cov[idx],
            score=None if score is None else score[idx],
            frame_id=f,
        )
    return out


def read_detections(path: str | os.PathLike[str], layout: DeckLayout) -> dict[int, Detections]:
    """Read a detections file and return ``{frame_id: Detections}`` in frame order."""
    return detections_from_frame(read_table(path, "detections"), layout, str(path))


#: Optional columns that let :func:`identify_unassigned` tell the bow beacon.
BOW_COLUMN = "is_bow"
COLOUR_COLUMNS = ("flux_r", "flux_g", "flux_b")


#: How an ``is_bow`` cell written as text reads (case and spaces aside); a blank cell is false.
_BOW_TEXT = {"1": True, "true": True, "yes": True, "y": True, "t": True,
             "0": False, "false": False, "no": False, "n": False, "f": False, "": False}


def bow_flags(column: pd.Series) -> np.ndarray:
    """An ``is_bow`` column as booleans, (n,): bools, numbers (non-zero is true) or text.

    Text is read by :data:`_BOW_TEXT` whatever pandas made of the column (``object`` or
    its ``str`` dtype, mixed with numbers or bools); a blank or missing cell is false.

    Raises
    ------
    InputDataError
        A cell that reads as neither true nor false (named, with its row).
    """
    if pd.api.types.is_bool_dtype(column.dtype) and not column.isna().any():
        return column.to_numpy(bool)
    if pd.api.types.is_numeric_dtype(column.dtype) and not pd.api.types.is_bool_dtype(column.dtype):
        values = column.to_numpy(float)
        return ~np.isnan(values) & (values != 0)
    out = np.zeros(len(column), bool)
    for i, cell in enumerate(column.tolist()):
        if cell is None or (isinstance(cell, float) and math.isnan(cell)) or cell is pd.NA:
            continue
        key = str(cell).strip().lower()  # (a bool reads "true"/"false", a number as below)
        if key not in _BOW_TEXT:
            try:  # a number, or one written as text ("1.0", "0.0", "inf")
                key = "false" if float(key) == 0 else "true"
            except ValueError:
                pass
        if key not in _BOW_TEXT:
            raise InputDataError(f"detections: is_bow on row {i + 1} is {short_repr(cell)}, which reads as neither true nor "
                              "false; write true/false, yes/no or 1/0 (blank: false)")
        out[i] = _BOW_TEXT[key]
    return out


def identify_unassigned(
    df: pd.DataFrame, frames: dict[int, Detections], layout: DeckLayout, camera: CameraModel
) -> tuple[dict[int, Detections], dict[int, str]]:
    """Give beacon ids to frames whose detections are all unassigned (``beacon_id = -1``).

    The same identification as ``deckpose detect`` (:func:`deckpose.detect.identify.
    identify_beacons`: the ring ellipse, its even spacing, the centre), from the
    positions. The bow beacon, which fixes the ring's ids, is told by an ``is_bow``
    column (true on the bow's row) or by per-channel flux columns ``flux_r, flux_g,
    flux_b`` (the distinctly red one). Frames with some ids given are left as they are.

    Returns
    -------
    frames : dict of int to Detections
        With ids where identification succeeded.
    notes : dict of int to str
        Why identification failed, per frame it failed for (what the table lacks).
    """
    from deckpose.detect.identify import identify_beacons

    frame_col = integer_column(df, "frame_id", "detections")
    has_bow = BOW_COLUMN in df.columns
    has_rgb = all(c in df.columns for c in COLOUR_COLUMNS)
    bow_v = bow_flags(df[BOW_COLUMN]) if has_bow else None
    rgb_v = df[list(COLOUR_COLUMNS)].to_numpy(float) if has_rgb else None
    out = dict(frames)
    notes: dict[int, str] = {}
    for f, d in frames.items():
        if not np.all(d.beacon_ids == UNASSIGNED) or len(d.beacon_ids) == 0:
            continue
        rows = np.flatnonzero(frame_col == f)  # the frame's rows, in the order Detections kept
        rgb = None
        if rgb_v is not None and np.isfinite(rgb_v[rows]).all():
            rgb = rgb_v[rows]
        elif bow_v is not None and bow_v[rows].any():  # also where a frame's flux cells are blank
            rgb = np.where(bow_v[rows][:, None], [[1.0, 0.0, 0.0]], [[1.0, 1.0, 1.0]])
        try:
            ident = identify_beacons(d.points_px, layout, camera, rgb_flux=rgb)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            notes[f] = f"identification raised {type(exc).__name__}: {exc}"
            continue
        if ident:
            out[f] = Detections(d.points_px, ident.beacon_ids, d.covariance_px2, d.score,
                                frame_id=f)
        else:
            if not (has_bow or has_rgb):
                need = ("; the table has no is_bow column (true on the bow's row) nor flux_r, flux_g, "
                        "flux_b to tell the bow by (add one; a frame deckpose detect could not identify "
                        "in its image keeps its reason in detect_frames.parquet)")
            elif rgb is None:
                said = [w for w, has in (("no row of it has is_bow true", has_bow),
                                         ("its flux_r, flux_g, flux_b cells are not all filled", has_rgb)) if has]
                need = f"; nothing in the table tells this frame's bow: {' and '.join(said)}"
            else:
                need = ""
            notes[f] = f"unidentified detections (beacon_id -1): {ident.reason}{need}"
    return out, notes
