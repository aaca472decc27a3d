"""The landing-window indicator: is the deck predicted calm enough for the next T seconds?

"Go" at a frame when, at every time of a grid over the next ``window_s`` seconds, the
predicted |roll|, |pitch| and |heave rate| stay below their limits by a margin of ``k``
of their predicted standard deviations, ``k`` chosen so that the whole window stays
within the limits with probability at least ``confidence`` under the predicted Gaussians:
each of the ``3 G`` checks (three channels, ``G`` grid times) fails with probability at most
``2 (1 - Phi(k))``, so by Boole's inequality (no assumption on their correlation)
``k = Phi^-1(1 - (1 - confidence) / (6 G))`` bounds the window's failure by
``1 - confidence`` (:func:`margin_sigmas`). Scored against the truth by
:func:`truth_window_calm`: the same test on the true motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import norm

from deckpose.errors import ConfigError, ShapeError
from deckpose.tracking.deck_motion_model import DeckMotionModel
from deckpose.tracking.prediction import predict_outputs

__all__ = ["LandingLimits", "landing_window_go", "margin_sigmas", "truth_window_calm", "window_horizons_s"]


@dataclass(frozen=True)
class LandingLimits:
    """Limits of a landing window (configs: the tracker's ``landing:`` section).

    Attributes
    ----------
    roll_deg, pitch_deg : float
        Largest |roll| and |pitch| allowed, degrees.
    heave_rate_m_per_s : float
        Largest |heave rate| allowed, m/s.
    window_s : float
        How long the deck must stay within the limits, seconds (T).
    step_s : float
        Spacing of the grid the window is checked on, seconds.
    confidence : float
        Least probability, under the prediction, that the deck stays within the limits over
        the whole window for a "go" (in (0, 1)).
    """

    roll_deg: float = 3.0
    pitch_deg: float = 2.0
    heave_rate_m_per_s: float = 0.5
    window_s: float = 3.0
    step_s: float = 0.25
    confidence: float = 0.95

    def __post_init__(self) -> None:
        for name in ("roll_deg", "pitch_deg", "heave_rate_m_per_s", "window_s", "step_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name}: must be a positive number, got {v:g}")
        if not 0 < self.confidence < 1:
            raise ConfigError(f"confidence: must lie in (0, 1) (a probability), got {self.confidence:g}")
        if self.step_s > self.window_s:
            raise ConfigError(f"step_s ({self.step_s:g} s) must not exceed window_s "
                              f"({self.window_s:g} s)")


def window_horizons_s(limits: LandingLimits) -> NDArray[np.float64]:
    """The grid of horizons the window is checked on: 0, step, 2 step, ... up to ``window_s``."""
    n = math.floor(limits.window_s / limits.step_s + 1e-9)
    return np.asarray(limits.step_s * np.arange(n + 1), dtype=np.float64)


def margin_sigmas(limits: LandingLimits) -> float:
    """``k``: predicted sigmas between each predicted value and its limit for a "go" (module docstring)."""
    n_checks = 3 * len(window_horizons_s(limits))
    return float(norm.isf((1.0 - limits.confidence) / (2 * n_checks)))


def _calm(roll: NDArray[np.float64], pitch: NDArray[np.float64], heave_rate: NDArray[np.float64],
          limits: LandingLimits) -> NDArray[np.bool_]:
    return ((np.abs(roll) < math.radians(limits.roll_deg)) & (np.abs(pitch) < math.radians(limits.pitch_deg))
            & (np.abs(heave_rate) < limits.heave_rate_m_per_s))


def landing_window_go(x: NDArray[np.float64], P: NDArray[np.float64], model: DeckMotionModel,
                      limits: LandingLimits) -> NDArray[np.bool_]:
    """The indicator for a batch of filter states.

    Parameters
    ----------
    x : (N, n) array of float
    P : (N, n, n) array of float
    model : DeckMotionModel
    limits : LandingLimits

    Returns
    -------
    (N,) array of bool
        True ("go") where every predicted |roll|, |pitch| and |heave rate| plus
        :func:`margin_sigmas` sigmas stays below its limit over the window.
    """
    mean, cov = predict_outputs(x, P, model, window_horizons_s(limits))
    sig = np.sqrt(np.maximum(np.diagonal(cov, axis1=2, axis2=3), 0.0))
    k = margin_sigmas(limits)
    bound = np.abs(mean) + k * sig                               # (N, H, 5)
    calm = _calm(bound[..., 0], bound[..., 1], bound[..., 3], limits)
    return np.all(calm, axis=1)


def truth_window_calm(t_s: NDArray[np.float64], roll_rad: NDArray[np.float64], pitch_rad: NDArray[np.float64],
                      heave_rate_m_per_s: NDArray[np.float64], limits: LandingLimits) -> NDArray[np.float64]:
    """Whether the true motion stays within the limits over each sample's next ``window_s``.

    Parameters
    ----------
    t_s : (N,) array of float
        Sample times of one sequence, seconds, increasing.
    roll_rad, pitch_rad, heave_rate_m_per_s : (N,) arrays of float
        The true motion at those times.
    limits : LandingLimits

    Returns
    -------
    (N,) array of float
        1.0 calm, 0.0 not, NaN where the window runs past the last sample (cannot be scored).
    """
    t = np.asarray(t_s, float)
    for name, a in (("roll_rad", roll_rad), ("pitch_rad", pitch_rad), ("heave_rate_m_per_s", heave_rate_m_per_s)):
        if np.shape(a) != t.shape:
            raise ShapeError(f"{name}: expected shape {t.shape} (as t_s), got {np.shape(a)}")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("t_s: sample times must increase")
    ok = _calm(np.asarray(roll_rad, float), np.asarray(pitch_rad, float), np.asarray(heave_rate_m_per_s, float),
               limits)
    # first sample not calm at or after each sample, through a reverse running index
    bad_idx = np.where(~ok, np.arange(t.size), t.size)
    next_bad = np.minimum.accumulate(bad_idx[::-1])[::-1]
    end = np.searchsorted(t, t + limits.window_s, side="right")   # first sample past the window
    out = np.where(next_bad >= end, 1.0, 0.0)
    if t.size:
        out[t + limits.window_s > t[-1] + 1e-9] = np.nan
    return out
