"""A texture of flat steps (a night sea on a low-noise 8-bit sensor) gives no spots.

The thesis sweep's 64 MP frames at 80 m (8-bit, 5 e read noise against a 20,000 e well:
78 e a DN) show the sea at night as patches 2-6 DN high with almost no noise: after
rounding, 60 % of the pixel differences are exactly 0 and the rest are steps of one DN per
channel, many noise sigmas. Every patch top was a plateau of equal local maxima (820,000 of
them: the frame was refused as "a flat bright or noisy frame"), and the tiles' texture,
a median absolute deviation of differences, read about 0, so the patches passed as spots.
The frame here is made independently of the renderer: a smooth random field rounded to
whole DN, with compact beacons on it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.significance import one_per_plateau, significant_spots

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.records import Frame


def _step_sea(shape: tuple[int, int], patch_px: float, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) float: a camouflage of flat patches (about ``patch_px`` across, hard edges) at
    three levels one DN apart, red 2 DN above blue as the night sea, plus 0.06 DN of noise
    (5 e of read noise at 78 e a DN), before rounding."""
    h, w = shape
    small = rng.normal(size=(max(2, int(h / patch_px)), max(2, int(w / patch_px))))
    field = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    level = np.digitize(field, np.quantile(field, [0.35, 0.7])).astype(float)
    sea = np.stack([2.0 + level, 1.0 + level, level], axis=2)
    return sea + rng.normal(0.0, 0.06, sea.shape)


def _beacons(shape: tuple[int, int], n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) float image of ``n`` Gaussian spots (sigma 1.2 px, peaks 40-200 DN per channel) on a
    circle, and their centres (n, 2) as (u, v)."""
    h, w = shape
    a = np.linspace(0, 2 * math.pi, n, endpoint=False) + rng.uniform(0, 0.5)
    r = 0.35 * min(h, w)
    centres = np.column_stack([w / 2 + r * np.cos(a), h / 2 + r * np.sin(a)]) + rng.uniform(-0.5, 0.5, (n, 2))
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.zeros(shape)
    for (u, v), peak in zip(centres, rng.uniform(40, 200, n)):
        img += peak * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 1.2**2))
    return img, centres


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_step_textured_sea_gives_no_spots_and_every_beacon_is_found(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (960, 1280)
    sea = _step_sea(shape, 24.0, rng)
    spots, centres = _beacons(shape, 12, rng)
    img = np.clip(np.round(sea + spots[..., None]), 0, 255).astype(np.uint8)
    # the texture is steps: most differences of neighbours are exactly 0
    assert np.mean(np.diff(img[..., 0].astype(int), axis=1) == 0) > 0.5
    cam = preset("4mp-thesis").with_size(shape[1], shape[0])
    fd = detect_frame(Frame(img, cam), "cog", DeckLayout(), identify=False)
    pts = fd.detections.points_px
    assert fd.reason == ""
    # every beacon found (peaks >= 40 DN: thousands of sigmas) ...
    d = np.linalg.norm(pts[:, None, :] - centres[None], axis=2)
    assert np.all(d.min(axis=0) < 0.5)
    # ... and nothing else: the patches (a step of 1 DN per channel over ~12 px) are texture
    assert len(pts) == len(centres), len(pts)


def test_a_large_step_textured_frame_is_not_refused_for_its_plateaus() -> None:
    # 8 MP (search factor 2): the patch tops are plateaus of equal maxima, more than
    # MAX_PEAKS pixels of them; counted once per plateau the frame is searched
    rng = np.random.default_rng(5)
    shape = (2160, 3840)
    sea = _step_sea(shape, 32.0, rng)
    img = np.clip(np.round(sea), 0, 255).astype(np.uint8)
    img[1000:1003, 2000:2003] = 120  # one compact bright spot
    centres, _radii, reason, _note = significant_spots(img, 5.0, 100)
    assert reason == ""
    assert len(centres) == 1 and np.allclose(centres[0], (2001, 1001), atol=2.5)


def test_one_per_plateau_keeps_the_member_nearest_each_groups_centroid() -> None:
    rng = np.random.default_rng(3)
    shape = (40, 50)
    mask = rng.random(shape) < 0.25
    ys, xs = np.nonzero(mask)  # row-major
    ky, kx = one_per_plateau(ys, xs, shape)
    # brute force: 8-connected groups by flood fill, nearest to the group's mean, first on a tie
    label = -np.ones(shape, int)
    groups = []
    for y0, x0 in zip(ys, xs):
        if label[y0, x0] >= 0:
            continue
        stack, members = [(y0, x0)], []
        label[y0, x0] = len(groups)
        while stack:
            y, x = stack.pop()
            members.append((y, x))
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < shape[0] and 0 <= xx < shape[1] and mask[yy, xx] and label[yy, xx] < 0:
                        label[yy, xx] = len(groups)
                        stack.append((yy, xx))
        groups.append(np.array(members))
    kept = list(zip(ky.tolist(), kx.tolist()))
    assert kept == sorted(kept)  # row-major order kept
    assert len(kept) == len(groups)  # one per group
    for (y, x) in kept:
        m = groups[label[y, x]]
        d2 = ((m - m.mean(axis=0)) ** 2).sum(axis=1)
        # the member nearest the group's centroid (equal distances: either; float rounding)
        assert ((y - m[:, 0].mean()) ** 2 + (x - m[:, 1].mean()) ** 2) <= d2.min() + 1e-9
