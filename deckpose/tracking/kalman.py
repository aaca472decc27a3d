"""The linear Kalman filter: predict, and update in Joseph form with Mahalanobis gating.

Pure functions on arrays (no filter object): the caller holds ``(x, P)`` and passes
the model's matrices in. Angles in a measurement are wrapped in the innovation
(``angle_rows``), so a yaw near +-180 deg is no outlier.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import check_shape
from deckpose.rotation import wrap_angle_rad

__all__ = ["Update", "kalman_predict", "kalman_update"]


@dataclass(frozen=True)
class Update:
    """The outcome of one measurement update.

    Attributes
    ----------
    x : (n,) array of float
        State mean after the update (the prior's where the measurement was gated out).
    P : (n, n) array of float
        State covariance after the update (likewise).
    nis : float
        Normalised innovation squared ``nu^T S^-1 nu`` (chi-square with m degrees of
        freedom where the model holds); NaN where ``S`` is singular.
    accepted : bool
        The measurement passed the gate and was applied.
    """

    x: NDArray[np.float64]
    P: NDArray[np.float64]
    nis: float
    accepted: bool


def kalman_predict(x: NDArray[np.float64], P: NDArray[np.float64], F: NDArray[np.float64],
                   Q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(F x, F P F^T + Q)``: the state one step ahead.

    Parameters
    ----------
    x : (n,) array of float
    P : (n, n) array of float
    F, Q : (n, n) arrays of float
        Transition and process-noise covariance of the step.
    """
    n = x.shape[0]
    check_shape("P", P, (n, n))
    check_shape("F", F, (n, n))
    check_shape("Q", Q, (n, n))
    P1 = F @ P @ F.T + Q
    return F @ x, 0.5 * (P1 + P1.T)


def kalman_update(x: NDArray[np.float64], P: NDArray[np.float64], z: NDArray[np.float64], R: NDArray[np.float64],
                  H: NDArray[np.float64], *, gate_nis: float = np.inf,
                  angle_rows: tuple[int, ...] = ()) -> Update:
    """Condition the state on ``z = H x + v``, ``v ~ N(0, R)``, unless it fails the gate.

    The covariance is updated in Joseph form, ``(I - K H) P (I - K H)^T + K R K^T``, valid for
    any gain (so rounding in ``K`` does not bias it), written out as
    ``P - K (P H^T)^T - (P H^T) K^T + K S K^T``: the same matrix in ``O(n^2 m)`` operations
    instead of the ``O(n^3)`` of the two ``n x n`` products, and symmetrised.

    Parameters
    ----------
    x : (n,) array of float
    P : (n, n) array of float
    z : (m,) array of float
        The measurement.
    R : (m, m) array of float
        Its covariance.
    H : (m, n) array of float
    gate_nis : float, keyword-only
        Largest accepted normalised innovation squared (e.g. the chi-square quantile of
        m degrees of freedom at the gate's probability); ``inf``: no gate.
    angle_rows : tuple of int, keyword-only
        Rows of ``z`` that are angles in radians: their innovation is wrapped to [-pi, pi).

    Returns
    -------
    Update
    """
    n, m = x.shape[0], z.shape[0]
    check_shape("P", P, (n, n))
    check_shape("R", R, (m, m))
    check_shape("H", H, (m, n))
    nu = z - H @ x
    if angle_rows:
        rows = list(angle_rows)
        nu[rows] = wrap_angle_rad(nu[rows])
    PHt = P @ H.T
    S = H @ PHt + R
    try:
        c = np.linalg.cholesky(0.5 * (S + S.T))
    except np.linalg.LinAlgError:
        return Update(x, P, float("nan"), False)
    w = np.linalg.solve(c, nu)
    nis = float(w @ w)
    if not nis <= gate_nis:
        return Update(x, P, nis, False)
    # K = P H^T S^-1 through the Cholesky factor (S = c c^T)
    K = np.linalg.solve(c.T, np.linalg.solve(c, PHt.T)).T
    KPHt = K @ PHt.T
    P1 = P - KPHt - KPHt.T + K @ S @ K.T
    return Update(x + K @ nu, 0.5 * (P1 + P1.T), nis, True)
