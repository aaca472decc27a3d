"""Read and write ROS ``camera_info`` YAML (the format ``camera_calibration`` writes)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from deckpose.atomic_io import atomic_open
from deckpose.camera import DISTORTION_MODELS, CameraModel
from deckpose.errors import CameraFileError, DeckposeError
from deckpose.typed_config import parse_yaml


def _matrix(doc: dict[str, Any], key: str, rows: int, cols: int | None, source: str) -> np.ndarray:
    node = doc.get(key)
    if not isinstance(node, dict) or "data" not in node:
        raise CameraFileError(f"{source}: field {key!r} is missing or has no 'data' list")
    try:
        data = np.asarray(node["data"], dtype=float).ravel()
    except (TypeError, ValueError) as exc:
        raise CameraFileError(f"{source}: field {key!r} has non-numeric data") from exc
    n_rows = int(node.get("rows", rows))
    n_cols = int(node.get("cols", cols if cols is not None else data.size // max(n_rows, 1)))
    if data.size != n_rows * n_cols or (cols is not None and (n_rows, n_cols) != (rows, cols)):
        raise CameraFileError(
            f"{source}: field {key!r} should be {rows}x{cols if cols else 'N'} "
            f"but has rows={n_rows}, cols={n_cols} and {data.size} values"
        )
    return data.reshape(n_rows, n_cols)


def camera_from_dict(doc: object, source: str = "camera_info") -> CameraModel:
    """Build a :class:`CameraModel` from a parsed camera_info mapping."""
    if not isinstance(doc, dict):
        raise CameraFileError(f"{source}: expected a YAML mapping with image_width, camera_matrix, ...")
    for key in ("image_width", "image_height", "camera_matrix"):
        if key not in doc:
            raise CameraFileError(f"{source}: required field {key!r} is missing")
    try:
        width, height = int(doc["image_width"]), int(doc["image_height"])
    except (TypeError, ValueError) as exc:
        raise CameraFileError(f"{source}: image_width/image_height must be integers") from exc
    K = _matrix(doc, "camera_matrix", 3, 3, source)
    model = str(doc.get("distortion_model", "plumb_bob"))
    dist = np.zeros(0)
    if "distortion_coefficients" in doc:
        dist = _matrix(doc, "distortion_coefficients", 1, None, source).ravel()
    if model not in ("plumb_bob", "rational_polynomial", "none", "") and dist.size:
        raise CameraFileError(
            f"{source}: distortion_model {model!r} is not supported; use plumb_bob or rational_polynomial"
        )
    counts = DISTORTION_MODELS.get(model)
    if counts is not None and dist.size and np.any(dist != 0) and dist.size not in counts:
        fits = [m for m, c in DISTORTION_MODELS.items() if dist.size in c]
        raise CameraFileError(
            f"{source}: distortion_model {model} takes {' or '.join(map(str, counts))} "
            f"coefficients but distortion_coefficients has {dist.size}"
            + (f"; for {dist.size} write distortion_model: {fits[0]}" if fits else "")
        )
    try:
        return CameraModel(width, height, K, dist, str(doc.get("camera_name", "")))
    except DeckposeError as exc:
        raise CameraFileError(f"{source}: {exc}") from exc


def read_camera_info(path: str | os.PathLike[str]) -> CameraModel:
    """Read a ROS camera_info YAML file.

    Raises
    ------
    CameraFileError
        If the file is missing, is not YAML, or lacks a required field.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise CameraFileError(f"cannot read camera file {p}: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise CameraFileError(
            f"{p}: not a text file (byte {exc.start} is not UTF-8); a camera_info YAML is text"
        ) from exc
    doc = parse_yaml(text, str(p), CameraFileError)
    try:
        return camera_from_dict(doc, str(p))
    except DeckposeError:
        raise
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        # a field of the wrong type (rows: three, data: a string) the checks above miss
        raise CameraFileError(
            f"{p}: a field has the wrong type ({type(exc).__name__}: {exc}); numbers must be "
            "numbers, matrices {rows, cols, data: [...]}"
        ) from exc


def camera_to_dict(camera: CameraModel) -> dict[str, Any]:
    """The camera_info mapping of a camera (rectification identity, P = [K | 0])."""
    P = np.hstack([camera.K, np.zeros((3, 1))])
    dist = camera.dist_coeffs if camera.dist_coeffs.size else np.zeros(5)
    return {
        "image_width": camera.width_px,
        "image_height": camera.height_px,
        "camera_name": camera.name or "deckpose",
        "camera_matrix": {"rows": 3, "cols": 3, "data": [float(x) for x in camera.K.ravel()]},
        "distortion_model": camera.distortion_model,
        "distortion_coefficients": {"rows": 1, "cols": int(dist.size), "data": [float(x) for x in dist]},
        "rectification_matrix": {"rows": 3, "cols": 3, "data": [float(x) for x in np.eye(3).ravel()]},
        "projection_matrix": {"rows": 3, "cols": 4, "data": [float(x) for x in P.ravel()]},
    }


def write_camera_info(camera: CameraModel, path: str | os.PathLike[str]) -> None:
    """Write a camera as ROS camera_info YAML (atomically)."""
    with atomic_open(path, "w") as fh:
        yaml.safe_dump(camera_to_dict(camera), fh, sort_keys=False)
