"""Whether the detectors' covariances are honest on frames we did not render: RMS of error / own sigma.

Frames from the independent generator (``benchmarks/independent_spots.py``; 1920x1080, ring
210-360 px in radius, sigma 0.8-2.5 px, background 30 e, read noise 5 e), four families:
RGB 16-bit, RGB 8-bit, RGB 16-bit with bright spots (300,000-900,000 e, full well raised so
none clips) and mono 16-bit. For each detector, every found beacon whose spot did not clip gives
``(u - u_true) / sigma_u`` and the same in ``v`` with the detector's own covariance; an honest
covariance gives an RMS of 1 (its sampling error about ``1 / sqrt(2 m)`` for ``m`` beacons).

Run::

    .venv/bin/python benchmarks/independent_covariance.py --frames 12
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FAMILIES = {
    "rgb16": {"rgb": True, "bits": 16},
    "rgb8": {"rgb": True, "bits": 8},
    "rgb16-bright": {"rgb": True, "bits": 16, "flux_e": (300_000.0, 900_000.0), "full_well_e": 2e6},
    "mono16": {"rgb": False, "bits": 16},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=12, help="frames per family")
    ap.add_argument("--detectors", default="cog,gauss", help="comma-separated")
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    import independent_spots as gen
    from deckpose.detect.frame_detection import detect_frame

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout
    from deckpose.records import Frame

    small = gen.SpotFrameSpec(width_px=1920, height_px=1080, focal_px=1250.0)
    print(f"# RMS of error / own sigma per axis, unclipped found beacons; {args.frames} frames a family, "
          f"seed {args.seed}; 1-minute load {os.getloadavg()[0]:.1f}")
    print(f"{'family':>13} {'detector':>8} {'beacons':>7} {'rms z u':>7} {'rms z v':>7}  (+/- 3 sampling sd)")
    for family, over in FAMILIES.items():
        spec = replace(small, **over)
        rng = np.random.default_rng(args.seed)
        frames = [gen.make_frame(spec, rng) for _ in range(args.frames)]
        for name in args.detectors.split(","):
            z = []
            for t in frames:
                cam = CameraModel(t.image.shape[1], t.image.shape[0], t.K)
                det = detect_frame(Frame(t.image, cam, 0), name, DeckLayout()).detections
                idx, _ = gen.match(det.points_px, t)
                for i in np.flatnonzero((idx >= 0) & ~t.saturated):
                    e = det.points_px[idx[i]] - t.centre_px[i]
                    z.append(e / np.sqrt(np.diag(det.covariance_px2[idx[i]])))
            za = np.array(z).reshape(-1, 2)
            rms = np.sqrt(np.mean(za**2, axis=0)) if len(za) else np.full(2, np.nan)
            tol = 3.0 / np.sqrt(2.0 * max(len(za), 1))
            print(f"{family:>13} {name:>8} {len(za):7d} {rms[0]:7.2f} {rms[1]:7.2f}  ({tol:.2f})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
