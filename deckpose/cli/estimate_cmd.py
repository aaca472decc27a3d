"""``deckpose estimate``: poses from a detections table and a camera file."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from deckpose.cli.common_options import (
    HelpFormatter,
    add_progress,
    add_scheduler,
    add_workers,
    frame_bar,
    workers,
)
from deckpose.cli.console import failures, wrote
from deckpose.cli.exit_codes import frames_exit_code
from deckpose.counted import counted

if TYPE_CHECKING:
    import pandas as pd

    from deckpose.estimate import registry


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
    p.add_argument("detections", type=Path, nargs="?",
                   help="detections table (.csv or .parquet), or a folder 'deckpose detect -o' wrote (its table, "
                   "its camera and its layout; the estimates go to FOLDER/estimates.parquet unless -o says)")
    p.add_argument("--camera", type=Path, help="the camera: a ROS camera_info YAML, a 'ros2 topic echo' "
                   "CameraInfo or an OpenCV FileStorage YAML; models plumb_bob, rational_polynomial and "
                   "equidistant (fisheye; in FileStorage: fisheye_model: 1)")
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
    p.add_argument("--no-prior", action="store_true",
                   help="with --run: do not identify the frames detection left unidentified (bow beacons out of "
                   "view, too little of a ring) by the last ok estimate of their time sequence; the estimates "
                   "table's identified_by column says how each frame was identified")
    p.add_argument("--max-prior-age-s", type=float, default=0.5,
                   help="with --run: oldest ok estimate used as a prior, seconds (default 0.5)")
    add_workers(p, "estimation (a camera's frames in one chunk per worker, when there are enough; the "
                   "table does not depend on it)", zero="in this process")
    add_scheduler(p, "the chunks of frames")
    add_progress(p)
    p.add_argument("--strict", action="store_true",
                   help="exit 4 when any frame failed (default: 0 when some succeeded, 3 when none did)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from deckpose.camera_info import read_camera_info
    from deckpose.errors import ConfigError, InputDataError
    from deckpose.estimate.run import EstimateRunResult, estimate_table
    from deckpose.layout import DeckLayout, read_layout
    from deckpose.output_folder import ensure_writable
    from deckpose.run_folder import FOLDER_ESTIMATES, check_folder_camera, read_detections_folder
    from deckpose.sequence_run import estimate_run_with_prior
    from deckpose.tables import read_table, write_table

    spec = _method_spec(args)
    n_workers = workers(args)  # a bad count is refused before any work
    if args.run is not None:
        from deckpose.run_folder import read_frames, run_paths

        n_frames = len(read_frames(run_paths(args.run)))  # the bar's total (a missing run says so here)
        with frame_bar(f"estimate ({spec.label})", enabled=not args.no_progress, total=n_frames) as bar:
            res = estimate_run_with_prior(args.run, spec, detector=getattr(args, "detector", None),
                                          sigma_px=args.sigma_px, radius_m=args.radius, prior=not args.no_prior,
                                          max_prior_age_s=args.max_prior_age_s, progress=bar.update,
                                          workers=n_workers, scheduler=args.scheduler)
    else:
        if args.no_prior:
            raise ConfigError("--no-prior applies to --run RUN (a table alone has no time sequence); drop it")
        detections, camera_file, output = args.detections, args.camera, args.output
        folder = None  # the detections folder the table is in (deckpose detect -o), read once
        if detections is not None and detections.is_dir():
            folder = read_detections_folder(detections)
            if folder is None:
                raise InputDataError(_not_a_detections_folder(detections))
            detections = folder.detections
            if camera_file is None:  # the folder's camera (check_folder_camera refuses several)
                camera_file = next(iter(folder.camera_files.values()), None)
            output = folder.root / FOLDER_ESTIMATES if output is None else output
        elif detections is not None:  # a table beside a folder's record
            folder = read_detections_folder(detections.parent)
        if detections is None or camera_file is None or output is None:
            raise ConfigError("give DETECTIONS --camera CAMERA.yaml -o OUTPUT (or a folder 'deckpose detect -o' "
                              "wrote), or --run RUN --detector NAME")
        if getattr(args, "layout", None):
            layout = read_layout(args.layout)
        elif folder is not None and folder.detections.name == detections.name:
            layout = folder.layout  # the layout the folder's frames were identified with
        else:
            layout = DeckLayout()
        if args.radius is not None:
            if not (math.isfinite(args.radius) and args.radius > 0):
                raise ConfigError(f"--radius must be a finite positive number of metres, got {args.radius}")
            if not args.radius > layout.beacon_radius_m:
                raise ConfigError(
                    f"--radius {args.radius:g} m is not larger than a beacon ({layout.beacon_radius_m:g} m); "
                    "give the ring's radius in metres, or a --layout file")
            layout = dataclasses.replace(layout, radius_m=float(args.radius))
        camera = read_camera_info(camera_file)
        if folder is not None:
            check_folder_camera(folder, camera, detections)
        out = Path(output)
        if out.exists() and out.resolve() == Path(detections).resolve():
            raise ConfigError(f"-o {out} is the detections table itself: the estimates would replace the "
                              "detections; give another output file")
        ensure_writable(out.parent)  # before the work, not after it
        table = read_table(detections, "detections")
        if table.empty:
            raise InputDataError(f"{detections} holds no detections (a header without rows); give a table "
                                 "with one row per detected beacon: frame_id, beacon_id, u_px, v_px")
        n_frames = table["frame_id"].nunique() if "frame_id" in table.columns else None
        with frame_bar(f"estimate ({spec.label})", enabled=not args.no_progress, total=n_frames) as bar:
            df = estimate_table(table, camera, layout, spec, sigma_px=args.sigma_px,
                                source=str(detections), progress=bar.update, workers=n_workers,
                                scheduler=args.scheduler)
        write_table(df, out, "estimates")
        res = EstimateRunResult(out, df)
    wrote(args, res.path, res.summary() + _mean_note(res.table))
    code = frames_exit_code(res.n_frames, res.n_ok, strict=args.strict)
    failures(args, _failure_lines(res.table), failing=code != 0)
    return code


def _not_a_detections_folder(path: Path) -> str:
    """What to give instead of a folder that 'deckpose detect -o' did not write."""
    from deckpose.run_folder import DETECT_RECORD, run_paths
    from deckpose.shell_command import deckpose_command

    if run_paths(path).manifest.is_file():
        return (f"{path} is a run folder, not a detections table: estimate it as a run, "
                f"{deckpose_command('estimate', '--run', path)}")
    return (f"{path} is a folder without {DETECT_RECORD}, so not one 'deckpose detect -o' wrote; give a "
            "detections table (.csv or .parquet) with --camera CAMERA.yaml -o OUTPUT, or that folder")


#: At most this many distinct reasons are listed for the frames that were not ok.
MAX_REASONS = 8


def _failure_lines(df: pd.DataFrame) -> list[str]:
    """The frames that were not ok, counted by reason (most frequent first)."""
    if "ok" not in df.columns or "reason" not in df.columns:
        return []
    counts = df.loc[~df["ok"].astype(bool), "reason"].fillna("").astype(str).value_counts()
    lines = [f"  {counted(n, 'frame')}: {reason or 'no reason given'}"
             for reason, n in counts.head(MAX_REASONS).items()]
    if len(counts) > MAX_REASONS:
        lines.append(f"  ... and {len(counts) - MAX_REASONS} other reasons (the table's reason column)")
    return lines


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
