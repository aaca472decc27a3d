"""Ship motion in irregular (long-crested) seas.

The sea is a sum of many regular waves: the band holding all but 0.1 % of the
spectrum's energy is split into ``n_components`` equal bins, each wave taking
a frequency drawn uniformly inside its bin (so the sum has no short repeat
period), the amplitude ``sqrt(2 S(w) dw)`` and a uniform random phase. Each wave passes
through the closed-form response (:mod:`deckpose.motion.closed_form`, causal
phases, roll scaled by the wave amplitude) at its own encounter frequency, so
for a long series the variance of each motion tends to the frequency-domain
value ``integral |RAO(w)|^2 S(w) dw`` (:func:`predicted_variances`).

Signs (deckpose frame: x bow, y port, z up; positive pitch = bow down): the
closed-form pitch is bow-down in head seas; as the model uses only
``|cos beta|`` we flip it in following seas, where a wave crest reaches the
stern first. Roll and its phase relative to heave are as the model gives them.

Yaw and slow surge/sway drift are second-order filtered noise
(:mod:`deckpose.motion.filtered_noise`); defaults (assumptions, not data):
yaw sigma 1 deg with period 30 s (course keeping under autopilot), surge and
sway sigma 0.5 m with period 60 s (station keeping of ship and hovering UAV).

"Significant" values: the significant *height* (double amplitude, crest to
trough) is ``4 sigma``, the definition of ``Hs = 4 sqrt(m0)``; the significant
*amplitude* (single amplitude, the usual naval seakeeping figure) is half of
it, ``2 sigma``, the figure naval seakeeping criteria usually quote.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError
from deckpose.motion.closed_form import (
    KNOTS_PER_M_S,
    PhaseConvention,
    pitch_sign_bow_down,
    response_amplitudes,
)
from deckpose.motion.filtered_noise import FilteredNoise, filtered_noise
from deckpose.motion.offset import motion_at_offset
from deckpose.motion.series import MotionSeries
from deckpose.motion.ship import ShipParticulars
from deckpose.motion.spectrum import WaveSpectrum, spectrum_for_sea_state

FloatArray = NDArray[np.float64]

#: Lower bound on |encounter frequency| inside the closed form (rad/s); see closed_form.
MIN_ENCOUNTER_RAD_S = 0.1
#: Elements per block of the (time x component) synthesis, to bound memory (~16 MB).
_BLOCK_ELEMENTS = 2_000_000


def default_yaw() -> FilteredNoise:
    """Yaw: sigma 1 deg, period 30 s, damping 0.4 (assumed autopilot course keeping)."""
    return FilteredNoise(sigma=math.radians(1.0), period_s=30.0, damping_ratio=0.4)


def default_drift() -> FilteredNoise:
    """Surge or sway drift: sigma 0.5 m, period 60 s, damping 0.7 (assumed)."""
    return FilteredNoise(sigma=0.5, period_s=60.0, damping_ratio=0.7)


@dataclass(frozen=True)
class IrregularSea:
    """Everything that sets an irregular-sea motion series (besides ship, duration and seed).

    Attributes
    ----------
    spectrum : WaveSpectrum
    heading_rad : float
        Wave heading relative to the ship: pi head seas, 3pi/4 bow quartering,
        pi/2 beam, 0 following.
    speed_m_s : float
        Ship speed (>= 0), m/s.
    n_components : int
        Number of regular waves in the sum (>= 16).
    yaw, surge, sway : FilteredNoise
        Slow channels (sigma in rad for yaw, m for surge and sway; 0 disables).
    deck_offset_m : tuple of 3 float
        Deck centre relative to the centre of gravity, deck frame, metres; the
        series describes the deck centre.
    """

    spectrum: WaveSpectrum
    heading_rad: float
    speed_m_s: float = 0.0
    n_components: int = 600
    yaw: FilteredNoise = field(default_factory=default_yaw)
    surge: FilteredNoise = field(default_factory=default_drift)
    sway: FilteredNoise = field(default_factory=default_drift)
    deck_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not math.isfinite(self.heading_rad):
            raise ConfigError(f"wave heading must be finite, got {self.heading_rad}")
        if not math.isfinite(self.speed_m_s) or self.speed_m_s < 0:
            raise ConfigError(f"ship speed must be >= 0 m/s, got {self.speed_m_s}")
        if int(self.n_components) != self.n_components or self.n_components < 16:
            raise ConfigError(f"n_components must be an integer >= 16, got {self.n_components}")
        off = tuple(float(v) for v in self.deck_offset_m)
        if len(off) != 3 or not all(math.isfinite(v) for v in off):
            raise ConfigError(f"deck_offset_m must be 3 finite numbers, got {self.deck_offset_m!r}")
        object.__setattr__(self, "deck_offset_m", off)


@dataclass(frozen=True)
class WaveComponents:
    """The regular waves of one realisation.

    Attributes
    ----------
    omega_rad_s : (K,) array of float
        Wave frequencies, rad/s.
    amplitude_m : (K,) array of float
        Wave amplitudes, metres.
    phase_rad : (K,) array of float
        Random phases, radians.
    """

    omega_rad_s: FloatArray
    amplitude_m: FloatArray
    phase_rad: FloatArray


def wave_components(spectrum: WaveSpectrum, n_components: int, rng: np.random.Generator) -> WaveComponents:
    """Draw the jittered-frequency, random-phase components of a spectrum.

    Parameters
    ----------
    spectrum : WaveSpectrum
    n_components : int
    rng : numpy.random.Generator
    """
    lo, hi = spectrum.band_rad_s()
    dw = (hi - lo) / n_components
    w = lo + (np.arange(n_components) + rng.uniform(size=n_components)) * dw
    amp = np.sqrt(2.0 * spectrum.density(w) * dw)
    phase = rng.uniform(0.0, 2.0 * math.pi, size=n_components)
    return WaveComponents(w, amp, phase)


def wave_frequency_motion(
    ship: ShipParticulars, sea: IrregularSea, components: WaveComponents, t_s: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Heave (m), pitch (rad) and roll (rad) at the centre of gravity, each (T,)."""
    resp = response_amplitudes(
        ship, components.omega_rad_s, heading_rad=sea.heading_rad, speed_m_s=sea.speed_m_s,
        phase=PhaseConvention.CAUSAL, min_encounter_rad_s=MIN_ENCOUNTER_RAD_S,
    )
    a = components.amplitude_m
    psi = components.phase_rad + resp.heave_phase_rad
    psi4 = components.phase_rad + resp.roll_phase_rad
    h = a * resp.heave_m_per_m
    p = pitch_sign_bow_down(sea.heading_rad) * a * resp.pitch_rad_per_m
    r = a * resp.roll_rad_per_m
    # x(t) = sum_i c_i cos(we_i t) - s_i sin(we_i t); columns: heave, pitch, roll.
    cos_coef = np.stack([h * np.cos(psi), p * np.sin(psi), r * np.cos(psi4)], axis=1)
    sin_coef = np.stack([h * np.sin(psi), -p * np.cos(psi), r * np.sin(psi4)], axis=1)
    we = resp.omega_encounter_rad_s
    out = np.empty((t_s.size, 3))
    block = max(1, _BLOCK_ELEMENTS // we.size)
    for i in range(0, t_s.size, block):
        arg = np.outer(t_s[i:i + block], we)
        out[i:i + block] = np.cos(arg) @ cos_coef - np.sin(arg) @ sin_coef
    return out[:, 0], out[:, 1], out[:, 2]


def irregular_series(
    ship: ShipParticulars,
    sea: IrregularSea,
    *,
    duration_s: float,
    dt_s: float,
    rng: np.random.Generator,
) -> MotionSeries:
    """A seeded irregular-sea motion series of the deck centre.

    Parameters
    ----------
    ship : ShipParticulars
    sea : IrregularSea
    duration_s : float
        Length of the series, seconds (> 0); samples at ``0, dt, ...`` up to it.
    dt_s : float
        Sample step, seconds (> 0).
    rng : numpy.random.Generator
        The only source of randomness: the same state gives the same series.

    Returns
    -------
    MotionSeries
        ZYX roll and pitch from the closed-form model, yaw and surge/sway from
        filtered noise, heave from the model, all moved to ``sea.deck_offset_m``.
    """
    if not math.isfinite(dt_s) or dt_s <= 0:
        raise ConfigError(f"time step must be > 0 s, got {dt_s}")
    if not math.isfinite(duration_s) or duration_s < dt_s:
        raise ConfigError(f"duration must be at least one time step ({dt_s} s), got {duration_s}")
    n = math.floor(duration_s / dt_s + 1e-9) + 1
    t = np.arange(n, dtype=float) * dt_s
    comps = wave_components(sea.spectrum, sea.n_components, rng)
    heave, pitch, roll = wave_frequency_motion(ship, sea, comps, t)
    at_cg = MotionSeries(
        t_s=t, roll_rad=roll, pitch_rad=pitch,
        yaw_rad=filtered_noise(sea.yaw, n, dt_s, rng),
        heave_m=heave,
        surge_m=filtered_noise(sea.surge, n, dt_s, rng),
        sway_m=filtered_noise(sea.sway, n, dt_s, rng),
    )
    if any(sea.deck_offset_m):
        return motion_at_offset(at_cg, sea.deck_offset_m)
    return at_cg


@dataclass(frozen=True)
class MotionVariances:
    """Frequency-domain variances ``integral |RAO|^2 S dw`` at the centre of gravity.

    Attributes
    ----------
    heave_m2 : float
    pitch_rad2 : float
    roll_rad2 : float
    """

    heave_m2: float
    pitch_rad2: float
    roll_rad2: float

    def significant_amplitudes(self) -> dict[str, float]:
        """Significant single amplitudes ``2 sigma``: heave in m, pitch and roll in degrees."""
        return {
            "heave_m": 2.0 * math.sqrt(self.heave_m2),
            "pitch_deg": math.degrees(2.0 * math.sqrt(self.pitch_rad2)),
            "roll_deg": math.degrees(2.0 * math.sqrt(self.roll_rad2)),
        }


def series_significant_amplitudes(series: MotionSeries) -> dict[str, float]:
    """Significant single amplitudes ``2 sigma`` of a series (heave m, pitch and roll deg).

    ``sigma`` is the sample standard deviation about the mean; double these for
    significant heights (``4 sigma``).
    """
    return {
        "heave_m": 2.0 * float(np.std(series.heave_m)),
        "pitch_deg": math.degrees(2.0 * float(np.std(series.pitch_rad))),
        "roll_deg": math.degrees(2.0 * float(np.std(series.roll_rad))),
    }


def ss6_frigate_sea() -> IrregularSea:
    """The sea-state-6 frigate scenario: JONSWAP (gamma 3.3) Hs 5.0 m, Tp 12.4 s,
    bow-quartering seas (heading 135 deg) at 15 knots, deck centre at the centre of gravity.

    Use with :func:`deckpose.motion.ship.ffg7_ship`.
    """
    return IrregularSea(
        spectrum=spectrum_for_sea_state(6), heading_rad=math.radians(135.0),
        speed_m_s=15.0 / KNOTS_PER_M_S,
    )


def predicted_variances(ship: ShipParticulars, sea: IrregularSea, *, nodes_per_piece: int = 128) -> MotionVariances:
    """Variances of heave, pitch and roll predicted in the frequency domain.

    Integrates ``|RAO(w)|^2 S(w)`` over wave frequencies from ``0.05 wp`` to
    ``40 wp`` (all but ~1e-6 of the wave energy) with Gauss-Legendre
    quadrature on pieces split at the spectral peak and at the roll resonance;
    independent of the component draw of :func:`irregular_series`.

    Parameters
    ----------
    ship : ShipParticulars
    sea : IrregularSea
    nodes_per_piece : int
        Quadrature nodes per piece (the default converges to ~1e-8 relative).
    """
    spec = sea.spectrum
    wp = spec.omega_peak_rad_s
    lo, hi = 0.05 * wp, 40.0 * wp
    edges = [lo, 0.5 * wp, 0.7 * wp, 0.85 * wp, wp, 1.15 * wp, 1.4 * wp, 2.0 * wp, 3.0 * wp,
             5.0 * wp, 10.0 * wp, 20.0 * wp, hi]
    # Roll resonance: the wave frequencies whose encounter frequency is the roll frequency.
    w4 = 2.0 * math.pi / ship.roll_period_s
    for w in _wave_frequencies_for_encounter(w4, sea.heading_rad, sea.speed_m_s):
        edges += [w * 0.8, w * 0.9, w, w * 1.1, w * 1.25]
    grid = np.array(sorted({e for e in edges if lo <= e <= hi}))
    x, wts = np.polynomial.legendre.leggauss(nodes_per_piece)
    a, b = grid[:-1, None], grid[1:, None]
    w_nodes = (0.5 * (b - a) * x + 0.5 * (b + a)).ravel()
    w_weights = (0.5 * (b - a) * wts).ravel()
    r = response_amplitudes(
        ship, w_nodes, heading_rad=sea.heading_rad, speed_m_s=sea.speed_m_s,
        phase=PhaseConvention.CAUSAL, min_encounter_rad_s=MIN_ENCOUNTER_RAD_S,
    )
    sw = spec.density(w_nodes) * w_weights
    return MotionVariances(
        heave_m2=float(np.sum(r.heave_m_per_m**2 * sw)),
        pitch_rad2=float(np.sum(r.pitch_rad_per_m**2 * sw)),
        roll_rad2=float(np.sum(r.roll_rad_per_m**2 * sw)),
    )


def _wave_frequencies_for_encounter(we: float, heading_rad: float, speed_m_s: float) -> list[float]:
    """Positive wave frequencies w with ``w - w^2 U cos(beta) / g = +-we``."""
    c = speed_m_s * math.cos(heading_rad) / 9.81
    if abs(c) < 1e-12:
        return [we]
    roots = []
    for target in (we, -we):
        disc = 1.0 - 4.0 * c * target
        if disc >= 0:
            for sgn in (1.0, -1.0):
                w = (1.0 + sgn * math.sqrt(disc)) / (2.0 * c)
                if w > 0:
                    roots.append(w)
    return roots
