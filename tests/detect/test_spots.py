"""The bright-spot search's shortcuts give exactly what the plain computations give."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.spots import (
    bright_components,
    bright_level,
    peak_block_max,
    peak_channel,
    spot_search,
)


def _spotty_image(rng: np.random.Generator, rgb: bool, dtype: type) -> np.ndarray:
    H, W = (int(x) for x in rng.integers(20, 300, 2))
    img = rng.integers(0, 50, (H, W, 3) if rgb else (H, W)).astype(dtype)
    for _ in range(int(rng.integers(0, 30))):
        y, x = int(rng.integers(0, H)), int(rng.integers(0, W))
        h, w = int(rng.integers(1, 8)), int(rng.integers(1, 8))
        img[y : y + h, x : x + w] = rng.integers(50, 255)
    return img


def _block_max_reference(pk: np.ndarray, f: int) -> np.ndarray:
    H, W = pk.shape
    h, w = -(-H // f), -(-W // f)
    pad = np.full((h * f, w * f), -np.inf)
    pad[:H, :W] = pk
    return pad.reshape(h, f, w, f).max(axis=(1, 3))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("rgb", [False, True])
def test_block_maxima_and_bright_level_are_exact(dtype: type, rgb: bool) -> None:
    rng = np.random.default_rng(int(rgb) + 2 * np.dtype(dtype).itemsize)
    for _ in range(40):
        img = _spotty_image(rng, rgb, dtype)
        pk = img.max(axis=2) if rgb else img
        np.testing.assert_array_equal(peak_channel(img), pk)
        f = int(rng.integers(1, 7))
        small = peak_block_max(img, f)
        np.testing.assert_array_equal(small, _block_max_reference(pk.astype(float), f))
        flat = np.sort(pk.ravel())
        want = float(flat[max(0, flat.size - 20)])  # the 20th brightest pixel
        assert bright_level(img, small, f) == want


def test_components_match_a_full_labelling() -> None:
    rng = np.random.default_rng(5)
    for _ in range(60):
        H, W = (int(x) for x in rng.integers(50, 900, 2))
        m = np.zeros((H, W), np.uint8)
        for _ in range(int(rng.integers(0, 40))):
            centre = (int(rng.integers(0, W)), int(rng.integers(0, H)))
            cv2.circle(m, centre, int(rng.integers(0, 6)), 1, -1)
        m |= (rng.random((H, W)) < rng.choice([0.0, 1e-4, 1e-2])).astype(np.uint8)
        _, _, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        got = bright_components(m.astype(bool), tile_px=int(rng.choice([100, 1000, 16_384])))
        assert sorted(map(tuple, stats[1:, :4].tolist())) == sorted(map(tuple, got.tolist()))


def test_spot_threshold_lies_between_background_and_the_spots() -> None:
    rng = np.random.default_rng(1)
    img = rng.normal(100.0, 3.0, (400, 600, 3)).clip(0, 65535).astype(np.uint16)
    for u, v in ((100, 100), (300, 200), (500, 350)):
        img[v - 3 : v + 4, u - 3 : u + 4, 0] = 5000  # red spots: only the peak channel sees them
    s = spot_search(img, DetectorOptions(coarse_max_px=10_000))
    assert s.factor == 5 and s.bright_dn == 5000.0
    assert abs(s.background_dn - 103.0) < 3.0  # median of the largest of three N(100, 3)
    assert s.threshold_dn == pytest.approx(s.background_dn + 0.8 * (5000.0 - s.background_dn))


def _glowing_spot(rng: np.random.Generator, sigma_px: float, size: int = 81):
    """A Gaussian core (peak 10000) with a 4x wider glow (5 % of the light) on a
    background of 100 with noise sigma 5; returns the window, its core mask and sigma."""
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    c = (size - 1) / 2 + 0.3
    r2 = (xx - c) ** 2 + (yy - c) ** 2
    core = 10000.0 * np.exp(-r2 / (2 * sigma_px**2))
    glow = 0.05 / 16 * 10000.0 / 0.95 * np.exp(-r2 / (2 * (4 * sigma_px) ** 2))
    img = 100.0 + core + glow + rng.normal(0.0, 5.0, r2.shape)
    return img, core > 0.8 * 10000.0


@pytest.mark.parametrize("sigma_px", [1.9, 3.6, 7.0])
def test_pedestal_of_a_clean_spot_lies_below_its_wings(sigma_px: float) -> None:
    """Beyond window_sigma spot sigmas the pedestal is the glow plus noise, far below the
    wings at twice the core radius (where the old pedestal, their maximum, sat)."""
    from deckpose.detect.spots import spot_pedestal

    img, core = _glowing_spot(np.random.default_rng(4), sigma_px)
    r_core = np.sqrt(core.sum() / np.pi)
    sigma_core = r_core / np.sqrt(2 * np.log(1 / 0.8))
    ped = spot_pedestal(img, core, 100.0, 3.0 * sigma_core - r_core)
    # the pedestal before: the brightest pixel farther than 2 r + 2 from the core
    dist = cv2.distanceTransform((~core).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    old = max(100.0, float(img[dist > int(np.ceil(2 * r_core + 2))].max()))
    glow_at_3_sigma = 0.05 / 16 * 10000.0 / 0.95 * np.exp(-((3.0 / 4) ** 2) / 2)
    assert 100.0 < ped < 100.0 + glow_at_3_sigma + 0.1 * 10000 * np.exp(-4.5) + 4 * 5.0
    assert old - 100.0 > 2 * (ped - 100.0)


def test_pedestal_rises_to_a_marking_on_one_side() -> None:
    """A bright marking next to the spot raises the pedestal to its level, so the
    marking (which the beacon does not light) does not pull the centre."""
    from deckpose.detect.spots import spot_pedestal

    img, core = _glowing_spot(np.random.default_rng(5), 3.6, size=41)  # a detector's window
    img[:, 33:37] += 2000.0  # a white line 13-16 px (3.6-4.5 sigma) right of the spot
    r_core = np.sqrt(core.sum() / np.pi)
    sigma_core = r_core / np.sqrt(2 * np.log(1 / 0.8))
    ped = spot_pedestal(img, core, 100.0, 3.0 * sigma_core - r_core)
    assert ped > 100.0 + 2000.0 - 4 * 5.0


def test_pedestal_is_the_highest_sector_percentile_as_numpy_takes_it() -> None:
    """The pedestal is the largest of the sectors' PEDESTAL_PERCENTILE percentiles (np.percentile's
    linear interpolation) of the pixels beyond the wings, and at least the border level: the rule
    written out with np.percentile per sector, on random windows (ties included), equal exactly."""
    import math

    from deckpose.detect.spots import PEDESTAL_PERCENTILE, PEDESTAL_SECTORS, spot_pedestal

    rng = np.random.default_rng(5)
    for t in range(60):
        h, w = (int(v) for v in rng.integers(15, 50, 2))
        pix = rng.normal(100.0, 10.0, (h, w))
        if t % 2:
            pix = np.rint(pix)  # ties
        core = np.zeros((h, w), bool)
        r = int(rng.integers(1, 4))
        core[h // 2 - r : h // 2 + r + 1, w // 2 - r : w // 2 + r + 1] = True
        wings, border = float(rng.uniform(1.0, 8.0)), float(rng.uniform(80.0, 120.0))
        got = spot_pedestal(pix, core, border, wings)
        r_px = math.ceil(max(wings, 2.0 * math.sqrt(core.sum() / math.pi) + 2.0))
        dist = cv2.distanceTransform((~core).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        fv, fu = np.nonzero(dist > r_px)
        if fv.size == 0:
            assert got == border
            continue
        vv, uu = np.nonzero(core)
        ang = np.arctan2(fv - vv.mean(), fu - uu.mean())
        sector = ((ang + np.pi) * (PEDESTAL_SECTORS / (2 * np.pi))).astype(int) % PEDESTAL_SECTORS
        levels = [float(np.percentile(pix[fv, fu][sector == k], PEDESTAL_PERCENTILE))
                  for k in range(PEDESTAL_SECTORS) if (sector == k).any()]
        assert got == max(border, max(levels))
