"""Camera entries of a render config: a thesis preset or explicit intrinsics, validated early."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from deckpose.camera import CameraModel, PixelForm, from_focal_angle, preset
from deckpose.errors import ConfigError
from deckpose.render.config_checks import check_keys, parse_enum


@dataclass(frozen=True)
class CameraSpec:
    """One camera: a preset (``4mp``, ``8mp-square``...) or explicit intrinsics.

    ``size`` re-samples a preset to another resolution keeping its field of view;
    ``focal_angle_deg`` with ``size`` builds a camera from scratch; ``K`` (3x3) with
    ``size`` gives full intrinsics; ``dist_coeffs`` adds OpenCV lens distortion.
    """

    preset: str | None = None
    size: tuple[int, int] | None = None
    focal_angle_deg: float | None = None
    form: str = "thesis"
    K: tuple[float, ...] | None = None
    dist_coeffs: tuple[float, ...] = ()
    name: str | None = None

    def model(self) -> CameraModel:
        """The :class:`CameraModel` this spec describes."""
        where = f"camera {self.name or self.preset or ''}".strip()
        if self.preset is not None:
            cam = preset(self.preset)
            if self.size is not None:
                cam = cam.with_size(*self.size)
            K = cam.K
        elif self.size is None:
            raise ConfigError(f"{where}: give a preset, or a size with focal_angle_deg or K")
        elif self.K is not None:
            K = np.asarray(self.K, dtype=float).reshape(3, 3)
        elif self.focal_angle_deg is not None:
            form = parse_enum(PixelForm, self.form, f"{where}.form")
            K = from_focal_angle(*self.size, self.focal_angle_deg, form=form).K
        else:
            raise ConfigError(f"{where}: needs focal_angle_deg or K besides size")
        w, h = self.size if self.size is not None else (cam.width_px, cam.height_px)
        if K[0, 1] != 0.0:
            raise ConfigError(f"{where}: the renderer needs zero skew (K[0,1] = 0)")
        return CameraModel(w, h, K, np.asarray(self.dist_coeffs, float), self.camera_name(w, h))

    def camera_name(self, w: int, h: int) -> str:
        if self.name:
            return self.name
        base = self.preset or f"fa{self.focal_angle_deg or 'K'}"
        return f"{base}-{w}x{h}" + ("-dist" if any(self.dist_coeffs) else "")


def camera_spec(doc: object, where: str) -> CameraSpec:
    if isinstance(doc, str):
        doc = {"preset": doc}
    d = check_keys(doc, CameraSpec, where)
    if "size" in d and d["size"] is not None:
        size = d["size"]
        if not (isinstance(size, (list, tuple)) and len(size) == 2 and all(isinstance(s, int) for s in size)):
            raise ConfigError(f"{where}.size: expected [width_px, height_px] integers, got {size!r}")
        if min(size) < 16:
            raise ConfigError(f"{where}.size: each side must be at least 16 px, got {size}")
        d["size"] = (int(size[0]), int(size[1]))
    if d.get("K") is not None:
        d["K"] = tuple(float(x) for x in np.ravel(d["K"]))
        if len(d["K"]) != 9:
            raise ConfigError(f"{where}.K: expected 9 numbers (3x3 row-major)")
    d["dist_coeffs"] = tuple(float(x) for x in d.get("dist_coeffs") or ())
    spec = CameraSpec(**d)
    spec.model()  # validate now, not in a worker
    return spec
