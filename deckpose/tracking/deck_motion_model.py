"""The deck-motion model of the tracker: a linear-Gaussian state-space model of ship and UAV motion.

Roll, pitch and heave of a ship in waves are narrow-band processes near the wave encounter
and roll frequencies; each is modelled as the sum of a bank of damped oscillators driven by
white noise (one per period of :attr:`DeckMotionModel.periods_s`), roll and pitch plus a slow
random-walk offset (a static heel or trim). Yaw, the deck centre's horizontal position
relative to the camera (surge, sway) and the camera's height above the nominal deck centre
(the UAV's own descent) are near-constant-velocity models (white acceleration).

State layout (:func:`state_slices`), metres and radians, per second for rates::

    roll:   offset, (p_k, v_k) for k in the bank      pitch: the same
    heave:  (p_k, v_k) for k in the bank               (deck displacement up)
    yaw, surge, sway, uav_height: (position, rate)

The measurement is a per-frame estimate in :data:`deckpose.records.POSE_PARAMS` order:
roll, pitch, yaw, surge, sway (deck centre minus camera), height (camera above the deck
centre) = uav_height - heave.

Discretisation is exact for any step: an oscillator's transition is its closed-form
solution, its process noise ``Q = P_inf - F P_inf F^T`` (``P_inf`` the stationary covariance,
exact for a stationary linear process), a near-constant-velocity block's the classical
``q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``. Tests check both against Van Loan's matrix
exponential (``scipy.linalg.expm``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError

__all__ = ["DeckMotionModel", "Discretisation", "bank_sigmas", "channel_oscillators", "discretise", "measurement_matrix", "ncv_discretisation",
           "oscillator_discretisation", "output_matrix", "prior", "state_size", "state_slices"]

#: Channels of :func:`output_matrix`: what prediction and the landing window use.
DECK_OUTPUTS = ("roll_rad", "pitch_rad", "heave_m", "heave_rate_m_per_s", "height_m")


@dataclass(frozen=True)
class DeckMotionModel:
    """Parameters of the deck-motion model (configs: the tracker's ``model:`` section).

    Attributes
    ----------
    periods_s : tuple of float
        Undamped periods of the oscillator bank, seconds (roll, pitch and heave share them).
        The default spans ship responses from 5 s to 20 s.
    damping_ratio : float
        Damping ratio of every oscillator, in (0, 1).
    roll_sigma_deg, pitch_sigma_deg, heave_sigma_m : float
        Stationary standard deviation of the channel's oscillating part (the bank's
        oscillators share its variance equally unless the channel's ``*_bank_sigmas_*``
        are given), degrees and metres.
    roll_bank_sigmas_deg, pitch_bank_sigmas_deg, heave_bank_sigmas_m : tuple of float
        Stationary standard deviation of each oscillator of the channel, one per period of
        ``periods_s`` (>= 0; 0 leaves that oscillator still), degrees and metres: the
        channel's spectrum as a sum of oscillator spectra (for example fitted to a sea state's
        response spectrum, :mod:`deckpose.tracking.sea_prior`). Empty (the default): equal
        shares of the channel sigma above.
    offset_rate_deg_per_sqrt_s : float
        Random-walk intensity of the roll and pitch offsets, deg / sqrt(s).
    offset_sigma_deg : float
        Prior standard deviation of the offsets, degrees.
    yaw_accel_deg_per_s2, surge_accel_m_per_s2, sway_accel_m_per_s2, height_accel_m_per_s2 : float
        White-acceleration intensities of the near-constant-velocity channels: the
        square root of the noise's spectral density (deg/s^2/sqrt(Hz), m/s^2/sqrt(Hz)).
    position_sigma_m, yaw_sigma_deg, rate_sigma_m_per_s, yaw_rate_sigma_deg_per_s : float
        Prior standard deviations of the near-constant-velocity channels (before the first
        measurement): wide, so the first estimate sets them.
    """

    periods_s: tuple[float, ...] = (5.0, 6.5, 8.0, 10.0, 12.5, 16.0, 20.0)
    damping_ratio: float = 0.08
    roll_sigma_deg: float = 4.0
    pitch_sigma_deg: float = 1.5
    heave_sigma_m: float = 1.0
    roll_bank_sigmas_deg: tuple[float, ...] = ()
    pitch_bank_sigmas_deg: tuple[float, ...] = ()
    heave_bank_sigmas_m: tuple[float, ...] = ()
    offset_rate_deg_per_sqrt_s: float = 0.02
    offset_sigma_deg: float = 2.0
    yaw_accel_deg_per_s2: float = 0.2
    surge_accel_m_per_s2: float = 0.2
    sway_accel_m_per_s2: float = 0.2
    height_accel_m_per_s2: float = 1.0
    position_sigma_m: float = 100.0
    yaw_sigma_deg: float = 180.0
    rate_sigma_m_per_s: float = 10.0
    yaw_rate_sigma_deg_per_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.periods_s:
            raise ConfigError("periods_s: give at least one oscillator period (seconds), e.g. [8, 11, 14]")
        if any(not (math.isfinite(p) and p > 0) for p in self.periods_s):
            raise ConfigError(f"periods_s: every period must be a positive number of seconds, got "
                              f"{list(self.periods_s)}")
        if not 0 < self.damping_ratio < 1:
            raise ConfigError(f"damping_ratio: must lie in (0, 1) (an underdamped oscillator), got "
                              f"{self.damping_ratio:g}")
        for name in ("roll_sigma_deg", "pitch_sigma_deg", "heave_sigma_m", "position_sigma_m", "yaw_sigma_deg",
                     "rate_sigma_m_per_s", "yaw_rate_sigma_deg_per_s", "offset_sigma_deg"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name}: must be a positive number, got {v:g}")
        for name in ("roll_bank_sigmas_deg", "pitch_bank_sigmas_deg", "heave_bank_sigmas_m"):
            v = getattr(self, name)
            if v and (len(v) != len(self.periods_s) or any(not (math.isfinite(x) and x >= 0) for x in v)):
                raise ConfigError(f"{name}: give one sigma >= 0 per period of periods_s ({len(self.periods_s)}), "
                                  f"or none for equal shares; got {list(v)}")
        for name in ("offset_rate_deg_per_sqrt_s", "yaw_accel_deg_per_s2", "surge_accel_m_per_s2",
                     "sway_accel_m_per_s2", "height_accel_m_per_s2"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name}: must be a number >= 0, got {v:g}")

    @property
    def n_oscillators(self) -> int:
        return len(self.periods_s)


@dataclass(frozen=True)
class Discretisation:
    """The model over one time step: ``x' = F x + w``, ``w ~ N(0, Q)``.

    Attributes
    ----------
    F : (n, n) array of float
        Transition matrix (read-only).
    Q : (n, n) array of float
        Process-noise covariance (read-only).
    """

    F: NDArray[np.float64]
    Q: NDArray[np.float64]


def state_size(model: DeckMotionModel) -> int:
    """Length of the state vector: ``(1 + 2 K_roll) + (1 + 2 K_pitch) + 2 K_heave + 8``.

    ``K_c`` counts the channel's oscillators with a sigma above zero (:func:`channel_oscillators`).
    """
    return state_slices(model)["uav_height"].stop


def state_slices(model: DeckMotionModel) -> dict[str, slice]:
    """Where each channel's block sits in the state vector.

    Keys ``roll``, ``pitch`` (offset first, then the oscillators' ``(p, v)`` pairs),
    ``heave`` (oscillator pairs), ``yaw``, ``surge``, ``sway``, ``uav_height`` (position, rate).
    Only oscillators with a sigma above zero have a pair (:func:`channel_oscillators`).
    """
    k = {name: len(om) for name, (om, _) in channel_oscillators(model).items()}
    out: dict[str, slice] = {}
    i = 0
    for name, size in (("roll", 1 + 2 * k["roll"]), ("pitch", 1 + 2 * k["pitch"]), ("heave", 2 * k["heave"]),
                       ("yaw", 2), ("surge", 2), ("sway", 2), ("uav_height", 2)):
        out[name] = slice(i, i + size)
        i += size
    return out


def channel_oscillators(model: DeckMotionModel) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """The oscillators in the state, per channel: ``(omega_rad_s (K_c,), sigma (K_c,))``.

    Keys ``roll``, ``pitch`` (sigma in rad), ``heave`` (m): the bank's oscillators whose sigma
    (:func:`bank_sigmas`) is above zero, in the order of ``periods_s``; one still at zero
    contributes nothing and is left out of the state.
    """
    omegas = _omegas(model)
    return {name: (omegas[sig > 0], sig[sig > 0]) for name, sig in bank_sigmas(model).items()}


def oscillator_discretisation(omega_rad_s: NDArray[np.float64], damping_ratio: float, sigma: NDArray[np.float64],
                              dt_s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact transition and process noise of damped oscillators over ``dt_s``.

    Each oscillator is ``p'' + 2 zeta omega p' + omega^2 p = w`` with white ``w`` scaled so
    that ``p`` has the stationary standard deviation ``sigma`` (then ``p'`` has ``omega sigma``).

    Parameters
    ----------
    omega_rad_s : (K,) array of float
        Undamped angular frequencies, rad/s.
    damping_ratio : float
        zeta, in (0, 1).
    sigma : (K,) array of float
        Stationary standard deviations of ``p`` (any unit; ``p'`` in that unit per second).
    dt_s : float
        Time step, seconds (>= 0).

    Returns
    -------
    F : (K, 2, 2) array of float
        ``[[p], [p']]`` at ``t + dt`` from ``t``: the closed-form solution.
    Q : (K, 2, 2) array of float
        Process noise, ``P_inf - F P_inf F^T`` with ``P_inf = diag(sigma^2, omega^2 sigma^2)``.
    """
    w = np.asarray(omega_rad_s, float).reshape(-1)
    s = np.asarray(sigma, float).reshape(-1)
    z = float(damping_ratio)
    wd = w * math.sqrt(1.0 - z * z)
    e = np.exp(-z * w * dt_s)
    c, sn = np.cos(wd * dt_s), np.sin(wd * dt_s)
    F = np.empty((w.size, 2, 2))
    F[:, 0, 0] = e * (c + z * w / wd * sn)
    F[:, 0, 1] = e * sn / wd
    F[:, 1, 0] = -e * w * w / wd * sn
    F[:, 1, 1] = e * (c - z * w / wd * sn)
    P_inf = np.zeros((w.size, 2, 2))
    P_inf[:, 0, 0] = s * s
    P_inf[:, 1, 1] = (w * s) ** 2
    Q = P_inf - F @ P_inf @ F.transpose(0, 2, 1)
    return F, 0.5 * (Q + Q.transpose(0, 2, 1))


def ncv_discretisation(accel_intensity: float, dt_s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Near-constant-velocity block over ``dt_s``: ``F = [[1, dt], [0, 1]]``, ``Q = q^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]]``.

    ``accel_intensity`` is ``q``, the square root of the white acceleration's spectral density.
    """
    F = np.array([[1.0, dt_s], [0.0, 1.0]])
    Q = accel_intensity ** 2 * np.array([[dt_s ** 3 / 3, dt_s ** 2 / 2], [dt_s ** 2 / 2, dt_s]])
    return F, Q


def _omegas(model: DeckMotionModel) -> NDArray[np.float64]:
    return 2.0 * np.pi / np.asarray(model.periods_s, float)


def bank_sigmas(model: DeckMotionModel) -> dict[str, NDArray[np.float64]]:
    """Stationary sigma of each oscillator, per channel (``roll``, ``pitch`` rad; ``heave`` m), each (K,)."""
    k = model.n_oscillators
    share = 1.0 / math.sqrt(k)
    out: dict[str, NDArray[np.float64]] = {}
    for name, per_osc, total, scale in (
            ("roll", model.roll_bank_sigmas_deg, model.roll_sigma_deg, math.pi / 180.0),
            ("pitch", model.pitch_bank_sigmas_deg, model.pitch_sigma_deg, math.pi / 180.0),
            ("heave", model.heave_bank_sigmas_m, model.heave_sigma_m, 1.0)):
        out[name] = (np.asarray(per_osc, float) if per_osc else np.full(k, total * share)) * scale
    return out


def _discretise(model: DeckMotionModel, dt_s: float) -> Discretisation:
    n = state_size(model)
    sl = state_slices(model)
    F, Q = np.zeros((n, n)), np.zeros((n, n))
    offset_q = math.radians(model.offset_rate_deg_per_sqrt_s) ** 2 * dt_s
    for name, (omegas, sig) in channel_oscillators(model).items():
        Fo, Qo = oscillator_discretisation(omegas, model.damping_ratio, sig, dt_s)
        start = sl[name].start
        if name != "heave":  # the random-walk offset
            F[start, start] = 1.0
            Q[start, start] = offset_q
            start += 1
        for j in range(len(omegas)):
            b = slice(start + 2 * j, start + 2 * j + 2)
            F[b, b], Q[b, b] = Fo[j], Qo[j]
    for name, q in (("yaw", math.radians(model.yaw_accel_deg_per_s2)), ("surge", model.surge_accel_m_per_s2),
                    ("sway", model.sway_accel_m_per_s2), ("uav_height", model.height_accel_m_per_s2)):
        Fb, Qb = ncv_discretisation(q, dt_s)
        F[sl[name], sl[name]], Q[sl[name], sl[name]] = Fb, Qb
    F.flags.writeable = False
    Q.flags.writeable = False
    return Discretisation(F, Q)


_discretise_cached = lru_cache(maxsize=64)(_discretise)


def discretise(model: DeckMotionModel, dt_s: float) -> Discretisation:
    """The whole model's transition and process noise over ``dt_s`` seconds (exact; cached by step).

    Raises
    ------
    ValueError
        ``dt_s`` negative or not finite.
    """
    if not (math.isfinite(dt_s) and dt_s >= 0):
        raise ValueError(f"dt_s: the time step must be a finite number >= 0 seconds, got {dt_s!r}")
    return _discretise_cached(model, float(dt_s))


def measurement_matrix(model: DeckMotionModel) -> NDArray[np.float64]:
    """``H`` (6, n): the per-frame estimate (POSE_PARAMS order) from the state.

    roll = offset + sum of roll oscillators, pitch likewise, yaw, surge, sway their
    positions, height = uav_height - sum of heave oscillators.
    """
    H = np.zeros((6, state_size(model)))
    sl = state_slices(model)
    for row, name in ((0, "roll"), (1, "pitch")):
        H[row, sl[name].start] = 1.0
        H[row, sl[name].start + 1:sl[name].stop:2] = 1.0
    H[2, sl["yaw"].start] = 1.0
    H[3, sl["surge"].start] = 1.0
    H[4, sl["sway"].start] = 1.0
    H[5, sl["uav_height"].start] = 1.0
    H[5, sl["heave"].start:sl["heave"].stop:2] = -1.0
    H.flags.writeable = False
    return H


def output_matrix(model: DeckMotionModel) -> NDArray[np.float64]:
    """``C`` (5, n): the outputs of :data:`DECK_OUTPUTS` from the state.

    Roll, pitch, heave (the oscillating part), heave rate, and the height of the camera
    above the deck centre (the measurement's height row: uav_height - heave).
    """
    C = np.zeros((5, state_size(model)))
    sl = state_slices(model)
    for row, name in ((0, "roll"), (1, "pitch")):
        C[row, sl[name].start] = 1.0
        C[row, sl[name].start + 1:sl[name].stop:2] = 1.0
    C[2, sl["heave"].start:sl["heave"].stop:2] = 1.0
    C[3, sl["heave"].start + 1:sl["heave"].stop:2] = 1.0
    C[4] = measurement_matrix(model)[5]
    C.flags.writeable = False
    return C


def prior(model: DeckMotionModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean (n,) and covariance (n, n) of the state before any measurement.

    Zero mean; oscillators at their stationary covariance, offsets and the
    near-constant-velocity channels at the model's (wide) prior sigmas.
    """
    n = state_size(model)
    sl = state_slices(model)
    var = np.zeros(n)
    for name, (omegas, sig) in channel_oscillators(model).items():
        start = sl[name].start
        if name != "heave":
            var[start] = math.radians(model.offset_sigma_deg) ** 2
            start += 1
        var[start:start + 2 * len(omegas):2] = sig ** 2
        var[start + 1:start + 2 * len(omegas):2] = (omegas * sig) ** 2
    var[sl["yaw"]] = (math.radians(model.yaw_sigma_deg) ** 2, math.radians(model.yaw_rate_sigma_deg_per_s) ** 2)
    for name in ("surge", "sway", "uav_height"):
        var[sl[name]] = (model.position_sigma_m ** 2, model.rate_sigma_m_per_s ** 2)
    return np.zeros(n), np.diag(var)
