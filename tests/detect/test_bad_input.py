"""Bad frames fail one by one with a reason; the batch goes on."""

import shutil

import cv2
import numpy as np
import pytest
from deckpose.detect.run import detect_frames
from deckpose.detect.sources import open_dataset


@pytest.fixture()
def damaged(tiny_dataset, tmp_path):
    ds = tmp_path / "damaged"
    shutil.copytree(tiny_dataset, ds)
    imgs = sorted((ds / "images").iterdir())
    data = imgs[0].read_bytes()
    imgs[0].write_bytes(data[: len(data) // 2])  # truncated PNG
    H, W = cv2.imread(str(imgs[1]), cv2.IMREAD_UNCHANGED).shape[:2]
    cv2.imwrite(str(imgs[1]), np.zeros((H, W + 8, 3), np.uint16))  # wrong size
    cv2.imwrite(str(imgs[2]), np.full((H, W, 3), 65535, np.uint16))  # saturated
    return ds, imgs


def test_each_bad_frame_has_a_reason_and_the_rest_succeed(damaged):
    ds, _imgs = damaged
    dets, frames = detect_frames(open_dataset(ds), "cog")
    reasons = dict(zip(frames.frame_id, frames.reason))
    assert "truncated" in reasons[0]
    assert "but camera" in reasons[1]
    assert "saturated" in reasons[2]
    assert bool(frames.ok.iloc[3]), reasons[3]
    assert list(frames.n_detections[:3]) == [0, 0, 0]
    assert set(dets.frame_id) == {3}


def test_dark_missing_and_non_image_files(damaged):
    ds, imgs = damaged
    H, W = cv2.imread(str(imgs[3]), cv2.IMREAD_UNCHANGED).shape[:2]
    rng = np.random.default_rng(0)
    cv2.imwrite(str(imgs[0]), rng.integers(95, 106, (H, W, 3)).astype(np.uint16))  # all dark
    imgs[1].write_bytes(b"not a png at all")
    imgs[2].unlink()
    _, frames = detect_frames(open_dataset(ds), "gauss")
    r = list(frames.reason)
    assert "dark frame" in r[0]
    assert "cannot decode" in r[1]
    assert "does not exist" in r[2]
    assert bool(frames.ok.iloc[3])


def test_all_black_frame(tiny_dataset, tmp_path):
    ds = tmp_path / "black"
    shutil.copytree(tiny_dataset, ds)
    img = min((ds / "images").iterdir())
    H, W = cv2.imread(str(img), cv2.IMREAD_UNCHANGED).shape[:2]
    cv2.imwrite(str(img), np.zeros((H, W), np.uint8))
    _, frames = detect_frames(open_dataset(ds), "binary")
    assert not frames.ok.iloc[0] and "dark frame" in frames.reason.iloc[0]


def test_a_centre_outside_the_image_does_not_end_the_frame():
    # A peer detector's diverged fit put a centre outside the frame; the colour measure then
    # raised "negative dimensions" and ended the benchmark. It is now a NaN colour.
    from deckpose.detect import registry
    from deckpose.detect.colour import blob_rgb_flux
    from deckpose.detect.frame_detection import detect_frame
    from deckpose.detect.registry import Blobs

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.records import Frame

    img = np.zeros((40, 60, 3), np.uint8)
    img[20, 30] = 200
    flux = blob_rgb_flux(img, np.array([[30.0, 20.0], [-500.0, 20.0], [np.nan, 1.0]]),
                         np.array([2.0, 2.0, 2.0]))
    assert np.all(np.isfinite(flux[0])) and np.isnan(flux[1:]).all()

    @registry.register("test-outside")
    def outside(frame, options):
        pts = np.array([[30.0, 20.0], [-500.0, 9000.0]])
        return Blobs(pts, np.stack([np.eye(2)] * 2), [1.0, 1.0], [1.0, 1.0], [1.0, 1.0])

    try:
        cam = preset("8mp").with_size(60, 40)
        fd = detect_frame(Frame(img, cam), "test-outside", DeckLayout())
        assert not fd.ok and "identification" in fd.reason
    finally:
        registry.unregister("test-outside")
