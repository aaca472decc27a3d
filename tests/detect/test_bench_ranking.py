"""The detector benchmark's ranking rule and RMS/CRB bootstrap interval, and their columns in
``deckpose bench-detectors``' report."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.bench_ranking import (
    INTERVAL_PERCENTILES,
    RANK_RULE,
    bootstrap_rms_over_crb,
    pool_by_detector,
    rank_detectors,
    with_interval_and_rank,
)

from deckpose.cli import main
from tests.tolerances import ROUNDOFF


def _table(rows: list[tuple[str, float, float, float, float]]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["detector", "frames_ok", "recall", "precision", "rms_over_crb"])


#: Detectors in the order the rule puts them, each row saying which key decides it.
RANKED = [
    ("most_frames", 11, 0.1, 0.1, 99.0),  # frames ok first, whatever the rest
    ("best_recall", 10, 0.95, 0.5, 5.0),  # then recall
    ("best_precision", 10, 0.9, 0.9, math.nan),  # then precision, even without a bound
    ("beta", 10, 0.9, 0.8, 1.1),  # then RMS/CRB, lower first
    ("zeta", 10, 0.9, 0.8, 1.1),  # a tie on all four: the name that sorts first wins
    ("worse_rms", 10, 0.9, 0.8, 1.2),
    ("no_bound", 10, 0.9, 0.8, math.nan),  # no RMS/CRB counts as infinite
    ("no_frames_ok", math.nan, 1.0, 1.0, 0.5),  # an empty frames ok counts as 0
]


def test_rank_follows_the_documented_rule_whatever_the_row_order():
    rng = np.random.default_rng(0)
    for _ in range(5):
        t = _table(RANKED).sample(frac=1.0, random_state=int(rng.integers(1 << 31)))
        ranks = rank_detectors(t)
        assert dict(zip(t["detector"], ranks.tolist())) == {r[0]: k + 1 for k, r in enumerate(RANKED)}
    assert "frames detected and identified" in RANK_RULE and "name" in RANK_RULE


def test_rank_is_within_each_group():
    t = pd.concat([_table(RANKED[:3]).assign(camera="a"), _table(RANKED[3:]).assign(camera="b")])
    ranks = rank_detectors(t.iloc[::-1], within=["camera"])
    got = dict(zip(t.iloc[::-1]["detector"], ranks.tolist()))
    assert got == {r[0]: k + 1 for k, r in enumerate(RANKED[:3])} | {r[0]: k + 1 for k, r in enumerate(RANKED[3:])}


def _spots(e2_by_frame: list[np.ndarray], crb_by_frame: list[np.ndarray]) -> pd.DataFrame:
    """Matched uncut spots, du = dv = sqrt(e^2), so that (du^2 + dv^2) / 2 = e^2."""
    e2, crb = np.concatenate(e2_by_frame), np.concatenate(crb_by_frame)
    frame_id = np.repeat(10 * np.arange(len(e2_by_frame)) + 3, [len(x) for x in e2_by_frame])
    return pd.DataFrame({"frame_id": frame_id, "du_px": np.sqrt(e2), "dv_px": -np.sqrt(e2),
                         "crb_var_px2": crb, "matched": True, "occluded": False})


def test_interval_collapses_when_every_frame_has_the_same_ratio():
    rng = np.random.default_rng(1)
    crb = [rng.uniform(0.01, 0.05, n) for n in (3, 7, 1, 12)]
    m = _spots([1.7**2 * c for c in crb], crb)  # every spot, hence every frame, at ratio 1.7
    point, lo, hi = bootstrap_rms_over_crb(m, rng=np.random.default_rng(2))
    assert point == pytest.approx(1.7, rel=ROUNDOFF)
    assert lo == pytest.approx(1.7, rel=ROUNDOFF) and hi == pytest.approx(1.7, rel=ROUNDOFF)


def test_interval_agrees_with_a_plain_resampling_of_the_frames():
    """Resample frames by hand (the same draws), pool each resample's spots, take the percentiles;
    unmatched, cut and bound-less spots are no part of it."""
    rng = np.random.default_rng(3)
    sizes = rng.integers(1, 9, 15)
    crb = [rng.uniform(0.01, 0.05, n) for n in sizes]
    e2 = [c * rng.gamma(2.0, 0.6) * rng.chisquare(2, len(c)) / 2 for c in crb]
    scored = _spots(e2, crb)
    noise = scored.sample(12, random_state=4).assign(matched=False, du_px=50.0)
    noise = pd.concat([noise, scored.sample(5, random_state=5).assign(occluded=True, du_px=50.0),
                       scored.sample(5, random_state=6).assign(crb_var_px2=np.nan, du_px=50.0)])
    m = pd.concat([scored, noise]).sample(frac=1.0, random_state=7)  # shuffled
    point, lo, hi = bootstrap_rms_over_crb(m, rng=np.random.default_rng(8), n_resamples=500)

    frames = list(dict.fromkeys(m.loc[m["matched"] & ~m["occluded"] & m["crb_var_px2"].notna(), "frame_id"]))
    pick = np.random.default_rng(8).integers(0, len(frames), (500, len(frames)))
    by_frame = {f: (float(np.sum(e2[k])), float(np.sum(crb[k]))) for k, f in enumerate(scored["frame_id"].unique())}
    ratios = [math.sqrt(sum(by_frame[frames[j]][0] for j in row) / sum(by_frame[frames[j]][1] for j in row))
              for row in pick]
    want_point = math.sqrt(sum(float(np.sum(x)) for x in e2) / sum(float(np.sum(c)) for c in crb))
    assert point == pytest.approx(want_point, rel=ROUNDOFF)
    assert (lo, hi) == pytest.approx(tuple(np.percentile(ratios, INTERVAL_PERCENTILES)), rel=ROUNDOFF)
    assert lo < point < hi


def test_interval_covers_the_true_ratio_about_95_percent_of_the_time():
    """400 simulated datasets of 40 frames whose spots share a per-frame error scale (the reason the
    frame, not the beacon, is resampled), true RMS/CRB 1.3. The percentile bootstrap's coverage
    is near 95 %: the binomial sd of 400 trials at 0.95 is 0.011, so 3 sd is 0.033; the percentile
    interval of a ratio at 40 frames also runs ~1-2 % short, hence [0.90, 0.985]. Resampling the
    beacons instead ignores the shared scale and covers far less (checked, as the contrast)."""
    rng = np.random.default_rng(9)
    k, n_sim, n_frames, n_spots = 1.3, 400, 40, 10
    covered = covered_by_beacons = 0
    for _ in range(n_sim):
        crb = rng.uniform(0.01, 0.05, (n_frames, n_spots))
        scale2 = rng.gamma(2.0, 0.5, (n_frames, 1))  # E = 1: the true ratio stays k
        e2 = k**2 * scale2 * crb * rng.chisquare(2, (n_frames, n_spots)) / 2
        _, lo, hi = bootstrap_rms_over_crb(_spots(list(e2), list(crb)), rng=rng)
        covered += lo <= k <= hi
        pick = rng.integers(0, e2.size, (1000, e2.size))  # the wrong unit: single spots
        boot = np.sqrt(e2.ravel()[pick].sum(axis=1) / crb.ravel()[pick].sum(axis=1))
        b_lo, b_hi = np.percentile(boot, INTERVAL_PERCENTILES)
        covered_by_beacons += b_lo <= k <= b_hi
    assert 0.90 <= covered / n_sim <= 0.985
    assert covered_by_beacons / n_sim < 0.85


def test_no_scored_spot_is_nan_without_a_draw():
    m = _spots([np.ones(3)], [np.full(3, np.nan)])
    rng = np.random.default_rng(10)
    assert all(math.isnan(x) for x in bootstrap_rms_over_crb(m, rng=rng))
    assert rng.integers(1 << 30) == np.random.default_rng(10).integers(1 << 30)


def test_interval_and_rank_per_cell_leave_the_table_alone():
    rng = np.random.default_rng(11)
    crb = [rng.uniform(0.01, 0.05, 5) for _ in range(6)]
    spots = _spots([c * rng.chisquare(2, 5) / 2 for c in crb], crb)
    matches = pd.concat([spots.assign(detector=d, camera="c", camera_height_m=h)
                         for d in ("x", "y") for h in (20.0, 30.0)], ignore_index=True)
    table = pd.DataFrame({"detector": ["x", "x", "y", "y"], "camera": "c", "height_m": [20.0, 30.0, 20.0, 30.0],
                          "frames_ok": 6, "recall": 1.0, "precision": [0.9, 0.9, 1.0, 1.0],
                          "rms_over_crb": [1.0, math.nan, 1.0, 1.0]})
    before = table.copy()
    out = with_interval_and_rank(table, matches, within=("camera", "height_m"), rng=np.random.default_rng(12))
    pd.testing.assert_frame_equal(table, before)
    assert out["rank"].tolist() == [2, 2, 1, 1]  # y's precision wins in both cells
    assert np.isnan(out.loc[1, ["rms_over_crb_lo", "rms_over_crb_hi"]].to_numpy(float)).all()  # no point
    again = np.random.default_rng(12)  # the rows with a point draw in row order
    for i in (0, 2, 3):
        sel = matches[(matches.detector == table.detector[i]) & (matches.camera_height_m == table.height_m[i])]
        assert out.loc[i, "rms_over_crb_lo":"rms_over_crb_hi"].tolist() == list(bootstrap_rms_over_crb(sel, rng=again)[1:])


def test_pooled_rows_are_ranked_with_their_interval():
    rng = np.random.default_rng(13)
    crb = [rng.uniform(0.01, 0.05, 4) for _ in range(5)]
    spots = _spots([c * rng.chisquare(2, 4) / 2 for c in crb], crb).assign(beacon_id=1, det_beacon_id=1)
    matches = pd.concat([spots.assign(detector="a", du_px=spots.du_px * 3), spots.assign(detector="b")])
    summary = pd.DataFrame({"detector": ["a", "b"], "frames": 5, "detections": 20, "false_per_frame": 0.0,
                            "lights_found": math.nan, "frames_ok": 5, "cpu_ms_per_frame": [1.0, 2.0]})
    pooled = pool_by_detector(summary, matches, rng=np.random.default_rng(0))
    assert pooled["detector"].tolist() == ["b", "a"] and pooled["rank"].tolist() == [1, 2]
    assert (pooled.rms_over_crb_lo < pooled.rms_over_crb).all() and (pooled.rms_over_crb < pooled.rms_over_crb_hi).all()


def test_bench_detectors_writes_interval_and_rank_columns(two_lighting_dataset, tmp_path):
    ds = two_lighting_dataset
    out = tmp_path / "bench"
    argv = ["bench-detectors", str(ds), "--detectors", "binary,cog", "--out", str(out), "--no-progress",
            "--seed", "7", "-q"]
    assert main(argv) == 0
    cells = pd.read_csv(out / "bench_detectors.csv")
    ranking = pd.read_csv(out / "bench_detectors_ranking.csv")
    by_light = pd.read_csv(out / "bench_detectors_by_lighting.csv")
    for t, within in ((cells, ["camera", "height_m"]), (ranking, []),
                      (by_light, ["camera", "height_m", "lighting"])):
        assert {"rms_over_crb_lo", "rms_over_crb_hi", "rank"} <= set(t.columns)
        assert (t.rms_over_crb_lo <= t.rms_over_crb * (1 + 1e-5)).all()  # the CSVs keep 6 digits
        assert (t.rms_over_crb * (1 - 1e-5) <= t.rms_over_crb_hi).all()
        assert t["rank"].tolist() == rank_detectors(t, within=within).tolist()
        assert (t[t.detector == "cog"]["rank"] == 1).all()  # same recall, precision, frames: RMS/CRB decides
    assert (cells.rms_over_crb_lo < cells.rms_over_crb_hi).all()  # two frames a cell: a real interval
    assert (by_light.rms_over_crb_lo == by_light.rms_over_crb_hi).all()  # one frame: collapsed
    md = (out / "bench_detectors.md").read_text()
    assert "## Ranking" in md and "RMS/CRB [95 %]" in md and "seed 7" in md and RANK_RULE in md
    assert "| 1 | cog |" in md and "| 2 | binary |" in md


def test_a_detector_that_matched_nothing_in_a_lighting_is_still_ranked_there():
    """Detector b finds no beacon at night: the per-lighting table keeps its night row, ranked last."""
    from deckpose.detect.bench_report import BenchmarkTables, lighting_table

    spots = _spots([np.full(4, 0.01)] * 2, [np.full(4, 0.01)] * 2)
    base = {"camera": "c", "camera_height_m": 30.0}
    matches = pd.concat([
        spots.assign(detector="a", lighting=light, **base) for light in ("night", "dusk")
    ] + [spots.assign(detector="b", lighting="dusk", **base),
         spots.assign(detector="b", lighting="night", matched=False, du_px=np.nan, dv_px=np.nan, **base)],
        ignore_index=True)
    split = pd.DataFrame({"detector": ["a", "a", "b", "b"], "camera": "c", "height_m": 30.0,
                          "lighting": ["night", "dusk", "night", "dusk"], "frames": 2,
                          "frames_ok": [2, 2, 0, 2], "recall": [1.0, 1.0, 0.0, 1.0], "precision": 1.0})
    tables = BenchmarkTables(summary=pd.DataFrame(), matches=matches, summary_by_lighting=split)
    t = lighting_table(tables, rng=np.random.default_rng(0)).set_index(["detector", "lighting"])
    assert len(t) == 4
    assert t.loc[("b", "night"), "beacons"] == 0 and t.loc[("b", "night"), "rank"] == 2
    assert t.loc[("a", "night"), "rank"] == 1 and t.loc[("a", "night"), "beacons"] == 8
