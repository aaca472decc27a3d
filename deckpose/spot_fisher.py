"""Fisher information of a light spot's parameters from its expected image, numerically.

The pixels of a spot are independent, each with expected electrons ``mu_k`` and
variance ``mu_k + extra`` (shot noise plus the signal-independent read and
quantisation noise; the shifted-Poisson approximation of :mod:`deckpose.detect.crb`).
For parameters ``theta`` the Fisher information is
``I = sum_k grad(mu_k) grad(mu_k)^T / var_k``; the Cramér–Rao bound on the centre is
the ``(u, v)`` block of ``I^-1`` (the other parameters unknown: nuisances). Unlike
:func:`deckpose.detect.crb.centroid_fisher`, which is written for a pixel-integrated
Gaussian, this takes the image and its derivatives from whatever PSF made them, so the
render stage can state the bound of the spot it actually drew
(:mod:`deckpose.render.optics`) and the benchmark can use it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["centre_crb_px2", "fisher_information"]

FloatArray = NDArray[np.float64]


def fisher_information(mu_e: FloatArray, grads_e: FloatArray, extra_variance_e2: float) -> FloatArray:
    """Fisher information of a spot's parameters.

    Parameters
    ----------
    mu_e : (h, w) array of float, electrons
        Expected electrons of each pixel (spot plus background).
    grads_e : (P, h, w) array of float
        Derivative of ``mu_e`` with respect to each parameter, electrons per unit.
    extra_variance_e2 : float
        Signal-independent variance of a pixel, electrons^2 (read noise^2 + quantisation).

    Returns
    -------
    (P, P) array of float
    """
    mu = np.asarray(mu_e, float)
    g = np.asarray(grads_e, float)
    if g.ndim != 3 or g.shape[1:] != mu.shape:
        raise ValueError(f"grads_e: expected shape (P, {mu.shape[0]}, {mu.shape[1]}), got {g.shape}")
    flat = g.reshape(g.shape[0], -1)
    w = 1.0 / (np.maximum(mu, 0.0).ravel() + extra_variance_e2)
    return np.asarray((flat * w) @ flat.T, dtype=np.float64)


def centre_crb_px2(mu_e: FloatArray, grads_e: FloatArray, extra_variance_e2: float) -> FloatArray:
    """Cramér–Rao bound on the covariance of an unbiased centre estimate, px^2.

    Parameters
    ----------
    mu_e, grads_e, extra_variance_e2
        As :func:`fisher_information`; ``grads_e[0]`` and ``grads_e[1]`` must be the
        derivatives with respect to the centre's column ``u`` and row ``v``, the others
        nuisance parameters (flux, background, width...).

    Returns
    -------
    (2, 2) array of float, px^2
    """
    info = fisher_information(mu_e, grads_e, extra_variance_e2)
    return np.asarray(np.linalg.inv(info)[:2, :2], dtype=np.float64)
