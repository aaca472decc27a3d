"""Second-order filtered noise: slow, smooth random channels (yaw, surge and sway drift).

A channel is white noise through a damped second-order filter (a randomly
forced mass-spring-damper with damped period ``period_s`` and damping ratio
``damping_ratio``), sampled as the AR(2) process with the filter's poles
``z = exp(s dt)``, scaled to the stationary standard deviation ``sigma`` and
started in its stationary distribution (no transient).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FilteredNoise:
    """A second-order filtered-noise channel.

    Attributes
    ----------
    sigma : float
        Stationary standard deviation, in the channel's unit (rad or m); 0 disables.
    period_s : float
        Damped oscillation period of the filter, seconds.
    damping_ratio : float
        Filter damping as a fraction of critical, in (0, 1).
    """

    sigma: float
    period_s: float
    damping_ratio: float = 0.5

    def __post_init__(self) -> None:
        if not math.isfinite(self.sigma) or self.sigma < 0:
            raise ConfigError(f"filtered-noise sigma must be >= 0, got {self.sigma}")
        if not math.isfinite(self.period_s) or self.period_s <= 0:
            raise ConfigError(f"filtered-noise period must be > 0 s, got {self.period_s}")
        if not 0 < self.damping_ratio < 1:
            raise ConfigError(f"filtered-noise damping ratio must be in (0, 1), got {self.damping_ratio}")


def ar2_coefficients(noise: FilteredNoise, dt_s: float) -> tuple[float, float]:
    """``(a1, a2)`` of ``x[n] = a1 x[n-1] + a2 x[n-2] + e[n]`` for the filter's poles."""
    if not math.isfinite(dt_s) or dt_s <= 0:
        raise ConfigError(f"time step must be > 0 s, got {dt_s}")
    wd = 2.0 * math.pi / noise.period_s
    z = noise.damping_ratio
    decay = z * wd / math.sqrt(1.0 - z * z)  # zeta * omega_n
    r = math.exp(-decay * dt_s)
    return 2.0 * r * math.cos(wd * dt_s), -r * r


def ar2_stationary_variance(a1: float, a2: float) -> float:
    """Stationary variance of the AR(2) process for unit innovation variance."""
    return (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1**2))


def filtered_noise(noise: FilteredNoise, n_samples: int, dt_s: float, rng: np.random.Generator) -> FloatArray:
    """One stationary realisation of the channel.

    Parameters
    ----------
    noise : FilteredNoise
    n_samples : int
        Number of samples (>= 1).
    dt_s : float
        Sample step, seconds.
    rng : numpy.random.Generator

    Returns
    -------
    (n_samples,) array of float
        In the unit of ``noise.sigma``; all zeros when ``sigma == 0`` (``rng`` untouched).
    """
    if n_samples < 1:
        raise ConfigError(f"need at least one sample, got {n_samples}")
    if noise.sigma == 0:
        return np.zeros(n_samples)
    a1, a2 = ar2_coefficients(noise, dt_s)
    var_unit = ar2_stationary_variance(a1, a2)
    rho1 = a1 / (1.0 - a2)
    # Start (x0, x1) in the stationary distribution: unit variance, lag-1 correlation rho1.
    x0 = rng.standard_normal()
    x1 = rho1 * x0 + math.sqrt(max(1.0 - rho1 * rho1, 0.0)) * rng.standard_normal()
    out = np.empty(max(n_samples, 2))
    out[0], out[1] = x0, x1
    if n_samples > 2:
        e = rng.standard_normal(n_samples - 2) / math.sqrt(var_unit)
        from scipy import signal  # here: its import slowed every deckpose command's start

        zi = signal.lfiltic([1.0], [1.0, -a1, -a2], y=[x1, x0])
        out[2:], _ = signal.lfilter([1.0], [1.0, -a1, -a2], e, zi=zi)
    return noise.sigma * out[:n_samples]
