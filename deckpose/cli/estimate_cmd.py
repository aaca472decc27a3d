"""``deckpose estimate``: poses from a detections table and a camera file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from deckpose.cli.common_options import HelpFormatter, add_progress
from deckpose.cli.exit_codes import frames_exit_code

if TYPE_CHECKING:
    import pandas as pd
    from tqdm import tqdm

    from deckpose.camera import CameraModel
    from deckpose.estimate import registry
    from deckpose.estimate.registry import EstimateOptions
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections, PoseEstimate


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "estimate",
        help="estimate the deck pose per frame from beacon detections",
        description=(
            "Read detections (CSV or Parquet with columns frame_id, beacon_id, u_px, v_px; "
            "beacon_id -1 = unassigned; a frame of only -1 is identified from the positions, its "
            "bow from an is_bow or flux_r/flux_g/flux_b column) and a ROS camera_info YAML, and "
            "write one row per frame: "
            "frame_id, method (with its variant: pnp+mean), ok, reason, roll_deg, pitch_deg, "
            "yaw_deg (ZYX), surge_m, sway_m, "
            "height_m (empty where the method does not give them), plus method extras "
            "(for --method thesis: thesis_roll_deg, thesis_pitch_deg, thesis_yaw_deg, the "
            "thesis's own X-Y-Z angles). A frame that cannot be solved gets ok=false and a reason."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("detections", type=Path, nargs="?", help="detections table (.csv or .parquet)")
    p.add_argument("--camera", type=Path, help="ROS camera_info YAML of the camera")
    p.add_argument("-o", "--output", type=Path, help="output table (.csv or .parquet)")
    p.add_argument("--run", type=Path, help="a run folder: read RUN/detections/DETECTOR.parquet with each "
                   "frame's own camera and write RUN/estimates/DETECTOR--METHOD.parquet (METHOD with its "
                   "variant, e.g. cog--pnp+mean.parquet)")
    p.add_argument("--detector", default=argparse.SUPPRESS,
                   help="with --run: which detector's detections to use (default: the run's only detector)")
    from deckpose.estimate import registry

    p.add_argument("--method", default="pnp",
                   help=f"estimator ({', '.join(registry.names())}; default pnp), optionally with a "
                   "variant suffix: +refine (= --refine) or +mean (= --posterior-mean), e.g. "
                   "pnp+mean. thesis is the thesis's method, faithfully: it assumes the deck centre "
                   "on the optical axis and marks frames where that biases it beyond its noise")
    p.add_argument("--layout", type=Path, default=argparse.SUPPRESS,
                   help="deck layout YAML (default: 12 ring beacons, radius 10, centre beacon)")
    p.add_argument("--radius", type=float, help="ring radius, overrides the layout's radius_m")
    p.add_argument("--refine", action="store_true", help="maximum-likelihood refinement after the estimator")
    p.add_argument("--posterior-mean", action="store_true",
                   help="report the posterior mean of the pose under a uniform prior (implies --refine): "
                   "lower RMS error than the maximum-likelihood pose when the noise is large against the "
                   "ring's size in the image, the same pose when it is small; ml_* columns keep the ML pose, which "
                   "stays the pose (posterior_mean = 0) where the posterior cannot be sampled")
    p.add_argument("--sigma-px", type=float, default=1.0, help="pixel sigma when detections carry no covariance")
    add_progress(p)
    p.add_argument("--strict", action="store_true",
                   help="exit 4 when any frame failed (default: 0 when some succeeded, 3 when none did)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from tqdm import tqdm

    from deckpose.camera_info import read_camera_info
    from deckpose.detections_io import detections_from_frame, identify_unassigned
    from deckpose.errors import ConfigError
    from deckpose.estimate import registry
    from deckpose.estimate.results_table import estimates_frame
    from deckpose.layout import DeckLayout, read_layout
    from deckpose.tables import read_table, write_table

    spec = _method_spec(args)
    if args.run is not None:
        return _run_folder(args, spec)
    if args.detections is None or args.camera is None or args.output is None:
        raise ConfigError("give DETECTIONS --camera CAMERA.yaml -o OUTPUT, or --run RUN --detector NAME")
    layout = read_layout(args.layout) if getattr(args, "layout", None) else DeckLayout()
    if args.radius is not None:
        if not args.radius > 0:
            raise ConfigError(f"--radius must be positive, got {args.radius}")
        if not args.radius > layout.beacon_radius_m:
            raise ConfigError(
                f"--radius {args.radius:g} m is not larger than a beacon ({layout.beacon_radius_m:g} m); "
                "give the ring's radius in metres, or a --layout file")
        layout = dataclasses.replace(layout, radius_m=float(args.radius))
    options = registry.EstimateOptions(sigma_px=args.sigma_px, refine=spec.refine,
                                       posterior_mean=spec.posterior_mean)
    camera = read_camera_info(args.camera)
    from deckpose.output_folder import ensure_writable

    ensure_writable(Path(args.output).parent)  # before the work, not after it
    table = read_table(args.detections, "detections")
    frames = detections_from_frame(table, layout, str(args.detections))
    # detections of your own without ids (beacon_id -1): identified here, as detect does
    frames, unidentified = identify_unassigned(table, frames, layout, camera)
    ids = list(frames)
    with tqdm(total=len(ids), desc=f"estimate ({spec.label})", unit="frame", disable=True if args.no_progress else None,
              leave=False) as bar:
        results = _estimate_in_chunks(spec.name, [frames[i] for i in ids], camera, layout, options,
                                      None, bar)
    df = estimates_frame(ids, results).assign(method=spec.label)
    if unidentified:  # the frame failed for want of ids: say so, not "0 usable"
        miss = df["frame_id"].isin(list(unidentified)) & ~df["ok"].astype(bool)
        df.loc[miss, "reason"] = df.loc[miss, "frame_id"].map(unidentified)
    write_table(df, args.output, "estimates")
    n_ok = int(df["ok"].sum()) if len(df) else 0
    print(f"{len(df)} frames, {n_ok} ok, {len(df) - n_ok} failed -> {args.output}{_mean_note(df)}")
    return frames_exit_code(len(df), n_ok, strict=args.strict)


def _mean_note(df: pd.DataFrame) -> str:
    """A line on the ok frames that kept their ML pose though the posterior mean was asked for."""
    if "posterior_mean" not in df.columns:
        return ""
    kept = int((df["ok"] & (df["posterior_mean"] == 0)).sum())
    if not kept:
        return ""
    return (f"\n{kept} ok frame(s) kept the maximum-likelihood pose (posterior_mean = 0): the likelihood is "
            "too far from the Laplace approximation for the posterior sample (posterior_effective_nodes < 8), "
            "as with few beacons and a weakly determined pose")


def _method_spec(args: argparse.Namespace) -> registry.MethodSpec:
    """The estimator and its variant from ``--method`` (``pnp+mean``) and the flags."""
    import dataclasses

    from deckpose.estimate import registry

    spec = registry.parse_method(args.method)
    return dataclasses.replace(spec, refine=spec.refine or args.refine,
                               posterior_mean=spec.posterior_mean or args.posterior_mean)


def _estimate_in_chunks(method: str, detections: list[Detections], camera: CameraModel,
                        layout: DeckLayout, options: EstimateOptions,
                        R_world_from_cam: np.ndarray | None, bar: tqdm, chunk: int = 4096,
                        ) -> list[PoseEstimate]:
    """:func:`~deckpose.estimate.batch.estimate_batch` over ``chunk`` frames at a time, advancing ``bar``."""
    from deckpose.estimate.batch import estimate_batch

    out: list[PoseEstimate] = []
    for lo in range(0, len(detections), chunk):
        R = None if R_world_from_cam is None else R_world_from_cam[lo:lo + chunk]
        out.extend(estimate_batch(method, detections[lo:lo + chunk], camera, layout, options,
                                  R_world_from_cam=R))
        bar.update(len(detections[lo:lo + chunk]))
    return out


def _run_folder(args: argparse.Namespace, spec: registry.MethodSpec) -> int:
    """``--run`` mode: per-frame cameras and camera attitudes from the dataset's frames table.

    The output is named after the variant's label (``RUN/estimates/cog--pnp+mean.parquet``), so
    a method's variants sit side by side.
    """
    import dataclasses

    from tqdm import tqdm

    from deckpose.detections_io import detections_from_frame
    from deckpose.errors import ConfigError
    from deckpose.estimate import registry
    from deckpose.estimate.results_table import estimates_frame
    from deckpose.evaluate import run_layout as rl
    from deckpose.tables import write_table

    run = rl.run_paths(args.run)
    rl.require_dataset(run)  # a missing folder says so, not "no detections"
    from deckpose.output_folder import claim_output

    claim_output(run.root, what="estimate")
    detectors = run.detectors()
    if getattr(args, "detector", None) is None:
        if len(detectors) != 1:
            raise ConfigError(f"--run needs --detector (this run has detections of: {detectors or 'none'})")
        args.detector = detectors[0]
    layout = rl.read_layout(run)
    if args.radius is not None:
        layout = dataclasses.replace(layout, radius_m=float(args.radius))
    frames = rl.read_frames(run).set_index("frame_id")
    cameras = rl.read_cameras(run, sorted(frames["camera"].unique()))
    det_df = rl.read_detections(run, args.detector)
    rl.check_frames_match(frames.reset_index(), det_df, f"detections of {args.detector}",
                          f"deckpose detect {run.root} --detector {args.detector}")
    dets = detections_from_frame(det_df, layout, str(run.detections(args.detector)))
    from deckpose.records import Detections

    options = registry.EstimateOptions(sigma_px=args.sigma_px, refine=spec.refine,
                                       posterior_mean=spec.posterior_mean)
    ids = [int(f) for f in frames.index]
    R_all = rl.R_world_from_cam_all(frames)
    results: list[PoseEstimate | None] = [None] * len(ids)
    with tqdm(total=len(ids), desc=f"estimate ({spec.label})", unit="frame", disable=True if args.no_progress else None,
              leave=False) as bar:
        # One batch per camera, each frame with its own camera attitude.
        for cam_name, rows in frames.reset_index().groupby("camera", sort=True).indices.items():
            dets_cam = [dets.get(ids[k], Detections(np.zeros((0, 2)), np.zeros(0, dtype=np.int64),
                                                    frame_id=ids[k])) for k in rows]
            got = _estimate_in_chunks(spec.name, dets_cam, cameras[cam_name], layout, options,
                                      R_all[rows], bar)
            for k, e in zip(rows, got):
                results[k] = e
    df = estimates_frame(ids, results).assign(method=spec.label)  # type: ignore[arg-type]
    out = run.estimates(args.detector, spec.label)
    write_table(df, out, "estimates")
    n_ok = int(df["ok"].sum()) if len(df) else 0
    print(f"{len(df)} frames, {n_ok} ok, {len(df) - n_ok} failed -> {out}{_mean_note(df)}")
    return frames_exit_code(len(df), n_ok, strict=args.strict)
