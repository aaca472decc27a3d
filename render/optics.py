"""The lens beyond a Gaussian: defocus, diffraction, glare, spikes, blooming, vignetting, CA, field blur.

Every effect is off by default (:class:`deckpose.render.optics_config.OpticsSpec`) and acts on the
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

The kernels are built in :mod:`deckpose.render.psf_kernels`, blooming is
:mod:`deckpose.render.blooming`, and the centroid Cramér–Rao bound of a spot
(:func:`deckpose.render.spot_bound.spot_crb_px`) is computed from this PSF: the core and
halo Gaussians of the spot and their derivatives (centre, width) are convolved with the
same kernels, summed over channels, and passed with the background and read noise to
:func:`deckpose.spot_fisher.centre_crb_px2`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from deckpose.render.beacons import Splat
from deckpose.render.blooming import bloom_splats
from deckpose.render.optics_config import OpticsSpec
from deckpose.render.psf_kernels import (
    AIRY_TRUNCATION,
    GAUSSIAN_TRUNCATION,
    GLARE_TRUNCATION,
    KERNEL_OVERSAMPLE,
    SPIKE_TRUNCATION,
    SPIKE_WIDTH_PX,
    Kernel,
    airy_first_zero_px,
    airy_kernel,
    convolve_kernels,
    disk_kernel,
    gaussian_kernel,
    glare_kernel,
    kernel_covariance,
    mix_kernels,
    spike_angles_rad,
    spike_kernel,
)
from deckpose.render.sensor import SpotRecord, spot_record
from deckpose.render.sensor_config import SensorSpec
from deckpose.render.split_kernels import CHANNELS, KernelParts, compose_parts, through_parts
from deckpose.render.spot_bound import spot_crb_px
from numpy.typing import NDArray

from deckpose.camera import CameraModel

__all__ = [
    "OPTICS_CHANNELS", "OPTICS_COLUMNS", "LensedFrame", "OpticsRecord", "SpotOptics",
    "apply_optics", "ca_centres_px", "channel_flux_e", "channel_kernels", "defocus_diameter_px", "field_sigma_px",
    "focal_length_m", "kernel_parts", "lens_record", "optics_block", "optics_record", "optics_row", "through_lens",
    "vignetting_gain", "vignetting_rows",
]


#: Channels of a spot's optical patch: red, green, blue (:data:`deckpose.render.split_kernels.CHANNELS`).
OPTICS_CHANNELS = CHANNELS



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


def kernel_parts(optics: OpticsSpec, camera: CameraModel, depth_m: float, centre_px: NDArray[np.float64]
                 ) -> KernelParts:
    """The :class:`KernelParts` of a light at ``depth_m`` seen at ``centre_px`` (2,)."""
    centre = np.asarray(centre_px, float).reshape(1, 2)
    blur = convolve_kernels(disk_kernel(float(defocus_diameter_px(np.array([depth_m]), camera, optics)[0])),
                 gaussian_kernel(float(field_sigma_px(centre, camera, optics)[0])))
    g, s = optics.glare_fraction, optics.spike_fraction
    cores = tuple(convolve_kernels(airy_kernel(w, optics), blur) if optics.diffraction else blur
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
    k = mix_kernels(parts)
    k.setflags(write=False)
    return k


def channel_kernels(optics: OpticsSpec, camera: CameraModel, depth_m: float, centre_px: NDArray[np.float64]
                    ) -> tuple[Kernel, Kernel, Kernel]:
    """The red, green and blue kernels ``K_c`` of a light at ``depth_m`` seen at ``centre_px``.

    Returns
    -------
    tuple of three (k, k) arrays of float
        Each sums to 1; all but the CA shift point-symmetric about ``[k // 2, k // 2]``.
    """
    parts = kernel_parts(optics, camera, depth_m, centre_px)
    return compose_parts(parts)


@dataclass(frozen=True)
class SpotOptics:
    """The optics applied to one splat: its channel kernels (in parts) and vignetting gain."""

    parts: KernelParts
    gain: float


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
        its ``sigma_px`` is the core's: the kernels are not composed).
    """
    out: list[Splat] = []
    used: list[SpotOptics] = []
    for sp, d in zip(splats, np.asarray(depth_m, float)):
        parts = kernel_parts(optics, camera, float(d), sp.centre_px)
        gain = float(vignetting_gain(sp.centre_px, camera, optics.vignetting_exponent)[0])
        patch = np.stack(through_parts(sp.patch, parts), axis=-1)
        patch = np.maximum(patch, 0, out=patch) * np.float32(gain)  # light: no negative round-off of the DFT
        r = (patch.shape[0] - sp.patch.shape[0]) // 2
        # the green kernel's second moment widens a beacon's recorded sigma; other lights record the core's
        cov = sp.cov_px2 + kernel_covariance(compose_parts(parts)[1]) if sp.beacon_id >= 0 else sp.cov_px2
        out.append(replace(sp, row0=sp.row0 - r, col0=sp.col0 - r, patch=patch.astype(np.float32, copy=False),
                           sigma_px=float(np.linalg.det(cov)) ** 0.25, core_flux=sp.core_flux * gain,
                           cov_px2=cov))
        used.append(SpotOptics(parts, gain))
    return out, used


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
    channel_flux_e : (N, 3) electrons of the spot's core in the channel sum that come from the
        red, green and blue light (they sum to ``spot_flux_e``); with ``centres_px`` they give
        the centroid of the light a channel-sum detector sees
        (:func:`deckpose.detect.benchmark.channel_sum_centre_px`).
    """

    defocus_px: NDArray[np.float64]
    field_sigma_px: NDArray[np.float64]
    vignetting: NDArray[np.float64]
    centres_px: NDArray[np.float64]
    crb_px: NDArray[np.float64]
    channel_flux_e: NDArray[np.float64]


def optics_record(optics: OpticsSpec, camera: CameraModel, points_px: NDArray[np.float64],
                  depth_m: NDArray[np.float64], crb_px: NDArray[np.float64],
                  channel_flux_e: NDArray[np.float64]) -> OpticsRecord:
    """The frame's :class:`OpticsRecord` from the beacons' true centres (N, 2), depths (N,), bounds (N,)
    and per-channel core electrons (N, 3)."""
    return OpticsRecord(defocus_diameter_px(depth_m, camera, optics), field_sigma_px(points_px, camera, optics),
                        vignetting_gain(points_px, camera, optics.vignetting_exponent),
                        ca_centres_px(points_px, camera, optics), np.asarray(crb_px, float),
                        np.asarray(channel_flux_e, float).reshape(-1, OPTICS_CHANNELS))


def channel_flux_e(flux_e: NDArray[np.float64], rgb: NDArray[np.float64]) -> NDArray[np.float64]:
    """Split each spot's channel-sum electrons into the parts its red, green and blue light give.

    The channel sum of a spot is ``sum_c rgb_c P_c`` (RGB frames; a mono frame's grey is that
    over 3), every channel's profile ``P_c`` holding the same light, so channel ``c``'s share
    is ``rgb_c / sum(rgb)``.

    Parameters
    ----------
    flux_e : (N,) array of float
        Electrons of each spot's core, summed over channels (``spot_flux_e``).
    rgb : (N, 3) array of float
        Each spot's colour.

    Returns
    -------
    (N, 3) array of float
        Electrons per channel; rows sum to ``flux_e``.
    """
    c = np.asarray(rgb, float).reshape(-1, OPTICS_CHANNELS)
    return np.asarray(np.asarray(flux_e, float).reshape(-1, 1) * c / c.sum(axis=1, keepdims=True), float)


def optics_block(optics: OpticsSpec, cameras: dict[str, CameraModel]) -> dict[str, object]:
    """The manifest's ``optics`` block: every kernel that does not depend on the light, resolved.

    Per camera the focal length, aperture and hyperfocal distance (circle of confusion one
    pixel); the Airy kernels per channel (arrays, when diffraction is on), the glare and
    spike kernels' sizes and truncations, the spikes' width and line angles (degrees from
    +u towards +v), the field blur Gaussian's truncation. With the ``optics`` keys of the
    config they rebuild each kernel. The per-light kernels' parameters (defocus diameter,
    field blur, vignetting, channel centres) are in ``beacons.parquet``.
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
        "gaussian_truncation_sigmas": GAUSSIAN_TRUNCATION,
    }
    if optics.diffraction:
        block["airy_first_zero_px"] = [airy_first_zero_px(w, optics) for w in optics.wavelength_nm]
        block["airy_kernels"] = [np.round(airy_kernel(w, optics), 9).tolist() for w in optics.wavelength_nm]
    if optics.glare_fraction > 0:
        block["glare_kernel_size_px"] = glare_kernel(optics).shape[0]
    if optics.spike_fraction > 0:
        block["spike_kernel_size_px"] = spike_kernel(optics).shape[0]
        block["spike_angles_deg"] = [math.degrees(t) for t in spike_angles_rad(optics.spike_blades)]
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
    record = lens_record(optics, camera, sensor, beacons, [(u.parts, u.gain) for u in used], spots, points_px,
                         depth_m)
    if optics.bloom:
        vig = (camera, optics.vignetting_exponent) if optics.vignetting_exponent > 0 else None
        lensed = bloom_splats(lensed, raster, scale_rgb, sensor, vig)
        lensed_lights = bloom_splats(lensed_lights, raster, scale_rgb, sensor, vig)
    return LensedFrame(lensed, lensed_lights, spots, record, gain_rows)


def lens_record(optics: OpticsSpec, camera: CameraModel, sensor: SensorSpec, beacons: list[Splat],
                lens: list[tuple[KernelParts, float]], spots: SpotRecord,
                points_px: NDArray[np.float64], depth_m: NDArray[np.float64]) -> OpticsRecord:
    """The frame's :class:`OpticsRecord`, with each beacon's bound (:func:`spot_crb_px`) under its lens.

    Parameters
    ----------
    optics, camera, sensor
    beacons : list of Splat
        The beacons' splats before the optics.
    lens : list of (KernelParts, float)
        Each splat's channel kernels, in parts, and vignetting gain (no optics:
        :data:`deckpose.render.split_kernels.NO_PARTS` and 1).
    spots : SpotRecord
        The spots' record (its background under the beacon, vignetted).
    points_px, depth_m : (N, 2) and (N,) arrays of float
        The beacons' true centres, pixels, and depths, metres.
    """
    n = points_px.shape[0]
    crb = np.full(n, np.nan)
    rgb = np.full((n, OPTICS_CHANNELS), np.nan)
    for sp, (parts, gain) in zip(beacons, lens):
        rgb[sp.beacon_id] = sp.rgb
        crb[sp.beacon_id] = spot_crb_px(sp, parts, gain, float(spots.background_e[sp.beacon_id]), sensor)
    return optics_record(optics, camera, points_px, depth_m, crb, channel_flux_e(spots.flux_e, rgb))


def optics_row(record: OpticsRecord | None, i: int) -> dict[str, float]:
    """Beacon ``i``'s optics columns of ``beacons.parquet`` (all NaN without optics)."""
    if record is None:
        return dict.fromkeys(OPTICS_COLUMNS, float("nan"))
    c = record.centres_px[i]
    f = record.channel_flux_e[i]
    return {"spot_crb_px": float(record.crb_px[i]), "defocus_px": float(record.defocus_px[i]),
            "field_blur_sigma_px": float(record.field_sigma_px[i]), "vignetting": float(record.vignetting[i]),
            "u_r_px": float(c[0, 0]), "v_r_px": float(c[0, 1]), "u_b_px": float(c[2, 0]), "v_b_px": float(c[2, 1]),
            "spot_flux_r_e": float(f[0]), "spot_flux_g_e": float(f[1]), "spot_flux_b_e": float(f[2])}


#: The optics columns of ``beacons.parquet`` (:data:`deckpose.table_schemas.BEACON_COLUMNS`).
OPTICS_COLUMNS = ("spot_crb_px", "defocus_px", "field_blur_sigma_px", "vignetting",
                  "u_r_px", "v_r_px", "u_b_px", "v_b_px", "spot_flux_r_e", "spot_flux_g_e", "spot_flux_b_e")
