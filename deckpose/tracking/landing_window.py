"""The landing-window indicator: is the deck predicted calm enough for the next T seconds?

"Go" at a frame when the probability, under the filter's prediction, that |roll|, |pitch|
and |heave rate| all stay below their limits at every time of a grid over the next
``window_s`` seconds is at least ``confidence`` (:func:`window_calm_probability`). The
prediction over the window is one joint Gaussian (three channels x the grid's times, with
their correlations across time: the deck's motion a quarter second apart is nearly the
same); the probability of that box is integrated by randomised quasi-Monte Carlo: a scrambled Sobol
sequence of :data:`QMC_POINTS` points drawn once with the fixed seed :data:`QMC_SEED` (a fixed
integration rule, so the indicator is deterministic; unscrambled Sobol points were biased by
~1.5 % here). (The bound this replaced treated the window's 3 x 13 checks as unrelated,
Boole's inequality, and asked each for a 3.2-sigma margin at 95 %: far more than the joint
probability needs, as the checks are strongly correlated.) Scored against the truth by
:func:`truth_window_calm`: the same test on the true motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError, ShapeError
from deckpose.tracking.deck_motion_model import DeckMotionModel, discretise, output_matrix

__all__ = ["QMC_POINTS", "QMC_SEED", "LandingLimits", "landing_window_go", "truth_window_calm", "window_calm_probability",
           "window_covariance", "window_horizons_s"]

#: Quasi-Monte Carlo points of the window probability (a power of two): its error is a few
#: tenths of a percent at the probabilities a landing decision is made at.
QMC_POINTS = 2 ** 12
#: Seed of the scrambling of the Sobol points: fixes the integration rule, not a random draw.
QMC_SEED = 21
#: Rows of :func:`~deckpose.tracking.deck_motion_model.output_matrix` the window checks:
#: roll, pitch, heave rate.
WINDOW_OUTPUTS = (0, 1, 3)


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
        the whole window (at every time of the step grid) for a "go" (in (0, 1)).
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


def window_covariance(model: DeckMotionModel, horizons_s: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                                    NDArray[np.float64]]:
    """The linear map from a state to the window's outputs, and the process noise's share of their covariance.

    The outputs are roll, pitch and heave rate at each horizon, grid-major (``3 G`` values for
    ``G`` horizons). From a state ``N(x, P)`` they are ``N(M x, M P M^T + S)``: ``M`` stacks
    ``C F(h_i)`` and ``S`` holds the process noise from now to each horizon, correlated across
    horizons: for ``h_i <= h_j``, ``Cov = C Q(h_i) F(h_j - h_i)^T C^T``.

    Parameters
    ----------
    model : DeckMotionModel
    horizons_s : (G,) array of float
        Increasing horizons, seconds (>= 0).

    Returns
    -------
    M : (3 G, n) array of float
    S : (3 G, 3 G) array of float
    """
    hs = np.asarray(horizons_s, float)
    C = output_matrix(model)[list(WINDOW_OUTPUTS)]
    g = hs.size
    discs = [discretise(model, float(h)) for h in hs]
    M = np.concatenate([C @ d.F for d in discs])
    S = np.zeros((3 * g, 3 * g))
    for i in range(g):
        CQ = C @ discs[i].Q
        for j in range(i, g):
            block = CQ @ discretise(model, float(hs[j] - hs[i])).F.T @ C.T
            S[3 * i:3 * i + 3, 3 * j:3 * j + 3] = block
            S[3 * j:3 * j + 3, 3 * i:3 * i + 3] = block.T
    return M, S


def _limits_rad(limits: LandingLimits) -> NDArray[np.float64]:
    return np.array([math.radians(limits.roll_deg), math.radians(limits.pitch_deg), limits.heave_rate_m_per_s])


def window_calm_probability(x: NDArray[np.float64], P: NDArray[np.float64], model: DeckMotionModel,
                            limits: LandingLimits) -> NDArray[np.float64]:
    """Probability, under the prediction, that the deck stays within the limits over the window.

    Parameters
    ----------
    x : (N, n) array of float
    P : (N, n, n) array of float
    model : DeckMotionModel
    limits : LandingLimits

    Returns
    -------
    (N,) array of float
        The joint probability that |roll|, |pitch| and |heave rate| stay below their limits at
        every time of :func:`window_horizons_s` (randomised quasi-Monte Carlo, :data:`QMC_POINTS` points).
    """
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    if x.ndim != 2 or P.shape != (x.shape[0], x.shape[1], x.shape[1]):
        raise ShapeError(f"x, P: expected shapes (N, n) and (N, n, n), got {x.shape} and {P.shape}")
    # imported here: scipy.stats at module level slowed every deckpose command's start
    from scipy.stats import norm, qmc

    M, S = window_covariance(model, window_horizons_s(limits))
    d = M.shape[0]
    u = qmc.Sobol(d, scramble=True, rng=QMC_SEED).random(QMC_POINTS)
    z = norm.ppf(u)                                                  # (Q, d) standard normal points
    lim = np.tile(_limits_rad(limits), d // 3)
    out = np.empty(x.shape[0])
    mean = x @ M.T
    for i in range(x.shape[0]):
        cov = M @ P[i] @ M.T + S
        cov = 0.5 * (cov + cov.T)
        jitter = 1e-12 * float(np.max(np.diag(cov)))
        L = np.linalg.cholesky(cov + jitter * np.eye(d))
        y = mean[i] + z @ L.T
        out[i] = float(np.mean(np.all(np.abs(y) < lim, axis=1)))
    return out


def landing_window_go(x: NDArray[np.float64], P: NDArray[np.float64], model: DeckMotionModel,
                      limits: LandingLimits) -> NDArray[np.bool_]:
    """The indicator for a batch of filter states: "go" where :func:`window_calm_probability` >= confidence.

    Parameters
    ----------
    x : (N, n) array of float
    P : (N, n, n) array of float
    model : DeckMotionModel
    limits : LandingLimits

    Returns
    -------
    (N,) array of bool
    """
    return np.asarray(window_calm_probability(x, P, model, limits) >= limits.confidence, dtype=bool)


def _calm(roll: NDArray[np.float64], pitch: NDArray[np.float64], heave_rate: NDArray[np.float64],
          limits: LandingLimits) -> NDArray[np.bool_]:
    return ((np.abs(roll) < math.radians(limits.roll_deg)) & (np.abs(pitch) < math.radians(limits.pitch_deg))
            & (np.abs(heave_rate) < limits.heave_rate_m_per_s))


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
