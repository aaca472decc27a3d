"""The centroid Cramér–Rao bound of a spot drawn through a lens's kernels, numerically.

The spot is a splat's Gaussian core and halo (:mod:`deckpose.render.beacons`) convolved,
per colour channel, with the kernels :mod:`deckpose.render.optics` applied; the bound
comes from :func:`deckpose.spot_fisher.centre_crb_px2`.
"""

from __future__ import annotations

import math

import numpy as np
from deckpose.render.bayer import filter_channels
from deckpose.render.beacons import Splat
from deckpose.render.sensor_config import BayerPattern, SensorSpec
from deckpose.render.split_kernels import KernelParts, through_parts
from numpy.typing import NDArray

from deckpose.spot_fisher import centre_crb_px2

__all__ = ["CRB_WINDOW_SIGMAS", "spot_crb_px"]

#: The centroid bound's window: this many core sigmas round the spot's centre, plus 2 px and
#: the kernel. Pixels farther out hold < 0.2 % of the information (the core's beyond 6 sigma:
#: nil; the halo's, ``halo_fraction / halo_scale**2`` = 0.3 % of the total, about half outside).
CRB_WINDOW_SIGMAS = 6.0


def _gauss(centre: NDArray[np.float64], cov: NDArray[np.float64], row0: int, col0: int, n: int
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A unit-flux Gaussian sampled at pixel centres and its derivatives in ``u``, ``v`` and a dilation."""
    inv = np.linalg.inv(cov)
    du = (np.arange(col0, col0 + n) - centre[0])[None, :]
    dv = (np.arange(row0, row0 + n) - centre[1])[:, None]
    q = inv[0, 0] * du * du + 2 * inv[0, 1] * du * dv + inv[1, 1] * dv * dv
    G = np.exp(-0.5 * q) / (2 * math.pi * math.sqrt(float(np.linalg.det(cov))))
    return G, G * (inv[0, 0] * du + inv[0, 1] * dv), G * (inv[1, 0] * du + inv[1, 1] * dv), G * (q - 2.0)


def spot_crb_px(base: Splat, parts: KernelParts, gain: float, background_e: float, sensor: SensorSpec) -> float:
    """Per-axis centroid Cramér–Rao bound of a spot drawn through the optics, pixels.

    The spot is the base splat's Gaussian core (``centre_px``, ``cov_px2``) and halo
    (``halo_fraction``, ``halo_scale``), each channel convolved with its kernel, weighted by
    the colour and summed over channels (the detectors' channel sum), on a uniform
    ``background_e``. Unknown: the centre, the core's width (a dilation), the flux and the
    background; the variance is that of :class:`deckpose.detect.synthetic.SensorModel`
    (``read_noise_e^2 + 1 / (12 gain^2)``, gain = ``(2^bits - 1) / full_well_e``).

    Parameters
    ----------
    base : Splat
        The splat before the optics (its window, centre, covariance, core flux, colour).
    parts : KernelParts
        The red, green and blue kernels applied (:func:`deckpose.render.optics.kernel_parts`;
        whole kernels: :meth:`KernelParts.from_kernels`), through
        :func:`deckpose.render.split_kernels.through_parts` as the drawn spot went.
    gain : float
        The vignetting gain applied.
    background_e : float
        Background electrons per pixel, summed over channels.
    sensor : SensorSpec

    Returns
    -------
    float
        ``sqrt(trace(CRB) / 2)``, pixels (NaN without light).
    """
    if not (base.core_flux > 0 and np.all(np.isfinite(base.cov_px2))):
        return float("nan")
    e_per_rad = sensor.exposure * sensor.full_well_e
    rgb = base.rgb.astype(np.float64)
    weights = rgb / 3.0 if sensor.color == "mono" else rgb  # mono: the grey is the channels' mean
    # the window: CRB_WINDOW_SIGMAS core sigmas round the centre (the kernel widens it)
    rho = math.ceil(CRB_WINDOW_SIGMAS * math.sqrt(float(np.linalg.eigvalsh(base.cov_px2)[-1]))) + 2
    n = 2 * rho + 1
    row0, col0 = round(float(base.centre_px[1])) - rho, round(float(base.centre_px[0])) - rho
    terms = np.zeros((4, n, n))
    h = sensor.halo_fraction
    for frac, scale2 in ((1.0, 1.0), (h / (1.0 - h), sensor.halo_scale ** 2)):
        if frac > 0:
            terms += frac * np.stack(_gauss(base.centre_px, base.cov_px2 * scale2, row0, col0, n))
    terms *= base.core_flux * e_per_rad * gain
    gain_dn = (2 ** sensor.bit_depth - 1) / sensor.full_well_e
    extra_e2 = sensor.read_noise_e ** 2 + 1.0 / (12.0 * gain_dn ** 2)
    # the four images as the channels of one window, through the same kernels as the drawn spot
    # (split_kernels.through_parts); float32 (7 digits: the bound to ~1e-6), several times faster than float64
    four_f32 = np.ascontiguousarray(np.moveaxis(terms, 0, -1), np.float32)
    channels = through_parts(four_f32, parts)
    if sensor.bayer is not BayerPattern.NONE:
        r = (channels[0].shape[0] - n) // 2  # the convolved window starts r before
        crb = _mosaic_crb_px2(channels, weights, background_e, extra_e2, sensor.bayer, row0 - r, col0 - r)
        return float(math.sqrt(max(float(np.trace(crb)) / 2.0, 0.0)))
    four = sum(w * ch.astype(np.float64) for w, ch in zip(weights, channels))  # the channel sum (linear)
    spot, d_u, d_v, d_s = np.moveaxis(np.asarray(four), -1, 0)
    mu = spot + max(background_e, 0.0)
    grads = np.stack([d_u, d_v, d_s, spot, np.ones_like(spot)])
    crb = centre_crb_px2(mu, grads, extra_e2)
    return float(math.sqrt(max(float(np.trace(crb)) / 2.0, 0.0)))


def _mosaic_crb_px2(channels: list[NDArray[np.float32]], weights: NDArray[np.float64], background_e: float,
                    extra_e2: float, pattern: BayerPattern, row0: int, col0: int) -> NDArray[np.float64]:
    """The centre's bound from a colour filter array's photosites, (2, 2) px^2.

    Each photosite collects its own filter's channel only (:func:`deckpose.render.bayer.select_mosaic`),
    so the information is the sum over the channels of that channel's image (its colour weight,
    through its own kernel) over that channel's photosites; a detector that demosaics and sums
    the channels works from these data and cannot do better. Nuisances: the core's width, the
    flux (the colour is known) and one background per channel; the recorded background is the
    channel sum, split evenly (its colour is not recorded: it enters only the variances and a
    nuisance, a second-order effect on the centre's bound).

    Parameters
    ----------
    channels : list of three (n, n, 4) arrays of float32
        The unit-colour spot, its ``u``, ``v`` and dilation derivatives, electrons, through
        the red, green and blue kernels, on the window whose top-left pixel is ``(row0, col0)``.
    weights : (3,) array of float
        The spot's colour, per channel.
    background_e, extra_e2
        As :func:`spot_crb_px` (``extra_e2``: read noise^2 + quantisation, e^2).
    pattern : BayerPattern
        Not ``NONE``.
    row0, col0 : int
        The window's top-left pixel in the image (the pattern's phase).
    """
    n = channels[0].shape[0]
    sites = filter_channels(pattern, n, n, row0, col0)
    on = (sites[None] == np.arange(3)[:, None, None]).astype(np.float64)  # (3, n, n): channel c's photosites
    # each photosite sees its own channel: sum_c on_c w_c image_c, for the spot and its three derivatives
    seen = np.einsum("chw,c,chwp->phw", on, np.asarray(weights, float), np.stack(channels).astype(np.float64))
    mu = seen[0] + max(background_e, 0.0) / 3.0
    # u, v, width, flux, and the three channels' backgrounds
    grads = np.concatenate([seen[1:], seen[:1], on])
    return centre_crb_px2(mu, grads, extra_e2)
