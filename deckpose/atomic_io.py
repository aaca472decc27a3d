"""Crash-safe file writing: write to a temporary name in the same folder, then rename.

A reader never sees a half-written file: either the old file (or none) or the
complete new one. ``os.replace`` is atomic on POSIX within one filesystem.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any


def is_temp_name(name: str) -> bool:
    """Whether ``name`` is one of :func:`atomic_path`'s temporary names (``.NAME.XXXX.tmp.EXT``)."""
    return name.startswith(".") and ".tmp" in name and name.count(".") >= 3


def remove_stale_temps(root: str | os.PathLike[str]) -> int:
    """Remove the temporary files a killed writer left under ``root``; returns how many.

    Only for a folder no other process is writing (one this process has claimed,
    :func:`deckpose.output_folder.claim_output`): a live writer's temporary file
    looks the same.
    """
    n = 0
    for folder, _dirs, files in os.walk(root):
        for name in files:
            if is_temp_name(name):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(os.path.join(folder, name))
                    n += 1
    return n


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Use for writers that want a file name (pandas, OpenCV, mcap). On an
    exception the temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp" + target.suffix,
                                    dir=target.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    # mkstemp creates 0600; give the file the mode a plain open() would (0666 & ~umask).
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", **kwargs: Any) -> Iterator[IO[Any]]:
    """Open a temporary file for writing; rename it onto ``path`` when the block ends cleanly."""
    if not any(m in mode for m in "wx"):
        raise ValueError(f"atomic_open is for writing; got mode {mode!r}")
    with atomic_path(path) as tmp, open(tmp, mode.replace("x", "w"), **kwargs) as fh:
        yield fh
        fh.flush()
        os.fsync(fh.fileno())


def write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; an ``OSError`` of the write names the file.

    A failed write or fsync (a full disk, say) raises an ``OSError`` without a file name;
    it is raised again with ``path`` in it, so the one-line error says where.
    """
    try:
        with atomic_open(path, "wb") as fh:
            fh.write(data)
    except OSError as exc:
        if exc.filename is None and exc.errno is not None:  # a write or fsync names no file: name it
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
