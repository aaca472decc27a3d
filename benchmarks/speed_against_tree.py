"""CPU per frame of one detector (with identification) in this tree against another, interleaved.

On a shared machine a timing drifts with the load; a ratio of two trees timed in
turn, run by run, does not. Two worker processes, one importing this checkout's
``deckpose`` and one the other tree's (``--base``, a checkout of the commit to
compare with, e.g. ``git worktree add --detach /tmp/base main``), load the same
decoded frames and time :func:`deckpose.detect.frame_detection.detect_frame` on
them (CPU time of the thread, one OpenCV thread, OMP/OpenBLAS one thread), in
alternating order, one frame at a time. Printed per frame: each tree's median CPU
time and the median (and quartiles) of the per-run ratios, with the load.

Frames: the speed benchmark's synthetic 8 MP and 64 MP frames (16-bit mono and 8-bit
RGB, ``bench_detectors.py``'s), with ``--independent`` the first 8 MP frame of some
datasets of the independent generator (``bench_independent.py``'s, its seed), and with
``--rendered DATASET`` some of its frames. Besides the medians, each tree's fastest run
per frame is printed: on a loaded machine the least disturbed of the runs, an indicator
of the CPU time on a quiet one.

Usage::

    .venv/bin/python benchmarks/speed_against_tree.py --base /tmp/base [--rendered DATASET]
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["OMP_NUM_THREADS"] = "1"
os.environ["OPENBLAS_NUM_THREADS"] = "1"

import numpy as np

#: The stage folders that install as subpackages of deckpose (pyproject's package-dir).
STAGES = ("render", "detect", "estimate", "evaluate")


def link_tree(checkout: Path, into: Path) -> Path:
    """A tree of links laid out as installed (``deckpose/`` holding the stages); its root."""
    root = into / "tree"
    root.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cp", "-rs", str(checkout.resolve() / "deckpose"), str(root / "deckpose")],
                   check=True)
    for d in STAGES:
        subprocess.run(["cp", "-rs", str(checkout.resolve() / d), str(root / "deckpose" / d)],
                       check=True)
    return root


def synthetic_frames(folder: Path) -> list[Path]:
    """The speed benchmark's synthetic frames (uint16 mono, uint8 RGB), pickled with their layout."""
    from deckpose.detect.synthetic import SensorModel, render_spots

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.pose import CameraPose, ShipPose
    from deckpose.projection import project_layout
    from deckpose.records import Frame

    sensor = SensorModel(gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, bit_depth=16)
    rng = np.random.default_rng(0)
    layout = DeckLayout()
    paths = []
    for cam_name, height in (("8mp", 30.0), ("64mp", 60.0)):
        cam = preset(cam_name)
        pr = project_layout(layout, ShipPose(0.03, -0.02, 0.4), CameraPose.nadir(height), cam)
        sigma = np.sqrt(pr.apparent_radius_px**2 / 4 + 0.7**2)
        flux = 3000.0 * np.pi * pr.apparent_radius_px**2
        mono = render_spots((cam.height_px, cam.width_px), pr.points_px, sigma, flux, sensor, rng)
        colour = np.ones((len(pr.points_px), 3))
        colour[layout.bow_id] = layout.bow_rgb
        rgb = render_spots((cam.height_px, cam.width_px), pr.points_px, sigma, flux, sensor, rng,
                           rgb=colour)
        for label, img in (("mono16", mono), ("rgb8", np.clip(rgb // 32, 0, 255).astype(np.uint8))):
            paths.append(_save(folder / f"{cam_name}_{label}.pkl", Frame(img, cam), layout))
    return paths


def rendered_frames(dataset: str, n: int, folder: Path) -> list[Path]:
    """``n`` decoded frames spread over a rendered dataset, pickled with its layout."""
    from deckpose.detect.sources import load_frame, open_dataset

    fs = open_dataset(dataset)
    step = max(1, len(fs.sources) // max(1, n))
    paths = []
    for src in fs.sources[::step][:n]:
        fr = load_frame(src, fs.cameras[src.camera_name])
        if not isinstance(fr, str):
            paths.append(_save(folder / f"rendered_{src.image_path.stem}.pkl", fr, fs.layout))
    return paths


#: Datasets of ``bench_independent.py`` whose first frame ``--independent`` times.
INDEPENDENT = ("rgb_uneven", "mono_dim_bow", "hard")


def independent_frames(folder: Path, seed: int = 2026) -> list[Path]:
    """The first frame of each of :data:`INDEPENDENT`'s datasets, as ``bench_independent.py`` makes it."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_independent as bi
    import independent_spots as gen

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout
    from deckpose.records import Frame

    paths = []
    for name in INDEPENDENT:
        rng = np.random.default_rng([seed, list(bi.DATASETS).index(name)])
        fr = gen.make_frame(bi.DATASETS[name][0], rng)
        cam = CameraModel(fr.image.shape[1], fr.image.shape[0], fr.K)
        paths.append(_save(folder / f"independent_{name}.pkl", Frame(fr.image, cam, 0), DeckLayout()))
    return paths


def _save(path: Path, frame: object, layout: object) -> Path:
    """A decoded frame and its deck layout, pickled for the workers (both trees read it)."""
    with open(path, "wb") as f:
        pickle.dump((frame, layout), f)
    return path


def worker(detector: str, paths: list[str]) -> None:
    """Load the frames, then time ``detect_frame`` on the frame index read from each stdin line.

    Run in this tree or (``PYTHONPATH``) the other; prints the module it timed, then one
    CPU time per line read.
    """
    import cv2
    from deckpose.detect import frame_detection

    cv2.setNumThreads(1)
    frames = []
    for p in paths:
        with open(p, "rb") as f:
            frame, layout = pickle.load(f)
        frame_detection.detect_frame(frame, detector, layout)  # warm caches and imports
        frames.append((frame, layout))
    print(f"ready {frame_detection.__file__}", flush=True)
    for line in sys.stdin:
        frame, layout = frames[int(line)]
        c0 = time.thread_time()
        res = frame_detection.detect_frame(frame, detector, layout)
        print(f"{time.thread_time() - c0:.6f} {len(res.detections.points_px)}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="checkout of the tree to compare with")
    ap.add_argument("--detector", default="cog")
    ap.add_argument("--repeat", type=int, default=7, help="interleaved runs per frame")
    ap.add_argument("--rendered", metavar="DATASET", help="also time frames of this dataset")
    ap.add_argument("--rendered-frames", type=int, default=4)
    ap.add_argument("--no-synthetic", action="store_true")
    ap.add_argument("--independent", action="store_true",
                    help="also time frames of the independent generator (bench_independent.py)")
    ap.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.detector, args.worker)
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = [] if args.no_synthetic else synthetic_frames(folder)
        if args.independent:
            paths += independent_frames(folder)
        if args.rendered:
            paths += rendered_frames(args.rendered, args.rendered_frames, folder)
        base_tree = link_tree(Path(args.base), folder)
        cmd = [sys.executable, __file__, "--base", args.base, "--detector", args.detector,
               "--worker", *map(str, paths)]
        procs = []
        for extra in ({"PYTHONPATH": str(base_tree)}, {}):
            p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                 env=dict(os.environ, **extra))
            assert p.stdout is not None
            print(f"{'base' if extra else 'this'}: {p.stdout.readline().split()[-1]}")
            procs.append(p)

        def run(p: subprocess.Popen[str], i: int) -> float:
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write(f"{i}\n")
            p.stdin.flush()
            return float(p.stdout.readline().split()[0])

        loads = [os.getloadavg()[0]]
        cpu = np.zeros((len(paths), 2, args.repeat))
        for r in range(args.repeat):
            for i in range(len(paths)):
                for k in ((0, 1) if r % 2 == 0 else (1, 0)):
                    cpu[i, k, r] = run(procs[k], i)
            loads.append(os.getloadavg()[0])
        for p in procs:
            assert p.stdin is not None
            p.stdin.close()
            p.wait()
    print(f"{args.detector} + identification, {args.repeat} interleaved runs per frame, one thread; "
          f"1-minute load {min(loads):.2f}-{max(loads):.2f} on {os.cpu_count()} cores")
    print(f"{'frame':28s} {'base ms':>8s} {'this ms':>8s} {'this/base':>10s}  (quartiles)  "
          "fastest run: base, this ms")
    for i, p in enumerate(paths):
        ratio = cpu[i, 1] / cpu[i, 0]
        q1, q3 = np.percentile(ratio, [25, 75])
        print(f"{Path(p).stem:28s} {1000 * np.median(cpu[i, 0]):8.1f} "
              f"{1000 * np.median(cpu[i, 1]):8.1f} {np.median(ratio):10.3f}  ({q1:.3f}-{q3:.3f})  "
              f"{1000 * np.min(cpu[i, 0]):6.1f} {1000 * np.min(cpu[i, 1]):6.1f}")


if __name__ == "__main__":
    main()
