"""Tabular files (CSV or Parquet, chosen by extension): read with clear errors, write atomically.

A Parquet file carries, in its key-value metadata under ``deckpose``, what it holds
(``kind``), the table format and deckpose version that wrote it, each column's unit and,
for the kinds :data:`SCHEMAS` documents, each column's description. Units come from the
kind's schema (:mod:`deckpose.table_schemas`) and otherwise off the column names, which
carry them by the project's convention (``roll_deg``, ``height_m``, ``u_px``,
``stamp_ns``); a column without a unit is a count, an id, a flag, a ratio or a name.
A kind in :data:`FIXED_KINDS` (the estimates) is written with exactly its schema's
columns, order and types, or not at all.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from deckpose.atomic_io import atomic_path
from deckpose.errors import InputDataError
from deckpose.estimates_schema import ESTIMATE_COLUMNS
from deckpose.table_schemas import (
    BEACON_COLUMNS,
    DETECT_FRAME_COLUMNS,
    DETECTION_COLUMNS,
    FRAME_COLUMNS,
    HOT_PIXEL_COLUMNS,
    LIGHT_COLUMNS,
    PAINTED_RING_BOUND_COLUMNS,
    PAINTED_RING_COLUMNS,
    RING_DETECTION_COLUMNS,
    TRACK_COLUMNS,
    TRACK_PREDICTION_COLUMNS,
    Column,
)

if TYPE_CHECKING:
    import pyarrow as pa

TABLE_SUFFIXES = (".csv", ".parquet", ".pq")
#: Version of the tables' layout, in each Parquet file's metadata.
TABLE_FORMAT = "deckpose-table/3"
#: Column-name suffix -> unit (the longest matching suffix wins).
UNIT_SUFFIXES: dict[str, str] = {
    "_deg": "deg", "_rad": "rad", "_m": "m", "_px": "px", "_px2": "px^2", "_s": "s", "_ns": "ns",
    "_e": "e-", "_dn": "DN", "_m_per_s": "m/s", "_dn_per_e": "DN/e-", "_kn": "kn", "_hz": "Hz",
}

#: Table kind (``write_table``'s ``what``) -> its documented columns.
SCHEMAS: dict[str, tuple[Column, ...]] = {
    "frames": FRAME_COLUMNS, "beacons": BEACON_COLUMNS, "detections": DETECTION_COLUMNS,
    "detect frames": DETECT_FRAME_COLUMNS, "estimates": ESTIMATE_COLUMNS, "lights": LIGHT_COLUMNS,
    "hot pixels": HOT_PIXEL_COLUMNS, "tracks": TRACK_COLUMNS, "track predictions": TRACK_PREDICTION_COLUMNS,
    "painted ring": PAINTED_RING_COLUMNS, "ring detections": RING_DETECTION_COLUMNS,
    "painted ring bounds": PAINTED_RING_BOUND_COLUMNS,
}
#: Kinds written with exactly their schema's columns, in order, with its types.
FIXED_KINDS = frozenset({"estimates", "tracks", "track predictions"})


def column_units(columns: list[str]) -> dict[str, str]:
    """The unit of each column that names one in its suffix (``roll_deg`` -> ``deg``)."""
    out = {}
    for c in columns:
        hits = [suf for suf in UNIT_SUFFIXES if str(c).endswith(suf)]
        if hits:
            out[str(c)] = UNIT_SUFFIXES[max(hits, key=len)]
    return out


def _check_suffix(p: Path, what: str) -> str:
    ext = p.suffix.lower()
    if ext not in TABLE_SUFFIXES:
        raise InputDataError(f"{p}: {what} must be a .csv or .parquet file, got {ext or 'no extension'!r}")
    return ext


def read_table(path: str | os.PathLike[str], what: str = "table") -> pd.DataFrame:
    """Read a CSV or Parquet file chosen by extension.

    Raises
    ------
    InputDataError
        Wrong extension, missing file, or a file that does not parse.
    """
    p = Path(path)
    ext = _check_suffix(p, what)
    if not p.exists():
        raise InputDataError(f"{what} file {p} does not exist")
    if p.is_dir():
        inner = sorted(q.name for q in p.glob(f"*{ext}"))
        inner.sort(key=lambda name: name != f"{what}{ext}")  # (deckpose detect -o DIR writes DIR/detections.parquet)
        hint = f"; read {p / inner[0]}" if inner else ""
        raise InputDataError(f"{p} is a folder, not a {what} file{hint}")
    try:
        if ext != ".csv":
            return pd.read_parquet(p)
        # a spreadsheet's CSV: "frame_id, beacon_id" (spaces after the commas) or, where the
        # decimal mark is a comma, fields split by ";" (told by the header line)
        sep, decimal = _csv_dialect(p)
        df = pd.read_csv(p, sep=sep, decimal=decimal, skipinitialspace=True)
        df.columns = [str(c).strip() for c in df.columns]
        return df
    except Exception as exc:  # pandas/pyarrow raise many exception types on corrupt files
        raise InputDataError(f"{p}: cannot read {what} ({type(exc).__name__}: {exc})") from exc


def _csv_dialect(path: Path) -> tuple[str, str]:
    """``(separator, decimal mark)`` of a CSV: ``";"`` where its header line has ``;`` and no
    ``,``, and then ``","`` decimals where some field holds one (``785,5``) and none a point."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        header = fh.readline()
        if ";" not in header or "," in header:
            return ",", "."
        body = fh.read()
    comma = re.search(r"\d,\d", body) is not None and re.search(r"\d\.\d", body) is None
    return ";", "," if comma else "."


def write_table(df: pd.DataFrame, path: str | os.PathLike[str], what: str = "table") -> None:
    """Write a table as CSV or Parquet (by extension) via a temporary file and rename.

    A Parquet file gets the ``deckpose`` metadata of the module docstring, ``what`` as its kind.

    Raises
    ------
    InputDataError
        ``df`` of a kind in :data:`FIXED_KINDS` lacks a column of its schema, has another, or
        has them in another order (a programming error: build it with the schema's columns).
    """
    p = Path(path)
    ext = _check_suffix(p, what)
    schema = SCHEMAS.get(what, ())
    if what in FIXED_KINDS:
        _check_columns(df, schema, what)
    with atomic_path(p) as tmp:
        if ext == ".csv":
            df.to_csv(tmp, index=False)
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            from deckpose import __version__

            fixed = arrow_schema(schema) if what in FIXED_KINDS else None
            table = pa.Table.from_pandas(df, schema=fixed, preserve_index=False)
            names = [str(c) for c in df.columns]
            known = {c.name: c for c in schema}
            units = {n: u for n, u in column_units(names).items() if n not in known}
            units.update({n: known[n].unit for n in names if n in known and known[n].unit})
            meta = {"format": TABLE_FORMAT, "kind": what, "deckpose_version": __version__, "units": units,
                    "descriptions": {n: known[n].description for n in names if n in known}}
            table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                                   b"deckpose": json.dumps(meta).encode()})
            pq.write_table(table, tmp)


def arrow_schema(columns: tuple[Column, ...]) -> pa.Schema:
    """The Arrow schema of documented columns (every field nullable: a failed row is null)."""
    import pyarrow as pa

    types = {"int64": pa.int64(), "float64": pa.float64(), "bool": pa.bool_(), "string": pa.string()}
    return pa.schema([pa.field(c.name, types[c.dtype]) for c in columns])


def _check_columns(df: pd.DataFrame, schema: tuple[Column, ...], what: str) -> None:
    want = [c.name for c in schema]
    got = [str(c) for c in df.columns]
    if got != want:
        missing = [c for c in want if c not in got]
        extra = [c for c in got if c not in want]
        raise InputDataError(f"the {what} table must have exactly its schema's columns in order "
                             f"(deckpose.tables.SCHEMAS); missing {missing[:5]}, unexpected {extra[:5]}"
                             + ("" if missing or extra else ", order differs"))


def table_metadata(path: str | os.PathLike[str]) -> dict[str, object]:
    """The ``deckpose`` metadata of a Parquet table (empty for files written otherwise)."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(b"deckpose")
    return dict(json.loads(raw)) if raw else {}
