"""The irregular-sea run configuration: parsed once from YAML / CLI into frozen records.

Schema (every key optional; defaults are the sea-state-6 frigate scenario)::

    ship: ffg7                 # a preset name, or a mapping of ShipParticulars fields
    sea:
      sea_state: 6             # Douglas 1..9
      spectrum: jonswap        # jonswap | pm
      hs_m: null               # null: the state's most probable height
      tp_s: null               # null: the state's most probable peak period
      gamma: 3.3
      heading_deg: 135         # 180 head, 135 bow quartering, 90 beam, 0 following
      speed_kn: 15
      n_components: 600
      yaw: {sigma_deg: 1.0, period_s: 30.0, damping_ratio: 0.4}
      drift: {sigma_m: 0.5, period_s: 60.0, damping_ratio: 0.7}
      deck_offset_m: [0, 0, 0] # deck centre from the centre of gravity (x bow, y port, z up)
    duration_s: 600
    dt_s: 0.1
    seed: 0

:func:`sea_run_to_mapping` writes the same schema fully resolved, so a run's
``.motion.yaml`` can be fed back with ``--config`` to repeat it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from deckpose.errors import ConfigError
from deckpose.motion.closed_form import KNOTS_PER_M_S
from deckpose.motion.filtered_noise import FilteredNoise
from deckpose.motion.irregular import IrregularSea, default_drift, default_yaw
from deckpose.motion.ship import ShipParticulars, ship_preset
from deckpose.motion.spectrum import SpectrumKind, sea_state_row, spectrum_for_sea_state

_TOP_KEYS = {"ship", "sea", "duration_s", "dt_s", "seed"}
_SEA_KEYS = {"sea_state", "spectrum", "hs_m", "tp_s", "gamma", "heading_deg", "speed_kn", "n_components",
             "yaw", "drift", "deck_offset_m"}


@dataclass(frozen=True)
class SeaRun:
    """A fully resolved irregular-sea run.

    Attributes
    ----------
    ship : ShipParticulars
    sea : IrregularSea
    sea_state : int
        The Douglas sea state the spectrum was taken from.
    duration_s, dt_s : float
        Series length and sample step, seconds.
    seed : int
        Seed of the ``numpy.random.Generator`` that draws the series.
    """

    ship: ShipParticulars
    sea: IrregularSea
    sea_state: int
    duration_s: float
    dt_s: float
    seed: int

    def __post_init__(self) -> None:
        if not math.isfinite(self.dt_s) or self.dt_s <= 0:
            raise ConfigError(f"dt_s must be > 0 s, got {self.dt_s}")
        if not math.isfinite(self.duration_s) or self.duration_s < self.dt_s:
            raise ConfigError(f"duration_s must be at least dt_s ({self.dt_s} s), got {self.duration_s}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"seed must be a non-negative integer, got {self.seed!r}")


def _check_keys(where: str, mapping: Mapping[str, Any], allowed: set[str]) -> None:
    unknown = sorted(set(mapping) - allowed)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} must be a number, got {value!r}")
    return float(value)


def _ship(value: Any) -> ShipParticulars:
    if isinstance(value, str):
        return ship_preset(value)
    if isinstance(value, Mapping):
        names = {f.name for f in fields(ShipParticulars)}
        _check_keys("ship", value, names)
        missing = sorted(names - set(value) - {"name"})
        if missing:
            raise ConfigError(f"ship: missing key(s) {missing} (or give a preset name: ffg7, thesis)")
        kw: dict[str, Any] = {k: (str(v) if k == "name" else _number(f"ship.{k}", v)) for k, v in value.items()}
        return ShipParticulars(**kw)
    raise ConfigError(f"ship must be a preset name or a mapping of particulars, got {value!r}")


def _noise(where: str, value: Any, default: FilteredNoise, sigma_key: str, to_internal: float) -> FilteredNoise:
    if value is None:
        return default
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where} must be a mapping with {sigma_key}, period_s, damping_ratio")
    _check_keys(where, value, {sigma_key, "period_s", "damping_ratio"})
    return FilteredNoise(
        sigma=_number(f"{where}.{sigma_key}", value.get(sigma_key, default.sigma / to_internal)) * to_internal,
        period_s=_number(f"{where}.period_s", value.get("period_s", default.period_s)),
        damping_ratio=_number(f"{where}.damping_ratio", value.get("damping_ratio", default.damping_ratio)),
    )


def parse_sea_run(mapping: Mapping[str, Any] | None) -> SeaRun:
    """Validate a configuration mapping (see the module docstring) into a :class:`SeaRun`."""
    m: Mapping[str, Any] = mapping or {}
    if not isinstance(m, Mapping):
        raise ConfigError(f"a motion configuration must be a mapping, got {type(m).__name__}")
    _check_keys("motion config", m, _TOP_KEYS)
    s: Mapping[str, Any] = m.get("sea") or {}
    if not isinstance(s, Mapping):
        raise ConfigError("sea must be a mapping")
    _check_keys("sea", s, _SEA_KEYS)
    code = s.get("sea_state", 6)
    sea_state_row(code)
    try:
        kind = SpectrumKind(s.get("spectrum", "jonswap"))
    except ValueError:
        raise ConfigError(f"sea.spectrum must be one of {[k.value for k in SpectrumKind]}, "
                          f"got {s.get('spectrum')!r}") from None
    hs = s.get("hs_m")
    tp = s.get("tp_s")
    spectrum = spectrum_for_sea_state(
        code, hs_m=None if hs is None else _number("sea.hs_m", hs),
        tp_s=None if tp is None else _number("sea.tp_s", tp),
        kind=kind, gamma=_number("sea.gamma", s.get("gamma", 3.3)),
    )
    drift = _noise("sea.drift", s.get("drift"), default_drift(), "sigma_m", 1.0)
    offset = s.get("deck_offset_m", (0.0, 0.0, 0.0))
    if not isinstance(offset, (list, tuple)) or len(offset) != 3:
        raise ConfigError(f"sea.deck_offset_m must be a list of 3 numbers, got {offset!r}")
    n_comp = s.get("n_components", 600)
    if isinstance(n_comp, bool) or not isinstance(n_comp, int):
        raise ConfigError(f"sea.n_components must be an integer, got {n_comp!r}")
    sea = IrregularSea(
        spectrum=spectrum,
        heading_rad=math.radians(_number("sea.heading_deg", s.get("heading_deg", 135.0))),
        speed_m_s=_number("sea.speed_kn", s.get("speed_kn", 15.0)) / KNOTS_PER_M_S,
        n_components=n_comp,
        yaw=_noise("sea.yaw", s.get("yaw"), default_yaw(), "sigma_deg", math.pi / 180.0),
        surge=drift,
        sway=drift,
        deck_offset_m=tuple(_number("sea.deck_offset_m", v) for v in offset),  # type: ignore[arg-type]
    )
    return SeaRun(
        ship=_ship(m.get("ship", "ffg7")), sea=sea, sea_state=int(code),
        duration_s=_number("duration_s", m.get("duration_s", 600.0)),
        dt_s=_number("dt_s", m.get("dt_s", 0.1)), seed=m.get("seed", 0),
    )


def _tidy(x: float) -> float:
    """Drop the last-bit noise of a unit round trip (135.00000000000003 -> 135.0)."""
    return float(f"{x:.12g}")


def sea_run_to_mapping(run: SeaRun) -> dict[str, Any]:
    """The run as a fully resolved configuration mapping (the schema of :func:`parse_sea_run`)."""
    sea = run.sea
    if sea.surge != sea.sway:
        raise ConfigError("the configuration schema has one drift for surge and sway; they differ here")
    return {
        "ship": run.ship.as_dict(),
        "sea": {
            "sea_state": run.sea_state,
            "spectrum": sea.spectrum.kind.value,
            "hs_m": sea.spectrum.hs_m,
            "tp_s": sea.spectrum.tp_s,
            "gamma": sea.spectrum.gamma,
            "heading_deg": _tidy(math.degrees(sea.heading_rad)),
            "speed_kn": _tidy(sea.speed_m_s * KNOTS_PER_M_S),
            "n_components": sea.n_components,
            "yaw": {"sigma_deg": _tidy(math.degrees(sea.yaw.sigma)), "period_s": sea.yaw.period_s,
                    "damping_ratio": sea.yaw.damping_ratio},
            "drift": {"sigma_m": sea.surge.sigma, "period_s": sea.surge.period_s,
                      "damping_ratio": sea.surge.damping_ratio},
            "deck_offset_m": list(sea.deck_offset_m),
        },
        "duration_s": run.duration_s,
        "dt_s": run.dt_s,
        "seed": run.seed,
    }
