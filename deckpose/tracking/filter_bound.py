"""The least error any causal filter can reach on a stationary Gaussian signal in white noise.

A signal ``s`` of spectral density ``S`` sampled every ``dt`` and measured as
``y_k = s_k + v_k`` with white ``v`` of variance ``r``: the best estimate of ``s_k`` from
``y_k, y_{k-1}, ...`` (linear, which for Gaussians is the best of all) has the error variance
``r - r^2 / sigma_e^2``, where ``sigma_e^2`` is the variance of the one-step prediction error of
``y``, given by the Kolmogorov-Szego formula ``exp((1 / 2 pi) integral log f_y(theta) d theta)``
over the sampled spectrum ``f_y = f_s + r``. It needs no model: only the signal's spectrum
(for a ship, :func:`deckpose.tracking.sea_prior.encounter_spectra` of the sea) and the noise.
Any filter, however its model is made, can do no better; a filter whose model is the signal's
spectrum exactly reaches it (the Kalman filter's steady state, which the tests check).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["optimal_filtered_variance"]

#: Nodes of the integral over the sampled spectrum's band (-pi, pi].
_THETA_NODES = 1 << 16


def optimal_filtered_variance(omega_rad_s: NDArray[np.float64], density: NDArray[np.float64],
                              noise_var: NDArray[np.float64] | float, dt_s: float) -> NDArray[np.float64]:
    """Least error variance of a causal filter on a signal of spectrum ``density`` in white noise.

    Parameters
    ----------
    omega_rad_s : (M,) array of float
        Increasing frequencies, rad/s, covering the signal's band.
    density : (M,) array of float
        The signal's one-sided spectral density on them (its variance is ``integral density d omega``);
        taken as zero outside them and below the Nyquist frequency ``pi / dt_s`` (no aliasing).
    noise_var : float or (K,) array of float
        Variance of the white measurement noise per sample (> 0).
    dt_s : float
        Sample interval, seconds.

    Returns
    -------
    (K,) array of float
        The filtered (a posteriori: using the current sample) error variance for each noise variance.
    """
    theta = (np.arange(_THETA_NODES) + 0.5) / _THETA_NODES * math.pi        # (0, pi): the spectrum is even
    omega = theta / dt_s
    s1 = np.interp(omega, np.asarray(omega_rad_s, float), np.asarray(density, float), left=0.0, right=0.0)
    # sampled two-sided density: f(theta) = (2 pi / dt) S2(theta / dt), S2 = S1 / 2 (one- to two-sided)
    f_s = math.pi / dt_s * s1
    r = np.atleast_1d(np.asarray(noise_var, float))
    log_mean = np.array([float(np.mean(np.log(f_s + ri))) for ri in r])     # (1 / pi) integral over (0, pi)
    sigma_e2 = np.exp(log_mean)
    return np.asarray(r - r * r / sigma_e2, dtype=np.float64)
