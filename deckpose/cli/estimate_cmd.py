"""``deckpose estimate``: poses from a detections table and a camera file."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: "argparse._SubParsersAction[argparse.ArgumentParser]") -> None:
    p = sub.add_parser(
        "estimate",
        help="estimate the deck pose per frame from beacon detections",
        description=(
            "Read detections (CSV or Parquet with columns frame_id, beacon_id, u_px, v_px; "
            "beacon_id -1 = unassigned) and a ROS camera_info YAML, and write one row per frame: "
            "frame_id, method, ok, reason, roll_deg, pitch_deg, yaw_deg (ZYX), surge_m, sway_m, "
            "height_m (empty where the method does not give them), plus method extras "
            "(for --method thesis: thesis_roll_deg, thesis_pitch_deg, thesis_yaw_deg, the "
            "thesis's own X-Y-Z angles). A frame that cannot be solved gets ok=false and a reason."
        ),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("detections", type=Path, help="detections table (.csv or .parquet)")
    p.add_argument("--camera", type=Path, required=True, help="ROS camera_info YAML of the camera")
    p.add_argument("-o", "--output", type=Path, required=True, help="output table (.csv or .parquet)")
    from deckpose.estimate import registry

    p.add_argument("--method", default="thesis", choices=registry.names(), help="estimator")
    p.add_argument("--layout", type=Path, help="deck layout YAML (default: 12 ring beacons, radius 10, centre beacon)")
    p.add_argument("--radius", type=float, help="ring radius, overrides the layout's radius_m")
    p.add_argument("--refine", action="store_true", help="maximum-likelihood refinement after the estimator")
    p.add_argument("--sigma-px", type=float, default=1.0, help="pixel sigma when detections carry no covariance")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from tqdm import tqdm

    from deckpose.camera_info import read_camera_info
    from deckpose.detections_io import read_detections
    from deckpose.errors import ConfigError
    from deckpose.estimate import registry
    from deckpose.estimate.results_table import estimates_frame
    from deckpose.layout import DeckLayout, read_layout
    from deckpose.tables import write_table

    layout = read_layout(args.layout) if args.layout else DeckLayout()
    if args.radius is not None:
        if not args.radius > 0:
            raise ConfigError(f"--radius must be positive, got {args.radius}")
        layout = dataclasses.replace(layout, radius_m=float(args.radius))
    estimator = registry.get(args.method)
    options = registry.EstimateOptions(sigma_px=args.sigma_px, refine=args.refine)
    camera = read_camera_info(args.camera)
    frames = read_detections(args.detections, layout)
    ids, results = [], []
    for frame_id, det in tqdm(frames.items(), desc=f"estimate ({args.method})", unit="frame",
                              disable=None, leave=False):
        ids.append(frame_id)
        results.append(estimator(det, camera, layout, options))
    df = estimates_frame(ids, results)
    write_table(df, args.output, "estimates")
    n_ok = int(df["ok"].sum()) if len(df) else 0
    print(f"{len(df)} frames, {n_ok} ok, {len(df) - n_ok} failed -> {args.output}")
    return 0
