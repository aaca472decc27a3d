"""The painted ring's edge points against the true edges, around the ring (issue 22's pitch excess).

For each frame of a rendered painted-ring dataset (one lighting), the ring's edges are detected
(:func:`deckpose.detect.ring_edges.detect_ring_edges`) and each edge point's signed distance
from its true edge conic (``painted_ring.parquet``) is taken along the conic's normal, positive
toward the paint, in units of the point's own Cramér–Rao bound (``z``). Each point's deck angle
``theta`` (0 at the bow, toward port positive) is its ray's intersection with the true deck.

Printed (markdown), per camera height and edge:

* ``z_rms``: RMS of ``z`` (1: the points scatter at their bounds);
* ``t_mean, t_cos, t_sin, t_cos2, t_sin2``: RMS over the frames of each harmonic's least-squares
  coefficient (``z`` against 1, cos, sin, cos 2, sin 2 of ``theta``) over its standard error were
  the points independent at their own RMS scatter: 1 for such noise; ``mean_z``: the mean
  harmonic's average (a bias of the edge toward the paint, positive: the ring looks narrower);
* ``corr_frames``: the mean correlation between frames of the points' ``z`` averaged in 10 degree
  bins of ``theta`` (each frame's mean removed): 0 for noise drawn anew per frame, near 1 for an
  error fixed to the deck (its texture, the same in every frame);

and per height the pose's errors over its correlated-noise bound (RMS over the frames) with the
line width fixed and free (:data:`deckpose.estimate.painted_ring_pose.FREE_WIDTH`).

    .venv/bin/python benchmarks/ring_edge_errors.py RUN --lighting day
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
#: Width of the angle bins of the between-frames correlation, degrees.
BIN_DEG = 10.0


def _deck_angle(points_px: FloatArray, T_cam_from_deck: FloatArray, K: FloatArray) -> FloatArray:
    """Deck angle (radians, 0 at the bow, +y positive) where each pixel's ray meets the deck plane."""
    rays = np.linalg.solve(K, np.column_stack([points_px, np.ones(len(points_px))]).T).T  # camera frame
    R, t = T_cam_from_deck[:3, :3], T_cam_from_deck[:3, 3]
    n = R[:, 2]  # the deck's normal in the camera frame
    s = float(n @ t) / (rays @ n)
    P = (s[:, None] * rays - t) @ R  # deck frame
    return np.arctan2(P[:, 1], P[:, 0])


def _signed_distance_px(C: FloatArray, points_px: FloatArray) -> FloatArray:
    """First-order distance of points from the conic ``C`` (negative inside), pixels, positive outside."""
    h = np.column_stack([points_px, np.ones(len(points_px))])
    value = np.einsum("ni,ij,nj->n", h, C, h)
    grad = 2.0 * (h @ C)[:, :2]
    return value / np.linalg.norm(grad, axis=1)


def _harmonic_t(theta: FloatArray, z: FloatArray) -> FloatArray:
    """Coefficients of z on (1, cos, sin, cos 2, sin 2) over their standard errors at z's own RMS, (5,)."""
    B = np.column_stack([np.ones_like(theta), np.cos(theta), np.sin(theta), np.cos(2 * theta), np.sin(2 * theta)])
    scale = float(np.sqrt(np.mean(z ** 2)))
    cov = np.linalg.inv(B.T @ B)
    coef = cov @ B.T @ z
    return np.asarray(coef / (scale * np.sqrt(np.diag(cov))), dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a dataset rendered with a painted_ring: section")
    ap.add_argument("--lighting", default="day", help="day, dusk or night")
    ap.add_argument("--frames", type=int, default=0, help="at most this many frames (0: all of the lighting)")
    args = ap.parse_args(argv)

    from deckpose.detect.ring_edges import detect_ring_edges
    from deckpose.detect.sources import read_image
    from deckpose.estimate.painted_ring_pose import estimate_painted_ring
    from deckpose.estimate.pose_model import params_from_relative

    from deckpose.painted_ring_run import painted_ring_of_run
    from deckpose.pose import T_cam_from_deck
    from deckpose.run_folder import RunPaths, frame_poses, read_cameras, read_frames

    run = RunPaths(Path(args.run))
    ring = painted_ring_of_run(run)
    frames = read_frames(run)
    cameras = read_cameras(run)
    truth = pd.read_parquet(run.root / "painted_ring.parquet")
    sel = frames[frames["lighting"] == args.lighting]
    if args.frames:
        sel = sel.head(args.frames)
    if sel.empty:
        print(f"{run.root}: no {args.lighting} frames", file=sys.stderr)
        return 1
    points, poses = [], []
    for _, f in sel.iterrows():
        fid = int(f["frame_id"])
        camera = cameras[str(f["camera"])]
        if camera.has_distortion:
            print(f"{run.root}: frame {fid}: a distorted camera (this check takes the truth conics as the image's)",
                  file=sys.stderr)
            return 1
        img = read_image(run.root / str(f["image"]))
        if isinstance(img, str):
            continue
        det = detect_ring_edges(img, camera, ring, frame_id=fid)
        if not det.ok:
            continue
        ship, cam = frame_poses(f)
        T = T_cam_from_deck(ship, cam)
        for edge, pts, crb in (("inner", det.inner_px, det.inner_crb_px), ("outer", det.outer_px, det.outer_crb_px)):
            row = truth[(truth["frame_id"] == fid) & (truth["edge"] == edge)].iloc[0]
            C = np.array([[float(row[f"conic_px_{i}{j}"]) for j in range(3)] for i in range(3)])
            toward_paint = 1.0 if edge == "inner" else -1.0
            z = toward_paint * _signed_distance_px(0.5 * (C + C.T), pts) / crb
            points.append(pd.DataFrame({"frame_id": fid, "height_m": float(f["camera_height_m"]), "edge": edge,
                                        "theta": _deck_angle(pts, T, camera.K), "z": z}))
        true = params_from_relative(T[:3, :3], T[:3, 3], cam.R_world_from_cam)
        for free in (False, True):
            res = estimate_painted_ring(det, camera, ring, cam.R_world_from_cam, free_width=free)
            e, b = res.estimate, res.bound_correlated
            if not e.ok or b is None:
                continue
            err = np.array([e.roll_rad, e.pitch_rad, e.yaw_rad, e.surge_m, e.sway_m, e.height_m]) - true
            err[:3] = (err[:3] + math.pi) % (2 * math.pi) - math.pi
            poses.append({"height_m": float(f["camera_height_m"]), "free_width": free,
                          **dict(zip(("roll", "pitch", "yaw", "surge", "sway", "height"),
                                     err / np.sqrt(np.diag(b)), strict=True))})
    P = pd.concat(points, ignore_index=True)
    print(f"# Painted ring edge points against the true edges: {run.root}, {args.lighting}, "
          f"{P['frame_id'].nunique()} frames\n")
    print("| height_m | edge | z_rms | mean_z | t_mean | t_cos | t_sin | t_cos2 | t_sin2 | corr_frames |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    nb = round(360 / BIN_DEG)
    for (h, edge), g in P.groupby(["height_m", "edge"], sort=True):
        t = np.array([_harmonic_t(q["theta"].to_numpy(float), q["z"].to_numpy(float)) for _, q in g.groupby("frame_id")])
        b = np.clip(((g["theta"] + math.pi) / (2 * math.pi) * nb).astype(int), 0, nb - 1)
        M = g.assign(b=b).groupby(["frame_id", "b"])["z"].mean().unstack()
        A = M.sub(M.mean(axis=1), axis=0).to_numpy(float)
        corr = np.ma.corrcoef(np.ma.masked_invalid(A))
        off = np.asarray(corr[~np.eye(len(corr), dtype=bool)], dtype=float)
        rms_t = np.sqrt(np.mean(t ** 2, axis=0))
        print(f"| {h:g} | {edge} | {math.sqrt(float(np.mean(g['z'] ** 2))):.2f} | {float(g['z'].mean()):+.3f} | "
              + " | ".join(f"{v:.2f}" for v in rms_t) + f" | {float(np.mean(off)):.2f} |")
    Q = pd.DataFrame(poses)
    names = ["roll", "pitch", "yaw", "surge", "sway", "height"]
    print("\nPose error over its correlated-noise bound, RMS over the frames:\n")
    print("| height_m | line width | frames | " + " | ".join(names) + " | tilt |")
    print("|---|---|---|" + "---|" * (len(names) + 1))
    groups = [(h, free, g) for (h, free), g in Q.groupby(["height_m", "free_width"], sort=True)]
    groups += [("all", free, g) for free, g in Q.groupby("free_width", sort=True)]
    for h, free, g in groups:
        rms = [math.sqrt(float(np.mean(g[p] ** 2))) for p in names]
        tilt = math.sqrt(0.5 * (rms[0] ** 2 + rms[1] ** 2))
        print(f"| {h} | {'free' if free else 'fixed'} | {len(g)} | " + " | ".join(f"{v:.2f}" for v in rms)
              + f" | {tilt:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
