"""Frames stored as Zstandard arrays (``image_format: zstd``): the same pixels, tables and detections as PNG."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.run import detect_frames
from deckpose.detect.sources import open_dataset, read_image
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset

from deckpose.errors import ConfigError, InputDataError
from deckpose.image_store import ImageFormat, decode_image, encode_image

from .conftest import tiny_doc


@pytest.mark.parametrize("shape, dtype", [((7, 5), np.uint8), ((6, 4, 3), np.uint16), ((1, 1, 3), np.uint8)])
def test_a_zst_frame_round_trips_bit_for_bit(shape, dtype):
    rng = np.random.default_rng(1)
    img = rng.integers(0, np.iinfo(dtype).max, shape, dtype=dtype, endpoint=True)
    data = encode_image(img, ImageFormat.ZSTD)
    back = decode_image(data)
    assert back.dtype == dtype and back.shape == shape and np.array_equal(back, img)
    # independently of our reader: the header, then a Zstandard frame of the C-order pixels
    import zstandard

    ndim = data[6]
    assert data[:4] == b"DKPZ" and ndim == len(shape)
    raw = zstandard.ZstdDecompressor().decompress(data[8 + 4 * ndim:])
    assert np.array_equal(np.frombuffer(raw, dtype).reshape(shape), img)


def test_damaged_frames_are_one_line_errors(tmp_path):
    data = encode_image(np.zeros((4, 4), np.uint8), ImageFormat.ZSTD)
    with pytest.raises(InputDataError, match="damaged .zst frame"):
        decode_image(data[:-3], "x.zst")
    bad = tmp_path / "000000.zst"
    bad.write_bytes(data[:12])
    msg = read_image(bad)
    assert isinstance(msg, str) and "000000.zst" in msg and "\n" not in msg
    with pytest.raises(ConfigError, match="image_format.*not one of"):
        config_from_dict(tiny_doc(image_format="jpeg"))


@pytest.fixture(scope="module")
def both_formats(tmp_path_factory, egl_renderer_factory):
    egl_renderer_factory(config_from_dict(tiny_doc()))
    root = tmp_path_factory.mktemp("formats")
    png = render_dataset(config_from_dict(tiny_doc()), root / "png", workers=0, progress=False)
    zst = render_dataset(config_from_dict(tiny_doc(image_format="zstd")), root / "zst", workers=0, progress=False)
    return png, zst


def test_zstd_frames_hold_the_png_frames_pixels(both_formats):
    png, zst = both_formats
    fp, fz = pd.read_parquet(png / "frames.parquet"), pd.read_parquet(zst / "frames.parquet")
    assert all(p.endswith(".png") for p in fp.image) and all(p.endswith(".zst") for p in fz.image)
    pd.testing.assert_frame_equal(fp.drop(columns="image"), fz.drop(columns="image"))
    pd.testing.assert_frame_equal(pd.read_parquet(png / "beacons.parquet"), pd.read_parquet(zst / "beacons.parquet"))
    for a, b in zip(fp.image, fz.image):
        ia, ib = read_image(png / a), read_image(zst / b)
        assert isinstance(ia, np.ndarray) and isinstance(ib, np.ndarray)
        assert np.array_equal(ia, ib)
        assert (png / a.replace("images", "previews")).read_bytes() == (zst / a.replace("images", "previews")).read_bytes()


def test_detections_on_zstd_frames_are_those_on_png(both_formats):
    png, zst = both_formats
    dp, _ = detect_frames(open_dataset(png), "cog")
    dz, _ = detect_frames(open_dataset(zst), "cog")
    pd.testing.assert_frame_equal(dp, dz)


def test_a_zstd_run_exports_png_images(both_formats, tmp_path):
    from deckpose.cli import main

    png, zst = both_formats
    assert main(["export", str(zst), "--format", "coco", "-o", str(tmp_path / "coco"), "--no-progress"]) == 0
    out = sorted((tmp_path / "coco" / "images").iterdir())
    frames = pd.read_parquet(png / "frames.parquet")
    assert [p.name for p in out] == [f"{f:06d}.png" for f in frames.frame_id]
    for p, rel in zip(out, frames.image):
        assert not p.is_symlink()  # converted, not linked
        a, b = read_image(p), read_image(png / rel)
        assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)
