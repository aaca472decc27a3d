"""Frames a lossy codec (JPEG) made: its block steps are not spots, and every beacon is still found.

A JPEG at moderate quality of a frame whose noise is a DN or two flattens the noise and leaves
whole 8 x 8 blocks raised by one quantum of a DCT term. The significance search took them for
spots (30-160 on a 2 MP frame at qualities 75-90, and identification failed), found by a user
with their own frames. Frames here come from the independent generator (``benchmarks/
independent_spots.py``), encoded by OpenCV's libjpeg, not from ``render/``.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from deckpose.detect.block_sums import block_sum
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.search_noise import codec_block_step

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame
from tests.detect.independent_generator import load_independent_generator


def _raised_blocks(rng: np.random.Generator, n_blocks: int, step_dn: int) -> np.ndarray:
    """A flat 8-bit RGB frame with ``n_blocks`` grid-aligned 8 x 8 blocks raised by ``step_dn`` a channel."""
    img = np.full((1080, 1920, 3), 12, np.uint8)
    for by, bx in zip(rng.integers(0, 135, n_blocks), rng.integers(0, 240, n_blocks)):
        img[8 * by : 8 * by + 8, 8 * bx : 8 * bx + 8] += np.uint8(step_dn)
    return img


@pytest.mark.parametrize("factor", [1, 2, 4])
def test_raised_codec_blocks_give_their_step_at_every_search_factor(factor: int) -> None:
    img = _raised_blocks(np.random.default_rng(1), 120, 2)
    S = block_sum(img, factor, exact=False)
    # the channel sum's step, 6 DN a pixel, in S's blocks of factor^2 pixels
    assert codec_block_step(S, factor) == pytest.approx(6.0 * factor**2)


def test_noise_and_short_patterns_are_not_codec_blocks() -> None:
    rng = np.random.default_rng(2)
    h, w = 1080, 1920
    dense = np.clip(rng.normal(40, 2, (h, w, 3)), 0, 255).astype(np.uint8)  # white noise
    sparse = (rng.random((h, w, 3)) < 0.01).astype(np.uint8) * 2  # rare single counts
    # a 2-pixel (Bayer) and a 4-pixel pattern, differing at the block edges' phase as often as
    # anywhere: rare columns of lit pixels at odd columns / every 4th column
    bayer = np.zeros((h, w, 3), np.uint8)
    lit = rng.random((h, w // 2)) < 0.05
    bayer[:, 1::2][lit] = 3
    four = np.zeros((h, w, 3), np.uint8)
    lit = rng.random((h, w // 4)) < 0.05
    four[:, 3::4][lit] = 3
    gen = load_independent_generator()
    spots = gen.make_frame(gen.SpotFrameSpec(width_px=1920, height_px=1080, bits=8, focal_px=1250.0),
                           np.random.default_rng(3)).image
    for name, img in (("dense", dense), ("sparse", sparse), ("bayer", bayer), ("four", four),
                      ("independent 8-bit", spots)):
        assert codec_block_step(block_sum(img, 1, exact=False), 1) == 0.0, name


def _jpeg(img_rgb: np.ndarray, quality: int) -> np.ndarray:
    ok, buf = cv2.imencode(".jpg", img_rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)[..., ::-1].copy()


@pytest.mark.parametrize(("seed", "quality"), [(0, 75), (2, 75), (0, 80), (1, 80), (2, 80), (3, 80),
                                               (0, 90), (1, 90)])
def test_every_beacon_of_a_jpeg_frame_is_found_and_nothing_else(seed: int, quality: int) -> None:
    """An 8-bit frame with 1.7 DN of noise (full well 2,000 e), sigma 1-2.5 px spots of 3,000-30,000 e,
    saved as JPEG: the 13 beacons are found and identified, and no block artefact is a detection
    (before: 30-40 extra detections at quality 75, 140-160 at 80, 50-70 at 90)."""
    gen = load_independent_generator()
    spec = gen.SpotFrameSpec(width_px=1920, height_px=1080, bits=8, full_well_e=2000.0, focal_px=1250.0,
                             sigma_px=(1.0, 2.5))
    truth = gen.make_frame(spec, np.random.default_rng(seed))
    image = _jpeg(truth.image, quality)
    res = detect_frame(Frame(image, CameraModel(1920, 1080, truth.K), 0), "cog", DeckLayout())
    assert res.ok, res.reason
    pts, ids = res.detections.points_px, res.detections.beacon_ids
    assert len(pts) == len(truth.beacon_id)  # nothing but the beacons
    # each beacon where it was drawn: the codec moves a spot's centroid by tenths of a pixel (its
    # quantised DCT terms), far less than the spacing of the beacons, so 1.5 px tells them apart
    for i, b in enumerate(ids):
        true_px = truth.centre_px[list(truth.beacon_id).index(b)]
        assert np.hypot(*(pts[i] - true_px)) < 1.5, (b, pts[i], true_px)


def test_a_clean_frames_edges_on_the_grid_are_not_codec_blocks() -> None:
    """A noise-free 8-bit frame whose only steps are a scene's edges lying on the 8 px grid: a
    vertical step (one axis only) or a panel (two edges on each axis) is no codec (helper 46 found
    the step edge taken for one, and 11 of 12 spots lost)."""
    h, w = 1080, 1920
    step = np.full((h, w, 3), 10, np.uint8)
    step[:, 960:] = 40
    panel = np.full((h, w, 3), 10, np.uint8)
    panel[64:512, 64:512] = 40
    for name, img in (("step", step), ("panel", panel)):
        assert codec_block_step(block_sum(img, 1, exact=False), 1) == 0.0, name
    gen = load_independent_generator()
    spec = gen.SpotFrameSpec(width_px=1920, height_px=1080, bits=8, focal_px=1250.0, full_well_e=2000.0,
                             read_noise_e=0.0, background_e=0.0)
    truth = gen.make_frame(spec, np.random.default_rng(4))
    for name, img in (("step", step), ("panel", panel)):
        frame_img = np.clip(truth.image.astype(np.int32) + img - 10, 0, 255).astype(np.uint8)
        if name == "step":  # the step beside the ring, not under it
            frame_img = np.clip(truth.image.astype(np.int32) + np.where(np.arange(w) >= 1600, 30, 0)[None, :, None],
                                0, 255).astype(np.uint8)
        res = detect_frame(Frame(frame_img, CameraModel(1920, 1080, truth.K), 0), "cog", DeckLayout())
        found = res.detections.points_px
        assert len(found), (name, res.reason)
        dist = np.hypot(*(found[:, None, :] - truth.centre_px[None]).transpose(2, 0, 1))
        assert (dist.min(axis=0) < 1.5).all(), name  # every beacon found
