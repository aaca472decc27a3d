"""Before a job writes: can it write there, is there room, and is no other job writing there?

Every command that writes calls :func:`claim_output` on its output folder before
the work starts, so a read-only folder, a full disk or a second job on the same
folder is one line at the start (exit status 2), not a traceback after an hour of
work:

* the folder is created if needed and a probe file is written and removed in it;
* the disk must have the space the job expects to write (when it can say);
* a lock (``fcntl.flock`` on a hidden ``.deckpose.lock`` holding the owner's pid
  and start time) keeps a second deckpose process out until the first ends. The
  kernel releases it when its process dies, even by SIGKILL, so no stale lock
  blocks a rerun; one process may claim a folder again (the pipeline runs its
  stages in-process). Once claimed, the temporary files a killed writer left in
  the folder are removed (:func:`deckpose.atomic_io.remove_stale_temps`).
"""

from __future__ import annotations

import atexit
import contextlib
import datetime as dt
import errno
import os
import shutil
import tempfile
from pathlib import Path

from deckpose.atomic_io import remove_stale_temps
from deckpose.errors import DeckposeError

#: The lock file's name in a claimed folder (hidden: folder listings skip it).
LOCK_NAME = ".deckpose.lock"


class OutputFolderError(DeckposeError, OSError):
    """An output folder cannot be written, has no room, or is another job's."""


_HELD: dict[Path, int] = {}  # folder -> open lock file descriptor, this process


def _release_all() -> None:
    for folder in list(_HELD):
        release(folder)


atexit.register(_release_all)


def ensure_writable(folder: str | os.PathLike[str], *, need_bytes: int = 0) -> Path:
    """Create ``folder`` if needed and check a file can be written there and fits.

    Raises
    ------
    OutputFolderError
        Naming the folder, what failed and what to do.
    """
    p = Path(folder)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFolderError(
            f"cannot create the output folder {p}: {exc.strerror}; choose another one (-o DIR)"
        ) from None
    if not p.is_dir():
        raise OutputFolderError(f"output {p} exists and is not a folder; choose another one (-o DIR)")
    try:
        fd, probe = tempfile.mkstemp(prefix=".deckpose-write-test.", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        hint = ("the disk is full; free some space" if exc.errno == errno.ENOSPC
                else "choose a folder you can write to (-o DIR)")
        raise OutputFolderError(f"cannot write in {p}: {exc.strerror}; {hint}") from None
    if need_bytes > 0:
        free = shutil.disk_usage(p).free
        if free < need_bytes:
            raise OutputFolderError(
                f"{p}: this job writes about {_size(need_bytes)} but the disk has {_size(free)} "
                "free; free some space or choose another folder (-o DIR)"
            )
    return p


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} GB"


def claim_output(
    folder: str | os.PathLike[str], *, need_bytes: int = 0, what: str = "job"
) -> Path:
    """:func:`ensure_writable`, then lock ``folder`` for this process until it exits.

    Parameters
    ----------
    folder : path-like
    need_bytes : int
        Bytes the job expects to write (0: unknown).
    what : str
        What the job is ("render", "detect"), written into the lock for the message
        another job gets.

    Raises
    ------
    OutputFolderError
        When the folder cannot be written or fits no more, or another deckpose
        process holds it (its pid, job and start time named).
    """
    p = ensure_writable(folder, need_bytes=need_bytes).resolve()
    if p in _HELD:
        return p
    import fcntl

    lock = p / LOCK_NAME
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutputFolderError(f"cannot lock {p}: {exc.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(fd)
        os.close(fd)
        raise OutputFolderError(
            f"{p} is being written by another deckpose job ({holder}); "
            "wait for it to finish or choose another folder"
        ) from None
    os.ftruncate(fd, 0)
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    os.pwrite(fd, f"deckpose {what}, pid {os.getpid()}, since {stamp}\n".encode(), 0)
    _HELD[p] = fd
    # no other deckpose process writes here now: what a killed one left half-written goes
    remove_stale_temps(p)
    return p


def _holder(fd: int) -> str:
    """What a lock file open as ``fd`` says of the job that holds it ("holder unknown" if nothing)."""
    text = ""
    with contextlib.suppress(OSError):
        text = os.pread(fd, 512, 0).decode("utf-8", "replace").strip()
    return text or "holder unknown"


def held_by_another(folder: str | os.PathLike[str]) -> str | None:
    """The job that holds ``folder``'s lock now, as its lock file names it; ``None`` if none does.

    A lock this process holds, or a lock file a finished or killed job left (no process
    holds it any more), is no other job's.
    """
    p = Path(folder).resolve()
    if p in _HELD:
        return None
    import fcntl

    try:
        fd = os.open(p / LOCK_NAME, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _holder(fd)
    finally:
        os.close(fd)  # (closing drops a shared lock taken above)
    return None


def release(folder: str | os.PathLike[str]) -> None:
    """Give up this process's lock on ``folder`` (no-op when it holds none)."""
    p = Path(folder).resolve()
    fd = _HELD.pop(p, None)
    if fd is None:
        return
    with contextlib.suppress(OSError):
        os.unlink(p / LOCK_NAME)  # while still locked: a waiting process sees no stale file
    os.close(fd)
