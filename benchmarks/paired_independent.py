"""Two detectors compared beacon by beacon on the same frames, from ``bench_independent.py``'s table.

The pooled RMS/CRB of each detector in ``report.md`` has a bootstrap interval of about
+-0.08 on 12 frames, too wide to tell two detectors near the bound apart. Both saw
the same frames and, on the beacons both found, largely the same noise, so their
*difference* is known much better. For each dataset this prints, over the unclipped
beacons both detectors found:

* each one's pooled ``sqrt(mean((e / crb)^2))`` (both axes);
* their ratio, with a 95 % bootstrap interval that resamples *frames* (a frame's
  beacons share its draw), pairs kept together;
* the mean paired difference of the normalised squared errors (axes averaged), with
  its interval the same way.

Usage::

    .venv/bin/python benchmarks/paired_independent.py reports/detectors_independent/matches.csv
    .venv/bin/python benchmarks/paired_independent.py MATCHES.csv --a gauss --b sep --boot 4000

It reads the ``matches.csv`` of a report folder (columns ``dataset, detector, frame,
kind, beacon_id, found, saturated, eu, ev``); it runs no detector.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

COLUMNS = ("dataset", "detector", "frame", "kind", "beacon_id", "found", "saturated", "eu", "ev")


def paired_table(matches: pd.DataFrame, a: str, b: str, *, n_boot: int = 4000,
                 seed: int = 1) -> pd.DataFrame:
    """One row per dataset holding both detectors: the paired comparison of ``a`` against ``b``.

    Parameters
    ----------
    matches : DataFrame
        ``bench_independent.py``'s per-beacon table (:data:`COLUMNS` at least).
    a, b : str
        Detector names.
    n_boot : int
        Bootstrap resamples of the frames.
    seed : int
        Seed of the bootstrap's generator.

    Returns
    -------
    DataFrame
        ``dataset, frames, beacons, rms_a, rms_b, ratio, ratio_lo, ratio_hi, mean_d,
        d_lo, d_hi`` (``d``: the per-beacon ``(ea^2 - eb^2)`` averaged over the axes,
        errors in CRB units).
    """
    missing = [c for c in COLUMNS if c not in matches.columns]
    if missing:
        raise ValueError(f"matches table lacks columns {missing}; give the matches.csv that "
                         "benchmarks/bench_independent.py writes")
    rng = np.random.default_rng(seed)
    b_rows = matches[(matches.kind == "beacon") & ~matches.saturated.astype(bool)]
    out = []
    for ds, g in b_rows.groupby("dataset", sort=False):
        ga, gb = g[g.detector == a], g[g.detector == b]
        if ga.empty or gb.empty:
            continue
        both = ga.merge(gb, on=["frame", "beacon_id"], suffixes=("_a", "_b")).set_index(
            ["frame", "beacon_id"])
        both = both[both.found_a.astype(bool) & both.found_b.astype(bool)]
        if both.empty:
            continue
        sq_a = 0.5 * (both.eu_a**2 + both.ev_a**2)
        sq_b = 0.5 * (both.eu_b**2 + both.ev_b**2)
        per_frame = pd.DataFrame({"a": sq_a, "b": sq_b}).groupby(level="frame").agg(["sum", "size"])
        sums = per_frame[[("a", "sum"), ("b", "sum")]].to_numpy(float)
        counts = per_frame[("a", "size")].to_numpy(float)
        idx = rng.integers(0, len(counts), (n_boot, len(counts)))
        s_a, s_b, n = sums[idx, 0].sum(1), sums[idx, 1].sum(1), counts[idx].sum(1)
        ratio = np.sqrt(s_a / s_b)
        diff = (s_a - s_b) / n
        out.append({
            "dataset": ds, "frames": len(counts), "beacons": int(counts.sum()),
            "rms_a": float(np.sqrt(sq_a.mean())), "rms_b": float(np.sqrt(sq_b.mean())),
            "ratio": float(np.sqrt(sq_a.sum() / sq_b.sum())),
            "ratio_lo": float(np.percentile(ratio, 2.5)), "ratio_hi": float(np.percentile(ratio, 97.5)),
            "mean_d": float((sq_a - sq_b).mean()),
            "d_lo": float(np.percentile(diff, 2.5)), "d_hi": float(np.percentile(diff, 97.5)),
        })
    return pd.DataFrame(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("matches", type=Path, help="a report folder's matches.csv")
    ap.add_argument("--a", default="gauss", help="first detector (default gauss)")
    ap.add_argument("--b", default="sep", help="second detector (default sep)")
    ap.add_argument("--boot", type=int, default=4000, help="bootstrap resamples (default 4000)")
    args = ap.parse_args(argv)
    if not args.matches.is_file():
        ap.error(f"{args.matches} is not a file; give the matches.csv of a report folder")
    table = paired_table(pd.read_csv(args.matches), args.a, args.b, n_boot=args.boot)
    if table.empty:
        print(f"no dataset of {args.matches} holds both {args.a} and {args.b}", file=sys.stderr)
        return 1
    print(f"{args.a} against {args.b}, beacons both found (unclipped), 95 % intervals over frames")
    print("| dataset | frames | beacons | RMS/CRB a | RMS/CRB b | a / b | 95 % | mean d(e^2) | 95 % |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in table.itertuples():
        print(f"| {r.dataset} | {r.frames} | {r.beacons} | {r.rms_a:.3f} | {r.rms_b:.3f} | "
              f"{r.ratio:.3f} | {r.ratio_lo:.3f}–{r.ratio_hi:.3f} | {r.mean_d:+.3f} | "
              f"{r.d_lo:+.3f} to {r.d_hi:+.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
