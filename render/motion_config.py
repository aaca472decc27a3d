"""The ``motion:`` section of a render config: where the ship poses come from."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["MotionSource", "MotionSpec", "motion_spec"]


class MotionSource(enum.Enum):
    FIXED = "fixed"
    FILE = "file"
    THESIS = "thesis"
    SEA_STATE = "sea_state"


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


def motion_spec(doc: object, where: str = "motion") -> MotionSpec:
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
