"""Memory one rendered frame needs, bytes per pixel: the figure behind ``render``'s memory check.

A render config whose frame would need more memory than the machine has is refused at
load (:data:`deckpose.render.camera_spec.BYTES_PER_PX`). This benchmark measures that
figure: each case runs in a fresh process that first renders a tiny frame (so the GL
context, the libraries and the caches are already counted), then one frame of the
size asked, and prints ``(peak - peak after the tiny frame) / pixels`` from the process's
peak resident memory (``ru_maxrss``). Two cases: the default frame (flat shading, no
realism) and every realism effect at once (pbr, ship and sea, optics with glare, spikes
and blooming, Bayer, fixed pattern, rolling shutter, vibration, bloom).

Usage::

    .venv/bin/python benchmarks/bench_render_memory.py [--size 3840x2160]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CASES: dict[str, dict[str, object]] = {
    "default": {},
    "every realism effect": {
        "optics": {"f_number": 2.0, "focus_distance_m": 2.0, "pixel_pitch_um": 2.0, "diffraction": True,
                   "glare_fraction": 0.01, "spike_fraction": 0.01, "bloom": True, "vignetting_exponent": 4.0,
                   "lateral_ca_ppm": [1500.0, -1500.0], "field_blur_px": 1.0},
        "sensor": {"bayer": "rggb", "prnu": 0.005, "dsnu_e": 2, "hot_pixel_fraction": 0.0001},
        "scene": {"shading": "pbr", "ship": {"hull": True, "superstructure": True}, "sea": {"waves": 8},
                  "bloom_fraction": 0.02},
        "shutter": {"line_delay_s": 1e-5, "vibration_deg_rms": 0.02},
    },
}

_CHILD = r"""
import json, os, resource, sys, tempfile
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset
size, extra = json.loads(sys.argv[1]), json.loads(sys.argv[2])
doc = {"name": "memory", "seed": 1, "backend": "egl", "cameras": [{"preset": "8mp-square", "size": [320, 180]}],
       "heights_m": [30.0], "lighting": ["night"], "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0]]},
       "sensor": {"bit_depth": 12}, "scene": {"shading": "flat", "texture_px": 2048}}
for k, v in extra.items():
    doc[k] = {**doc.get(k, {}), **v} if isinstance(v, dict) else v
with tempfile.TemporaryDirectory() as tmp:
    render_dataset(config_from_dict(doc), os.path.join(tmp, "tiny"), workers=0, progress=False)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    doc["cameras"] = [{"preset": "8mp-square", "size": size}]
    render_dataset(config_from_dict(doc), os.path.join(tmp, "big"), workers=0, progress=False)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"base_kib": base, "peak_kib": peak}))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="3840x2160", help="frame size WIDTHxHEIGHT (default 3840x2160)")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.lower().split("x"))
    from deckpose.render.camera_spec import BYTES_PER_PX

    load = os.getloadavg()[0]
    print(f"render memory per pixel, {w}x{h}, one frame in a fresh process; load {load:.1f} on "
          f"{os.cpu_count()} cores; the config check assumes {BYTES_PER_PX} B/px")
    for name, extra in CASES.items():
        out = subprocess.run([sys.executable, "-c", _CHILD, json.dumps([w, h]), json.dumps(extra)],
                             capture_output=True, text=True, check=True)
        got = json.loads(out.stdout.strip().splitlines()[-1])
        per_px = (got["peak_kib"] - got["base_kib"]) * 1024 / (w * h)
        print(f"  {name:22s} peak {got['peak_kib'] / 2**20:5.2f} GiB, {per_px:5.1f} B/px above the tiny frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
