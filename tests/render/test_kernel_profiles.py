"""The shapes of the lens's kernels (:mod:`deckpose.render.psf_kernels`) against their written laws.

Each law is computed here again from what the README's optics table and the docstrings write:

* glare, ``(1 + (r / a)^2)^-1.5`` out to ``8 a``: its integral over a pixel in closed form (the
  solid angle of a rectangle seen from height ``a``), with no sampling at all;
* spikes, ``exp(-|t| / L)`` along each line times a Gaussian of 0.5 px across, ``n`` spikes for
  ``n`` even blades and ``2n`` for odd, out to ``4 L``: on a sub-pixel grid five times finer than
  the renderer's, and along and across an arm in closed form;
* field blur, ``sigma = field_blur_px (rho / rho_corner)^2``: at points of known radius, in the
  kernel a beacon is actually drawn with, and in a rendered ``beacons.parquet``.

The tolerances are the renderer's own integration error: it averages each pixel over
``k x k = 7 x 7`` midpoints, and the midpoint rule on a cell of side ``h = 1 / k`` errs by about
``h^2 / 24`` times the cell's mean second derivative. Last, the manifest must hold every number
needed to build each kernel again: the test rebuilds them from the manifest alone.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from deckpose.render.config import OpticsSpec, RenderConfig, config_from_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.optics import field_sigma_px, kernel_parts
from deckpose.render.psf_kernels import KERNEL_OVERSAMPLE, glare_kernel, spike_kernel
from numpy.typing import NDArray
from scipy.ndimage import map_coordinates
from scipy.special import erf

from deckpose.camera import CameraModel
from deckpose.camera_info import camera_from_dict

from .conftest import tiny_doc

Array = NDArray[np.float64]

#: The renderer's sub-cell side, pixels: its midpoint rule errs by ~H2_24 x the second derivative.
H2_24 = (1.0 / KERNEL_OVERSAMPLE) ** 2 / 24.0
#: The spikes' Gaussian sigma across their line, pixels (README: "0.5 px across").
SPIKE_SIGMA_PX = 0.5


def _pixel_edges(radius_px: int) -> Array:
    return np.arange(-radius_px, radius_px + 2, dtype=np.float64) - 0.5


def _glare_pixels(a: float, radius_px: int) -> Array:
    """``(1 + (r/a)^2)^-1.5`` integrated exactly over each pixel of a (2R+1)^2 grid, summing to 1.

    ``a^3 / (a^2 + x^2 + y^2)^1.5`` has the antiderivative ``a^2 atan(x y / (a sqrt(a^2 + x^2 + y^2)))``
    in ``x`` and ``y`` (the solid angle of the rectangle [0, x] x [0, y] seen from height ``a``).
    """
    e = _pixel_edges(radius_px)
    x, y = np.meshgrid(e, e)
    F = a * a * np.arctan(x * y / (a * np.sqrt(a * a + x * x + y * y)))
    pix = F[1:, 1:] - F[1:, :-1] - F[:-1, 1:] + F[:-1, :-1]
    return pix / pix.sum()


@pytest.mark.parametrize("a", [3.0, 1.7])  # the default, and one whose 8 a is not a whole pixel
def test_glare_kernel_is_the_pixel_integrated_power_law(a: float) -> None:
    k = glare_kernel(OpticsSpec(glare_radius_px=a, glare_fraction=0.05))
    r = math.ceil(8.0 * a)  # "out to 8 a"
    assert k.shape == (2 * r + 1, 2 * r + 1)
    want = _glare_pixels(a, r)
    # per pixel the midpoint rule errs by H2_24 x the mean Laplacian, and |Laplacian / profile| =
    # |9 u^2 - 6| / (a^2 (1 + u^2)^2) <= 6 / a^2 (u = r / a); the normalisation by the sum errs by at
    # most as much again: 2 x 6 H2_24 / a^2 (1.1e-3 at a = 3), relative, on every pixel
    np.testing.assert_allclose(k, want, rtol=12.0 * H2_24 / (a * a), atol=0)


def _spike_lines(blades: int) -> int:
    """Lines through the centre, each two opposite spikes: n spikes (even n) or 2n (odd n)."""
    return blades // 2 if blades % 2 == 0 else blades


def _spike_pixels(blades: int, length_px: float, radius_px: int, sub: int) -> Array:
    """The spikes' profile averaged over each pixel on ``sub x sub`` midpoints, summing to 1.

    Line ``j`` runs at ``pi j / lines`` from the +u axis towards +v (rows are v, columns u).
    """
    n = 2 * radius_px + 1
    s = (np.arange(sub) + 0.5) / sub - 0.5
    x = (np.arange(-radius_px, radius_px + 1)[:, None] + s[None, :]).ravel()
    out = np.empty((n, n))
    lines = _spike_lines(blades)
    for row in range(n):  # a row of pixels at a time: a few MB
        y = (row - radius_px + s)[:, None]
        prof = np.zeros((sub, x.size))
        for j in range(lines):
            th = math.pi * j / lines
            t = x[None, :] * math.cos(th) + y * math.sin(th)
            p = -x[None, :] * math.sin(th) + y * math.cos(th)
            prof += np.exp(-np.abs(t) / length_px) * np.exp(-0.5 * (p / SPIKE_SIGMA_PX) ** 2)
        out[row] = prof.reshape(sub, n, sub).mean(axis=(0, 2))
    return out / out.sum()


def _spike_tolerance(length_px: float) -> float:
    """The renderer's midpoint error on the spikes, relative to their crest (the centre pixel).

    Across the line the Gaussian's second derivative is at most ``1 / w^2`` of its crest:
    ``H2_24 / w^2`` (0.34 %); along it, the kink of ``exp(-|t| / L)`` at the centre loses
    ``h^2 / (4 L)`` in the cell it crosses (0.06 % at L = 8). The normalisation errs by as much
    again: twice the sum.
    """
    h2 = 24.0 * H2_24
    return 2.0 * (H2_24 / SPIKE_SIGMA_PX ** 2 + h2 / (4.0 * length_px))


@pytest.mark.parametrize(("blades", "length_px"), [(6, 8.0), (5, 8.0), (4, 3.5)])
def test_spike_kernel_is_the_pixel_integrated_spikes(blades: int, length_px: float) -> None:
    k = spike_kernel(OpticsSpec(spike_fraction=0.05, spike_blades=blades, spike_length_px=length_px))
    r = math.ceil(4.0 * length_px)  # four 1/e lengths
    assert k.shape == (2 * r + 1, 2 * r + 1)
    # 35 x 35 midpoints a pixel: 25 times the renderer's accuracy, so the reference's own error is
    # 4 % of the tolerance
    want = _spike_pixels(blades, length_px, r, 35)
    np.testing.assert_allclose(k, want, rtol=0, atol=_spike_tolerance(length_px) * want.max())


def _gauss_pixel(lo: float, hi: float) -> float:
    """The spikes' Gaussian across their line, integrated over [lo, hi] (erf), crest 1."""
    c = SPIKE_SIGMA_PX * math.sqrt(2.0)
    return SPIKE_SIGMA_PX * math.sqrt(math.pi / 2.0) * (erf(hi / c) - erf(lo / c))


@pytest.mark.parametrize("length_px", [8.0, 3.5])
def test_spike_arms_fall_off_as_exp_along_and_gaussian_across(length_px: float) -> None:
    # four blades: two lines, along u and along v, each separable on the pixel grid
    k = spike_kernel(OpticsSpec(spike_fraction=0.05, spike_blades=4, spike_length_px=length_px))
    r = k.shape[0] // 2
    # along each of the four arms, pixel to pixel: an exp(-|t| / L) integrated over [x - 1/2, x + 1/2]
    # is exp(-1 / L) times the one before it, exactly, and so are its midpoint samples. From 4 px out
    # the crossing line's Gaussian (exp(-0.5 (3.5 / 0.5)^2) = 2e-11) adds nothing
    arms = {"+u": k[r, r:], "-u": k[r, r::-1], "+v": k[r:, r], "-v": k[r::-1, r]}
    for name, arm in arms.items():
        np.testing.assert_allclose(arm[5:] / arm[4:-1], math.exp(-1.0 / length_px), rtol=1e-9, err_msg=name)
    # across an arm at u = 6: the column is the Gaussian integrated over each pixel, over its crest's
    g0 = _gauss_pixel(-0.5, 0.5)
    want = np.array([_gauss_pixel(d - 0.5, d + 0.5) for d in range(-3, 4)]) / g0
    got = k[r - 3:r + 4, r + 6] / k[r, r + 6]
    # each pixel's midpoint error is at most H2_24 / w^2 of the crest; in the ratio twice that over g0
    np.testing.assert_allclose(got, want, rtol=0, atol=2.0 * H2_24 / SPIKE_SIGMA_PX ** 2 / g0)


@pytest.mark.parametrize(("blades", "spikes"), [(4, 4), (5, 10), (6, 6), (7, 14)])
def test_spike_count_follows_the_blades(blades: int, spikes: int) -> None:
    length_px = 8.0
    k = spike_kernel(OpticsSpec(spike_fraction=0.05, spike_blades=blades, spike_length_px=length_px))
    r = k.shape[0] // 2
    # the kernel's mean along rays from 4 px to 4 L - 1 out, every 0.25 degrees
    th = np.radians(np.arange(0.0, 360.0, 0.25))
    rho = np.linspace(4.0, r - 1.0, 200)
    u = r + rho[None, :] * np.cos(th)[:, None]
    v = r + rho[None, :] * np.sin(th)[:, None]
    ray = map_coordinates(k, [v.ravel(), u.ravel()], order=1).reshape(u.shape).mean(axis=1)
    peak = (ray > np.roll(ray, 1)) & (ray >= np.roll(ray, -1)) & (ray > 0.2 * ray.max())
    got = np.degrees(th[peak])
    assert got.size == spikes, got
    # evenly spaced, the first along +u (the renderer's convention; the README does not say): to the
    # bilinear interpolation's wobble, well under the 25.7 degrees between 14 spikes
    want = 360.0 * np.arange(spikes) / spikes
    np.testing.assert_allclose(got, want, atol=1.0)


CAMERA = CameraModel(320, 240, np.array([[300.0, 0, 101.7], [0, 280.0, 151.3], [0, 0, 1]]))  # off-centre


def test_field_blur_sigma_is_the_square_law_up_to_the_far_corner() -> None:
    fb = 2.5
    optics = OpticsSpec(field_blur_px=fb)
    c = np.array([CAMERA.cx, CAMERA.cy])
    # the image's corners, taken (as the renderer does) at (0, 0) and (W, H); with pixel centres at
    # integers (deckpose.camera) the frame's outer corners are (-0.5, -0.5) and (W - 0.5, H - 0.5): the
    # law does not say which, and rho_corner differs by < 0.71 px between the two (< 0.3 % here)
    corners = np.array([[0.0, 0.0], [320.0, 0.0], [0.0, 240.0], [320.0, 240.0]])
    far = corners[1]  # the principal point is left of and below the middle: (W, 0) is the farthest
    rho_c = float(np.hypot(*(far - c)))
    assert rho_c > float(np.hypot(*(corners[[0, 2, 3]] - c).T).max())
    # the centre, the far corner, the other corners, and points at 0.3, 0.5 and 0.8 rho_c
    direction = np.array([math.cos(2.0), math.sin(2.0)])
    frac = np.array([0.3, 0.5, 0.8])
    pts = np.vstack([c, far, corners[[0, 2, 3]], c + (frac * rho_c)[:, None] * direction])
    want = np.concatenate([[0.0, fb], fb * (np.hypot(*(corners[[0, 2, 3]] - c).T) / rho_c) ** 2, fb * frac ** 2])
    np.testing.assert_allclose(field_sigma_px(pts, CAMERA, optics), want, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("frac", [0.5, 0.8, 1.0])
def test_the_blur_a_beacon_is_drawn_with_has_the_law_sigma(frac: float) -> None:
    fb = 3.0
    optics = OpticsSpec(field_blur_px=fb)
    c = np.array([CAMERA.cx, CAMERA.cy])
    rho_c = math.hypot(320.0 - CAMERA.cx, CAMERA.cy)
    at = c + frac * rho_c * np.array([math.cos(-0.6), math.sin(-0.6)])
    k = kernel_parts(optics, CAMERA, 20.0, at).cores[1]  # no defocus, no diffraction: the field blur alone
    n = k.shape[0] // 2
    d = np.arange(-n, n + 1)
    var_u = float((k.sum(axis=0) * d ** 2).sum())
    var_v = float((k.sum(axis=1) * d ** 2).sum())
    # a Gaussian integrated over unit pixels has the variance sigma^2 + 1/12 (Sheppard; the next term
    # is ~exp(-2 pi^2 sigma^2) < 1e-4 for sigma >= 0.75 px); cutting it beyond 4 sigma takes at most
    # 2 (4 phi(4) + Q(4)) = 1.1e-3 of it (2e-4 here, the cut falling on a pixel's outer edge)
    want = (fb * frac * frac) ** 2 + 1.0 / 12.0
    assert var_u == pytest.approx(want, rel=2e-3)
    assert var_v == pytest.approx(want, rel=2e-3)
    assert float((k.sum(axis=0) * d).sum()) == pytest.approx(0.0, abs=1e-12)  # centred


LENS = {"glare_fraction": 0.03, "glare_radius_px": 2.5, "spike_fraction": 0.02, "spike_blades": 5,
        "spike_length_px": 6.0, "field_blur_px": 6.0}  # sigma 0.4-0.75 px on the ring


@pytest.fixture(scope="module")
def lens_dataset(tmp_path_factory: pytest.TempPathFactory) -> tuple[RenderConfig, Path]:
    """One 320 x 240 frame through a lens with glare, spikes and field blur (a few seconds)."""
    doc = tiny_doc(heights_m=[30.0], lighting=["night"],
                   motion={"source": "fixed", "attitudes_deg": [[4.0, -3.0, 20.0, 0.5, 0.3, -0.2]]}, optics=LENS)
    cfg = config_from_dict(doc)
    out = tmp_path_factory.mktemp("lens") / "ds"
    render_dataset(cfg, out, workers=1)
    return cfg, out


def _manifest(out: Path) -> tuple[dict[str, Any], CameraModel, pd.DataFrame]:
    manifest = json.loads((out / "manifest.json").read_text())
    (cam,) = manifest["cameras"]
    return manifest, camera_from_dict(cam["camera_info"]), pd.read_parquet(out / "beacons.parquet")


def test_rendered_beacons_record_the_field_blur_law_at_their_centres(lens_dataset: tuple[RenderConfig, Path]
                                                                     ) -> None:
    _, out = lens_dataset
    manifest, cam, beacons = _manifest(out)
    fb = manifest["config"]["optics"]["field_blur_px"]
    u, v = beacons["u_px"].to_numpy(), beacons["v_px"].to_numpy()
    half_w, half_h = cam.width_px / 2.0, cam.height_px / 2.0
    assert (cam.cx, cam.cy) == pytest.approx((half_w, half_h))  # a centred preset: every corner is rho_c out
    want = fb * (np.hypot(u - cam.cx, v - cam.cy) / math.hypot(half_w, half_h)) ** 2
    got = beacons["field_blur_sigma_px"].to_numpy()
    assert np.isfinite(want).all() and np.ptp(want) > 0.1  # the beacons sit at many radii
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-15)


def _midpoint_kernel(profile: Any, radius_px: int, oversample: int) -> Array:
    """``profile(x, y)`` averaged over each pixel on ``oversample^2`` midpoints, summing to 1."""
    s = (np.arange(oversample) + 0.5) / oversample - 0.5
    n = 2 * radius_px + 1
    x = (np.arange(-radius_px, radius_px + 1)[:, None] + s[None, :]).ravel()
    vals = profile(x[None, :], x[:, None]).reshape(n, oversample, n, oversample)
    k = vals.mean(axis=(1, 3))
    return k / k.sum()


def test_manifest_holds_what_rebuilds_every_kernel(lens_dataset: tuple[RenderConfig, Path]) -> None:
    cfg, out = lens_dataset
    manifest, cam, beacons = _manifest(out)
    lens, block = manifest["config"]["optics"], manifest["optics"]
    m = int(block["kernel_oversample"])
    # glare: a, its truncation in a, the sub-sampling
    a = float(lens["glare_radius_px"])
    rg = math.ceil(block["glare_truncation_radii"] * a)
    glare = _midpoint_kernel(lambda x, y: (1.0 + (x * x + y * y) / (a * a)) ** -1.5, rg, m)
    assert glare.shape[0] == block["glare_kernel_size_px"]
    np.testing.assert_allclose(glare, glare_kernel(cfg.optics), rtol=1e-12, atol=0)
    # spikes: L, the truncation in L, the width across and each line's angle
    L, w = float(lens["spike_length_px"]), float(block["spike_width_px"])
    angles = np.radians(block["spike_angles_deg"])

    def spikes(x: Array, y: Array) -> Array:
        return sum((np.exp(-np.abs(x * math.cos(t) + y * math.sin(t)) / L
                           - 0.5 * ((-x * math.sin(t) + y * math.cos(t)) / w) ** 2) for t in angles),
                   np.zeros(np.broadcast_shapes(x.shape, y.shape)))

    spike = _midpoint_kernel(spikes, math.ceil(block["spike_truncation_lengths"] * L), m)
    assert spike.shape[0] == block["spike_kernel_size_px"]
    np.testing.assert_allclose(spike, spike_kernel(cfg.optics), rtol=1e-12, atol=1e-15)
    # the field blur of each beacon: its recorded sigma, the Gaussian's truncation, integrated (erf)
    seen = beacons[beacons["visible"]]
    assert len(seen) > 3
    for _, b in seen.iterrows():
        s = float(b["field_blur_sigma_px"])
        n = math.ceil(block["gaussian_truncation_sigmas"] * s)
        e = np.diff(erf((np.arange(-n, n + 2) - 0.5) / (math.sqrt(2.0) * s)))
        want = np.outer(e, e) / np.outer(e, e).sum()
        drawn = kernel_parts(cfg.optics, cam, 30.0, np.array([b["u_px"], b["v_px"]])).cores[1]
        np.testing.assert_allclose(want, drawn, rtol=1e-12, atol=1e-15)
