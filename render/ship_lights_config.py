"""The ``ship_lights:`` section of a render config: lights that are not beacons."""

from __future__ import annotations

from dataclasses import dataclass

from deckpose.typed_config import check_range, from_mapping

__all__ = ["ShipLightsSpec", "ship_lights_spec"]


@dataclass(frozen=True)
class ShipLightsSpec:
    """Lights that are not beacons (:mod:`deckpose.render.ship_lights`), recorded in ``lights.parquet``.

    ``navigation``: the red port and green starboard sidelights, the white masthead and
    stern lights, on a notional superstructure forward of the deck and at the stern;
    ``floodlights``: white deck floodlights on poles along the deck edge;
    ``glints``: specular glints of the sun or moon on the sea per frame, placed where facets
    of a wind-roughened sea mirror the light into the camera (:mod:`deckpose.render.glints`;
    Cox and Munk's slopes for ``wind_m_per_s``); ``deck_glints``: the same on a wet deck,
    whose water film tilts by ``deck_slope_deg`` RMS per axis; each count is what is asked
    for in the image (fewer where the light's mirror point is far out of view); ``intensity``
    of each light relative to an on-axis beacon at the same distance (``glint_intensity``
    for glints).
    """

    navigation: bool = False
    floodlights: int = 0
    glints: int = 0
    deck_glints: int = 0
    intensity: float = 1.0
    glint_intensity: float = 0.5
    wind_m_per_s: float = 7.0
    deck_slope_deg: float = 10.0


def ship_lights_spec(doc: object, where: str = "ship_lights") -> ShipLightsSpec:
    spec = from_mapping(ShipLightsSpec, doc, where)
    check_range(spec.floodlights, f"{where}.floodlights", low=0, high=64)
    check_range(spec.glints, f"{where}.glints", low=0, high=256)
    check_range(spec.deck_glints, f"{where}.deck_glints", low=0, high=256)
    check_range(spec.wind_m_per_s, f"{where}.wind_m_per_s", low=0, high=60)
    check_range(spec.deck_slope_deg, f"{where}.deck_slope_deg", low=0, low_open=True, high=30)
    check_range(spec.intensity, f"{where}.intensity", low=0, low_open=True)
    check_range(spec.glint_intensity, f"{where}.glint_intensity", low=0, low_open=True)
    return spec
