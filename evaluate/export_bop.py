"""A run as a BOP dataset (scene-wise format of the BOP toolkit's ``docs/bop_datasets_format.md``).

Written under the output folder ``DIR``::

    DIR/models/obj_000001.ply          the deck (deck_model.py), millimetres, origin at its centre
    DIR/models/models_info.json        {"1": {diameter, min_x, min_y, min_z, size_x, size_y, size_z}}, mm
    DIR/test/SSSSSS/scene_camera.json  {im_id: {cam_K (3x3 row-major, px), depth_scale}}
    DIR/test/SSSSSS/scene_gt.json      {im_id: [{obj_id: 1, cam_R_m2c (row-major), cam_t_m2c (mm)}]}
    DIR/test/SSSSSS/rgb/IIIIII.png     the frame's image (``gray/`` for a mono sensor), linked or copied
    DIR/test_targets_bop19.json        [{scene_id, im_id, obj_id: 1, inst_count: 1}]
    DIR/dataset_info.md                where it came from and its conventions

One scene per camera (scene ids from 1, cameras in name order), one image per frame with
``im_id`` = the run's ``frame_id``, one object (the deck, ``obj_id`` 1) in every image:
``cam_R_m2c``, ``cam_t_m2c`` is ``T_cam_from_deck``, so ``s [u, v, 1] = K (R p + t)`` puts a
model point ``p`` (mm) at its pixel, OpenCV's pixel convention (pixel centres at integers),
as BOP's camera frame is OpenCV's. BOP's camera is a pinhole: it has no lens distortion, so a
run whose camera has distortion is refused (its pixels are not ``K (R p + t)``). No depth
images, masks or ``scene_gt_info.json`` are written (deckpose renders no depth);
``depth_scale`` is 1.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from deckpose.evaluate.deck_model import DeckMesh, deck_mesh, write_ply
from deckpose.evaluate.export_frames import ExportFrames, deck_half_size_m, read_export_frames
from deckpose.evaluate.export_images import ImageMode, export_suffix, place_images
from numpy.typing import ArrayLike

from deckpose.atomic_io import atomic_open
from deckpose.errors import InputDataError, check_shape
from deckpose.run_folder import RunPaths

__all__ = [
    "DECK_OBJ_ID",
    "BopExport",
    "bop_camera_entry",
    "bop_gt_entries",
    "is_bop_export",
    "models_info",
    "write_bop",
]


#: The notes every BOP export of ours writes at its top level, and their first line: how an
#: earlier export is told (``test_targets_bop19.json`` is in every BOP dataset, ours or not).
INFO_NAME = "dataset_info.md"
INFO_TITLE = "# deck (deckpose export)"

#: The deck's object id.
DECK_OBJ_ID = 1
#: BOP's unit of length, per metre.
MM_PER_M = 1000.0
#: The split the scenes go into (its ground truth is public, as a validation split's).
SPLIT = "test"


@dataclass(frozen=True)
class BopExport:
    """What :func:`write_bop` wrote.

    Attributes
    ----------
    root : Path
        The dataset folder.
    scenes : dict of int to str
        Scene id -> camera name.
    n_images : int
    model : Path
        The deck's PLY file.
    """

    root: Path
    scenes: dict[int, str]
    n_images: int
    model: Path


def bop_camera_entry(K: ArrayLike) -> dict[str, Any]:
    """One image's ``scene_camera.json`` entry: ``cam_K`` (row-major, pixels) and ``depth_scale`` 1."""
    K = np.asarray(K, float)
    check_shape("K", K, (3, 3))
    return {"cam_K": [float(x) for x in K.ravel()], "depth_scale": 1.0}


def bop_gt_entries(T_cam_from_deck: ArrayLike) -> list[dict[str, Any]]:
    """``scene_gt.json`` entries of a batch of frames, the deck being object 1.

    Parameters
    ----------
    T_cam_from_deck : (F, 4, 4) array of float, metres

    Returns
    -------
    list of F dict
        ``{"obj_id": 1, "cam_R_m2c": 9 floats row-major, "cam_t_m2c": 3 floats, mm}``.
    """
    T = np.asarray(T_cam_from_deck, float)
    check_shape("T_cam_from_deck", T, (None, 4, 4))
    return [{"obj_id": DECK_OBJ_ID, "cam_R_m2c": [float(x) for x in t[:3, :3].ravel()],
             "cam_t_m2c": [float(x) for x in t[:3, 3] * MM_PER_M]} for t in T]


def models_info(mesh: DeckMesh) -> dict[str, float]:
    """A model's ``models_info.json`` entry, mm: the 3-D bounding box and the diameter (the
    largest distance between two vertices, as BOP's ``calc_model_info.py`` computes it)."""
    from scipy.spatial.distance import pdist

    v = np.asarray(mesh.vertices_m, float) * MM_PER_M
    lo, hi = v.min(0), v.max(0)
    return {"diameter": float(pdist(v).max()),
            "min_x": float(lo[0]), "min_y": float(lo[1]), "min_z": float(lo[2]),
            "size_x": float(hi[0] - lo[0]), "size_y": float(hi[1] - lo[1]), "size_z": float(hi[2] - lo[2])}


def _bop_json(content: dict[int, Any] | list[Any]) -> str:
    """JSON laid out as the BOP toolkit's ``save_json`` writes it: one entry a line, keys in order."""
    if isinstance(content, dict):
        items = [f'  "{k}": {json.dumps(v, sort_keys=True)}' for k, v in sorted(content.items())]
        return "{\n" + ",\n".join(items) + "\n}\n"
    return "[\n" + ",\n".join(f"  {json.dumps(v, sort_keys=True)}" for v in content) + "\n]\n"


def _write_json(path: Path, content: dict[int, Any] | list[Any]) -> None:
    with atomic_open(path, "w") as fh:
        fh.write(_bop_json(content))


def _check_pinhole(frames: ExportFrames) -> None:
    for name in sorted(set(frames.camera)):
        cam = frames.cameras[name]
        if cam.has_distortion:
            raise InputDataError(
                f"camera {name} has lens distortion ({cam.distortion_model}, "
                f"{np.count_nonzero(cam.dist_coeffs)} non-zero coefficients), which the BOP format "
                "cannot hold (its camera is a pinhole K): the poses would not reproduce the image; "
                "export --format coco (keypoints in the distorted image) or render without distortion")


def _info_text(run: RunPaths, frames: ExportFrames, scenes: dict[int, str], images: ImageMode,
               folder: str) -> str:
    link = "symbolic links into the run" if images is ImageMode.SYMLINK else "copies"
    lines = [
        INFO_TITLE, "",
        (f"BOP dataset of the deckpose run `{run.root.resolve()}` ({frames.n_frames} frames), "
         "written by `deckpose export --format bop`."), "",
        ("* object 1: the ship deck (`models/obj_000001.ply`, mm, deck frame: x bow, y port, z up, "
         f"origin at the deck centre); vertex i < {frames.layout.n_beacons} is beacon id i's centre."),
        (f"* split `{SPLIT}`, one scene per camera; `im_id` = the run's `frame_id`; images in "
         f"`{folder}/` ({link})."),
        ("* pixels: OpenCV's convention (pixel centres at integer coordinates), as `cam_K` is; "
         "no lens distortion (a distorted camera is refused)."),
        "* poses: `cam_R_m2c`, `cam_t_m2c` (mm) = T_cam_from_deck at mid-exposure.",
        "* not written: depth, masks, `scene_gt_info.json` (depth_scale is 1, no depth images).",
        "", "| scene | camera | width | height |", "|---|---|---|---|"]
    for sid, name in scenes.items():
        cam = frames.cameras[name]
        lines.append(f"| {sid:06d} | {name} | {cam.width_px} | {cam.height_px} |")
    return "\n".join(lines) + "\n"


def is_bop_export(folder: Path) -> bool:
    """Whether ``folder`` holds a BOP export of ours (its notes' first line says so)."""
    try:
        with open(folder / INFO_NAME, encoding="utf-8") as fh:
            return fh.readline().rstrip("\n") == INFO_TITLE
    except (OSError, UnicodeDecodeError):
        return False


def write_bop(run: RunPaths, out: str | os.PathLike[str], *, images: ImageMode = ImageMode.SYMLINK,
              progress: Callable[[int], object] | None = None) -> BopExport:
    """Write ``run`` as a BOP dataset into ``out`` (layout in the module docstring).

    Parameters
    ----------
    run : RunPaths
        A rendered run (frames, beacons, cameras, images).
    out : path-like
        The dataset folder (created; files already there are replaced).
    images : ImageMode
        Link (default) or copy the images.
    progress : callable, optional
        Called with 1 after each image.

    Raises
    ------
    InputDataError
        Not a run, missing images or camera files, or a camera with lens distortion.
    """
    frames = read_export_frames(run)
    _check_pinhole(frames)
    root = Path(out)
    channels = int(frames.manifest.get("sensor_channels", 3))
    folder = "gray" if channels == 1 else "rgb"
    names = sorted(set(frames.camera))
    scenes = {i + 1: n for i, n in enumerate(names)}
    scene_of = {n: i for i, n in scenes.items()}
    gt = bop_gt_entries(frames.T_cam_from_deck)
    sources: list[Path] = []
    targets: list[Path] = []
    scene_camera: dict[int, dict[int, Any]] = {s: {} for s in scenes}
    scene_gt: dict[int, dict[int, Any]] = {s: {} for s in scenes}
    for i, fid in enumerate(frames.frame_id.tolist()):
        sid = scene_of[frames.camera[i]]
        scene_camera[sid][fid] = bop_camera_entry(frames.cameras[frames.camera[i]].K)
        scene_gt[sid][fid] = [gt[i]]
        src = frames.image_path[i]
        sources.append(src)
        targets.append(root / SPLIT / f"{sid:06d}" / folder / f"{fid:06d}{export_suffix(src)}")
    place_images(sources, targets, images, progress=progress)
    mesh = deck_mesh(frames.layout, deck_half_size_m(frames.manifest, frames.layout))
    model = root / "models" / f"obj_{DECK_OBJ_ID:06d}.ply"
    write_ply(model, mesh, scale=MM_PER_M,
              comments=(f"deckpose deck model, mm; vertex i < {mesh.n_beacons} is beacon id i",))
    _write_json(root / "models" / "models_info.json", {DECK_OBJ_ID: models_info(mesh)})
    for sid in scenes:
        _write_json(root / SPLIT / f"{sid:06d}" / "scene_camera.json", scene_camera[sid])
        _write_json(root / SPLIT / f"{sid:06d}" / "scene_gt.json", scene_gt[sid])
    targets_list = [{"im_id": fid, "inst_count": 1, "obj_id": DECK_OBJ_ID, "scene_id": scene_of[c]}
                    for fid, c in zip(frames.frame_id.tolist(), frames.camera, strict=True)]
    _write_json(root / "test_targets_bop19.json", targets_list)
    with atomic_open(root / INFO_NAME, "w") as fh:
        fh.write(_info_text(run, frames, scenes, images, folder))
    return BopExport(root, scenes, frames.n_frames, model)
