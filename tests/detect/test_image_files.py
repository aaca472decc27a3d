"""``deckpose detect`` on image files written by other tools (Pillow, imageio), not by deckpose.

One frame of the independent spot generator (``benchmarks/independent_spots.py``), saved the
ways a user's tools save it: 8-bit PNG (the reference), with an alpha channel, as WebP, as a
16-bit TIFF, as a JPEG whose pixels are stored turned 180 degrees with an EXIF tag that turns
them back, and as grey stored in RGB. Every form that keeps the pixels gives the reference's
centres; the JPEG is judged against the truth with the JPEG's own error allowed; a grey image
says why its bow cannot be found.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.sources import IMAGE_SUFFIXES

from deckpose.camera import CameraModel
from deckpose.camera_info import write_camera_info
from deckpose.cli import main

from .independent_generator import load_independent_generator

PIL = pytest.importorskip("PIL.Image")


@pytest.fixture(scope="module")
def frame(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, np.ndarray, Path]:
    """An 8-bit RGB frame (960x540), its true centres (M, 2) and its camera file."""
    gen = load_independent_generator()
    spec = gen.SpotFrameSpec(width_px=960, height_px=540, focal_px=625.0, bits=12, uneven=(0.6, 1.0),
                             flux_e=(8_000.0, 30_000.0), sigma_px=(1.0, 2.0), tilt_deg=2.0)
    fr = gen.make_frame(spec, np.random.default_rng(11))
    rgb8 = np.clip(np.round(fr.image * (255.0 / 4095.0)), 0, 255).astype(np.uint8)
    cam = tmp_path_factory.mktemp("cam") / "cam.yaml"
    write_camera_info(CameraModel(960, 540, fr.K), cam)
    return rgb8, np.asarray(fr.centre_px, float), cam


def _detect(folder: Path, cam: Path, tmp: Path) -> tuple[pd.DataFrame, pd.Series]:
    out = tmp / f"out_{folder.name}"
    main(["detect", str(folder), "--camera", str(cam), "-o", str(out), "--no-progress", "-q"])
    det = pd.read_parquet(out / "detections.parquet")
    return det, pd.read_parquet(out / "detect_frames.parquet").iloc[0]


def _save(tmp: Path, name: str, write) -> Path:
    folder = tmp / name
    folder.mkdir()
    write(folder)
    return folder


def _by_id(det: pd.DataFrame) -> pd.DataFrame:
    return det[det["beacon_id"] >= 0].set_index("beacon_id").sort_index()[["u_px", "v_px"]]


def test_lossless_forms_of_other_tools_give_the_same_centres(frame, tmp_path: Path) -> None:
    rgb8, truth, cam = frame
    import imageio.v3 as iio

    ref_det, ref_row = _detect(_save(tmp_path, "png", lambda f: PIL.fromarray(rgb8).save(f / "a.png")),
                               cam, tmp_path)
    assert ref_row["ok"], ref_row["reason"]
    assert len(_by_id(ref_det)) == len(truth)
    forms = {
        "rgba_png": lambda f: PIL.fromarray(rgb8).convert("RGBA").save(f / "a.png"),
        "webp": lambda f: PIL.fromarray(rgb8).save(f / "a.webp", lossless=True),
        # the same light in 16 bits: x 257 maps 0..255 onto 0..65535, so the centres are the same
        "tiff16": lambda f: iio.imwrite(f / "a.tif", rgb8.astype(np.uint16) * 257),
    }
    for name, write in forms.items():
        det, row = _detect(_save(tmp_path, name, write), cam, tmp_path)
        assert row["ok"], (name, row["reason"])
        np.testing.assert_allclose(_by_id(det).to_numpy(), _by_id(ref_det).to_numpy(), atol=1e-6,
                                   err_msg=name)


def test_an_exif_turned_jpeg_is_read_as_it_is_shown(frame, tmp_path: Path) -> None:
    """Pixels stored upside down with EXIF orientation 3: the centres are those of the upright image.

    Read without the tag, every centre would be ``(W - 1 - u, H - 1 - v)``: hundreds of pixels off.
    The JPEG (quality 95) moves a centre by a few hundredths of a pixel; 0.5 px is far above
    that and far below the turned image's error.
    """
    rgb8, truth, cam = frame

    def write(f: Path) -> None:
        im = PIL.fromarray(np.ascontiguousarray(rgb8[::-1, ::-1]))
        exif = im.getexif()
        exif[0x0112] = 3  # Orientation: rotate 180
        im.save(f / "a.jpg", quality=95, exif=exif)

    det, row = _detect(_save(tmp_path, "exif", write), cam, tmp_path)
    assert row["ok"], row["reason"]
    pts = det[["u_px", "v_px"]].to_numpy()
    nearest = np.linalg.norm(pts[:, None, :] - truth[None, :, :], axis=2).min(axis=0)
    assert nearest.max() < 0.5, nearest


def test_a_grey_image_stored_as_colour_says_it_is_grey(frame, tmp_path: Path) -> None:
    rgb8, truth, cam = frame
    for name, mode in (("grey_rgb", "RGB"), ("grey_alpha", "LA")):
        folder = _save(tmp_path, name, lambda f, m=mode: PIL.fromarray(rgb8).convert("L").convert(m).save(f / "a.png"))
        det, row = _detect(folder, cam, tmp_path)
        assert not row["ok"]
        assert "grey image" in row["reason"], (name, row["reason"])
        assert len(det) == len(truth)  # every beacon is still found, only the ids are missing


def test_webp_is_among_the_image_suffixes() -> None:
    assert ".webp" in IMAGE_SUFFIXES


def test_hidden_files_and_subfolders_are_no_frames(frame, tmp_path: Path) -> None:
    # a '.x.png' (an editor's or a copy's temporary, macOS's '._' files) had been read as a frame
    rgb8, _, cam = frame

    def write(folder: Path) -> None:
        PIL.fromarray(rgb8).save(folder / "a.png")
        (folder / ".a.png").write_bytes(b"\0\0")  # not an image at all
        (folder / "._b.png").write_bytes(b"Mac OS X resource fork")
        (folder / "sub.png").mkdir()

    folder = _save(tmp_path, "hidden", write)
    out = tmp_path / "out_hidden"
    assert main(["detect", str(folder), "--camera", str(cam), "-o", str(out), "--no-progress", "-q"]) == 0
    frames = pd.read_parquet(out / "detect_frames.parquet")
    assert len(frames) == 1 and bool(frames["ok"].iloc[0])
