"""Sea states and wave spectra.

Sea states follow the Douglas / WMO scale of the thesis's table 4.1
(significant wave height ranges). The thesis prints 2.4-4.0 m for state 5;
we use 2.5-4.0 m so the ranges tile (the WMO code). For each state the
*default* significant height and peak period are the "most probable" values
of the open-ocean North Atlantic table of Lee & Bales (1980), reproduced in
Price & Bishop and in Fossen's *Handbook of Marine Craft Hydrodynamics and
Motion Control*: for sea state 6, Hs = 5.0 m and Tp = 12.4 s. That table has no
peak period for states 0-1 and only "> 14 m" for state 9: our state-1 period
(2.0 s) and state-9 height (16.0 m) are assumptions.

Spectra (one-sided, in wave frequency omega, m^2 s/rad), both set by the
significant height ``Hs = 4 sqrt(m0)`` and the peak period ``Tp``:

* Pierson-Moskowitz / Bretschneider (two-parameter):
  ``S(w) = 5/16 Hs^2 wp^4 w^-5 exp(-5/4 (wp/w)^4)``, whose ``m0`` is exactly ``Hs^2/16``;
* JONSWAP: the same times ``gamma ** exp(-(w - wp)^2 / (2 s^2 wp^2))`` with
  ``s = 0.07`` below and ``0.09`` above the peak, ``gamma = 3.3`` by default,
  scaled numerically so that ``m0 = Hs^2/16`` exactly.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import integrate

from deckpose.errors import ConfigError

FloatArray = NDArray[np.float64]


class SpectrumKind(Enum):
    """The wave-spectrum shape."""

    JONSWAP = "jonswap"
    PIERSON_MOSKOWITZ = "pm"  #: Pierson-Moskowitz / two-parameter Bretschneider


@dataclass(frozen=True)
class SeaStateRow:
    """One row of the sea-state table.

    Attributes
    ----------
    code : int
        Douglas / WMO sea state, 1..9.
    description : str
    hs_min_m, hs_max_m : float
        Significant wave height range, metres (``hs_max_m`` is ``inf`` for state 9): the
        half-open interval ``hs_min_m < Hs <= hs_max_m``, as the Douglas and WMO tables
        read ("over 1.25 to 2.5 m"), so every height belongs to exactly one state and a
        boundary height to the lower one (2.5 m is sea state 4, not 5).
    hs_default_m, tp_default_s : float
        Default ("most probable") significant height and peak period.
    """

    code: int
    description: str
    hs_min_m: float
    hs_max_m: float
    hs_default_m: float
    tp_default_s: float

    def contains(self, hs_m: float) -> bool:
        """Whether a significant wave height of ``hs_m`` metres is in this state's range."""
        return self.hs_min_m < hs_m <= self.hs_max_m


SEA_STATES: tuple[SeaStateRow, ...] = (
    SeaStateRow(1, "Calm (ripples)", 0.0, 0.1, 0.05, 2.0),
    SeaStateRow(2, "Smooth (wavelets)", 0.1, 0.5, 0.3, 7.5),
    SeaStateRow(3, "Slight", 0.5, 1.25, 0.88, 7.5),
    SeaStateRow(4, "Moderate", 1.25, 2.5, 1.88, 8.8),
    SeaStateRow(5, "Rough", 2.5, 4.0, 3.25, 9.7),
    SeaStateRow(6, "Very rough", 4.0, 6.0, 5.0, 12.4),
    SeaStateRow(7, "High", 6.0, 9.0, 7.5, 15.0),
    SeaStateRow(8, "Very high", 9.0, 14.0, 11.5, 16.4),
    SeaStateRow(9, "Phenomenal", 14.0, math.inf, 16.0, 20.0),
)


def sea_state_row(code: int) -> SeaStateRow:
    """The table row of sea state ``code`` (1..9)."""
    if isinstance(code, bool) or not isinstance(code, (int, np.integer)) or not 1 <= code <= 9:
        raise ConfigError(f"sea state must be an integer from 1 to 9 (Douglas scale), got {code!r}")
    return SEA_STATES[int(code) - 1]


def sea_state_of(hs_m: float) -> SeaStateRow:
    """The sea state whose range holds a significant wave height of ``hs_m`` metres (> 0)."""
    if not (math.isfinite(hs_m) and hs_m > 0):
        raise ConfigError(f"significant wave height must be a finite height > 0 m, got {hs_m!r}")
    return next(row for row in SEA_STATES if row.contains(hs_m))


@dataclass(frozen=True)
class WaveSpectrum:
    """A parametric wave spectrum.

    Attributes
    ----------
    hs_m : float
        Significant wave height, 4 sqrt(m0), metres (> 0).
    tp_s : float
        Peak period, seconds (> 0).
    kind : SpectrumKind
    gamma : float
        JONSWAP peak enhancement (>= 1; ignored for Pierson-Moskowitz).
    """

    hs_m: float
    tp_s: float
    kind: SpectrumKind = SpectrumKind.JONSWAP
    gamma: float = 3.3

    def __post_init__(self) -> None:
        if not math.isfinite(self.hs_m) or self.hs_m <= 0:
            raise ConfigError(f"significant wave height must be > 0 m, got {self.hs_m}")
        if not math.isfinite(self.tp_s) or self.tp_s <= 0:
            raise ConfigError(f"peak period must be > 0 s, got {self.tp_s}")
        if not isinstance(self.kind, SpectrumKind):
            raise ConfigError(f"spectrum kind must be a SpectrumKind, got {self.kind!r}")
        if not math.isfinite(self.gamma) or self.gamma < 1:
            raise ConfigError(f"JONSWAP gamma must be >= 1, got {self.gamma}")

    @property
    def omega_peak_rad_s(self) -> float:
        return 2.0 * math.pi / self.tp_s

    def density(self, omega_rad_s: ArrayLike) -> FloatArray:
        """Spectral density S(omega), m^2 s/rad; zero at omega <= 0."""
        w = np.asarray(omega_rad_s, dtype=float)
        shape = _unit_shape(w / self.omega_peak_rad_s, self.kind, self.gamma)
        return (self.hs_m**2 / 16.0) / self.omega_peak_rad_s * shape / _unit_m0(self.kind, self.gamma)

    def band_rad_s(self, energy_fraction_lost: float = 1e-3) -> tuple[float, float]:
        """A frequency band holding all but about ``energy_fraction_lost`` of m0.

        Uses the Pierson-Moskowitz tails (JONSWAP's peak makes its tails lighter):
        the energy above ``w`` is ``1 - exp(-5/4 (wp/w)^4)`` of m0.
        """
        wp = self.omega_peak_rad_s
        hi = wp * (1.25 / -math.log1p(-energy_fraction_lost)) ** 0.25
        return 0.55 * wp, hi


def _unit_shape(x: FloatArray, kind: SpectrumKind, gamma: float) -> FloatArray:
    """Unnormalised spectrum shape in ``x = w / wp``: ``x^-5 exp(-5/4 x^-4)`` [times the JONSWAP peak]."""
    out = np.zeros_like(x, dtype=float)
    pos = x > 0
    xp = x[pos]
    s = np.exp(-1.25 * xp**-4) / xp**5
    if kind is SpectrumKind.JONSWAP:
        sig = np.where(xp <= 1.0, 0.07, 0.09)
        s = s * gamma ** np.exp(-((xp - 1.0) ** 2) / (2.0 * sig**2))
    out[pos] = s
    return out


@functools.lru_cache(maxsize=64)
def _unit_m0(kind: SpectrumKind, gamma: float) -> float:
    """Integral of :func:`_unit_shape` over x in (0, inf)."""
    if kind is SpectrumKind.PIERSON_MOSKOWITZ or gamma == 1.0:
        return 0.2  # int x^-5 exp(-5/4 x^-4) dx = 1/5
    f = lambda x: float(_unit_shape(np.array([x]), kind, gamma)[0])
    pieces = [(0.0, 0.7), (0.7, 1.0), (1.0, 1.5), (1.5, 4.0), (4.0, math.inf)]
    return sum(integrate.quad(f, a, b, limit=200, epsabs=1e-13, epsrel=1e-11)[0] for a, b in pieces)


def spectrum_for_sea_state(
    code: int,
    *,
    hs_m: float | None = None,
    tp_s: float | None = None,
    kind: SpectrumKind = SpectrumKind.JONSWAP,
    gamma: float = 3.3,
) -> WaveSpectrum:
    """The wave spectrum of a sea state, with its default Hs and Tp unless given.

    Parameters
    ----------
    code : int
        Sea state, 1..9.
    hs_m : float, optional
        Significant height; must lie in the state's range.
    tp_s : float, optional
        Peak period, seconds.
    kind : SpectrumKind
    gamma : float
        JONSWAP peak enhancement.
    """
    row = sea_state_row(code)
    hs = row.hs_default_m if hs_m is None else float(hs_m)
    if not math.isfinite(hs) or hs <= 0:
        raise ConfigError(f"significant wave height must be > 0 m, got {hs}")
    if not row.contains(hs):
        raise ConfigError(
            f"Hs = {hs} m is outside sea state {row.code} ({row.description}: over "
            f"{row.hs_min_m} up to {row.hs_max_m} m); it is sea state {sea_state_of(hs).code}: "
            "pick that sea state or omit Hs"
        )
    tp = row.tp_default_s if tp_s is None else float(tp_s)
    return WaveSpectrum(hs_m=hs, tp_s=tp, kind=kind, gamma=gamma)
