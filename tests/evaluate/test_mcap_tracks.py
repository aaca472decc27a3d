"""A run's tracks in its MCAP log: filtered and predicted decks, per-frame estimates and truth, and their plot."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from deckpose.evaluate.foxglove_layout import TRACK_PLOT_PANEL, foxglove_layout
from deckpose.evaluate.log_topics import horizon_name
from deckpose.evaluate.mcap_log import write_run_log
from deckpose.evaluate.run import track_horizons
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from deckpose import run_folder as rl
from deckpose.capture_time import capture_epoch, log_stamps
from tests.evaluate.conftest import TRACK_HORIZONS_S as HORIZONS
from tests.tolerances import ROUNDOFF


def _json(root, topic):
    with open(root / "log.mcap", "rb") as fh:
        return [json.loads(m.data) for _, _, m in make_reader(fh).iter_messages(topics=[topic])]


def test_the_log_holds_each_filtered_state_and_the_truth(tracked_run):
    run = rl.run_paths(tracked_run)
    tracks = rl.read_tracks(run, "fake", "thesis", "wave-bank").set_index("frame_id")
    msgs = _json(tracked_run, "/tracks/fake--thesis--wave-bank")
    assert sorted(m["frame_id"] for m in msgs) == sorted(tracks.index)
    for m in msgs:
        row = tracks.loc[m["frame_id"]]
        for q in ("roll_deg", "pitch_deg", "height_m", "sigma_roll_deg", "heave_m"):
            assert m[q] == pytest.approx(float(row[q]), abs=ROUNDOFF)
        assert m["status"] == row["status"] and m["landing_go"] == bool(row["landing_go"])
        assert not any(k.startswith("cov_") for k in m)
    frames = rl.read_frames(run).set_index("frame_id")
    truth = _json(tracked_run, "/truth/deck")
    assert len(truth) == len(frames)
    for m in truth:
        assert m["roll_deg"] == pytest.approx(float(frames.loc[m["frame_id"], "roll_deg"]), abs=ROUNDOFF)
    est = rl.read_estimates(run, "fake", "thesis").set_index("frame_id")
    for m in _json(tracked_run, "/estimates/fake--thesis"):
        assert m["ok"] == bool(est.loc[m["frame_id"], "ok"])
        if m["ok"]:
            assert m["pitch_deg"] == pytest.approx(float(est.loc[m["frame_id"], "pitch_deg"]), abs=ROUNDOFF)


def test_each_prediction_is_logged_at_the_frame_it_was_made_for(tracked_run):
    run = rl.run_paths(tracked_run)
    frames = rl.read_frames(run).set_index("frame_id")
    preds = rl.read_track_predictions(run, "fake", "thesis", "wave-bank").set_index(["frame_id", "horizon_s"])
    for h in HORIZONS:
        msgs = _json(tracked_run, f"/predictions/fake--thesis--wave-bank/{horizon_name(h)}")
        # three frames 0.1 s apart per sequence: 0.1 s ahead is due at the 2nd and 3rd, 0.2 s at the 3rd
        assert len(msgs) == (8 if h == 0.1 else 4)
        for m in msgs:
            made, due = m["made_at_frame_id"], m["frame_id"]
            # same sequence (camera and height), the horizon apart in motion time
            assert frames.loc[made, "camera"] == frames.loc[due, "camera"]
            assert frames.loc[made, "camera_height_m"] == frames.loc[due, "camera_height_m"]
            assert frames.loc[due, "t_s"] - frames.loc[made, "t_s"] == pytest.approx(h, abs=1e-9)
            assert m["roll_deg"] == pytest.approx(float(preds.loc[(made, h), "roll_deg"]), abs=ROUNDOFF)


def test_the_filtered_and_predicted_decks_are_transforms_and_scene_entities(tracked_run):
    run = rl.run_paths(tracked_run)
    frames = rl.read_frames(run)
    stamps = log_stamps(frames, capture_epoch(rl.read_manifest(run))[0])
    frame_at = dict(zip(stamps.to_numpy(np.int64), frames["frame_id"]))
    frames = frames.set_index("frame_id")
    tracks = rl.read_tracks(run, "fake", "thesis", "wave-bank").set_index("frame_id")
    with open(tracked_run / "log.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        decoded = [(c.topic, m.log_time, d) for _, c, m, d in reader.iter_decoded_messages(topics=["/tf", "/scene"])]
    tfs = {t: d for topic, t, d in decoded if topic == "/tf"}
    scenes = {t: d for topic, t, d in decoded if topic == "/scene"}
    assert sorted(frame_at[t] for t in tfs) == sorted(frames.index)
    n_pred = 0
    for t, msg in tfs.items():
        f = frame_at[t]
        row, tr = frames.loc[f], tracks.loc[f]
        by_child = {x.child_frame_id: x for x in msg.transforms}
        deck = by_child["deck_track/fake--thesis--wave-bank"]
        # deck centre = camera + (surge, sway, -height), surge/sway/height as filtered
        assert deck.translation.x == pytest.approx(row["cam_x_m"] + tr["surge_m"], abs=1e-9)
        assert deck.translation.y == pytest.approx(row["cam_y_m"] + tr["sway_m"], abs=1e-9)
        assert deck.translation.z == pytest.approx(row["cam_z_m"] - tr["height_m"], abs=1e-9)
        preds = [c for c in by_child if c.startswith("deck_pred/fake--thesis--wave-bank/")]
        n_pred += len(preds)
        ids = {e.id for e in scenes[t].entities}
        assert "deck_track/fake--thesis--wave-bank" in ids and set(preds) <= ids
    assert n_pred == 12   # as many predicted decks as predictions due (8 at 0.1 s, 4 at 0.2 s)


def test_the_layout_plots_the_tracks_topics_the_log_has(tracked_run):
    run = rl.run_paths(tracked_run)
    tracks = track_horizons(run)
    assert tracks == [("fake", "thesis", "wave-bank", list(HORIZONS))]
    layout = foxglove_layout(run.detectors(), run.estimate_pairs(), tracks)

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(layout["configById"])
    with open(tracked_run / "log.mcap", "rb") as fh:
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    plotted = [p["value"] for p in layout["configById"][TRACK_PLOT_PANEL]["paths"]]
    assert all(p.endswith(".roll_deg") for p in plotted)
    assert {p.rsplit(".", 1)[0] for p in plotted} <= topics
    # the log was written without errors handed over (as the pipeline writes it): the run's errors are in it
    error_plot = {p["value"].rsplit(".", 1)[0] for p in json.loads(
        (tracked_run / "foxglove_layout.json").read_text())["configById"]["Plot!errors"]["paths"]}
    assert error_plot == {"/errors/fake--thesis"} and error_plot <= topics
    assert len(plotted) == 3 + len(HORIZONS)   # truth, per frame, filtered, each horizon
    # a run without tracks keeps its three panels
    assert TRACK_PLOT_PANEL not in foxglove_layout(["fake"], [("fake", "thesis")])["configById"]


def test_a_missing_predictions_file_names_the_command(tracked_run, tmp_path):
    root = tmp_path / "run"
    shutil.copytree(tracked_run, root)
    run = rl.run_paths(root)
    run.track_predictions("fake", "thesis", "wave-bank").unlink()
    from deckpose.errors import InputDataError
    with pytest.raises(InputDataError, match="deckpose track .* --estimates thesis"):
        write_run_log(run)
