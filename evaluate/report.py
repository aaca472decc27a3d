"""``deckpose report``: a Markdown report with plots for one evaluated run.

Figures (:mod:`deckpose.evaluate.report_figures`, PNG under ``report/figures``): error
against resolution and height (Cramer-Rao bound dashed where known), error distributions,
centroid error vs apparent blob size, example frames with detections overlaid; and the
thesis's Table 4.2-4.13 maxima next to ours where resolution and height match.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.evaluate import thesis_reference as ref
from deckpose.evaluate.errors import centroid_errors
from deckpose.evaluate.report_figures import (
    example_frame,
    plot_centroid_vs_size,
    plot_distributions,
    plot_error_vs_height,
    plot_error_vs_resolution,
)
from deckpose.evaluate.resolution_tables import resolution_markdown, resolution_table

from deckpose import run_folder as rl
from deckpose.atomic_io import atomic_open
from deckpose.camera import THESIS_RESOLUTIONS
from deckpose.errors import InputDataError
from deckpose.shell_command import deckpose_command
from deckpose.tables import read_table

log = logging.getLogger(__name__)


def resolution_of(camera_name: str, size_px: tuple[int, int] | None = None) -> str | None:
    """The thesis resolution a camera has (``"8mp"``), if any.

    From its size (``(width_px, height_px)``) when given: a camera is the thesis's 4 MP
    camera only at 2312x1734, whatever it is called (the demo's ``4mp-640x480`` is a
    640x480 camera with the 4 MP preset's field of view, not a 4 MP one). Without a
    size, from a name of the form ``"8mp-..."``.
    """
    if size_px is not None:
        for res, wh in THESIS_RESOLUTIONS.items():
            if tuple(size_px) == wh:
                return res
        return None
    key = camera_name.lower().split("-")[0].split("_")[0]
    return key if key in THESIS_RESOLUTIONS else None


def saturated_cells(frames: pd.DataFrame, beacons: pd.DataFrame, full_well_e: float | None) -> set[tuple[str, float]]:
    """``(camera, table height)`` cells where some visible beacon's core clips.

    A beacon clips when the electrons of its brightest channel at the peak
    (``spot_peak_e`` of ``beacons.parquet``) reach the sensor's full well (the manifest's
    ``sensor.full_well_e``). Empty when either is unknown.
    """
    if full_well_e is None or "spot_peak_e" not in beacons:
        return set()
    b = beacons[beacons["visible"].astype(bool)][["frame_id", "spot_peak_e"]]
    m = b.merge(frames[["frame_id", "camera", "camera_height_m"]], on="frame_id")
    hit = m[m["spot_peak_e"] >= full_well_e]
    return {(str(c), float(h)) for c, h in zip(hit["camera"], hit["camera_height_m"])}


def thesis_comparison(table: pd.DataFrame, sizes_px: dict[str, tuple[int, int]] | None = None) -> list[str]:
    """Our measured maxima beside the thesis's (Tables 4.2-4.13, 4 px noise) where they correspond.

    ``sizes_px`` maps camera names to ``(width_px, height_px)``; a camera is set beside a
    thesis resolution only when its size is that resolution (:func:`resolution_of`).
    """
    lines = [("| detector + method | resolution | height | roll max ours / thesis [deg] | pitch | yaw | "
             "height [m] | centroid RMS ours / thesis image RMS [px] |"), "|---|---|---|---|---|---|---|---|"]
    n = 0
    for _, r in table.iterrows():
        res = resolution_of(str(r.camera), None if sizes_px is None else sizes_px.get(str(r.camera), (0, 0)))
        h = round(r.table_height_m)
        if res is None or h not in ref.MAX_ERROR[(res, 4)]:
            continue
        t = ref.MAX_ERROR[(res, 4)][h]
        lines.append(f"| {r.detector}+{r.method} | {res} | {h} | {r.max_roll:.4f} / {t[0]:.3f} | "
                     f"{r.max_pitch:.4f} / {t[1]:.3f} | {r.max_yaw:.4f} / {t[2]:.3f} | {r.max_height:.4f} / {t[3]:.3f} | "
                     f"{r.centroid_rms_mean_px:.3f} / {t[4]:.2f} |")
        n += 1
    if not n:
        sizes = "" if not sizes_px else " (this run's cameras: " + ", ".join(
            n if n == f"{w}x{h}" else f"{n} {w}x{h}" for n, (w, h) in sorted(sizes_px.items())) + ")"
        known = ", ".join(f"{r[:-2]} MP {w}x{h}" for r, (w, h) in THESIS_RESOLUTIONS.items())
        return [f"No cell of this run has a thesis resolution ({known}) at a thesis height "
                "(20/30/40/50/80 m)" + sizes
                + ", so there is nothing to set beside the thesis's tables."]
    return lines


def provenance_lines(run: rl.RunPaths) -> list[str]:
    """A "How this was made" section from the dataset manifest and ``pipeline.json`` (when present).

    Parameters
    ----------
    run : RunPaths
        The run folder.

    Returns
    -------
    list of str
        Markdown lines; empty when the run has neither record.
    """

    lines: list[str] = []
    if run.manifest.exists():
        m = json.loads(run.manifest.read_text())
        versions = m.get("versions", {})
        lines.append(f"- Dataset: config `{m.get('name')}`, {m.get('n_frames')} frames, seed {m.get('seed')}, "
                     f"rendered with deckpose {versions.get('deckpose', '?')} (numpy {versions.get('numpy', '?')}, "
                     f"OpenCV {versions.get('opencv-contrib-python-headless', versions.get('opencv-python', '?'))}).")
    record_path = run.root / "pipeline.json"
    if record_path.exists():
        r = json.loads(record_path.read_text())
        mach = r.get("machine", {})
        stages = ", ".join(f"{k} {v:.0f} s" for k, v in r.get("stage_seconds", {}).items())
        if r.get("command"):
            lines.append(f"- Command: `{' '.join(r['command'])}`")
        if r.get("earlier_stages_command"):
            lines.append(f"- Stages before `{r.get('from_stage')}` came from an earlier run of: "
                         f"`{' '.join(r['earlier_stages_command'])}`")
        lines.append(f"- Machine: {mach.get('platform', '?')}, {mach.get('cpu_count', '?')} CPUs, Python "
                     f"{mach.get('python', '?')}; render workers {r.get('workers')}"
                     + (f", Dask scheduler {r['scheduler']}" if r.get("scheduler") else "") + ".")
        if stages:
            lines.append(f"- Stage times on that machine (the render stage resumes, so it counts only the "
                         f"frames rendered by that command): {stages}.")
        loads = r.get("stage_load_1min", {})
        if loads:  # what those times were measured under (a shared machine's load moves them)
            lines.append("- 1-minute load during each stage, mean (max): " + ", ".join(
                f"{k} {v['mean']:.1f} ({v['max']:.1f})" for k, v in loads.items()) + ".")
        peak = r.get("peak_rss_gib", {})
        if peak:
            lines.append(f"- Peak memory: the pipeline process {peak.get('this_process', 0.0):.2f} GiB, its "
                         f"largest worker process {peak.get('largest_worker', 0.0):.2f} GiB.")
        lines.append(f"- Finished {r.get('finished_utc', '?')}.")
    return ["## How this was made", "", *lines, ""] if lines else []


def _run_title(run: rl.RunPaths) -> str:
    """The dataset's config name from its manifest (the folder name when there is none)."""

    if run.manifest.exists():
        name = json.loads(run.manifest.read_text()).get("name")
        if name:
            return str(name)
    return run.root.name


def track_sections(run: rl.RunPaths, frames: pd.DataFrame, fig_dir: Path,
                   figure_done: Callable[[], object] | None = None) -> list[str]:
    """The report's tracking sections, one per track of the run (none without tracks), with their figures.

    ``figure_done()`` is called after each track's figure.
    """
    from deckpose.evaluate.report_figures import plot_track_errors
    from deckpose.evaluate.track_errors import (
        filtered_by_height,
        markdown_table,
        predicted_roll_errors,
        prediction_errors,
        track_frame_errors,
    )

    lines: list[str] = []
    for d, m, t in run.track_triples():
        stem = f"{d}{rl.SEPARATOR}{m}{rl.SEPARATOR}{t}"
        tracks = rl.read_tracks(run, d, m, t)
        preds = rl.read_track_predictions(run, d, m, t)
        est = rl.read_estimates(run, d, m)
        errs = track_frame_errors(frames, est, tracks)
        pred = prediction_errors(frames, est, tracks, preds)
        horizons = sorted(preds["horizon_s"].unique())
        h_plot = min(horizons, key=lambda h: abs(h - 1.0)) if horizons else 1.0
        fig = f"track_{stem}.png"
        plot_track_errors(errs, predicted_roll_errors(frames, tracks, preds, h_plot), pred,
                          f"{d}+{m}, tracked ({t})", fig_dir / fig)
        if figure_done is not None:
            figure_done()
        status = tracks["status"].value_counts()
        z = errs[["roll_z_filtered", "pitch_z_filtered", "height_z_filtered"]].abs().to_numpy(float)
        lines += [f"## Tracking: {d}+{m} ({t})", "",
                  (f"{len(tracks)} frames in {tracks['sequence'].nunique()} sequence(s): "
                   + ", ".join(f"{int(status.get(k, 0))} {k}" for k in ("updated", "gated", "skipped"))
                   + f"; landing window \"go\" in {tracks['landing_go'].mean():.0%} of frames. Filtered "
                   f"errors beyond 5 of their own sigmas (roll, pitch, height): {int((z > 5).sum())} of "
                   f"{int(np.isfinite(z).sum())}."), "",
                  f"![tracking {stem}](figures/{fig})", "",
                  ("Filtered against per-frame error (RMS) by true height, both on the frames with an ok estimate; "
                   "`*_rms_filtered_all` is the filtered RMS on every frame (where no estimate is ok, the "
                   "filter's prediction):"), "",
                  *markdown_table(filtered_by_height(errs)), "",
                  ("Predictions against holding the last ok estimate as long (RMS at the frame each was made for; "
                   "z: RMS of the error in the prediction's own sigmas):"), "",
                  *markdown_table(pred), ""]
    return lines


def _warn_unevaluated(run: rl.RunPaths, errors: pd.DataFrame) -> None:
    """Warn of estimates tables the evaluation has not seen (estimated again, or anew, after it)."""
    evaluated = set(zip(errors["detector"].astype(str), errors["method"].astype(str)))
    t_eval = run.errors.stat().st_mtime
    for d, m in run.estimate_pairs():
        path = run.estimates(d, m)
        seen, newer = (d, m) in evaluated, path.stat().st_mtime > t_eval
        if not seen or newer:
            log.warning("%s is %s, so the report %s it; evaluate again first: %s", path,
                        "newer than the evaluation" if newer else "not in the evaluation",
                        "shows its older estimates" if seen else "leaves it out",
                        deckpose_command("evaluate", run.root))


def write_report(run: rl.RunPaths, *, progress: Callable[[int, int], object] | None = None) -> Path:
    """Write ``report/report.md`` and its figures for an evaluated run; return the Markdown path.

    ``progress(done, total)`` counts the figures as each is drawn.
    """
    rl.require_dataset(run)  # a missing run folder is named as such, not as a missing stage
    if not run.errors.exists():
        raise InputDataError(f"{run.errors} is missing; make it with: {deckpose_command('evaluate', run.root)}")
    errors = read_table(run.errors, "errors")
    _warn_unevaluated(run, errors)
    frames = rl.read_frames(run)
    beacons = rl.read_beacons(run)
    dets = {d: rl.read_detections(run, d) for d in run.detectors()}
    table = resolution_table(errors)
    fig_dir = run.report_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    cams = rl.read_cameras(run, sorted(frames["camera"].astype(str).unique()))
    sizes = {n: (c.width_px, c.height_px) for n, c in cams.items()}

    manifest = json.loads(run.manifest.read_text()) if run.manifest.exists() else {}
    full_well = (manifest.get("sensor") or {}).get("full_well_e")
    clipped = saturated_cells(frames, beacons, full_well)
    # the figures: four summary plots, an example frame per camera, a plot per track
    n_figures = 4 + frames["camera"].nunique() + len(run.track_triples())
    drawn = [0]

    def figure_done() -> None:
        drawn[0] += 1
        if progress is not None:
            progress(drawn[0], n_figures)

    plot_error_vs_resolution(table, sizes, fig_dir / "error_vs_resolution.png", clipped)
    figure_done()
    plot_error_vs_height(table, fig_dir / "error_vs_height.png")
    figure_done()
    plot_distributions(errors, fig_dir / "error_distributions.png")
    figure_done()
    camera_of = dict(zip(frames.frame_id.astype(int), frames.camera.astype(str)))
    plot_centroid_vs_size({d: centroid_errors(beacons, df) for d, df in dets.items()},
                          fig_dir / "centroid_vs_size.png", camera_of)
    figure_done()
    examples = []
    for cam, g in frames.groupby("camera"):
        row = g.sort_values("camera_height_m").iloc[0]
        name = f"example_{cam}.png"
        example_frame(run, row, beacons, dets, fig_dir / name)
        examples.append((cam, name))
        figure_done()
    ok = errors.groupby(["detector", "method"])["ok"].mean()
    lines = [f"# deckpose report: {_run_title(run)}", "",
             (f"{len(frames)} rendered frames; cameras {', '.join(sorted(frames.camera.unique()))}; "
             f"heights {', '.join(f'{h:g}' for h in sorted(frames.camera_height_m.unique()))} m; "
             f"detectors {', '.join(dets) or 'none'}; estimators {', '.join(sorted(errors.method.unique()))}."), "",
             "Share of frames with an estimate flagged ok: " + ", ".join(f"{d}+{m} {v:.1%}" for (d, m), v in zip(ok.index, ok)) + ".", "",
             *provenance_lines(run),
             "## Error against resolution", "",
             "![error vs resolution](figures/error_vs_resolution.png)", "",
             *(["Beacon cores clip (hollow points) at: "
                + ", ".join(f"{c} {h:g} m" for c, h in sorted(clipped)) + "."] if clipped else []),
             "",
             "## Error vs height", "", "![error vs height](figures/error_vs_height.png)", "",
             "## Error distributions", "", "![error distributions](figures/error_distributions.png)", "",
             "## Centroid error vs apparent beacon size", "", "![centroid vs size](figures/centroid_vs_size.png)", "",
             "## Beside the thesis", "",
             ("The thesis simulated eq. 4.1 noise on ideal pixel coordinates; here the errors come from "
             "rendered frames and real detectors. Its smallest noise level (4 px, Tables 4.4, 4.7, 4.10, 4.13) "
             "is shown."), ""]
    lines += thesis_comparison(table, sizes)
    lines += ["", "## Example frames", ""]
    lines += [f"![{cam}](figures/{name})" for cam, name in examples]
    lines += track_sections(run, frames, fig_dir, figure_done)
    lines += ["", resolution_markdown(table).replace("# Resolution tables", "## Resolution tables", 1)]
    md = run.report_dir / "report.md"
    with atomic_open(md, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return md
