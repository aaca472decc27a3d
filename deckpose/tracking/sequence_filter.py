"""The deck-motion filter over one time sequence of per-frame pose estimates.

For each frame in time order: predict the state to the frame's time, then update it
with the frame's estimate (its full covariance as the measurement noise) unless the
estimate is not ok (prediction only) or fails the Mahalanobis gate (an outlier:
prediction only, recorded as gated).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from deckpose.errors import ShapeError
from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    discretise,
    measurement_matrix,
    prior,
    state_size,
)
from deckpose.tracking.kalman import kalman_predict, kalman_update

__all__ = ["FilterStatus", "FilterTrack", "filter_sequence", "gate_nis"]

#: Rows of the measurement (POSE_PARAMS order) that are angles: roll, pitch, yaw.
ANGLE_ROWS = (0, 1, 2)


class FilterStatus(enum.Enum):
    """What the filter did with a frame's estimate."""

    UPDATED = "updated"   # the estimate was applied
    GATED = "gated"       # rejected as an outlier by the Mahalanobis gate
    SKIPPED = "skipped"   # no usable estimate (not ok, or no covariance): prediction only


@dataclass(frozen=True)
class FilterTrack:
    """The filtered states of one sequence, one per frame.

    Attributes
    ----------
    x : (N, n) array of float
        State means after each frame (radians, metres; layout of
        :func:`~deckpose.tracking.deck_motion_model.state_slices`).
    P : (N, n, n) array of float
        Their covariances.
    nis : (N,) array of float
        Normalised innovation squared of each frame's estimate (NaN where skipped).
    status : tuple of FilterStatus
        What the filter did with each frame's estimate.
    """

    x: NDArray[np.float64]
    P: NDArray[np.float64]
    nis: NDArray[np.float64]
    status: tuple[FilterStatus, ...]

    def __post_init__(self) -> None:
        n_frames = len(self.status)
        if self.x.ndim != 2 or self.x.shape[0] != n_frames or self.P.shape != (n_frames, self.x.shape[1],
                                                                                   self.x.shape[1]):
            raise ShapeError(f"FilterTrack: x (N, n), P (N, n, n) and status (N,) disagree: {self.x.shape}, "
                             f"{self.P.shape}, {n_frames}")
        for a in (self.x, self.P, self.nis):
            a.flags.writeable = False


def gate_nis(probability: float, dof: int = 6) -> float:
    """The gate on the normalised innovation squared: the chi-square quantile of ``dof`` degrees of freedom.

    ``probability`` 1 (or more) means no gate.
    """
    if probability >= 1.0:
        return math.inf
    if not probability > 0:
        raise ValueError(f"gate probability must lie in (0, 1], got {probability!r}")
    return float(chi2.ppf(probability, dof))


def filter_sequence(t_s: NDArray[np.float64], z: NDArray[np.float64], R: NDArray[np.float64],
                    usable: NDArray[np.bool_], model: DeckMotionModel, *, gate_probability: float = 0.9999,
                    reacquire_after: int = 10) -> FilterTrack:
    """Run the filter over one sequence of estimates.

    Parameters
    ----------
    t_s : (N,) array of float
        Frame times, seconds, non-decreasing (one time base).
    z : (N, 6) array of float
        Per-frame estimates in POSE_PARAMS order (roll, pitch, yaw rad; surge, sway, height m).
    R : (N, 6, 6) array of float
        Their covariances (ignored where not ``usable``).
    usable : (N,) array of bool
        Frames whose estimate may update the filter (ok, finite values and covariance).
    model : DeckMotionModel
    gate_probability : float, keyword-only
        Probability mass of the chi-square gate (6 degrees of freedom); 1 = no gate.
    reacquire_after : int, keyword-only
        After this many usable estimates gated out in a row, the next one is applied
        without the gate (the filter, not the estimates, has lost the deck).

    Returns
    -------
    FilterTrack
    """
    t = np.asarray(t_s, float)
    n_frames = t.shape[0]
    if z.shape != (n_frames, 6) or R.shape != (n_frames, 6, 6) or np.shape(usable) != (n_frames,):
        raise ShapeError(f"filter_sequence: expected t_s (N,), z (N, 6), R (N, 6, 6), usable (N,) for N = "
                         f"{n_frames}, got {z.shape}, {R.shape}, {np.shape(usable)}")
    if n_frames > 1 and np.any(np.diff(t) < 0):
        raise ValueError("t_s: frame times of a sequence must not decrease; sort the frames by time")
    n = state_size(model)
    H = measurement_matrix(model)
    gate = gate_nis(gate_probability)
    x, P = prior(model)
    xs, Ps = np.empty((n_frames, n)), np.empty((n_frames, n, n))
    nis = np.full(n_frames, np.nan)
    status: list[FilterStatus] = []
    started = False
    n_gated = 0
    for i in range(n_frames):
        if i > 0:
            d = discretise(model, float(t[i] - t[i - 1]))
            x, P = kalman_predict(x, P, d.F, d.Q)
        if bool(usable[i]):
            # before the first accepted estimate, the prior is too vague for a gate to mean anything
            gated = started and n_gated < reacquire_after
            up = kalman_update(x, P, z[i], R[i], H, gate_nis=gate if gated else math.inf,
                               angle_rows=ANGLE_ROWS)
            nis[i] = up.nis
            if up.accepted:
                x, P, started, n_gated = up.x, up.P, True, 0
                status.append(FilterStatus.UPDATED)
            else:
                n_gated += 1
                status.append(FilterStatus.GATED)
        else:
            status.append(FilterStatus.SKIPPED)
        xs[i], Ps[i] = x, P
    return FilterTrack(xs, Ps, nis, tuple(status))
