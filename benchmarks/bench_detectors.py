"""Detector benchmarks that print their figures.

1. Speed: every detector on one 8 MP and one 64 MP synthetic frame (16-bit
   mono, and the same as 8-bit RGB) with the 13 beacons of the standard layout,
   image already decoded, OpenCV restricted to one thread; median of
   ``--repeat`` runs, detection alone and detection + identification (what
   ``deckpose detect`` runs per frame); with ``--rendered DATASET`` also on some
   decoded frames of a rendered dataset. Both wall time and the thread's CPU time are
   printed: on a shared machine the CPU time is the one-core figure (wall time
   also counts the time other processes hold the core), and the 1-minute load
   average is printed with them.
2. Accuracy: Monte Carlo centroid error of every detector on analytic spots
   (:mod:`deckpose.detect.synthetic`) against the centroid Cramér–Rao bound,
   over spot sizes and fluxes; then on spots whose cores clip at full scale
   (where ``gauss`` is a censored fit of the wings).
3. Identification on exact projections with hidden beacons and glints.
4. Optionally (``--dataset DIR``) the full ``bench-detectors`` report on a dataset;
   ``--make-dataset CONFIG DIR`` writes the synthetic dataset of a config first.

Usage::

    .venv/bin/python benchmarks/bench_detectors.py [--repeat 5] [--trials 200]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import numpy as np
from deckpose.detect import registry
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.synthetic import SensorModel, render_spots

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Frame


def _time_frame(frame: Frame, detectors: list[str], repeat: int, layout: DeckLayout) -> None:
    """Print each detector's CPU and wall time on one decoded frame, median of ``repeat``.

    Two figures per detector: detection alone, and detection + identification
    (:func:`deckpose.detect.frame_detection.detect_frame`, what ``deckpose detect`` runs per
    frame), the latter interleaved with the former run by run.
    """
    for name in detectors:
        fn = registry.get(name)
        det_cpu, full_cpu, full_wall = [], [], []
        res = None
        for _ in range(repeat):
            c0 = time.thread_time()
            blobs = fn(frame, DetectorOptions())
            det_cpu.append(time.thread_time() - c0)
            t0, c0 = time.perf_counter(), time.thread_time()
            res = detect_frame(frame, name, layout)
            full_cpu.append(time.thread_time() - c0)
            full_wall.append(time.perf_counter() - t0)
        assert res is not None
        print(
            f"  {name:12s} detect CPU {1000 * np.median(det_cpu):7.1f} ms   detect + identify CPU "
            f"{1000 * np.median(full_cpu):7.1f} ms (min {1000 * np.min(full_cpu):.1f}, wall "
            f"{1000 * np.median(full_wall):.1f})  {len(blobs)} blobs, "
            f"{'ok' if res.ok else 'FAILED: ' + res.reason}"
        )


def speed(repeat: int, detectors: list[str], rendered: str | None, n_rendered: int) -> None:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"speed: 1-minute load average {load:.2f} on {os.cpu_count()} cores at the start")
    sensor = SensorModel(gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, bit_depth=16)
    rng = np.random.default_rng(0)
    layout = DeckLayout()
    for cam_name, height in (("8mp", 30.0), ("64mp", 60.0)):
        cam = preset(cam_name)
        pr = project_layout(layout, ShipPose(0.03, -0.02, 0.4), CameraPose.nadir(height), cam)
        sigma = np.sqrt(pr.apparent_radius_px**2 / 4 + 0.7**2)
        flux = 3000.0 * np.pi * pr.apparent_radius_px**2
        img = render_spots((cam.height_px, cam.width_px), pr.points_px, sigma, flux, sensor, rng)
        # The same spots as 8-bit RGB, the bow red, so that identification runs to the end
        # there (on mono frames it stops at the bow, which only its colour tells).
        colour = np.ones((len(pr.points_px), 3))
        colour[layout.bow_id] = layout.bow_rgb
        rgb = render_spots((cam.height_px, cam.width_px), pr.points_px, sigma, flux, sensor, rng,
                           rgb=colour)
        rgb8 = np.clip(rgb // 32, 0, 255).astype(np.uint8)
        del rgb
        for label, frame in (("uint16 mono", Frame(img, cam)), ("uint8 RGB", Frame(rgb8, cam))):
            print(
                f"\n{cam_name} synthetic frame {cam.width_px}x{cam.height_px} {label}, 13 spots of "
                f"radius {pr.apparent_radius_px.mean():.1f} px; one OpenCV thread; median of {repeat}"
            )
            _time_frame(frame, detectors, repeat, layout)
        del img, frame, rgb8
    if rendered:
        from deckpose.detect.sources import load_frame, open_dataset

        fs = open_dataset(rendered)
        step = max(1, len(fs.sources) // max(1, n_rendered))
        for src in fs.sources[::step][:n_rendered]:
            fr = load_frame(src, fs.cameras[src.camera_name])
            if isinstance(fr, str):
                print(f"\nrendered frame {src.frame_id}: {fr}")
                continue
            print(
                f"\nrendered frame {src.image_path.name} of {rendered} "
                f"({fr.image.shape[1]}x{fr.image.shape[0]} {fr.image.dtype} "
                f"{'RGB' if fr.image.ndim == 3 else 'mono'}), decoded; median of {repeat}"
            )
            _time_frame(fr, detectors, repeat, fs.layout)


def accuracy(trials: int, detectors: list[str]) -> None:
    sensor = SensorModel(gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, bit_depth=16)
    cam = preset("8mp").with_size(480, 320)
    rng = np.random.default_rng(1)
    print(f"\naccuracy on analytic spots: {trials} frames x 6 spots per case; sensor {sensor}")
    print("per-axis RMS error / CRB (and RMS in px); 'FWHM' = 2.355 sigma")
    print(
        f"{'sigma px':>8} {'FWHM px':>8} {'flux e':>9} {'CRB px':>8} "
        + " ".join(f"{d:>16}" for d in detectors)
    )
    for sigma, flux in (
        (0.85, 5e3),
        (0.85, 5e4),
        (1.5, 2e4),
        (1.5, 2e5),
        (3.0, 5e4),
        (3.0, 5e5),
        (0.5, 2e4),
    ):
        errs = {d: [] for d in detectors}
        crb = []
        for _ in range(trials):
            pts = np.array(
                [[60 + 160 * i, 80 + 160 * j] for i in range(3) for j in range(2)], float
            )
            pts += rng.uniform(-0.5, 0.5, pts.shape)
            img = render_spots((320, 480), pts, sigma, flux, sensor, rng)
            fr = Frame(img, cam)
            crb += [np.trace(centroid_crb_px2(u, v, sigma, flux, sensor)) / 2 for u, v in pts]
            for d in detectors:
                b = registry.get(d)(fr, DetectorOptions())
                if len(b) == 0:
                    continue
                dist = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2)
                ok = dist.min(1) < 3
                errs[d].append((b.points_px[dist.argmin(1)] - pts)[ok])
        c = float(np.sqrt(np.mean(crb)))
        cells = []
        for d in detectors:
            e = np.concatenate(errs[d]) if errs[d] else np.zeros((0, 2))
            rms = float(np.sqrt(np.mean(e**2))) if len(e) else float("nan")
            cells.append(f"{rms / c:6.2f} ({rms:.4f})")
        print(
            f"{sigma:8.2f} {2.355 * sigma:8.2f} {flux:9.0f} {c:8.4f} "
            + " ".join(f"{x:>16}" for x in cells)
        )


def saturated_accuracy(trials: int, detectors: list[str]) -> None:
    """Centroid error on spots whose cores clip (12-bit in uint16, full well 15,000 e)."""
    full_well_e = 15000.0
    sensor = SensorModel(
        gain_dn_per_e=4095 / full_well_e, read_noise_e=4.0, background_e=100.0, bit_depth=12
    )
    cam = preset("8mp").with_size(480, 320)
    rng = np.random.default_rng(2)
    print(
        f"\nsaturated analytic spots (12-bit, full well {full_well_e:.0f} e): {trials} frames x "
        "6 spots per case; per-axis RMS error in px ('over' = peak / full well)"
    )
    print(f"{'sigma px':>8} {'over':>6} " + " ".join(f"{d:>12}" for d in detectors))
    for sigma, over in ((1.2, 5.0), (1.5, 8.0), (2.5, 10.0), (4.0, 20.0)):
        flux = over * full_well_e * 2.0 * np.pi * sigma**2
        errs: dict[str, list[np.ndarray]] = {d: [] for d in detectors}
        for _ in range(trials):
            pts = np.array(
                [[60 + 160 * i, 80 + 160 * j] for i in range(3) for j in range(2)], float
            )
            pts += rng.uniform(-0.5, 0.5, pts.shape)
            fr = Frame(render_spots((320, 480), pts, sigma, flux, sensor, rng), cam)
            for d in detectors:
                b = registry.get(d)(fr, DetectorOptions(gain_dn_per_e=sensor.gain_dn_per_e))
                if len(b) == 0:
                    continue
                dist = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2)
                ok = dist.min(1) < 3
                errs[d].append((b.points_px[dist.argmin(1)] - pts)[ok])
        cells = []
        for d in detectors:
            e = np.concatenate(errs[d]) if errs[d] else np.zeros((0, 2))
            cells.append(f"{np.sqrt(np.mean(e**2)):12.4f}" if len(e) else f"{'nan':>12}")
        print(f"{sigma:8.2f} {over:6.1f} " + " ".join(cells))


def identification(trials: int) -> None:
    """Identification on exact projections + 0.1 px noise, with hidden beacons and glints."""
    from deckpose.detect.identify import identify_beacons

    from deckpose.layout import thesis_layout

    white, red = (100.0, 100.0, 90.0), (100.0, 10.0, 5.0)
    cam = preset("8mp")
    print(f"\nidentification: {trials} random poses per row (yaw uniform, height 20-80 m, 8mp)")
    for lay_name, lay in (("default", DeckLayout()), ("thesis", thesis_layout())):
        for tilt in (5, 15, 25):
            for n_glint, hide in ((0, False), (1, True), (2, True)):
                rng = np.random.default_rng(0)
                good = glint_in_gap = 0
                for _ in range(trials):
                    lo, hi = [-tilt, -tilt, -180], [tilt, tilt, 180]
                    ship = ShipPose(*np.radians(rng.uniform(lo, hi)))
                    h = float(rng.uniform(20, 80))
                    pr = project_layout(lay, ship, CameraPose.nadir(h), cam)
                    ids = np.flatnonzero(pr.visible)
                    if hide:
                        ids = ids[ids != rng.integers(1, lay.n_ring)]
                    pts = pr.points_px[ids] + rng.normal(0, 0.1, (len(ids), 2))
                    rgb = np.array([red if i == lay.bow_id else white for i in ids])
                    for _ in range(n_glint):
                        c = pts.mean(0)
                        while True:
                            g = c + rng.uniform(-500, 500, 2)
                            if np.min(np.linalg.norm(pts - g, axis=1)) > 60:
                                break
                        pts = np.vstack([pts, g])
                        ids = np.append(ids, -1)
                        rgb = np.vstack([rgb, white])
                    r = identify_beacons(pts, lay, cam, rgb_flux=rgb)
                    if r.ok and np.array_equal(r.beacon_ids, ids):
                        good += 1
                    elif r.ok and np.sum(r.beacon_ids != ids) == 1:
                        glint_in_gap += int(ids[r.beacon_ids != ids][0] == -1)
                print(
                    f"  {lay_name:8s} tilt<={tilt:2d} deg glints={n_glint} hidden={int(hide)}: "
                    f"{good}/{trials} correct; {glint_in_gap} with a glint taken for the hidden one"
                )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--detectors", default=",".join(registry.names()))
    ap.add_argument("--skip-speed", action="store_true")
    ap.add_argument("--rendered", metavar="DATASET",
                    help="also time the detectors on frames of this rendered dataset")
    ap.add_argument("--rendered-frames", type=int, default=4,
                    help="how many frames of --rendered to time (spread over the dataset)")
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--skip-identification", action="store_true")
    ap.add_argument("--dataset", help="also run the bench-detectors report on this dataset")
    ap.add_argument("--out", help="report folder for --dataset")
    ap.add_argument("--note", default="", help="line of text for the top of the --dataset report")
    ap.add_argument(
        "--make-dataset",
        nargs=2,
        metavar=("CONFIG", "DIR"),
        help="write the synthetic dataset of CONFIG (YAML) to DIR and exit",
    )
    args = ap.parse_args()
    if args.make_dataset:
        from deckpose.detect.synthetic_dataset import read_config, write_synthetic_dataset

        t0 = time.perf_counter()
        out = write_synthetic_dataset(read_config(args.make_dataset[0]), args.make_dataset[1])
        print(f"wrote {out} in {time.perf_counter() - t0:.0f} s")
        return
    cv2.setNumThreads(1)
    dets = args.detectors.split(",")
    if not args.skip_speed:
        speed(args.repeat, dets, args.rendered, args.rendered_frames)
    if not args.skip_accuracy:
        accuracy(args.trials, dets)
        saturated_accuracy(max(1, args.trials // 5), dets)
    if not args.skip_identification:
        identification(2 * args.trials)
    if args.dataset:
        from deckpose.cli import main as cli

        cli(
            [
                "bench-detectors",
                args.dataset,
                "--detectors",
                ",".join(dets),
                "--no-progress",
                "--note",
                args.note,
            ]
            + (["--out", args.out] if args.out else [])
        )


if __name__ == "__main__":
    main()
