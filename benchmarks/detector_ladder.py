"""The detector ladder: every detector on three rungs of difficulty and on each condition alone.

Rungs: ``configs/detector_benchmark_easy.yaml`` (today's conditions),
``..._real.yaml`` (our best estimate of a real landing) and ``..._hard.yaml``. Conditions:
the easy rung with one effect of the hard rung switched on, so a row says which condition
breaks which detector:

* ``uneven_leds``: point LEDs cos^6, units U(0.4, 1), bow at 0.4 (clear air);
* ``fog``: 0.5 km visibility alone;
* ``occlusion``: 10 % of beacons cut, up to wholly;
* ``other_lights``: navigation lights, 8 floodlights (3x a beacon), 12 glints;
* ``rolling_shutter``, ``defocus``, ``exposure``, ``optics``: the easy rung with the effect of
  ``configs/detector_benchmark_<name>.yaml`` (its values justified there).

Each dataset is rendered once into ``--work`` (resumed if there), benchmarked by
``deckpose.detect.bench_report.run_benchmark`` (the ``bench-detectors`` command's
engine, detection + identification on one thread) with its report in
``OUT/<dataset>/``, and pooled over heights and lightings into ``OUT/results.csv`` and
``OUT/report.md`` (``--only`` redoes some datasets and keeps the others' rows): recall, recall of cut beacons, precision, false detections per
frame, the share of recorded non-beacon lights that drew one, identification
accuracy, frames fully identified, the pooled RMS/CRB of the uncut spots with a 95 %
bootstrap interval (frames resampled), CPU time per frame, and a ranking per dataset (all of
them ``deckpose.detect.bench_ranking.pool_by_detector``'s, as in each dataset's report).

Usage (the committed report)::

    .venv/bin/python benchmarks/detector_ladder.py --work /tmp/ladder --out reports/detector_ladder
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import pandas as pd
import yaml
from deckpose.detect import registry
from deckpose.detect.bench_ranking import RANK_RULE, pool_by_detector
from deckpose.detect.bench_report import ranking_markdown, run_benchmark, write_report
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.sources import declared_gain, open_dataset
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset

from deckpose.atomic_io import atomic_open, atomic_path

ROOT = Path(__file__).resolve().parent.parent
RUNGS = ("easy", "real", "hard")
#: Conditions whose own config is the easy rung plus one effect (its values justified in it).
CONDITION_CONFIGS = {
    "rolling_shutter": "a rolling shutter (10 us a row) while the UAV drifts and turns",
    "defocus": "defocus",
    "exposure": "auto-exposure, a Bayer sensor and fixed-pattern noise",
    "optics": "a misfocused lens with diffraction, cos^4 vignetting and lateral colour",
}


def _rung(name: str) -> dict:
    return yaml.safe_load((ROOT / "configs" / f"detector_benchmark_{name}.yaml").read_text())


def datasets() -> dict[str, tuple[dict, str]]:
    """Dataset name -> (config document, what it holds)."""
    easy, hard = _rung("easy"), _rung("hard")
    out = {r: (_rung(r), f"rung '{r}' (configs/detector_benchmark_{r}.yaml)") for r in RUNGS}

    def easy_with(name: str, what: str, **sections: dict) -> None:
        doc = copy.deepcopy(easy)
        doc["name"] = f"detector_condition_{name}"
        doc.update(copy.deepcopy(sections))
        out[name] = (doc, f"easy + {what}")

    leds = dict(hard["leds"], visibility_km=None)
    easy_with("uneven_leds", "hard's LEDs (cos^6, U(0.4, 1), bow 0.4), clear air", leds=leds)
    easy_with("fog", "0.5 km visibility", leds={"visibility_km": hard["leds"]["visibility_km"]})
    easy_with("occlusion", "hard's occluders (10 %, up to wholly)", occlusion=hard["occlusion"])
    easy_with("other_lights", "hard's ship lights and glints", ship_lights=hard["ship_lights"])
    # conditions with a config of their own: the easy rung plus one effect, justified there
    for cond, what in CONDITION_CONFIGS.items():
        path = ROOT / "configs" / f"detector_benchmark_{cond}.yaml"
        if path.is_file():
            out[cond] = (_rung(cond), f"easy + {what} (configs/detector_benchmark_{cond}.yaml)")
    return out


def pooled(name: str, summary: pd.DataFrame, matches: pd.DataFrame, rng: np.random.Generator) -> pd.DataFrame:
    """One row per detector, the dataset's cells pooled and ranked (:func:`pool_by_detector`), named ``name``."""
    df = pool_by_detector(summary, matches, rng=rng)
    df.insert(0, "dataset", name)
    return df


def markdown(results: pd.DataFrame, what: dict[str, str], meta: dict) -> str:
    lines = ["# Detector ladder", ""]
    for run in meta["runs"]:
        lines.append(
            f"Datasets {', '.join(run['datasets'])} made by `{run['command']}` at commit {run['commit']} on "
            f"{run['machine']}; 1-minute load {run['load_start']:.1f} at the start, {run['load_end']:.1f} "
            f"at the end; {run['minutes']:.0f} minutes.")
        lines.append("")
    lines += ["Seeds are the configs' (recorded in each dataset's manifest).", "",
             ("Each dataset: 8 MP, 12-bit, heights 30/50/80 m, night/dusk/day, 5 thesis-series samples with 10 ms "
             "motion blur (45 frames). Rows are pooled over heights and lightings; a per-cell report is in "
             "`<dataset>/bench_detectors.md`."), "",
             ("Columns: recall over beacons in view and not wholly hidden; *cut*: recall of beacons an occluder "
             "cuts in part; precision; *false/fr*: detections matched to no beacon per frame; *lights*: share of "
             "the recorded non-beacon lights in view that drew one (within 4 px); *id*: found beacons with the "
             "right id; *frames ok*: frames detected and identified; RMS/CRB of the uncut spots (pooled, with "
             "its 95 % bootstrap interval over frames; the bound assumes unclipped pixels, and most beacon cores "
             "here saturate, so it is a scale, not a floor); the error is taken against the centroid of the "
             "beacon's light in the channel sum the detectors measure (under lateral colour, the flux-weighted "
             "mean of the red, green and blue centres); *geom.*: RMS/CRB against the geometric (green) centre "
             "instead, what the lens costs on top (the same as RMS/CRB without lateral colour; '—' for a dataset "
             "benchmarked before the column); "
             f"CPU ms per frame, median; {RANK_RULE}."), ""]
    lines += breaks_markdown(results)
    for name, g in results.groupby("dataset", sort=False):
        lines += [f"## {name}: {what[name]}", "", *ranking_markdown(g), ""]
    lines += ["![frames identified per dataset](frames_ok.png)", ""]
    return "\n".join(lines)


#: A detector is broken by a condition where, against the easy rung, its frames identified fall by
#: this much or more ...
BREAK_FRAMES_OK = 0.05
#: ... or its recall or precision falls by this much or more.
BREAK_RECALL = 0.02


def breaks_markdown(results: pd.DataFrame) -> list[str]:
    """The section that says which condition breaks which detector, against the easy rung.

    Every dataset but ``easy`` is the easy rung's frames with one condition added (or a rung's
    camera and conditions together); a detector is *broken* by it where its frames detected
    and identified fall by :data:`BREAK_FRAMES_OK` or more, or its recall or precision by
    :data:`BREAK_RECALL` or more. One row per dataset: each detector's frames ok and its change,
    the detectors it breaks and what falls, and the best detector there (rank 1).
    """
    if "easy" not in set(results["dataset"]):
        return []
    base = results[results["dataset"] == "easy"].set_index("detector")
    dets = list(base.sort_values("rank").index)
    head = ["dataset", *dets, "broken (what falls)", "best"]
    lines = ["## What breaks which detector", "",
             (f"Frames detected and identified per detector, and its change against the easy rung; a detector is "
              f"broken where its frames ok fall by {BREAK_FRAMES_OK:g} or more, or its recall or precision by "
              f"{BREAK_RECALL:g} or more. Each dataset is the easy rung's frames with the condition added "
              "(`real` and `hard`: a real camera and every condition at once)."), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, g in results.groupby("dataset", sort=False):
        g = g.set_index("detector")
        cells, broken = [], []
        for d in dets:
            if d not in g.index:
                cells.append("—")
                continue
            r, b = g.loc[d], base.loc[d]
            delta = r["frames_ok"] - b["frames_ok"]
            cells.append(f"{r['frames_ok']:.3f}" if name == "easy" else f"{r['frames_ok']:.3f} ({delta:+.3f})")
            falls = [f"{label} {r[k] - b[k]:+.3f}" for k, label, limit in
                     (("frames_ok", "frames ok", BREAK_FRAMES_OK), ("recall", "recall", BREAK_RECALL),
                      ("precision", "precision", BREAK_RECALL))
                     if name != "easy" and b[k] - r[k] >= limit]
            if falls:
                broken.append(f"{d} ({', '.join(falls)})")
        best = str(g["rank"].astype(float).idxmin()) if g["rank"].notna().any() else "—"
        lines.append("| " + " | ".join([name, *cells, "; ".join(broken) if broken else "none", best]) + " |")
    return [*lines, ""]


def plot(results: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(results["dataset"]))
    dets = sorted(results["detector"].unique())
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
    w = 0.8 / len(dets)
    for k, det in enumerate(dets):
        g = results[results["detector"] == det].set_index("dataset").reindex(names)
        x = np.arange(len(names)) + (k - (len(dets) - 1) / 2) * w
        axes[0].bar(x, g["frames_ok"], w, label=det)
        axes[1].bar(x, g["recall"], w, label=det)
    for ax, title in zip(axes, ("frames detected and identified", "recall")):
        ax.set_xticks(np.arange(len(names)), names, rotation=30, ha="right")
        ax.set_title(title)
        ax.set_ylim(0, 1.05)
        ax.grid(True, axis="y", alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def in_ladder_order(res: pd.DataFrame) -> pd.DataFrame:
    """The results' rows in the order of :func:`datasets` (stable within a dataset)."""
    order = {k: i for i, k in enumerate(datasets())}
    return res.sort_values("dataset", key=lambda c: c.map(order), kind="stable")


def write_ladder_report(out: Path, res: pd.DataFrame, meta: dict) -> None:
    """``frames_ok.png`` and ``report.md`` of results in ladder order, printed."""
    plot(res, out / "frames_ok.png")
    with atomic_open(out / "report.md", "w") as fh:
        fh.write(markdown(res, {k: v[1] for k, v in datasets().items()}, meta))
    print((out / "report.md").read_text())


def rewrite_report(out: Path) -> int:
    """Write ``report.md`` and ``frames_ok.png`` again from ``out``'s results and manifest (``--report-only``)."""
    if not (out / "results.csv").exists() or not (out / "manifest.json").exists():
        print(f"detector_ladder: {out} holds no results.csv and manifest.json to report; run the ladder "
              "first", file=sys.stderr)
        return 2
    write_ladder_report(out, in_ladder_order(pd.read_csv(out / "results.csv")),
                        json.loads((out / "manifest.json").read_text()))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", help="folder of the rendered datasets (resumed if present; needed but with "
                                    "--report-only)")
    ap.add_argument("--out", required=True, help="report folder")
    ap.add_argument("--detectors", help="comma-separated (default: every registered detector)")
    ap.add_argument("--only", help="comma-separated dataset names (default: all)")
    ap.add_argument("--workers", type=int, default=2, help="render worker processes")
    ap.add_argument("--seed", type=int, default=0, help="bootstrap seed")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite report.md and frames_ok.png from the report folder's results.csv and "
                         "manifest.json, rendering and benchmarking nothing")
    args = ap.parse_args(argv)
    if args.report_only:
        return rewrite_report(Path(args.out))
    if not args.work:
        ap.error("--work is needed to render and benchmark (only --report-only goes without it)")
    t0 = time.time()
    load0 = os.getloadavg()[0]
    # the code the run starts from (commits made while it runs are not its code)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True,
                            cwd=ROOT).stdout.strip()
    names = args.detectors.split(",") if args.detectors else registry.names()
    todo = datasets()
    if args.only:
        unknown = sorted(set(args.only.split(",")) - set(todo))
        if unknown:
            print(f"detector_ladder: no dataset named {', '.join(unknown)}; the datasets are "
                  f"{', '.join(todo)}", file=sys.stderr)
            return 2
        todo = {k: v for k, v in todo.items() if k in args.only.split(",")}
    out, work = Path(args.out), Path(args.work)
    (out / "configs").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    tables = []
    if (out / "results.csv").exists():  # keep the datasets this run does not redo (--only)
        kept = pd.read_csv(out / "results.csv")
        tables.append(kept[~kept["dataset"].isin(list(todo))])
    for name, (doc, _) in todo.items():
        with atomic_open(out / "configs" / f"{name}.yaml", "w") as fh:
            yaml.safe_dump(doc, fh, sort_keys=False)
        ds = work / name
        print(f"[{name}] render -> {ds}", flush=True)
        render_dataset(config_from_dict(doc, name), ds, workers=args.workers,
                       resume=(ds / "manifest.json").exists(), progress=True)
        manifest = open_dataset(ds).manifest
        options = DetectorOptions(gain_dn_per_e=declared_gain(manifest))
        print(f"[{name}] bench {','.join(names)}", flush=True)
        bench = run_benchmark(ds, names, options=options, progress=True)
        write_report(out / name, bench, dataset=str(ds), manifest=manifest, options=options,
                     note=f"Ladder dataset '{name}' ({todo[name][1]}).", seed=args.seed)
        tables.append(pooled(name, bench.summary, bench.matches, rng))
        res = pd.concat(tables, ignore_index=True)
        with atomic_path(out / "results.csv") as tmp:
            res.to_csv(tmp, index=False, float_format="%.6g")
    res = pd.concat(tables, ignore_index=True)
    every = datasets()
    res = in_ladder_order(res)
    this_run = {"command": " ".join([".venv/bin/python", "benchmarks/detector_ladder.py", *(argv or sys.argv[1:])]),
                "commit": commit, "machine": f"{platform.machine()}, {os.cpu_count()} cores",
                "load_start": load0, "load_end": os.getloadavg()[0], "minutes": (time.time() - t0) / 60,
                "datasets": list(todo)}
    # each dataset's provenance: the runs before this one keep the datasets it did not redo
    runs = []
    if args.only and (out / "manifest.json").exists():
        old = json.loads((out / "manifest.json").read_text())
        for r in old.get("runs", [dict(old, datasets=[k for k in every if k not in todo])]):
            kept_names = [d for d in r.get("datasets", []) if d not in todo and d in set(res["dataset"])]
            if kept_names:
                runs.append({k: v for k, v in dict(r, datasets=kept_names).items()
                             if k not in ("bootstrap_seed", "detectors", "runs")})
    runs.append(this_run)
    meta = {"runs": runs, "bootstrap_seed": args.seed, "detectors": names}
    with atomic_open(out / "manifest.json", "w") as fh:
        json.dump(meta, fh, indent=2)
    write_ladder_report(out, res, meta)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
