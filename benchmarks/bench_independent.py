"""Detectors on frames the project did not render, beside astronomy's centroiders.

Frames come from :mod:`independent_spots` (beside this file), which shares no code
with ``render/`` or ``detect/``. Each dataset is a family of 8 MP frames (see
:data:`DATASETS`); every registered detector (ours, and ``sep`` / ``photutils``
where ``deckpose[peers]`` is installed) runs on each frame through
``deckpose.detect.frame_detection.detect_frame`` (detection + identification), and its
detections are matched to the truth:

* recall (beacons found), identification (beacons with the right id), frames
  fully identified, detections on the frame's other lights, false detections
  (on nothing);
* centroid error over the per-axis Cramér–Rao bound of the channel-sum image,
  pooled as ``sqrt(mean((e / crb)^2))`` over both axes of every found beacon
  whose spot is not clipped, with a 95 % bootstrap interval (beacons resampled);
  also on the beacons every detector found (a like-for-like comparison), and per
  sigma and flux bin;
* CPU time per frame of detection + identification (one thread).

Usage (the committed report)::

    .venv/bin/python benchmarks/bench_independent.py --out reports/detectors_independent

``--frames`` sets frames per dataset, ``--seed`` the master seed (recorded).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2
import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_spots as gen
from deckpose.detect import registry
from deckpose.detect.frame_detection import detect_frame

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame

BASE = gen.SpotFrameSpec()
#: The datasets: name -> (spec, what it tests).
DATASETS: dict[str, tuple[gen.SpotFrameSpec, str]] = {
    "rgb_equal": (BASE, "RGB, 12-bit in 16, every beacon U(3k, 30k) e log-uniform"),
    "rgb_uneven": (replace(BASE, uneven=(0.4, 1.0)), "as rgb_equal, each beacon x U(0.4, 1)"),
    "mono_dim_bow": (
        replace(BASE, rgb=False, bits=16, uneven=(0.4, 1.0)),
        "mono 16-bit, uneven; the red bow at 0.43x in grey",
    ),
    "rgb8_uneven": (
        replace(BASE, bits=8, full_well_e=6000.0, uneven=(0.4, 1.0)),
        "RGB 8-bit (6,000 e full scale), uneven",
    ),
    "hard": (
        replace(BASE, sigma_px=(0.7, 3.0), flux_e=(2000.0, 30000.0), uneven=(0.4, 1.0),
                missing_ring=3, drop_centre=True, other_lights=5),
        "sigma 0.7-3 px, 2k-30k e, uneven, 3 ring beacons and the centre missing, 5 other lights",
    ),
    "saturated": (
        replace(BASE, saturate=True, full_well_e=1000.0, uneven=(0.4, 1.0)),
        "RGB, uneven, cores of the brighter beacons clip (1,000 e full scale)",
    ),
    # (last: a dataset's frames are drawn from its position in this table, so the others keep theirs)
    "rgb8_dark": (
        replace(BASE, bits=8, uneven=(0.4, 1.0)),
        "RGB 8-bit (20,000 e full scale): the 30 e background is 0.38 DN a channel and rounds to 0 DN, uneven",
    ),
}

SIGMA_BINS = (0.7, 1.2, 1.8, 3.01)
FLUX_BINS = (2000.0, 5000.0, 12000.0, 30001.0)


def run_dataset(name: str, n_frames: int, seed: int, detectors: list[str]) -> pd.DataFrame:
    """One row per (detector, frame, true beacon) plus rows for false detections."""
    spec = DATASETS[name][0]
    rng = np.random.default_rng([seed, list(DATASETS).index(name)])
    layout = DeckLayout()
    rows = []
    for k in range(n_frames):
        fr = gen.make_frame(spec, rng)
        cam = CameraModel(fr.image.shape[1], fr.image.shape[0], fr.K)
        frame = Frame(fr.image, cam, k)
        for det in detectors:
            res = detect_frame(frame, det, layout)
            pts = res.detections.points_px
            ids = res.detections.beacon_ids
            idx, _ = gen.match(pts, fr)
            used = {int(i) for i in idx if i >= 0}
            for i in range(fr.beacon_id.size):
                j = int(idx[i])
                e = pts[j] - fr.centre_px[i] if j >= 0 else np.array([np.nan, np.nan])
                rows.append({
                    "dataset": name, "detector": det, "frame": k, "kind": "beacon",
                    "beacon_id": int(fr.beacon_id[i]), "found": j >= 0,
                    "id_ok": bool(j >= 0 and ids[j] == fr.beacon_id[i]),
                    "eu": e[0] / fr.crb_px[i, 0], "ev": e[1] / fr.crb_px[i, 1],
                    "err_px": float(np.hypot(*e)), "crb_px": float(np.mean(fr.crb_px[i])),
                    "sigma_px": fr.sigma_px[i], "flux_e": fr.flux_e[i],
                    "saturated": bool(fr.saturated[i]), "frame_ok": res.ok,
                    "cpu_s": res.cpu_seconds,
                })
            rest = [j for j in range(len(pts)) if j not in used]
            for j in rest:
                on_light = (fr.lights_px.size > 0 and np.min(
                    np.linalg.norm(fr.lights_px - pts[j], axis=1)) < 6.0)
                rows.append({
                    "dataset": name, "detector": det, "frame": k,
                    "kind": "light" if on_light else "false", "beacon_id": int(ids[j]),
                    "found": True, "id_ok": False, "frame_ok": res.ok, "cpu_s": res.cpu_seconds,
                })
        print(f"  {name}: frame {k + 1}/{n_frames}", file=sys.stderr, flush=True)
    return pd.DataFrame(rows)


def pooled(e: np.ndarray) -> float:
    """``sqrt(mean(e^2))`` of (n, 2) normalised errors."""
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def bootstrap(e: np.ndarray, rng: np.random.Generator, n: int = 2000) -> tuple[float, float]:
    """95 % interval of :func:`pooled`, beacons resampled."""
    if len(e) < 5:
        return float("nan"), float("nan")
    sq = np.mean(e**2, axis=1)
    idx = rng.integers(0, len(sq), (n, len(sq)))
    vals = np.sqrt(sq[idx].mean(axis=1))
    return float(np.percentile(vals, 2.5)), float(np.percentile(vals, 97.5))


def summarise(df: pd.DataFrame, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    out = []
    for (ds, det), g in df.groupby(["dataset", "detector"], sort=False):
        b = g[g.kind == "beacon"]
        good = b[b.found & ~b.saturated]
        e = good[["eu", "ev"]].to_numpy(float)
        # like-for-like: beacons every detector found, unclipped
        # (among the detectors that found any beacon of the dataset: one that found none, as
        # photutils on the dark 8-bit frames, would leave no common beacon to compare on)
        allb = df[(df.dataset == ds) & (df.kind == "beacon")]
        allb = allb[allb.groupby("detector").found.transform("any").astype(bool)]
        common = allb.groupby(["frame", "beacon_id"]).found.all()
        key = set(common[common].index)
        # (a boolean array, not a list: an empty list would select columns, and a detector that
        # found no unclipped beacon of a dataset has an empty one)
        sel = np.array([(f, i) in key for f, i in zip(good.frame, good.beacon_id)], dtype=bool)
        ec = good[sel][["eu", "ev"]].to_numpy(float)
        lo, hi = bootstrap(e, rng)
        frames = g.groupby("frame").agg(ok=("frame_ok", "first"), cpu=("cpu_s", "first"))
        out.append({
            "dataset": ds, "detector": det, "beacons": len(b),
            "recall": b.found.mean(), "id_accuracy": b.id_ok.mean(),
            "frames_ok": frames.ok.mean(),
            "on_lights": int((g.kind == "light").sum()), "false": int((g.kind == "false").sum()),
            "rms_over_crb": pooled(e), "ci_lo": lo, "ci_hi": hi,
            "rms_over_crb_common": pooled(ec), "n_common": len(ec),
            "cpu_ms_per_frame": 1e3 * float(frames.cpu.median()),
        })
    return pd.DataFrame(out)


def binned(df: pd.DataFrame, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed + 1)
    b = df[(df.kind == "beacon") & df.found & ~df.saturated.astype(bool)].copy()
    b["sigma_bin"] = pd.cut(b.sigma_px, SIGMA_BINS)
    b["flux_bin"] = pd.cut(b.flux_e, FLUX_BINS)
    out = []
    for col in ("sigma_bin", "flux_bin"):
        for (det, bin_), g in b.groupby(["detector", col], observed=True, sort=True):
            e = g[["eu", "ev"]].to_numpy(float)
            lo, hi = bootstrap(e, rng)
            out.append({"by": col.replace("_bin", ""), "bin": str(bin_), "detector": det,
                        "n": len(g), "rms_over_crb": pooled(e), "ci_lo": lo, "ci_hi": hi})
    return pd.DataFrame(out)


def plot(summary: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dsets = list(dict.fromkeys(summary.dataset))
    dets = list(dict.fromkeys(summary.detector))
    fig, ax = plt.subplots(figsize=(10, 4.5))
    width = 0.8 / len(dets)
    for k, det in enumerate(dets):
        s = summary[summary.detector == det].set_index("dataset").reindex(dsets)
        x = np.arange(len(dsets)) + (k - (len(dets) - 1) / 2) * width
        y = s.rms_over_crb.to_numpy(float)
        err = np.vstack([y - s.ci_lo.to_numpy(float), s.ci_hi.to_numpy(float) - y])
        ax.bar(x, y, width, label=det, yerr=np.nan_to_num(err), capsize=2)
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="Cramér–Rao bound")
    ax.set_xticks(np.arange(len(dsets)), dsets, rotation=15)
    ax.set_yscale("log")
    ax.set_ylabel("pooled RMS centroid error / CRB")
    ax.set_title("Frames from an independent generator (95 % bootstrap intervals)")
    ax.legend(ncol=4, fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def _fmt(x: float, nd: int = 3) -> str:
    return "–" if not np.isfinite(x) else f"{x:.{nd}f}"


def write_report(out: Path, summary: pd.DataFrame, bins: pd.DataFrame, meta: dict) -> None:
    lines = [
        "# Detectors on frames we did not render",
        "",
        ("Frames from `benchmarks/independent_spots.py`, a generator that shares no code with "
        "`render/` or `detect/` (its own projection, erf-integrated Gaussian spots, Poisson + "
        "read noise, rounding, clipping, and its own Cramér–Rao bound of the channel-sum "
        "image). Every detector runs through `detect_frame` (detection + identification)."),
        "",
        f"Made by: `{meta['command']}`  ",
        (f"Seed {meta['seed']}, {meta['frames']} frames of 3840x2160 per dataset; "
        f"{meta['machine']}; load average {meta['load']} at the start; "
        f"{meta['minutes']:.1f} min."),
        "",
        "## Datasets",
        "",
        "| dataset | what |",
        "|---|---|",
    ]
    lines += [f"| `{k}` | {v[1]} |" for k, v in DATASETS.items()]
    lines += [
        "",
        ("Common to all: 13 beacons (12 on the ring, bow red, and the centre), spot sigma "
        "0.8–2.5 px and 3,000–30,000 e (channel sum) unless stated, background 30 e and read "
        "noise 5 e per pixel and channel, camera 35–60 m above the deck, tilted up to 5°."),
        "",
        "## Results",
        "",
        ("*recall*: beacons found (within max(3 px, 3 sigma)); *id*: beacons given their "
        "right id; *frames ok*: frames detected and fully identified; *lights*: detections "
        "on the frame's other lights (not beacons, they should get no id); *false*: "
        "detections on nothing. *RMS/CRB*: pooled over both axes of every found, unclipped "
        "beacon, with its 95 % bootstrap interval; *common*: over the beacons every "
        "detector found (every detector that found any beacon of the dataset). *CPU*: median per frame, detection + identification, one thread."),
        "",
        ("| dataset | detector | recall | id | frames ok | lights | false | RMS/CRB | 95 % | "
        "common | CPU ms |"),
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in summary.itertuples():
        lines.append(
            f"| {r.dataset} | {r.detector} | {_fmt(r.recall)} | {_fmt(r.id_accuracy)} | "
            f"{_fmt(r.frames_ok, 2)} | {r.on_lights} | {r.false} | {_fmt(r.rms_over_crb)} | "
            f"{_fmt(r.ci_lo, 2)}–{_fmt(r.ci_hi, 2)} | {_fmt(r.rms_over_crb_common)} | "
            f"{r.cpu_ms_per_frame:.0f} |"
        )
    lines += ["", "![RMS over CRB per dataset](rms_over_crb.png)", "",
              "## By spot sigma and flux (all datasets pooled, unclipped beacons)", "",
              "| by | bin | detector | n | RMS/CRB | 95 % |", "|---|---|---|---|---|---|"]
    for r in bins.itertuples():
        lines.append(f"| {r.by} | {r.bin} | {r.detector} | {r.n} | {_fmt(r.rms_over_crb)} | "
                     f"{_fmt(r.ci_lo, 2)}–{_fmt(r.ci_hi, 2)} |")
    lines += ["", "## Best of ours against the best peer", ""]
    ours = [d for d in summary.detector.unique() if d not in registry.OPTIONAL_DETECTORS]
    peers = [d for d in summary.detector.unique() if d in registry.OPTIONAL_DETECTORS]
    lines += [("| dataset | best of ours | RMS/CRB (common) | CPU ms | best peer | "
              "RMS/CRB (common) | CPU ms |"), "|---|---|---|---|---|---|---|"]
    for ds, g in summary.groupby("dataset", sort=False):
        g = g.set_index("detector")
        if g.loc[ours].rms_over_crb_common.isna().all():
            continue  # (none of ours found a beacon of this dataset: nothing to rank)
        o = g.loc[ours].rms_over_crb_common.idxmin()
        if peers and not g.loc[peers].rms_over_crb_common.isna().all():
            p = g.loc[peers].rms_over_crb_common.idxmin()
            lines.append(f"| {ds} | {o} | {_fmt(g.rms_over_crb_common[o])} | "
                         f"{g.cpu_ms_per_frame[o]:.0f} | {p} | "
                         f"{_fmt(g.rms_over_crb_common[p])} | {g.cpu_ms_per_frame[p]:.0f} |")
    text = "\n".join(lines) + "\n"
    tmp = out / ".report.md.tmp"
    tmp.write_text(text)
    os.replace(tmp, out / "report.md")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", "-o", type=Path, default=Path("reports/detectors_independent"),
                    help="report folder (default reports/detectors_independent)")
    ap.add_argument("--frames", type=int, default=24, help="frames per dataset (default 24)")
    ap.add_argument("--seed", type=int, default=2026, help="master seed (default 2026)")
    ap.add_argument("--datasets", default=",".join(DATASETS),
                    help="comma-separated datasets (default all)")
    ap.add_argument("--detectors", default="",
                    help="comma-separated detectors (default all registered)")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    dets = args.detectors.split(",") if args.detectors else registry.names()
    names = args.datasets.split(",")
    unknown = [n for n in names if n not in DATASETS]
    if unknown:
        ap.error(f"unknown dataset(s) {unknown}; choose from {', '.join(DATASETS)}")
    t0 = time.time()
    load = os.getloadavg()[0]
    df = pd.concat([run_dataset(n, args.frames, args.seed, dets) for n in names])
    args.out.mkdir(parents=True, exist_ok=True)
    # the matches first: the run's costly part survives a failure in what is made from it
    tmp = args.out / ".matches.csv.tmp"
    df.to_csv(tmp, index=False)
    os.replace(tmp, args.out / "matches.csv")
    summary = summarise(df, args.seed)
    bins = binned(df, args.seed)
    for name, table in (("results.csv", summary), ("by_bin.csv", bins)):
        tmp = args.out / f".{name}.tmp"
        table.to_csv(tmp, index=False)
        os.replace(tmp, args.out / name)
    meta = {
        "command": "python benchmarks/bench_independent.py " + " ".join(argv or sys.argv[1:]),
        "seed": args.seed, "frames": args.frames, "datasets": names, "detectors": dets,
        "specs": {n: asdict(DATASETS[n][0]) for n in names},
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "load": f"{load:.2f}", "minutes": (time.time() - t0) / 60,
    }
    (args.out / "manifest.json").write_text(json.dumps(meta, indent=2, default=str))
    plot(summary, args.out / "rms_over_crb.png")
    write_report(args.out, summary, bins, meta)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(summary.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"report: {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
