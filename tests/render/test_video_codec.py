"""Video compression of a run's frames (``sensor.video``): a real codec, in time order, truth unchanged."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.run import detect_run
from deckpose.render.config import config_from_dict, config_to_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.render_detection import RenderDetection
from deckpose.render.sensor_config import VideoCodec, VideoSpec
from deckpose.render.video_codec import video_round_trip, write_h264
from scipy.spatial import cKDTree

from deckpose.errors import ConfigError
from deckpose.image_store import decode_image

from .conftest import tiny_doc


def _frames(n: int = 6, shape: tuple[int, ...] = (240, 320, 3), seed: int = 0) -> list[np.ndarray]:
    """A textured scene panning 2 px a frame, with a little pixel noise (what a camera streams)."""
    rng = np.random.default_rng(seed)
    small = rng.uniform(30, 220, (shape[0] // 8 + 1, shape[1] // 8 + 12, *shape[2:]))
    big = np.repeat(np.repeat(small, 8, axis=0), 8, axis=1)
    out = []
    for k in range(n):
        f = big[:shape[0], 2 * k:2 * k + shape[1]] + rng.normal(0, 2, shape)
        out.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    return out


def _psnr_db(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(float) - b.astype(float)) ** 2))
    return 10 * math.log10(255.0 ** 2 / mse)


@pytest.mark.parametrize("codec", [VideoCodec.MP4V, VideoCodec.VP9, VideoCodec.H264])
def test_round_trip_is_deterministic_and_bounded(codec: VideoCodec) -> None:
    frames = _frames()
    spec = VideoSpec(codec=codec, bitrate_kbps=4000.0, gop_frames=12)
    a = video_round_trip(frames, 10.0, spec)
    b = video_round_trip(frames, 10.0, spec)
    assert len(a) == len(frames) and all(x.shape == f.shape and x.dtype == np.uint8 for x, f in zip(a, frames))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))  # the same stream, bit for bit
    # 4 Mbit/s at 10 Hz is 50 kB a frame for 230 kB of pixels: a lossy stream at an ordinary
    # rate, whose PSNR lies in lossy video's usual 30-45 dB (below 30 dB artefacts are plain);
    # and lossy: not the frames themselves
    for x, f in zip(a, frames):
        assert 30.0 < _psnr_db(x, f) < 60.0
        assert not np.array_equal(x, f)


def test_a_lower_bitrate_costs_more_error() -> None:
    """80x fewer bits cost PSNR once rate control binds (after the first key frame, which the
    encoder codes at its initial quantiser either way; above a few Mbit/s at this size the
    stream stops improving: the encoder's finest quantiser and the colour conversion remain)."""
    frames = _frames(12)
    psnr = [[_psnr_db(x, f) for x, f in zip(video_round_trip(frames, 10.0, VideoSpec(bitrate_kbps=r)), frames)]
            for r in (50.0, 4000.0)]
    assert psnr[0][0] == psnr[1][0]  # the first key frame
    assert np.mean(psnr[0][1:]) < np.mean(psnr[1][1:]) - 1.0


def test_frames_between_key_frames_are_predicted_from_the_ones_before() -> None:
    """With key frames only (gop 1) a frame's coding ignores the others; with P-frames it does not."""
    a, b = _frames(2, seed=1), _frames(2, seed=2)
    last_a = a[1]
    a_then = [a[0], last_a]
    b_then = [b[0], last_a]  # the same last frame after another first frame
    for gop, same in ((1, True), (12, False)):
        spec = VideoSpec(bitrate_kbps=500.0, gop_frames=gop)
        x, y = video_round_trip(a_then, 10.0, spec)[1], video_round_trip(b_then, 10.0, spec)[1]
        assert np.array_equal(x, y) is same, gop


def _panning(n: int, shape: tuple[int, int, int] = (240, 320, 3)) -> list[np.ndarray]:
    """``n`` frames of a textured scene panning 2 px a frame (the scene wide enough for all of them)."""
    rng = np.random.default_rng(5)
    small = rng.uniform(30, 220, (shape[0] // 8 + 1, shape[1] // 8 + n, shape[2]))
    big = np.repeat(np.repeat(small, 8, axis=0), 8, axis=1)
    return [np.clip(np.rint(big[:shape[0], 2 * k:2 * k + shape[1]] + rng.normal(0, 2, shape)), 0, 255)
            .astype(np.uint8) for k in range(n)]


def test_h264_is_h264_with_its_key_frames_and_rate(tmp_path: Path) -> None:
    """The ``h264`` stream, read by another decoder: OpenCV's FFmpeg names it H.264 and decodes it
    to the frames video_round_trip returns (PyAV's decode), key frames are exactly every
    ``gop_frames`` frames, and its average bitrate follows ``bitrate_kbps`` where rate control
    binds (x264's average-bitrate mode over a 3 s stream: within 25 %, and twice the rate about
    twice the bytes)."""
    av = pytest.importorskip("av")
    import cv2

    frames = _panning(30)
    payload = {}
    for kbps in (500.0, 1000.0):
        spec = VideoSpec(codec=VideoCodec.H264, bitrate_kbps=kbps, gop_frames=12)
        path = tmp_path / f"s{kbps:.0f}.mp4"
        write_h264(frames, 10.0, spec, path)
        with av.open(str(path)) as c:
            packets = [(pk.is_keyframe, pk.size) for pk in c.demux(video=0) if pk.size]
        assert [k for k, (key, _) in enumerate(packets) if key] == [0, 12, 24]
        payload[kbps] = sum(size for _, size in packets) * 8 / 3.0 / 1000  # kbit/s over 3 s
        assert 0.8 * kbps < payload[kbps] < 1.25 * kbps
        cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        try:
            assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little") in (b"h264", b"avc1")
            by_opencv = []
            while True:
                ok, bgr = cap.read()
                if not ok:
                    break
                by_opencv.append(bgr[..., ::-1])
        finally:
            cap.release()
        ours = video_round_trip(frames, 10.0, spec)
        assert len(by_opencv) == len(ours) == len(frames)
        for x, y in zip(by_opencv, ours):
            np.testing.assert_array_equal(x, y)
    assert 1.6 < payload[1000.0] / payload[500.0] < 2.4


def test_h264_without_pyav_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "av", None)  # import av raises ImportError
    with pytest.raises(RuntimeError, match=r"pip install 'deckpose\[video\]'"):
        video_round_trip(_frames(2), 10.0, VideoSpec(codec=VideoCodec.H264))


def test_an_h264_config_without_pyav_is_refused_at_the_edge(monkeypatch: pytest.MonkeyPatch) -> None:
    """The config, not the render's end, says that ``h264`` needs PyAV (one line, with the fix)."""
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a, **k: None if name == "av" else find_spec(name, *a, **k))
    with pytest.raises(ConfigError, match=r"codec h264 needs PyAV.*pip install 'deckpose\[video\]'"):
        config_from_dict(_doc({"codec": "h264"}))
    config_from_dict(_doc({"codec": "mp4v"}))  # the other codecs need nothing more


def test_h264_needs_an_even_size() -> None:
    pytest.importorskip("av")
    with pytest.raises(RuntimeError, match="even width and height"):
        video_round_trip([np.zeros((241, 320, 3), np.uint8)] * 2, 10.0, VideoSpec(codec=VideoCodec.H264))


@pytest.mark.parametrize("codec", [c.value for c in VideoCodec])
def test_a_video_config_with_an_odd_camera_size_is_refused_at_the_edge(codec: str) -> None:
    """Every codec is 4:2:0: an odd size is refused by the config, in one line naming the camera."""
    doc = {**_doc({"codec": codec}), "cameras": [{"preset": "4mp", "size": [641, 480], "name": "odd"}]}
    with pytest.raises(ConfigError, match=r"even image width and height.*odd 641x480"):
        config_from_dict(doc)
    config_from_dict({**doc, "cameras": [{"preset": "4mp", "size": [642, 480]}]})


@pytest.mark.parametrize("codec", [VideoCodec.MP4V, VideoCodec.VP9])
def test_opencv_codecs_do_not_hand_back_cropped_frames(codec: VideoCodec) -> None:
    """OpenCV's writers drop an odd row and column; the round trip says so rather than return them."""
    with pytest.raises(RuntimeError, match="not 321x241"):
        video_round_trip([np.zeros((241, 321, 3), np.uint8)] * 2, 10.0, VideoSpec(codec=codec))


def test_mono_frames_come_back_mono() -> None:
    frames = [f[..., 1] for f in _frames()]
    out = video_round_trip(frames, 10.0, VideoSpec())
    assert all(x.shape == f.shape for x, f in zip(out, frames))
    assert all(_psnr_db(x, f) > 30.0 for x, f in zip(out, frames))


# an easy night: 640x480, nadir at 25 m, the deck drifting 2 m along x over the sequence
_DOC = tiny_doc(cameras=[{"preset": "4mp", "size": [640, 480]}], heights_m=[25.0], lighting=["night"],
                motion={"source": "fixed", "dt_s": 0.1,
                        "attitudes_deg": [[0, 0, 0, 0, 0.5 * k, 0] for k in range(5)]})


def _doc(video: dict[str, object] | None) -> dict[str, object]:
    sensor = {"bit_depth": 8, "read_noise_e": 5, **({"video": video} if video else {})}
    return {**_DOC, "sensor": sensor}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, egl_renderer_factory) -> tuple[Path, Path]:
    plain_cfg = config_from_dict(_doc(None))
    egl_renderer_factory(plain_cfg)  # this process's GL platform
    root = tmp_path_factory.mktemp("video")
    plain = render_dataset(plain_cfg, root / "plain", workers=0, progress=False)
    video = render_dataset(config_from_dict(_doc({"codec": "mp4v", "bitrate_kbps": 3000, "gop_frames": 12})),
                           root / "video", workers=0, progress=False)
    return plain, video


def test_dataset_frames_are_the_sequence_through_the_codec_and_truth_is_unchanged(runs: tuple[Path, Path]) -> None:
    plain, video = runs
    for table in ("frames.parquet", "beacons.parquet", "lights.parquet"):
        pd.testing.assert_frame_equal(pd.read_parquet(plain / table), pd.read_parquet(video / table))
    frames = pd.read_parquet(plain / "frames.parquet").sort_values("t_s")
    raw = [decode_image((plain / rel).read_bytes())[..., ::-1] for rel in frames["image"]]
    want = video_round_trip(raw, 10.0, VideoSpec(bitrate_kbps=3000.0, gop_frames=12))  # 0.1 s apart
    for rel, w in zip(frames["image"], want):
        np.testing.assert_array_equal(decode_image((video / rel).read_bytes())[..., ::-1], w)
    block = json.loads((video / "manifest.json").read_text())["sensor"]["video"]
    assert (block["codec"], block["bitrate_kbps"], block["gop_frames"]) == ("mp4v", 3000.0, 12)


def test_beacons_are_still_detected_through_the_codec(runs: tuple[Path, Path]) -> None:
    """On the easy night frames every visible beacon is found within 0.5 px through the codec,
    as without it (a detection further than 0.5 px from every beacon would be a false one)."""
    for out in runs:
        _assert_every_beacon_found(out)


def _assert_every_beacon_found(out: Path) -> None:
    """``cog`` on run ``out`` finds every visible beacon of every frame within 0.5 px."""
    detect_run(out, "cog")
    det = pd.read_parquet(out / "detections" / "cog.parquet")
    truth = pd.read_parquet(out / "beacons.parquet")
    for fid, t in truth[truth["visible"]].groupby("frame_id"):
        d = det[det["frame_id"] == fid]
        dist, _ = cKDTree(d[["u_px", "v_px"]].to_numpy()).query(t[["u_px", "v_px"]].to_numpy())
        assert len(t) >= 10 and np.all(dist < 0.5), (out.name, fid, dist.max())


def test_an_h264_run_stores_the_sequence_through_h264(runs: tuple[Path, Path], tmp_path: Path) -> None:
    """``codec: h264`` in a run: the stored frames are the rendered sequence through H.264, the
    manifest names libx264, the truth is the plain run's, and every visible beacon is still
    found within 0.5 px."""
    pytest.importorskip("av")
    plain, _ = runs
    out = render_dataset(config_from_dict(_doc({"codec": "h264", "bitrate_kbps": 3000, "gop_frames": 12})),
                         tmp_path / "h264", workers=0, progress=False)
    pd.testing.assert_frame_equal(pd.read_parquet(plain / "beacons.parquet"), pd.read_parquet(out / "beacons.parquet"))
    frames = pd.read_parquet(plain / "frames.parquet").sort_values("t_s")
    raw = [decode_image((plain / rel).read_bytes())[..., ::-1] for rel in frames["image"]]
    want = video_round_trip(raw, 10.0, VideoSpec(codec=VideoCodec.H264, bitrate_kbps=3000.0, gop_frames=12))
    for rel, w in zip(frames["image"], want):
        np.testing.assert_array_equal(decode_image((out / rel).read_bytes())[..., ::-1], w)
    assert "libx264" in json.loads((out / "manifest.json").read_text())["sensor"]["video"]["encoder"]
    _assert_every_beacon_found(out)


def test_resume_does_not_compress_twice(runs: tuple[Path, Path]) -> None:
    _, video = runs
    frames = pd.read_parquet(video / "frames.parquet")
    before = [(video / rel).read_bytes() for rel in frames["image"]]
    cfg = config_from_dict(_doc({"codec": "mp4v", "bitrate_kbps": 3000, "gop_frames": 12}))
    render_dataset(cfg, video, workers=0, progress=False, resume=True)
    assert [(video / rel).read_bytes() for rel in frames["image"]] == before


def test_video_is_off_by_default_and_checked() -> None:
    cfg = config_from_dict(_doc(None))
    assert cfg.sensor.video is None and "video" not in config_to_dict(cfg)["sensor"]
    on = config_from_dict(_doc({"codec": "vp9", "bitrate_kbps": 800}))
    assert config_from_dict(config_to_dict(on)) == on
    for bad, key in (({"bitrate_kbps": 1}, "sensor.video.bitrate_kbps"), ({"codec": "h265"}, "sensor.video.codec")):
        with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
            config_from_dict(_doc(bad))
    with pytest.raises(ConfigError, match="8-bit"):
        config_from_dict({**_DOC, "sensor": {"bit_depth": 12, "video": {}}})
    with pytest.raises(ConfigError, match="deckpose detect"):
        render_dataset(on, "/nonexistent/never-written", workers=0, progress=False,
                       detection=RenderDetection(("cog",)))
