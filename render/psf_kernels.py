"""Point-spread kernels of a lens, integrated over pixels, and their full discrete convolution.

Each kernel is a ``(2R+1, 2R+1)`` array that sums to 1 and is centred on its middle pixel;
all but :func:`shift_kernel` are point-symmetric about it (so convolving a spot with them
keeps its centroid: the centroid of a full discrete convolution is the sum of the
centroids). Profiles are averaged over each pixel on :data:`KERNEL_OVERSAMPLE` x
:data:`KERNEL_OVERSAMPLE` points. Used by :mod:`deckpose.render.optics`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import cast

import cv2
import numpy as np
import scipy.fft
from deckpose.render.optics_config import OpticsSpec
from numpy.typing import NDArray
from scipy.special import erf, j1

__all__ = [
    "AIRY_TRUNCATION",
    "FFT_RADIUS_PX",
    "GAUSSIAN_TRUNCATION",
    "GLARE_TRUNCATION",
    "KERNEL_OVERSAMPLE",
    "SPIKE_TRUNCATION",
    "SPIKE_WIDTH_PX",
    "Kernel",
    "airy_first_zero_px",
    "airy_kernel",
    "convolve_kernels",
    "disk_kernel",
    "full_convolution",
    "gaussian_kernel",
    "glare_kernel",
    "kernel_covariance",
    "mix_kernels",
    "pad_kernel",
    "shift_kernel",
    "spike_angles_rad",
    "spike_kernel",
]

#: Sub-samples per pixel side when a kernel is integrated over pixels (odd: one falls on the centre).
KERNEL_OVERSAMPLE = 7
#: The Airy kernel's radius in first-zero radii (1.22 lambda N): ~98 % of its light inside.
AIRY_TRUNCATION = 4.0
#: The glare tail's radius in ``glare_radius_px`` (the profile there is 0.2 % of its peak).
GLARE_TRUNCATION = 8.0
#: A spike's length in ``spike_length_px`` (its 1/e length): exp(-4) = 2 % left at the end.
SPIKE_TRUNCATION = 4.0
#: A spike's Gaussian sigma across its line, pixels (an assumption: about the Airy core's half-width).
SPIKE_WIDTH_PX = 0.5
#: The field blur's Gaussian radius in sigmas (:func:`gaussian_kernel`): 1.3e-4 of its light beyond.
GAUSSIAN_TRUNCATION = 4.0

Kernel = NDArray[np.float64]


def airy_first_zero_px(wavelength_nm: float, optics: OpticsSpec) -> float:
    """Radius of the Airy pattern's first dark ring, ``1.22 lambda N``, pixels."""
    return 1.22 * wavelength_nm * 1e-9 * optics.f_number / (optics.pixel_pitch_um * 1e-6)


def _integrated(profile: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]],
                radius_px: int) -> Kernel:
    """``profile(dx, dy)`` averaged over each pixel of a (2R+1)^2 grid, normalised to sum 1."""
    k = KERNEL_OVERSAMPLE
    sub = (np.arange(k) + 0.5) / k - 0.5
    x = (np.arange(-radius_px, radius_px + 1)[:, None] + sub[None, :]).ravel()
    vals = profile(x[None, :], x[:, None])  # (rows = dy, cols = dx)
    n = 2 * radius_px + 1
    kern = vals.reshape(n, k, n, k).sum(axis=(1, 3))
    out = np.asarray(kern / kern.sum(), float)
    out.setflags(write=False)  # some are cached (lru_cache): shared, never modified
    return out


def disk_kernel(diameter_px: float) -> Kernel:
    """A uniform disc of ``diameter_px``, integrated over pixels ((1, 1) = no blur below 1/7 px)."""
    r = 0.5 * diameter_px
    if r < 0.5 / KERNEL_OVERSAMPLE:
        return np.ones((1, 1))
    return _integrated(lambda dx, dy: (dx * dx + dy * dy <= r * r).astype(float), math.ceil(r))


@functools.lru_cache(maxsize=32)
def airy_kernel(wavelength_nm: float, optics: OpticsSpec) -> Kernel:
    """The Airy pattern of ``wavelength_nm`` at ``optics.f_number``, integrated over pixels."""
    scale = math.pi * optics.pixel_pitch_um * 1e-6 / (wavelength_nm * 1e-9 * optics.f_number)  # x per px
    radius = max(1, math.ceil(AIRY_TRUNCATION * airy_first_zero_px(wavelength_nm, optics)))

    def profile(dx: NDArray[np.float64], dy: NDArray[np.float64]) -> NDArray[np.float64]:
        x = scale * np.hypot(dx, dy)
        safe = np.where(x > 1e-12, x, 1.0)
        return np.where(x > 1e-12, (2.0 * j1(safe) / safe) ** 2, 1.0)

    return _integrated(profile, radius)


@functools.lru_cache(maxsize=32)
def glare_kernel(optics: OpticsSpec) -> Kernel:
    """The glare tail ``(1 + (r / a)^2)^-1.5``, ``a = glare_radius_px``, integrated over pixels."""
    a = optics.glare_radius_px
    return _integrated(lambda dx, dy: (1.0 + (dx * dx + dy * dy) / (a * a)) ** -1.5,
                       math.ceil(GLARE_TRUNCATION * a))


def spike_angles_rad(blades: int) -> tuple[float, ...]:
    """The angle of each line of spikes from the +u axis towards +v, radians: ``pi j / lines``.

    A line holds two opposite spikes: an aperture of ``n`` blades has ``n / 2`` lines (``n``
    spikes) for even ``n``, ``n`` lines (``2n`` spikes) for odd ``n``; the first runs along +u.
    """
    lines = blades if blades % 2 else blades // 2
    return tuple(math.pi * j / lines for j in range(lines))


@functools.lru_cache(maxsize=32)
def spike_kernel(optics: OpticsSpec) -> Kernel:
    """Diffraction spikes of a ``spike_blades``-blade aperture (:func:`spike_angles_rad`), integrated over pixels."""
    angles = spike_angles_rad(optics.spike_blades)
    L = optics.spike_length_px

    def profile(dx: NDArray[np.float64], dy: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.zeros(np.broadcast_shapes(dx.shape, dy.shape))
        for th in angles:
            t = dx * math.cos(th) + dy * math.sin(th)
            p = -dx * math.sin(th) + dy * math.cos(th)
            out = out + np.exp(-np.abs(t) / L - 0.5 * (p / SPIKE_WIDTH_PX) ** 2)
        return out

    return _integrated(profile, math.ceil(SPIKE_TRUNCATION * L))


def gaussian_kernel(sigma_px: float) -> Kernel:
    """A circular Gaussian of ``sigma_px`` integrated over pixels (erf), ((1, 1) at sigma 0).

    Cut at :data:`GAUSSIAN_TRUNCATION` sigmas (rounded up to whole pixels) and renormalised.
    """
    if sigma_px <= 0:
        return np.ones((1, 1))
    r = math.ceil(GAUSSIAN_TRUNCATION * sigma_px)
    x = np.arange(-r, r + 1, dtype=float)
    e = 0.5 * (erf((x + 0.5) / (math.sqrt(2) * sigma_px)) - erf((x - 0.5) / (math.sqrt(2) * sigma_px)))
    k = np.outer(e, e)
    return np.asarray(k / k.sum(), float)


def shift_kernel(shift_px: NDArray[np.float64], radius_px: int | None = None) -> Kernel:
    """The bilinear kernel that moves light by ``shift_px = (du, dv)``; its centroid is exactly the shift.

    ``radius_px`` (default: just enough) sizes it ``(2 radius + 1)^2``.
    """
    du, dv = (float(x) for x in shift_px)
    r = math.ceil(max(abs(du), abs(dv))) + 1 if radius_px is None else radius_px
    k = np.zeros((2 * r + 1, 2 * r + 1))
    iu, iv = math.floor(du), math.floor(dv)
    fu, fv = du - iu, dv - iv
    for dr, wr in ((0, 1.0 - fv), (1, fv)):
        for dc, wc in ((0, 1.0 - fu), (1, fu)):
            k[r + iv + dr, r + iu + dc] += wr * wc
    return k


#: Kernels of this radius or more go through their Fourier transform (scipy.fft, the kernel's
#: transform cached), smaller ones through OpenCV's ``filter2D``: at the glare kernel's radius 24 on
#: a 131 px window the transform is 4.5x faster; at radius 5 the two are even.
FFT_RADIUS_PX = 8


def full_convolution(image: NDArray[np.floating], kernel: Kernel) -> NDArray[np.floating]:
    """The full discrete convolution of an (n, m) window with a (2R+1, 2R+1) kernel, (n + 2R, m + 2R).

    ``image`` may carry channels, (n, m, c), each convolved alike. Below
    :data:`FFT_RADIUS_PX`, OpenCV's ``filter2D`` on the window padded with R zeros each side
    (it correlates, so the kernel is turned by 180 degrees); from it on, the product of the
    discrete Fourier transforms, zero-padded to a fast length. Same dtype as ``image``.
    """
    if kernel.ndim != 2 or kernel.shape[0] != kernel.shape[1] or kernel.shape[0] % 2 == 0:
        raise ValueError(f"a kernel is square with an odd side, got shape {kernel.shape}")
    r = kernel.shape[0] // 2
    if r == 0:
        return image * image.dtype.type(kernel[0, 0])
    if r >= FFT_RADIUS_PX:
        return _fft_convolution(image, kernel)
    padded = cv2.copyMakeBorder(np.ascontiguousarray(image), r, r, r, r, cv2.BORDER_CONSTANT, value=0)
    k = np.ascontiguousarray(kernel[::-1, ::-1], dtype=image.dtype)
    return np.asarray(cv2.filter2D(padded, -1, k, borderType=cv2.BORDER_CONSTANT), image.dtype)


#: The largest kernel spectrum kept in the cache, elements (8 MiB in complex64): a window of
#: about 2,000 px a side; spectra of larger windows are made each time (64 at most are kept).
MAX_CACHED_SPECTRUM = 1 << 20


def _fft_convolution(image: NDArray[np.floating], kernel: Kernel) -> NDArray[np.floating]:
    """:func:`full_convolution` through real FFTs zero-padded to a fast length, the kernel's transform cached."""
    m0, m1 = image.shape[0] + kernel.shape[0] - 1, image.shape[1] + kernel.shape[1] - 1
    shape = (cast(int, scipy.fft.next_fast_len(m0, real=True)), cast(int, scipy.fft.next_fast_len(m1, real=True)))
    k = np.ascontiguousarray(kernel, dtype=image.dtype)
    if shape[0] * (shape[1] // 2 + 1) <= MAX_CACHED_SPECTRUM:
        spectrum = _spectrum(k.tobytes(), k.shape, k.dtype.str, shape)
    else:
        spectrum = _rfft2(k, shape)
    if image.ndim == 3:
        spectrum = spectrum[:, :, None]
    out = cast(NDArray[np.floating], scipy.fft.irfft2(_rfft2(image, shape) * spectrum, shape, axes=(0, 1)))
    return np.asarray(out[:m0, :m1], image.dtype)


def _rfft2(a: NDArray[np.floating], shape: tuple[int, int]) -> NDArray[np.complexfloating]:
    """The real FFT of ``a`` over its first two axes, zero-padded to ``shape``."""
    return cast(NDArray[np.complexfloating], scipy.fft.rfft2(a, shape, axes=(0, 1)))


@functools.lru_cache(maxsize=64)
def _spectrum(data: bytes, kshape: tuple[int, ...], dtype: str, shape: tuple[int, int]) -> NDArray[np.complexfloating]:
    """:func:`_rfft2` of a kernel given by its bytes, read-only: each light's lens shares the
    glare kernel, so its transform is made once per window size."""
    spectrum = _rfft2(np.frombuffer(data, np.dtype(dtype)).reshape(kshape), shape)
    spectrum.setflags(write=False)
    return spectrum


def convolve_kernels(a: Kernel, b: Kernel) -> Kernel:
    """Full discrete convolution of two centred kernels (a centred kernel again)."""
    if a.size == 1:
        return b * float(a[0, 0])
    if b.size == 1:
        return a * float(b[0, 0])
    return np.maximum(full_convolution(a, b) if a.shape[0] >= b.shape[0] else full_convolution(b, a), 0.0)


def pad_kernel(k: Kernel, radius: int) -> Kernel:
    p = radius - k.shape[0] // 2
    return np.pad(k, p) if p > 0 else k


def mix_kernels(parts: list[tuple[float, Kernel]]) -> Kernel:
    """``sum w_i K_i`` of centred kernels of any sizes."""
    radius = max(k.shape[0] // 2 for _, k in parts)
    return sum((w * pad_kernel(k, radius) for w, k in parts if w > 0), np.zeros((2 * radius + 1,) * 2))


def kernel_covariance(k: Kernel) -> NDArray[np.float64]:
    """Second-moment matrix of a kernel about its centroid, (2, 2) px^2 in (u, v)."""
    n = k.shape[0]
    v, u = np.mgrid[0:n, 0:n].astype(float)
    w = k / k.sum()
    cu, cv = float((w * u).sum()), float((w * v).sum())
    du, dv = u - cu, v - cv
    return np.array([[(w * du * du).sum(), (w * du * dv).sum()], [(w * du * dv).sum(), (w * dv * dv).sum()]])
