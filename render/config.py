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
import os
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from deckpose.render.approach import ApproachSpec, approach_spec
from deckpose.render.camera_spec import CameraSpec, camera_spec
from deckpose.render.texture_size import deck_texture_px

from deckpose.camera import CameraModel
from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH, epoch_ns
from deckpose.errors import ConfigError
from deckpose.image_store import ImageFormat
from deckpose.layout import DeckLayout, layout_from_dict, layout_to_dict
from deckpose.painted_ring import PaintedRing, painted_ring_from_dict
from deckpose.typed_config import check_range, coerce, did_you_mean, from_mapping, load_yaml


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


def _params(value: object, where: str) -> tuple[tuple[str, Any], ...]:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a mapping of keyword arguments")
    return tuple(sorted((str(k), v) for k, v in value.items()))


def _motion_spec(doc: object, where: str = "motion") -> MotionSpec:
    spec = from_mapping(MotionSpec, doc, where, convert={"params": _params})
    if not spec.attitudes_deg or not all(len(a) in (3, 6) for a in spec.attitudes_deg):
        raise ConfigError(f"{where}.attitudes_deg: expected a non-empty list of [roll, pitch, yaw] "
                          "or [roll, pitch, yaw, heave_m, surge_m, sway_m] (degrees, metres)")
    check_range(spec.start, f"{where}.start", low=0)
    check_range(spec.every, f"{where}.every", low=1)
    check_range(spec.blur_steps, f"{where}.blur_steps", low=1)
    if spec.max_samples is not None:
        check_range(spec.max_samples, f"{where}.max_samples", low=1)
    check_range(spec.dt_s, f"{where}.dt_s", low=0, low_open=True)
    check_range(spec.exposure_s, f"{where}.exposure_s", low=0)
    if spec.source is MotionSource.FILE and not spec.path:
        raise ConfigError(f"{where}.source 'file' needs motion.path (a .csv or .parquet motion table)")
    if spec.angles not in ("deg", "rad"):
        raise ConfigError(f"{where}.angles: 'deg' or 'rad', got {spec.angles!r}")
    return spec


class BayerPattern(enum.Enum):
    """Colour filter array, named by its top-left 2x2 block read row by row (``none``: RGB per pixel)."""

    NONE = "none"
    RGGB = "rggb"
    BGGR = "bggr"
    GRBG = "grbg"
    GBRG = "gbrg"


@dataclass(frozen=True)
class AutoExposureSpec:
    """Auto-exposure (:mod:`deckpose.render.auto_exposure`): ``exposure`` chosen per frame.

    The noise-free background of the frame is metered: its mean in full-scale units
    (``percentile: null``) or that percentile of its values is brought to ``target``;
    the exposure (the unit of ``sensor.exposure``) is clamped to
    [``min_exposure``, ``max_exposure``].
    """

    target: float = 0.18
    percentile: float | None = None
    min_exposure: float = 0.05
    max_exposure: float = 50.0


@dataclass(frozen=True)
class SensorSpec:
    """Sensor model applied after rendering (see :mod:`deckpose.render.sensor`).

    ``exposure`` scales scene radiance (1 = the raster's white fills the well);
    ``full_well_e`` electrons at saturation; ``read_noise_e`` electrons RMS;
    ``bit_depth`` 8, 12 or 16 (12 is stored in 16-bit PNG, values 0..4095);
    ``color`` ``rgb`` or ``mono``; ``noise: false`` gives the noise-free image.
    Sensor effects, off by default: ``bayer`` (:class:`BayerPattern`), ``jpeg_quality``,
    the fixed pattern ``prnu`` / ``dsnu_e`` / ``hot_pixel_fraction`` / ``hot_pixel_e`` and
    ``auto_exposure`` (:class:`AutoExposureSpec`); the README's "Sensor effects" says what each models.
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
    # issue 23 item 4, all off by default (render/bayer.py, compression.py, fixed_pattern.py, auto_exposure.py)
    bayer: BayerPattern = BayerPattern.NONE
    jpeg_quality: int | None = None
    prnu: float = 0.0
    dsnu_e: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_e: float = 2000.0
    auto_exposure: AutoExposureSpec | None = None


def _sensor_spec(doc: object, where: str = "sensor") -> SensorSpec:
    spec = from_mapping(SensorSpec, doc, where)
    if spec.bit_depth not in (8, 12, 16):
        raise ConfigError(f"{where}.bit_depth: 8, 12 or 16, got {spec.bit_depth!r}")
    if spec.color not in ("rgb", "mono"):
        raise ConfigError(f"{where}.color: 'rgb' or 'mono', got {spec.color!r}")
    for key in ("exposure", "full_well_e", "psf_sigma_px", "beacon_peak", "halo_scale"):
        check_range(getattr(spec, key), f"{where}.{key}", low=0, low_open=True)
    check_range(spec.read_noise_e, f"{where}.read_noise_e", low=0)
    # the halo is a fraction of the beacon's light spread around it
    check_range(spec.halo_fraction, f"{where}.halo_fraction", low=0, high=1, high_open=True)
    if spec.psf_sigma_px < 0.5:
        raise ConfigError(f"{where}.psf_sigma_px: must be >= 0.5 px so beacon centroids are not aliased")
    _check_sensor_effects(spec, where)
    return spec


def _check_sensor_effects(spec: SensorSpec, where: str) -> None:
    """Range checks of the sensor effects (Bayer, JPEG, fixed pattern, auto-exposure)."""
    if spec.bayer is not BayerPattern.NONE and spec.color == "mono":
        raise ConfigError(f"{where}.bayer: a mono sensor has no colour filter array; "
                          "set sensor.color: rgb or sensor.bayer: none")
    if spec.jpeg_quality is not None:
        check_range(spec.jpeg_quality, f"{where}.jpeg_quality", low=1, high=100)
        if spec.bit_depth != 8:
            raise ConfigError(f"{where}.jpeg_quality: JPEG holds 8-bit images only, got bit_depth "
                              f"{spec.bit_depth}; set sensor.bit_depth: 8 or jpeg_quality: null")
    check_range(spec.prnu, f"{where}.prnu", low=0, high=0.5)
    check_range(spec.dsnu_e, f"{where}.dsnu_e", low=0)
    check_range(spec.hot_pixel_fraction, f"{where}.hot_pixel_fraction", low=0, high=0.01)
    check_range(spec.hot_pixel_e, f"{where}.hot_pixel_e", low=0, low_open=True)
    ae = spec.auto_exposure
    if ae is not None:
        w = f"{where}.auto_exposure"
        check_range(ae.target, f"{w}.target", low=0, low_open=True, high=1, high_open=True)
        if ae.percentile is not None:
            check_range(ae.percentile, f"{w}.percentile", low=0, low_open=True, high=100)
        check_range(ae.min_exposure, f"{w}.min_exposure", low=0, low_open=True)
        if ae.max_exposure < ae.min_exposure:
            raise ConfigError(f"{w}: max_exposure {ae.max_exposure:g} is below min_exposure "
                              f"{ae.min_exposure:g}; raise max_exposure")


class LedModel(enum.Enum):
    """How a beacon's brightness is modelled (:mod:`deckpose.render.beacons`).

    ``disc``: an emitting disc of constant radiance, so a spot's light is its projected
    area times the radiance (today's frames). ``point``: an LED of intensity
    ``I(theta) = I0 cos(theta)**m`` (theta from the deck normal) whose light on the
    sensor falls with the square of the distance and the aperture's foreshortening.
    """

    DISC = "disc"
    POINT = "point"


class EmitterShape(enum.Enum):
    """A beacon's emitting surface (:mod:`deckpose.render.emitter`): a disc on the deck or a dome."""

    FLAT = "flat"
    DOME = "dome"


#: Koschmieder's constant: the extinction coefficient is 3.912 / visibility (2 % contrast).
KOSCHMIEDER = 3.912


@dataclass(frozen=True)
class LedSpec:
    """Beacons as real lights: emission pattern, unit-to-unit tolerance, extinction.

    ``model`` (:class:`LedModel`); ``emission_exponent`` ``m`` of ``cos(theta)**m``
    (``point`` only; 1 = Lambertian, ``ln 0.5 / ln cos(half-angle)`` for a lensed
    LED); ``intensity_tolerance`` ``t``: each unit's intensity is drawn once per
    dataset from U(1 - t, 1) (from the config seed and the beacon id, so a beacon
    keeps its brightness in every frame); ``bow_intensity`` scales the bow beacon
    (a dimmer red unit); ``visibility_km``: Beer–Lambert transmission
    ``exp(-3.912 d / V)`` over the beacon's distance ``d`` (null: clear air);
    ``emitter`` (:class:`EmitterShape`): ``dome`` centres each spot on the light centroid
    of a constant-radiance hemisphere, which is not the projected centre (both are
    recorded: ``u_px`` and ``light_u_px`` in ``beacons.parquet``).
    """

    model: LedModel = LedModel.DISC
    emitter: EmitterShape = EmitterShape.FLAT
    emission_exponent: float = 1.0
    intensity_tolerance: float = 0.0
    bow_intensity: float = 1.0
    visibility_km: float | None = None

    def extinction_per_m(self) -> float:
        """Beer–Lambert extinction coefficient, per metre (0 in clear air)."""
        return 0.0 if self.visibility_km is None else KOSCHMIEDER / (1000.0 * self.visibility_km)


def _led_spec(doc: object, where: str = "leds") -> LedSpec:
    spec = from_mapping(LedSpec, doc, where)
    check_range(spec.emission_exponent, f"{where}.emission_exponent", low=0)
    check_range(spec.intensity_tolerance, f"{where}.intensity_tolerance", low=0, high=1, high_open=True)
    check_range(spec.bow_intensity, f"{where}.bow_intensity", low=0, low_open=True)
    if spec.visibility_km is not None:
        check_range(spec.visibility_km, f"{where}.visibility_km", low=0, low_open=True)
    if spec.model is LedModel.DISC and spec.emission_exponent != 1.0:
        raise ConfigError(f"{where}.emission_exponent: only the 'point' model has an emission pattern "
                          "(a constant-radiance disc is Lambertian); set leds.model: point")
    return spec


@dataclass(frozen=True)
class OcclusionSpec:
    """Beacons hidden by crew, equipment or spray (:mod:`deckpose.render.occlusion`).

    Each beacon in view is occluded in a frame with ``probability``; an occluder is a
    straight edge across the spot that hides a fraction of its light drawn from
    U(``min_fraction``, ``max_fraction``) (1 = wholly hidden). Per frame and beacon the
    hidden fraction and the centroid of the light left are recorded in ``beacons.parquet``.
    """

    probability: float = 0.0
    min_fraction: float = 0.2
    max_fraction: float = 1.0


def _occlusion_spec(doc: object, where: str = "occlusion") -> OcclusionSpec:
    spec = from_mapping(OcclusionSpec, doc, where)
    check_range(spec.probability, f"{where}.probability", low=0, high=1)
    check_range(spec.min_fraction, f"{where}.min_fraction", low=0, low_open=True, high=1)
    check_range(spec.max_fraction, f"{where}.max_fraction", low=0, low_open=True, high=1)
    if spec.min_fraction > spec.max_fraction:
        raise ConfigError(f"{where}: min_fraction {spec.min_fraction} exceeds max_fraction {spec.max_fraction}")
    return spec


@dataclass(frozen=True)
class ShipLightsSpec:
    """Lights that are not beacons (:mod:`deckpose.render.ship_lights`), recorded in ``lights.parquet``.

    ``navigation``: the red port and green starboard sidelights, the white masthead and
    stern lights, on a notional superstructure forward of the deck and at the stern;
    ``floodlights``: white deck floodlights on poles along the deck edge;
    ``glints``: specular glints of the sun or moon on the sea per frame, at random
    positions near the ship (from the frame's seed); ``intensity`` of each light
    relative to an on-axis beacon at the same distance (``glint_intensity`` for glints).
    """

    navigation: bool = False
    floodlights: int = 0
    glints: int = 0
    intensity: float = 1.0
    glint_intensity: float = 0.5


def _ship_lights_spec(doc: object, where: str = "ship_lights") -> ShipLightsSpec:
    spec = from_mapping(ShipLightsSpec, doc, where)
    check_range(spec.floodlights, f"{where}.floodlights", low=0, high=64)
    check_range(spec.glints, f"{where}.glints", low=0, high=256)
    check_range(spec.intensity, f"{where}.intensity", low=0, low_open=True)
    check_range(spec.glint_intensity, f"{where}.glint_intensity", low=0, low_open=True)
    return spec


class Readout(enum.Enum):
    """Rolling-shutter readout order: ``top_down`` reads row 0 first, ``bottom_up`` the last row first."""

    TOP_DOWN = "top_down"
    BOTTOM_UP = "bottom_up"


@dataclass(frozen=True)
class ShutterSpec:
    """Rolling shutter and the UAV's motion during a frame (:mod:`deckpose.render.rolling_shutter`).

    ``line_delay_s``: time between the exposures of consecutive rows (0 = global shutter);
    row ``v`` is exposed around ``t_frame + (v - (H - 1) / 2) * line_delay_s`` (``readout``
    top_down; bottom_up reverses the sign). ``uav_velocity_m_per_s`` (world x, y, z) and
    ``uav_rate_deg_per_s`` (about the camera's x, y, z axes) move the camera during the
    readout and exposure; ``vibration_deg_rms`` / ``vibration_hz``: an angular jitter of
    the camera, one sinusoid per camera axis with a random phase per frame, that blurs the
    spots along its path (:mod:`deckpose.render.camera_motion`). All zero: today's frames.
    """

    line_delay_s: float = 0.0
    readout: Readout = Readout.TOP_DOWN
    uav_velocity_m_per_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    uav_rate_deg_per_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    vibration_deg_rms: float = 0.0
    vibration_hz: float = 120.0

    @property
    def enabled(self) -> bool:
        """Whether any effect of the section is on (off: frames exactly as without it)."""
        return (self.line_delay_s > 0 or self.vibration_deg_rms > 0
                or any(self.uav_velocity_m_per_s) or any(self.uav_rate_deg_per_s))


def _shutter_spec(doc: object, where: str = "shutter") -> ShutterSpec:
    spec = from_mapping(ShutterSpec, doc, where)
    # 1 ms a row would read 1000 rows in a second: far beyond any CMOS readout (tens of µs at most)
    check_range(spec.line_delay_s, f"{where}.line_delay_s", low=0, high=1e-3)
    for i, v in enumerate(spec.uav_velocity_m_per_s):
        check_range(v, f"{where}.uav_velocity_m_per_s[{i}]", low=-100, high=100)
    for i, v in enumerate(spec.uav_rate_deg_per_s):
        check_range(v, f"{where}.uav_rate_deg_per_s[{i}]", low=-720, high=720)
    check_range(spec.vibration_deg_rms, f"{where}.vibration_deg_rms", low=0, high=5)
    check_range(spec.vibration_hz, f"{where}.vibration_hz", low=0, low_open=True, high=10000)
    return spec


@dataclass(frozen=True)
class OpticsSpec:
    """The lens beyond a Gaussian (:mod:`deckpose.render.optics`), applied to the light spots.

    Each effect is off by default and switched on alone: ``focus_distance_m`` (null: no
    defocus) with ``f_number`` gives each spot a uniform blur disc of the thin-lens
    diameter at its distance; ``diffraction`` convolves it with the Airy pattern of
    ``f_number`` at ``wavelength_nm`` (red, green, blue) for pixels of ``pixel_pitch_um``;
    ``glare_fraction`` of the light goes into a wide point-symmetric tail
    (``(1 + (r / glare_radius_px)**2)**-1.5``) and ``spike_fraction`` into diffraction
    spikes of an aperture of ``spike_blades`` blades (``spike_length_px`` their 1/e
    length); ``bloom`` spills the charge above the full well along columns;
    ``vignetting_exponent`` ``n`` dims the raster and the spots by ``cos(theta)**n``
    (4: the cos^4 law); ``lateral_ca_ppm`` ``[red, blue]`` is each channel's radial
    magnification relative to green minus one, parts per million; ``field_blur_px``
    is the sigma of an extra Gaussian blur at the image corner, growing with the square
    of the distance from the principal point.
    """

    f_number: float = 2.8
    focus_distance_m: float | None = None
    pixel_pitch_um: float = 2.0
    diffraction: bool = False
    wavelength_nm: tuple[float, float, float] = (610.0, 540.0, 465.0)
    glare_fraction: float = 0.0
    glare_radius_px: float = 3.0
    spike_blades: int = 6
    spike_fraction: float = 0.0
    spike_length_px: float = 8.0
    bloom: bool = False
    vignetting_exponent: float = 0.0
    lateral_ca_ppm: tuple[float, float] = (0.0, 0.0)
    field_blur_px: float = 0.0

    def enabled(self) -> bool:
        """Whether any effect is on (off: the spots and frames are today's, bit for bit)."""
        return (self.focus_distance_m is not None or self.diffraction or self.glare_fraction > 0
                or self.spike_fraction > 0 or self.bloom or self.vignetting_exponent > 0
                or any(c != 0 for c in self.lateral_ca_ppm) or self.field_blur_px > 0)


def _optics_spec(doc: object, where: str = "optics") -> OpticsSpec:
    spec = from_mapping(OpticsSpec, doc, where)
    check_range(spec.f_number, f"{where}.f_number", low=0.5, high=64)
    if spec.focus_distance_m is not None:
        check_range(spec.focus_distance_m, f"{where}.focus_distance_m", low=0, low_open=True)
    check_range(spec.pixel_pitch_um, f"{where}.pixel_pitch_um", low=0.3, high=30)
    for i, w in enumerate(spec.wavelength_nm):
        check_range(w, f"{where}.wavelength_nm[{i}]", low=300, high=1100)
    check_range(spec.glare_fraction, f"{where}.glare_fraction", low=0, high=1, high_open=True)
    check_range(spec.spike_fraction, f"{where}.spike_fraction", low=0, high=1, high_open=True)
    if spec.glare_fraction + spec.spike_fraction >= 1:
        raise ConfigError(f"{where}: glare_fraction + spike_fraction must be < 1 (the rest is the core), "
                          f"got {spec.glare_fraction + spec.spike_fraction:g}")
    check_range(spec.glare_radius_px, f"{where}.glare_radius_px", low=0.5, high=50)
    check_range(spec.spike_blades, f"{where}.spike_blades", low=3, high=24)
    check_range(spec.spike_length_px, f"{where}.spike_length_px", low=1, high=100)
    check_range(spec.vignetting_exponent, f"{where}.vignetting_exponent", low=0, high=8)
    for name, ppm in zip(("red", "blue"), spec.lateral_ca_ppm):
        check_range(ppm, f"{where}.lateral_ca_ppm ({name})", low=-10000, high=10000)
    check_range(spec.field_blur_px, f"{where}.field_blur_px", low=0, high=20)
    return spec


@dataclass(frozen=True)
class ShipModelSpec:
    """The ship around the deck (:mod:`deckpose.render.ship_model`): ``hull`` (sides down to
    the waterline and a bow) and ``superstructure`` (a bridge block forward of the deck)."""

    hull: bool = False
    superstructure: bool = False


@dataclass(frozen=True)
class SeaSpec:
    """An animated sea of ``waves`` directional sine waves (:mod:`deckpose.render.sea`; 0: the flat
    textured plane): significant height ``height_m``, peak wavelength ``wavelength_m``,
    from ``direction_deg`` (world, from +x), phases and spread from ``seed``."""

    waves: int = 0
    height_m: float = 1.5
    wavelength_m: float = 60.0
    direction_deg: float = 30.0
    seed: int = 1


@dataclass(frozen=True)
class SceneSpec:
    """Deck plate and sea. ``deck_half_size_m`` must exceed the beacon ring radius.

    Ship look (issue 23 item 8, all off by default): ``ship``, ``sea``; ``light_pools_cd``,
    the beacons' light on the deck (:mod:`deckpose.render.light_pools`; candela toward
    the deck, 0: off); ``bloom_fraction`` of each light's flux spread as glare over a
    Gaussian of ``bloom_sigma_mrad`` (:mod:`deckpose.render.bloom`); ``shadows``: sun
    shadows in ``pbr`` shading; ``texture_px: auto`` sizes the deck texture from the
    cameras' ground sampling distance at the lowest height (:mod:`deckpose.render.texture_size`).
    ``antialias_samples``: multisample anti-aliasing of the deck and sea raster (4, as
    pyrender draws; 0 off: a 64 MP draw 1.6x faster, with edges of markings aliased; the
    beacons are drawn analytically and their truth does not change).
    """

    shading: Shading = Shading.FLAT
    deck_half_size_m: float | None = None
    freeboard_m: float = 6.0
    sea_half_size_m: float = 2000.0
    sea_drift_m_per_s: float = 0.8
    texture_px: int = 2048
    ship: ShipModelSpec = ShipModelSpec()
    sea: SeaSpec = SeaSpec()
    light_pools_cd: float = 0.0
    bloom_fraction: float = 0.0
    bloom_sigma_mrad: float = 4.0
    shadows: bool = False
    antialias_samples: int = 4


#: Multisample counts the deck raster may use (0: no multisampling).
ANTIALIAS_SAMPLES = (0, 2, 4, 8)


def _scene_spec(doc: object, where: str = "scene") -> SceneSpec:
    spec = from_mapping(SceneSpec, doc, where)
    check_range(spec.freeboard_m, f"{where}.freeboard_m", low=0, low_open=True)
    check_range(spec.sea_half_size_m, f"{where}.sea_half_size_m", low=0, low_open=True)
    check_range(spec.sea_drift_m_per_s, f"{where}.sea_drift_m_per_s", low=0)
    if spec.deck_half_size_m is not None:
        check_range(spec.deck_half_size_m, f"{where}.deck_half_size_m", low=0, low_open=True)
    check_range(spec.texture_px, f"{where}.texture_px", low=64, high=8192)
    check_range(spec.sea.waves, f"{where}.sea.waves", low=0, high=16)
    check_range(spec.sea.height_m, f"{where}.sea.height_m", low=0, high=0.5 * spec.freeboard_m)
    check_range(spec.sea.wavelength_m, f"{where}.sea.wavelength_m", low=2.0, high=500.0)
    check_range(spec.sea.seed, f"{where}.sea.seed", low=0)
    check_range(spec.light_pools_cd, f"{where}.light_pools_cd", low=0, high=1e5)
    check_range(spec.bloom_fraction, f"{where}.bloom_fraction", low=0, high=1, high_open=True)
    check_range(spec.bloom_sigma_mrad, f"{where}.bloom_sigma_mrad", low=0, low_open=True, high=100)
    if spec.antialias_samples not in ANTIALIAS_SAMPLES:
        raise ConfigError(f"{where}.antialias_samples: one of {', '.join(map(str, ANTIALIAS_SAMPLES))} "
                          f"(0: off), got {spec.antialias_samples}")
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
    "motion": _motion_spec,
    "sensor": _sensor_spec,
    "scene": _scene_spec,
    "layout": _layout,
    "leds": _led_spec,
    "occlusion": _occlusion_spec,
    "ship_lights": _ship_lights_spec,
    "shutter": _shutter_spec,
    "optics": _optics_spec,
    "approach": approach_spec,
    "painted_ring": lambda value, where: None if value is None else painted_ring_from_dict(value, where),
}


def config_from_dict(doc: object, source: str = "config") -> RenderConfig:
    """Validate a parsed YAML mapping into a :class:`RenderConfig`."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a YAML mapping at the top level")
    if "approach" in doc:
        doc = _approach_heights(doc, source)
    for key in ("cameras", "heights_m"):
        if key not in doc:
            # a mistyped key names the typo, not only the key it left missing
            top = {f.name for f in fields(RenderConfig)}
            typo = did_you_mean([k for k in doc if k not in top], [key])
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
    if cfg.optics.focus_distance_m is not None:
        f_m = max(c.model().fx for c in cfg.cameras) * cfg.optics.pixel_pitch_um * 1e-6
        if cfg.optics.focus_distance_m <= f_m:
            raise ConfigError(f"optics.focus_distance_m: must exceed the focal length ({f_m * 1e3:.2f} mm "
                              f"= fx x pixel_pitch_um), got {cfg.optics.focus_distance_m:g}")
    return cfg


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
            out[key] = sub
        else:
            out[key] = _plain(val)
    return out
