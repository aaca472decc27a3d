"""The ``scene:`` and ``lighting:`` sections of a render config: deck, ship, sea and light."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["ANTIALIAS_SAMPLES", "Lighting", "SceneSpec", "SeaSpec", "Shading", "ShipModelSpec", "scene_spec"]


class Lighting(enum.Enum):
    """Lighting preset; see :mod:`deckpose.render.scene` for what each sets."""

    NIGHT = "night"
    DUSK = "dusk"
    DAY = "day"


class Shading(enum.Enum):
    """``flat``: textures times the preset's light level (fast); ``pbr``: lit, with sun glints."""

    FLAT = "flat"
    PBR = "pbr"


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


#: The deck and sea textures' seed unless ``scene.texture_seed`` says.
DEFAULT_TEXTURE_SEED = 20240611


@dataclass(frozen=True)
class SceneSpec:
    """Deck plate and sea. ``deck_half_size_m`` must exceed the beacon ring radius.

    Ship look (issue 23 item 8, all off by default): ``ship``, ``sea``; ``light_pools_cd``,
    the beacons' light on the deck (:mod:`deckpose.render.light_pools`; candela toward
    the deck, 0: off); ``bloom_fraction`` of each light's flux spread as glare over a
    Gaussian of ``bloom_sigma_mrad`` (:mod:`deckpose.render.bloom`); ``shadows``: sun
    shadows in ``pbr`` shading; ``texture_px: auto`` sizes the deck texture from the
    cameras' ground sampling distance at the lowest height (:mod:`deckpose.render.texture_size`);
    ``texture_seed`` draws the deck's non-skid grain and the sea's pattern (another seed, another
    deck of the same statistics: the painted ring's edge errors follow the grain).
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
    texture_seed: int = DEFAULT_TEXTURE_SEED
    ship: ShipModelSpec = ShipModelSpec()
    sea: SeaSpec = SeaSpec()
    light_pools_cd: float = 0.0
    bloom_fraction: float = 0.0
    bloom_sigma_mrad: float = 4.0
    shadows: bool = False
    antialias_samples: int = 4


#: Multisample counts the deck raster may use (0: no multisampling).
ANTIALIAS_SAMPLES = (0, 2, 4, 8)


def scene_spec(doc: object, where: str = "scene") -> SceneSpec:
    spec = from_mapping(SceneSpec, doc, where)
    check_range(spec.freeboard_m, f"{where}.freeboard_m", low=0, low_open=True)
    check_range(spec.sea_half_size_m, f"{where}.sea_half_size_m", low=0, low_open=True)
    check_range(spec.sea_drift_m_per_s, f"{where}.sea_drift_m_per_s", low=0)
    if spec.deck_half_size_m is not None:
        check_range(spec.deck_half_size_m, f"{where}.deck_half_size_m", low=0, low_open=True)
    check_range(spec.texture_px, f"{where}.texture_px", low=64, high=8192)
    check_range(spec.texture_seed, f"{where}.texture_seed", low=0)
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
