"""Dark 8-bit frames whose noise does not dither the rounding: sparse counts, found at the limit.

A frame 2-4x darker than the independent benchmark's ``rgb8_dark`` (a 3-15 e background at
78-157 e a DN) stores a flat 0 DN with rare single-DN counts. The significance search had
floored such a frame's noise at a whole DN a channel and asked a dim beacon for some 20 DN at
its centre: recall 0.31-0.94 on the independent generator's frames. The threshold is now the
counts' own (``search_noise.count_threshold``, a Chernoff bound on the smoothed Poisson
counts, at the Gaussian threshold's tail probability).

What is there to be found is judged independently of the detector: each beacon's expected DN
above the background after the sensor's rounding (Poisson + read noise as a normal variable,
rounded to whole DN), summed over its pixels and channels. A beacon whose light rounds away
(under a DN in all) cannot be found by anyone; one with 8 DN or more must be.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from deckpose.detect.block_sums import block_pair_differences
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.search_noise import count_threshold, gaussian_norm, sparse_count_rate
from deckpose.detect.significance import significant_spots

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame
from tests.detect.independent_generator import load_independent_generator

gen = load_independent_generator()

SMALL = gen.SpotFrameSpec(width_px=1920, height_px=1080, focal_px=1250.0, bits=8, uneven=(0.4, 1.0))
#: Expected DN above the background that a beacon must have to be required found.
VISIBLE_DN = 8.0


def _tail(k_sigma: float) -> float:
    return 0.5 * math.erfc(k_sigma / math.sqrt(2.0))


def _kernel(sigma: float) -> np.ndarray:
    """The normalised 2-D Gaussian of ``sigma`` px over ``2 ceil(3 sigma) + 1`` px, written out."""
    r = math.ceil(3.0 * sigma)
    x = np.arange(-r, r + 1, dtype=float)
    g = np.exp(-(x**2) / (2.0 * sigma**2))
    g /= g.sum()
    return np.outer(g, g)


@pytest.mark.parametrize("rate", [0.05, 0.3])
def test_count_threshold_bounds_the_smoothed_counts_tail(rate: float) -> None:
    # Monte Carlo of the smoothed Poisson field: the bound is an upper bound, so the empirical
    # exceedance may not be above the asked probability (plus 3 of its sampling sd)
    p = 2e-3
    sigma = 0.75
    rng = np.random.default_rng(4)
    x = rng.poisson(rate, (1400, 1400)).astype(np.float64)
    G = cv2.filter2D(x, -1, _kernel(sigma), borderType=cv2.BORDER_REFLECT)[10:-10, 10:-10]
    T = count_threshold(rate, sigma, math.log(p))
    frac = float(np.mean(G - rate >= T))
    assert frac <= p + 3 * math.sqrt(p / G.size), (frac, p)
    # ... and it is a threshold, not a wall: it is passed at all
    assert frac > 0.0


def test_count_threshold_becomes_the_gaussian_one_on_dense_counts() -> None:
    # Chernoff's bound on Gaussian noise is exp(-T^2 / 2 sd^2): T = sqrt(2 ln(1/p)) sd
    p = _tail(5.0)
    rate, sigma = 1e5, 0.75
    sd = math.sqrt(rate) * gaussian_norm(sigma)[1]
    assert count_threshold(rate, sigma, math.log(p)) / sd == pytest.approx(math.sqrt(2 * math.log(1 / p)), rel=0.02)


def test_sparse_count_rate_measures_sparse_counts_and_refuses_dense_noise() -> None:
    rng = np.random.default_rng(2)
    rate = 0.004

    def pair_differences(S: np.ndarray) -> np.ndarray:  # neighbours, every 4th row and pair
        return (S[::4, 1::8] - S[::4, 0:-1:8]).ravel()

    S = rng.poisson(rate, (1080, 1920)).astype(np.float32) + 7.0  # a flat level of 7 DN
    d = pair_differences(S)
    est = sparse_count_rate(d)
    assert est is not None
    # the pairs' squared differences: 2 rate of them non-zero
    assert est == pytest.approx(rate, rel=4.0 / math.sqrt(2 * rate * d.size))
    assert sparse_count_rate(pair_differences(rng.poisson(3.0, (1080, 1920)).astype(np.float32))) is None


def test_block_pair_differences_are_the_exact_block_sums_differences() -> None:
    rng = np.random.default_rng(3)
    for shape, f in (((1001, 1533, 3), 2), ((2163, 3841, 3), 4), ((999, 777), 2), ((500, 600, 3), 1)):
        im = rng.integers(0, 256, shape).astype(np.uint8)
        h, w = shape[0] // f, shape[1] // f
        # the blocks' sums written out (int64), then the same grid of neighbour pairs
        blocks = im[: h * f, : w * f].astype(np.int64).reshape(h, f, w, f, -1).sum(axis=(1, 3, 4))
        d = block_pair_differences(im, f)
        step = max(1, int(math.sqrt(h * w / 60_000)))
        n = (w - 1) // step
        want = blocks[::step, 1::step][:, :n] - blocks[::step, 0 : w - 1 : step][:, :n]
        np.testing.assert_array_equal(d, want.ravel())


def test_a_sparse_frame_takes_any_significance_threshold() -> None:
    # a 40-sigma Gaussian tail is below the smallest float: the threshold is reached through
    # its logarithm (the tail itself, 0.0, had failed in math.log)
    rng = np.random.default_rng(0)
    img = (rng.random((300, 400)) < 0.003).astype(np.uint8)
    img[100:103, 200:203] = 40  # one bright compact spot
    assert sparse_count_rate(block_pair_differences(img, 1)) is not None
    for k in (5.0, 39.0, 60.0):
        centres, _radii, reason, _note = significant_spots(img, k, 100)
        assert reason == ""
        # the spot, 360 DN among single counts, stands above any threshold; nothing else does
        assert len(centres) == 1 and np.allclose(centres[0], (201, 101), atol=1.5), centres


def test_a_sparse_background_alone_gives_no_spots() -> None:
    # 8-bit RGB, 15 e and 20 e of background at 78 e a DN: the counts of chance alone
    rng = np.random.default_rng(9)
    for bg_e, rn_e in ((15.0, 5.0), (20.0, 5.0)):
        e = rng.poisson(bg_e, (1080, 1920, 3)) + rng.normal(0.0, rn_e, (1080, 1920, 3))
        img = np.clip(np.rint(e * 255 / 20_000), 0, 255).astype(np.uint8)
        assert 0 < np.count_nonzero(img) < 0.01 * img.size  # sparse counts, some of them
        centres, _radii, reason, _note = significant_spots(img, 5.0, 200)
        assert reason == "" and len(centres) == 0, centres


def test_lone_hot_pixels_on_a_sparse_background_are_no_spots() -> None:
    # a single pixel of 2-255 DN in one channel among zeros: its neighbours hold none of the
    # light a spot of sigma >= 0.6 px gives them. The sparse threshold finds such a pixel; the
    # defect test, with a whole DN a channel as its noise, had let 5-14 of 300 a frame through
    rng = np.random.default_rng(12)
    for bg_e in (3.0, 15.0, 20.0):
        e = rng.poisson(bg_e, (1080, 1920, 3)) + rng.normal(0.0, 3.0, (1080, 1920, 3))
        img = np.clip(np.rint(e * 255 / 20_000), 0, 255).astype(np.uint8)
        ys, xs = rng.integers(0, 1080, 300), rng.integers(0, 1920, 300)
        img[ys, xs, rng.integers(0, 3, 300)] = rng.integers(2, 256, 300)
        centres, _radii, reason, _note = significant_spots(img, 5.0, 200)
        assert reason == "" and len(centres) == 0, centres


@pytest.mark.parametrize(("bg_e", "read_e", "full_well_e", "seed"),
                         [(10.0, 2.0, 40_000.0, 31), (3.0, 2.0, 20_000.0, 32), (15.0, 5.0, 20_000.0, 33)])
def test_every_visible_beacon_of_a_sparse_dark_frame_is_found_and_nothing_else(
        bg_e: float, read_e: float, full_well_e: float, seed: int) -> None:
    spec = replace(SMALL, background_e=bg_e, read_noise_e=read_e, full_well_e=full_well_e)
    rng = np.random.default_rng(seed)
    n_visible = 0
    for _ in range(3):
        t = gen.make_frame(spec, rng)
        cam = CameraModel(t.image.shape[1], t.image.shape[0], t.K)
        res = detect_frame(Frame(t.image, cam, 0), "cog", DeckLayout())
        idx, _ = gen.match(res.detections.points_px, t)
        visible = gen.visible_dn(t, spec) >= VISIBLE_DN
        n_visible += int(visible.sum())
        assert np.all(idx[visible] >= 0), (t.flux_e[visible & (idx < 0)], t.sigma_px[visible & (idx < 0)])
        # every detection is a beacon's
        assert len(res.detections.points_px) == int(np.count_nonzero(idx >= 0)), "a false detection"
    assert n_visible >= 30  # the frames hold beacons to find (13 a frame, most of them visible)
