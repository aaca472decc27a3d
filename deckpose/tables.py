"""Tabular files (CSV or Parquet, chosen by extension): read with clear errors, write atomically.

A Parquet file carries, in its key-value metadata under ``deckpose``, what it holds
(``kind``), the table format and deckpose version that wrote it, and each column's
unit. Units are read off the column names, which carry them by the project's
convention (``roll_deg``, ``height_m``, ``u_px``, ``stamp_ns``); a column without a
unit suffix is a count, an id, a flag or a name.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd

from deckpose.atomic_io import atomic_path
from deckpose.errors import InputDataError

TABLE_SUFFIXES = (".csv", ".parquet", ".pq")
#: Version of the tables' layout, in each Parquet file's metadata.
TABLE_FORMAT = "deckpose-table/1"
#: Column-name suffix -> unit (the longest matching suffix wins).
UNIT_SUFFIXES: dict[str, str] = {
    "_deg": "deg", "_rad": "rad", "_m": "m", "_px": "px", "_px2": "px^2", "_s": "s", "_ns": "ns",
    "_e": "e-", "_dn": "DN", "_m_per_s": "m/s", "_dn_per_e": "DN/e-", "_kn": "kn", "_hz": "Hz",
}


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
    try:
        return pd.read_csv(p) if ext == ".csv" else pd.read_parquet(p)
    except Exception as exc:  # pandas/pyarrow raise many exception types on corrupt files
        raise InputDataError(f"{p}: cannot read {what} ({type(exc).__name__}: {exc})") from exc


def write_table(df: pd.DataFrame, path: str | os.PathLike[str], what: str = "table") -> None:
    """Write a table as CSV or Parquet (by extension) via a temporary file and rename.

    A Parquet file gets the ``deckpose`` metadata of the module docstring, ``what`` as its kind.
    """
    p = Path(path)
    ext = _check_suffix(p, what)
    with atomic_path(p) as tmp:
        if ext == ".csv":
            df.to_csv(tmp, index=False)
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            from deckpose import __version__

            table = pa.Table.from_pandas(df, preserve_index=False)
            meta = {"format": TABLE_FORMAT, "kind": what, "deckpose_version": __version__,
                    "units": column_units([str(c) for c in df.columns])}
            table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                                   b"deckpose": json.dumps(meta).encode()})
            pq.write_table(table, tmp)


def table_metadata(path: str | os.PathLike[str]) -> dict[str, object]:
    """The ``deckpose`` metadata of a Parquet table (empty for files written otherwise)."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(b"deckpose")
    return dict(json.loads(raw)) if raw else {}
