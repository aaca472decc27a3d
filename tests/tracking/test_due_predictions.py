"""Predictions placed at the frame they were made for, against a brute-force search."""

from __future__ import annotations

import numpy as np
import pandas as pd

from deckpose.tracking.due_predictions import predictions_due


def _tables(stamps_by_seq: list[np.ndarray], horizons: tuple[float, ...]):
    tracks, preds = [], []
    fid = 0
    for s, stamps in enumerate(stamps_by_seq):
        for st in stamps:
            tracks.append({"frame_id": fid, "sequence": s, "stamp_ns": int(st)})
            for h in horizons:
                preds.append({"frame_id": fid, "horizon_s": h, "stamp_ns": int(st) + round(h * 1e9),
                              "roll_deg": fid + h, "sigma_roll_deg": 0.1 * h})
            fid += 1
    return pd.DataFrame(tracks), pd.DataFrame(preds)


def _brute_force(tracks: pd.DataFrame, preds: pd.DataFrame) -> set[tuple[int, float, int]]:
    """(due frame, horizon, made-at frame): each prediction's nearest frame of its sequence, kept within half the
    sequence's median interval; of two due at one frame and horizon, the one made for the nearer time."""
    best_of: dict[tuple[int, float], tuple[int, int]] = {}
    seq = tracks.set_index("frame_id")["sequence"]
    for _, p in preds.iterrows():
        g = tracks[tracks["sequence"] == seq[p["frame_id"]]].sort_values("stamp_ns")
        half = 0.5 * float(np.median(np.diff(g["stamp_ns"].to_numpy())))
        d = (g["stamp_ns"] - p["stamp_ns"]).abs()
        best = d.idxmin()
        if d[best] <= half and int(g.loc[best, "frame_id"]) != int(p["frame_id"]):
            key = (int(g.loc[best, "frame_id"]), float(p["horizon_s"]))
            cand = (int(d[best]), int(p["frame_id"]))
            best_of[key] = min(best_of.get(key, cand), cand)
    return {(f, h, made) for (f, h), (_, made) in best_of.items()}


def test_each_prediction_lands_on_the_frame_it_was_made_for():
    rng = np.random.default_rng(3)
    # two sequences: 10 Hz with +-20 ms jitter, and 4 Hz; the second starts later (its own time base)
    a = np.cumsum(np.full(40, 100_000_000) + rng.integers(-20_000_000, 20_000_000, 40))
    b = 10**12 + np.arange(25) * 250_000_000
    tracks, preds = _tables([a, b], (0.04, 0.5, 1.0, 2.0, 5.0))
    due = predictions_due(tracks, preds)
    got = {(int(r.frame_id), float(r.horizon_s), int(r.made_at_frame_id)) for r in due.itertuples()}
    assert got == _brute_force(tracks, preds)
    # no prediction crosses into the other sequence, and the values travel with it
    seq = tracks.set_index("frame_id")["sequence"]
    assert (seq.loc[due["frame_id"]].to_numpy() == seq.loc[due["made_at_frame_id"]].to_numpy()).all()
    np.testing.assert_array_equal(due["roll_deg"], due["made_at_frame_id"] + due["horizon_s"])
    stamp = tracks.set_index("frame_id")["stamp_ns"]
    np.testing.assert_array_equal(due["due_offset_ns"], stamp.loc[due["frame_id"]].to_numpy()
                                  - (stamp.loc[due["made_at_frame_id"]].to_numpy()
                                     + np.round(due["horizon_s"].to_numpy() * 1e9).astype(np.int64)))


def test_horizons_beyond_the_sequence_have_nothing_due_and_an_empty_track_is_empty():
    tracks, preds = _tables([np.arange(5) * 100_000_000], (0.01, 0.1, 5.0))
    due = predictions_due(tracks, preds)
    # 0.1 s ahead lands on the next frame (4 of 5 frames have a successor); 5 s ahead is beyond the run;
    # 0.01 s ahead is nearest the frame it was made at, which is not a frame ahead
    assert set(due["horizon_s"]) == {0.1}
    assert due["made_at_frame_id"].tolist() == [0, 1, 2, 3] and due["frame_id"].tolist() == [1, 2, 3, 4]
    one, one_pred = _tables([np.array([0])], (0.5,))
    empty = predictions_due(one, one_pred)
    assert len(empty) == 0 and {"frame_id", "horizon_s", "made_at_frame_id", "roll_deg"} <= set(empty.columns)
