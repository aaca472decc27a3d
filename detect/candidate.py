"""One beacon candidate: a full-resolution window of the frame around one blob, and what a detector needs of it.

:func:`deckpose.detect.candidates.find_candidates` makes them; each detector's
measure function turns one into a row of :class:`~deckpose.detect.registry.Blobs`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.detect.background import percentile

__all__ = ["FLOOR_PERCENTILE", "Candidate"]

#: Percentile of a spot's surroundings that gives its floor (:meth:`Candidate.above_floor`).
FLOOR_PERCENTILE = 20.0


@dataclass(frozen=True)
class Candidate:
    """One blob, in a full-resolution window of the frame.

    Attributes
    ----------
    pixels : (h, w) array of float
        Mono signal of the window (sum of channels), DN, background not removed;
        with the bright-spot search (``DetectorOptions.spot_level``) the peak
        channel (largest channel per pixel).
    mask : (h, w) array of bool
        The blob's connected pixels above the full-resolution threshold.
    saturated : (h, w) array of bool
        Pixels with a channel at the saturation value.
    u0, v0 : int
        Full-resolution column and row of ``pixels[0, 0]``.
    background_dn : float
        Local background at the window centre, DN: a plane fitted to the window
        border (robustly), so a background gradient does not bias centroids.
    background_grad : (float, float)
        Slope of that plane along u and v, DN per pixel.
    noise_dn : float
        Background noise standard deviation, DN: the frame's, or with an uneven
        background (``background_kernel_px``) the window border's.
    gain_dn_per_e : float
        Gain used by the noise model (given, or estimated by
        :func:`deckpose.detect.gain.estimate_gain`), DN per electron.
    threshold_dn : float
        Full-resolution threshold used for ``mask``, DN.
    clip_signal : bool
        Bright-spot search (always, there): ``background_dn`` is the spot's pedestal
        (:func:`~deckpose.detect.spots.spot_pedestal`: the level around the core beyond
        its wings, raised by a marking under the beacon) and
        :meth:`signal` clips at 0, so a dark beacon housing or a white line around
        the core does not pull the centre.
    frame_shape : (int, int) or None
        ``(height, width)`` of the whole frame, pixels, so that a window can tell where
        the frame edge cuts a spot (:meth:`edge_distance_px`); None: not known.
    surround_grad : (float, float)
        A bright spot measured above its flat pedestal (``clip_signal``): the slope along
        u and v of a plane fitted to the window border, DN per pixel, which the pedestal
        does not remove (a neighbour's glare, the lit deck). (0, 0) where the plane is
        removed (``background_grad``) or not known. See :meth:`surround_tilt_cov`.
    surround_grad_sd : float
        Standard deviation of each component of ``surround_grad`` from the noise alone,
        DN per pixel (``noise_dn`` over the border's spread), so that a tilt within the
        noise does not count.
    """

    pixels: np.ndarray
    mask: np.ndarray
    saturated: np.ndarray
    u0: int
    v0: int
    background_dn: float
    background_grad: tuple[float, float]
    noise_dn: float
    gain_dn_per_e: float
    threshold_dn: float
    clip_signal: bool = False
    frame_shape: tuple[int, int] | None = None
    surround_grad: tuple[float, float] = (0.0, 0.0)
    surround_grad_sd: float = 0.0

    def edge_distance_px(self, u_px: float, v_px: float) -> float:
        """Distance from ``(u_px, v_px)`` to the nearest frame edge, pixels (inf if not known).

        Pixel centres are at integers, so the frame spans ``[-0.5, width - 0.5]``. A
        window reaching past this distance is cut by the edge on one side only, and a
        centroid in it is pulled away from the edge (a rendered 20 m beacon 17 px from
        the edge: 0.25 px).
        """
        if self.frame_shape is None:
            return math.inf
        h, w = self.frame_shape
        return min(u_px + 0.5, v_px + 0.5, w - 0.5 - u_px, h - 0.5 - v_px)

    def clipped_at_frame_edge(self) -> bool:
        """Whether the blob has saturated pixels and reaches the frame edge: a clipped core cut by it.

        The plateau of a clipped core carries no position; where the edge cuts it, the part in
        view does not say where its centre is (a rendered 20 m beacon of radius 18 px, its
        centre 5-15 px from the edge: cog errors of 1.9-7 px).
        """
        if self.frame_shape is None or not self.saturated[self.mask].any():
            return False
        rows, cols = np.nonzero(self.mask)
        h, w = self.frame_shape
        return bool(rows.min() + self.v0 == 0 or cols.min() + self.u0 == 0
                    or rows.max() + self.v0 == h - 1 or cols.max() + self.u0 == w - 1)

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Full-resolution ``(u, v)`` coordinates of the window's pixels, each (h, w)."""
        h, w = self.pixels.shape
        return np.meshgrid(np.arange(w, dtype=float) + self.u0, np.arange(h, dtype=float) + self.v0)

    def background_plane(self) -> np.ndarray:
        """The background's tilt over the window (zero at its centre), (h, w) DN."""
        h, w = self.pixels.shape
        gu, gv = self.background_grad
        return (np.arange(h)[:, None] - (h - 1) / 2) * gv + (
            np.arange(w)[None, :] - (w - 1) / 2
        ) * gu

    def _flat(self) -> bool:
        """Whether the background has no tilt (every bright spot's pedestal): no plane to remove."""
        return self.background_grad[0] == 0.0 and self.background_grad[1] == 0.0

    def signal(self) -> np.ndarray:
        """Background-subtracted pixels, DN."""
        s = self.pixels - self.background_dn
        if not self._flat():
            s = s - self.background_plane()
        return np.maximum(s, 0.0) if self.clip_signal else s

    def above_floor(
        self, u_px: float, v_px: float, radius_px: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pixels above the level a spot at ``(u_px, v_px)`` rises from, and where that level was taken.

        The floor is the :data:`FLOOR_PERCENTILE` percentile of the de-tilted pixels
        within ``radius_px`` of the spot: the darker part of its surroundings (a
        beacon's housing, the deck), not the pedestal, which a bright marking nearby
        raises.

        Returns
        -------
        signal_dn : (h, w) array of float
            De-tilted pixels minus the floor, DN (not clipped).
        near : (h, w) array of bool
            The pixels within ``radius_px`` of the spot.
        """
        h, w = self.pixels.shape
        uu = np.arange(w, dtype=float)[None, :] + self.u0  # broadcast: grid()'s values
        vv = np.arange(h, dtype=float)[:, None] + self.v0
        near = np.hypot(uu - u_px, vv - v_px) <= radius_px
        detilted = self.pixels if self._flat() else self.pixels - self.background_plane()
        return detilted - percentile(detilted[near], FLOOR_PERCENTILE), near

    def variance(self, signal_dn: np.ndarray | None = None) -> np.ndarray:
        """Per-pixel noise variance, DN^2: background noise plus shot noise of the signal."""
        s = self.signal() if signal_dn is None else signal_dn
        return self.noise_dn**2 + self.gain_dn_per_e * np.maximum(s, 0.0)

    def surround_tilt_cov(
        self, window: np.ndarray, signal_dn: np.ndarray, du_px: np.ndarray, dv_px: np.ndarray,
        flux_dn: float,
    ) -> np.ndarray:
        """Covariance of the centre's bias from the surround's tilt, px^2 (2, 2), isotropic.

        A background tilt ``g`` (DN/px) left in the signal moves a windowed centroid by
        ``g_u sum(w du^2) / F'`` along u (and likewise along v): the window is symmetric
        about the centre, so the tilt's first moment over it is not zero. (``w`` counts
        where the signal is positive; ``F' = F - sum_edge(r s) / 2`` over the window's soft
        edge, where the window follows the centre: the first-order solution of the
        re-centred window's fixed point.) For a large
        bright spot it dominates the noise: at 2 m the thesis camera sees 0.15 m
        beacons as spots of sigma 49 px, and the glare of the neighbours 570-750 px
        away tilts each one's surround by about 1e-3 DN/px, which moved ``cog``'s
        centres 0.03-0.04 px inward against a noise sigma of 0.003 px. The border's tilt
        (:attr:`surround_grad`) bounds it from the data; it measures the tilt farther out
        than the spot, where a neighbour's glare changes faster, and 2-5x the actual
        shift was seen on rendered frames, so this is an upper bound rather than a
        correction. Its direction is not a bound either (the border's tilt pointed
        across the actual shift on some of those frames), so the bias's size goes on both
        axes. The noise's share of the slope (:attr:`surround_grad_sd` per component) is
        taken out first (``E[|g_hat|^2] = |g|^2 + 2 sd^2``), so a flat surround adds
        nothing on average.

        Parameters
        ----------
        window : (h, w) array of float
            The disc window's weight of each pixel (1 inside, falling to 0 over its edge pixel).
        signal_dn : (h, w) array of float
            The signal the centroid was measured on, DN.
        du_px, dv_px : (h, w) or broadcastable arrays of float
            Pixel offsets from the centre, px.
        flux_dn : float
            Windowed flux ``F = sum(window * signal)``, DN.
        """
        if self.surround_tilt2() == 0.0 or not flux_dn > 0:
            return np.zeros((2, 2))
        r2 = du_px * du_px + dv_px * dv_px
        m2 = 0.5 * float((window * (signal_dn > 0) * r2).sum())
        edge = (window > 0) & (window < 1)
        f_eff = flux_dn - 0.5 * float((np.sqrt(r2) * signal_dn)[edge].sum())
        f_eff = f_eff if f_eff > 0.5 * flux_dn else flux_dn
        return self.surround_bias_cov(m2 / f_eff)

    def surround_tilt2(self) -> float:
        """The surround's squared tilt beyond its noise, ``max(|g|^2 - 2 sd^2, 0)``, (DN/px)^2."""
        gu, gv = self.surround_grad
        return max(gu * gu + gv * gv - 2.0 * self.surround_grad_sd**2, 0.0)

    def surround_bias_cov(self, px_per_tilt: float) -> np.ndarray:
        """Isotropic covariance (2, 2), px^2, of a centre that a unit tilt (1 DN/px) moves ``px_per_tilt``.

        The one rule of :meth:`surround_tilt_cov` (a windowed centroid) and of
        :func:`~deckpose.detect.core_fit.core_fit` (a least-squares fit, which finds its
        ``px_per_tilt`` by propagating a tilt through its normal equations): the
        border's tilt beyond its noise (:meth:`surround_tilt2`), times that response, on
        both axes.
        """
        return np.eye(2) * (self.surround_tilt2() * px_per_tilt**2)

    def mask_moments(self) -> tuple[float, float, float]:
        """Binary centroid ``(u, v)`` and Gaussian-equivalent sigma of the mask, pixels."""
        vv, uu = np.nonzero(self.mask)
        return float(uu.mean() + self.u0), float(vv.mean() + self.v0), self.mask_sigma()

    def mask_sigma(self) -> float:
        """Gaussian-equivalent sigma of the mask, pixels: half its equivalent radius plus 0.3."""
        area = int(np.count_nonzero(self.mask))
        return math.sqrt(max(area, 1) / math.pi) / 2.0 + 0.3

    def blob(
        self,
        u_px: float,
        v_px: float,
        *,
        flux_dn: float,
        size_px: float | None = None,
        cov_px2: np.ndarray | None = None,
    ) -> tuple[float, float, np.ndarray, float, float, float]:
        """A :class:`~deckpose.detect.registry.Blobs` row, filling in what is not given.

        The default covariance is that of an intensity-weighted centroid of a
        Gaussian spot of ``size_px`` under this window's noise model.
        """
        size = self.mask_sigma() if size_px is None else float(size_px)
        area = int(self.mask.sum())
        score = float(flux_dn / (self.noise_dn * math.sqrt(max(area, 1))))
        if cov_px2 is None:
            n_e = max(flux_dn, 1e-9) / self.gain_dn_per_e
            npix = 4.0 * math.pi * size**2
            bg_e2 = npix * self.noise_dn**2 / self.gain_dn_per_e**2
            var = (size**2 + 1.0 / 12.0) / n_e * (1.0 + bg_e2 / n_e)
            cov_px2 = np.eye(2) * var
        return (float(u_px), float(v_px), np.asarray(cov_px2, float), float(flux_dn), size, score)
