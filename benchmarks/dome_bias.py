"""How much of the pose error a domed beacon's light-centroid bias causes (issue 23 item 2).

A beacon under a constant-radiance dome is imaged centred on its light centroid, not on the
projection of its centre, the pose truth (:mod:`deckpose.render.emitter`; ``leds: {emitter:
dome}`` renders it and records both truths). This script takes, for each camera and height,
random deck poses (roll and pitch within +-5 deg, any yaw, surge and sway within +-3 m, a
nadir camera), and per pose:

* the offset of every beacon's light centroid from its projected centre, pixels;
* the pose that ``pnp`` estimates from the light centroids, noise-free: its error against the
  truth is the bias's share of the pose error, and nothing else (from the projected centres
  the same estimator returns the truth to 1e-9);
* that error over the pose's own sigma when each centroid carries ``--noise-px`` of noise
  (the estimator's covariance; the thesis sweep's ``cog`` errors are 0.002-0.015 px): above
  about 1 the bias dominates the pose error, and a detector can only remove it by knowing
  the emitter.

The pose sigma scales with the centroid noise, so the ratio at another noise ``s`` is the
printed one times ``--noise-px / s``.

Run::

    .venv/bin/python benchmarks/dome_bias.py [--poses 200] [--noise-px 0.01] [--out reports/dome_bias.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np
from deckpose.estimate.batch import estimate_batch
from deckpose.estimate.registry import EstimateOptions
from deckpose.render.emitter import dome_light_centroids

from deckpose.atomic_io import atomic_open
from deckpose.camera import CameraModel, preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import POSE_PARAMS, Detections

CAMERAS = ("4mp-thesis", "8mp-thesis", "8mp-square", "16mp-thesis", "64mp-thesis", "64mp-square")
HEIGHTS_M = (20.0, 30.0, 50.0, 80.0)
#: A pose is estimated where at least this many beacons are in the image (the ring may leave it low down).
MIN_BEACONS = 8
#: Reported pose parameters and their display units (radians shown in degrees).
SHOWN = (("roll_rad", "roll deg"), ("pitch_rad", "pitch deg"), ("yaw_rad", "yaw deg"), ("height_m", "height m"),
         ("surge_m", "surge m"), ("sway_m", "sway m"))


def poses(n: int, rng: np.random.Generator) -> list[ShipPose]:
    """``n`` deck poses: roll, pitch U(+-5 deg), yaw U(+-180 deg), surge and sway U(+-3 m), heave 0."""
    t = np.radians(5.0)
    return [ShipPose(roll_rad=rng.uniform(-t, t), pitch_rad=rng.uniform(-t, t), yaw_rad=rng.uniform(-np.pi, np.pi),
                     heave_m=0.0, surge_m=rng.uniform(-3, 3), sway_m=rng.uniform(-3, 3)) for _ in range(n)]


def cell(camera: CameraModel, height_m: float, ships: list[ShipPose], layout: DeckLayout, noise_px: float
         ) -> dict[str, float]:
    """Offsets and the pose bias over ``ships`` seen from ``height_m``: one table row."""
    cam_pose = CameraPose.nadir(height_m)
    offsets, dets, truth = [], [], []
    cov = np.broadcast_to(np.eye(2) * noise_px**2, (layout.n_beacons, 2, 2))
    for ship in ships:
        pr = project_layout(layout, ship, cam_pose, camera)
        seen = np.flatnonzero(pr.in_image)
        if len(seen) < MIN_BEACONS:
            continue
        light = dome_light_centroids(layout, cam_pose.T_cam_from_world @ ship.T_world_from_deck, camera)[seen]
        offsets.append(np.hypot(*(light - pr.points_px[seen]).T))
        dets.append(Detections(light, seen, cov[: len(seen)]))
        # the truth in POSE_PARAMS order: the deck's attitude and offset, the camera's height above it
        truth.append([ship.roll_rad, ship.pitch_rad, ship.yaw_rad, ship.surge_m, ship.sway_m, height_m - ship.heave_m])
    est = estimate_batch("pnp", dets, camera, layout, EstimateOptions())
    ok = np.array([e.ok for e in est])
    err = np.array([[getattr(e, k) for k in POSE_PARAMS] for e in est]) - np.array(truth)
    sig = np.array([np.sqrt(np.diag(e.covariance)) if e.covariance is not None else np.full(6, np.nan)
                    for e in est])
    off = np.concatenate(offsets)
    row: dict[str, float] = {"frames": float(len(dets)), "ok": float(ok.mean()),
                             "offset_mean_px": float(off.mean()), "offset_max_px": float(off.max())}
    for k, label in SHOWN:
        j = POSE_PARAMS.index(k)
        scale = np.degrees(1.0) if k.endswith("_rad") else 1.0
        row[f"bias {label}"] = float(np.sqrt(np.mean(err[ok, j] ** 2)) * scale)
        row[f"bias/sigma {label}"] = float(np.sqrt(np.mean((err[ok, j] / sig[ok, j]) ** 2)))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=200, help="deck poses per camera and height")
    ap.add_argument("--noise-px", type=float, default=0.01, help="centroid noise for the pose sigma, px")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("reports/dome_bias.md"))
    args = ap.parse_args()
    layout = DeckLayout()
    t0 = time.time()
    rows = []
    for name in CAMERAS:
        cam = preset(name)
        for h in HEIGHTS_M:
            ships = poses(args.poses, np.random.default_rng([args.seed, int(h)]))
            rows.append({"camera": name, "height_m": h, **cell(cam, h, ships, layout, args.noise_px)})
            print(f"{name} {h:g} m: offset mean {rows[-1]['offset_mean_px']:.3f} px", flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True).stdout.strip()
    head = ["camera", "height m", "frames", "offset mean px", "offset max px"]
    cols = ["camera", "height_m", "frames", "offset_mean_px", "offset_max_px"]
    for _, label in SHOWN:
        head.append(f"bias {label}")
        cols.append(f"bias {label}")
    for _, label in SHOWN[:4]:
        head.append(f"bias/σ {label.split()[0]}")
        cols.append(f"bias/sigma {label}")
    lines = [
        "# The domed beacon's bias in the pose (issue 23 item 2)", "",
        (f"Made by `.venv/bin/python benchmarks/dome_bias.py --poses {args.poses} --noise-px {args.noise_px:g} "
         f"--seed {args.seed} --out {args.out}` at commit {commit} on {platform.machine()}, {os.cpu_count()} cores, "
         f"in {time.time() - t0:.0f} s."), "",
        (f"Layout: {layout.n_ring} ring beacons at {layout.radius_m:g} m and the centre, domes of "
         f"{layout.beacon_radius_m:g} m radius (the beacon's). Per camera and height, {args.poses} deck poses "
         "(roll and pitch within ±5°, any yaw, surge and sway within ±3 m) under a nadir camera; frames with "
         f"fewer than {MIN_BEACONS} beacons in the image are left out, the others use the beacons in view. "
         "*offset*: the light centroid's distance from the projected centre (mean and largest over the beacons "
         "and poses). *bias*: RMS error of the `pnp` pose estimated from the noise-free light centroids, against "
         "the truth: the pose error the dome alone causes. *bias/σ*: that error over the pose's own sigma when "
         f"each centroid carries {args.noise_px:g} px of noise (RMS over the poses; at a noise `s` multiply by "
         f"{args.noise_px:g} / s)."), "",
        "| " + " | ".join(head) + " |", "|" + "---|" * len(head),
    ]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            cells.append(v if isinstance(v, str) else (f"{v:g}" if c in ("height_m", "frames") else f"{v:.3g}"))
        lines.append("| " + " | ".join(cells) + " |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
