"""Cost of the sequence effects: the auto-exposure controller's metering pre-pass and video compression.

Per frame, CPU seconds (``time.process_time``: this process's threads, Mesa's rasteriser
threads included) of

* ``frame``: :func:`deckpose.render.frame.render_frame` of a plain frame (the reference);
* ``meter@s``: :func:`deckpose.render.exposure_control.metering_exposure` at metering scale
  ``s`` (the pre-pass's work for one frame, done once per frame in the main process);
* ``video <codec>``: :func:`deckpose.render.video_codec.video_round_trip` of a sequence of
  the rendered frames, divided by their number (encode and decode).

The cases run interleaved, frame after frame, so a change of the machine's load hits each;
the table gives medians and the ratio to ``frame``.

Usage::

    python benchmarks/bench_sequence_effects.py [--size 1920 1080] [--frames 6]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

from deckpose.render.config import config_from_dict
from deckpose.render.exposure_control import metering_exposure
from deckpose.render.frame import render_frame
from deckpose.render.plan import plan_frames
from deckpose.render.scene import DeckRenderer
from deckpose.render.sensor_config import AutoExposureSpec, VideoCodec, VideoSpec
from deckpose.render.video_codec import video_round_trip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, nargs=2, default=(1920, 1080), metavar=("W", "H"))
    ap.add_argument("--frames", type=int, default=6)
    args = ap.parse_args()
    n = args.frames
    cfg = config_from_dict({
        "name": "bench", "seed": 1, "backend": "egl",
        "cameras": [{"preset": "8mp-square", "size": list(args.size)}], "heights_m": [30.0], "lighting": ["dusk"],
        "motion": {"source": "fixed", "dt_s": 0.1, "attitudes_deg": [[0.5 * k, 0, 0, 0, 0.2 * k, 0] for k in range(n)]},
        "scene": {"texture_px": 2048}})
    renderer = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    cam = next(iter(cfg.cameras_by_name().values()))
    plan = plan_frames(cfg)
    render_frame(cfg, plan[0], cam, renderer)  # warm-up: the GL context, textures, lens maps
    times: dict[str, list[float]] = {}
    frames = []
    for spec in plan:
        t = time.process_time()
        frames.append(render_frame(cfg, spec, cam, renderer).frame.image)
        times.setdefault("frame", []).append(time.process_time() - t)
        for scale in (0.25, 1.0):
            t = time.process_time()
            metering_exposure(spec, cam, renderer, cfg.sensor, cfg.scene.shading,
                              AutoExposureSpec(metering_scale=scale))
            times.setdefault(f"meter@{scale:g}", []).append(time.process_time() - t)
    for codec in VideoCodec:
        for _ in range(3):
            t = time.process_time()
            video_round_trip(frames, 10.0, VideoSpec(codec=codec, bitrate_kbps=8000.0))
            times.setdefault(f"video {codec.value}", []).append((time.process_time() - t) / n)
    ref = statistics.median(times["frame"])
    print(f"{args.size[0]}x{args.size[1]}, {n} frames, load average {os.getloadavg()[0]:.1f} at the end")
    print(f"{'case':>12} {'median s':>9} {'x frame':>8}")
    for name, v in times.items():
        print(f"{name:>12} {statistics.median(v):9.3f} {statistics.median(v) / ref:8.2f}")


if __name__ == "__main__":
    main()
