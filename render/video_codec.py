"""Video compression: a run's frames encoded as one stream per time sequence and decoded back.

A camera that streams video (an IP camera, a drone's downlink) does not compress each
frame alone: a key frame every ``gop_frames`` frames, and between them frames predicted
from the one before (motion compensation) with the residual coded at whatever bits the
bitrate leaves. So a frame's error depends on the frames before it, and a beacon that
moves or flickers costs bits a static deck does not. ``sensor.video`` passes each time
sequence of a run (:func:`deckpose.render.exposure_control.time_sequences`) through a real
encoder, FFmpeg's as OpenCV's ``VideoWriter`` ships it, at the sequence's frame rate, and
stores the decoded frames (:func:`video_round_trip`); the truth is unchanged.

Codecs (:class:`~deckpose.render.sensor_config.VideoCodec`): ``mp4v`` is MPEG-4 Part 2
(FFmpeg's ``mpeg4``: 8x8 DCT, half-pel motion compensation, I and P frames), ``vp9`` is
libvpx's VP9, both through OpenCV's ``VideoWriter``; ``h264`` is H.264 by libx264 through
PyAV (:func:`write_h264`; the optional ``video`` extra), because OpenCV's wheels carry no
software H.264 encoder (``avc1``, ``H264`` and ``X264`` fail to open here; FFmpeg tries only
the hardware ``h264_v4l2m2m``). The H.264 stream is what a drone's downlink sends: the
``veryfast`` preset, no B-frames and no look-ahead (``zerolatency``: a frame leaves the
encoder before the next one is captured), a key frame every ``gop_frames`` frames and
nowhere else (no scene-cut key frames), average-bitrate rate control at ``bitrate_kbps``,
one encoder thread (the stream is the same bit for bit on every machine and worker count).
Every codec codes 8-bit YUV 4:2:0 (chroma at half resolution in each direction), as a
camera's H.264 stream does. A mono frame is coded as grey (its luma) and read back as luma.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
from deckpose.render.sensor_config import H264_NEEDS_PYAV, VideoCodec, VideoSpec
from numpy.typing import NDArray

__all__ = ["CONTAINER", "FOURCC", "H264_OPTIONS", "encoder_description", "video_round_trip", "write_h264"]

#: OpenCV's FOURCC of each codec it encodes (the tag FFmpeg's MP4 muxer takes without a warning).
FOURCC: dict[VideoCodec, str] = {VideoCodec.MP4V: "mp4v", VideoCodec.VP9: "vp09"}
#: libx264's settings for ``h264`` besides the bitrate and key-frame interval (see the module docstring).
H264_OPTIONS: dict[str, str] = {"preset": "veryfast", "tune": "zerolatency", "threads": "1"}
#: The container the stream is written to (a temporary file).
CONTAINER = ".mp4"


def video_round_trip(frames: Sequence[NDArray[np.uint8]], fps: float, spec: VideoSpec
                     ) -> list[NDArray[np.uint8]]:
    """The frames of one time sequence after encoding as a video stream and decoding.

    Parameters
    ----------
    frames : sequence of (H, W, 3) RGB or (H, W) mono arrays of uint8
        The sequence in time order, all of one shape.
    fps : float
        Frames per second of the stream (the bitrate is spread over them), > 0.
    spec : VideoSpec
        Codec, bitrate (kbit/s) and key-frame interval.

    Returns
    -------
    list of arrays of uint8, the shapes of ``frames``

    Raises
    ------
    RuntimeError
        OpenCV's FFmpeg cannot open the encoder, or the stream decodes to another
        number of frames or another size (an odd width or height).
    """
    if not frames:
        return []
    shape = frames[0].shape
    if any(f.shape != shape or f.dtype != np.uint8 for f in frames):
        raise ValueError(f"video_round_trip: frames must all be uint8 of shape {shape}")
    if not fps > 0:
        raise ValueError(f"video_round_trip: fps must be positive, got {fps}")
    mono = len(shape) == 2
    with tempfile.TemporaryDirectory(prefix="deckpose-video-") as tmp:
        path = Path(tmp) / f"stream{CONTAINER}"
        if spec.codec is VideoCodec.H264:
            write_h264(frames, fps, spec, path)
            out = _read_pyav(path, mono)
        else:
            _write_opencv(frames, fps, spec, path)
            out = _read_opencv(path, mono)
    if len(out) != len(frames):
        raise RuntimeError(f"video_round_trip: {len(frames)} frames encoded, {len(out)} decoded")
    if out[0].shape != shape:  # OpenCV's writers drop an odd row and column without a word
        raise RuntimeError(f"video_round_trip: {spec.codec.value} gave back frames of {out[0].shape[1]}x"
                           f"{out[0].shape[0]}, not {shape[1]}x{shape[0]}; use an even image size")
    return out


def _write_opencv(frames: Sequence[NDArray[np.uint8]], fps: float, spec: VideoSpec, path: Path) -> None:
    """Encode one time sequence with OpenCV's FFmpeg writer (``mp4v``, ``vp9``) into ``path``."""
    h, w = frames[0].shape[:2]
    mono = frames[0].ndim == 2
    params = [cv2.VIDEOWRITER_PROP_BITRATE, round(spec.bitrate_kbps * 1000),
              cv2.VIDEOWRITER_PROP_GOP_SIZE, spec.gop_frames]
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter.fourcc(*FOURCC[spec.codec]), float(fps),
                             (w, h), params)
    if not writer.isOpened():
        raise RuntimeError(f"video_round_trip: OpenCV's FFmpeg cannot encode {spec.codec.value} at {w}x{h} "
                           f"(odd sizes and some codecs are refused); choose another sensor.video.codec")
    try:
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR if mono else cv2.COLOR_RGB2BGR))
    finally:
        writer.release()


def _read_opencv(path: Path, mono: bool) -> list[NDArray[np.uint8]]:
    """The frames of a video file, decoded by OpenCV's FFmpeg, as RGB or grey arrays of uint8."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    conv = cv2.COLOR_BGR2GRAY if mono else cv2.COLOR_BGR2RGB
    out: list[NDArray[np.uint8]] = []
    try:
        while True:
            ok, bgr = cap.read()
            if not ok:
                break
            out.append(np.ascontiguousarray(cv2.cvtColor(bgr, conv), np.uint8))
    finally:
        cap.release()
    return out

def _pyav():
    """PyAV, or a one-line error that says how to install it."""
    try:
        import av
    except ImportError:
        raise RuntimeError(f"sensor.video.{H264_NEEDS_PYAV}") from None
    return av


def encoder_description(codec: VideoCodec) -> str:
    """The encoder of ``codec`` as the run's manifest records it (library, version, settings)."""
    if codec is VideoCodec.H264:
        av = _pyav()
        opts = ", ".join(f"{k}={v}" for k, v in H264_OPTIONS.items())
        return (f"PyAV {av.__version__} libx264 ({opts}, keyint=min-keyint=gop_frames, scenecut=0, "
                f"average bitrate), {CONTAINER} container, YUV 4:2:0")
    return f"OpenCV {cv2.__version__} VideoWriter (FFmpeg), FOURCC {FOURCC[codec]!r}, {CONTAINER} container, YUV 4:2:0"


def write_h264(frames: Sequence[NDArray[np.uint8]], fps: float, spec: VideoSpec, path: Path) -> None:
    """Encode one time sequence as an H.264 stream (libx264 through PyAV) into an MP4 file.

    Parameters
    ----------
    frames : sequence of (H, W, 3) RGB or (H, W) mono arrays of uint8
        The sequence in time order, all of one shape; ``H`` and ``W`` even (4:2:0 chroma).
    fps : float
        Frames per second of the stream, > 0.
    spec : VideoSpec
        ``bitrate_kbps`` (average bitrate) and ``gop_frames`` (the key-frame interval).
    path : Path
        The ``.mp4`` file to write.
    """
    av = _pyav()
    h, w = frames[0].shape[:2]
    if h % 2 or w % 2:
        raise RuntimeError(f"video_round_trip: H.264 in 4:2:0 needs an even width and height, got {w}x{h}; "
                           "choose an even image size or codec mp4v")
    mono = frames[0].ndim == 2
    rate = Fraction(fps).limit_denominator(1001)
    with av.open(str(path), "w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=rate)
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
        stream.bit_rate = round(spec.bitrate_kbps * 1000)
        stream.codec_context.gop_size = spec.gop_frames
        stream.options = dict(H264_OPTIONS, **{
            "x264-params": f"keyint={spec.gop_frames}:min-keyint={spec.gop_frames}:scenecut=0:bframes=0"})
        for k, f in enumerate(frames):
            vf = av.VideoFrame.from_ndarray(np.ascontiguousarray(f), format="gray" if mono else "rgb24")
            vf = vf.reformat(format="yuv420p")
            vf.pts = k
            vf.time_base = 1 / rate
            for packet in stream.encode(vf):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def _read_pyav(path: Path, mono: bool) -> list[NDArray[np.uint8]]:
    """The frames of a video file, decoded by PyAV, as RGB or grey arrays of uint8."""
    av = _pyav()
    with av.open(str(path)) as container:
        return [np.ascontiguousarray(fr.to_ndarray(format="gray" if mono else "rgb24"), np.uint8)
                for fr in container.decode(video=0)]
