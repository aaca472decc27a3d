"""A tiny run folder in the dataset contract, built without the renderer.

Images carry Gaussian spots at the exact projected beacon centres, detections
are the truth plus seeded Gaussian noise, so every downstream number has a
known answer.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from deckpose.camera import preset
from deckpose.camera_info import write_camera_info
from deckpose.layout import DeckLayout, layout_to_dict
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout


def make_fake_run(root: Path, *, sigma_px: float = 0.3, seed: int = 0,
                  heights=(20.0, 40.0), n_per_cell: int = 3) -> Path:
    rng = np.random.default_rng(seed)
    layout = DeckLayout()
    cams = {"4mp-small": preset("4mp").with_size(578, 434), "8mp-small": preset("8mp").with_size(960, 540)}
    (root / "cameras").mkdir(parents=True)
    (root / "images").mkdir()
    for name, cam in cams.items():
        write_camera_info(cam, root / "cameras" / f"{name}.yaml")
    frames, beacons, dets = [], [], []
    fid = 0
    for cname, cam in cams.items():
        for h in heights:
            for k in range(n_per_cell):
                ship = ShipPose(*np.radians([rng.uniform(-8, 8), rng.uniform(-4, 4), rng.uniform(-30, 30)]),
                                heave_m=rng.uniform(-1, 1))
                pose = CameraPose.nadir(h)
                proj = project_layout(layout, ship, pose, cam)
                img = np.zeros((cam.height_px, cam.width_px), np.uint8)
                for b in np.flatnonzero(proj.visible):
                    cv2.circle(img, tuple(round(x) for x in proj.points_px[b]), 2, 255, -1)
                rel = f"images/{fid:06d}.png"
                cv2.imwrite(str(root / rel), img)
                tr, tp, ty = np.degrees(ship.thesis_angles_rad())
                row = {"frame_id": fid, "image": rel, "camera": cname, "stamp_ns": k * 100_000_000, "t_s": k * 0.1,
                           "camera_height_m": h, "roll_deg": np.degrees(ship.roll_rad), "pitch_deg": np.degrees(ship.pitch_rad),
                           "yaw_deg": np.degrees(ship.yaw_rad),
                           "heave_m": ship.heave_m, "surge_m": 0.0, "sway_m": 0.0, "thesis_roll_deg": tr, "thesis_pitch_deg": tp,
                           "thesis_yaw_deg": ty, "lighting": "night", "seed": seed, "n_visible": int(proj.visible.sum()),
                           "cam_x_m": 0.0, "cam_y_m": 0.0, "cam_z_m": h}
                for i in range(3):
                    for j in range(3):
                        row[f"R_world_from_cam_{i}{j}"] = pose.R_world_from_cam[i, j]
                frames.append(row)
                for b in range(layout.n_beacons):
                    beacons.append({"frame_id": fid, "beacon_id": b, "u_px": proj.points_px[b, 0], "v_px": proj.points_px[b, 1],
                                        "visible": bool(proj.visible[b]), "in_image": bool(proj.in_image[b]),
                                        "facing": bool(proj.facing[b]), "apparent_radius_px": proj.apparent_radius_px[b]})
                    if proj.visible[b]:
                        u, v = proj.points_px[b] + rng.normal(0, sigma_px, 2)
                        dets.append({"frame_id": fid, "beacon_id": b, "u_px": u, "v_px": v, "cov_uu": sigma_px**2, "cov_uv": 0.0,
                                         "cov_vv": sigma_px**2, "flux_dn": 1.0, "size_px": 3.0, "snr": 1.0, "detector": "fake"})
                fid += 1
    pd.DataFrame(frames).to_parquet(root / "frames.parquet", index=False)
    pd.DataFrame(beacons).to_parquet(root / "beacons.parquet", index=False)
    (root / "detections").mkdir()
    pd.DataFrame(dets).to_parquet(root / "detections" / "fake.parquet", index=False)
    (root / "manifest.json").write_text(json.dumps({"format": "deckpose-dataset/1", "seed": seed,
                                                    "layout": layout_to_dict(layout), "cameras": list(cams)}))
    return root
