"""A small run folder of a two-ring descent with its detect-stage output, synthesised here (no rendering).

The frames are :func:`tests.two_ring_frames.true_frame` (projected by hand) with Gaussian
pixel noise, a deck rolling and pitching slowly, the camera descending at 10 Hz. The
detect stage's output is what ``deckpose detect`` writes: every blob in
``detections/cog.parquet`` with the ids :func:`~deckpose.detect.identify.identify_beacons`
gives it (``-1`` where none) and ``detections/cog.frames.parquet`` with its ok and reason.
Frames listed in ``bow_hidden`` show their bow beacons white, as a bow out of view or
hidden does to identification: the frame alone is not identified.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.detect.identify import identify_beacons

from deckpose.camera_info import write_camera_info
from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH_NS
from deckpose.layout import layout_to_dict
from deckpose.run_folder import DATASET_FORMAT, camera_relpath, run_paths
from deckpose.table_schemas import (
    DETECT_FRAME_COLUMNS,
    DETECTION_COLUMNS,
    ROTATION_COLUMN_NAMES,
    typed_frame,
)
from deckpose.tables import write_table
from tests.two_ring_frames import LAYOUT, camera, shuffled_noisy, true_frame

#: Centre pixel noise of the synthesised detections, px.
SIGMA_PX = 0.2


def frame_truth(k: int, n: int, top_m: float, bottom_m: float) -> dict[str, float]:
    """Frame ``k`` of ``n``: the camera height (linear descent), drift and the deck's attitude, radians and metres."""
    h = top_m + (bottom_m - top_m) * k / max(n - 1, 1)
    return {"height_m": h, "x_m": 0.05 * math.sin(0.7 * k), "y_m": -0.04 * math.cos(0.5 * k),
            "roll_rad": 0.03 + 0.01 * math.sin(0.3 * k), "pitch_rad": -0.02 + 0.01 * math.cos(0.4 * k),
            "yaw_rad": 0.4 + 0.002 * k}


def write_two_ring_run(root: Path, *, n_frames: int = 10, top_m: float = 5.0, bottom_m: float = 4.0,
                       dt_s: float = 0.1, bow_hidden: tuple[int, ...] = (), seed: int = 0) -> np.ndarray:
    """Write the run folder ``root``; return the true estimator parameters per frame, (n_frames, 6)."""
    cam = camera()
    rng = np.random.default_rng(seed)
    paths = run_paths(root)
    root.mkdir(parents=True)
    paths.cameras_dir.mkdir()
    write_camera_info(cam, root / camera_relpath("cam"))
    paths.manifest.write_text(json.dumps({"format": DATASET_FORMAT, "layout": layout_to_dict(LAYOUT),
                                          "capture_epoch_ns": DEFAULT_CAPTURE_EPOCH_NS}))
    write_table(pd.DataFrame({"frame_id": [0], "beacon_id": [0]}), paths.beacons, "beacons")
    frames, det_rows, det_frames, truth = [], [], [], []
    bows = list(LAYOUT.bow_ids)
    for k in range(n_frames):
        f = true_frame(**frame_truth(k, n_frames, top_m, bottom_m))
        truth.append(f.params)
        pts, rgb, _ids = shuffled_noisy(f, SIGMA_PX, rng)
        if k in bow_hidden:
            rgb = np.where(np.isin(_ids, bows)[:, None], 1.0, rgb)  # the bow as white as the others
        ident = identify_beacons(pts, LAYOUT, cam, rgb_flux=rgb)
        row = {"frame_id": k, "image": f"images/{k:06d}.png", "camera": "cam",
               "stamp_ns": DEFAULT_CAPTURE_EPOCH_NS + round(k * dt_s * 1e9), "t_s": k * dt_s,
               "camera_height_m": top_m, "lighting": "night"}
        row.update(zip(ROTATION_COLUMN_NAMES, np.asarray(f.R_world_from_cam, float).reshape(-1), strict=True))
        frames.append(row)
        for (u, v), b in zip(pts, ident.beacon_ids, strict=True):
            det_rows.append({"frame_id": k, "beacon_id": int(b), "u_px": u, "v_px": v, "cov_uu": SIGMA_PX**2,
                             "cov_uv": 0.0, "cov_vv": SIGMA_PX**2, "flux_dn": 1000.0, "size_px": 1.5,
                             "snr": 50.0, "detector": "cog"})
        det_frames.append({"frame_id": k, "ok": ident.ok,
                           "reason": "" if ident.ok else f"identification: {ident.reason}",
                           "n_detections": len(pts), "n_identified": int(np.sum(ident.beacon_ids >= 0)),
                           "camera": "cam", "stamp_ns": row["stamp_ns"], "image": row["image"]})
    write_table(pd.DataFrame(frames), paths.frames, "frames")
    paths.detections_dir.mkdir()
    write_table(typed_frame(det_rows, DETECTION_COLUMNS), paths.detections("cog"), "detections")
    write_table(typed_frame(det_frames, DETECT_FRAME_COLUMNS), paths.detect_frames("cog"), "detect frames")
    return np.array(truth)
