"""Where frames come from: a deckpose dataset folder, or a folder of a user's images.

A dataset follows the contract ``deckpose-dataset/1`` (``manifest.json``,
``cameras/*.yaml``, ``images/``, ``frames.parquet``). A plain folder of images
needs a ROS camera_info file (one camera for all images) and optionally a
layout file; frame ids are then the images' positions in name order.

Loading a frame never raises for a bad file: it returns the reason instead,
so a batch goes on past unreadable, truncated or wrongly sized images.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from deckpose.camera import CameraModel
from deckpose.camera_info import read_camera_info
from deckpose.errors import InputDataError
from deckpose.image_store import decode_image
from deckpose.layout import DeckLayout, layout_from_dict, read_layout
from deckpose.records import Frame
from deckpose.run_folder import DATASET_FORMAT, RunPaths, unfinished_render
from deckpose.shell_command import deckpose_command

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm", ".webp", ".zst")


@dataclass(frozen=True)
class FrameSource:
    """One image to detect in, before it is read.

    Attributes
    ----------
    frame_id : int
    image_path : Path
    camera_name : str
    stamp_ns : int
    """

    frame_id: int
    image_path: Path
    camera_name: str
    stamp_ns: int = 0


@dataclass(frozen=True)
class FrameSet:
    """Frames with their cameras and the deck layout.

    Attributes
    ----------
    sources : tuple of FrameSource
    cameras : mapping of camera name to CameraModel
    camera_files : mapping of camera name to the camera_info path
    layout : DeckLayout
    kind : str
        ``"dataset"`` or ``"images"``.
    root : Path
    manifest : dict
        The dataset manifest (empty for an image folder).
    """

    sources: tuple[FrameSource, ...]
    cameras: dict[str, CameraModel]
    camera_files: dict[str, Path]
    layout: DeckLayout
    kind: str
    root: Path
    manifest: dict[str, Any] = field(default_factory=dict)


def declared_gain(manifest: dict[str, Any]) -> float | None:
    """The sensor gain (DN per electron) a dataset's manifest declares, or ``None``.

    Rendered and synthetic datasets write it in their ``sensor`` block; detectors use it
    for fit weights and covariances instead of estimating it from the frame's blobs
    (rendered beacons are no Gaussians, which inflates that estimate).
    """
    doc = manifest.get("sensor")
    if not isinstance(doc, dict):
        return None
    gain = doc.get("gain_dn_per_e")
    if isinstance(gain, (int, float)) and gain > 0 and doc.get("noise", True) is not False:
        return float(gain)
    return None


def is_dataset(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a dataset folder (has a manifest.json)."""
    return RunPaths(Path(path)).manifest.is_file()


def open_dataset(path: str | os.PathLike[str]) -> FrameSet:
    """Read a dataset's manifest, cameras and frame table.

    Raises
    ------
    InputDataError
        If the manifest, a camera file or ``frames.parquet`` is missing or malformed.
    """
    import pandas as pd

    root = Path(path)
    run = RunPaths(root)
    try:
        manifest = json.loads(run.manifest.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputDataError(
            f"{root}: cannot read manifest.json ({exc}); is this a deckpose dataset?"
        ) from exc
    fmt = manifest.get("format")
    if fmt != DATASET_FORMAT:
        raise InputDataError(
            f"{root}/manifest.json: format is {fmt!r}, expected {DATASET_FORMAT!r}"
        )
    unfinished = unfinished_render(run)
    if unfinished is not None:
        raise InputDataError(unfinished)
    layout = layout_from_dict(manifest.get("layout"), f"{root}/manifest.json: layout")
    if not run.frames.exists():  # the frames' parts are kept: a resumed render rebuilds the tables
        raise InputDataError(f"{run.frames} is missing; make it again with: "
                             f"{deckpose_command('render', 'CONFIG.yaml', root, '--resume')}")
    try:
        frames = pd.read_parquet(
            run.frames, columns=["frame_id", "image", "camera", "stamp_ns"]
        )
    except Exception as exc:  # pyarrow raises several types for missing/corrupt files
        raise InputDataError(
            f"{root}/frames.parquet: cannot read frame_id, image, camera, stamp_ns ({exc})"
        ) from exc
    cameras, files = {}, {}
    for name in sorted(set(frames["camera"].astype(str))):
        f = run.camera_file(name)
        cameras[name] = read_camera_info(f)
        files[name] = f
    sources = tuple(
        FrameSource(int(fid), root / str(image), str(camera), int(stamp_ns))
        for fid, image, camera, stamp_ns in zip(
            frames["frame_id"], frames["image"], frames["camera"], frames["stamp_ns"]
        )
    )
    return FrameSet(sources, cameras, files, layout, "dataset", root, manifest)


def open_image_folder(
    path: str | os.PathLike[str],
    camera_info: str | os.PathLike[str],
    layout_file: str | os.PathLike[str] | None = None,
) -> FrameSet:
    """A folder of images taken with one camera (frame ids in file-name order).

    Hidden files (``.name.png``: an editor's or a copy's temporary, macOS's ``._`` files) and
    subfolders are no frames.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputDataError(f"{root} is not a folder of images")
    images = sorted(p for p in root.iterdir()
                    if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file())
    if not images:
        raise InputDataError(f"{root}: no images ({', '.join(IMAGE_SUFFIXES)}) found")
    camera = read_camera_info(camera_info)
    name = camera.name or "camera"
    layout = DeckLayout() if layout_file is None else read_layout(layout_file)
    sources = tuple(FrameSource(i, p, name, 0) for i, p in enumerate(images))
    return FrameSet(sources, {name: camera}, {name: Path(camera_info)}, layout, "images", root)


def require_images(frameset: FrameSet, fix: str | Callable[[], str]) -> None:
    """Raise unless the dataset keeps its frames (a ``--no-images`` render keeps none).

    ``fix`` ends the one-line message: what to do instead, for the command that asked (a
    callable is called only for that message).
    """
    if frameset.manifest.get("images_kept") is False:
        hint = fix() if callable(fix) else fix
        raise InputDataError(f"{frameset.root} keeps no frames (rendered with --no-images), so there is "
                             f"nothing to detect in; {hint}")


#: What every reason :func:`read_image` and :func:`load_frame` give starts with: the frame's
#: own fault (a missing, damaged or mis-sized image), not a detector's.
UNREADABLE_FRAME = re.compile(r"^(image |cannot decode )")


def read_image(path: Path) -> np.ndarray | str:
    """Decode an image file (colour as RGB); the reason as a string if it cannot be used."""
    if not path.is_file():
        return f"image file {path} does not exist"
    try:
        img = decode_image(path.read_bytes(), str(path))
    except InputDataError as exc:
        return str(exc)
    if img.dtype not in (np.uint8, np.uint16):
        return f"image {path} has pixel type {img.dtype}; use 8- or 16-bit images"
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[:, :, :3]
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    elif img.ndim != 2:
        return f"image {path} has shape {img.shape}; expected mono or RGB"
    return img


def load_frame(src: FrameSource, camera: CameraModel) -> Frame | str:
    """The frame of ``src``, or the reason it cannot be used."""
    img = read_image(src.image_path)
    if isinstance(img, str):
        return img
    if img.shape[:2] != (camera.height_px, camera.width_px):
        return (
            f"image {src.image_path.name} is {img.shape[1]}x{img.shape[0]} but camera "
            f"{src.camera_name!r} is {camera.width_px}x{camera.height_px}; wrong camera_info?"
        )
    return Frame(img, camera, src.frame_id, src.stamp_ns)
