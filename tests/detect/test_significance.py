"""The significance search's building blocks against plain reference computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.detect.background import COUNTED_MEDIAN_MIN, _counted_row_median, row_median
from deckpose.detect.block_sums import block_sum
from deckpose.detect.significance import box_means, ring_samples
from deckpose.detect.tile_texture import TEXTURE_TILE_PX, texture_noise, tiles_of


@pytest.mark.parametrize("m", [1, 2, 3, 16, 17, 26, 256])
def test_row_median_is_numpys_median(m: int) -> None:
    rng = np.random.default_rng(m)
    # ties (small integers) and plain floats, float32 and float64
    for a in (rng.integers(-3, 4, (50, m)).astype(np.float64),
              rng.normal(size=(50, m)),
              rng.normal(size=(50, m)).astype(np.float32)):
        got = row_median(a)
        want = np.median(a, axis=1)
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)  # the same two middle values, the same mean



@pytest.mark.parametrize("m", [COUNTED_MEDIAN_MIN, COUNTED_MEDIAN_MIN + 1, 30_001, 60_000])
def test_long_rows_of_whole_and_half_dn_are_counted_to_numpys_median(m: int) -> None:
    """Long rows of whole or half DN take the counting path, which must give np.median's
    values bit for bit; rows it cannot count (other fractions, a wide range) fall back."""
    rng = np.random.default_rng(m)
    counted = [rng.poisson(3.0, (2, m)) - rng.poisson(3.0, (2, m)) + 0.0,   # differences of counts
               np.abs(rng.integers(-40, 40, (3, m)) - 0.5),                 # |d - median|: half DN
               rng.integers(0, 2, (1, m)) + 1e9,                            # ties, far from 0
               np.full((1, m), -7.5)]
    for a in counted:
        assert _counted_row_median(a) is not None
        np.testing.assert_array_equal(row_median(a), np.median(a, axis=1))
    left = [rng.normal(size=(2, m)),                                        # not multiples of 1/2
            rng.integers(0, 40, (1, m)) + 0.25,
            rng.integers(0, 100 * m, (1, m)) + 0.0]                          # a range of 100 x m
    tiny = np.full((1, m), -1000.5)
    tiny[0, m // 2:] = 1e-20  # below half an ulp of 1000.5: a difference from it would round
    left.append(tiny)
    for a in left:
        assert _counted_row_median(a) is None
        np.testing.assert_array_equal(row_median(a), np.median(a, axis=1))
    assert row_median(np.zeros((0, m))).shape == (0,)  # no rows: none to count

def _texture_reference(G: np.ndarray, step: int, tile_row: int, tile_col: int) -> float:
    """The documented rule, written out for one tile: differences of pixels ``step`` apart
    along rows, every 4th row and column of the tile (clipped to the image), 1.4826 MAD / sqrt 2."""
    h, w = G.shape
    T = TEXTURE_TILE_PX
    d = []
    for r in range(tile_row * T, tile_row * T + T, 4):
        for c in range(tile_col * T, tile_col * T + T, 4):
            rr = min(r, h - 1)
            cc = max(min(c, w - 1 - step), 0)
            d.append(float(G[rr, min(cc + step, w - 1)]) - float(G[rr, cc]))
    a = np.array(d)
    med = np.median(a)
    return 1.4826 * float(np.median(np.abs(a - med))) / math.sqrt(2.0)


@pytest.mark.parametrize("step", [2, 6, 16])
def test_texture_noise_matches_the_rule_per_tile(step: int) -> None:
    rng = np.random.default_rng(step)
    # a partial last tile in both directions; float32 as the search's smoothed image
    G = (rng.normal(0, 3, (150, 200)) + np.linspace(0, 50, 200)[None]).astype(np.float32)
    tiles = np.array([(i, j) for i in range(3) for j in range(4)])
    got = texture_noise(G, step, tiles)
    want = [_texture_reference(G, step, i, j) for i, j in tiles]
    # float32 differences in the function, float64 in the reference: the same samples, so
    # equal to float32 rounding of the differences (1e-6 relative of values ~50)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-4)
    # a tile's value does not depend on which other tiles are asked for
    np.testing.assert_array_equal(texture_noise(G, step, tiles[5:6]), got[5:6])


@pytest.mark.parametrize("n", [40, 3000])  # direct sums, and the integral image
def test_box_means_are_the_means_of_boxes_shifted_inside(n: int) -> None:
    rng = np.random.default_rng(n)
    G = rng.normal(10, 2, (90, 120)).astype(np.float32)
    ys, xs = rng.integers(0, 90, n), rng.integers(0, 120, n)
    half = 7
    k = 2 * half + 1
    got = box_means(G, ys, xs, half)
    for i in range(n):
        y0 = min(max(ys[i] - half, 0), 90 - k)
        x0 = min(max(xs[i] - half, 0), 120 - k)
        want = float(np.mean(G[y0 : y0 + k, x0 : x0 + k], dtype=np.float64))
        # float64 sums of float32 values: equal to ~1e-12 relative
        assert got[i] == pytest.approx(want, rel=1e-10)


@pytest.mark.parametrize("n", [0, 1, 500])
def test_ring_samples_are_the_image_at_clipped_offsets(n: int) -> None:
    rng = np.random.default_rng(n)
    G = rng.normal(0, 1, (60, 80)).astype(np.float32)
    # points anywhere, the frame's edge included (clipped there), and offsets of a ring
    ys, xs = rng.integers(0, 60, n), rng.integers(0, 80, n)
    dy = np.array([-7, -3, 0, 2, 7, 5])
    dx = np.array([0, 6, -7, 3, 1, -5])
    got = ring_samples(G, ys, xs, dy, dx)
    # the reference: each sample in a loop, its coordinates clipped to the image
    want = np.array([[G[min(max(y + a, 0), 59), min(max(x + b, 0), 79)] for a, b in zip(dy, dx)]
                     for y, x in zip(ys, xs)], np.float32).reshape(n, dy.size)
    assert got.dtype == G.dtype
    np.testing.assert_array_equal(got, want)  # the same pixels


@pytest.mark.parametrize("n", [0, 1, 7, 4000])
def test_tiles_of_are_the_sorted_tiles_holding_points(n: int) -> None:
    rng = np.random.default_rng(n)
    w = 700  # a partial last tile column
    ys, xs = rng.integers(0, 400, n), rng.integers(0, w, n)
    tiles, of = tiles_of(ys, xs, w)
    # the reference: each point's (tile row, tile column), the distinct pairs in row-major order
    pairs = sorted({(int(y) // TEXTURE_TILE_PX, int(x) // TEXTURE_TILE_PX) for y, x in zip(ys, xs)})
    assert tiles.tolist() == [list(p) for p in pairs]
    for i in range(n):
        assert tuple(tiles[of[i]]) == (ys[i] // TEXTURE_TILE_PX, xs[i] // TEXTURE_TILE_PX)


@pytest.mark.parametrize("factor", [2, 4])
def test_block_sums_of_an_8bit_frame_are_exact(factor):
    # OpenCV's area resampling rounds an 8-bit block mean to a whole DN; on a dark frame (pixels
    # 0 or 1 DN) that dropped a faint spot's light. The block sums must be the exact sums.
    rng = np.random.default_rng(3)
    img = (rng.random((64, 96, 3)) < 0.1).astype(np.uint8) + (rng.random((64, 96, 3)) < 0.01) * 250
    img = img.astype(np.uint8)
    h, w = 64 // factor, 96 // factor
    want = img.astype(np.float64).reshape(h, factor, w, factor, 3).sum(axis=(1, 3, 4))
    np.testing.assert_array_equal(block_sum(img, factor), want)
