"""Read and write camera files: ROS ``camera_info`` YAML, and read two other forms.

Read:

* ROS ``camera_info`` YAML, as ``camera_calibration`` writes it (``image_width``,
  ``camera_matrix: {rows, cols, data}``, ``distortion_model``, ...);
* a ``CameraInfo`` message as ``ros2 topic echo`` (``width``, ``k``, ``d``) or ROS 1's
  ``rostopic echo`` (``K``, ``D``) print it, the first message of the stream;
* OpenCV ``FileStorage`` YAML (``%YAML:1.0`` or ``%YAML 1.2``, ``!!opencv-matrix``), as
  OpenCV's calibration sample writes it, read with :class:`cv2.FileStorage`. Such a file
  names no model: four coefficients are plumb_bob's k1, k2, p1, p2 unless the file says
  ``fisheye_model: 1`` (the calibration tutorial's fisheye output) or carries a
  ``distortion_model`` string.

Models: ``plumb_bob``, ``rational_polynomial``, ``equidistant`` (OpenCV's fisheye, also read
as ``kannala_brandt``) and ``none``.

Written: ROS ``camera_info`` YAML.
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from deckpose.atomic_io import atomic_open
from deckpose.camera import DISTORTION_MODELS, CameraModel
from deckpose.errors import CameraFileError, DeckposeError
from deckpose.typed_config import parse_yaml

log = logging.getLogger(__name__)

#: OpenCV FileStorage names of the camera matrix and the distortion coefficients, in the
#: order they are looked for (the calibration sample's first, then common alternatives).
OPENCV_MATRIX_KEYS = ("camera_matrix", "cameraMatrix", "K", "M1")
OPENCV_DISTORTION_KEYS = ("distortion_coefficients", "distCoeffs", "dist_coeffs", "D", "D1")
#: Other names of a distortion model, read as the ROS name (Foxglove's CameraCalibration
#: calls OpenCV's fisheye model ``kannala_brandt``).
MODEL_ALIASES = {"kannala_brandt": "equidistant"}


def _matrix(doc: dict[str, Any], key: str, rows: int, cols: int | None, source: str) -> np.ndarray:
    node = doc.get(key)
    if not isinstance(node, dict) or "data" not in node:
        raise CameraFileError(f"{source}: field {key!r} is missing or has no 'data' list")
    try:
        data = np.asarray(node["data"], dtype=float).ravel()
    except (TypeError, ValueError) as exc:
        raise CameraFileError(f"{source}: field {key!r} has non-numeric data") from exc
    try:
        n_rows = int(node.get("rows", rows))
        n_cols = int(node.get("cols", cols if cols is not None else data.size // max(n_rows, 1)))
    except (TypeError, ValueError, OverflowError) as exc:  # (a list, a word, inf: 1e400 in YAML)
        raise CameraFileError(f"{source}: field {key!r} has rows or cols that are not whole numbers "
                              f"(rows={node.get('rows')!r}, cols={node.get('cols')!r})") from exc
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
    sizes = []
    for key in ("image_width", "image_height"):
        v = doc[key]
        # an integer, as camera_calibration writes it; not a string ("640"), a bool, or 640.5
        if isinstance(v, bool) or not (isinstance(v, int) or (isinstance(v, float) and v.is_integer())):
            raise CameraFileError(f"{source}: {key} must be an integer number of pixels, got {v!r}")
        sizes.append(int(v))
    width, height = sizes
    K = _matrix(doc, "camera_matrix", 3, 3, source)
    raw_model = doc.get("distortion_model", "plumb_bob")
    model = str(raw_model if raw_model is not None else "").strip().lower()
    model = MODEL_ALIASES.get(model, model)
    dist = np.zeros(0)
    if "distortion_coefficients" in doc:
        dist = _matrix(doc, "distortion_coefficients", 1, None, source).ravel()
    if model not in DISTORTION_MODELS:
        if dist.size:
            raise CameraFileError(
                f"{source}: distortion_model {model!r} is not supported; use plumb_bob, "
                "rational_polynomial or equidistant (OpenCV's fisheye)")
        model = "none"
    if model == "equidistant":
        if dist.size != 4:
            raise CameraFileError(
                f"{source}: distortion_model equidistant takes 4 coefficients (k1..k4 of OpenCV's "
                f"fisheye model) but distortion_coefficients has {dist.size}" + _count_hint(dist.size))
    elif not np.any(dist != 0):
        dist = np.zeros(0)  # zeros of any count: no distortion
    elif model == "plumb_bob" and dist.size == 4:
        # OpenCV reads four as k1, k2, p1, p2 (k3 = 0), a valid plumb_bob; but a fisheye
        # calibration's k1..k4 mislabelled plumb_bob has four too, and would be misread.
        log.warning("%s: distortion_model plumb_bob with 4 coefficients: read as k1, k2, p1, p2 "
                    "(k3 = 0); if they are k1..k4 of a fisheye calibration, write "
                    "distortion_model: equidistant (in an OpenCV FileStorage file: fisheye_model: 1)",
                    source)
    elif dist.size not in DISTORTION_MODELS[model]:
        counts = DISTORTION_MODELS[model]
        raise CameraFileError(
            f"{source}: distortion_model {model} takes {' or '.join(map(str, counts))} "
            f"coefficients but distortion_coefficients has {dist.size}" + _count_hint(dist.size))
    try:
        return CameraModel(width, height, K, dist, str(doc.get("camera_name", "")), model)
    except DeckposeError as exc:
        raise CameraFileError(f"{source}: {exc}") from exc


def _count_hint(n: int) -> str:
    """The fix for a coefficient count the named model does not take."""
    if n == 4:
        return ("; for 4 write distortion_model: equidistant (a fisheye's k1..k4) or plumb_bob "
                "(k1, k2, p1, p2)")
    fits = [m for m, c in DISTORTION_MODELS.items() if n in c and m != "none"]
    return f"; for {n} write distortion_model: {fits[0]}" if fits else ""


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
    if _is_opencv_storage(text):
        doc = _from_opencv_storage(text, str(p))
    else:
        doc = parse_yaml(_first_document(text), str(p), CameraFileError)
        doc = _from_message(doc)
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


def _first_document(text: str) -> str:
    """The first YAML document of a stream (``ros2 topic echo`` ends each message with ``---``)."""
    docs = [d for d in re.split(r"^---[ \t]*$", text, flags=re.MULTILINE) if d.strip()]
    return docs[0] if docs else text


def _from_message(doc: object) -> object:
    """A ``CameraInfo`` message (ROS 2 ``k, d``; ROS 1 ``K, D``) as a camera_info mapping; others as given."""
    if not isinstance(doc, dict) or "width" not in doc or not ({"k", "K"} & doc.keys()):
        return doc
    k = doc.get("k", doc.get("K"))
    d = doc.get("d", doc.get("D")) or []
    header = doc.get("header")
    name = header.get("frame_id", "") if isinstance(header, dict) else ""
    return {
        "image_width": doc.get("width"),
        "image_height": doc.get("height"),
        "camera_name": name,
        "camera_matrix": {"rows": 3, "cols": 3, "data": k},
        "distortion_model": doc.get("distortion_model") or ("plumb_bob" if d else "none"),
        "distortion_coefficients": {"rows": 1, "cols": len(d) if isinstance(d, list) else 0, "data": d},
    }


def _model_for_count(n: int) -> str:
    """The standard model of ``n`` coefficients (plumb_bob for any other count, which is then refused).

    Never ``equidistant``: a fisheye's four coefficients are told apart only by a model name.
    """
    return "rational_polynomial" if n in DISTORTION_MODELS["rational_polynomial"] else "plumb_bob"


def _opencv_model(fs: Any, n: int) -> str:
    """The model of a FileStorage file: its ``distortion_model`` string, ``fisheye_model: 1`` (as
    OpenCV's calibration tutorial writes a fisheye calibration), or the count's standard model."""
    named = fs.getNode("distortion_model")
    if not named.empty() and named.isString():
        return str(named.string())
    fisheye = fs.getNode("fisheye_model")
    if not fisheye.empty() and fisheye.isInt() and int(fisheye.real()) != 0:
        return "equidistant"
    return _model_for_count(n)


def _is_opencv_storage(text: str) -> bool:
    return text.lstrip().startswith("%YAML") or "!!opencv-matrix" in text


def _from_opencv_storage(text: str, source: str) -> dict[str, Any]:
    """An OpenCV FileStorage YAML as a camera_info mapping (read by :class:`cv2.FileStorage`)."""
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except cv2.error as exc:
        msg = " ".join(str(exc).split())
        raise CameraFileError(f"{source}: not a readable OpenCV FileStorage YAML ({msg[-200:]})") from None
    try:
        def node(keys: tuple[str, ...]) -> Any:
            return next((fs.getNode(k) for k in keys if not fs.getNode(k).empty()), None)

        K, dist = node(OPENCV_MATRIX_KEYS), node(OPENCV_DISTORTION_KEYS)
        if K is None or K.mat() is None:
            raise CameraFileError(f"{source}: an OpenCV FileStorage file, but it has no camera matrix "
                                  f"(looked for {', '.join(OPENCV_MATRIX_KEYS)})")
        size = [fs.getNode(k) for k in ("image_width", "image_height")]
        if any(n.empty() for n in size):
            raise CameraFileError(f"{source}: an OpenCV FileStorage file, but image_width or image_height "
                                  "is missing (the frame size in pixels)")
        K_mat = np.asarray(K.mat(), dtype=float)
        d = np.zeros(0) if dist is None or dist.mat() is None else np.asarray(dist.mat(), dtype=float).ravel()
        return {
            "image_width": int(size[0].real()),
            "image_height": int(size[1].real()),
            "camera_matrix": {"rows": int(K_mat.shape[0]), "cols": int(K_mat.shape[1]),
                              "data": [float(x) for x in K_mat.ravel()]},
            "distortion_model": _opencv_model(fs, int(d.size)),
            "distortion_coefficients": {"rows": 1, "cols": int(d.size), "data": [float(x) for x in d]},
        }
    finally:
        fs.release()


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
