"""``deckpose detect``: beacon detections of a dataset or an image folder, as Parquet tables."""

from __future__ import annotations

import argparse

from deckpose.cli.common_options import add_output, add_workers, workers
from deckpose.cli.console import failures, wrote


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "detect",
        help="detect and identify beacons in a dataset or a folder of images",
        description=(
            "Detect the deck beacons in every frame of DATASET (a deckpose dataset folder) or of "
            "a folder of images (then --camera and -o are required) and write a detections "
            "table (one row per frame x detection; beacon_id -1 = unassigned) and a frames table "
            "(one row per frame, with ok/reason). The output feeds 'deckpose estimate'. Bad "
            "frames are reported and skipped."
        ),
    )
    p.add_argument(
        "dataset",
        metavar="DATASET",
        nargs="?",
        help="dataset folder, or a folder of images (not needed with --list)",
    )
    p.add_argument("--detector", default="cog", help="detector name (see --list); default cog")
    add_output(
        p,
        "self-contained output folder (detections.parquet, detect_frames.parquet, cameras/, "
        "detect_run.json); default for a dataset: DATASET/detections/<detector>.parquet and "
        "<detector>.frames.parquet, where 'deckpose estimate --run DATASET' reads them; "
        "required for a folder of images",
        metavar="DIR", dest="out",
    )
    p.add_argument("--camera-info", dest="camera_info", help=argparse.SUPPRESS)  # old spelling
    p.add_argument(
        "--camera",
        dest="camera_info",
        metavar="CAMERA.yaml",
        help="ROS camera_info YAML for a folder of images",
    )
    p.add_argument(
        "--layout", help="layout YAML for a folder of images (default: the standard layout)"
    )
    p.add_argument(
        "--threshold-sigma",
        type=float,
        default=6.0,
        help="threshold in background-noise sigmas above the background (default 6)",
    )
    add_detector_arguments(p)
    p.add_argument("--list", action="store_true", help="list the detectors and exit")
    p.add_argument(
        "--strict",
        action="store_true",
        help="exit 4 when any frame failed (default: 0 when some succeeded, 3 when none did)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_workers(p, "detection (each decodes and detects its own frames; the tables do not depend on it)",
                zero="detect in this process")
    p.set_defaults(func=run)


def add_detector_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``detect`` and ``bench-detectors``: candidate search and plugins."""
    p.add_argument(
        "--gain",
        type=float,
        default=None,
        help="sensor gain in DN per electron for covariances and fit weights (default: the "
        "gain a dataset's manifest declares, else estimated per frame)",
    )
    p.add_argument(
        "--background-kernel-px",
        type=int,
        default=0,
        help="remove an uneven background (lit deck) with a grey opening of this diameter "
        "(pixels, larger than any beacon) before the candidate search; 0 = flat background",
    )
    p.add_argument(
        "--spot-level",
        type=float,
        default=0.8,
        help="bright-spot search: candidates reach this fraction of the way from the frame's "
        "background to its brightest level (largest channel); 0 = every blob threshold-sigma "
        "above the background (default 0.8)",
    )
    p.add_argument(
        "--significance-sigma",
        type=float,
        default=5.0,
        help="significance search, beside the bright-spot search: every compact spot this many "
        "local noise sigmas above its surroundings is a candidate, however dim; 0 = off "
        "(default 5)",
    )
    p.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="import MODULE first (it may register more detectors); repeatable",
    )


def run(args: argparse.Namespace) -> int:
    from deckpose.cli.exit_codes import frames_exit_code
    from deckpose.detect import registry
    from deckpose.detect.registry import DetectorOptions
    from deckpose.detect.run import detect_run
    from deckpose.errors import ConfigError

    for mod in args.plugin:
        registry.load_plugin(mod)
    if args.list:
        print("\n".join(registry.names()))  # what was asked for, also with -q
        return 0
    if args.dataset is None:
        raise ConfigError("no DATASET given: name a dataset folder or a folder of images")
    options = DetectorOptions(
        threshold_sigma=args.threshold_sigma,
        gain_dn_per_e=args.gain,
        background_kernel_px=args.background_kernel_px,
        spot_level=args.spot_level,
        significance_sigma=args.significance_sigma,
    )
    res = detect_run(args.dataset, args.detector, options=options, out_dir=args.out,
                     camera_file=args.camera_info, layout_file=args.layout, progress=not args.no_progress,
                     workers=workers(args))
    frames = res.frames
    wrote(args, res.path, res.summary())
    code = frames_exit_code(len(frames), res.n_ok, strict=args.strict)
    failures(args, (f"  frame {r.frame_id}: {r.reason}" for r in frames.itertuples() if not r.ok),
             failing=code != 0)
    return code
