"""The ``leds:`` section of a render config: beacons as real lights."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["KOSCHMIEDER", "EmitterShape", "LedModel", "LedSpec", "led_spec"]


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


def led_spec(doc: object, where: str = "leds") -> LedSpec:
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
