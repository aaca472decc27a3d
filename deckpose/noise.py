"""Pixel-noise models for analytic (non-rendered) studies.

All take a ``numpy.random.Generator`` and never touch global random state.
Points are arrays of shape ``(..., 2)``; the first two models act on *centred*
image coordinates ``(X', Y')`` (origin at the principal point), as in the thesis.

* :func:`thesis_uniform` — thesis eqs. 4.1-4.3: ``X' += dx*X'``, ``Y' += dy*Y'`` with
  ``dx, dy ~ U[-p, p]`` independent per beacon and ``p = N / ||(W/2, H/2)||``:
  the error grows with the distance from the image centre and reaches N px
  only in the image corners.
* :func:`norm_scaled_uniform` — our reading of the published code's variant:
  both components scale with the point's distance from the centre,
  ``X' += dx*||P||``, ``Y' += dy*||P||`` with the same ``p`` (isotropic in
  direction, radial in size).
* :func:`gaussian` — isotropic Gaussian, ``sigma_px`` per axis.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from deckpose.errors import ConfigError, ShapeError

FloatArray = NDArray[np.float64]


def _points(points: ArrayLike) -> FloatArray:
    P = np.asarray(points, dtype=float)
    if P.ndim < 1 or P.shape[-1] != 2:
        raise ShapeError(f"points: expected shape (..., 2), got {P.shape}")
    return P


def thesis_scale(max_px: float, width_px: int, height_px: int) -> float:
    """``p = N / ||(W/2, H/2)||`` of eq. 4.3: the largest relative perturbation."""
    if not (max_px >= 0 and math.isfinite(max_px)):
        raise ConfigError(f"noise level must be a finite, non-negative number of pixels, got {max_px}")
    return float(max_px / math.hypot(width_px / 2.0, height_px / 2.0))


def thesis_uniform(
    points_c: ArrayLike, max_px: float, width_px: int, height_px: int, rng: np.random.Generator
) -> FloatArray:
    """Thesis eqs. 4.1-4.3: coordinate-scaled uniform noise on centred coordinates.

    Parameters
    ----------
    points_c : (..., 2) array of float
        Centred image coordinates, pixels.
    max_px : float
        N, the error in pixels at the image corner (8, 6 or 4 in the thesis).
    width_px, height_px : int
        Image size, which sets ``p``.
    rng : numpy.random.Generator

    Returns
    -------
    (..., 2) array of float
    """
    P = _points(points_c)
    p = thesis_scale(max_px, width_px, height_px)
    delta = rng.uniform(-p, p, size=P.shape)
    return P + delta * P


def norm_scaled_uniform(
    points_c: ArrayLike, max_px: float, width_px: int, height_px: int, rng: np.random.Generator
) -> FloatArray:
    """Uniform noise scaled by each point's distance from the image centre (see module doc)."""
    P = _points(points_c)
    p = thesis_scale(max_px, width_px, height_px)
    delta = rng.uniform(-p, p, size=P.shape)
    return P + delta * np.linalg.norm(P, axis=-1, keepdims=True)


def gaussian(points_px: ArrayLike, sigma_px: float, rng: np.random.Generator) -> FloatArray:
    """Isotropic Gaussian noise with standard deviation ``sigma_px`` per axis."""
    P = _points(points_px)
    if not (sigma_px >= 0 and math.isfinite(sigma_px)):
        raise ConfigError(f"sigma_px must be finite and non-negative, got {sigma_px}")
    return P + rng.normal(0.0, sigma_px, size=P.shape)
