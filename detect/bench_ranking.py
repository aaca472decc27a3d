"""Detector benchmark: RMS/CRB with its bootstrap interval, detectors pooled over a dataset, and their rank.

The one home of the ranking rule and of the interval that ``deckpose bench-detectors``
(:mod:`deckpose.detect.bench_report`) and ``benchmarks/detector_ladder.py`` report.

* :func:`bootstrap_rms_over_crb`: the pooled ratio ``sqrt(sum(e^2) / sum(crb))`` of the
  matched uncut spots with a bound, and its 95 % percentile bootstrap interval. The
  resampling unit is the frame, not the beacon: a frame's spots share its pose, blur and
  lighting, so their errors are not independent.
* :func:`rank_detectors`: the rank of each row among the rows of its group (:data:`RANK_RULE`).
* :func:`pool_by_detector`: one row per detector, a dataset's cells pooled, ranked;
* :func:`with_interval_and_rank`: the interval and the rank on each row of a finer table
  (detector x camera x height, or x lighting too).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pandas as pd

__all__ = [
    "INTERVAL_PERCENTILES",
    "N_RESAMPLES",
    "RANK_RULE",
    "RmsOverCrb",
    "bootstrap_rms_over_crb",
    "geometric_rms_over_crb",
    "pool_by_detector",
    "rank_detectors",
    "scored_spots",
    "with_interval_and_rank",
]

#: Bootstrap resamples of the frames behind each interval.
N_RESAMPLES = 1000
#: The percentiles of the bootstrap distribution that bound the 95 % interval.
INTERVAL_PERCENTILES = (2.5, 97.5)
#: The ranking rule in words, for the reports' notes (:func:`rank_detectors` applies it).
RANK_RULE = (
    "rank: the detectors of a group ordered by frames detected and identified (more first), "
    "then recall, then precision (higher first), then RMS/CRB (lower first); an empty value "
    "counts as 0 (RMS/CRB: as infinite), and a tie on all four goes to the detector name "
    "that sorts first"
)


class RmsOverCrb(NamedTuple):
    """Pooled RMS/CRB and its bootstrap interval (NaN each when no spot has a bound).

    Attributes
    ----------
    point : float
        ``sqrt(sum(e^2) / sum(crb))`` over the spots, unitless.
    lo, hi : float
        The 2.5th and 97.5th percentiles of the ratio over the frame resamples.
    """

    point: float
    lo: float
    hi: float


def scored_spots(matches: pd.DataFrame) -> pd.DataFrame:
    """The rows RMS/CRB pools: matched, not cut by an occluder, with a finite bound.

    Parameters
    ----------
    matches : DataFrame
        Per-beacon rows of :func:`~deckpose.detect.benchmark.match_run` with ``occluded``
        and ``crb_var_px2`` (px^2) columns.

    Returns
    -------
    DataFrame
        The subset of ``matches`` (a new frame; ``matches`` is not modified).
    """
    keep = matches["matched"].astype(bool) & ~matches["occluded"].astype(bool)
    return matches[keep & np.isfinite(matches["crb_var_px2"].to_numpy(float))]


def bootstrap_rms_over_crb(
    matches: pd.DataFrame, *, rng: np.random.Generator, n_resamples: int = N_RESAMPLES
) -> RmsOverCrb:
    """Pooled RMS/CRB of the scored spots and its 95 % percentile bootstrap interval.

    Parameters
    ----------
    matches : DataFrame
        Per-beacon rows (:func:`scored_spots` picks the pooled ones): ``frame_id``, the
        error ``du_px, dv_px`` (px) against the light's centroid in the channel sum, and
        the per-axis bound ``crb_var_px2`` (px^2).
    rng : numpy.random.Generator
        Draws the resamples; one call of ``rng.integers`` of shape
        ``(n_resamples, frames)``, none when no spot is scored.
    n_resamples : int
        Resamples of the frames (with replacement, as many as there are).

    Returns
    -------
    RmsOverCrb
        ``point = sqrt(sum(e^2) / sum(crb))`` with ``e^2 = (du^2 + dv^2) / 2``, and the
        :data:`INTERVAL_PERCENTILES` of the same ratio over the resamples, each resample
        pooling the spots of its drawn frames. With one frame, or frames of equal ratio,
        the interval collapses to the point. NaN each when no spot is scored.
    """
    m = scored_spots(matches)
    if m.empty:
        return RmsOverCrb(math.nan, math.nan, math.nan)
    e2 = ((m["du_px"] ** 2 + m["dv_px"] ** 2) / 2).to_numpy(float)
    crb = m["crb_var_px2"].to_numpy(float)
    codes, fids = pd.factorize(m["frame_id"])
    se = np.bincount(codes, e2, len(fids))
    sc = np.bincount(codes, crb, len(fids))
    point = math.sqrt(se.sum() / sc.sum())
    pick = rng.integers(0, len(fids), (n_resamples, len(fids)))
    boot = np.sqrt(se[pick].sum(axis=1) / sc[pick].sum(axis=1))
    lo, hi = np.percentile(boot, INTERVAL_PERCENTILES)
    return RmsOverCrb(point, float(lo), float(hi))


def geometric_rms_over_crb(matches: pd.DataFrame) -> float:
    """Pooled RMS/CRB of the scored spots against the geometric (green) centre: what the lens costs.

    Parameters
    ----------
    matches : DataFrame
        As for :func:`bootstrap_rms_over_crb`, with ``du_geo_px, dv_geo_px`` (px).

    Returns
    -------
    float
        ``sqrt(sum(e_geo^2) / sum(crb))``, unitless; NaN without scored spots or the columns.
    """
    m = scored_spots(matches)
    if m.empty or "du_geo_px" not in m:
        return math.nan
    e2 = ((m["du_geo_px"] ** 2 + m["dv_geo_px"] ** 2) / 2).to_numpy(float)
    return math.sqrt(float(e2.sum()) / float(m["crb_var_px2"].to_numpy(float).sum()))


def rank_detectors(table: pd.DataFrame, *, within: Sequence[str] = ()) -> np.ndarray:
    """Rank of each row among the rows that share its ``within`` columns, by :data:`RANK_RULE`.

    Parameters
    ----------
    table : DataFrame
        One row per detector (per group): ``detector``, ``frames_ok`` (a count or a share:
        rows of a group compare like with like), ``recall``, ``precision``, ``rms_over_crb``.
    within : sequence of str
        The columns whose values make a group (none: the whole table is one group).

    Returns
    -------
    (len(table),) array of int
        1 for the best row of its group, then 2, 3, ...; distinct within a group.
    """
    n = len(table)
    keys = [table[c].fillna(0.0).to_numpy(float) for c in ("frames_ok", "recall", "precision")]
    rms = table["rms_over_crb"].fillna(np.inf).to_numpy(float)
    name = pd.factorize(table["detector"].astype(str), sort=True)[0]
    group = (pd.MultiIndex.from_frame(table[list(within)]).factorize()[0] if within
             else np.zeros(n, np.intp))
    # np.lexsort sorts by the last key first
    order = np.lexsort((name, rms, -keys[2], -keys[1], -keys[0], group))
    g = group[order]
    first = np.r_[True, g[1:] != g[:-1]] if n else np.zeros(0, bool)
    pos = np.arange(n)
    rank = np.empty(n, np.int64)
    rank[order] = pos - np.maximum.accumulate(np.where(first, pos, 0)) + 1
    return rank


def pool_by_detector(
    summary: pd.DataFrame, matches: pd.DataFrame, *, rng: np.random.Generator
) -> pd.DataFrame:
    """One row per detector: a dataset's cells pooled (sums over cells, medians of times), ranked.

    Parameters
    ----------
    summary : DataFrame
        :func:`~deckpose.detect.benchmark.summarise`'s rows (detector x camera x height).
    matches : DataFrame
        The per-beacon rows behind them, with ``detector``, ``occluded`` and ``crb_var_px2``.
    rng : numpy.random.Generator
        For :func:`bootstrap_rms_over_crb`, called once per detector in name order.

    Returns
    -------
    DataFrame
        ``detector, frames, beacons, recall, recall_occluded, precision, false_per_frame,
        lights_found, id_accuracy, frames_ok`` (a share), ``rms_over_crb, rms_over_crb_lo,
        rms_over_crb_hi, rms_geometric_over_crb, cpu_ms_per_frame`` (median of the cells'),
        ``rank`` (:func:`rank_detectors`), sorted by rank.
    """
    rows = []
    for det, s in summary.groupby("detector", sort=True):
        m = matches[matches["detector"] == det]
        occ = m[m["occluded"].astype(bool)]
        found = m[m["matched"]]
        n_det = int(s["detections"].sum())
        point, lo, hi = bootstrap_rms_over_crb(m, rng=rng)
        fl = s["false_per_frame"] * s["frames"]
        rows.append({
            "detector": det, "frames": int(s["frames"].sum()), "beacons": len(m),
            "recall": float(m["matched"].mean()),
            "recall_occluded": float(occ["matched"].mean()) if len(occ) else math.nan,
            "precision": len(found) / n_det if n_det else math.nan,
            "false_per_frame": float(fl.sum() / s["frames"].sum()),
            "lights_found": float(np.nansum(s["lights_found"] * s["frames"]) / s["frames"].sum())
            if s["lights_found"].notna().any() else math.nan,
            "id_accuracy": float((found["det_beacon_id"] == found["beacon_id"]).mean())
            if len(found) else math.nan,
            "frames_ok": float(s["frames_ok"].sum() / s["frames"].sum()),
            "rms_over_crb": point, "rms_over_crb_lo": lo, "rms_over_crb_hi": hi,
            "rms_geometric_over_crb": geometric_rms_over_crb(m),
            "cpu_ms_per_frame": float(np.median(s["cpu_ms_per_frame"])),
        })
    df = pd.DataFrame(rows)
    df["rank"] = rank_detectors(df)
    return df.sort_values("rank")


#: A table's column -> the column of the per-beacon matches holding the same key.
_MATCHES_COLUMN = {"height_m": "camera_height_m"}


def with_interval_and_rank(
    table: pd.DataFrame, matches: pd.DataFrame, *, within: Sequence[str], rng: np.random.Generator
) -> pd.DataFrame:
    """A copy of ``table`` with the RMS/CRB interval of each row and its rank within its group.

    Parameters
    ----------
    table : DataFrame
        One row per detector x the ``within`` columns, with the columns
        :func:`rank_detectors` reads (``rms_over_crb`` the row's point value).
    matches : DataFrame
        The per-beacon rows behind it (``detector`` and the ``within`` columns, ``height_m``
        read as ``camera_height_m``).
    within : sequence of str
        The columns of a group: each row's interval pools its detector's matches with the
        row's values there, and its rank is among the rows of the same values.
    rng : numpy.random.Generator
        For :func:`bootstrap_rms_over_crb`, called in row order for each row whose
        ``rms_over_crb`` is finite (the others' interval is NaN).

    Returns
    -------
    DataFrame
        ``table`` (not modified) with ``rms_over_crb_lo``, ``rms_over_crb_hi`` and ``rank``.
    """
    keys = ["detector", *within]
    groups = {k if isinstance(k, tuple) else (k,): g
              for k, g in matches.groupby([_MATCHES_COLUMN.get(c, c) for c in keys], sort=False)}
    bounds = np.full((len(table), 2), np.nan)
    for i, (key, point) in enumerate(zip(table[keys].itertuples(index=False, name=None),
                                         table["rms_over_crb"].to_numpy(float))):
        g = groups.get(tuple(key))
        if g is not None and np.isfinite(point):
            bounds[i] = bootstrap_rms_over_crb(g, rng=rng)[1:]
    return table.assign(rms_over_crb_lo=bounds[:, 0], rms_over_crb_hi=bounds[:, 1],
                        rank=rank_detectors(table, within=within))
