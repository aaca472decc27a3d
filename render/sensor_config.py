"""The ``sensor:`` section of a render config: the sensor model and its effects."""

from __future__ import annotations

import enum
import importlib.util
from dataclasses import dataclass

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["H264_NEEDS_PYAV", "AutoExposureSpec", "BayerPattern", "SensorSpec", "VideoCodec", "VideoSpec",
           "sensor_spec"]

#: What a run asking for ``h264`` without PyAV is told (the config's check and the encoder's).
H264_NEEDS_PYAV = ("codec h264 needs PyAV (libx264): pip install 'deckpose[video]' "
                   "(scripts/bootstrap.sh installs it), or choose codec mp4v or vp9")


class BayerPattern(enum.Enum):
    """Colour filter array, named by its top-left 2x2 block read row by row (``none``: RGB per pixel)."""

    NONE = "none"
    RGGB = "rggb"
    BGGR = "bggr"
    GRBG = "grbg"
    GBRG = "gbrg"


@dataclass(frozen=True)
class AutoExposureSpec:
    """Auto-exposure (:mod:`deckpose.render.auto_exposure`): ``exposure`` chosen per frame.

    The noise-free background of the frame is metered: its mean in full-scale units
    (``percentile: null``) or that percentile of its values is brought to ``target``;
    the exposure (the unit of ``sensor.exposure``) is clamped to
    [``min_exposure``, ``max_exposure``].

    Across frames (:mod:`deckpose.render.exposure_control`), off by default: with
    ``time_constant_s`` > 0 or a ``max_step_stops``, the exposure of frame ``k`` of a time
    sequence comes from the meterings of the frames before it, through a first-order
    controller in log exposure of that time constant (0: the next frame takes the last
    metering at once), its change per frame limited to ``max_step_stops`` stops (null:
    no limit); the meterings are taken in a pre-pass on the scene rendered at
    ``metering_scale`` times the frame's width and height (1: the full frame).
    """

    target: float = 0.18
    percentile: float | None = None
    min_exposure: float = 0.05
    max_exposure: float = 50.0
    time_constant_s: float = 0.0
    max_step_stops: float | None = None
    metering_scale: float = 0.25

    @property
    def controlled(self) -> bool:
        """Whether the exposure follows the sequence (False: each frame meters itself)."""
        return self.time_constant_s > 0 or self.max_step_stops is not None


class VideoCodec(enum.Enum):
    """A video codec (:mod:`deckpose.render.video_codec`).

    ``mp4v``: MPEG-4 Part 2 through OpenCV's FFmpeg writer (motion-compensated P-frames,
    8x8 DCT); ``vp9``: libvpx's VP9 through the same writer (a codec of H.264's and HEVC's
    generation: larger transforms, more prediction modes; several times slower); ``h264``:
    H.264 by libx264 through PyAV (the optional ``video`` extra, ``pip install
    'deckpose[video]'``: OpenCV's wheels carry no software H.264 encoder), the codec of
    most drone downlinks and IP cameras.
    """

    MP4V = "mp4v"
    VP9 = "vp9"
    H264 = "h264"


@dataclass(frozen=True)
class VideoSpec:
    """A run's frames compressed as a video stream, in time order, and decoded back.

    ``codec`` (:class:`VideoCodec`), ``bitrate_kbps`` of the stream at the sequence's
    frame rate, ``gop_frames``: frames from one key frame to the next.
    """

    codec: VideoCodec = VideoCodec.MP4V
    bitrate_kbps: float = 4000.0
    gop_frames: int = 12


@dataclass(frozen=True)
class SensorSpec:
    """Sensor model applied after rendering (see :mod:`deckpose.render.sensor`).

    ``exposure`` scales scene radiance (1 = the raster's white fills the well);
    ``full_well_e`` electrons at saturation; ``read_noise_e`` electrons RMS;
    ``bit_depth`` 8, 12 or 16 (12 is stored in 16-bit PNG, values 0..4095);
    ``color`` ``rgb`` or ``mono``; ``noise: false`` gives the noise-free image.
    Sensor effects, off by default: ``bayer`` (:class:`BayerPattern`), ``jpeg_quality``,
    the fixed pattern ``prnu`` / ``dsnu_e`` / ``hot_pixel_fraction`` / ``hot_pixel_e``,
    ``auto_exposure`` (:class:`AutoExposureSpec`) and ``video`` (:class:`VideoSpec`);
    the README's "Sensor effects" says what each models.
    """

    bit_depth: int = 8
    exposure: float = 1.0
    full_well_e: float = 20000.0
    read_noise_e: float = 5.0
    noise: bool = True
    color: str = "rgb"
    psf_sigma_px: float = 0.8
    beacon_peak: float = 6.0
    halo_fraction: float = 0.05
    halo_scale: float = 4.0
    # issue 23 item 4, all off by default (render/bayer.py, compression.py, fixed_pattern.py, auto_exposure.py)
    bayer: BayerPattern = BayerPattern.NONE
    jpeg_quality: int | None = None
    prnu: float = 0.0
    dsnu_e: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_e: float = 2000.0
    auto_exposure: AutoExposureSpec | None = None
    video: VideoSpec | None = None


def sensor_spec(doc: object, where: str = "sensor") -> SensorSpec:
    spec = from_mapping(SensorSpec, doc, where)
    if spec.bit_depth not in (8, 12, 16):
        raise ConfigError(f"{where}.bit_depth: 8, 12 or 16, got {spec.bit_depth!r}")
    if spec.color not in ("rgb", "mono"):
        raise ConfigError(f"{where}.color: 'rgb' or 'mono', got {spec.color!r}")
    for key in ("exposure", "full_well_e", "psf_sigma_px", "beacon_peak", "halo_scale"):
        check_range(getattr(spec, key), f"{where}.{key}", low=0, low_open=True)
    check_range(spec.read_noise_e, f"{where}.read_noise_e", low=0)
    # the halo is a fraction of the beacon's light spread around it
    check_range(spec.halo_fraction, f"{where}.halo_fraction", low=0, high=1, high_open=True)
    if spec.psf_sigma_px < 0.5:
        raise ConfigError(f"{where}.psf_sigma_px: must be >= 0.5 px so beacon centroids are not aliased")
    _check_sensor_effects(spec, where)
    return spec


def _check_sensor_effects(spec: SensorSpec, where: str) -> None:
    """Range checks of the sensor effects (Bayer, JPEG, fixed pattern, auto-exposure, video)."""
    if spec.bayer is not BayerPattern.NONE and spec.color == "mono":
        raise ConfigError(f"{where}.bayer: a mono sensor has no colour filter array; "
                          "set sensor.color: rgb or sensor.bayer: none")
    if spec.jpeg_quality is not None:
        check_range(spec.jpeg_quality, f"{where}.jpeg_quality", low=1, high=100)
        if spec.bit_depth != 8:
            raise ConfigError(f"{where}.jpeg_quality: JPEG holds 8-bit images only, got bit_depth "
                              f"{spec.bit_depth}; set sensor.bit_depth: 8 or jpeg_quality: null")
    check_range(spec.prnu, f"{where}.prnu", low=0, high=0.5)
    check_range(spec.dsnu_e, f"{where}.dsnu_e", low=0)
    check_range(spec.hot_pixel_fraction, f"{where}.hot_pixel_fraction", low=0, high=0.01)
    check_range(spec.hot_pixel_e, f"{where}.hot_pixel_e", low=0, low_open=True)
    ae = spec.auto_exposure
    if ae is not None:
        w = f"{where}.auto_exposure"
        check_range(ae.target, f"{w}.target", low=0, low_open=True, high=1, high_open=True)
        if ae.percentile is not None:
            check_range(ae.percentile, f"{w}.percentile", low=0, low_open=True, high=100)
        check_range(ae.min_exposure, f"{w}.min_exposure", low=0, low_open=True)
        if ae.max_exposure < ae.min_exposure:
            raise ConfigError(f"{w}: max_exposure {ae.max_exposure:g} is below min_exposure "
                              f"{ae.min_exposure:g}; raise max_exposure")
        check_range(ae.time_constant_s, f"{w}.time_constant_s", low=0, high=3600)
        if ae.max_step_stops is not None:
            check_range(ae.max_step_stops, f"{w}.max_step_stops", low=0, low_open=True, high=20)
        check_range(ae.metering_scale, f"{w}.metering_scale", low=0, low_open=True, high=1)
    video = spec.video
    if video is not None:
        w = f"{where}.video"
        if spec.bit_depth != 8:
            raise ConfigError(f"{w}: the video codecs hold 8-bit frames only, got bit_depth {spec.bit_depth}; "
                              "set sensor.bit_depth: 8 or video: null")
        if spec.jpeg_quality is not None:
            raise ConfigError(f"{w}: a frame is either JPEG-compressed or part of a video stream; "
                              "set jpeg_quality: null or video: null")
        # 10 kbit/s to 1 Gbit/s spans a thumbnail stream to a near-lossless 8K one
        check_range(video.bitrate_kbps, f"{w}.bitrate_kbps", low=10, high=1e6)
        check_range(video.gop_frames, f"{w}.gop_frames", low=1, high=1000)
        if video.codec is VideoCodec.H264 and importlib.util.find_spec("av") is None:
            raise ConfigError(f"{w}.{H264_NEEDS_PYAV}")
