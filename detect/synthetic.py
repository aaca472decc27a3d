"""Analytic beacon spots: an exactly pixel-integrated 2-D Gaussian, with a sensor noise model.

This is the detection stage's own test bench, independent of the renderer: every
spot is a circular Gaussian whose integral over each pixel is computed exactly
with :func:`scipy.special.erf`, so the true centre is known to float precision.
Pixel ``(row v, column u)`` covers ``[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]``
(pixel centres at integers, as everywhere in deckpose).

Noise model (per pixel, in electrons): Poisson photon noise on the expected
signal plus background, Gaussian read noise, then the analogue gain, an
offset (black level), rounding to integers and clipping to the bit depth:
``DN = clip(round(gain * (Poisson(mu) + Normal(0, read)) + offset), 0, 2**bits - 1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import erf

from deckpose.errors import ConfigError, check_shape

FloatArray = NDArray[np.float64]

_SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class SensorModel:
    """Photon-transfer model of a camera sensor.

    Attributes
    ----------
    gain_dn_per_e : float
        Digital numbers per photo-electron.
    read_noise_e : float
        Read-noise standard deviation, electrons.
    background_e : float
        Expected background (sky, deck, dark current) per pixel, electrons.
    offset_dn : float
        Black level added after the gain, DN.
    bit_depth : int
        8, 12 or 16; values clip at ``2**bit_depth - 1`` (12-bit images are uint16).
    """

    gain_dn_per_e: float = 1.0
    read_noise_e: float = 3.0
    background_e: float = 20.0
    offset_dn: float = 0.0
    bit_depth: int = 16

    def __post_init__(self) -> None:
        if not self.gain_dn_per_e > 0:
            raise ConfigError(f"gain_dn_per_e must be positive, got {self.gain_dn_per_e}")
        if not (self.read_noise_e >= 0 and self.background_e >= 0 and self.offset_dn >= 0):
            raise ConfigError("read_noise_e, background_e and offset_dn must be >= 0")
        if self.bit_depth not in (8, 12, 16):
            raise ConfigError(f"bit_depth must be 8, 12 or 16, got {self.bit_depth}")

    @property
    def max_dn(self) -> int:
        """Saturation value, DN."""
        return 2**self.bit_depth - 1

    @property
    def dtype(self) -> type:
        return np.uint8 if self.bit_depth == 8 else np.uint16

    @property
    def extra_variance_e2(self) -> float:
        """Signal-independent variance, electrons^2: read noise plus quantisation (1/12 DN^2)."""
        return self.read_noise_e**2 + 1.0 / (12.0 * self.gain_dn_per_e**2)


def pixel_fractions(centre_px: float, sigma_px: float, coords_px: ArrayLike) -> FloatArray:
    """Fraction of a 1-D Gaussian's mass falling in each unit pixel.

    Parameters
    ----------
    centre_px, sigma_px : float
        Mean and standard deviation of the Gaussian, pixels.
    coords_px : (M,) array of int or float
        Pixel centres; pixel ``x`` covers ``[x - 0.5, x + 0.5]``.

    Returns
    -------
    (M,) array of float
        Exact integrals, in [0, 1].
    """
    x = np.asarray(coords_px, dtype=float)
    s = _SQRT2 * sigma_px
    return 0.5 * (erf((x + 0.5 - centre_px) / s) - erf((x - 0.5 - centre_px) / s))


def spot_window(
    centre_px: tuple[float, float], sigma_px: float, half_width: int | None = None
) -> tuple[FloatArray, FloatArray]:
    """Integer pixel coordinates ``(us, vs)`` of a square window around a spot (±6 sigma)."""
    h = math.ceil(6.0 * sigma_px + 1.0) if half_width is None else int(half_width)
    u0, v0 = round(centre_px[0]), round(centre_px[1])
    return np.arange(u0 - h, u0 + h + 1, dtype=float), np.arange(v0 - h, v0 + h + 1, dtype=float)


def expected_electrons(
    shape: tuple[int, int],
    points_px: ArrayLike,
    sigma_px: ArrayLike,
    flux_e: ArrayLike,
    background_e: float,
) -> FloatArray:
    """Noise-free expected electrons per pixel of an image of Gaussian spots.

    Parameters
    ----------
    shape : (H, W)
    points_px : (N, 2) array of float
        Spot centres ``(u, v)``, pixels.
    sigma_px : (N,) array of float
        Spot standard deviations, pixels.
    flux_e : (N,) array of float
        Total electrons of each spot (before clipping at the image border).
    background_e : float
        Uniform background, electrons per pixel.

    Returns
    -------
    (H, W) array of float, electrons
    """
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    n = pts.shape[0]
    sig = np.broadcast_to(np.asarray(sigma_px, dtype=float), (n,))
    flux = np.broadcast_to(np.asarray(flux_e, dtype=float), (n,))
    if np.any(sig <= 0) or np.any(flux < 0):
        raise ConfigError("spot sigma_px must be positive and flux_e non-negative")
    H, W = shape
    mu = np.full((H, W), float(background_e))
    for (u, v), s, f in zip(pts, sig, flux):
        us, vs = spot_window((u, v), s)
        us, vs = us[(us >= 0) & (us < W)], vs[(vs >= 0) & (vs < H)]
        if us.size == 0 or vs.size == 0:
            continue
        block = f * np.outer(pixel_fractions(v, s, vs), pixel_fractions(u, s, us))
        mu[int(vs[0]) : int(vs[-1]) + 1, int(us[0]) : int(us[-1]) + 1] += block
    return mu


def add_noise(mu_e: ArrayLike, sensor: SensorModel, rng: np.random.Generator) -> np.ndarray:
    """Sample a sensor image from expected electrons (see the module docstring).

    Parameters
    ----------
    mu_e : array of float, electrons (any shape)
    sensor : SensorModel
    rng : numpy.random.Generator

    Returns
    -------
    array of uint8 or uint16, DN (same shape as ``mu_e``)
    """
    mu = np.asarray(mu_e, dtype=float)
    electrons = rng.poisson(np.maximum(mu, 0.0)).astype(float)
    if sensor.read_noise_e > 0:
        electrons += rng.normal(0.0, sensor.read_noise_e, size=mu.shape)
    dn = np.rint(sensor.gain_dn_per_e * electrons + sensor.offset_dn)
    return np.clip(dn, 0, sensor.max_dn).astype(sensor.dtype)


def render_spots(
    shape: tuple[int, int],
    points_px: ArrayLike,
    sigma_px: ArrayLike,
    flux_e: ArrayLike,
    sensor: SensorModel,
    rng: np.random.Generator,
    *,
    rgb: ArrayLike | None = None,
) -> np.ndarray:
    """A noisy image of Gaussian spots: mono ``(H, W)`` or, with ``rgb``, colour ``(H, W, 3)``.

    Parameters
    ----------
    shape : (H, W)
    points_px : (N, 2) array of float, pixels
    sigma_px, flux_e : (N,) array of float
        Spot size (pixels) and electrons (per channel at colour weight 1).
    sensor : SensorModel
    rng : numpy.random.Generator
    rgb : (N, 3) array of float in [0, 1], optional
        Per-spot colour: channel ``c`` receives ``flux_e * rgb[:, c]``.

    Returns
    -------
    array of uint8 or uint16, DN; colour images are RGB.
    """
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    if rgb is None:
        return add_noise(
            expected_electrons(shape, pts, sigma_px, flux_e, sensor.background_e), sensor, rng
        )
    col = np.asarray(rgb, dtype=float).reshape(-1, 3)
    check_shape("rgb", col, (pts.shape[0], 3))
    flux = np.broadcast_to(np.asarray(flux_e, dtype=float), (pts.shape[0],))
    chans = [
        add_noise(
            expected_electrons(shape, pts, sigma_px, flux * col[:, c], sensor.background_e),
            sensor,
            rng,
        )
        for c in range(3)
    ]
    return np.stack(chans, axis=-1)


def disc_spot_sigma_px(radius_px: ArrayLike, psf_sigma_px: float) -> FloatArray:
    """Gaussian-equivalent sigma of a uniform disc of ``radius_px`` blurred by a Gaussian PSF.

    A uniform disc of radius ``r`` has per-axis variance ``r**2 / 4``; blurring adds
    the PSF variance. The synthetic dataset uses this moment-matched Gaussian in
    place of the disc (an approximation of the rendered beacon, exact in its centre).
    """
    r = np.asarray(radius_px, dtype=float)
    return np.sqrt(r**2 / 4.0 + psf_sigma_px**2)
