"""Render benchmark: seconds per frame (render + sensor model + PNG write, one worker) and peak memory.

Each case runs in a fresh process (so its peak RSS is its own):

* ``ours``: :func:`deckpose.render.dataset.render_one` on an 8 MP and a 64 MP thesis
  camera (flat shading, night, 8-bit RGB, noise on), after one warm-up frame that
  pays the one-off GL context and framebuffer set-up;
* ``naive``: a fresh pyrender scene and OffscreenRenderer per frame, PBR shading,
  full-frame readback, ``cv2.imwrite`` at default settings (no tiling, no reuse);
* ``real``, with ``--realism``: ``ours`` with the realism effects of
  ``configs/detector_benchmark_hard.yaml`` (LED model, fog, occluders, ship lights and
  glints, and its camera: the lens with glare, the rolling shutter and UAV motion, Bayer,
  fixed pattern, auto-exposure) plus a 0.05 deg RMS vibration over a 10 ms exposure;
  ``bloom``: ``real`` with blooming on (``optics.bloom``, a worst case: most night spots
  saturate); ``ours``, ``real`` and ``bloom`` run ``--repeat`` times interleaved, and the
  ratios of their medians are printed (issue 23's budget: 1.5x);
* ``ship``, with ``--ship``: ``ours`` with the ``scene`` section of
  ``configs/realistic_ship.yaml`` (hull, superstructure, wave sea, light pools, bloom,
  shadows, auto-sized deck texture) under its own ``flat`` shading at night, timed and
  compared the same way; ``ship-day``: that scene by day under ``pbr`` shading (sun
  shading, glitter and shadows: the contact sheet's day tile, drawn with
  ``render/sun_shader.py``'s shader), against ``day``, ``ours`` by day;
* ``pbr-day``, with ``--ship``: the default scene by day under ``pbr`` (``pbr`` shading is
  older than the ship look), so ``ship-day`` against it is what the ship look adds to a
  ``pbr`` frame;
* ``all``, with both ``--realism`` and ``--ship``: every effect at once, the hard rung's
  (``real``) in the ship look's scene (flat, night), against ``ours``.

Usage::

    python benchmarks/bench_render.py [--sizes 8mp 64mp] [--frames 3] [--backend egl]

Prints a table of figures; targets: 8 MP <= 1.0 s, 64 MP <= 6 s per frame, peak
memory of a 64 MP worker < 3 GiB.

Measured on the 2-core, no-GPU development machine (shared with other jobs), 2026-11-24,
``--sizes 8mp 64mp --frames 3 --naive-frames 2``, EGL (llvmpipe)::

      size   case  s/frame   min s  first s  peak GiB
       8mp   ours     0.39    0.39     1.11      0.74
       8mp  naive     2.21    2.18     2.18      1.00
       8mp speed-up over naive: 5.7x
      64mp   ours     3.88    3.74     3.66      1.32
      64mp  naive    16.20   13.86    18.54      5.03
      64mp speed-up over naive: 4.2x

OSMesa, ours only: 8 MP 0.34 s/frame (0.58 GiB), 64 MP 3.19 s/frame (1.00 GiB).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The realism sections of the hard ladder rung (``real`` and ``bloom`` cases).
REALISM_SECTIONS = ("leds", "occlusion", "ship_lights", "optics", "shutter")
#: The hard rung's sensor effects the ``real`` case adds (Bayer, fixed pattern, auto-exposure; on the
#: 8-bit sensor of ``ours``).
SENSOR_EFFECT_KEYS = ("bayer", "prnu", "dsnu_e", "hot_pixel_fraction", "hot_pixel_e", "auto_exposure")
#: Where each realism case takes its sections from (a config in configs/).
CASE_SECTIONS = {"real": ("detector_benchmark_hard.yaml", REALISM_SECTIONS),
                 "bloom": ("detector_benchmark_hard.yaml", REALISM_SECTIONS),
                 "ship": ("realistic_ship.yaml", ("scene",)),
                 "ship-day": ("realistic_ship.yaml", ("scene",)),
                 "all": ("detector_benchmark_hard.yaml", REALISM_SECTIONS)}
#: The lighting of each case (night unless named).
CASE_LIGHTING = {"day": "day", "ship-day": "day", "pbr-day": "day"}


def _case_ours(size: str, frames: int, backend: str, out: Path, realism: str = "",
               lighting: str = "night") -> dict[str, float]:
    import yaml
    from deckpose.render.config import config_from_dict
    from deckpose.render.dataset import render_one
    from deckpose.render.plan import plan_frames

    doc = {
        "cameras": [{"preset": size}], "heights_m": [30.0], "lighting": [lighting], "backend": backend,
        "motion": {"source": "fixed", "attitudes_deg": [[3.0 + i, -2.0, 5.0 * i] for i in range(frames + 1)]},
    }
    if realism == "pbr-day":  # the default scene under pbr: what a pbr frame cost without the ship look
        doc["scene"] = {"shading": "pbr"}
    if realism in CASE_SECTIONS:
        name, sections = CASE_SECTIONS[realism]
        base = yaml.safe_load((Path(__file__).resolve().parent.parent / "configs" / name).read_text())
        doc.update({k: base[k] for k in sections})
        if realism == "ship-day":
            doc["scene"] = {**doc["scene"], "shading": "pbr"}
        if realism == "all":  # the hard rung's effects (below) in the ship look's scene (flat, night)
            ship = yaml.safe_load((Path(__file__).resolve().parent.parent / "configs" / "realistic_ship.yaml").read_text())
            doc["scene"] = {**ship["scene"], "shading": "flat"}
        if realism in ("real", "bloom", "all"):  # the hard rung's sensor effects, and vibration over a 10 ms exposure
            doc["shutter"] = {**base["shutter"], "vibration_deg_rms": 0.05}
            doc["motion"] = {**doc["motion"], "exposure_s": 0.01}
            doc["sensor"] = {k: base["sensor"][k] for k in SENSOR_EFFECT_KEYS}
        if realism == "bloom":
            doc["optics"] = {**base["optics"], "bloom": True}
    cfg = config_from_dict(doc)
    plan = plan_frames(cfg)
    t0 = time.perf_counter()
    render_one(cfg, plan[0], str(out))  # warm-up: context, framebuffers, textures
    warm = time.perf_counter() - t0
    times, cpu = [], []
    for spec in plan[1:]:
        t0, c0 = time.perf_counter(), time.process_time()
        render_one(cfg, spec, str(out))
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)  # every thread of the process (llvmpipe's included)
    return {"first_s": warm, "per_frame_s": sum(times) / len(times), "min_s": min(times),
            "cpu_s": sum(cpu) / len(cpu)}


def _case_naive(size: str, frames: int, backend: str, out: Path) -> dict[str, float]:
    os.environ["PYOPENGL_PLATFORM"] = backend
    import cv2
    import numpy as np
    import pyrender
    from deckpose.render.scene import (
        deck_texture,
        gl_camera_pose,
        gl_intrinsics,
        plane_primitive,
        sea_texture,
    )

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.pose import CameraPose, ShipPose

    cam = preset(size)
    layout = DeckLayout()
    times = []
    for i in range(frames):
        t0 = time.perf_counter()
        s = pyrender.Scene(ambient_light=[0.3] * 3)
        deck = pyrender.MetallicRoughnessMaterial(
            baseColorTexture=pyrender.Texture(source=deck_texture(layout, 14.0, 2048), source_channels="RGB"))
        sea = pyrender.MetallicRoughnessMaterial(
            baseColorTexture=pyrender.Texture(source=sea_texture(512), source_channels="RGB"))
        s.add(pyrender.Mesh([pyrender.Primitive(**plane_primitive(14.0, 14.0, 0.0, 1.0), material=deck)]),
              pose=ShipPose(0.05, -0.03, 0.1 * i).T_world_from_deck)
        s.add(pyrender.Mesh([pyrender.Primitive(**plane_primitive(2000.0, 2000.0, -6.0, 100.0), material=sea)]))
        s.add(pyrender.DirectionalLight(intensity=3.0))
        s.add(pyrender.IntrinsicsCamera(*gl_intrinsics(cam, 0, cam.height_px), znear=0.2, zfar=5000),
              pose=gl_camera_pose(CameraPose.nadir(30.0)))
        r = pyrender.OffscreenRenderer(cam.width_px, cam.height_px)
        color, _ = r.render(s)
        r.delete()
        img = color.astype(np.float32) / 255.0
        img = img + np.random.default_rng(i).normal(0, 0.01, img.shape).astype(np.float32)
        cv2.imwrite(str(out / f"naive_{i}.png"), (np.clip(img, 0, 1) * 255).astype(np.uint8)[..., ::-1])
        times.append(time.perf_counter() - t0)
    return {"first_s": times[0], "per_frame_s": sum(times) / len(times), "min_s": min(times)}


def _child(args: argparse.Namespace) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        if args.case == "naive":
            res = _case_naive(args.size, args.frames, args.backend, Path(tmp))
        else:
            res = _case_ours(args.size, args.frames, args.backend, Path(tmp),
                             realism=args.case if args.case in (*CASE_SECTIONS, "pbr-day") else "",
                             lighting=CASE_LIGHTING.get(args.case, "night"))
    res["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20
    print(json.dumps(res))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["8mp", "64mp"], metavar="PRESET",
                    help="camera presets to time, e.g. 8mp 64mp (default: %(default)s)")
    ap.add_argument("--frames", type=int, default=3, help="timed frames per case, after one warm-up frame")
    ap.add_argument("--naive-frames", type=int, default=2, help="frames of the naive pyrender loop")
    ap.add_argument("--backend", default="egl", choices=["egl", "osmesa"])
    ap.add_argument("--skip-naive", action="store_true", help="leave out the naive pyrender loop (slow)")
    ap.add_argument("--realism", action="store_true", help="also time the hard rung's realism effects")
    ap.add_argument("--ship", action="store_true",
                    help="also time configs/realistic_ship.yaml's scene (ship look, flat, night) and that scene "
                         "under pbr by day (sun light, shadows, glitter) against the default scene by day")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved runs of ours and real/ship")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    ap.add_argument("--size", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        _child(args)
        return
    print(f"deckpose render benchmark: backend={args.backend}, {os.cpu_count()} CPUs, one worker, "
          f"1-minute load {os.getloadavg()[0]:.1f}")
    print(f"{'size':>6} {'case':>8} {'s/frame':>8} {'min s':>7} {'first s':>8} {'peak GiB':>9} {'CPU s':>7}")

    def run(case: str, size: str, n: int) -> dict[str, float]:
        cmd = [sys.executable, __file__, "--case", case, "--size", size, "--frames", str(n),
               "--backend", args.backend]
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode != 0:  # the case's own last line, not a CalledProcessError traceback
            lines = done.stderr.strip().splitlines() or ["no message"]
            sys.exit(f"bench_render: {case} at {size} failed: {lines[-1]}")
        r = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{size:>6} {case:>8} {r['per_frame_s']:8.2f} {r['min_s']:7.2f} {r['first_s']:8.2f} "
              f"{r['peak_rss_gib']:9.2f} {r.get('cpu_s', float('nan')):7.2f}", flush=True)
        return r

    for size in args.sizes:
        res: dict[str, list[dict[str, float]]] = {}
        cases = (("ours",) + (("real", "bloom") if args.realism else ()) + (("ship", "day", "ship-day", "pbr-day") if args.ship else ())
                 + (("all",) if args.realism and args.ship else ()))
        for _ in range(args.repeat if len(cases) > 1 else 1):
            for case in cases:
                res.setdefault(case, []).append(run(case, size, args.frames))
        if not args.skip_naive:
            res["naive"] = [run("naive", size, args.naive_frames)]
        med = {k: statistics.median(r["per_frame_s"] for r in v) for k, v in res.items()}
        # CPU seconds of the process per frame: less swayed by other jobs than the wall time
        cpu = {k: statistics.median(r["cpu_s"] for r in v) for k, v in res.items() if "cpu_s" in v[0]}
        if "naive" in med:
            print(f"{size:>6} speed-up over naive: {med['naive'] / med['ours']:.1f}x")
        if "real" in med:
            print(f"{size:>6} realism (hard rung) / ours, medians of {args.repeat} interleaved: "
                  f"{med['real'] / med['ours']:.2f}x wall, {cpu['real'] / cpu['ours']:.2f}x CPU (budget 1.5x)")
        if "bloom" in med:
            print(f"{size:>6} the hard rung with blooming / without, medians of {args.repeat} interleaved: "
                  f"{med['bloom'] / med['real']:.2f}x wall, {cpu['bloom'] / cpu['real']:.2f}x CPU")
        if "all" in med:
            print(f"{size:>6} every effect at once (the hard rung in the ship look) / ours, medians of {args.repeat} "
                  f"interleaved: {med['all'] / med['ours']:.2f}x wall, {cpu['all'] / cpu['ours']:.2f}x CPU (budget 1.5x)")
        if "ship" in med:
            print(f"{size:>6} ship look (realistic_ship.yaml scene) / ours, medians of {args.repeat} interleaved: "
                  f"{med['ship'] / med['ours']:.2f}x wall, {cpu['ship'] / cpu['ours']:.2f}x CPU (budget 1.5x)")
        if "ship-day" in med:
            print(f"{size:>6} ship look by day, pbr (sun, glitter, shadows) / ours by day, medians of {args.repeat} "
                  f"interleaved: {med['ship-day'] / med['day']:.2f}x wall, {cpu['ship-day'] / cpu['day']:.2f}x CPU "
                  f"(budget 1.5x)")
            print(f"{size:>6} ship look by day, pbr / the default scene by day under pbr too (what the ship look adds "
                  f"to a pbr frame), medians of {args.repeat} interleaved: {med['ship-day'] / med['pbr-day']:.2f}x wall, "
                  f"{cpu['ship-day'] / cpu['pbr-day']:.2f}x CPU")


if __name__ == "__main__":
    main()
