"""A small run folder for the tracking tests: a sea-state-6 series as frames, truth plus noise as estimates.

No rendering: the frames table holds the truth (as render writes it), the estimates table is
the truth relative to the camera plus Gaussian noise drawn from each frame's stated covariance.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH_NS
from deckpose.estimates_schema import COVARIANCE_COLUMNS, ESTIMATE_COLUMNS, SIGMA_COLUMNS
from deckpose.motion.config import parse_sea_run
from deckpose.motion.irregular import irregular_series
from deckpose.run_folder import DATASET_FORMAT, run_paths
from deckpose.table_schemas import typed_frame
from deckpose.tables import write_table

#: Per-frame estimate sigmas: roll, pitch, yaw (deg), surge, sway, height (m) (pnp at ~40 m, 8 MP, 0.2 px).
SIGMAS = (0.04, 0.04, 0.006, 0.0013, 0.0013, 0.004)


def sea_series(duration_s: float, dt_s: float, seed: int):
    run = parse_sea_run({"seed": seed, "duration_s": duration_s, "dt_s": dt_s})
    return irregular_series(run.ship, run.sea, duration_s=run.duration_s, dt_s=run.dt_s,
                            rng=np.random.default_rng(seed))


def write_run(root: Path, *, duration_s: float = 40.0, dt_s: float = 0.1, heights_m: tuple[float, ...] = (40.0,),
              seed: int = 4, not_ok: tuple[int, ...] = (), outliers: tuple[int, ...] = (),
              sigma_scale: float = 1.0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write ``root`` (manifest, frames, beacons, estimates/cog--pnp.parquet); return frames and estimates."""
    s = sea_series(duration_s, dt_s, seed)
    n = len(s.t_s)
    rng = np.random.default_rng(seed + 100)
    sig = np.array(SIGMAS) * sigma_scale
    sig_rad = sig.copy()
    sig_rad[:3] = np.radians(sig[:3])
    frames, est = [], []
    fid = 0
    for h in heights_m:
        for i in range(n):
            frames.append({"frame_id": fid, "image": f"images/{fid:06d}.png", "camera": "8mp", "stamp_ns":
                           DEFAULT_CAPTURE_EPOCH_NS + round(float(s.t_s[i]) * 1e9) + int(fid // n) * 10**12,
                           "t_s": float(s.t_s[i]), "camera_height_m": h, "lighting": "night",
                           "roll_deg": math.degrees(s.roll_rad[i]), "pitch_deg": math.degrees(s.pitch_rad[i]),
                           "yaw_deg": math.degrees(s.yaw_rad[i]),
                           "heave_m": s.heave_m[i], "surge_m": s.surge_m[i], "sway_m": s.sway_m[i],
                           "cam_x_m": 0.0, "cam_y_m": 0.0, "cam_z_m": h})
            truth = np.array([s.roll_rad[i], s.pitch_rad[i], s.yaw_rad[i], s.surge_m[i], s.sway_m[i],
                              h - s.heave_m[i]])
            z = truth + rng.normal(size=6) * sig_rad
            if fid in outliers:
                z[0] += math.radians(3.0)
            row: dict[str, object] = {"frame_id": fid, "method": "pnp", "ok": fid not in not_ok,
                                      "reason": "" if fid not in not_ok else "too few beacons"}
            for k, name in enumerate(("roll_deg", "pitch_deg", "yaw_deg", "surge_m", "sway_m", "height_m")):
                row[name] = math.degrees(z[k]) if k < 3 else z[k]
            for k, name in enumerate(SIGMA_COLUMNS):
                row[name] = sig[k]
            for name, a, b in COVARIANCE_COLUMNS:
                row[name] = sig_rad[a] ** 2 if a == b else 0.0
            est.append(row)
            fid += 1
    root.mkdir(parents=True, exist_ok=True)
    paths = run_paths(root)
    paths.manifest.write_text(json.dumps({"format": DATASET_FORMAT, "capture_epoch_ns": DEFAULT_CAPTURE_EPOCH_NS}))
    frames_df = pd.DataFrame(frames)
    write_table(frames_df, paths.frames, "frames")
    write_table(pd.DataFrame({"frame_id": [0], "beacon_id": [0]}), paths.beacons, "beacons")
    est_df = typed_frame(est, ESTIMATE_COLUMNS)
    paths.estimates_dir.mkdir(exist_ok=True)
    write_table(est_df, paths.estimates("cog", "pnp"), "estimates")
    return frames_df, est_df
