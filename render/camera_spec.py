"""Camera entries of a render config: a thesis preset or explicit intrinsics, validated early."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from deckpose.render.lens import MAX_SIDE_PX, raster_camera

from deckpose.camera import CameraModel, PixelForm, from_focal_angle, preset
from deckpose.errors import ConfigError
from deckpose.typed_config import coerce, from_mapping


@dataclass(frozen=True)
class CameraSpec:
    """One camera: a preset (``4mp``, ``8mp-square``...) or explicit intrinsics.

    ``size`` re-samples a preset to another resolution keeping its field of view;
    ``focal_angle_deg`` with ``size`` builds a camera from scratch; ``K`` (3x3) with
    ``size`` gives full intrinsics; ``dist_coeffs`` adds OpenCV lens distortion, of the
    model ``distortion_model`` names (ROS names; empty: the standard model of the count,
    ``equidistant``: OpenCV's fisheye, k1..k4).
    """

    preset: str | None = None
    size: tuple[int, int] | None = None
    focal_angle_deg: float | None = None
    form: str = "thesis"
    K: tuple[float, ...] | None = None
    dist_coeffs: tuple[float, ...] = ()
    name: str | None = None
    distortion_model: str = ""

    def model(self) -> CameraModel:
        """The :class:`CameraModel` this spec describes."""
        where = f"camera {self.name or self.preset or ''}".strip()
        if self.preset is not None:
            cam = preset(self.preset)
            if self.size is not None:
                cam = cam.with_size(*self.size)
            K = cam.K
            w, h = self.size if self.size is not None else (cam.width_px, cam.height_px)
        elif self.size is None:
            raise ConfigError(f"{where}: give a preset, or a size with focal_angle_deg or K")
        elif self.K is not None:
            K = np.asarray(self.K, dtype=float).reshape(3, 3)
            w, h = self.size
        elif self.focal_angle_deg is not None:
            form = coerce(PixelForm, self.form, f"{where}.form")
            K = from_focal_angle(*self.size, self.focal_angle_deg, form=form).K
            w, h = self.size
        else:
            raise ConfigError(f"{where}: needs focal_angle_deg or K besides size")
        if K[0, 1] != 0.0:
            raise ConfigError(f"{where}: the renderer needs zero skew (K[0,1] = 0)")
        return CameraModel(w, h, K, np.asarray(self.dist_coeffs, float), self.camera_name(w, h),
                           self.distortion_model)

    def camera_name(self, w: int, h: int) -> str:
        if self.name:
            return self.name
        base = self.preset or f"fa{self.focal_angle_deg or 'K'}"
        if self.distortion_model.strip().lower() == "equidistant":
            return f"{base}-{w}x{h}-fisheye"
        return f"{base}-{w}x{h}" + ("-dist" if any(self.dist_coeffs) else "")


#: Memory one rendered frame needs, bytes per pixel, for the check that refuses a frame larger
#: than the machine's memory. Measured by ``benchmarks/bench_render_memory.py`` (peak resident
#: memory above a tiny frame's): 64 MP 27 B/px by default and 36 B/px with every realism effect;
#: 8 MP 58 and 68 B/px, where fixed buffers weigh more. The frames this check is for are the
#: largest, so 48 keeps a third of a margin over the 64 MP figure.
BYTES_PER_PX = 48


def _physical_memory_bytes() -> int | None:
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def _k_matrix(value: object, where: str) -> tuple[float, ...]:
    flat = value
    if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
        flat = [x for r in value for x in r]
    k = coerce(tuple[float, ...], flat, where)
    if len(k) != 9:
        raise ConfigError(f"{where}: expected 9 numbers (3x3 row-major), got {len(k)}")
    return k


def _size(value: object, where: str) -> tuple[int, int] | None:
    if value is None:
        return None
    if not (isinstance(value, list) and len(value) == 2):
        raise ConfigError(f"{where}: expected [width_px, height_px] integers, got {value!r}")
    w, h = coerce(tuple[int, int], value, where)
    if min(w, h) < 16:
        raise ConfigError(f"{where}: each side must be at least 16 px, got {[w, h]}")
    if w > MAX_SIDE_PX or h > 64 * MAX_SIDE_PX:
        raise ConfigError(
            f"{where}: {w}x{h} px is beyond what OpenGL renders here (at most {MAX_SIDE_PX} px "
            f"wide); use a smaller size"
        )
    mem = _physical_memory_bytes()
    need = BYTES_PER_PX * w * h
    if mem is not None and need > mem:
        raise ConfigError(
            f"{where}: a {w}x{h} frame needs about {need / 2**30:.0f} GiB while it is rendered, "
            f"more than this machine's {mem / 2**30:.0f} GiB; use a smaller size"
        )
    return w, h


def _dist(value: object, where: str) -> tuple[float, ...]:
    # how many coefficients: CameraModel's rule, checked by spec.model() below
    return coerce(tuple[float, ...], value if value is not None else [], where)


def camera_spec(doc: object, where: str) -> CameraSpec:
    if isinstance(doc, str):
        doc = {"preset": doc}
    spec = from_mapping(CameraSpec, doc, where,
                        convert={"K": lambda v, w: None if v is None else _k_matrix(v, w),
                                 "size": _size, "dist_coeffs": _dist})
    if spec.preset is not None and spec.size is None:
        cam = preset(spec.preset)
        _size([cam.width_px, cam.height_px], f"{where}.preset")
    try:
        raster_camera(spec.model())  # validate now, not in a worker: the intrinsics and the raster
    except ConfigError as exc:
        if str(exc).startswith(where):
            raise
        raise ConfigError(f"{where}: {exc}") from None
    return spec
