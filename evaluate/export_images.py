"""Putting a run's images into an export: a symbolic link to each (the default) or a copy.

A link costs nothing and keeps one copy of the images (large at 64 MP); the export then
works only where the run folder stays where it was (links are absolute). A copy makes the
export self-contained, to archive or move to another machine. Either way each file appears
atomically (:mod:`deckpose.atomic_io`): a reader never finds a half-copied image.
"""

from __future__ import annotations

import enum
import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from deckpose.atomic_io import atomic_path
from deckpose.errors import InputDataError
from deckpose.image_store import ImageFormat, decode_image, encode_image

__all__ = ["ImageMode", "export_suffix", "place_images"]


class ImageMode(enum.Enum):
    """How an export holds the run's images."""

    #: An absolute symbolic link to the run's image.
    SYMLINK = "symlink"
    #: A copy of the file.
    COPY = "copy"


def export_suffix(source: Path) -> str:
    """The suffix of ``source``'s image in an export: its own, but ``.png`` for a ``.zst`` frame.

    A run stored with ``image_format: zstd`` (:mod:`deckpose.image_store`) is exported as
    PNG, which the formats' tools read; such a frame is always written, never linked.
    """
    return ".png" if source.suffix == ImageFormat.ZSTD.suffix else source.suffix


def _place(source: Path, target: Path, mode: ImageMode) -> None:
    with atomic_path(target) as tmp:
        if source.suffix == ImageFormat.ZSTD.suffix:
            tmp.write_bytes(encode_image(decode_image(source.read_bytes(), str(source)), ImageFormat.PNG))
        elif mode is ImageMode.COPY:
            shutil.copyfile(source, tmp)
        else:
            tmp.unlink()  # atomic_path made a file; the link takes its name, then os.replace
            os.symlink(source.resolve(), tmp)


def place_images(sources: Sequence[Path], targets: Sequence[Path], mode: ImageMode, *,
                 progress: Callable[[int], object] | None = None) -> None:
    """Link or copy each ``sources[i]`` to ``targets[i]`` (folders made as needed).

    Parameters
    ----------
    sources, targets : sequences of Path, the same length
    mode : ImageMode
    progress : callable, optional
        Called with 1 after each image.

    Raises
    ------
    InputDataError
        When a source is not a file, or a target is the source itself (checked for all
        before any is placed).
    """
    if len(sources) != len(targets):
        raise InputDataError(f"place_images needs as many targets as sources, got {len(targets)} "
                             f"and {len(sources)}")
    missing = [str(s) for s in sources if not Path(s).is_file()]
    if missing:
        raise InputDataError(f"{len(missing)} images are missing (e.g. {missing[0]})")
    for source, target in zip(sources, targets, strict=True):
        t = Path(target)
        if t.exists() and not t.is_symlink() and os.path.samefile(source, t):
            raise InputDataError(f"{t} is the run's own image {source}; choose an output folder "
                                 "outside the run's images")
    for source, target in zip(sources, targets, strict=True):
        _place(Path(source), Path(target), mode)
        if progress is not None:
            progress(1)
