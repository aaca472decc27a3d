"""``deckpose pipeline CONFIG RUN``: render -> detect -> estimate -> evaluate -> report in one command.

Every stage is the same stage function as its own subcommand calls (``render_dataset``,
``detect_run``, ``estimate_run_with_prior``, ``evaluate_run``, ``write_report``). The render stage resumes
(frames already on disk are kept), so an interrupted pipeline picks up where it
stopped when run again with the same arguments; the later stages are cheap and
are rewritten. ``RUN/pipeline.json`` records the command, the machine and the
seconds each stage took, and the report quotes it. ``--publish DIR`` copies the
report, its figures and the resolution tables (not the dataset or the MCAP log)
into ``DIR``, which is how the reference reports under ``reports/`` are made.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from deckpose.atomic_io import atomic_open
from deckpose.cli.common_options import (
    HelpFormatter,
    add_progress,
    add_scheduler,
    add_workers,
    done_of_total,
    frame_bar,
    workers,
)
from deckpose.cli.console import is_quiet, wrote
from deckpose.errors import ConfigError, DeckposeError
from deckpose.machine_load import LoadSampler, peak_rss_gib
from deckpose.shell_command import deckpose_command

if TYPE_CHECKING:
    from deckpose.render.config import RenderConfig

log = logging.getLogger(__name__)

DEFAULT_METHODS: tuple[str, ...] = ("thesis", "conic", "pnp")
#: The stages, in order; ``--from-stage`` skips those before it (their outputs must exist).
STAGES: tuple[str, ...] = ("render", "detect", "estimate", "evaluate", "report")
PIPELINE_RECORD = "pipeline.json"


@dataclass(frozen=True)
class PipelineOptions:
    """What one pipeline run does (parsed once from the command line).

    Attributes
    ----------
    run_dir : Path
        Run folder (the rendered dataset; later stages add to it).
    detectors : tuple of str
        Detector names, each run over the whole dataset.
    methods : tuple of str
        Method labels (an estimator name, optionally ``+refine`` or ``+mean``), each run on
        every detector's detections.
    workers : int
        Local worker processes of every stage (0: in this process); no table depends on it.
    scheduler : str or None
        Dask scheduler address for the render, estimate and evaluate stages.
    mcap : bool
        Write the MCAP log in the evaluate stage.
    progress : bool
        Show progress bars.
    publish_dir : Path or None
        Copy the report, figures and resolution tables here at the end.
    from_stage : str
        First stage to run (one of :data:`STAGES`); earlier stages' outputs are reused.
    command : tuple of str
        The command line, recorded in ``pipeline.json``.
    detect_at_render : bool
        Detect each frame as it is rendered, from memory (``deckpose render --detect``), instead
        of decoding every frame again in a detect stage.
    keep_images : bool
        Write the frames' image files (``False`` needs ``detect_at_render``).
    track : bool
        After estimating, track every estimates table over time (``deckpose track``'s default
        tracker and config), so the log plays the filtered and predicted decks; needs frames in
        time (a motion series or an approach).
    quiet : bool
        Print nothing (``-q``): no stage lines or summaries; errors are raised.
    """

    run_dir: Path
    detectors: tuple[str, ...] = ("cog",)
    methods: tuple[str, ...] = DEFAULT_METHODS
    workers: int = 1
    scheduler: str | None = None
    mcap: bool = True
    progress: bool = True
    publish_dir: Path | None = None
    from_stage: str = "render"
    command: tuple[str, ...] = field(default_factory=tuple)
    detect_at_render: bool = False
    keep_images: bool = True
    track: bool = False
    quiet: bool = False

    def __post_init__(self) -> None:
        if not self.detectors:
            raise ConfigError("no detector given; pass --detector NAME (see 'deckpose detect --list')")
        if not self.methods:
            raise ConfigError("no estimator given; pass --method NAME (e.g. thesis, conic, pnp)")
        if self.from_stage not in STAGES:
            raise ConfigError(f"unknown stage {self.from_stage!r}; choose from {', '.join(STAGES)}")
        if self.workers < 0:
            raise ConfigError(f"--workers must be >= 0, got {self.workers}")
        if not self.keep_images and not self.detect_at_render:
            raise ConfigError("--no-images keeps no frame for the detect stage: add --detect-at-render")


def _csv(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "pipeline",
        help="render -> detect -> estimate -> evaluate -> report for a render config, in one command",
        description=(
            "Run the whole pipeline on a render config: render the dataset into RUN (resuming frames "
            "already there), detect with each --detector, estimate with each --method, evaluate (errors, "
            "resolution tables, MCAP log) and write the report. Example: deckpose pipeline "
            "configs/thesis_sweep_reference.yaml runs/thesis_sweep --workers 2 --publish reports/thesis_sweep"
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("config", type=Path, help="render config YAML (see configs/)")
    p.add_argument("run", type=Path, help="run folder (the dataset; later stages add to it)")
    p.add_argument("--detector", type=_csv, default="cog", help="detector name(s), comma-separated")
    p.add_argument("--method", type=_csv, default=",".join(DEFAULT_METHODS),
                   help="estimator name(s), comma-separated, each optionally with +refine or +mean "
                   "(posterior mean), e.g. thesis,pnp,pnp+mean")
    add_workers(p, "every stage's local", zero="run every stage in this process")
    add_scheduler(p, "the render, estimate and evaluate stages' tasks (detection stays on --workers)")
    p.add_argument("--no-mcap", action="store_true", help="skip the MCAP log")
    p.add_argument("--publish", type=Path, default=None, metavar="DIR",
                   help="copy report.md, figures and resolution tables into DIR at the end")
    p.add_argument("--from-stage", choices=STAGES, default="render",
                   help="start at this stage, reusing the earlier stages' outputs in RUN (e.g. 'report' "
                        "after changing only the report)")
    p.add_argument("--detect-at-render", action="store_true",
                   help="detect each frame as it is rendered, from memory (no frame decoded again)")
    p.add_argument("--no-images", action="store_true",
                   help="keep no frame (previews and tables only); needs --detect-at-render")
    p.add_argument("--track", action="store_true",
                   help="after estimating, track each estimates table over time (deckpose track's default "
                        "tracker); needs frames in time: a motion series or an approach")
    add_progress(p)
    p.set_defaults(func=run, resume_hint="rendered frames are kept whole; run the same command again: the "
                        "render resumes and the later stages run again (add --from-stage STAGE to "
                        "skip the finished ones)")


def run(args: argparse.Namespace) -> int:
    from deckpose.render.config import load_config

    config = load_config(args.config)
    options = PipelineOptions(
        run_dir=args.run, detectors=tuple(args.detector), methods=tuple(args.method), workers=workers(args),
        scheduler=args.scheduler, mcap=not args.no_mcap, progress=not args.no_progress,
        publish_dir=args.publish, from_stage=args.from_stage, command=_canonical_command(args),
        detect_at_render=args.detect_at_render, keep_images=not args.no_images, track=args.track,
        quiet=is_quiet(args),
    )
    paths = run_pipeline(config, options, config_label=str(args.config))
    wrote(args, paths["report"], "\n".join(f"  {key}: {path}" for key, path in paths.items()))
    return 0


def _canonical_command(args: argparse.Namespace) -> tuple[str, ...]:
    """The command line that reproduces ``args`` (recorded in ``pipeline.json``)."""
    cmd = ["deckpose", "pipeline", str(args.config), str(args.run), "--detector", ",".join(args.detector),
           "--method", ",".join(args.method), "--workers", str(workers(args))]
    if args.scheduler:
        cmd += ["--scheduler", args.scheduler]
    if args.no_mcap:
        cmd.append("--no-mcap")
    if args.publish is not None:
        cmd += ["--publish", str(args.publish)]
    if args.from_stage != STAGES[0]:
        cmd += ["--from-stage", args.from_stage]
    if args.detect_at_render:
        cmd.append("--detect-at-render")
    if args.no_images:
        cmd.append("--no-images")
    if args.track:
        cmd.append("--track")
    return tuple(cmd)


def _images_not_kept(manifest: Path) -> bool:
    """Whether the run at ``manifest`` was rendered with ``--no-images`` (its detections made at render time)."""
    try:
        return json.loads(manifest.read_text()).get("images_kept") is False
    except (OSError, ValueError):
        return False


def check_names(options: PipelineOptions) -> None:
    """Fail before the (long) render stage if a detector or estimator name is unknown."""
    from deckpose.detect import registry as detectors
    from deckpose.estimate import registry as estimators

    for kind, given, known in (("detector", options.detectors, detectors.names()),
                               ("estimator", [m.split("+")[0] for m in options.methods], estimators.names())):
        unknown = [n for n in given if n not in known]
        if unknown:
            raise ConfigError(f"unknown {kind} {', '.join(unknown)}; choose from {', '.join(known)}")
    for m in options.methods:
        estimators.parse_method(m)  # and its variant suffix: +refine or +mean


def _read_record(run_dir: Path) -> dict:
    path = Path(run_dir) / PIPELINE_RECORD
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError):
        return {}


def _machine() -> dict[str, object]:
    return {"platform": platform.platform(), "machine": platform.machine(), "python": platform.python_version(),
            "cpu_count": os.cpu_count()}


def run_pipeline(config: RenderConfig, options: PipelineOptions, config_label: str = "",
                 step: Callable[[int, int, str], None] | None = None) -> dict[str, Path]:
    """Run render -> detect -> estimate -> evaluate -> report on one render config.

    Parameters
    ----------
    config : deckpose.render.config.RenderConfig
        The validated render config.
    options : PipelineOptions
        Stages' options.
    config_label : str
        How the config is named in ``pipeline.json`` and the report (e.g. its path).
    step : callable, optional
        ``step(n, total, text)`` is called as each stage starts (default: print it).

    Returns
    -------
    dict of str to Path
        ``report``, ``tables``, ``errors`` and (when written) ``mcap`` and ``published``.
    """
    from deckpose.run_folder import run_paths

    check_names(options)
    if options.track and config.motion.source.value == "fixed":
        raise ConfigError("--track needs frames in time, and this config renders fixed attitudes (motion source "
                          "'fixed'): give it a motion series (motion.source sea_state, file or thesis) or an "
                          "approach: section, or drop --track")

    def tell(text: str) -> None:  # a summary line (none with quiet)
        if not options.quiet:
            print(text, flush=True)

    say = step or (lambda n, total, text: tell(f"[{n}/{total}] {text}"))
    total = 5 + bool(options.mcap) + (options.publish_dir is not None)
    first = STAGES.index(options.from_stage)
    paths = run_paths(Path(options.run_dir))
    if first > 0 and not paths.manifest.exists():
        raise DeckposeError(f"--from-stage {options.from_stage} needs a rendered dataset in {options.run_dir}; "
                            f"run the pipeline from the render stage first")
    from deckpose.output_folder import claim_output

    claim_output(Path(options.run_dir), what="pipeline")  # the stages run in this process and claim it again
    with LoadSampler(interval_s=10.0) as sampler:  # the load each stage runs under, for pipeline.json
        return _run_stages(config, options, config_label, say, tell, sampler, total, first)


def _run_stages(config: RenderConfig, options: PipelineOptions, config_label: str,
                say: Callable[[int, int, str], None], tell: Callable[[str], None], sampler: LoadSampler,
                total: int, first: int) -> dict[str, Path]:
    from deckpose import __version__
    from deckpose.detect.run import detect_run
    from deckpose.estimate.registry import parse_method
    from deckpose.evaluate.report import write_report
    from deckpose.evaluate.run import evaluate_run, write_log
    from deckpose.render.dataset import render_dataset
    from deckpose.render.render_detection import RenderDetection
    from deckpose.run_folder import read_frames, run_paths
    from deckpose.sequence_run import estimate_run_with_prior

    def runs(stage: str) -> bool:
        return STAGES.index(stage) >= first

    run_dir = Path(options.run_dir)
    paths = run_paths(run_dir)
    spans: dict[str, tuple[float, float]] = {}  # each stage's start and end (perf_counter, the sampler's clock)
    t_all = time.perf_counter()
    t = time.perf_counter()
    if runs("render"):
        say(1, total, f"render {config_label or getattr(config, 'name', 'config')} -> {run_dir} "
                      "(resumes frames on disk)")
        detection = (RenderDetection(options.detectors, keep_images=options.keep_images)
                     if options.detect_at_render else None)
        render_dataset(config, run_dir, workers=options.workers, resume=True, scheduler=options.scheduler,
                       progress=options.progress, detection=detection)
        spans["render"] = (t, time.perf_counter())
        log.info("stage render: %.1f s", spans["render"][1] - t)
    t = time.perf_counter()
    if runs("detect") and (options.detect_at_render or _images_not_kept(paths.manifest)):
        say(2, total, f"detect beacons ({', '.join(options.detectors)}): done at render time")
        for det in options.detectors:  # a run that keeps no frames has only those
            if not paths.detections(det).is_file():
                raise DeckposeError(f"{run_dir} has no {det} detections made at render time and keeps no "
                                    f"frames to detect in; render into a new folder with --detect-at-render")
    elif runs("detect"):
        say(2, total, f"detect beacons ({', '.join(options.detectors)})")
        for det in options.detectors:  # a stage whose every frame failed still ran: the report says so
            res = detect_run(run_dir, det, progress=options.progress, workers=options.workers)
            tell(res.summary())
        spans["detect"] = (t, time.perf_counter())
        log.info("stage detect: %.1f s", spans["detect"][1] - t)
    t = time.perf_counter()
    if runs("estimate"):
        say(3, total, f"estimate the pose ({', '.join(options.methods)})"
                      + (", then track it over time" if options.track else ""))
        n_frames = len(read_frames(paths))  # the bars' total
        for det in options.detectors:
            for method in options.methods:
                spec = parse_method(method)
                with frame_bar(f"estimate ({spec.label})", enabled=options.progress, total=n_frames) as b:
                    est = estimate_run_with_prior(run_dir, spec, detector=det, progress=b.update,
                                                  workers=options.workers, scheduler=options.scheduler)
                tell(est.summary())
                if options.track:
                    from deckpose.tracking.config import TRACKERS, TrackConfig
                    from deckpose.tracking.run import track_run

                    with frame_bar(f"track ({spec.label})", enabled=options.progress, total=n_frames) as b:
                        tr = track_run(run_dir, TrackConfig(), tracker=TRACKERS[0], detector=det, method=spec.label,
                                       command=list(options.command), progress=b.update)
                    tell(tr.summary())
        spans["estimate"] = (t, time.perf_counter())
        log.info("stage estimate: %.1f s", spans["estimate"][1] - t)
    t = time.perf_counter()
    if runs("evaluate"):
        say(4, total, "evaluate against the ground truth")
        # (the MCAP log is written after the report, which it attaches)
        with frame_bar("evaluate", enabled=options.progress) as b:
            evaluated = evaluate_run(paths, mcap=False, command=options.command, progress=done_of_total(b),
                                     workers=options.workers, scheduler=options.scheduler)
        for key, path in evaluated.items():
            tell(f"{key}: {path}")
        spans["evaluate"] = (t, time.perf_counter())
        log.info("stage evaluate: %.1f s", spans["evaluate"][1] - t)
    previous = _read_record(run_dir)
    stage_seconds = {k: v for k, v in previous.get("stage_seconds", {}).items()
                     if k in STAGES and not runs(k)}
    stage_seconds.update({k: round(end - start, 1) for k, (start, end) in spans.items()})
    stage_load = {k: v for k, v in previous.get("stage_load_1min", {}).items() if k in STAGES and not runs(k)}
    stage_load.update({k: sampler.summary(*span).as_dict() for k, span in spans.items()})
    # the peak of every process that made the record's stages (a later --from-stage run adds its own)
    peak = {k: max(v, float(previous.get("peak_rss_gib", {}).get(k, 0.0))) for k, v in peak_rss_gib().items()}
    record = {
        "command": list(options.command), "config": config_label, "config_name": getattr(config, "name", None),
        "detectors": list(options.detectors), "methods": list(options.methods), "workers": options.workers,
        "scheduler": options.scheduler, "deckpose_version": __version__, "machine": _machine(),
        "from_stage": options.from_stage, "detect_at_render": options.detect_at_render,
        "images_kept": options.keep_images, "tracked": options.track,
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "stage_seconds": {k: stage_seconds[k] for k in STAGES if k in stage_seconds},
        "stage_load_1min": {k: stage_load[k] for k in STAGES if k in stage_load},
        "peak_rss_gib": peak,
    }
    if first > 0 and previous.get("command"):
        record["earlier_stages_command"] = previous.get("earlier_stages_command", previous["command"])
    with atomic_open(run_dir / PIPELINE_RECORD, "w") as fh:
        json.dump(record, fh, indent=2)
    t = time.perf_counter()
    say(5, total, "write the report")
    with frame_bar("report", enabled=options.progress, unit="figure") as b:
        md = write_report(paths, progress=done_of_total(b))
    tell(f"report: {md}")
    out = {"report": paths.report_dir / "report.md", "tables": paths.evaluation_dir / "resolution_tables.md",
           "errors": paths.errors}
    if options.mcap and runs("evaluate"):
        t_log = time.perf_counter()
        say(6, total, "write the MCAP log (with the report attached)")
        for key, path in write_log(paths, command=options.command, workers=options.workers).items():
            tell(f"{key}: {path}")
        record["log_seconds"] = round(time.perf_counter() - t_log, 1)
        with atomic_open(run_dir / PIPELINE_RECORD, "w") as fh:
            json.dump(record, fh, indent=2)
    if options.mcap:
        out["mcap"] = paths.mcap
    if options.publish_dir is not None:
        say(total, total, f"publish the report and tables -> {options.publish_dir}")
        out["published"] = publish_report(run_dir, Path(options.publish_dir))
    tell(f"pipeline done in {time.perf_counter() - t_all:.0f} s (report {time.perf_counter() - t:.0f} s)")
    return out


def publish_report(run_dir: Path, dest: Path) -> Path:
    """Copy a run's report, figures, resolution tables and ``pipeline.json`` into ``dest``.

    The copy is built beside ``dest`` and swapped in with a rename, so ``dest``
    is either the old or the complete new report, never half of each.

    Returns
    -------
    Path
        ``dest / "report.md"``.
    """
    from deckpose.run_folder import run_paths

    paths = run_paths(run_dir)
    report = paths.report_dir / "report.md"
    if not report.exists():
        raise DeckposeError(f"{report} is missing; make it with: {deckpose_command('report', run_dir)}")
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.parent / f".{dest.name}.tmp-{os.getpid()}"
    old = dest.parent / f".{dest.name}.old-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(paths.report_dir, tmp)
    for name in ("resolution_tables.md", "resolution_tables.csv"):
        if (paths.evaluation_dir / name).exists():
            shutil.copy2(paths.evaluation_dir / name, tmp / name)
    if (run_dir / PIPELINE_RECORD).exists():
        shutil.copy2(run_dir / PIPELINE_RECORD, tmp / PIPELINE_RECORD)
    if dest.exists():
        dest.rename(old)
    tmp.rename(dest)
    shutil.rmtree(old, ignore_errors=True)
    return dest / "report.md"
