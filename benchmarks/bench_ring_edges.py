"""CPU time of the painted ring's edge detection per frame, optionally against another revision.

Frames are analytic (the ring's exact area coverage, :func:`deckpose.render.painted_ring.paint_coverage`
with 8 x 8 samples a pixel, on a flat deck of 60 DN, paint 180 DN, white noise of 4 DN), drawn
from 28-36 m at seeded attitudes, for a 640 x 480 camera and an 8 MP (3264 x 2448) camera with
the same 75 x 60 degree field. Each frame is run through
:func:`deckpose.detect.ring_edges.detect_ring_edges` and timed with ``time.process_time``
(one BLAS and one OpenCV thread).

``--against REV`` also loads ``detect/edge_profile_fit.py`` as it was at git revision ``REV``
and runs it on the same frames, interleaved frame by frame with this tree's, printing both
medians and their ratio (the machine's load moves both alike), and the largest difference of the
fitted edge points between the two in units of each point's own Cramér–Rao bound.

    .venv/bin/python benchmarks/bench_ring_edges.py --against HEAD~1 --frames 3 --repeats 3
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import importlib.util
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import cv2
import deckpose.detect.edge_profile_fit as this_tree
import numpy as np
from deckpose.detect import model_edge, ring_edges
from deckpose.render.painted_ring import paint_coverage

from deckpose.camera import CameraModel
from deckpose.painted_ring import PaintedRing
from deckpose.pose import CameraPose, ShipPose

ROOT = Path(__file__).resolve().parents[1]
RING = PaintedRing()


def camera(width_px: int, height_px: int) -> CameraModel:
    """A pinhole camera of the given size with a 75 x 60 degree field, principal point near the centre."""
    fx = 0.5 * width_px / math.tan(math.radians(37.5))
    fy = 0.5 * height_px / math.tan(math.radians(30.0))
    K = np.array([[fx, 0.0, width_px / 2 - 2.0], [0.0, fy, height_px / 2 + 3.0], [0.0, 0.0, 1.0]])
    return CameraModel(width_px, height_px, K)


def frame(cam: CameraModel, seed: int) -> np.ndarray:
    """One analytic frame (float32 DN): the module docstring's deck, paint and noise."""
    rng = np.random.default_rng(1000 + seed)
    ship = ShipPose(math.radians(rng.uniform(-4, 4)), math.radians(rng.uniform(-4, 4)),
                    math.radians(rng.uniform(-40, 40)), 0.0, rng.uniform(-1, 1), rng.uniform(-1, 1))
    got = paint_coverage(RING, ship, CameraPose.nadir(float(rng.uniform(28, 36))), cam, samples=8)
    if got is None:
        raise SystemExit("bench_ring_edges: the ring left the frame; choose other seeds")
    r0, c0, cov = got
    img = np.full((cam.height_px, cam.width_px), 60.0)
    img[r0:r0 + cov.shape[0], c0:c0 + cov.shape[1]] += 120.0 * cov
    return (img + rng.normal(0.0, 4.0, img.shape)).astype(np.float32)


def module_at(rev: str) -> ModuleType:
    """``detect/edge_profile_fit.py`` as it was at git revision ``rev``, loaded under its own name."""
    try:
        src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:detect/edge_profile_fit.py"],
                             check=True, capture_output=True, text=True).stdout
    except subprocess.CalledProcessError as exc:
        raise SystemExit(f"bench_ring_edges: cannot read detect/edge_profile_fit.py at {rev!r}: "
                         f"{exc.stderr.strip()}") from None
    path = Path(tempfile.mkdtemp()) / "edge_profile_fit_against.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("edge_profile_fit_against", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def use(mod: ModuleType) -> None:
    """Point the ring detector at ``mod``'s profile fit."""
    ring_edges.blur_of_edges = mod.blur_of_edges
    ring_edges.conic_edge_profiles = mod.conic_edge_profiles
    model_edge.conic_edge_profiles = mod.conic_edge_profiles
    model_edge.fit_edge_profiles = mod.fit_edge_profiles


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", metavar="REV", help="also time detect/edge_profile_fit.py at this git revision")
    ap.add_argument("--frames", type=int, default=3, help="frames per camera (seeds 0..N-1)")
    ap.add_argument("--repeats", type=int, default=3, help="passes over the frames")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    variants: list[tuple[str, ModuleType]] = [("this tree", this_tree)]
    if args.against:
        variants.append((args.against, module_at(args.against)))
    print(f"load before: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    for name, cam in (("640x480", camera(640, 480)), ("8 MP 3264x2448", camera(3264, 2448))):
        frames = [frame(cam, s) for s in range(args.frames)]
        times: dict[str, list[float]] = {label: [] for label, _ in variants}
        worst_in_crb = 0.0
        for _ in range(args.repeats):
            for img in frames:
                points = {}
                for label, mod in variants:
                    use(mod)
                    t0 = time.process_time()
                    det = ring_edges.detect_ring_edges(img, cam, RING, ring_edges.RingEdgeOptions())
                    times[label].append(time.process_time() - t0)
                    if not det.ok:
                        raise SystemExit(f"bench_ring_edges: {label} found no ring: {det.reason}")
                    points[label] = (det.inner_px, det.inner_crb_px, det.outer_px, det.outer_crb_px)
                if len(points) == 2:
                    a, b = points.values()
                    for pa, crb, pb in ((a[0], a[1], b[0]), (a[2], a[3], b[2])):
                        if pa.shape == pb.shape:
                            worst_in_crb = max(worst_in_crb, float(np.nanmax(np.linalg.norm(pa - pb, axis=1) / crb)))
                        else:
                            worst_in_crb = math.inf
        med = {label: statistics.median(t) for label, t in times.items()}
        line = f"{name}: this tree {med['this tree']:.2f} s CPU per frame (median of {len(times['this tree'])})"
        if args.against:
            ratio = med["this tree"] / med[args.against]
            line += (f"; {args.against} {med[args.against]:.2f} s; ratio {ratio:.2f}; "
                     f"largest point difference {worst_in_crb:.2g} of its CRB")
        print(line, flush=True)
    use(this_tree)
    print(f"load after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
