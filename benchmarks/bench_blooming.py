"""What blooming and glare cost on a saturated 8 MP night frame, and blooming before and after vectorising.

The easy rung's scene at 30 m, night (most beacon cores saturate), through the optics
condition's lens (configs/detector_benchmark_optics.yaml), with a 3 % glare tail, with
blooming (``optics.bloom``), and with blooming by the implementation before vectorising (kept
in tests/render/test_realism_finish.py as the reference); variants interleaved, medians of
the main thread's CPU time per ``render_frame`` (the GL rasteriser's threads and the PNG write
not included: the effects run on this thread).

Usage::

    .venv/bin/python benchmarks/bench_blooming.py [REPEATS]
"""
import copy
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import yaml
from deckpose.render import optics as optics_mod
from deckpose.render.config import Backend, config_from_dict
from deckpose.render.frame import render_frame
from deckpose.render.plan import plan_frames
from deckpose.render.scene import DeckRenderer, use_backend

from tests.render.test_realism_finish import reference_bloom_splats

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    easy = yaml.safe_load((ROOT / "configs" / "detector_benchmark_easy.yaml").read_text())
    lens = yaml.safe_load((ROOT / "configs" / "detector_benchmark_optics.yaml").read_text())["optics"]
    easy.update(heights_m=[30.0], lighting=["night"], motion={"source": "fixed", "attitudes_deg": [[3, -2, 5]]})
    variants = {"optics": dict(lens), "glare": dict(lens, glare_fraction=0.03),
                "glare+bloom": dict(lens, glare_fraction=0.03, bloom=True), "glare+bloom(old)": dict(lens, glare_fraction=0.03, bloom=True),
                "plain": None}
    cfgs = {}
    for k, o in variants.items():
        d = copy.deepcopy(easy)
        if o is not None:
            d["optics"] = o
        cfgs[k] = config_from_dict(d)
    use_backend(Backend.EGL)
    c0 = cfgs["plain"]
    r = DeckRenderer(c0.layout, c0.scene, c0.deck_half_size_m(), c0.backend)
    spec = plan_frames(c0)[0]
    cam = c0.cameras_by_name()[spec.camera_name]
    fast = optics_mod.bloom_splats
    times = {k: [] for k in cfgs}
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    for rep in range(n + 1):
        for k, cfg in cfgs.items():
            optics_mod.bloom_splats = reference_bloom_splats if k.endswith("(old)") else fast
            t = time.thread_time()
            render_frame(cfg, spec, cam, r)
            dt = time.thread_time() - t
            if rep:
                times[k].append(dt)
    base = statistics.median(times["plain"])
    print(f"load {os.getloadavg()[0]:.1f}; medians of {n} interleaved, thread CPU s per frame (render_frame, no PNG)")
    for k, v in times.items():
        print(f"{k:>18} {statistics.median(v):.3f} s  {statistics.median(v)/base:.2f}x plain")

if __name__ == "__main__":
    main()
