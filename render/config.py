"""Render configuration: YAML parsed once into frozen, validated dataclasses.

This module holds the whole job (:class:`RenderConfig`), its loaders and the embedded
defaults; each section's record and parser has its own module: ``motion``
(:mod:`~deckpose.render.motion_config`), ``sensor`` (:mod:`~deckpose.render.sensor_config`),
``scene`` and ``lighting`` (:mod:`~deckpose.render.scene_config`), ``leds``
(:mod:`~deckpose.render.leds_config`), ``occlusion`` (:mod:`~deckpose.render.occlusion_config`),
``ship_lights`` (:mod:`~deckpose.render.ship_lights_config`), ``shutter``
(:mod:`~deckpose.render.shutter_config`) and ``optics`` (:mod:`~deckpose.render.optics_config`).

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
import os
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from deckpose.render.approach import ApproachSpec, approach_spec
from deckpose.render.camera_spec import CameraSpec, camera_spec
from deckpose.render.leds_config import KOSCHMIEDER, EmitterShape, LedModel, LedSpec, led_spec
from deckpose.render.motion_config import MotionSource, MotionSpec, motion_spec
from deckpose.render.occlusion_config import OcclusionSpec, occlusion_spec
from deckpose.render.optics_config import OpticsSpec, optics_spec
from deckpose.render.scene_config import (
    ANTIALIAS_SAMPLES,
    Lighting,
    SceneSpec,
    SeaSpec,
    Shading,
    ShipModelSpec,
    scene_spec,
)
from deckpose.render.sensor_config import AutoExposureSpec, BayerPattern, SensorSpec, sensor_spec
from deckpose.render.ship_lights_config import ShipLightsSpec, ship_lights_spec
from deckpose.render.shutter_config import Readout, ShutterSpec, shutter_spec
from deckpose.render.texture_size import deck_texture_px

from deckpose.camera import CameraModel
from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH, epoch_ns
from deckpose.errors import ConfigError
from deckpose.image_store import ImageFormat
from deckpose.layout import DeckLayout, layout_from_dict, layout_to_dict
from deckpose.painted_ring import PaintedRing, painted_ring_from_dict
from deckpose.typed_config import check_range, coerce, did_you_mean, from_mapping, load_yaml

__all__ = [
    # the job, its loaders and defaults; and each section's record, whose home is its own
    # module (render/*_config.py), named here too so ``from deckpose.render.config import
    # SensorSpec`` keeps working
    "ANTIALIAS_SAMPLES",
    "APPROACH_DEMO_CONFIG",
    "DEFAULT_CONFIG",
    "KOSCHMIEDER",
    "AutoExposureSpec",
    "Backend",
    "BayerPattern",
    "EmitterShape",
    "LedModel",
    "LedSpec",
    "Lighting",
    "MotionSource",
    "MotionSpec",
    "OcclusionSpec",
    "OpticsSpec",
    "Readout",
    "RenderConfig",
    "SceneSpec",
    "SeaSpec",
    "SensorSpec",
    "Shading",
    "ShipLightsSpec",
    "ShipModelSpec",
    "ShutterSpec",
    "approach_demo_config",
    "config_from_dict",
    "config_to_dict",
    "default_config",
    "load_config",
]


class Backend(enum.Enum):
    """Headless OpenGL platform (``PYOPENGL_PLATFORM``)."""

    EGL = "egl"
    OSMESA = "osmesa"


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
    leds: LedSpec = LedSpec()
    occlusion: OcclusionSpec = OcclusionSpec()
    ship_lights: ShipLightsSpec = ShipLightsSpec()
    shutter: ShutterSpec = ShutterSpec()
    optics: OpticsSpec = OpticsSpec()
    #: A painted ring on the deck (:mod:`deckpose.painted_ring`); None: none (the default).
    painted_ring: PaintedRing | None = None
    seed: int = 0
    backend: Backend = Backend.EGL
    name: str = "dataset"
    #: Capture time of the first frame, ISO 8601 with a time zone (:mod:`deckpose.capture_time`).
    capture_epoch: str = DEFAULT_CAPTURE_EPOCH
    #: How frames are stored: ``png`` (any tool reads it) or ``zstd`` (:mod:`deckpose.image_store`).
    image_format: ImageFormat = ImageFormat.PNG
    #: A UAV approach (:mod:`deckpose.render.approach`) instead of the heights grid; None: the grid.
    approach: ApproachSpec | None = None

    def deck_half_size_m(self) -> float:
        """Half the side of the square deck plate, metres."""
        if self.scene.deck_half_size_m is not None:
            return self.scene.deck_half_size_m
        return 1.4 * self.layout.radius_m

    def cameras_by_name(self) -> dict[str, CameraModel]:
        models = [c.model() for c in self.cameras]
        return {m.name: m for m in models}


def _cameras(value: object, where: str) -> tuple[CameraSpec, ...]:
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: must be a non-empty list (e.g. [{{preset: 8mp}}])")
    cameras = tuple(camera_spec(c, f"{where}[{i}]") for i, c in enumerate(value))
    names = [c.model().name for c in cameras]
    if len(set(names)) != len(names):
        raise ConfigError(f"{where}: camera names must be unique, got {names}; set 'name:' per camera")
    return cameras


def _heights(value: object, where: str) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: must be a non-empty list of camera heights, metres")
    heights = coerce(tuple[float, ...], value, where)
    for i, h in enumerate(heights):
        check_range(h, f"{where}[{i}]", low=0, low_open=True)
    return heights


def _lighting(value: object, where: str) -> tuple[Lighting, ...]:
    light = [value] if isinstance(value, str) else value
    if not isinstance(light, list) or not light:
        raise ConfigError(f"{where}: must be a non-empty list of {[e.value for e in Lighting]}")
    return coerce(tuple[Lighting, ...], light, where)


def _layout(value: object, where: str) -> DeckLayout:
    if isinstance(value, dict) and value.get("n_ring") == 0:
        raise ConfigError(f"{where}: n_ring is 0 - a deck needs beacons (at least 3)")
    return layout_from_dict(value, where)


_SECTIONS: dict[str, Any] = {
    "cameras": _cameras,
    "heights_m": _heights,
    "lighting": _lighting,
    "motion": motion_spec,
    "sensor": sensor_spec,
    "scene": scene_spec,
    "layout": _layout,
    "leds": led_spec,
    "occlusion": occlusion_spec,
    "ship_lights": ship_lights_spec,
    "shutter": shutter_spec,
    "optics": optics_spec,
    "approach": approach_spec,
    "painted_ring": lambda value, where: None if value is None else painted_ring_from_dict(value, where),
}


def config_from_dict(doc: object, source: str = "config") -> RenderConfig:
    """Validate a parsed YAML mapping into a :class:`RenderConfig`."""
    if doc is None:
        raise ConfigError(f"{source}: the config is empty; start from one in configs/ (e.g. configs/smoke.yaml)")
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a YAML mapping at the top level")
    if "approach" in doc:
        doc = _approach_heights(doc, source)
    for key in ("cameras", "heights_m"):
        if key not in doc:
            # a mistyped key names the typo, not only the key it left missing
            top = {f.name for f in fields(RenderConfig)}
            near = [k for k in doc if k not in top and did_you_mean([k], [key])]
            typo = f" (the config has {near[0]!r} instead: a typo?)" if near else ""
            raise ConfigError(f"{source}: {key!r} is missing{typo}: "
                              + ("a list of cameras (e.g. [{preset: 8mp}])" if key == "cameras"
                                 else "a list of camera heights, metres"))
    scene_doc = doc.get("scene")
    auto_texture = False
    if isinstance(scene_doc, dict) and isinstance(scene_doc.get("texture_px"), str) \
            and scene_doc["texture_px"] != "auto":
        raise ConfigError(f"{source}: scene.texture_px: an integer (64-8192) or auto, got {scene_doc['texture_px']!r}")
    if isinstance(scene_doc, dict) and scene_doc.get("texture_px") == "auto":  # sized from the GSD below
        doc = {**doc, "scene": {k: v for k, v in scene_doc.items() if k != "texture_px"}}
        auto_texture = True
    cfg = from_mapping(RenderConfig, doc, f"{source}:", convert=_SECTIONS)
    if auto_texture:
        lowest = min(cfg.approach.heights_m) if cfg.approach is not None else min(cfg.heights_m)
        px = deck_texture_px([c.model() for c in cfg.cameras], lowest, cfg.deck_half_size_m())
        cfg = replace(cfg, scene=replace(cfg.scene, texture_px=px))
    check_range(cfg.seed, f"{source}: seed", low=0)
    epoch_ns(cfg.capture_epoch, f"{source}: capture_epoch")  # a time with a zone, this century
    half = cfg.deck_half_size_m()
    if half <= cfg.layout.radius_m + cfg.layout.beacon_radius_m:
        raise ConfigError(f"scene.deck_half_size_m={half} must exceed the ring radius "
                          f"{cfg.layout.radius_m} so the beacons sit on the deck")
    if cfg.painted_ring is not None:
        _check_painted_ring(cfg, cfg.painted_ring, source)
    if cfg.sensor.video is not None:
        _check_video_sizes(cfg, source)
    ae = cfg.sensor.auto_exposure
    if ae is not None and ae.controlled and cfg.motion.every > 1:
        gap_s = cfg.motion.every * cfg.motion.dt_s
        raise ConfigError(f"{source}: sensor.auto_exposure's controller (time_constant_s, max_step_stops) runs "
                          f"over consecutive camera frames, but motion.every {cfg.motion.every} renders one "
                          f"sample in {cfg.motion.every} ({gap_s:g} s apart), so it would expose each frame for "
                          f"a scene {gap_s:g} s old; set motion.every: 1, or drop time_constant_s and "
                          "max_step_stops (each frame then meters itself)")
    if cfg.optics.focus_distance_m is not None:
        f_m = max(c.model().fx for c in cfg.cameras) * cfg.optics.pixel_pitch_um * 1e-6
        if cfg.optics.focus_distance_m <= f_m:
            raise ConfigError(f"optics.focus_distance_m: must exceed the focal length ({f_m * 1e3:.2f} mm "
                              f"= fx x pixel_pitch_um), got {cfg.optics.focus_distance_m:g}")
    return cfg


def _check_video_sizes(cfg: RenderConfig, source: str) -> None:
    """Every camera of a video config has an even width and height (4:2:0 chroma).

    H.264 refuses an odd size, and OpenCV's ``mp4v`` and ``vp9`` writers silently drop
    the odd row and column, so the frames would come back smaller than the camera.
    """
    odd = [m for m in (c.model() for c in cfg.cameras) if m.width_px % 2 or m.height_px % 2]
    if odd:
        sizes = ", ".join(f"{m.name} {m.width_px}x{m.height_px}" for m in odd)
        raise ConfigError(f"{source}: sensor.video needs an even image width and height (4:2:0 chroma), "
                          f"got {sizes}; give those cameras an even size (cameras[].size) or set video: null")


def _approach_heights(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """A config with an ``approach:``: its one nominal height (the first waypoint's) as ``heights_m``."""
    if "heights_m" in doc:
        raise ConfigError(f"{source}: give heights_m or approach, not both (an approach's heights are its "
                          "waypoints, approach.heights_m)")
    motion = doc.get("motion")
    src = motion.get("source", MotionSource.FIXED.value) if isinstance(motion, dict) else MotionSource.FIXED.value
    if src == MotionSource.FIXED.value:
        raise ConfigError(f"{source}: an approach needs a motion series (motion.source: sea_state, file or thesis), "
                          "not fixed attitudes")
    if isinstance(motion, dict) and (motion.get("every", 1) != 1 or motion.get("max_samples") is not None):
        raise ConfigError(f"{source}: motion.every and motion.max_samples do not apply to an approach (its frames "
                          "are approach.rate_hz apart); remove them")
    appr = doc["approach"]
    first = appr.get("heights_m") if isinstance(appr, dict) else None
    nominal = first[0] if isinstance(first, list) and first else 1.0  # (approach_spec says what is wrong)
    return {**doc, "heights_m": [nominal]}


def _check_painted_ring(cfg: RenderConfig, ring: PaintedRing, source: str) -> None:
    """The painted ring must lie on the deck, clear of the beacons, in flat shading."""
    if ring.extent_m >= cfg.deck_half_size_m():
        raise ConfigError(f"{source}: painted_ring reaches {ring.extent_m:g} m from the centre, beyond the deck "
                          f"(half size {cfg.deck_half_size_m():g} m): make it smaller or scene.deck_half_size_m larger")
    clear = cfg.layout.radius_m - 3 * cfg.layout.beacon_radius_m  # the beacons' dark fittings
    if ring.extent_m >= clear:
        raise ConfigError(f"{source}: painted_ring reaches {ring.extent_m:g} m from the centre, onto the beacons' "
                          f"fittings (from {clear:g} m): make the ring (or its bar) smaller or layout.radius_m larger")
    if cfg.scene.shading is not Shading.FLAT:
        raise ConfigError(f"{source}: painted_ring needs scene.shading: flat (pbr lights the deck with a sun "
                          "the analytic paint does not see)")


#: The embedded default job (the same as ``configs/smoke.yaml``): two small resolutions x two
#: heights x night/day x three attitudes = 24 frames, seconds on two cores.
DEFAULT_CONFIG: dict[str, Any] = {
    "name": "smoke",
    "seed": 7,
    "backend": "egl",
    # small frames, named for their size (not 4 MP and 8 MP cameras), square pixels
    "cameras": [{"preset": "4mp-square", "size": [640, 480], "name": "640x480"},
                {"preset": "8mp-square", "size": [960, 540], "name": "960x540"}],
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


#: The demo's short approach (the same as ``configs/approach_small.yaml``): 30 s at 2 Hz from 60 m
#: down to 30 m over sea state 6 on a 960x540 camera, 61 frames.
APPROACH_DEMO_CONFIG: dict[str, Any] = {
    "name": "approach_small",
    "seed": 21,
    "backend": "egl",
    "cameras": [{"preset": "8mp-square", "size": [960, 540], "name": "960x540"}],
    "lighting": ["night"],
    "motion": {"source": "sea_state",
               "params": {"sea": {"sea_state": 6, "hs_m": 5.0, "tp_s": 12.4, "heading_deg": 135, "speed_kn": 15},
                          "duration_s": 40, "dt_s": 0.1, "seed": 1},
               "exposure_s": 0.005},
    "approach": {"times_s": [0, 5, 25, 30], "heights_m": [60, 60, 30, 30], "rate_hz": 2, "drift_m": 1.0,
                 "drift_period_s": 30, "wobble_deg": 2.0, "wobble_period_s": 4},
    "sensor": {"bit_depth": 8, "read_noise_e": 5},
    "scene": {"shading": "flat", "texture_px": 1024},
}


def approach_demo_config() -> RenderConfig:
    """The demo's embedded short approach (no file needed)."""
    return config_from_dict(APPROACH_DEMO_CONFIG, "demo approach config")


def load_config(path: str | os.PathLike[str]) -> RenderConfig:
    """Read and validate a render config YAML file."""
    return config_from_dict(load_yaml(path, "render config"), str(path))


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
        if key == "painted_ring" and val is None:
            continue  # no key: a config without a ring resolves as it did before issue 22
        if key == "approach":
            if val is not None:  # (None, the grid: the key stays out, as before approaches)
                out[key] = {k: _plain(v) for k, v in asdict(val).items()}
                out.pop("heights_m", None)  # the approach sets it
        elif key == "layout":
            out[key] = layout_to_dict(val)
        elif key == "cameras":
            out[key] = [{k: _plain(v) for k, v in asdict(c).items() if v is not None} for c in val]
        elif hasattr(val, "__dataclass_fields__"):
            sub = {k: _plain(v) for k, v in asdict(val).items()}
            if key == "motion":
                sub["params"] = dict(val.params)
            if key == "sensor" and sub.get("video") is None:
                sub.pop("video", None)  # no key: a config without video resolves as it did before
            out[key] = sub
        else:
            out[key] = _plain(val)
    return out
