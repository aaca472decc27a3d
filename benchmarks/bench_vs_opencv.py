"""Our pose estimation and detection against plain OpenCV on the same inputs: the ratios of issue 20.

Two comparisons, each printed with the machine's load (interleaved repeats, medians):

1. **Pose** (``--frames``, default 2,000): exact projections of the standard deck from
   random poses (10-120 m, tilt up to 10 deg, any yaw, up to 3 m surge and sway) into the
   8 MP camera, with 0.3 px Gaussian noise on every beacon. Ours: ``pnp`` batched
   (``estimate_batch`` over all frames) and one frame at a time (``run_estimator``).
   OpenCV's: ``solvePnP(SOLVEPNP_SQPNP)`` then ``solvePnPRefineLM`` per frame on the same
   pixels and camera matrix. Accuracy: RMS roll/pitch error and height error against the
   truth; time: CPU per frame (one BLAS and one OpenCV thread).
2. **Detection, whole process** (``--detect``): one 64 MP (9248 x 6936) 16-bit RGB frame from
   :mod:`independent_spots` (no code shared with ``render/`` or ``detect/``), written as PNG
   with a camera file. Ours: ``deckpose detect FOLDER --camera cam.yaml -o OUT --workers 1``
   (``--detector cog``, a new process each run). OpenCV's: a six-line script (``imread``,
   grey, threshold, ``connectedComponentsWithStats``, centroids). Accuracy: RMS centre error of
   each against the generator's truth, and over the centroid CRB.

Run::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_vs_opencv.py [--frames 2000] [--detect] [--repeats 5]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

cv2.setNumThreads(1)

from deckpose.estimate.batch import estimate_batch, run_estimator
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import CameraModel, preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Detections

LAYOUT = DeckLayout()
CAMERA = preset("8mp")
NOISE_PX = 0.3

#: The OpenCV peer of the detection comparison: read, grey, threshold, components, centroids.
OPENCV_SCRIPT = """\
import sys, cv2, numpy as np
img = cv2.imread(sys.argv[1], cv2.IMREAD_UNCHANGED)
grey = img.astype(np.float32).sum(axis=2) if img.ndim == 3 else img.astype(np.float32)
mask = (grey > float(sys.argv[2])).astype(np.uint8)
n, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
np.save(sys.argv[3], centroids[1:][stats[1:, cv2.CC_STAT_AREA] >= 2])
"""


def _load() -> str:
    return f"1-minute load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores"


def _cpu(fn) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def pose_frames(n: int, rng: np.random.Generator) -> tuple[list[Detections], np.ndarray]:
    """``n`` noisy exact projections and their truth rows (roll, pitch, yaw, height_m)."""
    tilt = np.radians(10.0)
    dets, truth = [], []
    while len(dets) < n:
        ship = ShipPose(rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-np.pi, np.pi),
                        0.0, rng.uniform(-3, 3), rng.uniform(-3, 3))
        h = float(rng.uniform(10, 120))
        pr = project_layout(LAYOUT, ship, CameraPose.nadir(h), CAMERA)
        if not np.all(pr.in_image):
            continue
        pts = pr.points_px + rng.normal(0, NOISE_PX, pr.points_px.shape)
        dets.append(Detections(pts, np.arange(len(pts)), np.broadcast_to(np.eye(2) * NOISE_PX**2, (len(pts), 2, 2))))
        truth.append((ship.roll_rad, ship.pitch_rad, h))
    return dets, np.array(truth)


def _opencv_pose(dets: list[Detections], camera: CameraModel) -> list[tuple[np.ndarray, np.ndarray]]:
    obj = np.ascontiguousarray(LAYOUT.positions_deck_m(), dtype=np.float64)
    K = np.ascontiguousarray(camera.K, dtype=np.float64)
    out = []
    for d in dets:
        img = np.ascontiguousarray(d.points_px, dtype=np.float64)
        _, rv, tv = cv2.solvePnP(obj, img, K, None, flags=cv2.SOLVEPNP_SQPNP)
        rv, tv = cv2.solvePnPRefineLM(obj, img, K, None, rv, tv)
        out.append((rv, tv))
    return out


def _opencv_errors(sols: list[tuple[np.ndarray, np.ndarray]], truth: np.ndarray) -> np.ndarray:
    """(roll, pitch, height) errors of OpenCV's poses, in our pose parameters (nadir camera)."""
    from deckpose.estimate.pnp import params_from_rodrigues

    R_wc = CameraPose.nadir(1.0).R_world_from_cam
    p = np.array([params_from_rodrigues(rv, tv, R_wc) for rv, tv in sols])
    return np.column_stack([p[:, 0], p[:, 1], p[:, 5]]) - truth


def bench_pose(n: int, repeats: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    dets, truth = pose_frames(n, rng)
    opts = EstimateOptions()
    lone = dets[: min(n, 300)]
    t_batch, t_lone, t_cv = [], [], []
    for _ in range(repeats):  # interleaved
        t_batch.append(_cpu(lambda: estimate_batch("pnp", dets, CAMERA, LAYOUT, opts)) / n)
        t_lone.append(_cpu(lambda: [run_estimator("pnp", d, CAMERA, LAYOUT, opts) for d in lone]) / len(lone))
        t_cv.append(_cpu(lambda: _opencv_pose(dets, CAMERA)) / n)
    ests = estimate_batch("pnp", dets, CAMERA, LAYOUT, opts)
    ok = np.array([e.ok for e in ests])
    ours = np.array([(e.roll_rad, e.pitch_rad, e.height_m) for e in ests]) - truth
    cv_err = _opencv_errors(_opencv_pose(dets, CAMERA), truth)

    def rms(e: np.ndarray) -> str:
        return (f"roll {np.degrees(np.sqrt(np.mean(e[:, 0] ** 2))):.4f} deg, pitch "
                f"{np.degrees(np.sqrt(np.mean(e[:, 1] ** 2))):.4f} deg, height {np.sqrt(np.mean(e[:, 2] ** 2)):.4f} m")

    b, lo, c = float(np.median(t_batch)), float(np.median(t_lone)), float(np.median(t_cv))
    print(f"pose: {n} frames, 13 beacons, {NOISE_PX} px noise, 8 MP camera; {repeats} interleaved repeats, "
          f"median CPU per frame; {_load()}")
    print(f"  OpenCV SQPnP + RefineLM   {c * 1e6:8.1f} us   RMS {rms(cv_err)}")
    print(f"  pnp batched               {b * 1e6:8.1f} us   RMS {rms(ours[ok])}  ({int(ok.sum())}/{n} ok)"
          f"   ratio {b / c:.2f}x OpenCV")
    print(f"  pnp one frame alone       {lo * 1e6:8.1f} us   (first {len(lone)} frames)   ratio {lo / c:.2f}x OpenCV")


def _independent_frame(seed: int):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import independent_spots as gen

    spec = gen.SpotFrameSpec(width_px=9248, height_px=6936, rgb=True, bits=16, focal_px=6100.0,
                             height_m=(40.0, 60.0))
    return gen.make_frame(spec, np.random.default_rng(seed))


def _rms_to_truth(found: np.ndarray, truth_px: np.ndarray) -> tuple[float, int]:
    """RMS distance (px) of each truth centre to its nearest found point within 3 px, and misses."""
    if len(found) == 0:
        return float("nan"), len(truth_px)
    d = np.linalg.norm(truth_px[:, None, :] - found[None, :, :], axis=2)
    near = d.min(axis=1)
    hit = near < 3.0
    return float(np.sqrt(np.mean(near[hit] ** 2))) if hit.any() else float("nan"), int((~hit).sum())


def _time_detect(png: Path, camera_file: Path, thr: float, repeats: int, root: Path
                 ) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Median wall of ``deckpose detect`` and of the OpenCV script on one PNG, each a new process per run.

    Returns (ours_s, peer_s, ours_xy, peer_xy): medians over ``repeats`` interleaved runs, and
    each one's centres, pixels.
    """
    script = root / "opencv_peer.py"
    script.write_text(OPENCV_SCRIPT)
    exe = str(Path(sys.executable).parent / "deckpose")
    ours_cmd = [exe, "detect", str(png.parent), "--camera", str(camera_file), "--detector", "cog",
                "-o", "", "--workers", "1", "--no-progress", "-q"]
    peer_cmd = [sys.executable, str(script), str(png), f"{thr:.3f}", str(root / "peer.npy")]
    t_ours, t_peer = [], []
    for k in range(repeats):  # interleaved, a new process each
        out = root / f"ours{k}"
        cmd = list(ours_cmd)
        cmd[cmd.index("-o") + 1] = str(out)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        t_ours.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        subprocess.run(peer_cmd, check=True)
        t_peer.append(time.perf_counter() - t0)
    import pandas as pd

    dets = pd.read_parquet(root / "ours0" / "detections.parquet")
    return (float(np.median(t_ours)), float(np.median(t_peer)), dets[["u_px", "v_px"]].to_numpy(float),
            np.load(root / "peer.npy"))


def _report_detect(what: str, repeats: int, o: float, p: float, ours_xy: np.ndarray, peer_xy: np.ndarray,
                   truth_px: np.ndarray, crb_px: float) -> None:
    r_ours, miss_ours = _rms_to_truth(ours_xy, truth_px)
    r_peer, miss_peer = _rms_to_truth(peer_xy, truth_px)

    def over_crb(r: float) -> str:
        return f" = {r / crb_px:.2f}x CRB" if np.isfinite(crb_px) else ""

    print(f"detect, whole process: {what}; {repeats} interleaved runs, median wall; {_load()}")
    print(f"  OpenCV script (imread, threshold, components)  {p:6.2f} s   RMS {r_peer:.4f} px{over_crb(r_peer)}, "
          f"{miss_peer} missed")
    print(f"  deckpose detect --detector cog --workers 1     {o:6.2f} s   RMS {r_ours:.4f} px{over_crb(r_ours)}, "
          f"{miss_ours} missed   ratio {o / p:.2f}x the script's time, {r_peer / r_ours:.1f}x its accuracy")


def bench_detect(repeats: int, seed: int) -> None:
    from deckpose.camera_info import write_camera_info

    fr = _independent_frame(seed)
    with tempfile.TemporaryDirectory(prefix="bench_vs_opencv_") as tmp:
        root = Path(tmp)
        (root / "frames").mkdir()
        png = root / "frames" / "000000.png"
        img = fr.image if fr.image.ndim == 2 else fr.image[..., ::-1]
        cv2.imwrite(str(png), img)
        H, W = fr.image.shape[:2]
        write_camera_info(CameraModel(W, H, fr.K, np.zeros(0), "bench-64mp"), root / "cam.yaml")
        # the peer's threshold: 6 sigma of the background noise of the channel sum, in DN
        sigma_dn = fr.gain_dn_per_e * np.sqrt(3 * (30.0 + 5.0**2))
        thr = 3 * 30.0 * fr.gain_dn_per_e + 6 * sigma_dn
        o, p, ours_xy, peer_xy = _time_detect(png, root / "cam.yaml", thr, repeats, root)
    _report_detect(f"one 64 MP 16-bit RGB PNG ({W}x{H}, {len(fr.centre_px)} beacons, independent generator)",
                   repeats, o, p, ours_xy, peer_xy, fr.centre_px, float(np.sqrt(np.mean(fr.crb_px**2))))


def bench_detect_rendered(dataset: Path, frame_id: int, repeats: int) -> None:
    """The same comparison on a frame ``deckpose render`` wrote (the issue's case: a sweep's 64 MP PNG).

    The truth is the frame's visible beacons in ``beacons.parquet``; the script's threshold is
    6 robust sigmas (1.4826 MAD) above the median of the frame's channel sum.
    """
    import shutil

    import pandas as pd

    src = dataset / "images" / f"{frame_id:06d}.png"
    cams = sorted((dataset / "cameras").glob("*.yaml"))
    truth = pd.DataFrame()
    if (dataset / "beacons.parquet").is_file():
        beacons = pd.read_parquet(dataset / "beacons.parquet")
        truth = beacons[(beacons.frame_id == frame_id) & beacons.visible]
    img = cv2.imread(str(src), cv2.IMREAD_UNCHANGED) if src.is_file() else None
    if img is None or len(cams) != 1 or truth.empty:
        raise SystemExit(f"bench_vs_opencv: {dataset} needs images/{frame_id:06d}.png, one camera file and "
                         "beacons.parquet with that frame's visible beacons; render a one-camera dataset with "
                         "images")
    grey = img.astype(np.float32).sum(axis=2) if img.ndim == 3 else img.astype(np.float32)
    med = float(np.median(grey))
    thr = med + 6 * 1.4826 * float(np.median(np.abs(grey - med)))
    H, W = grey.shape
    del img, grey
    with tempfile.TemporaryDirectory(prefix="bench_vs_opencv_") as tmp:
        root = Path(tmp)
        (root / "frames").mkdir()
        png = root / "frames" / src.name
        shutil.copyfile(src, png)
        o, p, ours_xy, peer_xy = _time_detect(png, cams[0], thr, repeats, root)
    crb = truth["spot_crb_px"].to_numpy(float) if "spot_crb_px" in truth else np.full(len(truth), np.nan)
    _report_detect(f"frame {frame_id} of {dataset} ({W}x{H} PNG, {len(truth)} beacons in view, rendered)",
                   repeats, o, p, ours_xy, peer_xy, truth[["u_px", "v_px"]].to_numpy(float),
                   float(np.sqrt(np.nanmean(crb**2))) if np.isfinite(crb).any() else float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=2000, help="frames of the pose comparison (0: skip it)")
    ap.add_argument("--detect", action="store_true", help="also the whole-process detection comparison (64 MP)")
    ap.add_argument("--detect-rendered", type=Path, metavar="DATASET",
                    help="also the whole-process detection comparison on a rendered dataset's frame "
                         "(e.g. a thesis sweep's 64 MP frame, as issue 20 measured it)")
    ap.add_argument("--frame-id", type=int, default=0, help="the rendered frame (--detect-rendered)")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved repeats (medians)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"bench_vs_opencv: seed {args.seed}; OpenCV {cv2.__version__}, one thread")
    if args.frames:
        bench_pose(args.frames, args.repeats, args.seed)
    if args.detect:
        bench_detect(args.repeats, args.seed)
    if args.detect_rendered:
        bench_detect_rendered(args.detect_rendered, args.frame_id, args.repeats)


if __name__ == "__main__":
    main()
