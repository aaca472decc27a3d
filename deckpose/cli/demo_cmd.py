"""``deckpose demo``: the main job end to end on the embedded default.

render (embedded smoke config: two small cameras x two heights x night/day)
-> detect -> estimate (thesis, conic, pnp) -> evaluate (errors, resolution
tables, MCAP log + Foxglove layout) -> report; a short approach over sea state 6
(embedded ``configs/approach_small.yaml``) rendered with detection, estimated
(pnp), tracked and logged; and the thesis's tables at reduced scale. Each step is the same code as its own subcommand; running the
demo again resumes the dataset and rewrites the later stages' outputs.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

from deckpose.cli.common_options import HelpFormatter, add_progress, add_workers, workers
from deckpose.cli.console import is_quiet, say, wrote

METHODS = ("thesis", "conic", "pnp")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "demo",
        help="run the main job end to end on the embedded default (what the README's first command runs)",
        description=(
            "Render the embedded default dataset, detect the beacons, estimate the pose with the "
            "thesis, conic and pnp estimators, evaluate against the ground truth (tables, MCAP log for "
            "Foxglove) and write a report; then fly a short approach over sea state 6 (render with "
            "detection, estimate, track, log), and reproduce the thesis's tables at reduced scale."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument("-o", "--output", type=Path, default=Path("runs/demo"), help="output folder")
    p.add_argument("--detector", default="cog", help="beacon detector")
    add_workers(p, "render")
    p.add_argument("--repetitions", type=int, default=20, help="thesis-table repetitions (500 = full scale)")
    p.add_argument("--seed", type=int, default=20221, help="seed of the thesis-table Monte Carlo")
    add_progress(p)
    p.set_defaults(func=run)


def _drop_stale_demo(run_dir: Path, config: object, say: Callable[[str], None]) -> None:
    """Remove a demo run rendered from an older embedded config (after an update), which
    could not be resumed; a folder that holds anything but a demo run is left alone."""
    import json
    import shutil

    from deckpose.render.config import config_to_dict
    from deckpose.run_folder import RunPaths

    manifest = RunPaths(run_dir).manifest
    if not manifest.is_file():
        return
    try:
        old = json.loads(manifest.read_text())
    except (OSError, ValueError):
        return
    now = json.loads(json.dumps(config_to_dict(config)))  # type: ignore[arg-type]
    if old.get("config") != now and (old.get("config") or {}).get("name") == now.get("name"):
        say(f"{run_dir} holds a demo of an older embedded config; rendering it anew")
        shutil.rmtree(run_dir)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from deckpose.cli.pipeline_cmd import PipelineOptions, run_pipeline
    from deckpose.evaluate.thesis_tables import ThesisTablesConfig, cell_specs, run_thesis_tables
    from deckpose.render.config import approach_demo_config, default_config

    t0 = time.perf_counter()

    def tell(text: str) -> None:
        say(args, text)

    def _step(n: int, total: int, text: str) -> None:
        tell(f"[{n}/{total}] {text}")

    thesis_config = ThesisTablesConfig(repetitions=args.repetitions, seed=args.seed)  # checked before any work
    out = Path(args.output)
    run_dir = out / "run"
    _drop_stale_demo(run_dir, default_config(), tell)
    options = PipelineOptions(run_dir=run_dir, detectors=(args.detector,), methods=METHODS, workers=workers(args),
                              progress=not args.no_progress, command=("deckpose", "demo", "-o", str(out)),
                              quiet=is_quiet(args))
    # the demo's steps are the pipeline's, then the thesis tables
    pipeline_steps = [0]

    def pipeline_step(n: int, total: int, text: str) -> None:
        pipeline_steps[0] = total
        _step(n, total + 2, text)

    paths = run_pipeline(default_config(), options, config_label="the embedded default (configs/smoke.yaml)",
                         step=pipeline_step)
    total = pipeline_steps[0] + 2
    _step(total - 1, total, "a short approach over sea state 6 (61 frames at 2 Hz, 60 m to 30 m): render with "
                            "detection, estimate (pnp), track, log")
    approach_dir = out / "approach"
    _drop_stale_demo(approach_dir, approach_demo_config(), tell)
    approach = run_pipeline(
        approach_demo_config(),
        PipelineOptions(run_dir=approach_dir, detectors=(args.detector,), methods=("pnp",), workers=workers(args),
                        progress=not args.no_progress, detect_at_render=True, keep_images=False, track=True,
                        quiet=is_quiet(args),
                        command=("deckpose", "demo", "-o", str(out))),
        config_label="the embedded approach (configs/approach_small.yaml)",
        step=lambda n, t, text: tell(f"      approach {n}/{t}: {text}"))
    _step(total, total, f"thesis tables 4.2-4.15, {args.repetitions} x 495 images per cell")
    config = thesis_config
    bar = tqdm(total=len(cell_specs()), desc="thesis tables", unit="cell", disable=True if args.no_progress else None)
    md = run_thesis_tables(config, out, lambda done, _total: bar.update(done - bar.n))
    bar.close()
    tell(f"\ndone in {time.perf_counter() - t0:.0f} s.")
    wrote(args, paths["report"], "\n".join(
        f"  {label + ':':19s}{path}"
        for label, path in (("report", paths["report"]), ("resolution tables", paths["tables"]),
                            ("MCAP log", f"{paths['mcap']}  (open in Foxglove with {run_dir / 'foxglove_layout.json'})"),
                            ("approach log", f"{approach['mcap']}  (tracked; layout {approach_dir / 'foxglove_layout.json'})"),
                            ("thesis tables", md))))
    return 0
