"""A reader and checker of BOP datasets, written from the format's documentation alone.

Source: the BOP toolkit's ``docs/bop_datasets_format.md`` (github.com/thodan/bop_toolkit,
read at commit cea62d6). What it says, and what is checked here:

* ``models/models_info.json``: per object id, "the 3D bounding box and the diameter"; the
  diameter is "the largest distance between any pair of model vertices"; the toolkit's
  ``calc_model_info.py`` names the box ``min_x, min_y, min_z, size_x, size_y, size_z``.
* ``models/obj_OBJ_ID.ply``: "PLY (ascii)", "All models include vertex normals", vertex
  colour optional; the toolkit reads triangular faces only. Model units are 1 mm, and "the
  origin coincides with the center of the 3D bounding box".
* ``SPLIT/SCENE_ID/scene_camera.json``: per image id, ``cam_K`` "3x3 intrinsic camera matrix
  K (saved row-wise)" and ``depth_scale``.
* ``SPLIT/SCENE_ID/scene_gt.json``: per image id, a list of ``obj_id``, ``cam_R_m2c`` (3x3,
  row-wise), ``cam_t_m2c`` (3x1, mm), with ``s [u, v, 1]' = K [R, t] [x, y, z, 1]'`` for a
  model point.
* ``rgb/`` (or ``gray/``) images with the image id as their name (``000000.png``).
* "All coordinate systems (model, camera, world) are right-handed": so R is a rotation
  (orthonormal, determinant +1).

Nothing here imports deckpose: it is the format's reader, not the writer's mirror.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

IMAGE_FOLDERS = ("rgb", "gray")
SPLITS = ("train", "val", "test")
BOX_KEYS = ("min_x", "min_y", "min_z", "size_x", "size_y", "size_z")


@dataclass
class BopModel:
    pts_mm: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    colors: np.ndarray | None


@dataclass
class BopScene:
    path: Path
    camera: dict[int, dict]
    gt: dict[int, list[dict]]
    images: dict[int, Path] = field(default_factory=dict)


@dataclass
class BopDataset:
    models_info: dict[int, dict]
    models: dict[int, BopModel]
    scenes: dict[tuple[str, int], BopScene]


def _int_keys(doc: dict, where: str) -> dict[int, object]:
    out = {}
    for k, v in doc.items():
        assert isinstance(k, str) and k.lstrip("-").isdigit(), f"{where}: key {k!r} is not an id"
        out[int(k)] = v
    return out


def read_ply_ascii(path: Path) -> BopModel:
    """An ASCII PLY with x, y, z, nx, ny, nz (and optionally red, green, blue), triangles."""
    lines = path.read_text().splitlines()
    assert lines[0] == "ply", f"{path}: not a PLY file"
    assert lines[1] == "format ascii 1.0", f"{path}: BOP models are ASCII PLY, got {lines[1]!r}"
    end = lines.index("end_header")
    n_vert = n_face = 0
    props: list[str] = []
    section = None
    for line in lines[2:end]:
        words = line.split()
        if words[0] == "element":
            section, count = words[1], int(words[2])
            if section == "vertex":
                n_vert = count
            elif section == "face":
                n_face = count
        elif words[0] == "property" and section == "vertex":
            props.append(words[-1])
    for need in ("x", "y", "z", "nx", "ny", "nz"):
        assert need in props, f"{path}: vertex property {need} missing (BOP models have normals)"
    body = lines[end + 1:]
    assert len(body) == n_vert + n_face, f"{path}: {len(body)} data lines, header says {n_vert + n_face}"
    vals = np.array([[float(x) for x in row.split()] for row in body[:n_vert]])
    col = {p: i for i, p in enumerate(props)}
    pts = vals[:, [col["x"], col["y"], col["z"]]]
    normals = vals[:, [col["nx"], col["ny"], col["nz"]]]
    colors = vals[:, [col["red"], col["green"], col["blue"]]] if "red" in col else None
    faces = np.array([[int(x) for x in row.split()] for row in body[n_vert:]], dtype=np.int64)
    assert faces.shape == (n_face, 4) and np.all(faces[:, 0] == 3), f"{path}: faces must be triangles"
    faces = faces[:, 1:]
    assert faces.min() >= 0 and faces.max() < n_vert, f"{path}: a face indexes a missing vertex"
    return BopModel(pts, normals, faces, colors)


def _matrix(values: object, shape: tuple[int, ...], where: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    assert a.size == int(np.prod(shape)) and np.all(np.isfinite(a)), f"{where}: need {shape} numbers"
    return a.reshape(shape)


def read_bop_dataset(root: Path, *, rotation_tol: float = 1e-9) -> BopDataset:
    """Read and check a BOP dataset; an AssertionError names what breaks the format."""
    info_path = root / "models" / "models_info.json"
    assert info_path.is_file(), f"{info_path} missing"
    models_info = _int_keys(json.loads(info_path.read_text()), str(info_path))
    models = {}
    for obj_id, info in models_info.items():
        assert isinstance(info, dict)
        for k in ("diameter", *BOX_KEYS):
            assert isinstance(info.get(k), (int, float)), f"models_info {obj_id}: {k} missing"
        model = read_ply_ascii(root / "models" / f"obj_{obj_id:06d}.ply")
        lo, hi = model.pts_mm.min(0), model.pts_mm.max(0)
        box = np.array([info[k] for k in BOX_KEYS])
        np.testing.assert_allclose(box, np.concatenate([lo, hi - lo]), atol=1e-6)
        d = np.sqrt(((model.pts_mm[:, None] - model.pts_mm[None]) ** 2).sum(-1)).max()
        np.testing.assert_allclose(info["diameter"], d, rtol=1e-9)
        np.testing.assert_allclose((lo + hi) / 2, 0.0, atol=1e-6)  # origin at the box centre
        np.testing.assert_allclose(np.linalg.norm(model.normals, axis=1), 1.0, atol=1e-6)
        models[obj_id] = model
    scenes = {}
    for split in SPLITS:
        if not (root / split).is_dir():
            continue
        for scene_dir in sorted(p for p in (root / split).iterdir() if p.is_dir()):
            assert scene_dir.name.isdigit(), f"{scene_dir}: scene folders are named by id"
            camera = _int_keys(json.loads((scene_dir / "scene_camera.json").read_text()), str(scene_dir))
            gt = _int_keys(json.loads((scene_dir / "scene_gt.json").read_text()), str(scene_dir))
            assert set(gt) <= set(camera), f"{scene_dir}: ground truth for images without a camera"
            scene = BopScene(scene_dir, {}, {})
            for im_id, cam in camera.items():
                assert isinstance(cam, dict)
                K = _matrix(cam["cam_K"], (3, 3), f"{scene_dir} {im_id} cam_K")
                np.testing.assert_array_equal(K[2], [0.0, 0.0, 1.0])
                assert K[0, 0] > 0 and K[1, 1] > 0
                assert isinstance(cam["depth_scale"], (int, float)) and cam["depth_scale"] > 0
                scene.camera[im_id] = {"cam_K": K, "depth_scale": float(cam["depth_scale"])}
                found = [p for f in IMAGE_FOLDERS for p in (scene_dir / f).glob(f"{im_id:06d}.*")]
                assert len(found) == 1 and found[0].is_file(), f"{scene_dir}: image {im_id:06d} missing"
                scene.images[im_id] = found[0]
            for im_id, instances in gt.items():
                assert isinstance(instances, list) and instances
                scene.gt[im_id] = []
                for inst in instances:
                    assert inst["obj_id"] in models, f"{scene_dir} {im_id}: unknown obj_id"
                    R = _matrix(inst["cam_R_m2c"], (3, 3), f"{scene_dir} {im_id} cam_R_m2c")
                    t = _matrix(inst["cam_t_m2c"], (3, 1), f"{scene_dir} {im_id} cam_t_m2c")
                    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=rotation_tol)
                    assert abs(np.linalg.det(R) - 1.0) < rotation_tol
                    scene.gt[im_id].append({"obj_id": int(inst["obj_id"]), "R": R, "t_mm": t})
            scenes[(split, int(scene_dir.name))] = scene
    assert scenes, f"{root}: no scenes under {', '.join(SPLITS)}"
    return BopDataset(models_info, models, scenes)


def project_bop(pts_mm: np.ndarray, K: np.ndarray, R: np.ndarray, t_mm: np.ndarray) -> np.ndarray:
    """``s [u, v, 1]' = K [R, t] [x, y, z, 1]'``, (N, 2) pixels."""
    p = (K @ (R @ pts_mm.T + t_mm)).T
    return p[:, :2] / p[:, 2:3]
