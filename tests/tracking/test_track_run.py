"""Tracking a run folder: sequences, statuses, files, accuracy against the truth and errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from deckpose.errors import ConfigError, InputDataError
from deckpose.run_folder import run_paths
from deckpose.table_schemas import TRACK_COLUMNS, TRACK_PREDICTION_COLUMNS
from deckpose.tables import read_table, table_metadata
from deckpose.tracking.config import TrackConfig, load_track_config
from deckpose.tracking.run import track_run, track_table
from tests.tracking.synthetic_run import write_run


def test_track_table_filters_each_sequence_and_reports_what_it_did(tmp_path):
    frames, est = write_run(tmp_path / "run", duration_s=20.0, heights_m=(30.0, 60.0), not_ok=(50,),
                            outliers=(120,))
    tracks, preds = track_table(frames, est, TrackConfig())
    assert list(tracks.columns) == [c.name for c in TRACK_COLUMNS]
    assert list(preds.columns) == [c.name for c in TRACK_PREDICTION_COLUMNS]
    assert sorted(tracks["frame_id"]) == sorted(frames["frame_id"])
    assert tracks.groupby("sequence")["frame_id"].min().tolist() == [0, 201]
    assert tracks.set_index("frame_id").loc[50, "status"] == "skipped"
    assert tracks.set_index("frame_id").loc[120, "status"] == "gated"
    assert (tracks["status"] == "updated").sum() == len(frames) - 2
    assert np.all(np.diff(tracks["stamp_ns"].to_numpy()[:201]) > 0)
    assert len(preds) == 4 * len(frames) and set(preds["horizon_s"]) == {0.5, 1.0, 2.0, 5.0}
    assert tracks["yaw_deg"].between(-180, 180).all()


def test_filtered_and_predicted_deck_against_the_truth(tmp_path):
    # 60 s of sea state 6 at 10 Hz, estimates with their stated noise (roll sigma 0.2 deg)
    frames, est = write_run(tmp_path / "run", duration_s=60.0, sigma_scale=5.0)
    tracks, preds = track_table(frames, est, TrackConfig())
    t = tracks.merge(frames, on="frame_id", suffixes=("", "_true")).iloc[100:]    # after a 10 s warm-up
    e = est.set_index("frame_id").loc[t["frame_id"]]
    filt = t["roll_deg"].to_numpy() - t["roll_deg_true"].to_numpy()
    raw = e["roll_deg"].to_numpy() - t["roll_deg_true"].to_numpy()
    rms = lambda a: float(np.sqrt(np.mean(np.square(a))))
    # the filter averages the per-frame noise: its error is clearly smaller (measured ~0.6 of it)
    assert rms(filt) < 0.85 * rms(raw)
    # and honest: every filtered roll, pitch and height within 5 of its own sigmas
    for q, truth in (("roll_deg", t["roll_deg_true"]), ("pitch_deg", t["pitch_deg_true"]),
                     ("height_m", t["cam_z_m"] - t["heave_m_true"])):
        z = (t[q] - truth) / t[f"sigma_{q}"]
        assert np.all(np.abs(z) < 5), q
        assert 0.2 < rms(z) < 2.0, q                 # neither over- nor far under-confident
    # 1 s ahead: the prediction beats holding the last estimate (measured ~0.3 of its error)
    p = preds[preds["horizon_s"] == 1.0].set_index("frame_id")
    ids = t["frame_id"].to_numpy()[:-10]
    truth_ahead = frames.set_index("frame_id").loc[ids + 10, "roll_deg"].to_numpy()
    pred_err = p.loc[ids, "roll_deg"].to_numpy() - truth_ahead
    hold_err = est.set_index("frame_id").loc[ids, "roll_deg"].to_numpy() - truth_ahead
    assert rms(pred_err) < 0.6 * rms(hold_err)


def test_track_run_writes_the_tables_and_the_record(tmp_path):
    write_run(tmp_path / "run", duration_s=5.0)
    res = track_run(tmp_path / "run", TrackConfig(), command=["deckpose", "track", "run"])
    paths = run_paths(tmp_path / "run")
    assert res.path == paths.tracks("cog", "pnp", "wave-bank") and res.path.exists()
    back = read_table(res.path, "tracks")
    pd.testing.assert_frame_equal(back, res.table, check_dtype=False)
    assert table_metadata(res.path)["kind"] == "tracks"
    assert read_table(res.predictions_path, "track predictions")["horizon_s"].nunique() == 4
    rec = json.loads(res.record_path.read_text())
    assert rec["n_updated"] == 51 and rec["config"]["gate_probability"] == 0.9999
    # the record's config reads back as the same config
    (tmp_path / "again.yaml").write_text(json.dumps(rec["config"]))
    assert load_track_config(tmp_path / "again.yaml") == TrackConfig()
    assert "51 frames in 1 sequence: 51 updated" in res.summary()


def test_which_estimates_and_bad_configs_are_one_line_errors(tmp_path):
    write_run(tmp_path / "run", duration_s=2.0)
    with pytest.raises(InputDataError, match="no estimates of detector gauss"):
        track_run(tmp_path / "run", TrackConfig(), detector="gauss")
    est = run_paths(tmp_path / "run").estimates("cog", "pnp")
    est.rename(est.with_name("cog--conic.parquet"))
    write_run(tmp_path / "run", duration_s=2.0)
    with pytest.raises(InputDataError, match="several estimates tables; choose one with --detector cog"):
        track_run(tmp_path / "run", TrackConfig())
    assert track_run(tmp_path / "run", TrackConfig(), method="conic").path.name == "cog--conic--wave-bank.parquet"
    with pytest.raises(ConfigError, match="unknown tracker"):
        track_run(tmp_path / "run", TrackConfig(), tracker="nosuch")
    (tmp_path / "bad.yaml").write_text("model: {periods_s: [8, 11], dampin_ratio: 0.1}\n")
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['dampin_ratio'\]"):
        load_track_config(tmp_path / "bad.yaml")
    (tmp_path / "bad2.yaml").write_text("landing: {window_s: -1}\n")
    with pytest.raises(ConfigError, match="window_s: must be a positive number"):
        load_track_config(tmp_path / "bad2.yaml")
    assert math.isfinite(TrackConfig().gate_probability)


def test_the_committed_config_is_the_defaults():
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "configs" / "track" / "wave_bank.yaml"
    assert load_track_config(path) == TrackConfig()


def test_named_tracks_of_two_configs_stay_side_by_side(tmp_path):
    """A second config's track under its own --name does not replace the default one."""
    write_run(tmp_path / "run", duration_s=3.0)
    first = track_run(tmp_path / "run", TrackConfig())
    other = TrackConfig(gate_probability=0.99)
    second = track_run(tmp_path / "run", other, name="gate99")
    assert first.path.name == "cog--pnp--wave-bank.parquet" and second.path.name == "cog--pnp--gate99.parquet"
    assert first.path.exists() and second.path.exists()
    assert sorted(run_paths(tmp_path / "run").track_triples()) == [("cog", "pnp", "gate99"), ("cog", "pnp", "wave-bank")]
    rec = json.loads(second.record_path.read_text())
    assert (rec["tracker"], rec["name"], rec["config"]["gate_probability"]) == ("wave-bank", "gate99", 0.99)
    for bad in ("a--b", "../x", "", "sp ace"):
        with pytest.raises(ConfigError, match="track name"):
            track_run(tmp_path / "run", TrackConfig(), name=bad)
