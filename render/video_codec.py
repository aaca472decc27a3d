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
libvpx's VP9. H.264 itself is not offered: OpenCV's wheels carry no software H.264
encoder (``avc1``, ``H264`` and ``X264`` fail to open here; FFmpeg tries only the
hardware ``h264_v4l2m2m``), and PyAV or an ``ffmpeg`` binary would be a new dependency.
Both codecs code 8-bit YUV 4:2:0 (chroma at half resolution in each direction), as a
camera's H.264 stream does. A mono frame is coded as grey (its luma) and read back as luma.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from deckpose.render.sensor_config import VideoCodec, VideoSpec
from numpy.typing import NDArray

__all__ = ["CONTAINER", "FOURCC", "video_round_trip"]

#: OpenCV's FOURCC of each codec (the tag FFmpeg's MP4 muxer takes without a warning).
FOURCC: dict[VideoCodec, str] = {VideoCodec.MP4V: "mp4v", VideoCodec.VP9: "vp09"}
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
        number of frames.
    """
    if not frames:
        return []
    shape = frames[0].shape
    if any(f.shape != shape or f.dtype != np.uint8 for f in frames):
        raise ValueError(f"video_round_trip: frames must all be uint8 of shape {shape}")
    if not fps > 0:
        raise ValueError(f"video_round_trip: fps must be positive, got {fps}")
    h, w = shape[:2]
    mono = len(shape) == 2
    params = [cv2.VIDEOWRITER_PROP_BITRATE, round(spec.bitrate_kbps * 1000),
              cv2.VIDEOWRITER_PROP_GOP_SIZE, spec.gop_frames]
    with tempfile.TemporaryDirectory(prefix="deckpose-video-") as tmp:
        path = str(Path(tmp) / f"stream{CONTAINER}")
        writer = cv2.VideoWriter(path, cv2.CAP_FFMPEG, cv2.VideoWriter.fourcc(*FOURCC[spec.codec]), float(fps),
                                 (w, h), params)
        if not writer.isOpened():
            raise RuntimeError(f"video_round_trip: OpenCV's FFmpeg cannot encode {spec.codec.value} at {w}x{h} "
                               f"(odd sizes and some codecs are refused); choose another sensor.video.codec")
        try:
            for f in frames:
                writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR if mono else cv2.COLOR_RGB2BGR))
        finally:
            writer.release()
        cap = cv2.VideoCapture(path, cv2.CAP_FFMPEG)
        out: list[NDArray[np.uint8]] = []
        try:
            while True:
                ok, bgr = cap.read()
                if not ok:
                    break
                conv = cv2.COLOR_BGR2GRAY if mono else cv2.COLOR_BGR2RGB
                out.append(np.ascontiguousarray(cv2.cvtColor(bgr, conv), np.uint8))
        finally:
            cap.release()
    if len(out) != len(frames):
        raise RuntimeError(f"video_round_trip: {len(frames)} frames encoded, {len(out)} decoded")
    return out
