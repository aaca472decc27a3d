"""Tabular files (CSV or Parquet, chosen by extension): read with clear errors, write atomically."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from deckpose.atomic_io import atomic_path
from deckpose.errors import InputDataError

TABLE_SUFFIXES = (".csv", ".parquet", ".pq")


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
    """Write a table as CSV or Parquet (by extension) via a temporary file and rename."""
    p = Path(path)
    ext = _check_suffix(p, what)
    with atomic_path(p) as tmp:
        if ext == ".csv":
            df.to_csv(tmp, index=False)
        else:
            df.to_parquet(tmp, index=False)
