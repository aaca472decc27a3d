"""Issue 23's last items: blooming vectorised (same charge as the walk), bloom and optics together.

The pixel-by-pixel blooming walk that :func:`deckpose.render.blooming.bloom_column` replaced
is kept here as the reference (:func:`_walk`), written as it was. Bloom (``scene.bloom_fraction``,
glare before the lens) and the optics together are checked against what each keeps alone:
the light of every channel, its centroid on the channel's true centre, the recorded truth and
the manifest's record of both.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from deckpose.render.beacons import Splat, beacon_splats
from deckpose.render.bloom import bloom
from deckpose.render.blooming import BLOOM_MAX_PAD_PX, bloom_column, bloom_splats
from deckpose.render.config import OpticsSpec, SensorSpec, config_from_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.optics import LensedFrame, apply_optics, ca_centres_px, through_lens
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

from .conftest import tiny_doc


def _walk(charge_e: np.ndarray, full_well_e: float) -> np.ndarray:
    """The reference: the pixel-by-pixel walk (the implementation before vectorising)."""
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


_LUMA = np.array([0.299, 0.587, 0.114])  # expose()'s grey, as the reference had it


def reference_bloom_splats(splats: list[Splat], raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32],
                 sensor: SensorSpec, vignetting: tuple[CameraModel, float] | None = None) -> list[Splat]:
    """The reference, as it was before (with :func:`_walk`)."""
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
        bg = _window_background_reference(sp.row0, sp.col0, sp.patch.shape[0], raster, scale, mono, vignetting)
        over = np.maximum(light + bg - cap, 0.0).sum(axis=0)
        if not over.any():
            out.append(sp)
            continue
        n = sp.patch.shape[0]
        pad = min(math.ceil(float(over.max()) / max(cap - float(bg.max()), 0.1 * cap)) + 2, BLOOM_MAX_PAD_PX)
        light = np.pad(light, ((pad, pad), (0, 0), (0, 0)))
        bg = np.concatenate([_window_background_reference(sp.row0 - pad, sp.col0, pad, raster, scale, mono, vignetting, n),
                             bg, _window_background_reference(sp.row0 + n, sp.col0, pad, raster, scale, mono, vignetting, n)])
        bloomed = np.stack([_walk(light[..., c] + bg[..., c], cap) - bg[..., c]
                            for c in range(light.shape[2])], axis=-1)
        if mono:
            patch = np.repeat(bloomed / (e_per_rad * rgb.mean()), 3, axis=2)
        else:
            patch = np.divide(bloomed, rgb * e_per_rad, out=np.zeros_like(bloomed), where=rgb > 0)
        out.append(replace(sp, row0=sp.row0 - pad, patch=patch.astype(np.float32)))
    return out


def _window_background_reference(row0: int, col0: int, n: int, raster: NDArray[np.uint8], scale_e: NDArray[np.float64],
                       mono: bool, vignetting: tuple[CameraModel, float] | None,
                       width: int | None = None) -> NDArray[np.float64]:
    """The reference\'s window background, as it was."""
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


def _columns(seed: int) -> np.ndarray:
    """Columns with what the walk has to get right: several saturated runs per column, pixels
    already over the well next to the fullest, charge that runs off either end, empty columns."""
    rng = np.random.default_rng(seed)
    h, w, cap = 60, 40, 1000.0
    col = rng.uniform(0, 0.9 * cap, (h, w))
    for j in range(w):
        for _ in range(rng.integers(0, 4)):
            i = rng.integers(0, h)
            col[max(i - 2, 0):i + 3, j] += rng.uniform(0, 20) * cap * rng.uniform(0.2, 1, min(i + 3, h) - max(i - 2, 0))
    col[:, 0] = 0.0  # nothing to spill
    col[0, 1] = 8 * cap  # at the window's edge: half leaves at once
    col[:, 2] = 1.5 * cap  # every pixel over the well
    return col


@pytest.mark.parametrize("seed", range(6))
def test_vectorised_blooming_is_the_walk(seed: int) -> None:
    col = _columns(seed)
    cap = 1000.0
    want = _walk(col, cap)
    got = bloom_column(col, cap)
    # the running sum reorders the additions of the walk: round-off of a few ulp of the
    # charges summed (~1e5 e- here, ulp ~1e-11), far below 1e-6 e-
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    assert got.max() <= cap * (1 + 1e-12)
    # charge kept where none reaches an end (columns whose end pixels stay below the well before and after)
    inside = (want[0] < cap) & (want[-1] < cap)
    np.testing.assert_allclose(got.sum(axis=0)[inside], col.sum(axis=0)[inside], rtol=1e-12)


@pytest.mark.parametrize("mono", [False, True])
def test_bloom_splats_are_the_reference(mono: bool) -> None:
    camera = CameraModel(640, 480, [[600.0, 0, 321.3], [0, 600.0, 238.6], [0, 0, 1]])
    sensor = SensorSpec(bit_depth=12, noise=False, beacon_peak=0.6, full_well_e=15000.0, exposure=20.0,
                        color="mono" if mono else "rgb")
    ship = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
    pose = CameraPose.nadir(40.0)
    base = beacon_splats(DeckLayout(), (ship,), pose, camera, sensor)
    proj = project_layout(DeckLayout(), ship, pose, camera)
    lensed, _ = apply_optics(base, proj.depth_m[[sp.beacon_id for sp in base]], OpticsSpec(bloom=True), camera)
    raster = np.full((camera.height_px, camera.width_px, 3), 10, np.uint8)
    scale = np.full(3, 0.2 / (10 * sensor.exposure), np.float32)
    raster[200:300, 250:400] = 40  # a brighter patch of deck (0.8 wells) under some spots
    vig = (camera, 4.0)
    got = bloom_splats(lensed, raster, scale, sensor, vig)
    want = reference_bloom_splats(lensed, raster, scale, sensor, vig)
    assert len(got) == len(want) and sum(a.row0 != b.row0 for a, b in zip(got, lensed)) >= 6  # they bloomed
    for a, b in zip(got, want):
        assert (a.row0, a.col0, a.patch.shape) == (b.row0, b.col0, b.patch.shape)
        # float32 patches of the same float64 charges to ~1e-12: equal to a float32 ulp. Mono: the reference
        # wrote the grey into every channel; the columns left alone keep their channels, whose grey is it
        if mono:
            np.testing.assert_allclose(a.patch @ a.rgb / 3, b.patch @ b.rgb / 3, rtol=1e-6,
                                       atol=1e-6 * float(b.patch.max()))
        else:
            np.testing.assert_allclose(a.patch, b.patch, rtol=1e-6, atol=1e-6 * float(b.patch.max()))


CAMERA = CameraModel(640, 480, [[600.0, 0, 321.3], [0, 600.0, 238.6], [0, 0, 1]])
SENSOR = SensorSpec(bit_depth=16, noise=False, beacon_peak=0.6, full_well_e=1e6)  # no clipping, no noise
OPTICS = OpticsSpec(f_number=2.0, focus_distance_m=3.0, pixel_pitch_um=2.0, diffraction=True,
                    vignetting_exponent=4.0, lateral_ca_ppm=(3000.0, -2000.0), field_blur_px=1.0)


def _lensed(fraction: float) -> tuple[list[Splat], np.ndarray, LensedFrame]:
    ship = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
    pose = CameraPose.nadir(40.0)
    proj = project_layout(DeckLayout(), ship, pose, CAMERA)
    splats = beacon_splats(DeckLayout(), (ship,), pose, CAMERA, SENSOR)
    splats = bloom(splats, fraction, 3.0) if fraction > 0 else splats
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    lens = through_lens(OPTICS, CAMERA, SENSOR, raster, np.ones(3, np.float32), splats, [], proj.points_px,
                        proj.depth_m, np.zeros(0))
    return lens.beacons, proj.points_px, lens


def test_bloom_and_optics_together_keep_each_channels_light_and_truth() -> None:
    f = 0.05
    both, points, lens_b = _lensed(f)
    alone, _, lens_a = _lensed(0.0)
    ca = ca_centres_px(points, CAMERA, OPTICS)
    by_id = {sp.beacon_id: sp for sp in alone}
    assert len(both) >= 10
    for sp in both:
        v, u = np.mgrid[sp.row0:sp.row0 + sp.patch.shape[0], sp.col0:sp.col0 + sp.patch.shape[1]]
        ref = by_id[sp.beacon_id]
        for c in range(3):
            p = sp.patch[..., c].astype(np.float64)
            # bloom spreads light, the lens moves it: each channel's light stays on its true centre
            # (point-symmetric glare; the lens's tolerance of tests/render/test_optics.py, float32 DFTs)
            np.testing.assert_allclose([(p * u).sum() / p.sum(), (p * v).sum() / p.sum()],
                                       ca[sp.beacon_id, c], atol=1e-3)
            # and keeps it: bloom's window holds its whole kernel, the lens's kernels sum to 1
            assert p.sum() == pytest.approx(float(ref.patch[..., c].astype(np.float64).sum()), rel=1e-5)
    ra, rb = lens_a.record, lens_b.record
    np.testing.assert_array_equal(rb.centres_px, ra.centres_px)  # the truth does not move
    # the core flux the record keeps is the 1 - f bloom leaves in it, in every channel
    seen = np.isfinite(ra.channel_flux_e[:, 0])
    np.testing.assert_allclose(rb.channel_flux_e[seen], (1 - f) * ra.channel_flux_e[seen], rtol=1e-12)
    assert np.all(np.isfinite(rb.crb_px[seen]))


def test_manifest_records_bloom_and_optics(tmp_path: Path) -> None:
    doc = tiny_doc(heights_m=[30.0], lighting=["night"], cameras=[{"preset": "8mp-square", "size": [320, 180]}],
                   motion={"source": "fixed", "attitudes_deg": [[0, 0, 0]]},
                   scene={"shading": "flat", "texture_px": 256, "bloom_fraction": 0.05, "bloom_sigma_mrad": 4.0},
                   optics={"diffraction": True, "lateral_ca_ppm": [800.0, -800.0], "vignetting_exponent": 2.0})
    cfg = config_from_dict(doc)
    render_dataset(cfg, tmp_path / "ds", workers=1)
    manifest = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert manifest["config"]["scene"]["bloom_fraction"] == 0.05
    assert manifest["config"]["scene"]["bloom_sigma_mrad"] == 4.0
    assert manifest["optics"]["enabled"] is True and len(manifest["optics"]["airy_kernels"]) == 3
    beacons = pd.read_parquet(tmp_path / "ds" / "beacons.parquet")
    lit = beacons[beacons["visible"]]
    assert len(lit) > 0
    # per-channel electrons recorded and adding up to the spot's
    parts = lit[["spot_flux_r_e", "spot_flux_g_e", "spot_flux_b_e"]].sum(axis=1)
    np.testing.assert_allclose(parts, lit["spot_flux_e"], rtol=1e-12)
