"""A light's lens kernels in the parts they are applied in, and a window through them.

The red, green and blue kernels of :mod:`deckpose.render.optics` are

``K_c = shift(d_c) * (core_weight core_c + wide)``

(``*`` discrete convolution): ``core_c`` small (Airy * disc * field blur), ``wide`` the glare
and spikes (large, the same for every channel), ``shift(d_c)`` the lateral chromatic
aberration. By linearity a window goes through all three with one convolution by the wide
kernel, not three (:func:`through_parts`; :func:`compose_parts` writes the same formula as
whole kernels, which the recorded sigma needs, and a test holds the two equal); the spots' pixels
(:func:`deckpose.render.optics.apply_optics`) and their Cramér–Rao bound
(:func:`deckpose.render.spot_bound.spot_crb_px`) both go through here, so what is drawn
and what is bounded are the same convolution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.render.psf_kernels import (
    Kernel,
    convolve_kernels,
    full_convolution,
    mix_kernels,
    pad_kernel,
    shift_kernel,
)
from numpy.typing import NDArray

__all__ = ["CHANNELS", "NO_PARTS", "KernelParts", "compose_parts", "shift_radius", "through_parts"]

#: Channels of a light's kernels: red, green, blue.
CHANNELS = 3


@dataclass(frozen=True)
class KernelParts:
    """A light's kernels in the parts they are applied in (:func:`compose_parts` composes them).

    ``K_c = shift(shifts_px[c]) * (core_weight * cores[c] + wide)``: ``cores`` the red, green
    and blue small kernels (Airy * disc * field blur), ``wide`` the glare and spikes
    (already weighted by their fractions; None without them), the same for every channel;
    ``shifts_px`` (3, 2) each channel's lateral shift ``(du, dv)``, pixels.
    """

    cores: tuple[Kernel, Kernel, Kernel]
    core_weight: float
    wide: Kernel | None
    shifts_px: NDArray[np.float64]

    @classmethod
    def from_kernels(cls, kernels: tuple[Kernel, Kernel, Kernel]) -> KernelParts:
        """Three whole channel kernels as parts (no wide kernel, no shift)."""
        return cls(kernels, 1.0, None, np.zeros((CHANNELS, 2)))


def _identity() -> Kernel:
    k = np.ones((1, 1))
    k.setflags(write=False)
    return k


#: No lens: every channel's kernel the identity (read-only arrays: the record is shared).
NO_PARTS = KernelParts.from_kernels((_identity(), _identity(), _identity()))
NO_PARTS.shifts_px.setflags(write=False)


def shift_radius(shifts_px: NDArray[np.float64]) -> int:
    """The radius of the channels' shift kernels (0: no chromatic aberration)."""
    m = float(np.abs(shifts_px).max())
    return math.ceil(m) + 1 if m > 0 else 0


def compose_parts(parts: KernelParts) -> tuple[Kernel, Kernel, Kernel]:
    """The red, green and blue kernels ``K_c``, each ``(2R+1, 2R+1)``, one ``R`` for all three."""
    rs = shift_radius(parts.shifts_px)
    out = []
    for c in range(CHANNELS):
        k = mix_kernels([(parts.core_weight, parts.cores[c])] + ([(1.0, parts.wide)] if parts.wide is not None else []))
        if rs:
            k = convolve_kernels(k, shift_kernel(parts.shifts_px[c], rs))
        out.append(k)
    radius = max(k.shape[0] // 2 for k in out)
    r, gr, b = (pad_kernel(k, radius) for k in out)
    return r, gr, b


def _pad_plane(a: NDArray[np.float32], p: int) -> NDArray[np.float32]:
    """``a`` with ``p`` zero rows and columns each side (trailing axes untouched)."""
    return np.pad(a, ((p, p), (p, p)) + ((0, 0),) * (a.ndim - 2)) if p else a


def through_parts(window: NDArray[np.float32], parts: KernelParts) -> list[NDArray[np.float32]]:
    """The full convolution of a window with each channel's kernel.

    Parameters
    ----------
    window : (h, w) or (h, w, m) array of float32
        The window; ``m`` images (at most 4) are convolved alike, each on its own.
    parts : KernelParts

    Returns
    -------
    list of three arrays, each (h + 2R, w + 2R) or (h + 2R, w + 2R, m), float32
        Red, green, blue; ``R`` the radius of :func:`compose_parts`'s kernels. Equal to
        ``full_convolution(window, compose_parts(parts)[c])`` up to float32 round-off.
    """
    wide = full_convolution(window, parts.wide) if parts.wide is not None else None
    r_core = max(k.shape[0] // 2 for k in parts.cores)
    r_mix = max(r_core, 0 if parts.wide is None else parts.wide.shape[0] // 2)
    rs = shift_radius(parts.shifts_px)
    channels = []
    for c in range(CHANNELS):
        core = full_convolution(window, parts.cores[c])
        if parts.core_weight != 1.0:
            core = core * np.float32(parts.core_weight)
        ch = _pad_plane(core, r_mix - parts.cores[c].shape[0] // 2)
        if wide is not None and parts.wide is not None:
            ch = ch + _pad_plane(wide, r_mix - parts.wide.shape[0] // 2)
        if rs:
            ch = full_convolution(ch, shift_kernel(parts.shifts_px[c], rs))
        channels.append(np.asarray(ch, np.float32))
    return channels
