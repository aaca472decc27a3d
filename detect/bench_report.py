"""``deckpose bench-detectors``: run detectors on a dataset and write the benchmark report.

Writes into the output folder: ``bench_detectors.md`` (Markdown tables and
notes), ``bench_detectors.csv`` (the same numbers per detector x camera x height, with
the RMS/CRB's bootstrap interval and the rank of the detectors in each cell),
``bench_detectors_ranking.csv`` (the detectors pooled over the dataset and ranked,
:func:`~deckpose.detect.bench_ranking.pool_by_detector`), ``error_vs_height.png``
(per-axis RMS error vs camera height, one panel per resolution, with the CRB)
and ``error_vs_size.png`` (RMS error vs apparent beacon radius).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
from deckpose.detect.bench_ranking import (
    N_RESAMPLES,
    RANK_RULE,
    pool_by_detector,
    with_interval_and_rank,
)
from deckpose.detect.benchmark import (
    centroid_by_lighting,
    crb_per_beacon,
    false_detections,
    match_run,
    summarise,
)
from deckpose.detect.identify import IdentifyOptions
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.run import detect_frames_with
from deckpose.detect.sources import UNREADABLE_FRAME, FrameSet, open_dataset, require_images
from deckpose.detect.synthetic import SensorModel
from deckpose.detect.synthetic_dataset import summed_channels_sensor

from deckpose.atomic_io import atomic_open, atomic_path
from deckpose.errors import InputDataError
from deckpose.run_folder import RunPaths, read_lights, require_dataset

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class BenchmarkTables:
    """What :func:`run_benchmark` measured on a dataset.

    Attributes
    ----------
    summary : DataFrame
        One row per detector x camera x height (:func:`~deckpose.detect.benchmark.summarise`).
    matches : DataFrame
        Per-beacon rows of every detector (``detector``, ``crb_var_px2`` px^2, ``saturated``).
    summary_by_lighting : DataFrame
        The summary's rows split by lighting too (a ``lighting`` column); empty unless the
        dataset has several lightings.
    """

    summary: pd.DataFrame
    matches: pd.DataFrame
    summary_by_lighting: pd.DataFrame


def dataset_sensor(frameset: FrameSet) -> SensorModel | None:
    """The summed-channel sensor model of a dataset (:func:`manifest_sensor` of its manifest)."""
    return manifest_sensor(frameset.manifest)


def manifest_sensor(manifest: dict) -> SensorModel | None:
    """The summed-channel sensor model of a dataset that declares one (else None).

    Reads the manifest's ``sensor`` block (synthetic datasets, and rendered datasets
    from the renderer that records spot models); keys other than
    :class:`~deckpose.detect.synthetic.SensorModel`'s fields (``full_well_e``) are
    ignored. ``None`` for datasets without the block or rendered without noise.
    """
    doc = manifest.get("sensor")
    if not isinstance(doc, dict) or doc.get("noise", True) is False:
        return None
    known = {f.name for f in dataclasses.fields(SensorModel)}
    try:
        sensor = SensorModel(**{k: v for k, v in doc.items() if k in known})
    except (TypeError, ValueError):
        return None
    return summed_channels_sensor(sensor, int(manifest.get("sensor_channels", 1)))


def crb_note(beacons: pd.DataFrame, sensor: SensorModel | None) -> str:
    """Why the CRB column stays empty for a dataset ("" when it can be filled)."""
    missing = [c for c in ("spot_sigma_px", "spot_flux_e") if c not in beacons.columns]
    if sensor is None:
        return (
            "CRB left empty: the dataset's manifest has no sensor block (or it was rendered "
            "without noise); re-render it with this version of deckpose to get the bound."
        )
    if missing:
        return (
            f"CRB left empty: beacons.parquet lacks {', '.join(missing)} (a dataset rendered "
            "before the renderer recorded its spot model); re-render it to get the bound."
        )
    return ""


def saturated_flags(beacons: pd.DataFrame, manifest: dict) -> np.ndarray:
    """Per beacon row: whether its core reaches the full well (NaN where unknown)."""
    doc = manifest.get("sensor")
    full = doc.get("full_well_e") if isinstance(doc, dict) else None
    if full is None or "spot_peak_e" not in beacons.columns:
        return np.full(len(beacons), np.nan)
    peak = beacons["spot_peak_e"].to_numpy(float)
    return np.where(np.isfinite(peak), (peak >= float(full)).astype(float), np.nan)


def run_benchmark(
    dataset: str | os.PathLike[str],
    detectors: list[str],
    *,
    options: DetectorOptions = DetectorOptions(),
    progress: bool = False,
) -> BenchmarkTables:
    """Summary tables (per detector x camera x height, and x lighting) and per-beacon matches.

    Raises
    ------
    InputDataError
        The dataset lacks a table, keeps no frames (``--no-images``), or none of its
        frames can be read. Frames that cannot be read (a missing or damaged image) are
        left out of every table, with a warning naming each: they are no detector's miss.
    """
    run = RunPaths(Path(dataset))
    require_dataset(run)  # beacons.parquet too: the truth the detectors are scored against
    fs = open_dataset(dataset)
    require_images(fs, "render it again without --no-images to benchmark the detectors on its frames")
    beacons = pd.read_parquet(run.beacons)
    frames = pd.read_parquet(run.frames)
    lights = read_lights(run) if run.manifest.exists() else None
    sensor = dataset_sensor(fs)
    summaries, matches, by_lighting = [], [], []
    crb_cache: pd.Series | None = None
    runs = detect_frames_with(
        fs, detectors, options=options, identify_options=IdentifyOptions(), progress=progress
    )
    unread = unreadable_frames(runs[detectors[0]][1])
    if len(unread) == len(fs.sources):
        first = next(iter(unread.values()), "no frames")
        raise InputDataError(f"{dataset}: none of its {len(fs.sources)} frames can be read ({first})")
    for fid, why in unread.items():
        log.warning("frame %d left out of the benchmark: %s", fid, why)
    if unread:  # not the detectors' misses: out of every table
        gone = list(unread)
        beacons = beacons[~beacons["frame_id"].isin(gone)]
        frames = frames[~frames["frame_id"].isin(gone)]
        runs = {d: (t[~t["frame_id"].isin(gone)], f[~f["frame_id"].isin(gone)]) for d, (t, f) in runs.items()}
    for name in detectors:
        dets, fout = runs[name]
        m = match_run(dets, fout, beacons, frames)
        if crb_cache is None:
            crb_cache = pd.Series(
                crb_per_beacon(m, sensor),
                index=pd.MultiIndex.from_frame(m[["frame_id", "beacon_id"]]),
            )
        m["crb_var_px2"] = crb_cache.reindex(
            pd.MultiIndex.from_frame(m[["frame_id", "beacon_id"]])
        ).to_numpy()
        m["saturated"] = saturated_flags(m, fs.manifest)
        m["detector"] = name
        false = false_detections(dets, m, lights, [int(i) for i in frames["frame_id"]])
        summaries.append(summarise(name, m, dets, fout, frames, false))
        if "lighting" in m and m["lighting"].nunique() > 1:  # the cells' frames of each lighting
            by_lighting += [summarise(name, g, dets, fout, frames, false).assign(lighting=str(light))
                            for light, g in m.groupby("lighting", sort=True)]
        matches.append(m)
    return BenchmarkTables(
        pd.concat(summaries, ignore_index=True),
        pd.concat(matches, ignore_index=True),
        pd.concat(by_lighting, ignore_index=True) if by_lighting else pd.DataFrame(),
    )


def unreadable_frames(frames_table: pd.DataFrame) -> dict[int, str]:
    """Frames the loader could not use (a missing, damaged or mis-sized image): the frame's own fault.

    Parameters
    ----------
    frames_table : DataFrame
        A detector's frames table (``frame_id``, ``ok``, ``reason``); the loader's reason
        is every detector's, so any detector's table will do.

    Returns
    -------
    dict
        Frame id to the loader's reason (:data:`~deckpose.detect.sources.UNREADABLE_FRAME`), in frame order.
    """
    bad = [not ok and bool(UNREADABLE_FRAME.match(str(r))) for ok, r in zip(frames_table["ok"], frames_table["reason"])]
    return {int(f): str(r) for f, r, b in zip(frames_table["frame_id"], frames_table["reason"], bad) if b}


def _fmt(x: float, nd: int = 3) -> str:
    return "—" if not np.isfinite(x) else f"{x:.{nd}f}"


def _interval(r: dict) -> str:
    """A row's RMS/CRB and its 95 % interval: ``1.02 [0.95, 1.10]``."""
    return (f"{_fmt(r['rms_over_crb'], 2)} "
            f"[{_fmt(r['rms_over_crb_lo'], 2)}, {_fmt(r['rms_over_crb_hi'], 2)}]")


def ranking_markdown(pooled: pd.DataFrame) -> list[str]:
    """Markdown lines (head and rows) of :func:`~deckpose.detect.bench_ranking.pool_by_detector`'s table.

    Rows in the table's order; ``rms_geometric_over_crb`` may be missing ('—').
    """
    lines = [("| rank | detector | recall | cut | precision | false/fr | lights | id | frames ok "
              "| RMS/CRB [95 %] | geom. | CPU ms |"), "|" + "|".join(["---"] * 12) + "|"]
    for r in pooled.to_dict("records"):
        lines.append(
            f"| {r['rank']} | {r['detector']} | {_fmt(r['recall'])} | {_fmt(r['recall_occluded'])} | "
            f"{_fmt(r['precision'])} | {_fmt(r['false_per_frame'], 2)} | {_fmt(r['lights_found'], 2)} | "
            f"{_fmt(r['id_accuracy'])} | {_fmt(r['frames_ok'])} | {_interval(r)} | "
            f"{_fmt(r.get('rms_geometric_over_crb', math.nan), 2)} | "
            f"{_fmt(r['cpu_ms_per_frame'], 0)} |")
    return lines


def markdown_table(summary: pd.DataFrame) -> str:
    """The summary (with :func:`~deckpose.detect.bench_ranking.with_interval_and_rank`'s columns) as Markdown."""
    head = (
        "| rank | detector | camera | height m | radius px | sat. | RMS px | CRB px | RMS/CRB [95 %] "
        "| RMS geom. px | bias px | p95 px | recall | precision | id acc. | false/frame | lights hit "
        "| frames ok | ms/frame | CPU ms |"
    )
    lines = [head, "|" + "|".join(["---"] * 20) + "|"]
    for r in summary.sort_values(["camera", "height_m", "rank"]).to_dict("records"):
        lines.append(
            f"| {r['rank']} | {r['detector']} | {r['camera']} | {r['height_m']:g} | {r['radius_px']:.2f} | "
            f"{_fmt(r.get('saturated', math.nan), 2)} | {_fmt(r['rms_px'], 4)} | "
            f"{_fmt(r['crb_px'], 4)} | {_interval(r)} | "
            f"{_fmt(r.get('rms_geometric_px', math.nan), 4)} | {_fmt(r['bias_px'], 4)} | {_fmt(r['p95_px'], 4)} | {_fmt(r['recall'], 3)} | "
            f"{_fmt(r['precision'], 3)} | {_fmt(r['id_accuracy'], 3)} | "
            f"{_fmt(r.get('false_per_frame', math.nan), 2)} | {_fmt(r.get('lights_found', math.nan), 2)} | "
            f"{r['frames_ok']}/{r['frames']} | {_fmt(r['ms_per_frame'], 1)} | "
            f"{_fmt(r.get('cpu_ms_per_frame', math.nan), 1)} |"
        )
    return "\n".join(lines)


def lighting_table(tables: BenchmarkTables, *, rng: np.random.Generator) -> pd.DataFrame:
    """The centroid error per detector x camera x height x lighting, with interval and rank.

    Every row of ``tables.summary_by_lighting`` (``frames_ok`` of ``frames``, ``recall`` and
    ``precision``, each detector x camera x height x lighting) with
    :func:`~deckpose.detect.benchmark.centroid_by_lighting`'s columns where the detector
    matched a beacon there (NaN and 0 beacons where it matched none: it is still ranked) and
    :func:`~deckpose.detect.bench_ranking.with_interval_and_rank`'s columns, the detectors
    ranked within each camera x height x lighting. Empty with one lighting.
    """
    by_light = centroid_by_lighting(tables.matches)
    if by_light.empty:
        return by_light
    keys = ["detector", "camera", "height_m", "lighting"]
    # every detector of every cell and lighting, its centroid figures where it matched a beacon
    # (one that matched none there is still ranked, last on recall)
    split = tables.summary_by_lighting[[*keys, "frames", "frames_ok", "recall", "precision"]]
    by_light = split.merge(by_light, on=keys, how="left")
    by_light["beacons"] = by_light["beacons"].fillna(0).astype(int)
    return with_interval_and_rank(by_light, tables.matches, within=keys[1:], rng=rng)


def lighting_section(by_light: pd.DataFrame) -> list[str]:
    """Markdown lines of :func:`lighting_table` (none when the dataset has one lighting)."""
    if by_light.empty:
        return []
    lines = ["## Centroid error by lighting", "",
             ("The table above pools the dataset's lightings; here they are apart, the detectors "
              "ranked within each camera, height and lighting."), "",
             ("| rank | detector | camera | height m | lighting | beacons | recall | precision | frames ok "
              "| RMS px | CRB px | RMS/CRB [95 %] |"),
             "|" + "|".join(["---"] * 12) + "|"]
    for r in by_light.sort_values(["camera", "height_m", "lighting", "rank"]).to_dict("records"):
        lines.append(f"| {r['rank']} | {r['detector']} | {r['camera']} | {r['height_m']:g} | {r['lighting']} | "
                     f"{r['beacons']} | {_fmt(r['recall'])} | {_fmt(r['precision'])} | "
                     f"{r['frames_ok']}/{r['frames']} | "
                     f"{_fmt(r['rms_px'], 4)} | {_fmt(r['crb_px'], 4)} | {_interval(r)} |")
    return lines + [""]


def plot_error_vs_height(summary: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cams = sorted(summary["camera"].unique())
    fig, axes = plt.subplots(1, len(cams), figsize=(5 * len(cams), 4), squeeze=False, sharey=True)
    for ax, cam in zip(axes[0], cams):
        s = summary[summary["camera"] == cam]
        for det, g in s.groupby("detector"):
            g = g.sort_values("height_m")
            ax.plot(g["height_m"], g["rms_px"], "o-", label=det)
        g = s.drop_duplicates("height_m").sort_values("height_m")
        if np.isfinite(g["crb_px"]).any():
            ax.plot(g["height_m"], g["crb_px"], "k--", label="CRB")
        ax.set_yscale("log")
        ax.set_title(f"camera {cam}")
        ax.set_xlabel("camera height (m)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("per-axis RMS centroid error (px)")
    axes[0][-1].legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def plot_error_vs_size(matches: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = matches[matches["matched"]]
    fig, ax = plt.subplots(figsize=(6, 4))
    if m.empty:  # no detector found a beacon: say so on the figure rather than fail
        ax.text(0.5, 0.5, "no beacon found by any detector", ha="center", va="center", transform=ax.transAxes)
    edges = np.unique(np.quantile(m["apparent_radius_px"], np.linspace(0, 1, 9))) if len(m) else np.zeros(0)
    for det, g in m.groupby("detector"):
        idx = np.clip(np.digitize(g["apparent_radius_px"], edges) - 1, 0, len(edges) - 2)
        x, y = [], []
        for b in range(len(edges) - 1):
            sel = g[idx == b]
            if len(sel):
                x.append(sel["apparent_radius_px"].mean())
                y.append(np.sqrt(np.mean((sel["du_px"] ** 2 + sel["dv_px"] ** 2) / 2)))
        ax.plot(x, y, "o-", label=det)
    if np.isfinite(m["crb_var_px2"]).any():
        g = m.drop_duplicates(["frame_id", "beacon_id"])
        idx = np.clip(np.digitize(g["apparent_radius_px"], edges) - 1, 0, len(edges) - 2)
        xs = [
            g[idx == b]["apparent_radius_px"].mean()
            for b in range(len(edges) - 1)
            if (idx == b).any()
        ]
        ys = [
            np.sqrt(g[idx == b]["crb_var_px2"].mean())
            for b in range(len(edges) - 1)
            if (idx == b).any()
        ]
        ax.plot(xs, ys, "k--", label="CRB")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("apparent beacon radius (px)")
    ax.set_ylabel("per-axis RMS centroid error (px)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def write_report(
    out_dir: str | os.PathLike[str],
    tables: BenchmarkTables,
    *,
    dataset: str,
    manifest: dict,
    options: DetectorOptions,
    note: str = "",
    seed: int = 0,
) -> Path:
    """Write the Markdown report, CSV tables and plots; returns the Markdown path.

    The RMS/CRB intervals draw on ``numpy.random.default_rng(seed)`` (recorded in the
    report): first the ranking over the dataset
    (:func:`~deckpose.detect.bench_ranking.pool_by_detector`,
    ``bench_detectors_ranking.csv``), then the summary's cells (``bench_detectors.csv``),
    then, for a dataset with several lightings, :func:`lighting_table`
    (``bench_detectors_by_lighting.csv`` and a section of the report).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    matches = tables.matches
    rng = np.random.default_rng(seed)
    ranking = pool_by_detector(tables.summary, matches, rng=rng)
    summary = with_interval_and_rank(tables.summary, matches, within=("camera", "height_m"), rng=rng)
    by_light = lighting_table(tables, rng=rng)
    with atomic_path(out / "bench_detectors.csv") as tmp:
        summary.to_csv(tmp, index=False, float_format="%.6g")
    with atomic_path(out / "bench_detectors_ranking.csv") as tmp:
        ranking.to_csv(tmp, index=False, float_format="%.6g")
    if not by_light.empty:
        with atomic_path(out / "bench_detectors_by_lighting.csv") as tmp:
            by_light.to_csv(tmp, index=False, float_format="%.6g")
    plot_error_vs_height(summary, out / "error_vs_height.png")
    plot_error_vs_size(matches, out / "error_vs_size.png")
    gen = manifest.get("generator", "a rendered deckpose dataset")
    missing_crb = crb_note(matches, manifest_sensor(manifest))
    md = [
        "# Detector benchmark",
        "",
        f"Dataset: `{dataset}` — {gen}.",
        "",
        note,
        "",
        *([missing_crb, ""] if missing_crb else []),
        f"Detector options: `{dataclasses.asdict(options)}`.",
        "",
        "## Ranking",
        "",
        "The detectors pooled over the dataset's cameras, heights and lightings.",
        "",
        *ranking_markdown(ranking),
        "",
        ("frames ok = share of frames detected and identified; cut = recall of the beacons an occluder "
         "cuts in part; the other columns as below (sums over the cells, CPU ms the median of theirs)."),
        "",
        "## Per camera and height",
        "",
        markdown_table(summary),
        "",
        ("RMS = per-axis RMS centroid error against the centroid of the beacon's light in the channel sum "
        "the detectors measure (the exact projected centre, unless a lens's lateral colour moves the red and "
        "blue light: then the flux-weighted mean of the channels' exact centres); RMS geom. = the same against "
        "the projected (green, geometric) centre, what the lens costs on top; "
        "CRB = per-axis RMS of the centroid Cramér–Rao bound (unknown centre, width, flux and "
        "background; Poisson + read + quantisation noise; pixels assumed unclipped), '—' where "
        "the dataset does not declare its spot model and sensor; sat. = fraction of the cell's "
        "beacons whose core reaches the full well (the bound is optimistic for those); "
        "bias = length of the mean error vector; "
        "p95 = 95th percentile of the radial error; recall and "
        "precision from one-to-one matching within max(3 px, 2 apparent radii); id acc. = matched "
        "detections with the right beacon id; false/frame = detections matched to no beacon, "
        "per frame; lights hit = fraction of the recorded non-beacon lights in view (lights.parquet: "
        "navigation lights, floodlights, glints) that drew a false detection within 4 px; "
        "occluded beacons count in the recall but not in RMS or CRB; ms/frame = median wall time of detection + "
        "identification (decoded image, this machine); CPU ms = median CPU time of the same "
        "work on its one thread (the one-core cost when other jobs share the machine); "
        "frames ok = frames detected and identified, of the cell's frames."),
        "",
        (f"RMS/CRB = sqrt(sum(e^2) / sum(CRB)) over the uncut matched spots, with its 95 % percentile "
         f"bootstrap interval in brackets ({N_RESAMPLES} resamples of the frames, not the beacons, "
         f"since a frame's spots share its pose and blur; seed {seed}; a cell of one frame gives "
         f"no interval: it collapses to the point); "
         f"{RANK_RULE}. A group is the whole dataset in the ranking, a camera x height cell in the "
         "table per camera and height, and a camera x height x lighting cell in the table by lighting."),
        "",
        *lighting_section(by_light),
        "![error vs height](error_vs_height.png)",
        "",
        "![error vs size](error_vs_size.png)",
        "",
    ]
    with atomic_open(out / "bench_detectors.md", "w") as fh:
        fh.write("\n".join(md))
    return out / "bench_detectors.md"
