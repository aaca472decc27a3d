"""The ``occlusion:`` section of a render config: beacons hidden by crew, equipment or spray."""

from __future__ import annotations

from dataclasses import dataclass

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["OcclusionSpec", "occlusion_spec"]


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


def occlusion_spec(doc: object, where: str = "occlusion") -> OcclusionSpec:
    spec = from_mapping(OcclusionSpec, doc, where)
    check_range(spec.probability, f"{where}.probability", low=0, high=1)
    check_range(spec.min_fraction, f"{where}.min_fraction", low=0, low_open=True, high=1)
    check_range(spec.max_fraction, f"{where}.max_fraction", low=0, low_open=True, high=1)
    if spec.min_fraction > spec.max_fraction:
        raise ConfigError(f"{where}: min_fraction {spec.min_fraction} exceeds max_fraction {spec.max_fraction}")
    return spec
