"""Sensor-model benchmark: ms per frame of :func:`deckpose.render.sensor.expose`, now and before.

``before`` is a copy of ``expose`` as of commit 37382e8 (names suffixed; 256-row strips,
two ``cv2.LUT`` tables, ``cv2.randn`` re-seeded per strip); ``now`` is the module's. Both
get the same input a frame hands over: an (H, W, 3) uint8 raster (the distorted deck
and sea; random values here, which cost the same as a real one: every step is a table
look-up or element-wise), the night radiance scale, and the beacon splats of the default
layout seen from 30 m. The two run interleaved (``before, now, now, before, ...``) so a
change in the machine's load hits both; the table gives medians and the ratio of
medians. Peak extra memory is tracemalloc's peak during one call less the image it
returns (numpy and OpenCV's numpy-backed arrays are traced).

Usage::

    python benchmarks/bench_sensor.py [--sizes 8mp 64mp] [--repeats 7] [--bit-depth 8]
                                      [--color rgb]

Measured on the 2-core development machine, 2026-12-02, while two other jobs kept both
cores busy (load average 3.7-4.2; ``--repeats 9``)::

     size   model  median ms   min ms  ns/value  extra MiB
      8mp  before        291      162     11.69       56.3
      8mp     now        121       99      4.86        4.0
      8mp speed-up now over before: 2.41x (median of paired ratios 1.93x)
     64mp  before       1369      981      7.11      135.5
     64mp     now        843      705      4.38        4.0
     64mp speed-up now over before: 1.62x (median of paired ratios 1.69x)

16-bit mono, 8 MP: 76 -> 46 ms (1.63x paired); 12-bit RGB, 8 MP: 230 -> 142 ms (1.52x).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import tracemalloc
from collections.abc import Callable

import cv2
import numpy as np
from deckpose.render.beacons import Splat, add_splats, beacon_splats
from deckpose.render.config import SensorSpec
from deckpose.render.scene import Lighting, Shading, radiance_scale
from deckpose.render.sensor import expose
from numpy.typing import NDArray

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

_LUMA = np.array([0.299, 0.587, 0.114], np.float32)
_STRIP_ROWS_BEFORE = 256

Expose = Callable[
    [NDArray[np.uint8], NDArray[np.float32], list[Splat], SensorSpec, np.random.Generator],
    np.ndarray,
]


def _luts_before(scale_e: np.ndarray, sensor: SensorSpec,
                 dn_per_e: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.arange(256, dtype=np.float64)[:, None] * scale_e[None, :]
    mean = (v * dn_per_e).astype(np.float32)
    sigma = (np.sqrt(v + sensor.read_noise_e ** 2) * dn_per_e).astype(np.float32)
    C = scale_e.size
    return mean.reshape(1, 256, C), sigma.reshape(1, 256, C)


def expose_before(raster: NDArray[np.uint8], scale_rgb: NDArray[np.float32], splats: list[Splat],
                  sensor: SensorSpec, rng: np.random.Generator) -> np.ndarray:
    """``expose`` as of commit 37382e8, for the comparison (same arguments and result)."""
    H, W = raster.shape[:2]
    mono = sensor.color == "mono"
    dn_max = float(2 ** sensor.bit_depth - 1)
    dn_per_e = dn_max / sensor.full_well_e
    e_per_rad = sensor.exposure * sensor.full_well_e
    scale = np.asarray(scale_rgb, np.float64) * e_per_rad
    if mono:
        scale = np.array([scale @ _LUMA])
    lut_mean, lut_sigma = _luts_before(scale, sensor, dn_per_e)
    src = cv2.cvtColor(raster, cv2.COLOR_RGB2GRAY) if mono else raster
    C = 1 if mono else 3
    depth = cv2.CV_8U if sensor.bit_depth == 8 else cv2.CV_16U
    out = np.empty((H, W) if mono else (H, W, C), np.uint8 if sensor.bit_depth == 8 else np.uint16)
    read2 = np.float32(sensor.read_noise_e ** 2)
    for r0 in range(0, H, _STRIP_ROWS_BEFORE):
        r1 = min(H, r0 + _STRIP_ROWS_BEFORE)
        block = src[r0:r1]
        mean = np.asarray(cv2.LUT(block, lut_mean), dtype=np.float32).reshape(r1 - r0, W, C)
        touched = add_splats(mean, splats, r0, gain=e_per_rad * dn_per_e)
        if sensor.noise:
            sigma = cv2.LUT(block, lut_sigma).reshape(r1 - r0, W, C)
            for rr, cc in touched:
                m = mean[rr, cc]
                sigma[rr, cc] = np.sqrt(np.maximum(m, 0) / np.float32(dn_per_e) + read2) * np.float32(dn_per_e)
            noise = np.empty(mean.shape, np.float32)
            cv2.setRNGSeed(int(rng.integers(2**31 - 1)))
            cv2.randn(noise.reshape(r1 - r0, -1), 0.0, 1.0)  # pyright: ignore[reportCallIssue, reportArgumentType]
            noise *= sigma
            shape = out[r0:r1].shape
            cv2.add(mean.reshape(shape), noise.reshape(shape), dst=out[r0:r1], dtype=depth)
        else:
            np.clip(np.rint(mean), 0.0, dn_max, out=mean)
            out[r0:r1] = mean.reshape(out[r0:r1].shape)
    if sensor.bit_depth == 12:
        np.minimum(out, np.uint16(dn_max), out=out)
    return out


def _inputs(size: str, sensor: SensorSpec,
            seed: int) -> tuple[NDArray[np.uint8], NDArray[np.float32], list[Splat]]:
    """Raster, radiance scale and beacon splats of one ``size`` frame (night, flat shading)."""
    cam = preset(f"{size}-thesis")
    shape = (cam.height_px, cam.width_px, 3)
    raster = np.random.default_rng(seed).integers(0, 256, shape, np.uint8)
    splats = beacon_splats(DeckLayout(), (ShipPose(),), CameraPose.nadir(30.0), cam, sensor)
    return raster, radiance_scale(Lighting.NIGHT, Shading.FLAT), splats


def _time_s(fn: Expose, args: tuple[NDArray[np.uint8], NDArray[np.float32], list[Splat]],
            sensor: SensorSpec, seed: int) -> float:
    t0 = time.perf_counter()
    fn(*args, sensor, np.random.default_rng(seed))
    return time.perf_counter() - t0


def _peak_extra_bytes(fn: Expose, args: tuple[NDArray[np.uint8], NDArray[np.float32], list[Splat]],
                      sensor: SensorSpec) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    img = fn(*args, sensor, np.random.default_rng(0))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak - base - img.nbytes


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["8mp", "64mp"])
    ap.add_argument("--repeats", type=int, default=7, help="timed calls of each model per size")
    ap.add_argument("--bit-depth", type=int, default=8, choices=(8, 12, 16))
    ap.add_argument("--color", default="rgb", choices=("rgb", "mono"))
    args = ap.parse_args(argv)
    sensor = SensorSpec(bit_depth=args.bit_depth, color=args.color)
    models: dict[str, Expose] = {"before": expose_before, "now": expose}
    print(f"sensor: {args.bit_depth}-bit {args.color}, noise on; "
          f"{args.repeats} interleaved repeats; "
          f"{os.cpu_count()} CPUs, load average at start {os.getloadavg()[0]:.2f}")
    print(f"{'size':>5} {'model':>7} {'median ms':>10} {'min ms':>8} {'ns/value':>9} "
          f"{'extra MiB':>10}")
    for size in args.sizes:
        inputs = _inputs(size, sensor, seed=1)
        n_values = inputs[0].size // (3 if args.color == "mono" else 1)
        for fn in models.values():  # warm-up: page in the raster, OpenCV's first-call set-up
            _time_s(fn, inputs, sensor, 0)
        times: dict[str, list[float]] = {k: [] for k in models}
        for rep in range(args.repeats):
            order = list(models) if rep % 2 == 0 else list(models)[::-1]
            for name in order:
                times[name].append(_time_s(models[name], inputs, sensor, rep))
        for name, fn in models.items():
            med = statistics.median(times[name])
            extra = _peak_extra_bytes(fn, inputs, sensor) / 2**20
            print(f"{size:>5} {name:>7} {med * 1e3:10.0f} {min(times[name]) * 1e3:8.0f} "
                  f"{med / n_values * 1e9:9.2f} {extra:10.1f}")
        ratio = statistics.median(times["before"]) / statistics.median(times["now"])
        paired = statistics.median(
            b / n for b, n in zip(times["before"], times["now"], strict=True))
        print(f"{size:>5} speed-up now over before: {ratio:.2f}x "
              f"(median of paired ratios {paired:.2f}x)")
    print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
