"""Deck roll, pitch, heave, heave rate and the camera's height above the deck predicted ahead from the filter's state.

The prediction ``h`` seconds ahead of a state ``N(x, P)`` is the model propagated
over ``h`` with no measurement: mean ``C F(h) x``, covariance ``C (F(h) P F(h)^T + Q(h)) C^T``
(``C`` = :func:`~deckpose.tracking.deck_motion_model.output_matrix`), exact for any
horizon because the model's discretisation is exact.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ShapeError
from deckpose.tracking.deck_motion_model import (
    DeckMotionModel,
    discretise,
    output_matrix,
    state_size,
)

__all__ = ["predict_outputs"]


def predict_outputs(x: NDArray[np.float64], P: NDArray[np.float64], model: DeckMotionModel,
                    horizons_s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and covariance of the deck outputs at each horizon, for a batch of states.

    Parameters
    ----------
    x : (N, n) array of float
        State means (radians, metres).
    P : (N, n, n) array of float
        State covariances.
    model : DeckMotionModel
    horizons_s : (H,) array of float
        How far ahead, seconds (>= 0; 0 is the state itself).

    Returns
    -------
    mean : (N, H, 5) array of float
        roll_rad, pitch_rad, heave_m, heave_rate_m_per_s, height_m (camera above the deck
        centre) (:data:`~deckpose.tracking.deck_motion_model.DECK_OUTPUTS`).
    cov : (N, H, 5, 5) array of float
        Their covariance.
    """
    n = state_size(model)
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    if x.ndim != 2 or x.shape[1] != n or P.shape != (x.shape[0], n, n):
        raise ShapeError(f"x, P: expected shapes (N, {n}) and (N, {n}, {n}), got {x.shape} and {P.shape}")
    hs = np.asarray(horizons_s, float).reshape(-1)
    C = output_matrix(model)
    discs = [discretise(model, float(h)) for h in hs]
    M = np.stack([C @ d.F for d in discs])                       # (H, 5, n)
    CQC = np.stack([C @ d.Q @ C.T for d in discs])               # (H, 5, 5)
    mean = np.einsum("hon,Nn->Nho", M, x)
    cov = np.einsum("hon,Nnm,hpm->Nhop", M, P, M, optimize=True) + CQC[None]
    return mean, cov
