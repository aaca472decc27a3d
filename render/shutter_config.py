"""The ``shutter:`` section of a render config: rolling shutter and the UAV's motion in a frame."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from deckpose.typed_config import check_range, from_mapping

__all__ = ["Readout", "ShutterSpec", "shutter_spec"]


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


def shutter_spec(doc: object, where: str = "shutter") -> ShutterSpec:
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
