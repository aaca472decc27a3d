"""The deck's beacon layout: a ring of n beacons, an optional centre beacon, an optional inner ring.

Beacon ids index the layout: ring beacons ``0..n-1`` start at the bow and
increase counter-clockwise seen from above (toward port, +y); the centre beacon,
when present, has id ``n``. An inner ring of ``m`` beacons (``inner_n_ring > 0``,
for a camera too low to see the outer ring) follows with ids ``c..c+m-1``,
``c = n + has_centre``, also from its own bow beacon (on the bow axis, coloured
``bow_rgb`` like the outer bow) counter-clockwise. Positions are in the deck frame
(x bow, y port, z up).
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from deckpose.errors import ConfigError
from deckpose.typed_config import from_mapping, load_yaml

FloatArray = np.ndarray


@dataclass(frozen=True)
class DeckLayout:
    """Geometry and appearance of the deck beacons.

    Attributes
    ----------
    n_ring : int
        Number of ring beacons (>= 3).
    radius_m : float
        Ring radius, metres (the thesis's "units").
    has_centre : bool
        Whether a beacon sits at the deck centre (id ``n_ring``).
    bow_id : int
        Ring id of the beacon that marks the bow. Ids start at the bow, so this
        must be 0; the field exists so configs can state it explicitly.
    bow_rgb : tuple of float
        Colour that tells the bow beacon apart (linear RGB in [0, 1]).
    beacon_rgb : tuple of float
        Colour of the other beacons.
    beacon_radius_m : float
        Radius of a beacon's emitting disc, metres (rendering).
    intensity : float
        Relative emitted radiance of a beacon (rendering; 1 = saturating at
        the default exposure).
    inner_n_ring : int
        Beacons on an inner ring (0: none, the default; else >= 5, so the
        inner ring can be identified on its own by its ellipse).
    inner_radius_m : float
        Inner ring radius, metres (used when ``inner_n_ring > 0``; smaller
        than ``radius_m``).
    """

    n_ring: int = 12
    radius_m: float = 10.0
    has_centre: bool = True
    bow_id: int = 0
    bow_rgb: tuple[float, float, float] = (1.0, 0.1, 0.05)
    beacon_rgb: tuple[float, float, float] = (1.0, 1.0, 0.9)
    beacon_radius_m: float = 0.15
    intensity: float = 1.0
    inner_n_ring: int = 0
    inner_radius_m: float = 1.5

    def __post_init__(self) -> None:
        if int(self.n_ring) < 3:
            raise ConfigError(f"layout needs at least 3 ring beacons, got n_ring={self.n_ring}")
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise ConfigError(f"layout radius_m must be a finite positive number of metres, got {self.radius_m}")
        if int(self.bow_id) != 0:
            raise ConfigError(
                f"bow_id must be 0 (ring ids start at the bow beacon), got {self.bow_id}; "
                "renumber the ring so the bow beacon is id 0"
            )
        if not (self.beacon_radius_m > 0 and self.beacon_radius_m < self.radius_m):
            raise ConfigError(
                f"beacon_radius_m must be positive and smaller than the ring, got {self.beacon_radius_m}"
            )
        if not self.intensity > 0:
            raise ConfigError(f"intensity must be positive, got {self.intensity}")
        for name in ("bow_rgb", "beacon_rgb"):
            rgb = tuple(float(c) for c in getattr(self, name))
            if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
                raise ConfigError(f"{name} must be three values in [0, 1], got {getattr(self, name)}")
            object.__setattr__(self, name, rgb)
        if int(self.inner_n_ring) != 0:
            if int(self.inner_n_ring) < 5:
                raise ConfigError(
                    f"inner_n_ring must be 0 (no inner ring) or >= 5 (identified by its ellipse), "
                    f"got {self.inner_n_ring}"
                )
            if not (math.isfinite(self.inner_radius_m)
                    and 2 * self.beacon_radius_m < self.inner_radius_m < self.radius_m - 2 * self.beacon_radius_m):
                raise ConfigError(
                    f"inner_radius_m must lie between two beacon radii from the centre and from the "
                    f"outer ring ({2 * self.beacon_radius_m:g} .. {self.radius_m - 2 * self.beacon_radius_m:g} m), "
                    f"got {self.inner_radius_m}"
                )
        object.__setattr__(self, "inner_n_ring", int(self.inner_n_ring))
        object.__setattr__(self, "inner_radius_m", float(self.inner_radius_m))
        object.__setattr__(self, "n_ring", int(self.n_ring))
        object.__setattr__(self, "bow_id", int(self.bow_id))
        object.__setattr__(self, "radius_m", float(self.radius_m))

    @property
    def n_beacons(self) -> int:
        """Total number of beacons: ring, centre and inner ring."""
        return self.n_ring + int(self.has_centre) + self.inner_n_ring

    @property
    def inner_first_id(self) -> int | None:
        """Id of the inner ring's bow beacon, or ``None`` without an inner ring."""
        return self.n_ring + int(self.has_centre) if self.inner_n_ring else None

    def inner_ring_ids(self) -> np.ndarray:
        """Ids of the inner ring beacons, shape (inner_n_ring,) (empty without one)."""
        return self.n_ring + int(self.has_centre) + np.arange(self.inner_n_ring)

    @property
    def bow_ids(self) -> tuple[int, ...]:
        """Ids of the beacons that mark the bow: the outer ring's, then the inner ring's if any."""
        first = self.inner_first_id
        return (self.bow_id,) if first is None else (self.bow_id, first)

    def beacon_rgb_all(self) -> FloatArray:
        """Colour of every beacon (linear RGB), shape (n_beacons, 3): ``bow_rgb`` for the bow ids."""
        rgb = np.tile(np.asarray(self.beacon_rgb, float), (self.n_beacons, 1))
        rgb[list(self.bow_ids)] = self.bow_rgb
        rgb.setflags(write=False)
        return rgb

    @property
    def centre_id(self) -> int | None:
        """Id of the centre beacon, or ``None`` if there is none."""
        return self.n_ring if self.has_centre else None

    def positions_deck_m(self) -> FloatArray:
        """Beacon positions in the deck frame.

        Returns
        -------
        (n_beacons, 3) array of float, metres
            Row ``i`` is beacon id ``i``: ring beacon ``i`` at angle ``2*pi*i/n``
            from the bow toward port; the centre beacon; then inner ring beacon
            ``k`` at angle ``2*pi*k/m`` and radius ``inner_radius_m``.
        """
        ring = ring_positions_m(self.n_ring, self.radius_m)
        if self.has_centre:
            ring = np.vstack([ring, np.zeros((1, 3))])
        if self.inner_n_ring:
            ring = np.vstack([ring, ring_positions_m(self.inner_n_ring, self.inner_radius_m)])
        ring.setflags(write=False)
        return ring

    def ring_ids(self) -> np.ndarray:
        """Ids of the ring beacons, shape (n_ring,)."""
        return np.arange(self.n_ring)


def ring_positions_m(n: int, radius_m: float) -> FloatArray:
    """Deck-frame positions of ``n`` beacons on a ring, from the bow counter-clockwise, (n, 3), metres."""
    ang = 2.0 * np.pi * np.arange(n) / n
    return np.stack([radius_m * np.cos(ang), radius_m * np.sin(ang), np.zeros_like(ang)], 1)


def thesis_layout() -> DeckLayout:
    """The thesis's layout: 12 beacons on a radius-10 ring, bow = 0, no centre beacon."""
    return DeckLayout(n_ring=12, radius_m=10.0, has_centre=False)


def layout_from_dict(doc: object, source: str = "layout") -> DeckLayout:
    """Build a :class:`DeckLayout` from a mapping (``None``: the default), typed exactly."""
    try:
        return from_mapping(DeckLayout, doc, source)
    except ConfigError:
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{source}: {exc}") from exc


def read_layout(path: str | os.PathLike[str]) -> DeckLayout:
    """Read a layout YAML file (keys as :class:`DeckLayout` fields, or under ``layout:``)."""
    doc = load_yaml(path, "layout file")
    if isinstance(doc, dict) and set(doc) == {"layout"}:
        doc = doc["layout"]
    return layout_from_dict(doc, f"{path}:")


def layout_to_dict(layout: DeckLayout) -> dict[str, Any]:
    """Plain mapping of a layout (for manifests and YAML)."""
    d = asdict(layout)
    if not layout.inner_n_ring:  # a one-ring layout's mapping stays as it was before inner rings
        del d["inner_n_ring"], d["inner_radius_m"]
    d["bow_rgb"] = list(d["bow_rgb"])
    d["beacon_rgb"] = list(d["beacon_rgb"])
    return d
