"""A run as a COCO keypoints dataset: one category ``deck`` whose keypoints are the beacons.

Written under the output folder ``DIR``::

    DIR/deck_keypoints.json   info, images, annotations, categories (COCO's keypoint format)
    DIR/images/IIIIII.png     the frames' images, linked or copied; ``file_name`` is this path
                              relative to DIR

Keypoint ``k`` is beacon id ``k``: ``bow`` (ring id 0), ``ring_1`` ... ``ring_{n-1}``
counter-clockwise from it seen from above, then ``centre`` when the layout has one
(13 for the default layout). The skeleton joins neighbours on the ring and, with a centre,
the centre to every ring beacon, in COCO's 1-based keypoint indices.

One image per frame (``id`` = the run's ``frame_id``) and one annotation per image in which
at least one beacon is labelled (``id`` = ``frame_id + 1``: COCO's evaluation takes an id
of 0 for "no match"). Per beacon, ``v = 2`` where it is visible (in the image and the camera
sees its lit side), ``v = 1`` where it is in the image but the deck hides it (seen from
below), ``v = 0`` with ``x = y = 0`` where it is outside the image or behind the camera.

Pixels: COCO's coordinates are continuous with ``(0, 0)`` the top-left corner of the
top-left pixel; deckpose's (OpenCV's) put pixel centres at integers, so ``x = u + 0.5``,
``y = v + 0.5``. Keypoints are where the beacons are in the image as rendered, lens
distortion included. ``bbox`` is the box of the labelled keypoints (``[x, y, w, h]``,
clipped to the image) and ``area`` its ``w * h`` (COCO's keypoint similarity scale).
"""

from __future__ import annotations

import datetime as dt
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from deckpose.evaluate.export_frames import read_export_frames
from deckpose.evaluate.export_images import ImageMode, export_suffix, place_images
from numpy.typing import ArrayLike

from deckpose.atomic_io import atomic_open
from deckpose.errors import check_shape
from deckpose.layout import DeckLayout
from deckpose.run_folder import RunPaths

__all__ = ["ANNOTATIONS_NAME", "COCO_FROM_OPENCV_PX", "DECK_CATEGORY_ID", "CocoExport",
           "coco_keypoints", "deck_category", "is_coco_export", "keypoint_names", "skeleton", "write_coco"]

#: The annotation file's name in the output folder.
ANNOTATIONS_NAME = "deck_keypoints.json"
#: Added to an OpenCV pixel coordinate (centres at integers) to give COCO's (corner at 0).
COCO_FROM_OPENCV_PX = 0.5
#: The deck's category id.
DECK_CATEGORY_ID = 1
#: The folder of the images in the output folder.
IMAGES_DIR = "images"


@dataclass(frozen=True)
class CocoExport:
    """What :func:`write_coco` wrote: the annotation file, and how many images and annotations."""

    annotations: Path
    n_images: int
    n_annotations: int


def keypoint_names(layout: DeckLayout) -> list[str]:
    """Keypoint names in beacon-id order: ``bow``, ``ring_1`` ... ``ring_{n-1}``, ``centre``."""
    names = ["bow" if i == layout.bow_id else f"ring_{i}" for i in range(layout.n_ring)]
    return names + (["centre"] if layout.has_centre else [])


def skeleton(layout: DeckLayout) -> list[list[int]]:
    """Ring edges, then spokes from the centre, as 1-based keypoint index pairs (COCO's)."""
    n = layout.n_ring
    edges = [[i + 1, (i + 1) % n + 1] for i in range(n)]
    if layout.centre_id is not None:
        edges += [[layout.centre_id + 1, i + 1] for i in range(n)]
    return edges


def deck_category(layout: DeckLayout) -> dict[str, Any]:
    """The ``deck`` category with its keypoints and skeleton."""
    return {"id": DECK_CATEGORY_ID, "name": "deck", "supercategory": "ship",
            "keypoints": keypoint_names(layout), "skeleton": skeleton(layout)}


def coco_keypoints(points_px: ArrayLike, in_image: ArrayLike, facing: ArrayLike) -> np.ndarray:
    """COCO ``[x, y, v]`` per beacon, for a batch of frames.

    Parameters
    ----------
    points_px : (F, N, 2) array of float, pixels
        Beacon centres, OpenCV's convention (pixel centres at integers); NaN allowed.
    in_image, facing : (F, N) arrays of bool

    Returns
    -------
    (F, N, 3) array of float
        ``x, y`` in COCO's convention (``u + 0.5``, ``v + 0.5``) and ``v`` = 2 (visible),
        1 (in the image, lit side away from the camera) or 0 (``x = y = 0``: outside).
    """
    p = np.asarray(points_px, float)
    check_shape("points_px", p, (None, None, 2))
    inside = np.asarray(in_image, bool) & np.all(np.isfinite(p), axis=-1)
    fac = np.asarray(facing, bool)
    check_shape("in_image", inside, p.shape[:2])
    check_shape("facing", fac, p.shape[:2])
    v = np.where(inside, np.where(fac, 2.0, 1.0), 0.0)
    xy = np.where(inside[..., None], p + COCO_FROM_OPENCV_PX, 0.0)
    return np.concatenate([xy, v[..., None]], axis=-1)


def _annotation(kp: np.ndarray, image_id: int, width: int, height: int) -> dict[str, Any] | None:
    labelled = kp[:, 2] > 0
    if not labelled.any():
        return None
    xy = kp[labelled, :2]
    x0, y0 = np.clip(xy.min(0), 0.0, [width, height])
    x1, y1 = np.clip(xy.max(0), 0.0, [width, height])
    w, h = float(x1 - x0), float(y1 - y0)
    flat: list[float | int] = []
    for x, y, v in kp:
        flat += [float(x), float(y), int(v)]
    return {"id": image_id + 1, "image_id": image_id, "category_id": DECK_CATEGORY_ID,
            "keypoints": flat, "num_keypoints": int(labelled.sum()), "bbox": [float(x0), float(y0), w, h],
            "area": w * h, "iscrowd": 0}


def is_coco_export(folder: Path) -> bool:
    """Whether ``folder`` holds a COCO export of ours (its annotation file, by our name for it)."""
    return (folder / ANNOTATIONS_NAME).is_file()


def write_coco(run: RunPaths, out: str | os.PathLike[str], *, images: ImageMode = ImageMode.SYMLINK,
               progress: Callable[[int], object] | None = None) -> CocoExport:
    """Write ``run`` as a COCO keypoints dataset into ``out`` (layout in the module docstring).

    Parameters
    ----------
    run : RunPaths
    out : path-like
        The dataset folder (created; files already there are replaced).
    images : ImageMode
        Link (default) or copy the images.
    progress : callable, optional
        Called with 1 after each image.

    Raises
    ------
    InputDataError
        Not a run, or missing images or camera files.
    """
    frames = read_export_frames(run)
    root = Path(out)
    kps = coco_keypoints(frames.points_px, frames.in_image, frames.facing)
    rel = [f"{IMAGES_DIR}/{fid:06d}{export_suffix(p)}" for fid, p in zip(frames.frame_id.tolist(),
                                                                  frames.image_path, strict=True)]
    place_images(list(frames.image_path), [root / r for r in rel], images, progress=progress)
    coco_images, annotations = [], []
    for i, fid in enumerate(frames.frame_id.tolist()):
        cam = frames.cameras[frames.camera[i]]
        coco_images.append({"id": fid, "file_name": rel[i], "width": cam.width_px,
                            "height": cam.height_px, "camera": frames.camera[i]})
        ann = _annotation(kps[i], fid, cam.width_px, cam.height_px)
        if ann is not None:
            annotations.append(ann)
    doc = {
        "info": {"description": f"deck beacons of the deckpose run {run.root.resolve()} "
                                "(pixel coordinates: COCO's, top-left pixel corner at 0, 0)",
                 "version": "1.0", "year": dt.date.today().year, "contributor": "deckpose export",
                 "date_created": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")},
        "licenses": [],
        "images": coco_images,
        "annotations": annotations,
        "categories": [deck_category(frames.layout)],
    }
    path = root / ANNOTATIONS_NAME
    with atomic_open(path, "w") as fh:
        json.dump(doc, fh)
    return CocoExport(path, len(coco_images), len(annotations))
