"""Detect on a rendered dataset and score against its ground truth (beacons.parquet).

Usage: python benchmarks/rendered_detect.py DATASET [DETECTOR ...]
Prints, per detector and lighting, the identified-frame rate and the centroid RMS
of identified beacons (distorted pixels).
"""

from __future__ import annotations

import sys
from collections import defaultdict

import numpy as np
import pandas as pd
from deckpose.detect import registry
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.sources import load_frame, open_dataset


def main() -> None:
    root = sys.argv[1]
    detectors = sys.argv[2:] or registry.names()
    fs = open_dataset(root)
    frames = pd.read_parquet(f"{root}/frames.parquet").set_index("frame_id")
    gt = pd.read_parquet(f"{root}/beacons.parquet").set_index(["frame_id", "beacon_id"])
    for det in detectors:
        ok: dict[str, list[bool]] = defaultdict(list)
        err: dict[str, list[float]] = defaultdict(list)
        fails = []
        for src in fs.sources:
            frame = load_frame(src, fs.cameras[src.camera_name])
            light = str(frames.loc[src.frame_id, "lighting"])
            if isinstance(frame, str):
                ok[light].append(False)
                continue
            fd = detect_frame(frame, det, fs.layout)
            ok[light].append(fd.ok)
            if not fd.ok:
                fails.append((src.frame_id, light, fd.reason[:100]))
            d = fd.detections
            for (u, v), i in zip(d.points_px, d.beacon_ids):
                if i >= 0 and (src.frame_id, int(i)) in gt.index:
                    g = gt.loc[(src.frame_id, int(i))]
                    err[light].append(float(np.hypot(u - g.u_px, v - g.v_px)))
        for light, oks in ok.items():
            e = np.asarray(err[light])
            rms = float(np.sqrt(np.mean(e**2))) if e.size else float("nan")
            mx = float(e.max()) if e.size else float("nan")
            print(f"{det:12s} {light:6s} ok {sum(oks)}/{len(oks)}  "
                  f"rms {rms:.3f} px  max {mx:.3f} px  n {e.size}")
        for f in fails[:6]:
            print("   fail", *f)


if __name__ == "__main__":
    main()
