"""The tracker's configuration: parsed once (YAML or defaults) into a frozen, validated record.

Schema (every key optional; defaults in the records)::

    model:                    # DeckMotionModel: the oscillator bank and slow channels
      periods_s: [5, 6.5, 8, 10, 12.5, 16, 20]
      damping_ratio: 0.08
      roll_sigma_deg: 4.0
      ...
    landing:                  # LandingLimits: the landing-window indicator
      roll_deg: 3.0
      pitch_deg: 2.0
      heave_rate_m_per_s: 0.5
      window_s: 3.0
      step_s: 0.25
      confidence: 0.95
    sea:                      # SeaPrior, optional: fit the bank's sigmas to this sea's response spectra
      sea_state: 6
      heading_deg: 135
      speed_kn: 15
      ship: ffg7
    gate_probability: 0.9999  # chi-square gate on each estimate (6 dof); 1 = no gate
    reacquire_after: 10       # gated estimates in a row before the next is applied ungated
    horizons_s: [0.5, 1, 2, 5]
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Any

from deckpose.errors import ConfigError
from deckpose.tracking.deck_motion_model import DeckMotionModel
from deckpose.tracking.landing_window import LandingLimits
from deckpose.tracking.sea_prior import SeaPrior, model_for_sea
from deckpose.typed_config import check_range, from_mapping, load_yaml

__all__ = ["TRACKERS", "TrackConfig", "load_track_config", "track_config_to_mapping"]

#: Tracker names (``deckpose track --method``): the wave-frequency oscillator bank filter.
TRACKERS = ("wave-bank",)


@dataclass(frozen=True)
class TrackConfig:
    """Everything ``deckpose track`` needs besides the run.

    Attributes
    ----------
    model : DeckMotionModel
        With ``sea`` given and no per-oscillator sigmas in it, its roll, pitch and heave
        oscillators' sigmas are fitted to that sea (:func:`~deckpose.tracking.sea_prior.model_for_sea`)
        when the config is made; the resolved config records the fitted sigmas.
    landing : LandingLimits
    sea : SeaPrior or None
        The sea the ship is in, as the operator knows it (not a realisation of it); None: the
        model's sigmas as given (equal shares of each channel's sigma by default).
    gate_probability : float
        Probability mass of the chi-square gate on each estimate (6 dof), in (0, 1]; 1 = no gate.
    reacquire_after : int
        Usable estimates gated out in a row before the next one is applied ungated.
    horizons_s : tuple of float
        Prediction horizons written per frame, seconds (> 0).
    """

    model: DeckMotionModel = DeckMotionModel()
    landing: LandingLimits = LandingLimits()
    sea: SeaPrior | None = None
    gate_probability: float = 0.9999
    reacquire_after: int = 10
    horizons_s: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)

    def __post_init__(self) -> None:
        check_range(self.gate_probability, "gate_probability", low=0, high=1, low_open=True)
        check_range(self.reacquire_after, "reacquire_after", low=1)
        if not self.horizons_s or any(not (math.isfinite(h) and 0 < h <= 600) for h in self.horizons_s):
            raise ConfigError(f"horizons_s: give a list of horizons in (0, 600] seconds, got {list(self.horizons_s)}")
        m = self.model
        if self.sea is not None and not (m.roll_bank_sigmas_deg or m.pitch_bank_sigmas_deg or m.heave_bank_sigmas_m):
            object.__setattr__(self, "model", model_for_sea(m, self.sea))


def load_track_config(path: str | os.PathLike[str] | None) -> TrackConfig:
    """The tracker config of a YAML file (``None``: the defaults)."""
    if path is None:
        return TrackConfig()
    doc = load_yaml(path, "tracker config")
    return from_mapping(TrackConfig, doc, f"{path}:")


def track_config_to_mapping(config: TrackConfig) -> dict[str, Any]:
    """``config`` fully resolved, as the YAML/JSON mapping :func:`load_track_config` reads back."""
    def plain(v: Any) -> Any:
        return list(v) if isinstance(v, tuple) else v

    return {k: ({kk: plain(vv) for kk, vv in v.items()} if isinstance(v, dict) else plain(v))
            for k, v in dataclasses.asdict(config).items()}
