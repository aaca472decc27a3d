"""Closed-form heave, pitch and roll of a ship in regular waves.

The model of Jensen, Mansour & Olsen (2004), "Estimation of ship motions using
closed-form expressions", Ocean Engineering 31 (as in Fossen's Marine Systems
Simulator), written exactly as specified in
``docs/THESIS_IMPLEMENTATION.md`` ("The closed-form ship response").

Regular waves of amplitude ``a`` and frequency ``omega0`` meet the ship at
heading ``beta`` (180 deg = head seas, 90 deg = beam seas, 0 = following seas;
the model uses only ``|cos beta|`` and ``sin beta``) and speed ``U``. The responses
at the centre of gravity are::

    heave(t) = a * H3 * cos(we t + eps)
    pitch(t) = a * H5 * sin(we t + eps)       (radians)
    roll(t)  = a * H4 * cos(we t + eps4)      (radians)

with the encounter frequency ``we = omega0 - omega0**2 U cos(beta) / g``.

Two faithful-to-the-source details are kept as options:

* phases: the published code uses a plain ``atan`` for ``eps`` and ``eps4``,
  which jumps by pi through resonance (:attr:`PhaseConvention.THESIS`); the
  causal lag of a second-order system, ``atan2``, in [0, pi], is
  :attr:`PhaseConvention.CAUSAL`. Amplitudes are identical.
* the published code does not multiply roll by the wave amplitude (its roll is
  that of a 1 m wave); :func:`thesis_regular_response` reproduces that, while
  :func:`regular_wave_response` scales roll by ``a`` like heave and pitch.

Small encounter frequencies make the roll excitation singular (it grows like
``we**-0.5``); :func:`response_amplitudes` evaluates the model at
``max(|we|, min_encounter_rad_s)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from deckpose.errors import ConfigError
from deckpose.motion.series import MotionSeries
from deckpose.motion.ship import ShipParticulars

FloatArray = NDArray[np.float64]

#: Gravity, m/s^2, and sea-water density, kg/m^3 (the values of the published code).
GRAVITY_M_S2 = 9.81
RHO_SEA_KG_M3 = 1025.0
#: Knots per metre per second (the published code's factor).
KNOTS_PER_M_S = 1.94384


class PhaseConvention(Enum):
    """How the response phases ``eps`` are computed."""

    THESIS = "thesis"  #: plain atan, as published (jumps by pi at resonance)
    CAUSAL = "causal"  #: atan2: the lag of a second-order system, in [0, pi]


@dataclass(frozen=True)
class ResponseAmplitudes:
    """Closed-form responses per metre of wave amplitude, one entry per wave frequency.

    Attributes
    ----------
    omega_wave_rad_s : (K,) array of float
        Wave frequencies omega0, rad/s.
    omega_encounter_rad_s : (K,) array of float
        Signed encounter frequencies, rad/s (negative: the ship overtakes the waves).
    heave_m_per_m : (K,) array of float
        Heave amplitude H3 per metre of wave amplitude (signed, as the model gives it).
    pitch_rad_per_m : (K,) array of float
        Pitch amplitude H5, radians per metre of wave amplitude.
    roll_rad_per_m : (K,) array of float
        Roll amplitude H4, radians per metre of wave amplitude.
    heave_phase_rad, roll_phase_rad : (K,) array of float
        ``eps`` (heave and pitch) and ``eps4`` (roll).
    """

    omega_wave_rad_s: FloatArray
    omega_encounter_rad_s: FloatArray
    heave_m_per_m: FloatArray
    pitch_rad_per_m: FloatArray
    roll_rad_per_m: FloatArray
    heave_phase_rad: FloatArray
    roll_phase_rad: FloatArray

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            arr = np.array(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


def _sinc_terms(sigma: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``sin(s)/s`` and ``(1/s)(sin(s)/s - cos(s))``, with series near ``s = 0`` (beam seas)."""
    small = np.abs(sigma) < 1e-4
    s = np.where(small, 1.0, sigma)
    sinc = np.where(small, 1.0 - sigma**2 / 6.0, np.sin(s) / s)
    pitch_term = np.where(small, sigma / 3.0 - sigma**3 / 30.0, (np.sin(s) / s - np.cos(s)) / s)
    return sinc, pitch_term


def _phase(num: FloatArray, den: FloatArray, convention: PhaseConvention) -> FloatArray:
    if convention is PhaseConvention.THESIS:
        with np.errstate(divide="ignore"):
            return np.arctan(num / den)
    return np.arctan2(num, den)


def response_amplitudes(
    ship: ShipParticulars,
    omega_wave_rad_s: ArrayLike,
    *,
    heading_rad: float,
    speed_m_s: float = 0.0,
    phase: PhaseConvention = PhaseConvention.CAUSAL,
    min_encounter_rad_s: float = 0.0,
) -> ResponseAmplitudes:
    """Closed-form response amplitudes (RAOs) and phases for regular waves.

    Parameters
    ----------
    ship : ShipParticulars
    omega_wave_rad_s : (K,) array_like of float
        Wave frequencies (> 0), rad/s.
    heading_rad : float
        Wave heading relative to the ship, radians (pi = head seas, 0 = following).
    speed_m_s : float
        Forward speed (>= 0), m/s.
    phase : PhaseConvention
        ``THESIS`` for the published plain-atan phases.
    min_encounter_rad_s : float
        Lower bound on ``|we|`` used inside the model (0: none; the published code
        needs none because it never meets ``we = 0``).

    Returns
    -------
    ResponseAmplitudes
    """
    w0 = np.atleast_1d(np.asarray(omega_wave_rad_s, dtype=float))
    if w0.ndim != 1 or not np.all(np.isfinite(w0)) or np.any(w0 <= 0):
        raise ConfigError("wave frequencies must be a 1-D array of positive numbers (rad/s)")
    if not math.isfinite(heading_rad):
        raise ConfigError(f"heading must be finite, got {heading_rad}")
    if not math.isfinite(speed_m_s) or speed_m_s < 0:
        raise ConfigError(f"ship speed must be >= 0 m/s, got {speed_m_s}")
    g, rho = GRAVITY_M_S2, RHO_SEA_KG_M3
    L, B, T = ship.length_m, ship.beam_m, ship.draught_m
    cb = math.cos(heading_rad)
    k = w0**2 / g
    we_signed = w0 - k * speed_m_s * cb
    we = np.maximum(np.abs(we_signed), min_encounter_rad_s)
    if np.any(we == 0):
        raise ConfigError(
            "the encounter frequency is zero for some wave (following seas at the wave speed); "
            "set min_encounter_rad_s > 0 or change speed/heading"
        )
    ke = np.abs(k * cb)
    sigma = ke * L / 2.0
    kappa = np.exp(-ke * T)
    r = we / w0
    A = 2.0 * np.sin(k * B * r**2 / 2.0) * np.exp(-k * T * r**2)
    f = np.sqrt((1.0 - k * T) ** 2 + (A**2 / (k * B * r**3)) ** 2)
    sinc, pitch_term = _sinc_terms(sigma)
    F = kappa * f * sinc
    G = kappa * f * (6.0 / L) * pitch_term
    wn = math.sqrt(g / (2.0 * T))
    zeta = (A**2 / (B * r**3)) * np.sqrt(1.0 / (8.0 * k**3 * T))
    s = np.sqrt((2.0 * wn * zeta) ** 2 + (wn**2 - we**2) ** 2 / we**2)
    eps = _phase(2.0 * we * wn * zeta, wn**2 - we**2, phase)
    # Roll
    w4 = 2.0 * math.pi / ship.roll_period_s
    z4 = ship.roll_damping_ratio
    C44 = rho * g * ship.displaced_volume_m3 * ship.gm_m
    M44 = C44 / w4**2
    B44 = 2.0 * z4 * w4 * M44
    M = math.sin(heading_rad) * np.sqrt(B44 * rho * g**2 / we)
    s4 = np.sqrt((2.0 * w4 * z4) ** 2 + (w4**2 - we**2) ** 2 / we**2)
    eps4 = _phase(2.0 * we * w4 * z4, w4**2 - we**2, phase)
    return ResponseAmplitudes(
        omega_wave_rad_s=w0,
        omega_encounter_rad_s=we_signed,
        heave_m_per_m=F * wn**2 / (s * we),
        pitch_rad_per_m=G * wn**2 / (s * we),
        roll_rad_per_m=(M / C44) * w4**2 / (s4 * we),
        heave_phase_rad=eps,
        roll_phase_rad=eps4,
    )


@dataclass(frozen=True)
class RegularWave:
    """A regular wave train: amplitude, period, heading relative to the ship, ship speed.

    Attributes
    ----------
    amplitude_m : float
        Wave amplitude (half the height), metres (>= 0).
    period_s : float
        Wave period T0, seconds (> 0).
    heading_rad : float
        pi = head seas, 0 = following seas.
    speed_m_s : float
        Ship speed (>= 0), m/s.
    """

    amplitude_m: float
    period_s: float
    heading_rad: float
    speed_m_s: float = 0.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.amplitude_m) or self.amplitude_m < 0:
            raise ConfigError(f"wave amplitude must be >= 0 m, got {self.amplitude_m}")
        if not math.isfinite(self.period_s) or self.period_s <= 0:
            raise ConfigError(f"wave period must be > 0 s, got {self.period_s}")
        if not math.isfinite(self.heading_rad):
            raise ConfigError(f"wave heading must be finite, got {self.heading_rad}")
        if not math.isfinite(self.speed_m_s) or self.speed_m_s < 0:
            raise ConfigError(f"ship speed must be >= 0 m/s, got {self.speed_m_s}")


@dataclass(frozen=True)
class RegularResponse:
    """Heave, pitch and roll over time in one regular wave (closed-form model's own angles).

    Attributes
    ----------
    t_s : (T,) array of float
    heave_m, pitch_rad, roll_rad : (T,) array of float
    """

    t_s: FloatArray
    heave_m: FloatArray
    pitch_rad: FloatArray
    roll_rad: FloatArray


def _regular(
    ship: ShipParticulars, wave: RegularWave, t_s: ArrayLike, phase: PhaseConvention, roll_scale: float
) -> RegularResponse:
    t = np.asarray(t_s, dtype=float)
    resp = response_amplitudes(
        ship, [2.0 * math.pi / wave.period_s], heading_rad=wave.heading_rad,
        speed_m_s=wave.speed_m_s, phase=phase,
    )
    we = resp.omega_encounter_rad_s[0]
    a = wave.amplitude_m
    arg = we * t + resp.heave_phase_rad[0]
    return RegularResponse(
        t_s=t,
        heave_m=a * resp.heave_m_per_m[0] * np.cos(arg),
        pitch_rad=a * resp.pitch_rad_per_m[0] * np.sin(arg),
        roll_rad=roll_scale * resp.roll_rad_per_m[0] * np.cos(we * t + resp.roll_phase_rad[0]),
    )


def regular_wave_response(
    ship: ShipParticulars,
    wave: RegularWave,
    t_s: ArrayLike,
    *,
    phase: PhaseConvention = PhaseConvention.CAUSAL,
) -> RegularResponse:
    """Physical closed-form response: all three motions scale with the wave amplitude.

    Parameters
    ----------
    ship : ShipParticulars
    wave : RegularWave
    t_s : (T,) array_like of float
        Times, seconds.
    phase : PhaseConvention
    """
    return _regular(ship, wave, t_s, phase, roll_scale=wave.amplitude_m)


def thesis_regular_response(ship: ShipParticulars, wave: RegularWave, t_s: ArrayLike) -> RegularResponse:
    """The response exactly as the published code computes it.

    Plain-atan phases, and roll *not* scaled by the wave amplitude (roll of a 1 m wave).
    """
    return _regular(ship, wave, t_s, PhaseConvention.THESIS, roll_scale=1.0)


def pitch_sign_bow_down(heading_rad: float) -> float:
    """Factor turning the model's pitch into deckpose pitch (positive = bow down).

    The closed-form pitch is bow-down in head seas (``cos beta < 0``); the model
    uses only ``|cos beta|``, so in following seas (``cos beta > 0``), where a
    crest reaches the stern first, the sign flips.
    """
    return -1.0 if math.cos(heading_rad) > 0 else 1.0


def regular_series(
    ship: ShipParticulars, wave: RegularWave, *, duration_s: float, dt_s: float
) -> MotionSeries:
    """Physical regular-wave motion as a :class:`MotionSeries` (yaw, surge, sway zero).

    Causal phases, roll scaled by the wave amplitude, pitch positive bow down
    (:func:`pitch_sign_bow_down`); the small angles are used as ZYX roll and pitch.

    Parameters
    ----------
    ship : ShipParticulars
    wave : RegularWave
    duration_s, dt_s : float
        Samples at ``0, dt, ...`` up to ``duration_s``, seconds.
    """
    if not math.isfinite(dt_s) or dt_s <= 0:
        raise ConfigError(f"time step must be > 0 s, got {dt_s}")
    if not math.isfinite(duration_s) or duration_s < dt_s:
        raise ConfigError(f"duration must be at least one time step ({dt_s} s), got {duration_s}")
    t = np.arange(math.floor(duration_s / dt_s + 1e-9) + 1, dtype=float) * dt_s
    r = regular_wave_response(ship, wave, t)
    return MotionSeries(
        t_s=t, roll_rad=r.roll_rad, pitch_rad=pitch_sign_bow_down(wave.heading_rad) * r.pitch_rad,
        yaw_rad=np.zeros_like(t), heave_m=r.heave_m,
    )
