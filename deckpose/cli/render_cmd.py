"""``deckpose render CONFIG.yaml OUT``: render a dataset of frames with exact ground truth."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from deckpose.cli.common_options import (
    add_output,
    add_progress,
    add_scheduler,
    add_workers,
    workers,
)
from deckpose.cli.console import say, wrote
from deckpose.counted import counted


def _duration(seconds: float) -> str:
    """``12.3 s``, ``4 min 05 s`` or ``2 h 03 min``: a wall time for a person."""
    if round(seconds, 1) < 60:
        return f"{seconds:.1f} s"
    minutes, s = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {s:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _config_keys() -> list[str]:
    """The render config's top-level keys, read off its record (the one list of them)."""
    import dataclasses

    from deckpose.render.config import RenderConfig

    return [f.name for f in dataclasses.fields(RenderConfig)]


def register(subparsers: Any) -> None:
    """Add the ``render`` subcommand."""
    p = subparsers.add_parser(
        "render",
        help="render a synthetic dataset (images + ground truth) from a YAML config",
        description="Render a dataset: images/, frames.parquet, beacons.parquet, manifest.json. "
                    "Example: deckpose render configs/smoke.yaml datasets/smoke "
                    "('deckpose render' alone renders the embedded smoke config into datasets/smoke)",
        epilog=f"A config's top-level keys: {', '.join(_config_keys())}; the README's "
               "'Rendering datasets' section explains each (configs/ has examples).",
    )
    p.add_argument("config", type=Path, nargs="?", default=None,
                   help="render config YAML (see configs/); default: the embedded smoke config")
    p.add_argument("out", type=Path, nargs="?", default=None,
                   help="dataset folder (default: datasets/<config name>); or give it with -o")
    add_output(p, "dataset folder (the same as OUT; -o as on detect, estimate and export)", metavar="DIR")
    add_workers(p, "local render", zero="render in this process")
    p.add_argument("--backend", choices=["egl", "osmesa"], default=None,
                   help="headless GL backend (overrides the config)")
    p.add_argument("--resume", action="store_true", help="finish an interrupted run of the same config")
    add_scheduler(p, "frames")
    p.add_argument("--seed", type=int, default=None, help="override the config's seed")
    p.add_argument("--detect", default=None, metavar="DETECTORS",
                   help="also detect each frame as it is rendered, from memory, with these detectors "
                        "(comma-separated; default options); writes detections/<detector>.parquet as "
                        "'deckpose detect' would, without decoding a frame")
    p.add_argument("--no-images", action="store_true",
                   help="keep no frame (previews and tables only); needs --detect")
    add_progress(p)
    p.set_defaults(func=run, resume_hint="finished frames are kept whole; add --resume to the same command to render the rest")


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from deckpose.errors import ConfigError
    from deckpose.render.config import Backend, default_config, load_config
    from deckpose.render.dataset import render_dataset

    if args.output is not None and args.out is not None and args.output != args.out:
        raise ConfigError(f"two output folders given ({args.out} and -o {args.output}); give one")
    cfg = default_config() if args.config is None else load_config(args.config)
    if args.backend:
        cfg = dataclasses.replace(cfg, backend=Backend(args.backend))
    if args.seed is not None:
        cfg = dataclasses.replace(cfg, seed=args.seed)
    out = args.output or args.out or Path("datasets") / cfg.name
    detection = None
    if args.detect is not None or args.no_images:
        from deckpose.render.dataset import sensor_block
        from deckpose.render.render_detection import RenderDetection, resolve_detection

        names = tuple(n.strip() for n in (args.detect or "").split(",") if n.strip())
        if args.detect is not None and not names:
            raise ConfigError("--detect needs detector names, e.g. --detect cog,gauss (see 'deckpose detect --list')")
        # checked before the output folder is claimed (created), as a config is
        detection = resolve_detection(RenderDetection(detectors=names, keep_images=not args.no_images),
                                      sensor_block(cfg))
    from deckpose.output_folder import claim_output
    from deckpose.run_folder import RunPaths, read_frames

    n_workers = workers(args)  # a bad count is refused before the output folder is claimed (created)

    # room for at least the largest frame (uncompressed), checked before anything is written
    biggest = max(c.width_px * c.height_px for c in cfg.cameras_by_name().values())
    claim_output(out, need_bytes=biggest * 3 * (2 if cfg.sensor.bit_depth > 8 else 1), what="render")
    t0 = time.perf_counter()
    path = render_dataset(cfg, out, workers=n_workers, resume=args.resume, scheduler=args.scheduler,
                          progress=not args.no_progress, detection=detection)
    n_frames = len(read_frames(RunPaths(path)))
    took = _duration(time.perf_counter() - t0)
    wrote(args, path, f"dataset of {counted(n_frames, 'frame')} written to {path} in {took}"
                      + (" (resumed: only the frames not yet written were rendered)" if args.resume else ""))
    if detection is not None and detection.detectors:
        for name in detection.detectors:
            say(args, f"detections at render time: {RunPaths(path).detections(name)}")
    return 0
