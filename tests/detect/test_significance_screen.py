"""The significance search's screen is a bound: with it the search finds exactly the spots it finds without.

The screen (``significant_spots(..., screen=True)``, the default) drops, before the dear
tests, the peaks that cannot pass any ring: each ring's few samples against the pixel
noise and the tile's texture. Without it (``screen=False``) every local maximum goes
through every ring's full test. The two must give the same spots, centre for centre and
radius for radius, on every kind of frame: plain noise with spots of every strength
(many near the threshold), frames of the independent generator
(``benchmarks/independent_spots.py``), and a lit-sea-like texture with markings, whose
thousands of bumps are what the screen is for.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from deckpose.detect.block_sums import block_sum
from deckpose.detect.significance import search_factor, significant_spots

from tests.detect.independent_generator import load_independent_generator


def _spots(shape: tuple[int, int], n: int, rng: np.random.Generator, amp: tuple[float, float],
           sigma: tuple[float, float]) -> np.ndarray:
    """Gaussian spots at random places, amplitudes log-uniform in ``amp`` (DN at the peak)."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    out = np.zeros(shape)
    for _ in range(n):
        y, x = rng.uniform(3, h - 3), rng.uniform(3, w - 3)
        s = rng.uniform(*sigma)
        a = math.exp(rng.uniform(math.log(amp[0]), math.log(amp[1])))
        r = int(4 * s) + 2
        y0, y1, x0, x1 = max(0, int(y) - r), min(h, int(y) + r), max(0, int(x) - r), min(w, int(x) + r)
        out[y0:y1, x0:x1] += a * np.exp(-((yy[y0:y1, x0:x1] - y) ** 2 + (xx[y0:y1, x0:x1] - x) ** 2)
                                        / (2 * s * s))
    return out


def _noise_frame(seed: int) -> np.ndarray:
    """640x480 uint16 mono: background 100 DN, noise 5 DN, 60 spots from 2 to 60 noise sigmas."""
    rng = np.random.default_rng(seed)
    img = 100.0 + _spots((480, 640), 60, rng, (10.0, 300.0), (0.8, 3.0))
    img = rng.normal(img, 5.0)
    return np.clip(np.rint(img), 0, 65535).astype(np.uint16)


def _sea_frame(seed: int) -> np.ndarray:
    """640x480 uint16 mono like a rendered frame's lit sea: a bright smooth-random texture
    (bumps of 2-6 px, tens of noise sigmas), a glare gradient, two marking lines, and spots."""
    rng = np.random.default_rng(seed)
    h, w = 480, 640
    tex = np.zeros((h, w))
    for s, a in ((1.5, 400.0), (3.0, 600.0), (6.0, 800.0)):
        f = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), s)
        tex += a * f / f.std()
    img = 4000.0 + tex + np.linspace(0, 3000, w)[None, :]
    img[200:203, :] += 1500.0  # a marking
    img[:, 400:402] += 1200.0
    img += _spots((h, w), 15, rng, (3000.0, 30000.0), (1.0, 3.0))
    img = np.maximum(img, 100.0)
    img = rng.normal(img, np.sqrt(img) * 0.5)
    return np.clip(np.rint(img), 0, 65535).astype(np.uint16)


def _independent_frame(seed: int, rgb: bool, bits: int) -> np.ndarray:
    gen = load_independent_generator()
    spec = gen.SpotFrameSpec(width_px=640, height_px=480, focal_px=420.0, rgb=rgb, bits=bits,
                             uneven=(0.4, 1.0), other_lights=3, sigma_px=(0.7, 3.0),
                             flux_e=(1_500.0, 30_000.0))
    return gen.make_frame(spec, np.random.default_rng(seed)).image


def _local_maxima_above(image: np.ndarray, k_sigma: float) -> int:
    """About how many local maxima of the smoothed block sums stand k_sigma of their noise above
    the median: the peaks the screen has to judge (an independent count, numpy + OpenCV)."""
    S = block_sum(image, search_factor(image.shape[:2]))  # 640x480: the frame itself
    G = cv2.GaussianBlur(S, (0, 0), 1.5)
    d = np.diff(S, axis=1).ravel()
    # the pixel noise (MAD of differences), through a Gaussian of sigma s, whose 2-D kernel has
    # the norm 1 / (4 pi s^2) (continuous approximation; a count, not a threshold test)
    noise = 1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2) / (2 * math.sqrt(math.pi) * 1.5)
    is_max = G >= cv2.dilate(G, np.ones((3, 3), np.uint8))
    return int(np.count_nonzero(is_max & (G > np.median(G) + k_sigma * noise)))


FRAMES = {
    "noise_a": lambda: _noise_frame(1),
    "noise_b": lambda: _noise_frame(2),
    "sea_a": lambda: _sea_frame(3),
    "sea_b": lambda: _sea_frame(4),
    "independent_rgb16": lambda: _independent_frame(5, True, 16),
    "independent_mono12": lambda: _independent_frame(6, False, 12),
    "independent_rgb8": lambda: _independent_frame(7, True, 8),
}


@pytest.mark.parametrize("name", sorted(FRAMES))
def test_the_screen_keeps_every_spot_the_full_tests_find(name: str) -> None:
    image = FRAMES[name]()
    for k_sigma in (3.0, 5.0, 8.0):  # the default 5 and either side: other peaks at the edge
        c1, r1, why1, note1 = significant_spots(image, k_sigma, 10_000, screen=True)
        c0, r0, why0, note0 = significant_spots(image, k_sigma, 10_000, screen=False)
        assert (why1, note1) == (why0, note0)
        # the same spots: the same centres and ring radii, in the same order
        np.testing.assert_array_equal(c1, c0)
        np.testing.assert_array_equal(r1, r0)


def test_the_sea_frames_give_the_screen_a_thousand_peaks_and_it_keeps_the_spots() -> None:
    # not a vacuous comparison: the sea frames hold thousands of local maxima above the
    # threshold (what the screen rejects), and the search still finds most planted spots
    for seed in (3, 4):
        image = _sea_frame(seed)
        assert _local_maxima_above(image, 5.0) > 800
        centres, _r, why, _note = significant_spots(image, 5.0, 10_000)
        # the texture hides the dimmer of the 15 spots; the bright ones stand out of it
        assert why == "" and 5 <= centres.shape[0] < 50
