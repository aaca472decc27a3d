"""Ship particulars for the closed-form motion model, and named presets.

Two presets:

* ``"thesis"``: the ship behind the thesis's published motion series
  (L = 88 m, B = 12.83 m, T = 2.627 m, Cb = 0.419, GM = 1.1 m, roll period
  0.88 B / sqrt(GM) = 10.77 s, roll damping ratio 0.1).
* ``"ffg7"``: a frigate like the Oliver Hazard Perry (FFG-7) class. Length,
  beam and draught are the class's waterline figures (L = 124 m, B = 13.7 m,
  T = 4.5 m). **Assumed** (not published class data): block coefficient 0.50
  (about 3900 t full-load displacement), GM = 1.2 m, roll period from the same
  rule as the thesis ship, 0.88 B / sqrt(GM) = 11.0 s, and roll damping ratio
  0.1 (bilge keels, moderate speed).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from deckpose.errors import ConfigError

#: Coefficient c of the roll-period rule T4 = c * B / sqrt(GM) used by the thesis code.
ROLL_PERIOD_COEFFICIENT = 0.88


@dataclass(frozen=True)
class ShipParticulars:
    """Main dimensions and roll properties of a ship.

    Attributes
    ----------
    length_m : float
        Length (between perpendiculars / waterline), metres.
    beam_m : float
        Waterline beam, metres.
    draught_m : float
        Draught, metres.
    block_coefficient : float
        Cb = displaced volume / (L B T), in (0, 1].
    gm_m : float
        Transverse metacentric height, metres (> 0).
    roll_period_s : float
        Natural roll period T4, seconds.
    roll_damping_ratio : float
        Roll damping as a fraction of critical, zeta4 in (0, 1).
    name : str
        Label for reports.
    """

    length_m: float
    beam_m: float
    draught_m: float
    block_coefficient: float
    gm_m: float
    roll_period_s: float
    roll_damping_ratio: float
    name: str = "custom"

    def __post_init__(self) -> None:
        for field in ("length_m", "beam_m", "draught_m", "gm_m", "roll_period_s"):
            v = float(getattr(self, field))
            if not math.isfinite(v) or v <= 0:
                raise ConfigError(f"ship {field} must be a positive number, got {v}")
            object.__setattr__(self, field, v)
        cb = float(self.block_coefficient)
        if not (0 < cb <= 1):
            raise ConfigError(f"ship block_coefficient must be in (0, 1], got {cb}")
        object.__setattr__(self, "block_coefficient", cb)
        z = float(self.roll_damping_ratio)
        if not (0 < z < 1):
            raise ConfigError(f"ship roll_damping_ratio must be in (0, 1), got {z}")
        object.__setattr__(self, "roll_damping_ratio", z)

    @property
    def displaced_volume_m3(self) -> float:
        """Cb L B T, cubic metres."""
        return self.block_coefficient * self.length_m * self.beam_m * self.draught_m

    def as_dict(self) -> dict[str, float | str]:
        """Plain dictionary (for resolved-config files)."""
        return asdict(self)


def roll_period_rule_s(beam_m: float, gm_m: float) -> float:
    """The thesis code's natural roll period ``0.88 * B / sqrt(GM)``, seconds."""
    return ROLL_PERIOD_COEFFICIENT * beam_m / math.sqrt(gm_m)


def thesis_ship() -> ShipParticulars:
    """The ship of the thesis's published motion series."""
    return ShipParticulars(
        length_m=88.0, beam_m=12.83, draught_m=2.627, block_coefficient=0.419, gm_m=1.1,
        roll_period_s=roll_period_rule_s(12.83, 1.1), roll_damping_ratio=0.1, name="thesis",
    )


def ffg7_ship() -> ShipParticulars:
    """A frigate like the FFG-7 class (see the module docstring for what is assumed)."""
    return ShipParticulars(
        length_m=124.0, beam_m=13.7, draught_m=4.5, block_coefficient=0.50, gm_m=1.2,
        roll_period_s=roll_period_rule_s(13.7, 1.2), roll_damping_ratio=0.1, name="ffg7",
    )


_PRESETS = {"thesis": thesis_ship, "ffg7": ffg7_ship}
SHIP_PRESETS: tuple[str, ...] = tuple(_PRESETS)


def ship_preset(name: str) -> ShipParticulars:
    """A named ship: ``"thesis"`` or ``"ffg7"``."""
    try:
        return _PRESETS[name.lower()]()
    except KeyError:
        raise ConfigError(f"unknown ship preset {name!r}; choose one of {list(_PRESETS)}") from None
