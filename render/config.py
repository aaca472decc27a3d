"""Render configuration: YAML parsed once into frozen, validated dataclasses.

Every section rejects unknown keys and impossible values with a
:class:`~deckpose.errors.ConfigError` that says what is wrong and how to fix it,
before any frame is rendered. Angles are degrees in the YAML and radians inside.

A config looks like ``configs/smoke.yaml``::

    seed: 7
    backend: egl                 # egl | osmesa
    cameras: [{preset: 4mp, size: [640, 480]}]
    heights_m: [20, 40]
    lighting: [night, day]
    motion: {source: fixed, attitudes_deg: [[0, 0, 0], [3, -2, 10]]}
    sensor: {bit_depth: 8, read_noise_e: 3}
    scene: {shading: flat}
    layout: {n_ring: 12, radius_m: 10}
"""

from __future__ import annotations

import enum
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import yaml

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout, layout_from_dict, layout_to_dict
from deckpose.render.camera_spec import CameraSpec, camera_spec
from deckpose.render.config_checks import check_keys, parse_enum


class Backend(enum.Enum):
    """Headless OpenGL platform (``PYOPENGL_PLATFORM``)."""

    EGL = "egl"
    OSMESA = "osmesa"


class Lighting(enum.Enum):
    """Lighting preset; see :mod:`deckpose.render.scene` for what each sets."""

    NIGHT = "night"
    DUSK = "dusk"
    DAY = "day"


class Shading(enum.Enum):
    """``flat``: textures times the preset's light level (fast); ``pbr``: lit, with sun glints."""

    FLAT = "flat"
    PBR = "pbr"


class MotionSource(enum.Enum):
    FIXED = "fixed"
    FILE = "file"
    THESIS = "thesis"
    SEA_STATE = "sea_state"


#: The thesis motion series shipped with the project (THESIS-convention angles).


def _positive(value: object, where: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ConfigError(f"{where}: must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


@dataclass(frozen=True)
class MotionSpec:
    """Where the ship poses come from.

    * ``fixed``: ``attitudes_deg`` = list of ZYX ``[roll, pitch, yaw]`` (degrees),
      optionally ``[roll, pitch, yaw, heave_m, surge_m, sway_m]``; ``dt_s`` apart.
    * ``file``: a motion table read by :func:`deckpose.motion.read_series` (``path``).
    * ``thesis``: the thesis series (THESIS-convention angles; heave increases the
      camera distance, as in the thesis).
    * ``sea_state``: :func:`deckpose.motion.irregular.sea_state_series` with ``params``.

    ``start``, ``every`` and ``max_samples`` pick samples from a series;
    ``exposure_s`` > 0 enables motion blur (series sources only).
    """

    source: MotionSource = MotionSource.FIXED
    attitudes_deg: tuple[tuple[float, ...], ...] = ((0.0, 0.0, 0.0),)
    dt_s: float = 0.1
    path: str | None = None
    angles: str = "deg"
    params: tuple[tuple[str, Any], ...] = ()
    start: int = 0
    every: int = 1
    max_samples: int | None = None
    exposure_s: float = 0.0
    blur_steps: int = 7


def _motion_spec(doc: object) -> MotionSpec:
    d = check_keys(doc, MotionSpec, "motion")
    if "source" in d:
        d["source"] = parse_enum(MotionSource, d["source"], "motion.source")
    if "attitudes_deg" in d:
        att = d["attitudes_deg"]
        if not isinstance(att, list) or not att or not all(
            isinstance(a, list) and len(a) in (3, 6) for a in att
        ):
            raise ConfigError("motion.attitudes_deg: expected a non-empty list of [roll, pitch, yaw] "
                              "or [roll, pitch, yaw, heave_m, surge_m, sway_m] (degrees, metres)")
        d["attitudes_deg"] = tuple(tuple(float(x) for x in a) for a in att)
    if "params" in d:
        if not isinstance(d["params"], dict):
            raise ConfigError("motion.params: expected a mapping of keyword arguments")
        d["params"] = tuple(sorted(d["params"].items()))
    for key in ("start", "every", "blur_steps"):
        if key in d and (not isinstance(d[key], int) or d[key] < (0 if key == "start" else 1)):
            raise ConfigError(f"motion.{key}: expected an integer >= {0 if key == 'start' else 1}")
    if d.get("max_samples") is not None and (not isinstance(d["max_samples"], int) or d["max_samples"] < 1):
        raise ConfigError("motion.max_samples: expected a positive integer or null")
    if "dt_s" in d:
        d["dt_s"] = _positive(d["dt_s"], "motion.dt_s")
    if "exposure_s" in d:
        d["exposure_s"] = _positive(d["exposure_s"], "motion.exposure_s", allow_zero=True)
    spec = MotionSpec(**d)
    if spec.source is MotionSource.FILE and not spec.path:
        raise ConfigError("motion.source 'file' needs motion.path (a .csv or .parquet motion table)")
    if spec.angles not in ("deg", "rad"):
        raise ConfigError(f"motion.angles: 'deg' or 'rad', got {spec.angles!r}")
    return spec


@dataclass(frozen=True)
class SensorSpec:
    """Sensor model applied after rendering (see :mod:`deckpose.render.sensor`).

    ``exposure`` scales scene radiance (1 = the raster's white fills the well);
    ``full_well_e`` electrons at saturation; ``read_noise_e`` electrons RMS;
    ``bit_depth`` 8, 12 or 16 (12 is stored in 16-bit PNG, values 0..4095);
    ``color`` ``rgb`` or ``mono``; ``noise: false`` gives the noise-free image.
    """

    bit_depth: int = 8
    exposure: float = 1.0
    full_well_e: float = 20000.0
    read_noise_e: float = 5.0
    noise: bool = True
    color: str = "rgb"
    psf_sigma_px: float = 0.8
    beacon_peak: float = 6.0
    halo_fraction: float = 0.05
    halo_scale: float = 4.0


def _sensor_spec(doc: object) -> SensorSpec:
    d = check_keys(doc, SensorSpec, "sensor")
    spec = SensorSpec(**d)
    if spec.bit_depth not in (8, 12, 16):
        raise ConfigError(f"sensor.bit_depth: 8, 12 or 16, got {spec.bit_depth!r}")
    if spec.color not in ("rgb", "mono"):
        raise ConfigError(f"sensor.color: 'rgb' or 'mono', got {spec.color!r}")
    for key in ("exposure", "full_well_e", "psf_sigma_px", "beacon_peak", "halo_scale"):
        _positive(getattr(spec, key), f"sensor.{key}")
    for key in ("read_noise_e", "halo_fraction"):
        _positive(getattr(spec, key), f"sensor.{key}", allow_zero=True)
    if spec.psf_sigma_px < 0.5:
        raise ConfigError("sensor.psf_sigma_px: must be >= 0.5 px so beacon centroids are not aliased")
    return spec


@dataclass(frozen=True)
class SceneSpec:
    """Deck plate and sea. ``deck_half_size_m`` must exceed the beacon ring radius."""

    shading: Shading = Shading.FLAT
    deck_half_size_m: float | None = None
    freeboard_m: float = 6.0
    sea_half_size_m: float = 2000.0
    sea_drift_m_per_s: float = 0.8
    texture_px: int = 2048


def _scene_spec(doc: object) -> SceneSpec:
    d = check_keys(doc, SceneSpec, "scene")
    if "shading" in d:
        d["shading"] = parse_enum(Shading, d["shading"], "scene.shading")
    spec = SceneSpec(**d)
    _positive(spec.freeboard_m, "scene.freeboard_m")
    _positive(spec.sea_half_size_m, "scene.sea_half_size_m")
    if spec.deck_half_size_m is not None:
        _positive(spec.deck_half_size_m, "scene.deck_half_size_m")
    if not isinstance(spec.texture_px, int) or not 64 <= spec.texture_px <= 8192:
        raise ConfigError("scene.texture_px: an integer in 64..8192")
    return spec


@dataclass(frozen=True)
class RenderConfig:
    """A whole render job: every frame is cameras x heights x lighting x motion samples."""

    cameras: tuple[CameraSpec, ...]
    heights_m: tuple[float, ...]
    lighting: tuple[Lighting, ...] = (Lighting.NIGHT,)
    motion: MotionSpec = MotionSpec()
    sensor: SensorSpec = SensorSpec()
    scene: SceneSpec = SceneSpec()
    layout: DeckLayout = DeckLayout()
    seed: int = 0
    backend: Backend = Backend.EGL
    name: str = "dataset"

    def deck_half_size_m(self) -> float:
        """Half the side of the square deck plate, metres."""
        if self.scene.deck_half_size_m is not None:
            return self.scene.deck_half_size_m
        return 1.4 * self.layout.radius_m

    def cameras_by_name(self) -> dict[str, CameraModel]:
        models = [c.model() for c in self.cameras]
        return {m.name: m for m in models}


_TOP = {f.name for f in fields(RenderConfig)}


def config_from_dict(doc: object, source: str = "config") -> RenderConfig:
    """Validate a parsed YAML mapping into a :class:`RenderConfig`."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a YAML mapping at the top level")
    unknown = set(doc) - _TOP
    if unknown:
        raise ConfigError(f"{source}: unknown key(s) {sorted(unknown)}; valid keys are {sorted(_TOP)}")
    cams = doc.get("cameras")
    if not isinstance(cams, list) or not cams:
        raise ConfigError(f"{source}: 'cameras' must be a non-empty list (e.g. [{{preset: 8mp}}])")
    cameras = tuple(camera_spec(c, f"cameras[{i}]") for i, c in enumerate(cams))
    names = [c.model().name for c in cameras]
    if len(set(names)) != len(names):
        raise ConfigError(f"{source}: camera names must be unique, got {names}; set 'name:' per camera")
    heights = doc.get("heights_m")
    if not isinstance(heights, list) or not heights:
        raise ConfigError(f"{source}: 'heights_m' must be a non-empty list of camera heights, metres")
    heights_m = tuple(_positive(h, "heights_m") for h in heights)
    layout = doc.get("layout")
    if isinstance(layout, dict) and layout.get("n_ring") == 0:
        raise ConfigError(f"{source}: layout.n_ring is 0 - a deck needs beacons (at least 3)")
    layout_obj = layout_from_dict(layout, f"{source}: layout")
    light = doc.get("lighting", ["night"])
    light = [light] if isinstance(light, str) else light
    if not isinstance(light, list) or not light:
        raise ConfigError(f"{source}: 'lighting' must be a non-empty list of {[e.value for e in Lighting]}")
    seed = doc.get("seed", 0)
    if not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"{source}: seed must be a non-negative integer, got {seed!r}")
    cfg = RenderConfig(
        cameras=cameras,
        heights_m=heights_m,
        lighting=tuple(parse_enum(Lighting, x, "lighting") for x in light),
        motion=_motion_spec(doc.get("motion")),
        sensor=_sensor_spec(doc.get("sensor")),
        scene=_scene_spec(doc.get("scene")),
        layout=layout_obj,
        seed=seed,
        backend=parse_enum(Backend, doc.get("backend", "egl"), "backend"),
        name=str(doc.get("name", "dataset")),
    )
    half = cfg.deck_half_size_m()
    if half <= cfg.layout.radius_m + cfg.layout.beacon_radius_m:
        raise ConfigError(f"scene.deck_half_size_m={half} must exceed the ring radius "
                          f"{cfg.layout.radius_m} so the beacons sit on the deck")
    return cfg


#: The embedded default job (the same as ``configs/smoke.yaml``): two small resolutions x two
#: heights x night/day x three attitudes = 24 frames, seconds on two cores.
DEFAULT_CONFIG: dict[str, Any] = {
    "name": "smoke",
    "seed": 7,
    "backend": "egl",
    "cameras": [{"preset": "4mp", "size": [640, 480]}, {"preset": "8mp", "size": [960, 540]}],
    "heights_m": [30, 50],
    "lighting": ["night", "day"],
    "motion": {"source": "fixed",
               "attitudes_deg": [[0, 0, 0], [4.5, 2.1, 0], [-3.0, 5.0, 15.0, 1.0, 0.0, 0.0]]},
    "sensor": {"bit_depth": 8, "read_noise_e": 5},
    "scene": {"shading": "flat", "texture_px": 1024},
    "layout": {"n_ring": 12, "radius_m": 10.0, "has_centre": True},
}


def default_config() -> RenderConfig:
    """The embedded default config (no file needed)."""
    return config_from_dict(DEFAULT_CONFIG, "default config")


def load_config(path: str | os.PathLike[str]) -> RenderConfig:
    """Read and validate a render config YAML file."""
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read render config {p}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p}: not valid YAML ({exc})") from exc
    return config_from_dict(doc, str(p))


def _plain(x: Any) -> Any:
    if isinstance(x, enum.Enum):
        return x.value
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


def config_to_dict(cfg: RenderConfig) -> dict[str, Any]:
    """The resolved config as plain YAML/JSON data (``config_from_dict`` reads it back)."""
    d = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
    out: dict[str, Any] = {}
    for key, val in d.items():
        if key == "layout":
            out[key] = layout_to_dict(val)
        elif key == "cameras":
            out[key] = [{k: _plain(v) for k, v in asdict(c).items() if v is not None} for c in val]
        elif hasattr(val, "__dataclass_fields__"):
            sub = {k: _plain(v) for k, v in asdict(val).items()}
            if key == "motion":
                sub["params"] = dict(val.params)
            out[key] = sub
        else:
            out[key] = _plain(val)
    return out
