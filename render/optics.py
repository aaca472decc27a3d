"""The lens beyond a Gaussian: defocus, diffraction, glare, spikes, blooming, vignetting, CA, field blur.

Every effect is off by default (:class:`deckpose.render.config.OpticsSpec`) and acts on the
light spots (:mod:`deckpose.render.beacons`), not on the whole frame (cost). A spot's
window, the Gaussian core and halo sampled at pixel centres, is convolved in full, per
colour channel ``c``, with a kernel

``K_c = shift(d_c) * [(1 - g - s) Airy_c * Disk(D) * Gauss(sigma_f) + g Glare + s Spikes]``

(``*`` discrete convolution), each factor a ``(2R+1, 2R+1)`` array summing to 1 and
integrated over pixels (sub-sampled :data:`KERNEL_OVERSAMPLE` x per side):

* ``Disk(D)``: a uniform disc of the thin-lens blur diameter at the light's depth ``s``,
  ``D = f^2 |s - s_f| / (N s (s_f - f))`` on the sensor (``f`` = ``fx`` x pixel pitch,
  ``N`` the f-number, ``s_f`` the focus distance), in pixels;
* ``Airy_c``: ``(2 J1(x) / x)^2``, ``x = pi r / (lambda_c N)`` (``r`` on the sensor),
  cut at :data:`AIRY_TRUNCATION` first-zero radii ``1.22 lambda N`` (about 98 % of the
  light) and renormalised;
* ``Gauss(sigma_f)``: the field-dependent blur, ``sigma_f = field_blur_px (rho / rho_corner)^2``
  with ``rho`` the distance from the principal point;
* ``Glare``: ``(1 + (r / a)^2)^-1.5`` out to :data:`GLARE_TRUNCATION` ``a``; ``Spikes``:
  ``exp(-|t| / L)`` along each spike's line times a Gaussian of :data:`SPIKE_WIDTH_PX`
  across it (an aperture of ``n`` blades gives ``n`` spikes when ``n`` is even, ``2n``
  when odd; spikes come in opposite pairs, as the diffraction pattern of any aperture is
  point-symmetric);
* ``shift(d_c)``: lateral chromatic aberration, the bilinear kernel that moves the
  channel's light by ``d_c = (m_c - 1) (x - x_0)`` (``m_c`` the channel's magnification
  relative to green, ``x_0`` the principal point); its centroid is exactly ``d_c``.

Every factor but the shift is point-symmetric about its centre pixel, so (the centroid of
a full discrete convolution being the sum of the centroids) each channel's light stays
centred where the spot was, the green one on ``u_px, v_px``, and the shift moves the red
and blue exactly to their recorded truth; the kernels sum to 1, so the flux is kept.
Vignetting multiplies the raster (:func:`vignetting_rows`) and each spot (at its centre)
by ``cos(theta)^n``, ``tan(theta)`` the pinhole ray's slope. Blooming
(:func:`bloom_splats`) spills the charge a pixel holds above the full well up and down its
column, half each way, filling the next unsaturated pixels; it conserves charge.

The centroid Cramér–Rao bound of a spot (:func:`spot_crb_px`) is computed from this
PSF: the core and halo Gaussians of the spot and their derivatives (centre, width) are
convolved with the same kernels, summed over channels, and passed with the background and
read noise to :func:`deckpose.spot_fisher.centre_crb_px2`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np
from deckpose.render.beacons import Splat
from deckpose.render.config import OpticsSpec, SensorSpec
from deckpose.render.sensor import SpotRecord, spot_record
from numpy.typing import NDArray
from scipy.special import erf, j1

from deckpose.camera import CameraModel
from deckpose.spot_fisher import centre_crb_px2

__all__ = [
    "AIRY_TRUNCATION", "BLOOM_MAX_PAD_PX", "CRB_WINDOW_SIGMAS", "GLARE_TRUNCATION", "KERNEL_OVERSAMPLE", "OPTICS_CHANNELS", "OPTICS_COLUMNS",
    "SPIKE_TRUNCATION", "SPIKE_WIDTH_PX", "KernelParts", "LensedFrame", "OpticsRecord", "SpotOptics", "airy_first_zero_px", "airy_kernel", "apply_optics",
    "bloom_column", "bloom_splats", "ca_centres_px", "channel_kernels", "defocus_diameter_px", "disk_kernel",
    "field_sigma_px", "focal_length_m", "gaussian_kernel", "glare_kernel", "kernel_parts", "optics_block", "optics_record",
    "optics_row", "shift_kernel", "spike_kernel", "spot_crb_px", "through_lens", "vignetting_gain",
    "vignetting_rows",
]

#: Sub-samples per pixel side when a kernel is integrated over pixels (odd: one falls on the centre).
KERNEL_OVERSAMPLE = 7
#: The Airy kernel's radius in first-zero radii (1.22 lambda N): ~98 % of its light inside.
AIRY_TRUNCATION = 4.0
#: The glare tail's radius in ``glare_radius_px`` (the profile there is 0.2 % of its peak).
GLARE_TRUNCATION = 8.0
#: A spike's length in ``spike_length_px`` (its 1/e length): exp(-4) = 2 % left at the end.
SPIKE_TRUNCATION = 4.0
#: A spike's Gaussian half-width across its line, pixels (an assumption: about the Airy core's).
SPIKE_WIDTH_PX = 0.5
#: The centroid bound's window: this many core sigmas round the spot's centre, plus 2 px and
#: the kernel. Pixels farther out hold < 0.2 % of the information (the core's beyond 6 sigma:
#: nil; the halo's, ``halo_fraction / halo_scale**2`` = 0.3 % of the total, about half outside).
CRB_WINDOW_SIGMAS = 6.0
#: Channels of a spot's optical patch: red, green, blue.
OPTICS_CHANNELS = 3

Kernel = NDArray[np.float64]


def focal_length_m(camera: CameraModel, optics: OpticsSpec) -> float:
    """Focal length of the lens, metres: ``fx`` (pixels) times the pixel pitch."""
    return camera.fx * optics.pixel_pitch_um * 1e-6


def defocus_diameter_px(depth_m: NDArray[np.float64], camera: CameraModel, optics: OpticsSpec
                        ) -> NDArray[np.float64]:
    """Thin-lens blur-circle diameter of points at ``depth_m``, pixels (0 without defocus).

    Parameters
    ----------
    depth_m : (N,) array of float
        Distance of each point along the optical axis, metres.
    camera : CameraModel
    optics : OpticsSpec
        ``f_number``, ``focus_distance_m`` (None: 0 everywhere), ``pixel_pitch_um``.

    Returns
    -------
    (N,) array of float
        ``f^2 |s - s_f| / (N s (s_f - f)) / pitch``.
    """
    s = np.asarray(depth_m, float)
    if optics.focus_distance_m is None:
        return np.zeros_like(s)
    f = focal_length_m(camera, optics)
    sf = optics.focus_distance_m
    c_m = f * f * np.abs(s - sf) / (optics.f_number * s * (sf - f))
    return np.asarray(c_m / (optics.pixel_pitch_um * 1e-6), float)


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


@functools.lru_cache(maxsize=32)
def spike_kernel(optics: OpticsSpec) -> Kernel:
    """Diffraction spikes of a ``spike_blades``-blade aperture, integrated over pixels."""
    n = optics.spike_blades
    lines = n if n % 2 else n // 2  # 2n spikes (odd n) or n spikes (even n), in opposite pairs
    L = optics.spike_length_px

    def profile(dx: NDArray[np.float64], dy: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.zeros(np.broadcast_shapes(dx.shape, dy.shape))
        for j in range(lines):
            th = math.pi * j / lines
            t = dx * math.cos(th) + dy * math.sin(th)
            p = -dx * math.sin(th) + dy * math.cos(th)
            out = out + np.exp(-np.abs(t) / L - 0.5 * (p / SPIKE_WIDTH_PX) ** 2)
        return out

    return _integrated(profile, math.ceil(SPIKE_TRUNCATION * L))


def gaussian_kernel(sigma_px: float) -> Kernel:
    """A circular Gaussian of ``sigma_px`` integrated over pixels (erf), ((1, 1) at sigma 0)."""
    if sigma_px <= 0:
        return np.ones((1, 1))
    r = math.ceil(4.0 * sigma_px)
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


def _full_conv(image: NDArray[np.floating], kernel: Kernel) -> NDArray[np.floating]:
    """The full discrete convolution of an (n, m) window with a (2R+1, 2R+1) kernel, (n + 2R, m + 2R).

    OpenCV's ``filter2D`` (a DFT for large kernels) on the window padded with R zeros each
    side; it correlates, so the kernel is turned by 180 degrees. Same dtype as ``image``.
    """
    r = kernel.shape[0] // 2
    if r == 0:
        return image * image.dtype.type(kernel[0, 0])
    padded = cv2.copyMakeBorder(np.ascontiguousarray(image), r, r, r, r, cv2.BORDER_CONSTANT, value=0)
    k = np.ascontiguousarray(kernel[::-1, ::-1], dtype=image.dtype)
    return np.asarray(cv2.filter2D(padded, -1, k, borderType=cv2.BORDER_CONSTANT), image.dtype)


def _conv(a: Kernel, b: Kernel) -> Kernel:
    """Full discrete convolution of two centred kernels (a centred kernel again)."""
    if a.size == 1:
        return b * float(a[0, 0])
    if b.size == 1:
        return a * float(b[0, 0])
    return np.maximum(_full_conv(a, b) if a.shape[0] >= b.shape[0] else _full_conv(b, a), 0.0)


def _pad(k: Kernel, radius: int) -> Kernel:
    p = radius - k.shape[0] // 2
    return np.pad(k, p) if p > 0 else k


def _mix(parts: list[tuple[float, Kernel]]) -> Kernel:
    """``sum w_i K_i`` of centred kernels of any sizes."""
    radius = max(k.shape[0] // 2 for _, k in parts)
    return sum((w * _pad(k, radius) for w, k in parts if w > 0), np.zeros((2 * radius + 1,) * 2))


def vignetting_gain(points_px: NDArray[np.float64], camera: CameraModel, exponent: float
                    ) -> NDArray[np.float64]:
    """``cos(theta)^n`` at each point, ``tan^2 theta = ((u - cx) / fx)^2 + ((v - cy) / fy)^2``; (N,)."""
    p = np.asarray(points_px, float).reshape(-1, 2)
    t2 = ((p[:, 0] - camera.cx) / camera.fx) ** 2 + ((p[:, 1] - camera.cy) / camera.fy) ** 2
    return np.asarray((1.0 + t2) ** (-0.5 * exponent), float)


def vignetting_rows(camera: CameraModel, exponent: float) -> Callable[[int, int], NDArray[np.float32]]:
    """The raster's vignetting gain, rows ``r0:r1`` at a time: ``f(r0, r1) -> (r1 - r0, W)`` float32."""
    tx2 = (((np.arange(camera.width_px) - camera.cx) / camera.fx) ** 2).astype(np.float32)

    def rows(r0: int, r1: int) -> NDArray[np.float32]:
        ty2 = (((np.arange(r0, r1) - camera.cy) / camera.fy) ** 2).astype(np.float32)
        return np.asarray((1.0 + ty2[:, None] + tx2[None, :]) ** np.float32(-0.5 * exponent), np.float32)

    return rows


def ca_centres_px(points_px: NDArray[np.float64], camera: CameraModel, optics: OpticsSpec
                  ) -> NDArray[np.float64]:
    """Each channel's centre under lateral CA: ``x_0 + m_c (x - x_0)``; (N, 3, 2), channels r, g, b."""
    p = np.asarray(points_px, float).reshape(-1, 2)
    x0 = np.array([camera.cx, camera.cy])
    m = 1.0 + np.array([optics.lateral_ca_ppm[0], 0.0, optics.lateral_ca_ppm[1]]) * 1e-6
    return x0 + m[None, :, None] * (p - x0)[:, None, :]


def field_sigma_px(points_px: NDArray[np.float64], camera: CameraModel, optics: OpticsSpec
                   ) -> NDArray[np.float64]:
    """Field-dependent blur sigma, ``field_blur_px (rho / rho_corner)^2``, pixels; (N,)."""
    p = np.asarray(points_px, float).reshape(-1, 2)
    corners = np.array([[0, 0], [camera.width_px, 0], [0, camera.height_px], [camera.width_px, camera.height_px]])
    rho_c = float(np.max(np.hypot(corners[:, 0] - camera.cx, corners[:, 1] - camera.cy)))
    rho = np.hypot(p[:, 0] - camera.cx, p[:, 1] - camera.cy)
    return np.asarray(optics.field_blur_px * (rho / rho_c) ** 2, float)


@dataclass(frozen=True)
class KernelParts:
    """A light's kernels in the parts they are applied in (:func:`channel_kernels` composes them).

    ``K_c = shift(shifts_px[c]) * (core_weight * cores[c] + wide)``: ``cores`` the red, green
    and blue small kernels (Airy * disc * field blur), ``wide`` the glare and spikes
    (already weighted by their fractions; None without them), the same for every channel.
    """

    cores: tuple[Kernel, Kernel, Kernel]
    core_weight: float
    wide: Kernel | None
    shifts_px: NDArray[np.float64]


def kernel_parts(optics: OpticsSpec, camera: CameraModel, depth_m: float, centre_px: NDArray[np.float64]
                 ) -> KernelParts:
    """The :class:`KernelParts` of a light at ``depth_m`` seen at ``centre_px`` (2,)."""
    centre = np.asarray(centre_px, float).reshape(1, 2)
    blur = _conv(disk_kernel(float(defocus_diameter_px(np.array([depth_m]), camera, optics)[0])),
                 gaussian_kernel(float(field_sigma_px(centre, camera, optics)[0])))
    g, s = optics.glare_fraction, optics.spike_fraction
    cores = tuple(_conv(airy_kernel(w, optics), blur) if optics.diffraction else blur
                  for w in optics.wavelength_nm)
    return KernelParts((cores[0], cores[1], cores[2]), 1.0 - g - s, _wide_kernel(optics),
                       ca_centres_px(centre, camera, optics)[0] - centre[0])


@functools.lru_cache(maxsize=32)
def _wide_kernel(optics: OpticsSpec) -> Kernel | None:
    """``g Glare + s Spikes`` (None when both fractions are 0)."""
    parts = [(optics.glare_fraction, glare_kernel(optics))] if optics.glare_fraction > 0 else []
    if optics.spike_fraction > 0:
        parts.append((optics.spike_fraction, spike_kernel(optics)))
    if not parts:
        return None
    k = _mix(parts)
    k.setflags(write=False)
    return k


def _shift_radius(shifts_px: NDArray[np.float64]) -> int:
    """The radius of the channels' shift kernels (0: no chromatic aberration)."""
    m = float(np.abs(shifts_px).max())
    return math.ceil(m) + 1 if m > 0 else 0


def channel_kernels(optics: OpticsSpec, camera: CameraModel, depth_m: float, centre_px: NDArray[np.float64]
                    ) -> tuple[Kernel, Kernel, Kernel]:
    """The red, green and blue kernels ``K_c`` of a light at ``depth_m`` seen at ``centre_px``.

    Returns
    -------
    tuple of three (k, k) arrays of float
        Each sums to 1; all but the CA shift point-symmetric about ``[k // 2, k // 2]``.
    """
    parts = kernel_parts(optics, camera, depth_m, centre_px)
    return _compose(parts)


def _compose(parts: KernelParts) -> tuple[Kernel, Kernel, Kernel]:
    rs = _shift_radius(parts.shifts_px)
    out = []
    for c in range(OPTICS_CHANNELS):
        k = _mix([(parts.core_weight, parts.cores[c])] + ([(1.0, parts.wide)] if parts.wide is not None else []))
        if rs:
            k = _conv(k, shift_kernel(parts.shifts_px[c], rs))
        out.append(k)
    radius = max(k.shape[0] // 2 for k in out)
    r, gr, b = (_pad(k, radius) for k in out)
    return r, gr, b


def _kernel_cov(k: Kernel) -> NDArray[np.float64]:
    """Second-moment matrix of a kernel about its centroid, (2, 2) px^2 in (u, v)."""
    n = k.shape[0]
    v, u = np.mgrid[0:n, 0:n].astype(float)
    w = k / k.sum()
    cu, cv = float((w * u).sum()), float((w * v).sum())
    du, dv = u - cu, v - cv
    return np.array([[(w * du * du).sum(), (w * du * dv).sum()], [(w * du * dv).sum(), (w * dv * dv).sum()]])


@dataclass(frozen=True)
class SpotOptics:
    """The optics applied to one splat: its channel kernels (composed) and vignetting gain."""

    kernels: tuple[Kernel, Kernel, Kernel]
    gain: float


def _lens_patch(patch: NDArray[np.float32], parts: KernelParts) -> NDArray[np.float32]:
    """A window through :class:`KernelParts`: ``(h, w)`` in, ``(h + 2R, w + 2R, 3)`` out.

    By linearity, ``patch * K_c = shift_c * (core_weight (patch * core_c) + patch * wide)``:
    the wide kernel (the costly one) is applied once, not once per channel.
    """
    wide = _full_conv(patch, parts.wide) if parts.wide is not None else None
    r_core = max(k.shape[0] // 2 for k in parts.cores)
    r_mix = max(r_core, 0 if parts.wide is None else parts.wide.shape[0] // 2)
    rs = _shift_radius(parts.shifts_px)
    channels = []
    for c in range(OPTICS_CHANNELS):
        core = _full_conv(patch, parts.cores[c]) * np.float32(parts.core_weight)
        p = r_mix - parts.cores[c].shape[0] // 2
        ch = np.pad(core, p) if p else core
        if wide is not None:
            q = r_mix - parts.wide.shape[0] // 2 if parts.wide is not None else 0
            ch = ch + (np.pad(wide, q) if q else wide)
        if rs:
            ch = _full_conv(ch, shift_kernel(parts.shifts_px[c], rs))
        channels.append(ch)
    out = np.stack(channels, axis=-1)
    return np.maximum(out, 0, out=out)  # light: no negative round-off of the DFT


def apply_optics(splats: list[Splat], depth_m: NDArray[np.float64], optics: OpticsSpec, camera: CameraModel
                 ) -> tuple[list[Splat], list[SpotOptics]]:
    """Each splat through the lens: per-channel patches ``(h, w, 3)``, dimmed by the vignetting.

    Parameters
    ----------
    splats : list of Splat
        The lights' splats (2-D patches).
    depth_m : (len(splats),) array of float
        Each light's distance along the optical axis, metres (defocus).
    optics : OpticsSpec
    camera : CameraModel

    Returns
    -------
    list of Splat
        ``patch`` (h, w, 3) float32, channel ``c`` to be multiplied by ``rgb[c]``; the
        window grows by the kernel's radius on every side; ``core_flux`` times the
        vignetting; ``cov_px2`` and ``sigma_px`` include the green kernel's second moment.
    list of SpotOptics
        What was applied, per splat (for a light that is not a beacon, ``beacon_id < 0``,
        the kernels are not composed: (1, 1) placeholders, and its ``sigma_px`` is the core's).
    """
    out: list[Splat] = []
    used: list[SpotOptics] = []
    for sp, d in zip(splats, np.asarray(depth_m, float)):
        parts = kernel_parts(optics, camera, float(d), sp.centre_px)
        gain = float(vignetting_gain(sp.centre_px, camera, optics.vignetting_exponent)[0])
        patch = _lens_patch(sp.patch, parts) * np.float32(gain)
        r = (patch.shape[0] - sp.patch.shape[0]) // 2
        # the composed kernels (the bound and sigma need them) for beacons; other lights record neither
        one: Kernel = np.ones((1, 1))
        kernels = _compose(parts) if sp.beacon_id >= 0 else (one, one, one)
        cov = sp.cov_px2 + _kernel_cov(kernels[1])
        out.append(replace(sp, row0=sp.row0 - r, col0=sp.col0 - r, patch=patch.astype(np.float32),
                           sigma_px=float(np.linalg.det(cov)) ** 0.25, core_flux=sp.core_flux * gain,
                           cov_px2=cov))
        used.append(SpotOptics(kernels, gain))
    return out, used


def _gauss(centre: NDArray[np.float64], cov: NDArray[np.float64], row0: int, col0: int, n: int
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A unit-flux Gaussian sampled at pixel centres and its derivatives in ``u``, ``v`` and a dilation."""
    inv = np.linalg.inv(cov)
    du = (np.arange(col0, col0 + n) - centre[0])[None, :]
    dv = (np.arange(row0, row0 + n) - centre[1])[:, None]
    q = inv[0, 0] * du * du + 2 * inv[0, 1] * du * dv + inv[1, 1] * dv * dv
    G = np.exp(-0.5 * q) / (2 * math.pi * math.sqrt(float(np.linalg.det(cov))))
    return G, G * (inv[0, 0] * du + inv[0, 1] * dv), G * (inv[1, 0] * du + inv[1, 1] * dv), G * (q - 2.0)


def spot_crb_px(base: Splat, used: SpotOptics, background_e: float, sensor: SensorSpec) -> float:
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
    used : SpotOptics
        The kernels and vignetting gain :func:`apply_optics` applied.
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
    terms *= base.core_flux * e_per_rad * used.gain
    kernel = np.asarray(sum(w * k for w, k in zip(weights, used.kernels)), float)  # the channel sum (linear)
    # the four images as the channels of one (OpenCV filters each channel with the same kernel)
    # float32 (7 digits: the bound to ~1e-6), which OpenCV's DFT runs several times faster than float64
    four = _full_conv(np.ascontiguousarray(np.moveaxis(terms, 0, -1), np.float32), kernel)
    spot, d_u, d_v, d_s = np.moveaxis(four.astype(np.float64), -1, 0)
    mu = spot + max(background_e, 0.0)
    grads = np.stack([d_u, d_v, d_s, spot, np.ones_like(spot)])
    gain_dn = (2 ** sensor.bit_depth - 1) / sensor.full_well_e
    crb = centre_crb_px2(mu, grads, sensor.read_noise_e ** 2 + 1.0 / (12.0 * gain_dn ** 2))
    return float(math.sqrt(max(float(np.trace(crb)) / 2.0, 0.0)))


def bloom_column(charge_e: NDArray[np.float64], full_well_e: float) -> NDArray[np.float64]:
    """Charge above the full well spilled along each column; (h, w) in, (h, w) out.

    Repeatedly the fullest pixel of a column keeps ``full_well_e`` and sends half its
    excess up and half down; on the way each pixel fills to the well and passes the rest
    on (a pixel already over the well passes its own excess too). Charge that reaches the
    window's end is lost (it would drain off the sensor); inside, the total is kept.
    """
    out = np.array(charge_e, dtype=np.float64)
    h = out.shape[0]
    cap = full_well_e
    for j in np.flatnonzero((out > cap).any(axis=0)):
        col = out[:, j]
        while True:
            i = int(np.argmax(col))
            if col[i] <= cap:
                break
            excess = col[i] - cap
            col[i] = cap
            for step in (-1, 1):
                e, k = 0.5 * excess, i + step
                while e > 0 and 0 <= k < h:
                    total = col[k] + e
                    col[k], e = (total, 0.0) if total <= cap else (cap, total - cap)
                    k += step
    return out


_LUMA = np.array([0.299, 0.587, 0.114])
#: The most rows blooming adds above and below a spot's window; charge spilled farther is dropped.
BLOOM_MAX_PAD_PX = 256


def bloom_splats(splats: list[Splat], raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32],
                 sensor: SensorSpec, vignetting: tuple[CameraModel, float] | None = None) -> list[Splat]:
    """The splats with the charge their light and the background put above the full well spilled.

    Per channel (mono: the grey pixel) the expected electrons of light plus background in
    the splat's window are bloomed along columns (:func:`bloom_column`, the window padded
    so the charge stays in it, by at most :data:`BLOOM_MAX_PAD_PX` rows) and the background
    taken off again; a splat that fills no pixel is returned as it is. The window grows
    in rows only (it is no longer square).

    Parameters
    ----------
    splats : list of Splat
        Optical splats (``(h, w, 3)`` patches, :func:`apply_optics`).
    raster : (H, W, 3) array of uint8
        The distorted raster (the background), as :func:`deckpose.render.sensor.expose` takes it.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    sensor : SensorSpec
    vignetting : (CameraModel, float), optional
        The camera and ``vignetting_exponent`` of the raster's vignetting (:func:`vignetting_gain`).
    """
    e_per_rad = sensor.exposure * sensor.full_well_e
    cap = sensor.full_well_e
    scale = np.asarray(scale_rgb, np.float64) * e_per_rad
    mono = sensor.color == "mono"
    out: list[Splat] = []
    for sp in splats:
        rgb = sp.rgb.astype(np.float64)
        light = sp.patch.astype(np.float64) * rgb * e_per_rad  # (n, n, 3) electrons
        if mono:
            light = light.mean(axis=2, keepdims=True)
        bg = _window_background(sp.row0, sp.col0, sp.patch.shape[0], raster, scale, mono, vignetting)
        over = np.maximum(light + bg - cap, 0.0).sum(axis=0)
        if not over.any():
            out.append(sp)
            continue
        n = sp.patch.shape[0]
        pad = min(math.ceil(float(over.max()) / max(cap - float(bg.max()), 0.1 * cap)) + 2, BLOOM_MAX_PAD_PX)
        light = np.pad(light, ((pad, pad), (0, 0), (0, 0)))
        bg = np.concatenate([_window_background(sp.row0 - pad, sp.col0, pad, raster, scale, mono, vignetting, n),
                             bg, _window_background(sp.row0 + n, sp.col0, pad, raster, scale, mono, vignetting, n)])
        bloomed = np.stack([bloom_column(light[..., c] + bg[..., c], cap) - bg[..., c]
                            for c in range(light.shape[2])], axis=-1)
        if mono:
            patch = np.repeat(bloomed / (e_per_rad * rgb.mean()), 3, axis=2)
        else:
            patch = np.divide(bloomed, rgb * e_per_rad, out=np.zeros_like(bloomed), where=rgb > 0)
        out.append(replace(sp, row0=sp.row0 - pad, patch=patch.astype(np.float32)))
    return out


def _window_background(row0: int, col0: int, n: int, raster: NDArray[np.uint8], scale_e: NDArray[np.float64],
                       mono: bool, vignetting: tuple[CameraModel, float] | None,
                       width: int | None = None) -> NDArray[np.float64]:
    """Expected background electrons of an ``n`` x ``width`` (default ``n``) window, (n, width, C); 0 off the image."""
    H, W = raster.shape[:2]
    C = 1 if mono else 3
    w = n if width is None else width
    out = np.zeros((n, w, C))
    r0, r1, c0, c1 = max(row0, 0), min(row0 + n, H), max(col0, 0), min(col0 + w, W)
    if r0 >= r1 or c0 >= c1:
        return out
    block = raster[r0:r1, c0:c1]
    if mono:  # expose(): the grey raster (OpenCV's rounding) times the luma-weighted scale
        vals = cv2.cvtColor(np.ascontiguousarray(block), cv2.COLOR_RGB2GRAY)[..., None] * float(scale_e @ _LUMA)
    else:
        vals = block * scale_e
    if vignetting is not None:  # vignetting_gain() on the window's grid, by broadcasting
        cam, n_exp = vignetting
        tx2 = ((np.arange(c0, c1) - cam.cx) / cam.fx) ** 2
        ty2 = ((np.arange(r0, r1) - cam.cy) / cam.fy) ** 2
        vals = vals * ((1.0 + ty2[:, None] + tx2[None, :]) ** (-0.5 * n_exp))[..., None]
    out[r0 - row0:r1 - row0, c0 - col0:c1 - col0] = vals
    return out


@dataclass(frozen=True)
class OpticsRecord:
    """Per-beacon optics of a frame (``beacons.parquet``); all (N,), NaN where unknown.

    Attributes
    ----------
    defocus_px : blur-circle diameter at the beacon's depth, pixels.
    field_sigma_px : field-dependent blur sigma at the beacon's centre, pixels.
    vignetting : ``cos(theta)^n`` at the beacon's centre (1 without vignetting).
    centres_px : (N, 3, 2) each channel's true centre (r, g, b), pixels; green = ``u_px, v_px``.
    crb_px : per-axis centroid Cramér–Rao bound of the spot drawn (:func:`spot_crb_px`).
    """

    defocus_px: NDArray[np.float64]
    field_sigma_px: NDArray[np.float64]
    vignetting: NDArray[np.float64]
    centres_px: NDArray[np.float64]
    crb_px: NDArray[np.float64]


def optics_record(optics: OpticsSpec, camera: CameraModel, points_px: NDArray[np.float64],
                  depth_m: NDArray[np.float64], crb_px: NDArray[np.float64]) -> OpticsRecord:
    """The frame's :class:`OpticsRecord` from the beacons' true centres (N, 2) and depths (N,)."""
    return OpticsRecord(defocus_diameter_px(depth_m, camera, optics), field_sigma_px(points_px, camera, optics),
                        vignetting_gain(points_px, camera, optics.vignetting_exponent),
                        ca_centres_px(points_px, camera, optics), np.asarray(crb_px, float))


def optics_block(optics: OpticsSpec, cameras: dict[str, CameraModel]) -> dict[str, object]:
    """The manifest's ``optics`` block: every kernel that does not depend on the light, resolved.

    Per camera the focal length, aperture and hyperfocal distance (circle of confusion one
    pixel); the Airy kernels per channel (arrays, when diffraction is on), the glare and
    spike kernels' sizes and truncations. The per-light kernels (defocus diameter, field
    blur, vignetting, channel centres) are in ``beacons.parquet``.
    """
    p_m = optics.pixel_pitch_um * 1e-6
    cams = {}
    for name, cam in cameras.items():
        f = focal_length_m(cam, optics)
        cams[name] = {"focal_length_mm": f * 1e3, "aperture_mm": f / optics.f_number * 1e3,
                      "hyperfocal_m": f * f / (optics.f_number * p_m) + f}
    block: dict[str, object] = {
        "enabled": optics.enabled(), "kernel_oversample": KERNEL_OVERSAMPLE, "cameras": cams,
        "airy_truncation_first_zeros": AIRY_TRUNCATION, "glare_truncation_radii": GLARE_TRUNCATION,
        "spike_truncation_lengths": SPIKE_TRUNCATION, "spike_width_px": SPIKE_WIDTH_PX,
    }
    if optics.diffraction:
        block["airy_first_zero_px"] = [airy_first_zero_px(w, optics) for w in optics.wavelength_nm]
        block["airy_kernels"] = [np.round(airy_kernel(w, optics), 9).tolist() for w in optics.wavelength_nm]
    if optics.glare_fraction > 0:
        block["glare_kernel_size_px"] = glare_kernel(optics).shape[0]
    if optics.spike_fraction > 0:
        block["spike_kernel_size_px"] = spike_kernel(optics).shape[0]
    return block


@dataclass(frozen=True)
class LensedFrame:
    """A frame's splats through the lens, what they record, and the raster's vignetting.

    Attributes
    ----------
    beacons, lights : list of Splat
        The splats to expose (bloomed where ``bloom`` is on).
    spots : SpotRecord
        The beacons' spot model after the optics (flux vignetted, sigma with the kernel,
        background vignetted, peak before blooming: at or above the full well it saturates).
    record : OpticsRecord
    background_gain : callable or None
        The raster's vignetting rows for :func:`deckpose.render.sensor.expose`.
    """

    beacons: list[Splat]
    lights: list[Splat]
    spots: SpotRecord
    record: OpticsRecord
    background_gain: Callable[[int, int], NDArray[np.float32]] | None


def through_lens(optics: OpticsSpec, camera: CameraModel, sensor: SensorSpec, raster: NDArray[np.uint8],
                 scale_rgb: NDArray[np.float32], beacons: list[Splat], lights: list[Splat],
                 points_px: NDArray[np.float64], depth_m: NDArray[np.float64],
                 light_depth_m: NDArray[np.float64]) -> LensedFrame:
    """Every optics effect on a frame's splats (:func:`apply_optics`, :func:`spot_crb_px`, :func:`bloom_splats`).

    Parameters
    ----------
    optics, camera, sensor
    raster : (H, W, 3) array of uint8
        The distorted raster.
    scale_rgb : (3,) array of float32
        Raster value to radiance, per channel.
    beacons : list of Splat
        The beacons' splats (after the occluders).
    lights : list of Splat
        Other lights' splats (``beacon_id = -1 - light id``).
    points_px : (N, 2) array of float
        The beacons' true centres (the projection), pixels.
    depth_m : (N,) array of float
        The beacons' camera-frame depth, metres.
    light_depth_m : (len(lights),) array of float
        Each light splat's depth, metres.
    """
    n = points_px.shape[0]
    lensed, used = apply_optics(beacons, depth_m[[sp.beacon_id for sp in beacons]], optics, camera)
    lensed_lights, _ = apply_optics(lights, light_depth_m, optics, camera)
    gain_rows = vignetting_rows(camera, optics.vignetting_exponent) if optics.vignetting_exponent > 0 else None
    spots = spot_record(raster, scale_rgb, lensed, sensor, n)
    vig = vignetting_gain(points_px, camera, optics.vignetting_exponent)
    spots = replace(spots, background_e=spots.background_e * np.where(np.isfinite(vig), vig, 1.0))
    crb = np.full(n, np.nan)
    for sp, u in zip(beacons, used):
        crb[sp.beacon_id] = spot_crb_px(sp, u, float(spots.background_e[sp.beacon_id]), sensor)
    if optics.bloom:
        vig = (camera, optics.vignetting_exponent) if optics.vignetting_exponent > 0 else None
        lensed = bloom_splats(lensed, raster, scale_rgb, sensor, vig)
        lensed_lights = bloom_splats(lensed_lights, raster, scale_rgb, sensor, vig)
    return LensedFrame(lensed, lensed_lights, spots, optics_record(optics, camera, points_px, depth_m, crb),
                       gain_rows)


def optics_row(record: OpticsRecord | None, i: int) -> dict[str, float]:
    """Beacon ``i``'s optics columns of ``beacons.parquet`` (all NaN without optics)."""
    if record is None:
        return dict.fromkeys(OPTICS_COLUMNS, float("nan"))
    c = record.centres_px[i]
    return {"spot_crb_px": float(record.crb_px[i]), "defocus_px": float(record.defocus_px[i]),
            "field_blur_sigma_px": float(record.field_sigma_px[i]), "vignetting": float(record.vignetting[i]),
            "u_r_px": float(c[0, 0]), "v_r_px": float(c[0, 1]), "u_b_px": float(c[2, 0]), "v_b_px": float(c[2, 1])}


#: The optics columns of ``beacons.parquet`` (:data:`deckpose.table_schemas.BEACON_COLUMNS`).
OPTICS_COLUMNS = ("spot_crb_px", "defocus_px", "field_blur_sigma_px", "vignetting",
                  "u_r_px", "v_r_px", "u_b_px", "v_b_px")
